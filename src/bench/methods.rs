//! The rendering methods the bench compares, and the clock their times come from.

use std::fmt::Write as _;

use super::BenchError;
use crate::cave::RenderMode;
use crate::scene::Shading;
use crate::sky::SkyMode;
use crate::tess::criteria::parse_criterion;
use crate::tess::{Criterion, TessSettings};

/// One way of rendering a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Method {
    pub name: String,
    pub mode: RenderMode,
    pub tess: TessSettings,
    /// `None`: no sky.
    pub sky: Option<SkyMode>,
    pub shading: Shading,
    pub shadows: MethodShadows,
}

/// How a method draws the config's shadows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MethodShadows {
    /// As the config says.
    Config,
    /// Not at all.
    Off,
    /// As the config says, but the 3×3 filter gathers at every point (no range test).
    FilterEverywhere,
}

/// A criterion from its parameter, and the parameters swept.
type Sweep = (fn(f32) -> Criterion, &'static [f32]);

/// Parameters of each tessellation criterion the bench sweeps (a full run; `--quick` takes
/// every other one), coarse to fine. Each sweep starts coarse enough to miss the exactness
/// target on some scene and size (at its coarse end a criterion splits little beyond the
/// edges it must follow to the clip boundary), so that the cheapest exact method is where
/// accuracy runs out, not where the sweep happened to stop: with the coarsest at `error:4`,
/// `edge:64` and `sphere:64`, every swept setting was exact on the living room at `--quick`.
const SWEEP: [Sweep; 4] = [
    (
        Criterion::Error,
        &[32.0, 16.0, 8.0, 4.0, 2.0, 1.0, 0.5, 0.25],
    ),
    (
        |px| Criterion::Edge(px),
        &[256.0, 128.0, 64.0, 32.0, 16.0, 8.0],
    ),
    (
        |px| Criterion::Sphere(px),
        &[512.0, 256.0, 128.0, 64.0, 32.0, 16.0, 8.0],
    ),
    (|n| Criterion::Uniform(n as u32), &[1.0, 2.0, 3.0]),
];

/// The control for the cost of triangles as such: the reference's picture drawn with four
/// times its triangles (and the tessellator's stages). What a tessellated method pays for
/// the triangles it adds, apart from its warp; on a software rasteriser, which shades whole
/// blocks along every triangle's border, most of what separates the exact methods from
/// stereo.
pub const TRIANGLE_CONTROL: &str = "stereo + tess uniform:1";

/// The methods compared, the reference (plain off-axis stereo, no sky) first: mono, stereo,
/// both omnistereo warps without tessellation, the off-axis warp with each criterion at
/// several parameters, and the sky modes. Every method tessellates with `base` (the config's
/// `[tessellation]`: maximum depth, culling, drawing fine clusters directly) and its own
/// criterion; `base`'s criterion is ignored.
pub fn methods(quick: bool, base: TessSettings) -> Vec<Method> {
    let m = |mode: RenderMode, tess: TessSettings, sky: Option<SkyMode>| {
        let mut name = mode.name().to_owned();
        if let Some(c) = tess.criterion {
            let _ = write!(name, " + tess {c}");
        }
        if let Some(s) = sky {
            let _ = write!(name, " + sky {s}");
        }
        Method {
            name,
            mode,
            tess,
            sky,
            shading: Shading::Pbr,
            shadows: MethodShadows::Config,
        }
    };
    let none = TessSettings {
        criterion: None,
        ..base
    };
    let with = |c: Criterion| TessSettings {
        criterion: Some(c),
        ..base
    };
    // What the physically based shading costs: stereo with the simple model it replaced.
    let simple = Method {
        name: "stereo + shading simple".into(),
        shading: Shading::Simple,
        ..m(RenderMode::Stereo, none, None)
    };
    // And what the shadows cost (where the config's lights cast any).
    let unshadowed = Method {
        name: "stereo + shadows off".into(),
        shadows: MethodShadows::Off,
        ..m(RenderMode::Stereo, none, None)
    };
    // And what the filter's range test saves (where they are filtered).
    let filtered = Method {
        name: "stereo + shadow range test off".into(),
        shadows: MethodShadows::FilterEverywhere,
        ..m(RenderMode::Stereo, none, None)
    };
    let mut out = vec![
        m(RenderMode::Stereo, none, None),
        simple,
        unshadowed,
        filtered,
        // And what triangles cost the rasteriser: stereo's picture, through the tessellator
        // with every triangle cut in four and no warp (see [`TRIANGLE_CONTROL`]).
        m(RenderMode::Stereo, with(Criterion::Uniform(1)), None),
        m(RenderMode::Mono, none, None),
        m(RenderMode::Stereo, none, Some(SkyMode::Offaxis)),
        m(RenderMode::OmniOnAxis, none, None),
        m(RenderMode::OmniOffAxis, none, None),
        m(RenderMode::OmniOffAxis, none, Some(SkyMode::Offaxis)),
        m(RenderMode::OmniOffAxis, none, Some(SkyMode::OmniQuad)),
        m(RenderMode::OmniOffAxis, none, Some(SkyMode::OmniExact)),
        m(
            RenderMode::OmniOffAxis,
            with(Criterion::Error(0.5)),
            Some(SkyMode::OmniExact),
        ),
    ];
    for (criterion, values) in SWEEP {
        for (i, &v) in values.iter().enumerate() {
            if !quick || i % 2 == 0 || v == 0.5 {
                out.push(m(RenderMode::OmniOffAxis, with(criterion(v)), None));
            }
        }
    }
    out
}

/// The methods named in `names`, after the reference (plain stereo), which every ratio needs;
/// all of them when `names` is empty. A name is one the report writes, or any render mode
/// with any criterion, `MODE + tess CRITERION` (e.g. `omni-offaxis + tess error:3`),
/// tessellated with `base` as [`methods`] does.
pub fn select_methods(
    all: Vec<Method>,
    names: &[String],
    base: TessSettings,
) -> Result<Vec<Method>, BenchError> {
    let Some(reference) = all.first().filter(|_| !names.is_empty()) else {
        return Ok(all);
    };
    let mut picked = vec![reference.clone()];
    for name in names {
        let method = match all.iter().find(|m| &m.name == name) {
            Some(m) => m.clone(),
            None => parse_method(name, base).ok_or_else(|| BenchError::UnknownMethod {
                name: name.clone(),
                known: all
                    .iter()
                    .map(|m| format!("'{}'", m.name))
                    .collect::<Vec<_>>()
                    .join(", "),
            })?,
        };
        if !picked.contains(&method) {
            picked.push(method);
        }
    }
    Ok(picked)
}

/// `MODE + tess CRITERION` as a method (no sky, physically based shading, shadows on).
fn parse_method(name: &str, base: TessSettings) -> Option<Method> {
    let (mode, criterion) = name.split_once(" + tess ")?;
    let criterion = parse_criterion(criterion).ok()??;
    Some(Method {
        name: name.to_owned(),
        mode: RenderMode::from_name(mode)?,
        tess: TessSettings {
            criterion: Some(criterion),
            ..base
        },
        sky: None,
        shading: Shading::Pbr,
        shadows: MethodShadows::Config,
    })
}

/// The methods' family for the chart: render mode and criterion kind (a series whose points
/// are the criterion's parameters).
pub fn family(m: &Method) -> String {
    if m.shading != Shading::Pbr || m.shadows != MethodShadows::Config {
        return m.name.clone();
    }
    match m.tess.criterion {
        None => m.mode.name().to_owned(),
        Some(c) => {
            let text = c.to_string();
            let kind = text.split(':').next().unwrap_or("");
            format!("{} + tess {kind}", m.mode.name())
        }
    }
}

/// The reference render for the image comparison: the off-axis warp tessellated until the
/// geometric error is below 0.05 px (DESIGN.md's reference) with the config's `base`
/// settings, at least 12 levels deep (deep enough for the city's ground quad near the
/// viewer) and never shallower than the methods it judges.
pub fn reference_method(base: TessSettings) -> Method {
    let max_depth = base.max_depth.max(12);
    Method {
        name: format!("reference: omni-offaxis + tess error:0.05, depth {max_depth}"),
        mode: RenderMode::OmniOffAxis,
        tess: TessSettings {
            criterion: Some(Criterion::Error(0.05)),
            max_depth,
            ..base
        },
        sky: None,
        shading: Shading::Pbr,
        shadows: MethodShadows::Config,
    }
}

/// Which clock a time came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Timer {
    /// GPU timestamps around the frame's work.
    Gpu,
    /// Wall clock from the start of encoding to the GPU finishing.
    Wall,
}

