//! `omnicave bench`: loads the scenes and the sky, measures every case and writes the
//! reports as it goes.

use std::path::PathBuf;

use super::cases::{bundled_path, cases};
use super::error::BenchError;
use super::measure::{Row, measure};
use super::methods::{Method, methods, select_methods};
use super::options::{BenchOptions, QUICK_SIZE};
use super::panorama;
use super::report::{write_file, write_outputs};
use super::tracking::{TrackingOutcome, Watching, tracking_markdown, write_tracking_csv};
use crate::config::Config;
use crate::render::Gpu;
use crate::render::tessellator::DEFAULT_CAPACITY;
use crate::scene::Scene;
use crate::setup::load_scene;
use crate::sky::{CubeMap, load_sky};
use crate::tess::Criterion;

/// Everything a run produced.
#[derive(Debug, Clone)]
pub struct BenchReport {
    pub rows: Vec<Row>,
    /// The panorama methods (see [`panorama`]).
    pub pano_rows: Vec<panorama::PanoRow>,
    pub adapter: String,
    pub files: Vec<PathBuf>,
    /// What the config's tracking source did during the run.
    pub tracking: TrackingOutcome,
}

/// The methods a scene of `triangles` triangles is measured with: uniform subdivision is left
/// out where its output (4^n triangles per source triangle, n capped at the method's maximum
/// depth) would not fit the tessellator's
/// budget of [`DEFAULT_CAPACITY`] per view: it would be drawn less refined than its name says.
pub fn methods_within_budget(methods: &[Method], triangles: usize) -> Vec<Method> {
    methods
        .iter()
        .filter(|m| match m.tess.criterion {
            Some(Criterion::Uniform(n)) => {
                let levels = n.min(m.tess.max_depth).min(16);
                let out = (triangles as u64).saturating_mul(1u64 << (2 * levels));
                let fits = out <= u64::from(DEFAULT_CAPACITY);
                if !fits {
                    tracing::info!(
                        "{}: {out} triangles per view exceed the tessellator's budget of \
                         {DEFAULT_CAPACITY}; not measured",
                        m.name
                    );
                }
                fits
            }
            _ => true,
        })
        .cloned()
        .collect()
}

/// What the steps of a run share once the scenes, the sky and the GPU are loaded.
struct BenchRun<'a> {
    options: &'a BenchOptions,
    config: &'a Config,
    gpu: &'a Gpu,
    sky: &'a CubeMap,
    /// The adapter, as the report names it.
    adapter: &'a str,
    /// Timed frames per method.
    frames: usize,
}

/// One scene of a run.
struct BenchScene {
    name: String,
    /// `None`: the sky alone.
    scene: Option<Scene>,
    /// An animated scene or its static twin: measured from the start viewpoint only (what
    /// moves stands ahead) and left out of the panorama methods.
    animated_pair: bool,
}

type Scenes = Vec<BenchScene>;

/// Runs the benchmark and writes `results.csv`, `report.md` and the chart into the output
/// folder. `progress(done, total, what)` is told before each case.
pub fn run(
    options: &BenchOptions,
    progress: &mut dyn FnMut(usize, usize, &str),
) -> Result<BenchReport, BenchError> {
    let config = load_config(options)?;
    let scenes = load_scenes(options, &config)?;
    let sky = load_sky(&sky_path(options, &config))?;
    let frames = options
        .frames
        .unwrap_or(if options.quick { 5 } else { 12 })
        .max(1);
    let gpu = Gpu::headless()?;
    let adapter = adapter_name(&gpu);
    let base = config.settings.tess();
    let methods = select_methods(methods(options.quick, base), &options.methods, base)?;
    let run = BenchRun {
        options,
        config: &config,
        gpu: &gpu,
        sky: &sky,
        adapter: &adapter,
        frames,
    };
    let total = run.case_count(&scenes);
    // The tracker is heard while the machine is loaded, as in the lab.
    let watching = Watching::start(&config);
    let rows = run.measure_walls(&scenes, &methods, total, progress)?;
    progress(
        total,
        total,
        "panorama methods (geometric and image routes, against the CPU ray caster)",
    );
    let (pano_rows, pano_files) = run.panoramas(&scenes)?;
    let tracking = watching.finish();
    progress(total, total, "done");
    let files = run.finish_report(&rows, &pano_rows, pano_files, &tracking)?;
    Ok(BenchReport {
        pano_rows,
        rows,
        adapter,
        files,
        tracking,
    })
}

