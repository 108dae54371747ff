//! `omnicave guests`: a config and a scene in, the maps out (heat maps as PNG, the grid as
//! CSV, the sweet area per method as Markdown and CSV), and the sweep when asked.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::DVec3;

use super::grid::{
    Grid, MAX_JUDGEMENTS, MethodMap, REACH_DIRECTIONS, REACH_STEP_M, Thresholds,
    compute_each_assumed,
};
use super::heatmap::{Metric, Scale, svg};
use super::sweep::{self, Parameter, SweepRow, SweepSettings};
use super::{Gaze, Method, Setup, points};
use crate::config::{Config, ConfigError};
use crate::scene::SceneError;

/// Anything that stops `omnicave guests`.
#[derive(Debug, thiserror::Error)]
pub enum GuestsError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error("{0}")]
    Invalid(String),
    #[error("cannot write {path}: {message}")]
    Write { path: PathBuf, message: String },
}

/// Where the judged points come from.
#[derive(Debug, Clone, PartialEq)]
pub enum PointSource {
    /// What the assumed head sees of the scene (the config's, or this file): `count` rays.
    Scene(Option<PathBuf>),
    /// Shells of these radii (metres) around the assumed head.
    Shells(Vec<f64>),
}

/// Fewer scene points than this make percentiles a guess: `guests` warns (a model at its
/// authored size, a few centimetres, seen from the head).
pub const MIN_POINTS_WORTH_A_MAP: usize = 100;

/// Most viewer eye heights one run maps.
pub const MAX_EYE_HEIGHTS: usize = 8;

/// What `omnicave guests` was asked for.
#[derive(Debug, Clone, PartialEq)]
pub struct GuestsRequest {
    pub config: PathBuf,
    pub source: PointSource,
    /// Scene points judged (directions cast, or points on the shells), at most
    /// [`super::grid::MAX_POINTS`].
    pub points: usize,
    pub methods: Vec<Method>,
    /// Grid cell size, metres.
    pub step: f64,
    /// Viewer eye heights; empty: the tracked head's.
    pub eye_heights: Vec<f64>,
    pub head: Option<glam::Vec3>,
    pub head_yaw_degrees: Option<f32>,
    pub ipd: Option<f64>,
    pub limits: Thresholds,
    /// Wall points drawn at their pixel's centre.
    pub quantise: bool,
    /// Also run the sweep (CAVE size, head distance, resolution).
    pub sweep: bool,
    pub threads: usize,
    pub out: PathBuf,
}

/// One method's sweet area at one eye height.
#[derive(Debug, Clone, PartialEq)]
pub struct SweetArea {
    pub method: Method,
    pub eye_height: f64,
    pub sweet_area_m2: f64,
    pub floor_area_m2: f64,
    pub shown_points: usize,
    /// How far from the assumed head a viewer stays within the limits: the least, median and
    /// most over the directions walked (metres), and the area they bound (m²).
    pub reach_min_m: f64,
    pub reach_median_m: f64,
    pub reach_max_m: f64,
    pub reach_area_m2: f64,
    /// The grid's area and the area within reach under the vertical limit alone.
    pub fusable_area_m2: f64,
    pub fusion_reach_area_m2: f64,
}

/// What a run found and wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct GuestsOutcome {
    pub areas: Vec<SweetArea>,
    /// Points judged, viewer cells inside the CAVE (per eye height), and the maps' time.
    pub points: usize,
    pub cells: usize,
    pub map_seconds: f64,
    pub sweep: Vec<SweepRow>,
    pub files: Vec<PathBuf>,
}