impl Timer {
    pub fn name(self) -> &'static str {
        match self {
            Self::Gpu => "gpu-timestamps",
            Self::Wall => "wall-clock",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn methods_start_with_the_reference_and_cover_every_sky_mode() {
        let m = methods(false, TessSettings::default());
        assert_eq!(m[0].mode, RenderMode::Stereo);
        assert!(m[0].sky.is_none() && m[0].tess.criterion.is_none());
        for sky in [SkyMode::Offaxis, SkyMode::OmniQuad, SkyMode::OmniExact] {
            assert!(m.iter().any(|x| x.sky == Some(sky)));
        }
        // The triangle control, in both lists: stereo, no sky, every triangle cut in four.
        for quick in [false, true] {
            let all = methods(quick, TessSettings::default());
            let control = all
                .iter()
                .find(|x| x.name == TRIANGLE_CONTROL)
                .expect("the triangle control");
            assert_eq!(control.mode, RenderMode::Stereo);
            assert_eq!(control.tess.criterion, Some(Criterion::Uniform(1)));
            assert!(control.sky.is_none() && control.shadows == MethodShadows::Config);
            assert_eq!(control.shading, Shading::Pbr);
            let mut names: Vec<&str> = all.iter().map(|x| x.name.as_str()).collect();
            names.sort_unstable();
            names.dedup();
            assert_eq!(names.len(), all.len(), "method names are unique");
        }
    }

    #[test]
    fn a_selection_keeps_the_reference_and_refuses_unknown_names() {
        let all = methods(true, TessSettings::default());
        let base = TessSettings::default();
        let picked = select_methods(all.clone(), &["omni-offaxis + tess edge:64".into()], base)
            .expect("known name");
        let names: Vec<&str> = picked.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["stereo", "omni-offaxis + tess edge:64"]);
        assert_eq!(
            select_methods(all.clone(), &[], base).expect("all").len(),
            all.len()
        );
        // Any mode with any criterion, parsed.
        let own = select_methods(all.clone(), &["omni-onaxis + tess error:3".into()], base)
            .expect("a mode and a criterion");
        assert_eq!(own[1].mode, RenderMode::OmniOnAxis);
        assert_eq!(own[1].tess.criterion, Some(Criterion::Error(3.0)));
        let e = select_methods(all, &["edge:64".into()], base).expect_err("unknown name");
        let text = e.to_string();
        assert!(text.contains("'edge:64'") && text.contains("'omni-offaxis + tess edge:64'"));
    }

    #[test]
    fn methods_tessellate_with_the_configs_settings_and_their_own_criterion() {
        let base = TessSettings {
            criterion: Some(Criterion::Edge(5.0)),
            max_depth: 14,
            backface_cull: false,
            frustum_cull: false,
            skip_fine: false,
            shared_eyes: false,
        };
        let all = methods(true, base);
        for m in &all {
            assert_eq!(m.tess.max_depth, 14, "{}", m.name);
            assert!(!m.tess.backface_cull && !m.tess.frustum_cull && !m.tess.skip_fine);
            assert!(!m.tess.shared_eyes);
        }
        // The config's criterion is not a method's: the reference stays untessellated.
        assert_eq!(all[0].tess.criterion, None);
        let parsed = select_methods(all, &["omni-offaxis + tess error:3".into()], base)
            .expect("a mode and a criterion");
        assert_eq!(parsed[1].tess.criterion, Some(Criterion::Error(3.0)));
        assert_eq!(parsed[1].tess.max_depth, 14);
    }
}
