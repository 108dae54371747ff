//! The benchmark (`omnicave bench`): frame time and accuracy of every rendering method on scenes
//! and head positions, measured in one run so that methods compare by ratio, written as CSV,
//! Markdown and a speed-against-accuracy chart.

pub mod accuracy;
pub mod chart;
pub mod panorama;
pub mod stability;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{Mat4, Vec3};

use accuracy::Accuracy;

use crate::cave::{Head, RenderMode};
use crate::config::{Config, ConfigError};
use crate::render::{Gpu, RenderError, RenderSettings, Renderer, WallImages};
use crate::scene::{Scene, SceneError, load_gltf};
use crate::setup::frame_params;
use crate::sky::{CubeMap, SkyError, SkyMode, load_sky};
use crate::tess::{Criterion, TessSettings};

/// Anything that stops the benchmark.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Sky(#[from] SkyError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error("cannot write {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("cannot draw the chart {path}: {message}")]
    Chart { path: PathBuf, message: String },
}

/// What to run.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    pub config: PathBuf,
    /// Scenes; empty: the config's scene and the bundled city.
    pub scenes: Vec<PathBuf>,
    /// Sky for the sky methods; `None`: the config's, else the bundled one.
    pub sky: Option<PathBuf>,
    pub out: PathBuf,
    /// Fewer frames and head positions (finishes in well under 2 minutes on lavapipe).
    pub quick: bool,
    /// Timed frames per method and case (default 12, quick 3).
    pub frames: Option<usize>,
    /// Replaces every wall's pixel size (quick default: 192×108).
    pub size: Option<[u32; 2]>,
    /// Only the panorama methods (`panorama.csv` and a report of them alone).
    pub panorama_only: bool,
}

/// Wall size of a quick run: 15 % of the thesis CAVE's in each direction, so that CI's
/// software renderer (which spends seconds per full-size city frame) finishes in under two
/// minutes.
pub const QUICK_SIZE: [u32; 2] = [192, 108];

/// One way of rendering a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Method {
    pub name: String,
    pub mode: RenderMode,
    pub tess: TessSettings,
    /// `None`: no sky.
    pub sky: Option<SkyMode>,
}

