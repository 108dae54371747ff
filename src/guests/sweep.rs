//! The thesis's question as a sweep (Meindl 2015, 8.1): the sweet area per method against the
//! CAVE's size, the tracked head's distance to the front wall and the walls' resolution (the
//! pixel quantisation of disparity), over shells of points around the assumed head.

use glam::Vec3;

use super::grid::{Grid, MethodMap, Thresholds, drawn, sweet_reach};
use super::points::shells;
use super::{Gaze, Method, Setup};
use crate::cave::omni::PoleMerge;
use crate::cave::{Cave, Head};
use crate::output::chart::{Axes, ChartPoint};

/// What the sweep varies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Parameter {
    /// The CAVE scaled on the floor about its centre to this width (metres, 2–4), its walls'
    /// height kept.
    CaveSize,
    /// The tracked head this far from the front wall (metres), centred sideways.
    HeadToFrontWall,
    /// Every wall this many pixels wide (the height kept in proportion), wall points drawn at
    /// their pixel's centre.
    WallPixels,
}

crate::named_enum!(Parameter {
    Self::CaveSize => "cave-size-m",
    Self::HeadToFrontWall => "head-to-front-wall-m",
    Self::WallPixels => "wall-pixels-wide",
});

impl Parameter {
    /// The chart's x-axis label.
    pub fn axis_label(self) -> &'static str {
        match self {
            Parameter::CaveSize => "CAVE width and depth (m), the walls' height kept",
            Parameter::HeadToFrontWall => "tracked head's distance to the front wall (m)",
            Parameter::WallPixels => "pixels across each wall",
        }
    }
}

/// The sweep's sampling.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepSettings {
    /// Points on the shells, in all.
    pub points: usize,
    /// Shell radii around the assumed head, metres.
    pub radii: Vec<f64>,
    /// Grid cell size, metres.
    pub step: f64,
    pub limits: Thresholds,
}

impl Default for SweepSettings {
    fn default() -> Self {
        Self {
            points: 2000,
            radii: vec![1.0, 2.0, 4.0, 8.0],
            step: 0.1,
            limits: Thresholds::default(),
        }
    }
}

/// One method's sweet area at one value of one parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRow {
    pub parameter: Parameter,
    pub value: f64,
    pub method: Method,
    /// Within both limits, and within the vertical limit alone (areas within reach).
    pub sweet_area_m2: f64,
    pub fusion_area_m2: f64,
    pub floor_area_m2: f64,
    /// Of the shells' points, those the method draws on the walls for both eyes.
    pub shown_points: usize,
}

/// The room `cave` scaled on the floor about its centre so that its wider side is `width`
/// metres; the walls keep their height (a taller room would change which points are drawn at
/// all, not how a step distorts them).
pub fn scaled_cave(cave: &Cave, width: f32) -> Cave {
    let (lo, hi) = Cave::bounding_box(&cave.walls);
    let pivot = Vec3::new(0.5 * (lo.x + hi.x), 0.0, 0.5 * (lo.z + hi.z));
    let k = width / (hi.x - lo.x).max(hi.z - lo.z).max(1e-3);
    let scale = Vec3::new(k, 1.0, k);
    let mut out = cave.clone();
    for wall in &mut out.walls {
        for p in [
            &mut wall.lower_left,
            &mut wall.lower_right,
            &mut wall.upper_left,
        ] {
            *p = pivot + scale * (*p - pivot);
        }
    }
    out.projection_centre = pivot + scale * (cave.projection_centre - pivot);
    out
}

/// The wall the fixed-direction stereo faces (its normal most against the view direction).
fn front_wall(cave: &Cave) -> Option<&crate::cave::Wall> {
    cave.walls.iter().max_by(|a, b| {
        let f = |w: &crate::cave::Wall| -w.normal().dot(cave.stereo_view_direction);
        f(a).total_cmp(&f(b))
    })
}