/// Runs `omnicave guests`.
pub fn run(request: &GuestsRequest) -> Result<GuestsOutcome, GuestsError> {
    let loaded = Config::load(&request.config)?;
    let mut settings = loaded.settings;
    if let Some(p) = request.head {
        settings.head.position = p.to_array();
    }
    if let Some(yaw) = request.head_yaw_degrees {
        settings.head.yaw_degrees = yaw;
    }
    let config = settings.validate(&request.config)?;
    let cave = &config.cave;
    let head = config.settings.head();
    let ipd = request
        .ipd
        .unwrap_or(f64::from(config.settings.cave.eye_separation));
    if !(ipd.is_finite() && (0.0..=0.2).contains(&ipd)) {
        return Err(GuestsError::Invalid(format!(
            "eye separation {ipd} m must be 0 to 0.2 m"
        )));
    }
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !(positive(request.limits.vertical_arcmin) && positive(request.limits.direction_degrees)) {
        return Err(GuestsError::Invalid(format!(
            "limits {} arcmin and {}° must be positive",
            request.limits.vertical_arcmin, request.limits.direction_degrees
        )));
    }
    if request.methods.is_empty() {
        return Err(GuestsError::Invalid("no method to map".into()));
    }
    if request.points == 0 || request.points > super::grid::MAX_POINTS {
        return Err(GuestsError::Invalid(format!(
            "{} points: give 1 to {}",
            request.points,
            super::grid::MAX_POINTS
        )));
    }
    if request.eye_heights.len() > MAX_EYE_HEIGHTS {
        return Err(GuestsError::Invalid(format!(
            "{} eye heights: at most {MAX_EYE_HEIGHTS}",
            request.eye_heights.len()
        )));
    }
    let pole = config.settings.omni().pole_merge;
    let mut setup = Setup::new(cave, head, ipd, pole);
    setup.quantise = request.quantise;
    let heights = if request.eye_heights.is_empty() {
        vec![f64::from(head.position.y)]
    } else {
        request.eye_heights.clone()
    };
    let (lo, hi) = crate::cave::Cave::head_bounds(&cave.walls);
    if let Some(bad) = heights
        .iter()
        .find(|h| !(h.is_finite() && (f64::from(lo.y)..=f64::from(hi.y)).contains(*h)))
    {
        return Err(GuestsError::Invalid(format!(
            "eye height {bad} m is outside the CAVE ({:.2} to {:.2} m)",
            lo.y, hi.y
        )));
    }
    if let PointSource::Shells(radii) = &request.source
        && radii
            .iter()
            .any(|r| !(r.is_finite() && *r > 0.0 && *r <= 1e4))
    {
        return Err(GuestsError::Invalid(format!(
            "shell radii {radii:?} must be positive distances up to 10 km"
        )));
    }
    let far = f64::from(cave.far);
    // The points for each assumed head (each is judged from where its method renders).
    let scene = match &request.source {
        PointSource::Scene(path) => {
            let path = path
                .clone()
                .or_else(|| config.scene_path.clone())
                .ok_or_else(|| {
                    GuestsError::Invalid(format!(
                        "no scene: pass --scene, --shells or set [scene] path in {}",
                        request.config.display()
                    ))
                })?;
            Some(crate::setup::load_scene(&config.settings, &path)?)
        }
        PointSource::Shells(_) => None,
    };
    let cave_from_world = config.settings.world_from_cave().inverse();
    let points_for = |centre: DVec3| match (&request.source, &scene) {
        (PointSource::Shells(radii), _) => points::shells(centre, radii, request.points),
        (_, Some(scene)) => {
            points::visible_surface(scene, cave_from_world, centre, request.points, far)
        }
        _ => Vec::new(),
    };
    crate::output::ensure_dir(&request.out).map_err(|e| GuestsError::Write {
        path: request.out.clone(),
        message: e.to_string(),
    })?;
    let mut files = Vec::new();
    let mut areas = Vec::new();
    let mut csv_rows = Vec::new();
    let mut cells = 0;
    let mut judged_points = 0;
    let mut map_seconds = 0.0;
    let distinct = {
        let mut rules: Vec<_> = request.methods.iter().map(Method::eye_rule).collect();
        rules.sort_by_key(|(mode, assumed)| (mode.name(), assumed.name()));
        rules.dedup();
        rules.len() as u64
    };
    for &height in &heights {
        let grid = Grid::over(cave, request.step, height).map_err(GuestsError::Invalid)?;
        // Each distinct method also walks its reach twice (sweet and fusion): at most
        // REACH_DIRECTIONS × (the floor's diagonal in steps + 6 bisections) viewers each.
        let [[x0, z0], [x1, z1]] = grid.bounds;
        let walk = ((x1 - x0).hypot(z1 - z0) / REACH_STEP_M).ceil() as u64 + 6;
        let viewers = grid.inside.len() as u64 + 2 * REACH_DIRECTIONS as u64 * walk;
        let judgements = viewers * request.points as u64 * distinct * heights.len() as u64;
        if judgements > MAX_JUDGEMENTS {
            return Err(GuestsError::Invalid(format!(
                "{viewers} viewer positions (grid and reach) × {} points × {distinct} distinct methods × {} eye heights is {judgements} judgements, over the {MAX_JUDGEMENTS} allowed: a coarser --step or fewer --points",
                request.points,
                heights.len()
            )));
        }
        cells = grid.inside.iter().filter(|i| **i).count();
        // The points each assumed head sees are cast and judged inside the time reported.
        let timer = Instant::now();
        let (maps, most) = compute_each_assumed(
            &setup,
            &request.methods,
            points_for,
            &grid,
            Gaze::AtPoint,
            &request.limits,
            request.threads,
        );
        map_seconds += timer.elapsed().as_secs_f64();
        judged_points = judged_points.max(most);
        if most < MIN_POINTS_WORTH_A_MAP && matches!(request.source, PointSource::Scene(_)) {
            tracing::warn!(
                "only {most} of {} rays from the head meet the scene: its percentiles say little; \
                 place the model in the CAVE ([scene] fit, size_m, offset_m) or judge --shells",
                request.points
            );
        }
        let suffix = if heights.len() > 1 {
            format!("-h{height:.2}")
        } else {
            String::new()
        };
        for metric in Metric::ALL {
            let scale = Scale::shared(metric, &maps, &request.limits);
            for map in &maps {
                let assumed = setup.assumed_head(map.method.assumed).position.as_dvec3();
                let drawn = svg(cave, &grid, map, &scale, assumed, &request.limits);
                let name = format!(
                    "map-{}-{}{suffix}.png",
                    map.method.name().replace('@', "-at-"),
                    metric.name()
                );
                files.push(write_svg_png(&request.out, &name, &drawn)?);
            }
        }
        for map in &maps {
            areas.push(SweetArea {
                method: map.method,
                eye_height: height,
                sweet_area_m2: map.sweet_area(&grid, &request.limits),
                floor_area_m2: MethodMap::floor_area(&grid),
                shown_points: map.shown_points,
                reach_min_m: map.reach_m.iter().copied().fold(f64::INFINITY, f64::min),
                reach_median_m: super::grid::percentile(&mut map.reach_m.clone(), 0.5),
                reach_max_m: map.reach_m.iter().copied().fold(0.0, f64::max),
                reach_area_m2: map.reach_area_m2,
                fusable_area_m2: map.sweet_area(&grid, &request.limits.fusion_only()),
                fusion_reach_area_m2: map.fusion_reach_area_m2,
            });
            for (cell, figures) in map.cells.iter().enumerate() {
                if !grid.inside[cell] {
                    continue;
                }
                let g = grid.viewer(cell);
                csv_rows.push(GridRow::of(map, g, figures.as_ref(), &request.limits));
            }
        }
    }
    let path = request.out.join("grid.csv");
    write_csv(&path, &csv_rows)?;
    files.push(path);
    let sweep = if request.sweep {
        let settings = SweepSettings {
            limits: request.limits,
            ..SweepSettings::default()
        };
        let rows = sweep::run(cave, head, ipd, pole, &request.methods, &settings)
            .map_err(GuestsError::Invalid)?;
        files.extend(write_sweep(&request.out, &rows)?);
        rows
    } else {
        Vec::new()
    };
    let outcome = GuestsOutcome {
        areas,
        points: judged_points,
        cells,
        map_seconds,
        sweep,
        files,
    };
    let summary = summary_markdown(&outcome, &request.limits, &config.source);
    let path = request.out.join("summary.md");
    write_text(&path, &summary)?;
    let mut outcome = outcome;
    outcome.files.push(path);
    let path = request.out.join("summary.csv");
    let rows: Vec<SummaryRow> = outcome.areas.iter().map(SummaryRow::of).collect();
    write_csv(&path, &rows)?;
    outcome.files.push(path);
    Ok(outcome)
}