/// Parameters of each tessellation criterion the bench sweeps (a full run; `--quick` takes
/// every other one), coarse to fine.
/// A criterion from its parameter, and the parameters swept.
type Sweep = (fn(f32) -> Criterion, &'static [f32]);
const SWEEP: [Sweep; 4] = [
    (Criterion::Error, &[4.0, 2.0, 1.0, 0.5, 0.25]),
    (|px| Criterion::Edge(px), &[64.0, 32.0, 16.0, 8.0]),
    (|px| Criterion::Sphere(px), &[64.0, 32.0, 16.0, 8.0]),
    (|n| Criterion::Uniform(n as u32), &[1.0, 2.0, 3.0]),
];

/// The methods compared, the reference (plain off-axis stereo, no sky) first: mono, stereo,
/// both omnistereo warps without tessellation, the off-axis warp with each criterion at
/// several parameters, and the sky modes.
pub fn methods(quick: bool) -> Vec<Method> {
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
        }
    };
    let none = TessSettings::default();
    let with = |c: Criterion| TessSettings {
        criterion: Some(c),
        ..TessSettings::default()
    };
    let mut out = vec![
        m(RenderMode::Stereo, none, None),
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

/// The methods' family for the chart: render mode and criterion kind (a series whose points
/// are the criterion's parameters).
pub fn family(m: &Method) -> String {
    match m.tess.criterion {
        None => m.mode.name().to_owned(),
        Some(c) => {
            let text = c.to_string();
            let kind = text.split(':').next().unwrap_or("");
            format!("{} + tess {kind}", m.mode.name())
        }
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

/// One measured (case, method).
#[derive(Debug, Clone)]
pub struct Row {
    pub scene: String,
    /// Where the CAVE stands in the scene (see [`viewpoints`]).
    pub viewpoint: String,
    pub head: String,
    pub method: Method,
    pub timer: Timer,
    /// Sorted frame times (ms) of the chosen timer.
    pub times_ms: Vec<f64>,
    /// Median wall-clock time (ms), for reference when the GPU timer is used.
    pub wall_median_ms: f64,
    pub input_triangles: usize,
    /// Triangles drawn over all views (after tessellation and culling).
    pub drawn_triangles: usize,
    /// Error against the omnistereo ideal and the CPU twin's counts (`None`: the sky alone).
    pub accuracy: Option<Accuracy>,
    /// Share of eye-image pixels (%) that differ visibly from the reference render
    /// (`None`: the sky alone).
    pub image_diff_pct: Option<f64>,
}

impl Row {
    pub fn median(&self) -> f64 {
        percentile(&self.times_ms, 0.5)
    }
}

/// The `q` quantile of sorted values (linear interpolation).
pub fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = q.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    sorted[lo] + (pos - lo as f64) * (sorted[hi] - sorted[lo])
}

/// Everything a run produced.
#[derive(Debug, Clone)]
pub struct BenchReport {
    pub rows: Vec<Row>,
    /// The panorama methods (see [`panorama`]).
    pub pano_rows: Vec<panorama::PanoRow>,
    pub adapter: String,
    pub files: Vec<PathBuf>,
}

/// Head positions: the config's, off-centre, 0.3 m from the front wall and near a corner
/// (0.35 m from two walls); `--quick`: the first and the third. Placed relative to the walls'
/// bounding box (front = −z), and skipped with a warning where that is behind a wall.
pub fn heads(config: &Config, quick: bool) -> Vec<(String, Vec3)> {
    let (min, max) = crate::cave::Cave::bounding_box(&config.cave.walls);
    let h = config.settings.head().position;
    let size = max - min;
    let candidates = [
        ("centred", h),
        (
            "off-centre",
            h + Vec3::new(0.18 * size.x, -0.2, 0.12 * size.z),
        ),
        (
            "0.3 m from the front wall",
            Vec3::new(h.x + 0.3, h.y, min.z + 0.3),
        ),
        (
            "near a corner",
            Vec3::new(min.x + 0.35, h.y - 0.1, min.z + 0.35),
        ),
    ];
    candidates
        .into_iter()
        .enumerate()
        .filter(|(i, _)| !quick || *i == 0 || *i == 2)
        .filter_map(|(_, (name, p))| match config.cave.head_problem(p) {
            None => Some((name.to_owned(), p)),
            Some(problem) => {
                tracing::warn!("bench: head '{name}' skipped: {problem}");
                None
            }
        })
        .collect()
}

/// Where the CAVE stands in the scene: the config's placement (`start`), and the same turned
/// about the config's head by 90° to the left and by 180° (the scene seen in other
/// directions, as a user navigating would). `--quick`: `start` and `turned 180°`.
pub fn viewpoints(config: &Config, quick: bool) -> Vec<(String, Mat4)> {
    let h = config.settings.head().position;
    let turned = |degrees: f32| {
        config.settings.world_from_cave()
            * Mat4::from_translation(h)
            * Mat4::from_rotation_y(degrees.to_radians())
            * Mat4::from_translation(-h)
    };
    let all = [
        ("start", config.settings.world_from_cave()),
        ("turned 90° left", turned(90.0)),
        ("turned 180°", turned(180.0)),
    ];
    all.into_iter()
        .filter(|(name, _)| !quick || *name != "turned 90° left")
        .map(|(name, m)| (name.to_owned(), m))
        .collect()
}

/// One measured situation: scene placement and head.
#[derive(Debug, Clone)]
struct Case {
    viewpoint: String,
    world_from_cave: Mat4,
    head_name: String,
    head: Vec3,
}

/// Every viewpoint with every head; `--quick`: both heads at `start`, the centred head at
/// the other viewpoint. The sky alone only from `start` (turning turns the sky only).
fn cases(config: &Config, quick: bool, with_scene: bool) -> Vec<Case> {
    let heads = heads(config, quick);
    let mut out = Vec::new();
    for (i, (viewpoint, world_from_cave)) in viewpoints(config, quick).into_iter().enumerate() {
        if i > 0 && !with_scene {
            break;
        }
        for (j, (head_name, head)) in heads.iter().enumerate() {
            if quick && i > 0 && j > 0 {
                continue;
            }
            out.push(Case {
                viewpoint: viewpoint.clone(),
                world_from_cave,
                head_name: head_name.clone(),
                head: *head,
            });
        }
    }
    out
}

/// Runs the benchmark and writes `results.csv`, `report.md` and the chart into the output
/// folder. `progress(done, total, what)` is told before each case.
pub fn run(
    options: &BenchOptions,
    progress: &mut dyn FnMut(usize, usize, &str),
) -> Result<BenchReport, BenchError> {
    let mut config = Config::load(&options.config)?;
    if let Some(size) = options.size.or(options.quick.then_some(QUICK_SIZE)) {
        for wall in &mut config.cave.walls {
            wall.resolution = size;
        }
    }
    let mut scenes: Vec<(String, Option<Scene>)> = Vec::new();
    let scene_paths: Vec<PathBuf> = if options.scenes.is_empty() {
        let mut v: Vec<PathBuf> = config.scene_path.iter().cloned().collect();
        let city = bundled_path(&options.config, "assets/city.glb");
        if city.is_file() && !v.contains(&city) {
            v.push(city);
        }
        v
    } else {
        options.scenes.clone()
    };
    for path in &scene_paths {
        let name = path.file_stem().map_or_else(
            || path.display().to_string(),
            |s| s.to_string_lossy().into(),
        );
        scenes.push((name, Some(load_gltf(path)?)));
    }
    // The sky alone, over the whole of every wall: its worst case.
    scenes.push(("sky only".into(), None));

    let sky_path = options
        .sky
        .clone()
        .or_else(|| config.sky_path.clone())
        .unwrap_or_else(|| bundled_path(&options.config, crate::sky::bundled::PATH));
    let sky = load_sky(&sky_path)?;

    let frames = options
        .frames
        .unwrap_or(if options.quick { 3 } else { 12 })
        .max(1);

    let gpu = Gpu::headless()?;
    let adapter = {
        let info = gpu.adapter.get_info();
        format!(
            "{} ({:?}, driver {} {})",
            info.name, info.backend, info.driver, info.driver_info
        )
    };
    let methods = methods(options.quick);
    let mut rows = Vec::new();
    let total: usize = scenes
        .iter()
        .filter(|_| !options.panorama_only)
        .map(|(_, s)| cases(&config, options.quick, s.is_some()).len())
        .sum();
    let mut done = 0;
    let wall_scenes: &[(String, Option<Scene>)] = if options.panorama_only { &[] } else { &scenes };
    for (scene_name, scene) in wall_scenes {
        for case in cases(&config, options.quick, scene.is_some()) {
            let what = format!(
                "{scene_name}, {}, head {}: {} methods × {frames} frames",
                case.viewpoint,
                case.head_name,
                methods.len()
            );
            progress(done, total, &what);
            done += 1;
            tracing::info!("[{done}/{total}] {what}");
            rows.extend(measure(
                &gpu,
                &config,
                scene_name,
                scene.as_ref(),
                &sky,
                &case,
                &methods,
                frames,
            )?);
            // Rewritten after every case, so a run that is stopped keeps what it measured.
            write_outputs(options, &config, &adapter, frames, &rows)?;
        }
    }
    progress(
        total,
        total,
        "panorama methods (geometric and image routes, against the CPU ray caster)",
    );
    let with_geometry: Vec<(String, Scene)> = scenes
        .iter()
        .filter_map(|(name, s)| s.clone().map(|s| (name.clone(), s)))
        .collect();
    let (pano_rows, pano_files) = panorama::run_panorama(
        &gpu,
        &config,
        &with_geometry,
        &options.out,
        options.quick,
        frames,
    )?;
    progress(total, total, "done");
    let md_path = options.out.join("report.md");
    let (mut files, mut md) = if options.panorama_only {
        let md = format!(
            "# omnicave bench: the panorama methods\n\nadapter: {adapter}\n\ncommand: `omnicave \
             bench --panorama-only --config {}{}`\n",
            options.config.display(),
            if options.quick { " --quick" } else { "" }
        );
        (Vec::new(), md)
    } else {
        let files = write_outputs(options, &config, &adapter, frames, &rows)?;
        // The panorama section at the end of the report.
        let md = std::fs::read_to_string(&md_path).map_err(|source| BenchError::Write {
            path: md_path.clone(),
            source,
        })?;
        (files, md)
    };
    let images: Vec<PathBuf> = pano_files
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .cloned()
        .collect();
    md.push_str(&panorama::pano_markdown(
        &pano_rows,
        panorama::pano_size(options.quick),
        &images,
    ));
    write_file(&md_path, &md)?;
    if options.panorama_only {
        files.push(md_path);
    }
    files.extend(pano_files);
    Ok(BenchReport {
        pano_rows,
        rows,
        adapter,
        files,
    })
}

/// A bundled file: relative to the repository the config lives in (config/…), else the
/// current folder.
fn bundled_path(config: &Path, relative: &str) -> PathBuf {
    let beside = config
        .parent()
        .and_then(Path::parent)
        .map(|root| root.join(relative));
    match beside {
        Some(p) if p.exists() => p,
        _ => PathBuf::from(relative),
    }
}

#[allow(clippy::too_many_arguments)]
fn measure(
    gpu: &Gpu,
    config: &Config,
    scene_name: &str,
    scene: Option<&Scene>,
    sky: &CubeMap,
    case: &Case,
    methods: &[Method],
    frames: usize,
) -> Result<Vec<Row>, BenchError> {
    let mut renderer = Renderer::new(
        gpu,
        &config.cave,
        RenderSettings {
            msaa: config.settings.render.msaa,
            wireframe: false,
        },
    )?;
    if let Some(scene) = scene {
        renderer.set_scene(scene);
    }
    renderer.set_sky(Some(sky))?;
    let timer = if renderer.enable_gpu_timing(gpu) {
        Timer::Gpu
    } else {
        Timer::Wall
    };
    let mut gpu_times = vec![Vec::with_capacity(frames); methods.len()];
    let mut wall_times = vec![Vec::with_capacity(frames); methods.len()];
    let mut drawn = vec![0usize; methods.len()];
    let params = |m: &Method| {
        let mut p = frame_params(config);
        p.head = Head::at(case.head);
        p.world_from_cave = case.world_from_cave;
        p.mode = m.mode;
        p.tess = m.tess;
        p.sky.mode = m.sky.unwrap_or(SkyMode::Off);
        p
    };
    // One warm-up frame per method (first-use costs), then round-robin so that any drift of the
    // machine spreads over all methods alike.
    for (i, m) in methods.iter().enumerate() {
        let stats = renderer.render(&params(m))?;
        renderer.wait_idle()?;
        let tess: usize = renderer
            .read_tess_stats()?
            .iter()
            .map(|s| s.emitted as usize)
            .sum();
        drawn[i] = if m.tess.criterion.is_some() {
            tess
        } else {
            stats.triangles_submitted
        };
    }
    for _ in 0..frames {
        for (i, m) in methods.iter().enumerate() {
            let start = Instant::now();
            renderer.render(&params(m))?;
            renderer.wait_idle()?;
            wall_times[i].push(start.elapsed().as_secs_f64() * 1e3);
            if let Some(ms) = renderer.read_gpu_time_ms()? {
                gpu_times[i].push(ms);
            }
        }
    }
    let input = scene.map_or(0, Scene::triangle_count);
    // Accuracy from the CPU twin; a sky does not change the geometry, so sky methods share
    // the accuracy of the same method without one.
    let mut accuracies: Vec<Option<Accuracy>> = vec![None; methods.len()];
    if let Some(scene) = scene {
        for (i, m) in methods.iter().enumerate() {
            let base = methods[..i]
                .iter()
                .position(|o| o.mode == m.mode && o.tess == m.tess)
                .and_then(|j| accuracies[j]);
            accuracies[i] = Some(base.unwrap_or_else(|| {
                accuracy::accuracy(config, scene, case.head, case.world_from_cave, m)
            }));
        }
    }
    // The picture against the reference render (one read-back per method, outside the timing).
    let mut diffs: Vec<Option<f64>> = vec![None; methods.len()];
    if scene.is_some() {
        renderer.render(&params(&reference_method()))?;
        let reference = renderer.read_images()?;
        for (i, m) in methods.iter().enumerate() {
            let base = methods[..i]
                .iter()
                .position(|o| o.mode == m.mode && o.tess == m.tess)
                .and_then(|j| diffs[j]);
            diffs[i] = Some(match base {
                Some(d) => d,
                None => {
                    // Without the sky, as the reference: the comparison is of the geometry,
                    // and methods differing only by their sky share it.
                    let mut p = params(m);
                    p.sky.mode = SkyMode::Off;
                    renderer.render(&p)?;
                    image_difference_pct(&renderer.read_images()?, &reference)
                }
            });
        }
    }
    Ok(methods
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let mut wall = std::mem::take(&mut wall_times[i]);
            wall.sort_by(f64::total_cmp);
            let mut times = std::mem::take(&mut gpu_times[i]);
            times.sort_by(f64::total_cmp);
            let wall_median_ms = percentile(&wall, 0.5);
            Row {
                scene: scene_name.to_owned(),
                viewpoint: case.viewpoint.clone(),
                head: case.head_name.clone(),
                method: m.clone(),
                timer,
                times_ms: if timer == Timer::Gpu { times } else { wall },
                wall_median_ms,
                input_triangles: input,
                drawn_triangles: drawn[i],
                accuracy: accuracies[i],
                image_diff_pct: diffs[i],
            }
        })
        .collect())
}

