//! The bench's reports: `results.csv`, `report.md` (frame times, sky costs, accuracy, the
//! overhead question and scaling with scene size) and their charts.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::accuracy::Accuracy;
use super::chart;
use super::error::BenchError;
use super::measure::{Row, STAGE_COLUMNS, VISIBLE_DIFFERENCE, percentile, stage_names};
use super::methods::{Method, MethodShadows, family};
use super::options::BenchOptions;
use crate::cave::RenderMode;
use crate::config::Config;
use crate::render::frame_timer::ViewStage;
use crate::scene::Shading;
use crate::sky::SkyMode;

/// Writes a CSV table: a header and rows of cells (quoted where a cell needs it, so a scene
/// name with a comma stays one cell).
pub(super) fn write_csv(
    path: &Path,
    header: &[&str],
    rows: impl IntoIterator<Item = Vec<String>>,
) -> Result<(), BenchError> {
    let fail = |e: csv::Error| BenchError::Csv {
        path: path.to_owned(),
        message: e.to_string(),
    };
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(header).map_err(fail)?;
    for row in rows {
        writer.write_record(&row).map_err(fail)?;
    }
    let bytes = writer.into_inner().map_err(|e| BenchError::Csv {
        path: path.to_owned(),
        message: e.to_string(),
    })?;
    std::fs::write(path, bytes).map_err(|source| BenchError::Write {
        path: path.to_owned(),
        source,
    })
}

pub(super) fn write_file(path: &Path, text: &str) -> Result<(), BenchError> {
    std::fs::write(path, text).map_err(|source| BenchError::Write {
        path: path.to_owned(),
        source,
    })
}

/// The row of the same case and render mode without a sky (for sky ratios) or the case's
/// reference method (plain stereo).
fn find<'a>(rows: &'a [Row], like: &Row, pred: impl Fn(&Method) -> bool) -> Option<&'a Row> {
    rows.iter().find(|r| {
        r.scene == like.scene
            && r.viewpoint == like.viewpoint
            && r.head == like.head
            && pred(&r.method)
    })
}

/// The columns of `results.csv`, in order.
const RESULT_HEADER: &[&str] = &[
    "scene",
    "viewpoint",
    "head",
    "method",
    "mode",
    "tessellation",
    "sky",
    "frames",
    "timer",
    "median_ms",
    "p25_ms",
    "p75_ms",
    "min_ms",
    "max_ms",
    "wall_median_ms",
    "input_triangles",
    "drawn_triangles",
    "ratio_to_stereo",
    "ratio_to_no_sky",
    "error_max_px",
    "error_p99_px",
    "error_samples",
    "cpu_input_triangles",
    "cpu_culled_triangles",
    "cpu_drawn_triangles",
    "cpu_edge_px",
    "image_diff_pct",
    "seam_max_px",
    "seam_p99_px",
    "seam_crossings",
    "pose_ms",
    "shadows_ms",
    "tess_cull_ms",
    "tess_split_ms",
    "tess_sort_ms",
    "scene_ms",
    "sky_ms",
    "resolve_ms",
    "dispatches",
    "refined_input_triangles",
];

/// Plain off-axis stereo of the same case; none for an empty scene, whose reference frame
/// would be a bare clear.
fn reference_row<'a>(rows: &'a [Row], r: &Row) -> Option<&'a Row> {
    find(rows, r, |m| {
        m.mode == RenderMode::Stereo
            && m.sky.is_none()
            && m.tess.criterion.is_none()
            && m.shading == Shading::Pbr
            && m.shadows == MethodShadows::Config
    })
    .filter(|o| o.input_triangles > 0)
}

/// The same method of the same case without a sky.
fn without_sky_row<'a>(rows: &'a [Row], r: &Row) -> Option<&'a Row> {
    find(rows, r, |m| {
        m.mode == r.method.mode
            && m.tess == r.method.tess
            && m.sky.is_none()
            && m.shading == r.method.shading
            && m.shadows == r.method.shadows
    })
}

/// A number as a CSV cell with four decimals.
fn f4(v: f64) -> String {
    format!("{v:.4}")
}

/// One row of `results.csv`: the cells of `r`, in the order of [`RESULT_HEADER`].
fn result_cells(rows: &[Row], r: &Row) -> Vec<String> {
    let ratio = |other: Option<&Row>| other.map_or(String::new(), |o| f4(r.ratio_to(o)));
    let mut cells = vec![
        r.scene.clone(),
        r.viewpoint.clone(),
        r.head.clone(),
        r.method.name.clone(),
        r.method.mode.name().to_owned(),
        r.method
            .tess
            .criterion
            .map_or("none".into(), |c| c.to_string()),
        r.method.sky.map_or("none", SkyMode::name).to_owned(),
        r.times_ms.len().to_string(),
        r.timer.name().to_owned(),
        f4(r.median()),
        f4(percentile(&r.times_ms, 0.25)),
        f4(percentile(&r.times_ms, 0.75)),
        f4(r.times_ms.first().copied().unwrap_or(f64::NAN)),
        f4(r.times_ms.last().copied().unwrap_or(f64::NAN)),
        f4(r.wall_median_ms),
        r.input_triangles.to_string(),
        r.drawn_triangles.to_string(),
        ratio(reference_row(rows, r)),
        if r.method.sky.is_some() {
            ratio(without_sky_row(rows, r))
        } else {
            String::new()
        },
    ];
    push_accuracy_cells(&mut cells, r);
    cells.push(r.dispatches.to_string());
    cells.push(r.refined_input.to_string());
    cells
}

