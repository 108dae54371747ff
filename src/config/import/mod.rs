//! `omnicave config import`: walls from the configuration files of the software a lab uses
//! today (an Equalizer `.eqc` wall list, a CalVR screen list, an Unreal nDisplay `.ndisplay`
//! screen list), converted into omnicave's `[[wall]]` tables in CAVE space.

mod calvr;
mod equalizer;
mod ndisplay;

use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::cave::placement::LengthUnit;
use crate::read_capped::{MAX_CONFIG_BYTES, read_capped_text};

/// Budget: the most walls one file may describe (omnicave's own `budgets.max_walls` default).
pub const MAX_IMPORTED_WALLS: usize = 64;

/// The formats `config import` reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImportFormat {
    /// Equalizer's `.eqc`: `wall { bottom_left [...] bottom_right [...] top_left [...] }`, metres,
    /// y up.
    Equalizer,
    /// CalVR's XML `<Screen originX= originY= originZ= h= p= r= width= height= />`, mm, z up.
    CalVr,
    /// Unreal nDisplay's JSON `scene.screens` (with `scene.xforms` parents), cm, z up, x forward.
    NDisplay,
}

crate::named_enum!(ImportFormat {
    Self::Equalizer => "equalizer",
    Self::CalVr => "calvr",
    Self::NDisplay => "ndisplay",
});

impl ImportFormat {
    /// The format a file name suggests.
    pub fn from_extension(path: &Path) -> Option<Self> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "eqc" => Some(Self::Equalizer),
            "xml" => Some(Self::CalVr),
            "ndisplay" | "json" => Some(Self::NDisplay),
            _ => None,
        }
    }

    /// The length unit the format's documentation uses.
    pub fn default_unit(self) -> LengthUnit {
        match self {
            Self::Equalizer => LengthUnit::Metre,
            Self::CalVr => LengthUnit::Millimetre,
            Self::NDisplay => LengthUnit::Centimetre,
        }
    }
}

/// A wall read from another program's file, in CAVE space (metres, y up).
#[derive(Debug, Clone, PartialEq)]
pub struct ImportedWall {
    pub name: String,
    pub lower_left: DVec3,
    pub lower_right: DVec3,
    pub upper_left: DVec3,
    /// Pixels, where the file says (a window or viewport of this wall).
    pub resolution: Option<[u32; 2]>,
}

/// What can go wrong importing, naming the file.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {why}")]
    Invalid { path: PathBuf, why: String },
    #[error("{path}: no walls found ({what})")]
    NoWalls { path: PathBuf, what: &'static str },
    #[error("{path}: more than {MAX_IMPORTED_WALLS} walls")]
    TooMany { path: PathBuf },
    #[error(
        "cannot tell the format of {path} from its extension: give --format (equalizer, calvr or ndisplay)"
    )]
    Format { path: PathBuf },
}

/// Reads `path` (at most [`MAX_CONFIG_BYTES`]) and returns its walls in CAVE space.
pub fn import_walls(
    path: &Path,
    format: Option<ImportFormat>,
    unit: Option<LengthUnit>,
) -> Result<Vec<ImportedWall>, ImportError> {
    let format = format
        .or_else(|| ImportFormat::from_extension(path))
        .ok_or_else(|| ImportError::Format {
            path: path.to_owned(),
        })?;
    let text = read_capped_text(path, MAX_CONFIG_BYTES, "config files").map_err(|source| {
        ImportError::Read {
            path: path.to_owned(),
            source,
        }
    })?;
    let unit = unit.unwrap_or(format.default_unit());
    let invalid = |why: String| ImportError::Invalid {
        path: path.to_owned(),
        why,
    };
    let walls = match format {
        ImportFormat::Equalizer => equalizer::walls(&text, unit).map_err(invalid)?,
        ImportFormat::CalVr => calvr::walls(&text, unit).map_err(invalid)?,
        ImportFormat::NDisplay => ndisplay::walls(&text, unit).map_err(invalid)?,
    };
    if walls.is_empty() {
        return Err(ImportError::NoWalls {
            path: path.to_owned(),
            what: match format {
                ImportFormat::Equalizer => "no wall { } blocks",
                ImportFormat::CalVr => "no <Screen> elements",
                ImportFormat::NDisplay => "no scene.screens",
            },
        });
    }
    if walls.len() > MAX_IMPORTED_WALLS {
        return Err(ImportError::TooMany {
            path: path.to_owned(),
        });
    }
    Ok(unique_names(walls))
}

/// A wall name omnicave accepts (1–64 of a-z, A-Z, 0-9, '-', '_'), from any text.
pub fn clean_name(raw: &str, fallback: &str) -> String {
    let name: String = raw
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .take(64)
        .collect();
    if name.trim_matches('_').is_empty() {
        fallback.to_owned()
    } else {
        name
    }
}