fn write_file(path: &Path, text: &str) -> Result<(), BenchError> {
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

fn write_outputs(
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
    // Plain off-axis stereo of the same case; none for an empty scene, whose reference frame
    // would be a bare clear.
    let reference = |r: &Row| {
        find(rows, r, |m| {
            m.mode == RenderMode::Stereo && m.sky.is_none() && m.tess.criterion.is_none()
        })
        .filter(|o| o.input_triangles > 0)
    };
    let without_sky = |r: &Row| {
        find(rows, r, |m| {
            m.mode == r.method.mode && m.tess == r.method.tess && m.sky.is_none()
        })
    };

    let mut csv = String::from(
        "scene,viewpoint,head,method,mode,tessellation,sky,frames,timer,median_ms,p25_ms,p75_ms,min_ms,\
         max_ms,wall_median_ms,input_triangles,drawn_triangles,ratio_to_stereo,ratio_to_no_sky,\
         error_max_px,error_p99_px,error_samples,cpu_input_triangles,cpu_culled_triangles,\
         cpu_drawn_triangles,image_diff_pct,seam_max_px,seam_p99_px,seam_crossings\n",
    );
    for r in rows {
        let ratio = |other: Option<&Row>| {
            other.map_or(String::new(), |o| format!("{:.4}", r.median() / o.median()))
        };
        let seam = r.accuracy.map_or(",,".to_owned(), |a| {
            format!("{:.4},{:.4},{}", a.seam.max, a.seam.p99, a.seam.samples)
        });
        let accuracy = r.accuracy.map_or(",,,,,".to_owned(), |a| {
            format!(
                "{:.4},{:.4},{},{},{},{}",
                a.error.max, a.error.p99, a.error.samples, a.input, a.culled, a.emitted
            )
        });
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{},{},{},{},{accuracy},{},{seam}",
            r.scene,
            r.viewpoint,
            r.head,
            r.method.name,
            r.method.mode.name(),
            r.method
                .tess
                .criterion
                .map_or("none".into(), |c| c.to_string()),
            r.method.sky.map_or("none", SkyMode::name),
            r.times_ms.len(),
            r.timer.name(),
            r.median(),
            percentile(&r.times_ms, 0.25),
            percentile(&r.times_ms, 0.75),
            r.times_ms.first().copied().unwrap_or(f64::NAN),
            r.times_ms.last().copied().unwrap_or(f64::NAN),
            r.wall_median_ms,
            r.input_triangles,
            r.drawn_triangles,
            ratio(reference(r)),
            if r.method.sky.is_some() {
                ratio(without_sky(r))
            } else {
                String::new()
            },
            r.image_diff_pct
                .map_or(String::new(), |d| format!("{d:.3}")),
        );
    }
    let csv_path = options.out.join("results.csv");
    write_file(&csv_path, &csv)?;

    let walls: Vec<String> = config
        .cave
        .walls
        .iter()
        .map(|w| format!("{} {}×{}", w.name, w.resolution[0], w.resolution[1]))
        .collect();
    let timer = rows.first().map_or("none", |r| r.timer.name());
    let mut md = String::new();
    let _ = writeln!(md, "# omnicave benchmark\n");
    let _ = writeln!(
        md,
        "- adapter: {adapter}\n- machine: {}\n- CAVE: {} ({}), MSAA ×{}, both eyes\n- timer: {timer}; \
         median of {frames} frames per method, methods interleaved frame by frame\n- command: \
         `omnicave bench --config {}{}{}{}{}`\n",
        machine(),
        options.config.display(),
        walls.join(", "),
        config.settings.render.msaa,
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
    let _ = writeln!(md, "## Frame time of the whole stereo frame\n");
    let _ = writeln!(
        md,
        "| scene | viewpoint | head | method | median ms | p25–p75 ms | × stereo | drawn triangles |\n|---|---|---|---|---:|---:|---:|---:|"
    );
    for r in rows {
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
            reference(r).map_or("–".into(), |o| format!("{:.3}", r.median() / o.median())),
            r.drawn_triangles,
        );
    }
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
    let summary = summarise(rows);
    write_accuracy_sections(&mut md, &summary);
    let md_path = options.out.join("report.md");
    write_file(&md_path, &md)?;
    let mut files = vec![csv_path, md_path];
    if let Some(first) = summary.first() {
        let points = chart_points(first);
        let svg = chart::svg(
            &points,
            &format!("Speed against accuracy: {}", first.scene),
            &format!(
                "walls {} · MSAA ×{} · median frame time and worst p99 error over {} \
                 viewpoint/head case(s)",
                walls.join(", "),
                config.settings.render.msaa,
                first.cases
            ),
        );
        let svg_path = options.out.join("speed-vs-accuracy.svg");
        write_file(&svg_path, &svg)?;
        files.push(svg_path);
        let png_path = options.out.join("speed-vs-accuracy.png");
        let png = chart::png(&svg).map_err(|message| BenchError::Chart {
            path: png_path.clone(),
            message,
        })?;
        std::fs::write(&png_path, png).map_err(|source| BenchError::Write {
            path: png_path.clone(),
            source,
        })?;
        files.push(png_path);
    }
    Ok(files)
}