/// The CSV cells from `error_max_px` to `resolve_ms`: the CPU twin's accuracy, the image
/// difference, the seams and the stage times (empty where the row has none).
fn push_accuracy_cells(cells: &mut Vec<String>, r: &Row) {
    match r.accuracy {
        Some(a) => cells.extend([
            format!("{:.4}", a.error.max),
            format!("{:.4}", a.error.p99),
            a.error.samples.to_string(),
            a.input.to_string(),
            a.culled.to_string(),
            a.emitted.to_string(),
            format!("{:.0}", a.edge_px),
        ]),
        None => cells.extend(std::iter::repeat_n(String::new(), 7)),
    }
    cells.push(
        r.image_diff_pct
            .map_or(String::new(), |d| format!("{d:.3}")),
    );
    match r.accuracy {
        Some(a) => cells.extend([
            format!("{:.4}", a.seam.max),
            format!("{:.4}", a.seam.p99),
            a.seam.samples.to_string(),
        ]),
        None => cells.extend(std::iter::repeat_n(String::new(), 3)),
    }
    match r.stages_ms {
        Some(st) => cells.extend(st.iter().map(|&v| f4(v))),
        None => cells.extend(std::iter::repeat_n(String::new(), STAGE_COLUMNS)),
    }
}

/// What the report's sections and charts share: the run's settings and its rows.
struct ReportInputs<'a> {
    options: &'a BenchOptions,
    config: &'a Config,
    adapter: &'a str,
    frames: usize,
    rows: &'a [Row],
    /// The CAVE's walls with their resolutions, comma separated.
    walls: String,
}

/// Writes `results.csv`, `report.md` and the charts into the output folder; returns their paths.
pub(super) fn write_outputs(
    options: &BenchOptions,
    config: &Config,
    adapter: &str,
    frames: usize,
    rows: &[Row],
) -> Result<Vec<PathBuf>, BenchError> {
    std::fs::create_dir_all(&options.out).map_err(|source| BenchError::Write {
        path: options.out.clone(),
        source,
    })?;
    let csv_path = options.out.join("results.csv");
    write_csv(
        &csv_path,
        RESULT_HEADER,
        rows.iter().map(|r| result_cells(rows, r)),
    )?;
    let inputs = ReportInputs {
        options,
        config,
        adapter,
        frames,
        rows,
        walls: config
            .cave
            .walls
            .iter()
            .map(|w| format!("{} {}×{}", w.name, w.resolution[0], w.resolution[1]))
            .collect::<Vec<String>>()
            .join(", "),
    };
    let summary = summarise(rows);
    // A CAVE without a floor to stand on (one flat wall) has no map; the bench goes on.
    let (guests_md, guest_files) = guests_outputs(options, config).unwrap_or_else(|e| {
        tracing::warn!("where guests may stand: {e}");
        (
            format!("\n## Where guests may stand (thesis 8.1)\n\nNot computed: {e}\n"),
            Vec::new(),
        )
    });
    let md_path = options.out.join("report.md");
    write_file(&md_path, &(inputs.report(&summary) + &guests_md))?;
    let mut files = vec![csv_path, md_path];
    inputs.write_charts(&summary, &mut files)?;
    files.extend(guest_files);
    Ok(files)
}

/// The thesis's open question (8.1) for this config: how long a floor map takes (a 0.1 m grid,
/// every default method, points on shells around the head), and the sweep of the sweet area
/// against CAVE size, head distance and resolution, written to `guests/` (`sweep.csv` and
/// charts); returns the report's section and the files.
fn guests_outputs(
    options: &BenchOptions,
    config: &Config,
) -> Result<(String, Vec<PathBuf>), BenchError> {
    use crate::guests::grid::{Grid, MethodMap, Thresholds, compute_each_assumed};
    use crate::guests::sweep::{self, SweepSettings};
    use crate::guests::{Gaze, Method, Setup, points};

    let dir = options.out.join("guests");
    let fail = |message: String| BenchError::Chart {
        path: dir.clone(),
        message,
    };
    let settings = &config.settings;
    let head = settings.head();
    let ipd = f64::from(settings.cave.eye_separation);
    let pole = settings.omni().pole_merge;
    let methods = Method::defaults();
    let limits = Thresholds::default();
    let setup = Setup::new(&config.cave, head, ipd, pole);
    let map_points = if options.quick { 2_000 } else { 10_000 };
    let grid = Grid::over(&config.cave, 0.1, f64::from(head.position.y)).map_err(fail)?;
    let radii = [1.0, 2.0, 4.0, 8.0];
    let started = std::time::Instant::now();
    let (maps, points_judged) = compute_each_assumed(
        &setup,
        &methods,
        |centre| points::shells(centre, &radii, map_points),
        &grid,
        Gaze::AtPoint,
        &limits,
        0,
    );
    let map_seconds = started.elapsed().as_secs_f64();
    let sweep_settings = SweepSettings {
        points: if options.quick { 500 } else { 2_000 },
        ..SweepSettings::default()
    };
    let started = std::time::Instant::now();
    let rows =
        sweep::run(&config.cave, head, ipd, pole, &methods, &sweep_settings).map_err(fail)?;
    let sweep_seconds = started.elapsed().as_secs_f64();
    std::fs::create_dir_all(&dir).map_err(|source| BenchError::Write {
        path: dir.clone(),
        source,
    })?;
    let files = crate::guests::report::write_sweep(&dir, &rows).map_err(|e| fail(e.to_string()))?;
    let mut md = String::new();
    let _ = writeln!(md, "\n## Where guests may stand (thesis 8.1)\n");
    let _ = writeln!(
        md,
        "One floor map (`omnicave guests`): a 0.1 m grid of {} viewer positions, {} points on shells at 1, 2, 4 and 8 m around each assumed head, {} methods: {map_seconds:.2} s on {} threads. The sweep ({} points a case): {sweep_seconds:.1} s.\n",
        grid.inside.iter().filter(|i| **i).count(),
        points_judged,
        methods.len(),
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        sweep_settings.points,
    );
    let _ = writeln!(
        md,
        "| method | fusion area, grid (m², p95 vertical < {} arcmin) | sweet area within reach (m², and direction < {}°) |\n|---|---|---|",
        limits.vertical_arcmin, limits.direction_degrees
    );
    for map in &maps {
        let _ = writeln!(
            md,
            "| {} | {:.2} of {:.2} | {:.4} |",
            map.method.name(),
            map.sweet_area(&grid, &limits.fusion_only()),
            MethodMap::floor_area(&grid),
            map.reach_area_m2
        );
    }
    let _ = writeln!(
        md,
        "\nThe sweep against CAVE size, the head's distance to the front wall and the walls' resolution: `guests/sweep.csv` and `guests/sweep-*.png`.\n"
    );
    Ok((md, files))
}