/// One line of `grid.csv`.
#[derive(Debug, serde::Serialize)]
struct GridRow {
    method: String,
    /// The computation the row comes from: the other omnistereo mode's rows are the same.
    computed_as: String,
    x_m: f64,
    z_m: f64,
    eye_height_m: f64,
    seen_points: usize,
    vertical_p95_arcmin: f64,
    direction_p95_arcmin: f64,
    horizontal_p95_arcmin: f64,
    depth_ratio_p5: f64,
    depth_ratio_median: f64,
    depth_ratio_p95: f64,
    within_limits: bool,
}

impl GridRow {
    fn of(
        map: &MethodMap,
        g: DVec3,
        f: Option<&super::grid::ViewerFigures>,
        limits: &Thresholds,
    ) -> Self {
        let v = |get: fn(&super::grid::ViewerFigures) -> f64| f.map_or(f64::NAN, get);
        Self {
            method: map.method.name(),
            computed_as: map.computed_as.name(),
            x_m: g.x,
            z_m: g.z,
            eye_height_m: g.y,
            seen_points: f.map_or(0, |f| f.seen),
            vertical_p95_arcmin: v(|f| f.vertical_p95),
            direction_p95_arcmin: v(|f| f.direction_p95),
            horizontal_p95_arcmin: v(|f| f.horizontal_p95),
            depth_ratio_p5: v(|f| f.depth_p5),
            depth_ratio_median: v(|f| f.depth_median),
            depth_ratio_p95: v(|f| f.depth_p95),
            within_limits: f.is_some_and(|f| f.within(limits)),
        }
    }
}