/// What `bench --stability` runs.
#[derive(Debug, Clone)]
pub struct StabilityOptions {
    pub config: PathBuf,
    pub out: PathBuf,
    /// Every ninth head position for the rendered part (the CPU vertex sweep stays whole).
    pub quick: bool,
    /// Wall size of the rendered part's images (default [`STABILITY_SIZE`]).
    pub size: Option<[u32; 2]>,
}

/// Wall size of the rendered part of the stability sweep: a quarter of the thesis CAVE's in
/// each direction, enough to show holes a pixel wide and render the whole grid in minutes.
pub const STABILITY_SIZE: [u32; 2] = [320, 180];

/// Runs the stability sweep (`bench --stability`) on the config's CAVE: the CPU vertex sweep for
/// every warp configuration, then every rendered method on the closed sweep scene over the
/// head grid (holes on the GPU, popping with the CPU twin); writes `stability.md` and
/// `stability.csv` into `out`. `progress(done, total, what)` is told before each method.
pub fn run_stability(
    options: &StabilityOptions,
    progress: &mut dyn FnMut(usize, usize, &str),
) -> Result<Vec<PathBuf>, BenchError> {
    let (config_path, out) = (&options.config, &options.out);
    let config = Config::load(config_path)?;
    let mut results = Vec::new();
    for (name, settings) in stability::configurations() {
        tracing::info!("stability sweep: {name}");
        results.push((
            name,
            stability::sweep(&config.cave, config.settings.cave.eye_separation, settings),
        ));
    }
    let rendered = run_rendered_sweep(options, &config, progress)?;
    std::fs::create_dir_all(out).map_err(|source| BenchError::Write {
        path: out.to_owned(),
        source,
    })?;
    let mut csv = String::from(
        "warp,heads,vertices,triangles,non_finite,ghost_vertices,misplaced_vertices,\
         exploded_triangles,torn_triangles\n",
    );
    for (name, f) in &results {
        let cells: Vec<String> = f.counts().iter().map(usize::to_string).collect();
        let _ = writeln!(csv, "{},{}", name.replace(',', ";"), cells.join(","));
    }
    let csv_path = out.join("stability.csv");
    write_file(&csv_path, &csv)?;
    let mut rendered_csv = String::from(
        "method,edge_points,max_error_px,max_pop_px,points_popping,frames,frames_with_holes,\
         hole_pixels,worst_frame_holes_pct\n",
    );
    for (m, r) in &rendered {
        let _ = writeln!(
            rendered_csv,
            "{},{},{:.4},{:.4},{},{},{},{},{:.4}",
            m.name.replace(',', ";"),
            r.motion.samples,
            r.motion.max_error_px,
            r.motion.max_pop_px,
            r.motion.popping,
            r.frames,
            r.frames_with_holes,
            r.hole_pixels,
            r.worst_frame_pct
        );
    }
    let rendered_csv_path = out.join("stability-rendered.csv");
    write_file(&rendered_csv_path, &rendered_csv)?;
    let heads = results.first().map_or(0, |(_, f)| f.heads);
    let mut md = format!(
        "# omnicave stability sweep\n\n- CAVE: {} ({} walls), eye separation {} m\n- {heads} head \
         positions over the walls' bounding box, the outer ones 5 cm from the walls and the \
         ceiling edge; around each, small triangles every 30° of azimuth at elevations −89.9° \
         to 89.9° (0.1° from the poles) 0.4, 2 and 12 m away, and large triangles across the \
         wall seams and the pole; every wall and eye\n- command: `omnicave bench --stability \
         --config {}`\n\n",
        config_path.display(),
        config.cave.walls.len(),
        config.settings.cave.eye_separation,
        config_path.display()
    );
    md.push_str(&stability::markdown(&results));
    md.push_str(
        "\nghost: a vertex drawn on a wall through which its own eye cannot see it; misplaced: \
         drawn more than 1 px from where its own eye sees it; exploded: a triangle drawn more \
         than twice (+10 px) the size of its exact image; torn: a small triangle whose corners' \
         eyes jumped by more than half the eye separation (eyes flipping across the pole).\n",
    );
    if let Some((name, f)) = results.first() {
        let _ = writeln!(
            md,
            "\nRecommended configuration ({name}): {}\n",
            if f.total() == 0 {
                "no failure of any kind.".to_owned()
            } else {
                format!("{} failures — see the table.", f.total())
            }
        );
    }
    let size = options.size.unwrap_or(STABILITY_SIZE);
    let rendered_heads = rendered.first().map_or(0, |(_, r)| r.frames);
    let _ = writeln!(
        md,
        "## Rendered: holes and popping\n\nA closed room around the CAVE (one quad per face, \
         seen from inside: every pixel of every wall must show it) with closed boxes over the \
         centre (the pole overhead), on the floor under it (the pole underfoot), behind the \
         viewer and outside every seam; {rendered_heads} head positions of the grid{}. Holes: \
         pixels showing the background. Error: distance between where a point of a scene edge \
         is drawn and where the recommended omnistereo ideal puts it ({} points per edge). Pop: \
         how much that error jumps as the head moves {} mm (the second difference over three \
         head positions in a row, so a smoothly growing error does not count).\n",
        if options.quick { " (every ninth)" } else { "" },
        stability::POP_SAMPLES_PER_EDGE,
        stability::POP_STEP_M * 1000.0,
    );
    md.push_str(&stability::rendered_markdown(&rendered, size));
    if let Some((m, r)) = rendered.first() {
        let _ = writeln!(
            md,
            "\nRecommended method ({}): {} hole pixels, {} points popping, largest error {:.2} px.",
            m.name, r.hole_pixels, r.motion.popping, r.motion.max_error_px
        );
    }
    let md_path = out.join("stability.md");
    write_file(&md_path, &md)?;
    Ok(vec![csv_path, rendered_csv_path, md_path])
}