impl ReportInputs<'_> {
    /// The whole `report.md`.
    fn report(&self, summary: &[SceneSummary]) -> String {
        let mut md = String::new();
        self.write_header(&mut md);
        self.write_frame_time_section(&mut md);
        self.write_sky_cost_section(&mut md);
        let tess = self.config.settings.tess();
        let reference = super::methods::reference_method(tess).name;
        write_accuracy_sections(&mut md, summary, &reference);
        // Both eyes of every wall.
        write_scaling_section(&mut md, summary, 2 * self.config.cave.walls.len());
        write_animation_section(&mut md, summary);
        md
    }

    /// The report's title, the run's setup and command, and the tessellation settings.
    fn write_header(&self, md: &mut String) {
        let (options, adapter, frames) = (self.options, self.adapter, self.frames);
        let timer = self.rows.first().map_or("none", |r| r.timer.name());
        let _ = writeln!(md, "# omnicave benchmark\n");
        let _ = writeln!(
            md,
            "- adapter: {adapter}\n- machine: {}\n- CAVE: {} ({}), MSAA ×{}, both eyes\n- timer: {timer}; \
             median of {frames} frames per method, methods interleaved frame by frame\n- command: \
             `omnicave bench --config {}{}{}{}{}`\n",
            machine(),
            options.config.display(),
            self.walls,
            self.config.settings.render.msaa,
            options.config.display(),
            options
                .size
                .map_or(String::new(), |[w, h]| format!(" --size {w}x{h}")),
            options
                .frames
                .map_or(String::new(), |n| format!(" --frames {n}")),
            if options.quick { " --quick" } else { "" },
            options
                .scenes
                .iter()
                .map(|s| format!(" --scene {}", s.display()))
                .collect::<String>(),
        );
        let tess = self.config.settings.tess();
        let on = |b: bool| if b { "on" } else { "off" };
        let _ = writeln!(
            md,
            "Every tessellated method uses the config's `[tessellation]` with its own criterion: \
             maximum depth {}, back-face culling {}, frustum culling {}, fine clusters drawn \
             directly {}, one refinement for both eyes of a wall {}.\n",
            tess.max_depth,
            on(tess.backface_cull),
            on(tess.frustum_cull),
            on(tess.skip_fine),
            on(tess.shared_eyes)
        );
    }

    /// The table of every row's whole-frame time and its ratio to stereo.
    fn write_frame_time_section(&self, md: &mut String) {
        let _ = writeln!(md, "## Frame time of the whole stereo frame\n");
        let _ = writeln!(
            md,
            "| scene | viewpoint | head | method | median ms | p25–p75 ms | × stereo | drawn triangles |\n|---|---|---|---|---:|---:|---:|---:|"
        );
        for r in self.rows {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {:.2} | {:.2}–{:.2} | {} | {} |",
                r.scene,
                r.viewpoint,
                r.head,
                r.method.name,
                r.median(),
                percentile(&r.times_ms, 0.25),
                percentile(&r.times_ms, 0.75),
                reference_row(self.rows, r)
                    .map_or("–".into(), |o| format!("{:.3}", r.ratio_to(o))),
                r.drawn_triangles,
            );
        }
    }

    /// The table of each sky mode's frame time relative to the same method without a sky.
    fn write_sky_cost_section(&self, md: &mut String) {
        let rows = self.rows;
        let _ = writeln!(
            md,
            "\n## Cost of each sky mode relative to no sky (same render mode, same run)\n"
        );
        let _ = writeln!(
            md,
            "| scene | viewpoint | head | render mode | offaxis | omni-quad | omni-exact |\n|---|---|---|---|---:|---:|---:|"
        );
        for r in rows.iter().filter(|r| r.method.sky.is_none()) {
            let cell = |sky: SkyMode| {
                find(rows, r, |m| {
                    m.mode == r.method.mode && m.tess == r.method.tess && m.sky == Some(sky)
                })
                .map_or("–".into(), |s| format!("{:.3}", s.median() / r.median()))
            };
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {} | {} |",
                r.scene,
                r.viewpoint,
                r.head,
                r.method.name,
                cell(SkyMode::Offaxis),
                cell(SkyMode::OmniQuad),
                cell(SkyMode::OmniExact),
            );
        }
    }

    /// The scaling chart (with two scenes or more) and the first scene's speed-against-accuracy
    /// chart; appends their files to `files`.
    fn write_charts(
        &self,
        summary: &[SceneSummary],
        files: &mut Vec<PathBuf>,
    ) -> Result<(), BenchError> {
        let out = &self.options.out;
        let msaa = self.config.settings.render.msaa;
        if summary.len() > 1 {
            let cases = summary.iter().map(|s| s.cases).max().unwrap_or(0);
            let svg = chart::svg(
                &scaling_points(summary),
                &chart::Axes::time_against_triangles(),
                "Scaling with scene size: stereo, plain warp and the cheapest exact method",
                &format!(
                    "walls {} · MSAA ×{msaa} · median frame time over {cases} \
                     viewpoint/head case(s)",
                    self.walls,
                ),
            );
            files.extend(write_chart(out, "time-vs-triangles", &svg)?);
        }
        if let Some(first) = summary.first() {
            let points = chart_points(first);
            let svg = chart::svg(
                &points,
                &chart::Axes::speed_against_accuracy(),
                &format!("Speed against accuracy: {}", first.scene),
                &format!(
                    "walls {} · MSAA ×{msaa} · median frame time and worst p99 error over {} \
                     viewpoint/head case(s)",
                    self.walls, first.cases
                ),
            );
            files.extend(write_chart(out, "speed-vs-accuracy", &svg)?);
        }
        if let Some((animated, still)) = animated_pairs(summary).into_iter().next() {
            let mut points = chart_points(animated);
            points.extend(chart_points(still).into_iter().map(|p| chart::ChartPoint {
                family: format!("{} (static)", p.family),
                ..p
            }));
            let svg = chart::svg(
                &points,
                &chart::Axes::speed_against_accuracy(),
                &format!(
                    "Speed against accuracy: {}, posed every frame and static",
                    animated.scene
                ),
                &format!(
                    "walls {} · MSAA ×{msaa} · a new instant every frame · median frame time \
                     and worst p99 error over {} viewpoint/head case(s)",
                    self.walls, animated.cases
                ),
            );
            files.extend(write_chart(out, "speed-vs-accuracy-animated", &svg)?);
        }
        Ok(())
    }
}