/// One line of `summary.csv`.
#[derive(Debug, serde::Serialize)]
struct SummaryRow {
    method: String,
    eye_height_m: f64,
    sweet_area_m2: f64,
    floor_area_m2: f64,
    sweet_fraction: f64,
    reach_min_m: f64,
    reach_median_m: f64,
    reach_max_m: f64,
    reach_area_m2: f64,
    fusable_area_m2: f64,
    fusion_reach_area_m2: f64,
    shown_points: usize,
}

impl SummaryRow {
    fn of(a: &SweetArea) -> Self {
        Self {
            method: a.method.name(),
            eye_height_m: a.eye_height,
            sweet_area_m2: a.sweet_area_m2,
            floor_area_m2: a.floor_area_m2,
            sweet_fraction: a.sweet_area_m2 / a.floor_area_m2.max(1e-12),
            reach_min_m: a.reach_min_m,
            reach_median_m: a.reach_median_m,
            reach_max_m: a.reach_max_m,
            reach_area_m2: a.reach_area_m2,
            fusable_area_m2: a.fusable_area_m2,
            fusion_reach_area_m2: a.fusion_reach_area_m2,
            shown_points: a.shown_points,
        }
    }
}

/// One line of `sweep.csv`.
#[derive(Debug, serde::Serialize)]
struct SweepLine {
    parameter: &'static str,
    value: f64,
    method: String,
    sweet_area_m2: f64,
    fusion_area_m2: f64,
    floor_area_m2: f64,
    shown_points: usize,
}

fn write_csv<T: serde::Serialize>(path: &Path, rows: &[T]) -> Result<(), GuestsError> {
    let fail = |message: String| GuestsError::Write {
        path: path.to_owned(),
        message,
    };
    let mut w = csv::Writer::from_path(path).map_err(|e| fail(e.to_string()))?;
    for row in rows {
        w.serialize(row).map_err(|e| fail(e.to_string()))?;
    }
    w.flush().map_err(|e| fail(e.to_string()))
}

fn write_text(path: &Path, text: &str) -> Result<(), GuestsError> {
    std::fs::write(path, text).map_err(|e| GuestsError::Write {
        path: path.to_owned(),
        message: e.to_string(),
    })
}

fn write_svg_png(dir: &Path, name: &str, svg: &str) -> Result<PathBuf, GuestsError> {
    let path = dir.join(name);
    let png = crate::output::chart::png(svg).map_err(|message| GuestsError::Write {
        path: path.clone(),
        message,
    })?;
    std::fs::write(&path, png).map_err(|e| GuestsError::Write {
        path: path.clone(),
        message: e.to_string(),
    })?;
    Ok(path)
}