/// The rendered part of the sweep: every method of [`stability::sweep_methods`] at the grid's
/// head positions, holes counted on the GPU's images, popping with the CPU twin.
fn run_rendered_sweep(
    options: &StabilityOptions,
    config: &Config,
    progress: &mut dyn FnMut(usize, usize, &str),
) -> Result<Vec<(stability::SweepMethod, stability::Rendered)>, BenchError> {
    let scene = stability::sweep_scene(&config.cave);
    let mut cave = config.cave.clone();
    let size = options.size.unwrap_or(STABILITY_SIZE);
    for wall in &mut cave.walls {
        wall.resolution = size;
    }
    let heads: Vec<Vec3> = stability::sweep_heads(&config.cave)
        .into_iter()
        .enumerate()
        .filter(|(i, _)| !options.quick || i % 9 == 0)
        .map(|(_, h)| h)
        .collect();
    // The neighbouring heads: 2 mm either way along a diagonal (the grid stays 5 cm inside).
    let step = stability::POP_STEP_M * Vec3::new(1.0, 0.6, 0.8).normalize();
    let gpu = Gpu::headless()?;
    let mut renderer = Renderer::new(
        &gpu,
        &cave,
        RenderSettings {
            msaa: 1,
            wireframe: false,
        },
    )?;
    renderer.set_scene(&scene);
    let methods = stability::sweep_methods();
    let mut out = Vec::new();
    for (i, method) in methods.iter().enumerate() {
        progress(i, methods.len(), method.name);
        tracing::info!("stability sweep, rendered: {}", method.name);
        let mut r = stability::Rendered::default();
        for &head in &heads {
            let mut p = frame_params(config);
            p.cave = &cave;
            p.head = Head::at(head);
            p.mode = method.mode;
            p.omni = method.omni;
            p.tess = method.tess;
            p.world_from_cave = Mat4::IDENTITY;
            p.background = stability::HOLE_COLOUR;
            p.sky.mode = SkyMode::Off;
            renderer.render(&p)?;
            let images = renderer.read_images()?;
            let (mut holes, mut total) = (0u64, 0u64);
            for wall in &images {
                for img in [&wall.left, &wall.right] {
                    total += img.pixels().len() as u64;
                    holes += img
                        .pixels()
                        .filter(|px| stability::is_hole([px.0[0], px.0[1], px.0[2]]))
                        .count() as u64;
                }
            }
            r.frames += 1;
            r.hole_pixels += holes;
            if holes > 0 {
                r.frames_with_holes += 1;
            }
            r.worst_frame_pct = r
                .worst_frame_pct
                .max(100.0 * holes as f64 / total.max(1) as f64);
            r.motion = r.motion.merge(stability::motion(
                &config.cave,
                &scene,
                config.settings.cave.eye_separation,
                method,
                head,
                step,
            ));
        }
        out.push((*method, r));
    }
    progress(methods.len(), methods.len(), "done");
    Ok(out)
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
}