/// Each animated scene with its static twin (see `run::STATIC_TWIN`).
fn animated_pairs(summary: &[SceneSummary]) -> Vec<(&SceneSummary, &SceneSummary)> {
    summary
        .iter()
        .filter_map(|s| {
            let twin = format!("{}{}", s.scene, super::run::STATIC_TWIN);
            summary
                .iter()
                .find(|o| o.scene == twin)
                .map(|still| (s, still))
        })
        .collect()
}

/// What posing costs: per animated scene and method, the frame time with a new instant every
/// frame against the same scene static, and the pose pass's own GPU time.
fn write_animation_section(md: &mut String, summary: &[SceneSummary]) {
    let pairs = animated_pairs(summary);
    if pairs.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "\n## Animated scenes: what posing costs\n\nEach animated scene is measured twice: \
         posed at a new instant every frame (the pose pass, then the shadow maps redrawn) and \
         static (the same geometry in its rest pose, nothing posed). Median frame time over \
         the cases; `pose` is the pose pass's GPU time (timestamps), `–` without timestamps.\n"
    );
    let _ = writeln!(
        md,
        "| scene | triangles | method | animated ms | static ms | × static | pose ms | p99 error px |\n|---|---:|---|---:|---:|---:|---:|---:|"
    );
    for (animated, still) in pairs {
        for m in &animated.methods {
            let Some(s) = still
                .methods
                .iter()
                .find(|o| o.method.name == m.method.name)
            else {
                continue;
            };
            let _ = writeln!(
                md,
                "| {} | {} | {} | {:.2} | {:.2} | {:.3} | {} | {:.2} |",
                animated.scene,
                animated.triangles,
                m.method.name,
                m.time_ms,
                s.time_ms,
                m.time_ms / s.time_ms,
                m.stages_ms.map_or("–".into(), |st| format!("{:.3}", st[0])),
                m.error_p99,
            );
        }
    }
}

/// Writes a chart as `NAME.svg` and `NAME.png` into `dir`; returns both paths.
fn write_chart(dir: &Path, name: &str, svg: &str) -> Result<[PathBuf; 2], BenchError> {
    let svg_path = dir.join(format!("{name}.svg"));
    write_file(&svg_path, svg)?;
    let png_path = dir.join(format!("{name}.png"));
    let png = chart::png(svg).map_err(|message| BenchError::Chart {
        path: png_path.clone(),
        message,
    })?;
    std::fs::write(&png_path, png).map_err(|source| BenchError::Write {
        path: png_path.clone(),
        source,
    })?;
    Ok([svg_path, png_path])
}

