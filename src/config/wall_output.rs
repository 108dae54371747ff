//! A wall's `output`: one stereo format for its window (`output = "side-by-side"`), or one
//! window per eye (`[[wall.output]] eye = "left"`, …) for a passive-stereo wall fed by two
//! projectors, each with a crop and offset to align it to the other by a few pixels.

use std::fmt;

use schemars::JsonSchema;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::{Deserialize, Serialize, Serializer};

use super::MonitorRef;
use crate::cave::Eye;
use crate::output::formats::StereoFormat;

/// Budget: outputs of one wall (two eyes; a few more for mirrored operator copies).
pub const MAX_EYE_OUTPUTS: usize = 4;

/// Which eye an output window shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputEye {
    Left,
    Right,
}

crate::named_enum!(OutputEye {
    Self::Left => "left",
    Self::Right => "right",
});

impl OutputEye {
    pub fn eye(self) -> Eye {
        match self {
            Self::Left => Eye::Left,
            Self::Right => Eye::Right,
        }
    }
}

/// One projector's window of a wall: an eye, where the window goes, and its alignment.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct EyeOutputSection {
    pub eye: OutputEye,
    /// The monitor this window goes fullscreen on: an index or a name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub monitor: Option<MonitorRef>,
    /// Borderless window position when no monitor is named or found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_position: Option<[i32; 2]>,
    /// Window size when no monitor is named or found; default: the crop's or the wall's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_size: Option<[u32; 2]>,
    /// The part of the eye image this projector shows: x, y, width, height in wall pixels;
    /// default: all of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crop: Option<[u32; 4]>,
    /// Moves the image in the window by x, y pixels (right, down), to align two projectors;
    /// what moves out is cut, what it uncovers is black.
    #[serde(default, skip_serializing_if = "is_zero")]
    #[schemars(inner(range(min = -4096, max = 4096)))]
    pub offset: [i32; 2],
}

fn is_zero(v: &[i32; 2]) -> bool {
    *v == [0, 0]
}

/// A wall's output: a format for its one window, or a window per eye.
#[derive(Debug, Clone, PartialEq)]
pub enum WallOutput {
    Format(StereoFormat),
    PerEye(Vec<EyeOutputSection>),
}

impl Serialize for WallOutput {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Self::Format(f) => f.serialize(s),
            Self::PerEye(outputs) => outputs.serialize(s),
        }
    }
}

impl<'de> Deserialize<'de> for WallOutput {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct OutputVisitor;
        impl<'de> Visitor<'de> for OutputVisitor {
            type Value = WallOutput;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(
                    f,
                    "a stereo format ({}) or [[wall.output]] tables with an eye each",
                    StereoFormat::NAMES.join(", ")
                )
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<WallOutput, E> {
                v.parse().map(WallOutput::Format).map_err(E::custom)
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<WallOutput, A::Error> {
                let mut outputs = Vec::new();
                while let Some(o) = seq.next_element::<EyeOutputSection>()? {
                    if outputs.len() == MAX_EYE_OUTPUTS {
                        return Err(de::Error::custom(format!(
                            "more than {MAX_EYE_OUTPUTS} outputs for one wall"
                        )));
                    }
                    outputs.push(o);
                }
                Ok(WallOutput::PerEye(outputs))
            }
        }
        d.deserialize_any(OutputVisitor)
    }
}

impl JsonSchema for WallOutput {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "WallOutput".into()
    }
    fn json_schema(generator: &mut schemars::SchemaGenerator) -> schemars::Schema {
        let format = generator.subschema_for::<StereoFormat>();
        let outputs = generator.subschema_for::<Vec<EyeOutputSection>>();
        schemars::json_schema!({ "anyOf": [format, outputs] })
    }
}