/// The methods of one scene.
#[derive(Debug, Clone)]
pub struct SceneSummary {
    pub scene: String,
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
                            Some(r.median() / reference.median())
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
                    }
                })
                .collect();
            SceneSummary {
                scene,
                cases: cases.len(),
                methods,
            }
        })
        .collect()
}

/// The chart's points: one per method, grouped by family.
pub fn chart_points(summary: &SceneSummary) -> Vec<chart::ChartPoint> {
    summary
        .methods
        .iter()
        .map(|m| chart::ChartPoint {
            family: family(&m.method),
            label: m
                .method
                .tess
                .criterion
                .map(|c| c.to_string().split(':').nth(1).unwrap_or("").to_owned())
                .unwrap_or_default(),
            time_ms: m.time_ms,
            error_px: f64::from(m.error_p99),
        })
        .collect()
}

/// The reference render for the image comparison: the off-axis warp tessellated until the
/// geometric error is below 0.05 px (DESIGN.md's reference), deep enough for the city's
/// ground quad.
pub fn reference_method() -> Method {
    Method {
        name: "reference: omni-offaxis + tess error:0.05, depth 10".into(),
        mode: RenderMode::OmniOffAxis,
        tess: TessSettings {
            criterion: Some(Criterion::Error(0.05)),
            max_depth: 10,
            ..TessSettings::default()
        },
        sky: None,
    }
}