/// One method on one scene, over all head positions.
#[derive(Debug, Clone)]
pub struct MethodSummary {
    pub method: Method,
    /// Median over cases (viewpoint and head) of the median frame time, ms.
    pub time_ms: f64,
    /// Geometric mean over cases of the ratio to plain stereo.
    pub ratio_to_stereo: Option<f64>,
    /// Worst over cases.
    pub error_p99: f32,
    pub error_max: f32,
    /// Worst over cases: largest jump of an edge at a wall seam, px.
    pub seam_max: f32,
    /// Worst over cases: share of pixels differing visibly from the reference render, %.
    pub image_diff_pct: f64,
    /// Largest over cases (CPU twin, all views).
    pub drawn_triangles: u64,
    /// Median over cases of each stage's median GPU time, ms (`None` without timestamps).
    pub stages_ms: Option<[f64; STAGE_COLUMNS]>,
    /// Compute dispatches per frame (the largest over cases).
    pub dispatches: usize,
    /// Source triangles entering the tessellator per frame, all views (largest over cases).
    pub refined_input: usize,
}

/// The methods of one scene.
#[derive(Debug, Clone)]
pub struct SceneSummary {
    pub scene: String,
    /// Source triangles in the scene.
    pub triangles: usize,
    /// Measured situations (viewpoint and head).
    pub cases: usize,
    pub methods: Vec<MethodSummary>,
}

/// Per scene with geometry, per method without a sky: frame time and accuracy over cases.
pub fn summarise(rows: &[Row]) -> Vec<SceneSummary> {
    let mut scenes: Vec<String> = Vec::new();
    for r in rows.iter().filter(|r| r.accuracy.is_some()) {
        if !scenes.contains(&r.scene) {
            scenes.push(r.scene.clone());
        }
    }
    scenes
        .into_iter()
        .map(|scene| {
            let of_scene: Vec<&Row> = rows.iter().filter(|r| r.scene == scene).collect();
            let mut cases: Vec<(&str, &str)> = of_scene
                .iter()
                .map(|r| (r.viewpoint.as_str(), r.head.as_str()))
                .collect();
            cases.dedup();
            let mut names: Vec<&Method> = Vec::new();
            for r in &of_scene {
                if r.method.sky.is_none() && !names.iter().any(|m| m.name == r.method.name) {
                    names.push(&r.method);
                }
            }
            let methods = names
                .into_iter()
                .map(|m| {
                    let mine: Vec<&&Row> = of_scene
                        .iter()
                        .filter(|r| r.method.name == m.name)
                        .collect();
                    let mut times: Vec<f64> = mine.iter().map(|r| r.median()).collect();
                    times.sort_by(f64::total_cmp);
                    let ratios: Vec<f64> = mine
                        .iter()
                        .filter_map(|r| {
                            let reference = of_scene.iter().find(|o| {
                                o.head == r.head
                                    && o.viewpoint == r.viewpoint
                                    && o.method.mode == RenderMode::Stereo
                                    && o.method.sky.is_none()
                                    && o.method.tess.criterion.is_none()
                            })?;
                            Some(r.ratio_to(reference))
                        })
                        .collect();
                    let ratio = (!ratios.is_empty()).then(|| {
                        (ratios.iter().map(|r| r.ln()).sum::<f64>() / ratios.len() as f64).exp()
                    });
                    let acc = |f: fn(&Accuracy) -> f32| {
                        mine.iter()
                            .filter_map(|r| r.accuracy.as_ref().map(f))
                            .fold(0.0f32, f32::max)
                    };
                    MethodSummary {
                        method: m.clone(),
                        time_ms: percentile(&times, 0.5),
                        ratio_to_stereo: ratio,
                        error_p99: acc(|a| a.error.p99),
                        error_max: acc(|a| a.error.max),
                        seam_max: acc(|a| a.seam.max),
                        image_diff_pct: mine
                            .iter()
                            .filter_map(|r| r.image_diff_pct)
                            .fold(0.0, f64::max),
                        drawn_triangles: mine
                            .iter()
                            .filter_map(|r| r.accuracy.map(|a| a.emitted))
                            .max()
                            .unwrap_or(0),
                        stages_ms: stage_medians(&mine),
                        dispatches: mine.iter().map(|r| r.dispatches).max().unwrap_or(0),
                        refined_input: mine.iter().map(|r| r.refined_input).max().unwrap_or(0),
                    }
                })
                .collect();
            SceneSummary {
                triangles: of_scene
                    .iter()
                    .map(|r| r.input_triangles)
                    .max()
                    .unwrap_or(0),
                scene,
                cases: cases.len(),
                methods,
            }
        })
        .collect()
}

/// Per stage, the median over `rows` of their medians (`None` if any row has no timestamps).
fn stage_medians(rows: &[&&Row]) -> Option<[f64; STAGE_COLUMNS]> {
    let all: Vec<[f64; STAGE_COLUMNS]> = rows.iter().map(|r| r.stages_ms).collect::<Option<_>>()?;
    (!all.is_empty()).then(|| {
        std::array::from_fn(|k| {
            let mut v: Vec<f64> = all.iter().map(|s| s[k]).collect();
            v.sort_by(f64::total_cmp);
            percentile(&v, 0.5)
        })
    })
}

/// The chart's points: one per method, grouped by family.
pub fn chart_points(summary: &SceneSummary) -> Vec<chart::ChartPoint> {
    summary
        .methods
        .iter()
        // The triangle control draws stereo's picture: a measurement, not a method to pick.
        .filter(|m| m.method.name != super::methods::TRIANGLE_CONTROL)
        .map(|m| chart::ChartPoint {
            family: family(&m.method),
            label: m
                .method
                .tess
                .criterion
                .map(|c| c.to_string().split(':').nth(1).unwrap_or("").to_owned())
                .unwrap_or_default(),
            x: m.time_ms,
            y: f64::from(m.error_p99),
        })
        .collect()
}