/// The config, with every wall at the run's size where it sets one.
fn load_config(options: &BenchOptions) -> Result<Config, BenchError> {
    let mut config = Config::load(&options.config)?;
    if let Some(size) = options.size.or(options.quick.then_some(QUICK_SIZE)) {
        for wall in &mut config.cave.walls {
            wall.resolution = size;
        }
    }
    Ok(config)
}

/// The scenes measured, loaded and named by their files, then the sky alone.
fn load_scenes(options: &BenchOptions, config: &Config) -> Result<Scenes, BenchError> {
    let mut scenes: Scenes = Vec::new();
    let scene_paths: Vec<PathBuf> = if options.scenes.is_empty() {
        let mut v: Vec<PathBuf> = config.scene_path.iter().cloned().collect();
        // The bundled city and the large atrium (225 108 triangles), for scaling with size.
        for bundled in ["assets/city.glb", "assets/atrium.glb"] {
            let path = bundled_path(&options.config, bundled);
            if path.is_file() && !v.contains(&path) {
                v.push(path);
            }
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
        let scene = load_scene(&config.settings, path)?;
        if scene.rig.is_empty() {
            scenes.push(BenchScene {
                name,
                scene: Some(scene),
                animated_pair: false,
            });
        } else {
            push_with_static_twin(&mut scenes, &name, scene);
        }
    }
    if options.scenes.is_empty() {
        animated_scenes(options, config, &mut scenes)?;
    }
    // The sky alone, over the whole of every wall: its worst case.
    scenes.push(BenchScene {
        name: "sky only".into(),
        scene: None,
        animated_pair: false,
    });
    Ok(scenes)
}

/// Suffix of an animated scene's static twin (the same geometry in its rest pose, nothing
/// posed per frame): the pose pass's cost is the difference.
pub(super) const STATIC_TWIN: &str = " (static)";

/// An animated scene, then the same static.
fn push_with_static_twin(scenes: &mut Scenes, name: &str, scene: Scene) {
    let mut still = scene.clone();
    still.rig = crate::scene::rig::Rig::default();
    scenes.push(BenchScene {
        name: name.to_owned(),
        scene: Some(scene),
        animated_pair: true,
    });
    scenes.push(BenchScene {
        name: format!("{name}{STATIC_TWIN}"),
        scene: Some(still),
        animated_pair: true,
    });
}

/// The animated scenes, each with its static twin: the bundled animated sample (skin, morph
/// targets, an animated node) and, where `../shared/corpus` lies beside the repository, the
/// Fox walking (a 24-joint skin), placed on the floor 1.2 m long, 2 m ahead.
fn animated_scenes(
    options: &BenchOptions,
    config: &Config,
    out: &mut Scenes,
) -> Result<(), BenchError> {
    let mut add = |name: &str, scene: Scene| push_with_static_twin(out, name, scene);
    let sample = bundled_path(&options.config, "assets/animated.glb");
    if sample.is_file() {
        let mut settings = config.settings.clone();
        settings.scene = Default::default();
        settings.animation = Default::default();
        add("animated", load_scene(&settings, &sample)?);
    }
    let fox = bundled_path(&options.config, "../shared/corpus/Fox/Fox.glb");
    if fox.is_file() {
        let mut settings = config.settings.clone();
        settings.scene = crate::config::SceneSection {
            fit: crate::scene::SceneFit::Floor,
            size_m: 1.2,
            offset_m: [0.0, 0.0, -2.0],
            ..Default::default()
        };
        settings.animation = Default::default();
        let mut scene = load_scene(&settings, &fox)?;
        // The Fox walking: its Walk animation alone (the clock plays the first).
        scene.rig.clips.retain(|c| c.name == "Walk");
        add("fox walking", scene);
    } else {
        tracing::info!(
            "bench: {} not found: the Fox is not measured (the shared corpus lies beside the \
             repository)",
            fox.display()
        );
    }
    Ok(())
}

/// The sky's file: the run's, else the config's, else the bundled one.
fn sky_path(options: &BenchOptions, config: &Config) -> PathBuf {
    options
        .sky
        .clone()
        .or_else(|| config.sky_path.clone())
        .unwrap_or_else(|| bundled_path(&options.config, crate::sky::bundled::PATH))
}

/// The adapter's name, backend and driver, as the report names them.
fn adapter_name(gpu: &Gpu) -> String {
    let info = gpu.adapter.get_info();
    format!(
        "{} ({:?}, driver {} {})",
        info.name, info.backend, info.driver, info.driver_info
    )
}

impl BenchRun<'_> {
    /// The cases the walls are measured in, over all scenes (none for a panorama-only run).
    fn case_count(&self, scenes: &Scenes) -> usize {
        let options = self.options;
        scenes
            .iter()
            .filter(|_| !options.panorama_only)
            .map(|s| self.cases(s).len())
            .sum()
    }

    /// The cases `scene` is measured in.
    fn cases(&self, scene: &BenchScene) -> Vec<super::cases::Case> {
        let mut all = cases(self.config, self.options.quick, scene.scene.is_some());
        if scene.animated_pair {
            let start = all.first().map(|c| c.viewpoint.clone());
            all.retain(|c| Some(&c.viewpoint) == start.as_ref());
        }
        all
    }

    /// Measures every case of every scene on the walls, rewriting the reports after each.
    fn measure_walls(
        &self,
        scenes: &Scenes,
        methods: &[Method],
        total: usize,
        progress: &mut dyn FnMut(usize, usize, &str),
    ) -> Result<Vec<Row>, BenchError> {
        let (options, config, frames) = (self.options, self.config, self.frames);
        let mut rows = Vec::new();
        let mut done = 0;
        let wall_scenes: &[BenchScene] = if options.panorama_only { &[] } else { scenes };
        for bench_scene in wall_scenes {
            let (scene_name, scene) = (&bench_scene.name, &bench_scene.scene);
            let triangles = scene.as_ref().map_or(0, Scene::triangle_count);
            let methods = methods_within_budget(methods, triangles);
            for case in self.cases(bench_scene) {
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
                    self.gpu,
                    config,
                    scene_name,
                    scene.as_ref(),
                    self.sky,
                    &case,
                    &methods,
                    frames,
                )?);
                // Rewritten after every case, so a run that is stopped keeps what it measured.
                write_outputs(options, config, self.adapter, frames, &rows)?;
            }
        }
        Ok(rows)
    }

    /// The panorama methods on the scenes with geometry (none when the run names methods).
    fn panoramas(
        &self,
        scenes: &Scenes,
    ) -> Result<(Vec<panorama::PanoRow>, Vec<PathBuf>), BenchError> {
        let with_geometry: Vec<(String, Scene)> = scenes
            .iter()
            .filter(|s| !s.animated_pair)
            .filter_map(|s| s.scene.clone().map(|scene| (s.name.clone(), scene)))
            .collect();
        if !self.options.methods.is_empty() {
            return Ok((Vec::new(), Vec::new()));
        }
        panorama::run_panorama(
            self.gpu,
            self.config,
            &with_geometry,
            &self.options.out,
            self.options.quick,
            self.frames,
        )
    }

    /// Writes the final reports with the panorama and tracking sections at the end of
    /// `report.md`, and `tracking.csv`; returns every file written.
    fn finish_report(
        &self,
        rows: &[Row],
        pano_rows: &[panorama::PanoRow],
        pano_files: Vec<PathBuf>,
        tracking: &TrackingOutcome,
    ) -> Result<Vec<PathBuf>, BenchError> {
        let options = self.options;
        let adapter = self.adapter;
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
            let files = write_outputs(options, self.config, adapter, self.frames, rows)?;
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
            pano_rows,
            panorama::pano_size(options.quick),
            &images,
        ));
        md.push_str(&tracking_markdown(tracking));
        write_file(&md_path, &md)?;
        if options.panorama_only {
            files.push(md_path);
        }
        files.extend(pano_files);
        let csv_path = options.out.join("tracking.csv");
        write_tracking_csv(&csv_path, tracking)?;
        files.push(csv_path);
        Ok(files)
    }
}