fn unique_names(mut walls: Vec<ImportedWall>) -> Vec<ImportedWall> {
    let mut seen = std::collections::HashSet::new();
    for (i, w) in walls.iter_mut().enumerate() {
        if !seen.insert(w.name.clone()) {
            let mut name: String = w.name.chars().take(56).collect();
            name.push_str(&format!("_{i}"));
            w.name = name;
            seen.insert(w.name.clone());
        }
    }
    walls
}

/// A number as TOML writes it: six decimals (a micrometre), no trailing zeros, no "-0".
fn number(v: f64) -> String {
    let rounded = (v * 1e6).round() / 1e6;
    let rounded = if rounded == 0.0 { 0.0 } else { rounded };
    let mut s = format!("{rounded:.6}");
    while s.ends_with('0') {
        s.pop();
    }
    if s.ends_with('.') {
        s.push('0');
    }
    s
}

/// The walls as `[[wall]]` tables (`resolution` where the file gives none).
pub fn walls_toml(walls: &[ImportedWall], resolution: [u32; 2], source: &Path) -> String {
    let mut out = format!(
        "# Walls imported from {} by `omnicave config import` (CAVE space: metres, +y up).\n",
        source.display()
    );
    for w in walls {
        let p = |v: DVec3| format!("[{}, {}, {}]", number(v.x), number(v.y), number(v.z));
        let [rw, rh] = w.resolution.unwrap_or(resolution);
        out.push_str(&format!(
            "\n[[wall]]\nname = \"{}\"\nlower_left = {}\nlower_right = {}\nupper_left = {}\n\
             resolution = [{rw}, {rh}]\n",
            w.name,
            p(w.lower_left),
            p(w.lower_right),
            p(w.upper_left)
        ));
    }
    out
}

/// The keys that place a wall (replaced on import).
const GEOMETRY_KEYS: [&str; 10] = [
    "lower_left",
    "lower_right",
    "upper_left",
    "centre",
    "yaw_pitch_roll_degrees",
    "origin",
    "horizontal_axis",
    "vertical_axis",
    "size",
    "resolution",
];

/// `base` (a config's text) with its `[[wall]]` tables replaced by `walls` (its comments and
/// every other setting kept).
pub fn replace_walls(
    base: &str,
    walls: &[ImportedWall],
    resolution: [u32; 2],
) -> Result<String, String> {
    let mut doc: toml_edit::DocumentMut = base.parse().map_err(|e| format!("{e}"))?;
    // The base's walls by name (any case): a wall of the same name keeps its monitor, window
    // and output settings.
    let base_walls: Vec<toml_edit::Table> = doc
        .get("wall")
        .and_then(toml_edit::Item::as_array_of_tables)
        .map(|a| a.iter().cloned().collect())
        .unwrap_or_default();
    let mut tables = toml_edit::ArrayOfTables::new();
    for w in walls {
        let mut t = base_walls
            .iter()
            .find(|b| {
                b.get("name")
                    .and_then(toml_edit::Item::as_str)
                    .is_some_and(|n| n.eq_ignore_ascii_case(&w.name))
            })
            .cloned()
            .unwrap_or_default();
        for geometry in GEOMETRY_KEYS {
            t.remove(geometry);
        }
        let p = |v: DVec3| {
            let mut a = toml_edit::Array::new();
            for c in [v.x, v.y, v.z] {
                a.push(number(c).parse::<f64>().unwrap_or(c));
            }
            toml_edit::value(a)
        };
        t["name"] = toml_edit::value(w.name.clone());
        t["lower_left"] = p(w.lower_left);
        t["lower_right"] = p(w.lower_right);
        t["upper_left"] = p(w.upper_left);
        let [rw, rh] = w.resolution.unwrap_or(resolution);
        let mut r = toml_edit::Array::new();
        r.push(i64::from(rw));
        r.push(i64::from(rh));
        t["resolution"] = toml_edit::value(r);
        tables.push(t);
    }
    // The walls are in CAVE metres, y up, whatever the base said.
    if let Some(cave) = doc.get_mut("cave").and_then(toml_edit::Item::as_table_mut) {
        cave.remove("wall_units");
        cave.remove("wall_up_axis");
    }
    doc["wall"] = toml_edit::Item::ArrayOfTables(tables);
    Ok(doc.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_short_and_exact_to_a_micrometre() {
        assert_eq!(number(-1.65), "-1.65");
        assert_eq!(number(2.9000000000000004), "2.9");
        assert_eq!(number(-1e-17), "0.0");
        assert_eq!(number(3.0), "3.0");
    }

    #[test]
    fn names_are_made_acceptable() {
        assert_eq!(clean_name("screen front", "w"), "screen_front");
        assert_eq!(clean_name("  ", "wall3"), "wall3");
        let walls = ["a", "a", "a"]
            .map(|n| ImportedWall {
                name: n.into(),
                lower_left: DVec3::ZERO,
                lower_right: DVec3::X,
                upper_left: DVec3::Y,
                resolution: None,
            })
            .to_vec();
        let names: Vec<_> = unique_names(walls).into_iter().map(|w| w.name).collect();
        assert_eq!(names, ["a", "a_1", "a_2"]);
    }
}