/// Series of the scaling chart and table: plain off-axis stereo, the plain warp
/// (omni-offaxis without tessellation) and the cheapest exact omnistereo method.
pub const SCALING_SERIES: [&str; 3] = ["off-axis stereo", "plain warp", "cheapest exact"];

/// Per scene, the methods of the scaling series (`None` where the run has none).
fn scaling_methods(s: &SceneSummary) -> [Option<&MethodSummary>; 3] {
    // As the reference: shaded, shadowed, no sky.
    let plain = |m: &&MethodSummary| {
        m.method.sky.is_none()
            && m.method.tess.criterion.is_none()
            && m.method.shading == Shading::Pbr
            && m.method.shadows == MethodShadows::Config
    };
    [
        s.methods
            .iter()
            .filter(plain)
            .find(|m| m.method.mode == RenderMode::Stereo),
        s.methods
            .iter()
            .filter(plain)
            .find(|m| m.method.mode == RenderMode::OmniOffAxis),
        s.cheapest_exact(),
    ]
}

/// The scaling chart's points: frame time against the scene's triangles, one series each
/// for stereo, the plain warp and the cheapest exact method (labelled with its criterion).
pub fn scaling_points(summary: &[SceneSummary]) -> Vec<chart::ChartPoint> {
    let mut points = Vec::new();
    for (k, family) in SCALING_SERIES.iter().enumerate() {
        for s in summary {
            if let Some(m) = scaling_methods(s)[k] {
                points.push(chart::ChartPoint {
                    family: (*family).into(),
                    label: if k == 2 {
                        m.method
                            .tess
                            .criterion
                            .map_or(String::new(), |c| c.to_string())
                    } else {
                        String::new()
                    },
                    x: s.triangles as f64,
                    y: m.time_ms,
                });
            }
        }
    }
    points
}

/// The tessellator's stages (culling, split and sort) of a row of stage times: the pose pass
/// and the shadow maps, then [`ViewStage::ALL`].
fn tessellation_ms(stages: &[f64; STAGE_COLUMNS]) -> f64 {
    ViewStage::ALL
        .iter()
        .zip(&stages[STAGE_COLUMNS - ViewStage::ALL.len()..])
        .filter(|(stage, _)| stage.is_tessellation())
        .map(|(_, ms)| ms)
        .sum()
}

/// How frame time and the tessellator's work grow with the scene: per scene, its triangles,
/// each series' time and ratio, and the source triangles the exact method refines.
fn write_scaling_section(md: &mut String, summary: &[SceneSummary], views: usize) {
    if summary.len() < 2 {
        return;
    }
    let _ = writeln!(
        md,
        "\n## Scaling with scene size\n\nTime: median frame over the cases, ms (× stereo: the \
         geometric mean over the cases of the paired ratio). `refined`: source triangles that \
         entered the tessellator per frame, summed over its refinements (one per wall where \
         both eyes share it, `shared_eyes`; largest over the cases), against the scene's \
         triangles × {views} views. Chart: `time-vs-triangles.svg`.\n\n\
         | scene | triangles | stereo ms | plain warp ms (×) | cheapest exact | ms (×) | tess \
         stages ms | refined | of |\n|---|---:|---:|---:|---|---:|---:|---:|---:|"
    );
    let ratio = |m: &MethodSummary| m.ratio_to_stereo.map_or("–".into(), |r| format!("{r:.3}"));
    for s in summary {
        let [stereo, plain, exact] = scaling_methods(s);
        let ms =
            |m: Option<&MethodSummary>| m.map_or("–".into(), |m| format!("{:.2}", m.time_ms));
        let ms_ratio = |m: Option<&MethodSummary>| {
            m.map_or("–".into(), |m| format!("{:.2} ({})", m.time_ms, ratio(m)))
        };
        let tess_ms = exact
            .and_then(|m| m.stages_ms)
            .map_or("–".into(), |st| format!("{:.2}", tessellation_ms(&st)));
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            s.scene,
            s.triangles,
            ms(stereo),
            ms_ratio(plain),
            exact.map_or("none exact".into(), |m| format!("`{}`", m.method.name)),
            ms_ratio(exact),
            tess_ms,
            exact.map_or("–".into(), |m| m.refined_input.to_string()),
            s.triangles * views,
        );
    }
}

/// The error target the report answers for (px, 99th percentile).
pub const TARGET_P99_PX: f32 = 0.5;
/// ... and for the largest error of any case (px): "exact" means both.
pub const TARGET_MAX_PX: f32 = 1.0;

impl SceneSummary {
    /// The cheapest omnistereo method with tessellation that is exact
    /// ([`MethodSummary::is_exact`]): the lowest paired ratio to stereo (what drifts on a shared
    /// machine cancels in it), else the lowest median time.
    pub fn cheapest_exact(&self) -> Option<&MethodSummary> {
        let cost = |m: &MethodSummary| m.ratio_to_stereo.unwrap_or(f64::INFINITY);
        self.methods
            .iter()
            .filter(|m| {
                m.method.mode.is_omni()
                    && m.method.sky.is_none()
                    && m.method.tess.criterion.is_some()
                    && m.is_exact()
            })
            .min_by(|a, b| {
                cost(a)
                    .total_cmp(&cost(b))
                    .then(a.time_ms.total_cmp(&b.time_ms))
            })
    }
}