/// Runs the sweep for `methods` from the base `cave` and tracked `head`.
pub fn run(
    cave: &Cave,
    head: Head,
    ipd: f64,
    pole_merge: Option<PoleMerge>,
    methods: &[Method],
    settings: &SweepSettings,
) -> Result<Vec<SweepRow>, String> {
    let mut rows = Vec::new();
    let mut measure = |parameter: Parameter, value: f64, cave: &Cave, head: Head, quantise| {
        let mut setup = Setup::new(cave, head, ipd, pole_merge);
        setup.quantise = quantise;
        let floor = Grid::over(cave, settings.step, f64::from(head.position.y))
            .map(|g| MethodMap::floor_area(&g))?;
        for &method in methods {
            let centre = setup.assumed_head(method.assumed).position.as_dvec3();
            let points = shells(centre, &settings.radii, settings.points);
            let drawn = drawn(&setup, method, &points);
            let area =
                |limits: &Thresholds| sweet_reach(&setup, &drawn, centre, Gaze::AtPoint, limits).1;
            rows.push(SweepRow {
                parameter,
                value,
                method,
                sweet_area_m2: area(&settings.limits),
                fusion_area_m2: area(&settings.limits.fusion_only()),
                floor_area_m2: floor,
                shown_points: drawn.len(),
            });
        }
        Ok::<(), String>(())
    };
    let (lo, hi) = Cave::bounding_box(&cave.walls);
    let mid = 0.5 * (lo + hi);
    for width in [2.0f32, 2.5, 3.0, 3.5, 4.0] {
        let room = scaled_cave(cave, width);
        let centred = Head {
            position: Vec3::new(mid.x, head.position.y, mid.z),
            ..head
        };
        measure(Parameter::CaveSize, f64::from(width), &room, centred, false)?;
    }
    if let Some(front) = front_wall(cave) {
        // From 0.3 m to the back of the room, in six steps (the open back of a three-wall
        // CAVE is its walls' bounding box).
        let n = front.normal();
        let depth = cave
            .walls
            .iter()
            .flat_map(|w| w.corners())
            .map(|c| front.signed_distance(c))
            .fold(0.0f32, f32::max);
        let centre = front.centre();
        for k in 0..6 {
            let d = 0.3 + (depth - 0.4).max(0.0) * k as f32 / 5.0;
            let mut p = centre + d * n;
            p.y = head.position.y;
            measure(
                Parameter::HeadToFrontWall,
                (f64::from(d) * 1000.0).round() / 1000.0,
                cave,
                Head {
                    position: p,
                    ..head
                },
                false,
            )?;
        }
    }
    for wide in [480u32, 960, 1280, 1920, 3840] {
        let mut room = cave.clone();
        for wall in &mut room.walls {
            let aspect = wall.resolution[1] as f32 / wall.resolution[0].max(1) as f32;
            wall.resolution = [wide, ((wide as f32 * aspect).round() as u32).max(1)];
        }
        measure(Parameter::WallPixels, f64::from(wide), &room, head, true)?;
    }
    Ok(rows)
}

/// The chart points of one parameter, one series per method: the sweet area, or with
/// `fusion` the area within the vertical limit alone.
pub fn chart_points(rows: &[SweepRow], parameter: Parameter, fusion: bool) -> Vec<ChartPoint> {
    rows.iter()
        .filter(|r| r.parameter == parameter)
        .map(|r| ChartPoint {
            family: r.method.name(),
            label: String::new(),
            x: r.value,
            y: if fusion {
                r.fusion_area_m2
            } else {
                r.sweet_area_m2
            },
        })
        .collect()
}

/// The chart's axes for one parameter.
pub fn axes(parameter: Parameter, fusion: bool) -> Axes {
    let y = if fusion {
        "area within the vertical limit (m²)"
    } else {
        "sweet area (m²)"
    };
    Axes::linear(parameter.axis_label(), y)
}

/// Where a viewer may stand, as a distance: the radius of a disc with the sweet area.
pub fn equivalent_radius(area_m2: f64) -> f64 {
    (area_m2 / std::f64::consts::PI).sqrt()
}