/// A pixel differs visibly when a channel is off by more than this (of 255): a different
/// surface or a shifted texture, not a shading nuance (lighting from the per-vertex eye differs
/// by a few levels at most).
pub const VISIBLE_DIFFERENCE: u8 = 24;

/// Share (%) of pixels of `images` that differ visibly from `reference`.
pub fn image_difference_pct(images: &[WallImages], reference: &[WallImages]) -> f64 {
    let mut total = 0usize;
    let mut differing = 0usize;
    for (a, b) in images.iter().zip(reference) {
        for (p, q) in [(&a.left, &b.left), (&a.right, &b.right)] {
            total += p.pixels().len();
            differing += p
                .pixels()
                .zip(q.pixels())
                .filter(|(u, v)| (0..3).any(|c| u.0[c].abs_diff(v.0[c]) > VISIBLE_DIFFERENCE))
                .count();
        }
    }
    100.0 * differing as f64 / total.max(1) as f64
}

/// The error target the report answers for (px, 99th percentile).
pub const TARGET_P99_PX: f32 = 0.5;

fn write_accuracy_sections(md: &mut String, summary: &[SceneSummary]) {
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
             than {VISIBLE_DIFFERENCE}/255 from the reference render (omni-offaxis + \
             error:0.05 at depth 10), worst over the heads. Seam: the largest jump, along the \
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
        let tessellated = |m: &&MethodSummary| {
            m.method.mode.is_omni()
                && m.method.tess.criterion.is_some()
                && m.error_p99 <= TARGET_P99_PX
        };
        let best = s
            .methods
            .iter()
            .filter(tessellated)
            .min_by(|a, b| a.time_ms.total_cmp(&b.time_ms));
        let _ = writeln!(
            md,
            "\n**At ≤ {TARGET_P99_PX} px p99 error** ({}): {}\n",
            s.scene,
            match best {
                Some(m) => format!(
                    "the fastest omnistereo + tessellation method is `{}`, {:.2} ms, **{} × \
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
            .filter(|m| m.method.tess.criterion.is_some())
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
                .find(|m| family(&m.method) == kind && m.error_p99 <= TARGET_P99_PX);
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

    #[test]
    fn percentiles_interpolate() {
        let v = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(percentile(&v, 0.5), 2.5);
        assert_eq!(percentile(&v, 0.0), 1.0);
        assert_eq!(percentile(&v, 1.0), 4.0);
        assert!(percentile(&[], 0.5).is_nan());
    }

    #[test]
    fn methods_start_with_the_reference_and_cover_every_sky_mode() {
        let m = methods(false);
        assert_eq!(m[0].mode, RenderMode::Stereo);
        assert!(m[0].sky.is_none() && m[0].tess.criterion.is_none());
        for sky in [SkyMode::Offaxis, SkyMode::OmniQuad, SkyMode::OmniExact] {
            assert!(m.iter().any(|x| x.sky == Some(sky)));
        }
    }
}
