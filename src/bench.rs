//! The benchmark (`omnicave bench`): frame times of every rendering method on scenes and head
//! positions, measured in one run so that methods compare by ratio, written as CSV and Markdown.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;

use crate::cave::{Head, RenderMode};
use crate::config::{Config, ConfigError};
use crate::headless::frame_params;
use crate::render::{Gpu, RenderError, RenderSettings, Renderer};
use crate::scene::{Scene, SceneError, load_gltf};
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

/// The methods compared, the reference (plain off-axis stereo, no sky) first.
pub fn methods() -> Vec<Method> {
    let tess = TessSettings {
        criterion: Some(Criterion::Error(0.5)),
        ..TessSettings::default()
    };
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
    vec![
        m(RenderMode::Stereo, none, None),
        m(RenderMode::Stereo, none, Some(SkyMode::Offaxis)),
        m(RenderMode::OmniOffAxis, none, None),
        m(RenderMode::OmniOffAxis, none, Some(SkyMode::Offaxis)),
        m(RenderMode::OmniOffAxis, none, Some(SkyMode::OmniQuad)),
        m(RenderMode::OmniOffAxis, none, Some(SkyMode::OmniExact)),
        m(RenderMode::OmniOffAxis, tess, None),
        m(RenderMode::OmniOffAxis, tess, Some(SkyMode::OmniExact)),
    ]
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
    pub adapter: String,
    pub files: Vec<PathBuf>,
}

/// Runs the benchmark and writes `results.csv` and `report.md` into the output folder.
pub fn run(options: &BenchOptions) -> Result<BenchReport, BenchError> {
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

    let mut heads = vec![("centred".to_owned(), config.head.position)];
    if !options.quick {
        heads.push((
            "0.3 m from the front wall".into(),
            Vec3::new(0.3, 1.7, -1.35),
        ));
    }
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
    let methods = methods();
    let mut rows = Vec::new();
    let total = scenes.len() * heads.len();
    let mut done = 0;
    for (scene_name, scene) in &scenes {
        for (head_name, head) in &heads {
            done += 1;
            tracing::info!(
                "[{done}/{total}] {scene_name}, head {head_name}: {} methods × {frames} frames",
                methods.len()
            );
            rows.extend(measure(
                &gpu,
                &config,
                scene_name,
                scene.as_ref(),
                &sky,
                head_name,
                *head,
                &methods,
                frames,
            )?);
            // Rewritten after every case, so a run that is stopped keeps what it measured.
            write_outputs(options, &config, &adapter, frames, &rows)?;
        }
    }
    let files = write_outputs(options, &config, &adapter, frames, &rows)?;
    Ok(BenchReport {
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
    head_name: &str,
    head: Vec3,
    methods: &[Method],
    frames: usize,
) -> Result<Vec<Row>, BenchError> {
    let mut renderer = Renderer::new(
        gpu,
        &config.cave,
        RenderSettings {
            msaa: config.msaa,
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
        p.head = Head::at(head);
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
                head: head_name.to_owned(),
                method: m.clone(),
                timer,
                times_ms: if timer == Timer::Gpu { times } else { wall },
                wall_median_ms,
                input_triangles: input,
                drawn_triangles: drawn[i],
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
    rows.iter()
        .find(|r| r.scene == like.scene && r.head == like.head && pred(&r.method))
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
        "scene,head,method,mode,tessellation,sky,frames,timer,median_ms,p25_ms,p75_ms,min_ms,\
         max_ms,wall_median_ms,input_triangles,drawn_triangles,ratio_to_stereo,ratio_to_no_sky\n",
    );
    for r in rows {
        let ratio = |other: Option<&Row>| {
            other.map_or(String::new(), |o| format!("{:.4}", r.median() / o.median()))
        };
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{},{},{},{}",
            r.scene,
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
         `omnicave bench --config {}{}{}`\n",
        machine(),
        options.config.display(),
        walls.join(", "),
        config.msaa,
        options.config.display(),
        options
            .size
            .map_or(String::new(), |[w, h]| format!(" --size {w}x{h}")),
        if options.quick { " --quick" } else { "" },
    );
    let _ = writeln!(md, "## Frame time of the whole stereo frame\n");
    let _ = writeln!(
        md,
        "| scene | head | method | median ms | p25–p75 ms | × stereo | drawn triangles |\n|---|---|---|---:|---:|---:|---:|"
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.2} | {:.2}–{:.2} | {} | {} |",
            r.scene,
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
        "| scene | head | render mode | offaxis | omni-quad | omni-exact |\n|---|---|---|---:|---:|---:|"
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
            "| {} | {} | {} | {} | {} | {} |",
            r.scene,
            r.head,
            r.method.name,
            cell(SkyMode::Offaxis),
            cell(SkyMode::OmniQuad),
            cell(SkyMode::OmniExact),
        );
    }
    let md_path = options.out.join("report.md");
    write_file(&md_path, &md)?;
    Ok(vec![csv_path, md_path])
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
        let m = methods();
        assert_eq!(m[0].mode, RenderMode::Stereo);
        assert!(m[0].sky.is_none() && m[0].tess.criterion.is_none());
        for sky in [SkyMode::Offaxis, SkyMode::OmniQuad, SkyMode::OmniExact] {
            assert!(m.iter().any(|x| x.sky == Some(sky)));
        }
    }
}