impl MethodSummary {
    /// Exact omnistereo: every case's p99 error within [`TARGET_P99_PX`] and its maximum
    /// within [`TARGET_MAX_PX`].
    pub fn is_exact(&self) -> bool {
        self.error_p99 <= TARGET_P99_PX && self.error_max <= TARGET_MAX_PX
    }
}

fn write_accuracy_sections(md: &mut String, summary: &[SceneSummary], reference: &str) {
    for s in summary {
        let points = chart_points(s);
        let front = chart::pareto_front(&points);
        let _ = writeln!(
            md,
            "\n## Speed against accuracy: {} ({} viewpoint and head positions)\n\nError: distance in pixels \
             between where each method draws points along the scene's edges and where the \
             omnistereo ideal puts them (each point seen from its own eye), sampled every 4 px \
             along every drawn edge of every wall and eye (CPU twin); p99 and max are the worst \
             over the viewpoints and head positions. Pixels off: share of eye-image pixels differing by more \
             than {VISIBLE_DIFFERENCE}/255 from the {reference}, worst over the heads. Seam: the largest jump, along the \
             shared edge, of a scene edge crossing from one wall's image to the next (same \
             eye), worst over them. Time: median over them.\n",
            s.scene, s.cases
        );
        let _ = writeln!(
            md,
            "| method | median ms | × stereo | p99 error px | max error px | seam max px | pixels off % | drawn triangles | Pareto |\n|---|---:|---:|---:|---:|---:|---:|---:|:---:|"
        );
        for (i, m) in s.methods.iter().enumerate() {
            let _ = writeln!(
                md,
                "| {} | {:.2} | {} | {:.3} | {:.2} | {:.2} | {:.2} | {} | {} |",
                m.method.name,
                m.time_ms,
                m.ratio_to_stereo.map_or("–".into(), |r| format!("{r:.3}")),
                m.error_p99,
                m.error_max,
                m.seam_max,
                m.image_diff_pct,
                m.drawn_triangles,
                if front.contains(&i) { "●" } else { "" }
            );
        }
        // The overhead of omnistereo with tessellation at the target error.
        let best = s.cheapest_exact();
        let _ = writeln!(
            md,
            "\n**Exact (p99 ≤ {TARGET_P99_PX} px and max ≤ {TARGET_MAX_PX} px in every case)** \
             ({}): {}\n",
            s.scene,
            match best {
                Some(m) => format!(
                    "the cheapest omnistereo + tessellation method is `{}`, {:.2} ms, **{} × \
                     off-axis stereo** ({:+.0} %), drawing {} triangles.",
                    m.method.name,
                    m.time_ms,
                    m.ratio_to_stereo.map_or("–".into(), |r| format!("{r:.3}")),
                    m.ratio_to_stereo.map_or(f64::NAN, |r| (r - 1.0) * 100.0),
                    m.drawn_triangles
                ),
                None => "no omnistereo + tessellation method reached it in this run.".into(),
            }
        );
        let _ = writeln!(
            md,
            "Coarsest setting of each criterion that reaches it, and what it draws:\n\n\
             | criterion | setting | p99 px | max px | drawn triangles | × stereo |\n\
             |---|---|---:|---:|---:|---:|"
        );
        let mut kinds: Vec<String> = Vec::new();
        for m in s
            .methods
            .iter()
            .filter(|m| m.method.tess.criterion.is_some() && m.method.mode.is_omni())
        {
            let f = family(&m.method);
            if !kinds.contains(&f) {
                kinds.push(f);
            }
        }
        for kind in kinds {
            // Methods are listed coarse to fine: the first that reaches the target.
            let reached = s
                .methods
                .iter()
                .find(|m| family(&m.method) == kind && m.is_exact());
            let _ = match reached {
                Some(m) => writeln!(
                    md,
                    "| {kind} | {} | {:.3} | {:.2} | {} | {} |",
                    m.method
                        .tess
                        .criterion
                        .map_or(String::new(), |c| c.to_string()),
                    m.error_p99,
                    m.error_max,
                    m.drawn_triangles,
                    m.ratio_to_stereo.map_or("–".into(), |r| format!("{r:.3}"))
                ),
                None => writeln!(md, "| {kind} | not reached | | | | |"),
            };
        }
        write_stage_table(md, s);
        write_triangle_control(md, s);
    }
}

/// What the triangle control says about this scene: how much the tessellator's stages and
/// four times the triangles cost with the picture unchanged.
fn write_triangle_control(md: &mut String, s: &SceneSummary) {
    let Some(control) = s
        .methods
        .iter()
        .find(|m| m.method.name == super::methods::TRIANGLE_CONTROL)
    else {
        return;
    };
    let Some(ratio) = control.ratio_to_stereo else {
        return;
    };
    let _ = writeln!(
        md,
        "
`{}` draws stereo's picture through the tessellator with every triangle cut in \
         four (after the tessellator's culling) and no warp: {ratio:.2} × stereo. That is what \
         the tessellator's stages and four times the triangles cost here with the picture \
         unchanged: how much the adapter charges for added triangles, whatever the warp.",
        control.method.name
    );
}