/// `sweep.csv` and one chart per parameter.
pub fn write_sweep(dir: &Path, rows: &[SweepRow]) -> Result<Vec<PathBuf>, GuestsError> {
    let mut files = Vec::new();
    let path = dir.join("sweep.csv");
    let lines: Vec<SweepLine> = rows
        .iter()
        .map(|r| SweepLine {
            parameter: r.parameter.name(),
            value: r.value,
            method: r.method.name(),
            sweet_area_m2: r.sweet_area_m2,
            fusion_area_m2: r.fusion_area_m2,
            floor_area_m2: r.floor_area_m2,
            shown_points: r.shown_points,
        })
        .collect();
    write_csv(&path, &lines)?;
    files.push(path);
    for parameter in Parameter::ALL {
        for fusion in [false, true] {
            let points = sweep::chart_points(rows, parameter, fusion);
            if points.is_empty() {
                continue;
            }
            let (title, subtitle, suffix) = if fusion {
                (
                    "Area within the vertical limit against",
                    "floor within reach of the assumed head where p95 vertical disparity < the limit",
                    "-fusion",
                )
            } else {
                (
                    "Sweet area against",
                    "floor within reach of the assumed head where p95 vertical disparity and direction error < the limits",
                    "",
                )
            };
            let chart = crate::output::chart::svg(
                &points,
                &sweep::axes(parameter, fusion),
                &format!("{title} {}", parameter.axis_label()),
                subtitle,
            );
            let name = format!("sweep-{}{suffix}.png", parameter.name());
            files.push(write_svg_png(dir, &name, &chart)?);
        }
    }
    Ok(files)
}

/// `summary.md`: the sweet area per method and the run's figures.
fn summary_markdown(outcome: &GuestsOutcome, limits: &Thresholds, config: &Path) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "# Where guests may stand\n");
    let _ = writeln!(
        s,
        "Config `{}`; {} scene points; {} viewer positions per eye height; the maps took {:.2} s.\n",
        config.display(),
        outcome.points,
        outcome.cells,
        outcome.map_seconds
    );
    let _ = writeln!(
        s,
        "Sweet area: the floor where the 95th percentile of vertical disparity stays under {} arcmin and that of the direction error under {}°.\n",
        limits.vertical_arcmin, limits.direction_degrees
    );
    let _ = writeln!(
        s,
        "The grid's area counts the cells (their part inside the room); the reach walks {} directions from the assumed head to the first viewer outside the limits (to under a millimetre), so it resolves areas smaller than a cell. Depth ratios are infinite where a guest's rays diverge; a position that sees nothing has no figures.\n",
        super::grid::REACH_DIRECTIONS
    );
    let _ = writeln!(
        s,
        "| method | eye height (m) | sweet area, grid (m²) | reach least / median / most (m) | sweet area within reach (m²) | fusion area, grid (m²) | of the floor | fusion area within reach (m²) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    for a in &outcome.areas {
        let _ = writeln!(
            s,
            "| {} | {:.2} | {:.2} | {:.3} / {:.3} / {:.3} | {:.4} | {:.2} | {:.0} % | {:.3} |",
            a.method.name(),
            a.eye_height,
            a.sweet_area_m2,
            a.reach_min_m,
            a.reach_median_m,
            a.reach_max_m,
            a.reach_area_m2,
            a.fusable_area_m2,
            100.0 * a.fusable_area_m2 / a.floor_area_m2.max(1e-12),
            a.fusion_reach_area_m2
        );
    }
    if !outcome.sweep.is_empty() {
        let _ = writeln!(
            s,
            "\n## The sweep\n\nShells at 1, 2, 4 and 8 m around the assumed head; areas within reach; the fusion area under the vertical limit alone.\n"
        );
        let _ = writeln!(
            s,
            "| parameter | value | method | sweet area (m²) | fusion area (m²) |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|");
        for r in &outcome.sweep {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.4} | {:.3} |",
                r.parameter.name(),
                r.value,
                r.method.name(),
                r.sweet_area_m2,
                r.fusion_area_m2
            );
        }
    }
    s
}