/// Where each method's GPU time goes, per stage summed over the views (median over the
/// cases), with the frame's compute dispatches and drawn triangles.
fn write_stage_table(md: &mut String, s: &SceneSummary) {
    if s.methods.iter().all(|m| m.stages_ms.is_none()) {
        let _ = writeln!(
            md,
            "\nNo GPU timestamps on this adapter: no breakdown per stage."
        );
        return;
    }
    let names = stage_names();
    let _ = writeln!(
        md,
        "\nWhere the time goes ({}; GPU timestamps between stages, ms per frame summed over \
         the views, median over the cases; `resolve` is the end of each view's render pass, \
         MSAA resolve and stores; `tess cull` is the culling dispatch, which also splits the \
         first {} levels, `tess split` the split dispatches beyond them; `refined` counts the \
         source triangles that entered the tessellator, all refinements: one per wall where \
         both eyes share it, `shared_eyes`):\n\n| method | total | {} | dispatches | refined | drawn triangles |\n|---|---:|{}---:|---:|---:|",
        s.scene,
        crate::render::tessellator::SPLIT_LEVELS,
        names.join(" | "),
        "---:|".repeat(names.len())
    );
    for m in &s.methods {
        let Some(st) = m.stages_ms else { continue };
        let cells: Vec<String> = st.iter().map(|v| format!("{v:.2}")).collect();
        let _ = writeln!(
            md,
            "| {} | {:.2} | {} | {} | {} | {} |",
            m.method.name,
            st.iter().sum::<f64>(),
            cells.join(" | "),
            m.dispatches,
            m.refined_input,
            m.drawn_triangles
        );
    }
}

/// The CPU model and core count, as far as the OS tells.
fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_owned())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_owned());
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    format!("{cpu}, {cores} cores available")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::methods::methods;

    #[test]
    fn the_tessellation_stages_are_culling_split_and_sort() {
        // Pose, shadows, then cull, split, sort, scene, sky, resolve: powers of two, so any
        // wrong column shows in the sum. (It summed shadows, cull and split: 14.)
        let stages = [1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0];
        assert_eq!(tessellation_ms(&stages), 28.0);
    }

    /// A method of the quick list by name, with its time, ratio and accuracy.
    fn summary(name: &str, time_ms: f64, ratio: f64, p99: f32, max: f32) -> MethodSummary {
        let method = methods(true, crate::tess::TessSettings::default())
            .into_iter()
            .find(|m| m.name == name)
            .unwrap_or_else(|| panic!("no method {name}"));
        MethodSummary {
            method,
            time_ms,
            ratio_to_stereo: Some(ratio),
            error_p99: p99,
            error_max: max,
            seam_max: 0.0,
            image_diff_pct: 0.0,
            drawn_triangles: 0,
            stages_ms: None,
            dispatches: 0,
            refined_input: 0,
        }
    }

    #[test]
    fn scaling_series_take_stereo_the_plain_warp_and_the_cheapest_exact_by_ratio() {
        let scene = |name: &str, triangles: usize| SceneSummary {
            scene: name.into(),
            triangles,
            cases: 3,
            methods: vec![
                summary("stereo", 100.0, 1.0, 9.0, 12.0),
                summary("stereo + shadows off", 90.0, 0.9, 9.0, 12.0),
                summary("omni-offaxis", 101.0, 1.01, 1.0, 50.0),
                // Not exact: too large a maximum, however cheap.
                summary("omni-offaxis + tess error:8", 105.0, 1.05, 0.3, 1.6),
                // Exact, faster by median time but dearer by the paired ratio.
                summary("omni-offaxis + tess sphere:128", 120.0, 1.25, 0.2, 0.9),
                summary("omni-offaxis + tess edge:64", 125.0, 1.20, 0.1, 0.5),
            ],
        };
        let summaries = [scene("small", 7_000), scene("large", 225_000)];
        let cheapest = summaries[0].cheapest_exact().expect("an exact method");
        assert_eq!(cheapest.method.name, "omni-offaxis + tess edge:64");
        let points = scaling_points(&summaries);
        let series: Vec<(&str, f64, f64)> = points
            .iter()
            .map(|p| (p.family.as_str(), p.x, p.y))
            .collect();
        assert_eq!(
            series,
            vec![
                ("off-axis stereo", 7_000.0, 100.0),
                ("off-axis stereo", 225_000.0, 100.0),
                ("plain warp", 7_000.0, 101.0),
                ("plain warp", 225_000.0, 101.0),
                ("cheapest exact", 7_000.0, 125.0),
                ("cheapest exact", 225_000.0, 125.0),
            ]
        );
        assert_eq!(points[4].label, "edge:64");
        let mut md = String::new();
        write_scaling_section(&mut md, &summaries, 6);
        assert!(
            md.contains(
                "| small | 7000 | 100.00 | 101.00 (1.010) | `omni-offaxis + tess edge:64` | \
                 125.00 (1.200) | – | 0 | 42000 |"
            ),
            "{md}"
        );
        // One scene: nothing to scale against.
        let mut one = String::new();
        write_scaling_section(&mut one, &summaries[..1], 6);
        assert!(one.is_empty());
    }

    #[test]
    fn a_cell_with_a_comma_or_quote_stays_one_cell() {
        let path = std::env::temp_dir().join(format!("omnicave-csv-{}.csv", std::process::id()));
        let name = "Sponza, \"decimated\"";
        write_csv(
            &path,
            &["scene", "ms"],
            [vec![name.to_owned(), "1.5".into()]],
        )
        .expect("write");
        let mut reader = csv::Reader::from_path(&path).expect("read");
        let rows: Vec<csv::StringRecord> = reader.records().map(|r| r.expect("row")).collect();
        let _ = std::fs::remove_file(&path);
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].len(), 2);
        assert_eq!(&rows[0][0], name);
    }
}
