//! `omnicave bench --stability`: the CPU vertex sweep of every warp configuration and the
//! rendered sweep of every method (holes on the GPU, popping with the CPU twin), and their
//! reports.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};

use super::error::BenchError;
use super::report::{write_csv, write_file};
use super::stability;
use crate::cave::Head;
use crate::config::Config;
use crate::render::{Gpu, RenderSettings, Renderer};
use crate::setup::frame_params;
use crate::sky::SkyMode;

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

/// A warp configuration's name and what the CPU vertex sweep found.
type SweepResult = (&'static str, stability::Failures);

/// A method and what the rendered sweep found.
type RenderedResult = (stability::SweepMethod, stability::Rendered);

/// Runs the stability sweep (`bench --stability`) on the config's CAVE: the CPU vertex sweep for
/// every warp configuration, then every rendered method on the closed sweep scene over the
/// head grid (holes on the GPU, popping with the CPU twin); writes `stability.md` and
/// `stability.csv` into `out`. `progress(done, total, what)` is told before each method.
pub fn run_stability(
    options: &StabilityOptions,
    progress: &mut dyn FnMut(usize, usize, &str),
) -> Result<Vec<PathBuf>, BenchError> {
    let out = &options.out;
    let config = Config::load(&options.config)?;
    let results = run_vertex_sweeps(&config);
    let rendered = run_rendered_sweep(options, &config, progress)?;
    std::fs::create_dir_all(out).map_err(|source| BenchError::Write {
        path: out.to_owned(),
        source,
    })?;
    let csv_path = out.join("stability.csv");
    write_sweep_csv(&csv_path, &results)?;
    let rendered_csv_path = out.join("stability-rendered.csv");
    write_rendered_csv(&rendered_csv_path, &rendered)?;
    let mut md = sweep_markdown(options, &config, &results);
    md.push_str(&rendered_markdown(options, &rendered));
    let md_path = out.join("stability.md");
    write_file(&md_path, &md)?;
    Ok(vec![csv_path, rendered_csv_path, md_path])
}

/// The CPU vertex sweep of every warp configuration.
fn run_vertex_sweeps(config: &Config) -> Vec<SweepResult> {
    let mut results = Vec::new();
    for (name, settings) in stability::configurations() {
        tracing::info!("stability sweep: {name}");
        results.push((
            name,
            stability::sweep(&config.cave, config.settings.cave.eye_separation, settings),
        ));
    }
    results
}

/// Writes `stability.csv`: the failures of each warp configuration.
fn write_sweep_csv(path: &Path, results: &[SweepResult]) -> Result<(), BenchError> {
    write_csv(
        path,
        &[
            "warp",
            "heads",
            "vertices",
            "triangles",
            "non_finite",
            "ghost_vertices",
            "misplaced_vertices",
            "exploded_triangles",
            "torn_triangles",
        ],
        results.iter().map(|(name, f)| {
            std::iter::once(name.to_string())
                .chain(f.counts().iter().map(usize::to_string))
                .collect()
        }),
    )
}

/// Writes `stability-rendered.csv`: the holes and popping of each rendered method.
fn write_rendered_csv(path: &Path, rendered: &[RenderedResult]) -> Result<(), BenchError> {
    write_csv(
        path,
        &[
            "method",
            "edge_points",
            "max_error_px",
            "max_pop_px",
            "points_popping",
            "frames",
            "frames_with_holes",
            "hole_pixels",
            "worst_frame_holes_pct",
        ],
        rendered.iter().map(|(m, r)| {
            vec![
                m.name.to_owned(),
                r.motion.samples.to_string(),
                format!("{:.4}", r.motion.max_error_px),
                format!("{:.4}", r.motion.max_pop_px),
                r.motion.popping.to_string(),
                r.frames.to_string(),
                r.frames_with_holes.to_string(),
                r.hole_pixels.to_string(),
                format!("{:.4}", r.worst_frame_pct),
            ]
        }),
    )
}

/// The start of `stability.md`: the setup and the CPU vertex sweep's table and verdict.
fn sweep_markdown(options: &StabilityOptions, config: &Config, results: &[SweepResult]) -> String {
    let config_path = &options.config;
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
    md.push_str(&stability::markdown(results));
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
    md
}

/// The rendered part of `stability.md`: what was measured, the table and the verdict.
fn rendered_markdown(options: &StabilityOptions, rendered: &[RenderedResult]) -> String {
    let mut md = String::new();
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
    md.push_str(&stability::rendered_markdown(rendered, size));
    if let Some((m, r)) = rendered.first() {
        let _ = writeln!(
            md,
            "\nRecommended method ({}): {} hole pixels, {} points popping, largest error {:.2} px.",
            m.name, r.hole_pixels, r.motion.popping, r.motion.max_error_px
        );
    }
    md
}

/// The rendered part of the sweep: every method of [`stability::sweep_methods`] at the grid's
/// head positions, holes counted on the GPU's images, popping with the CPU twin.
fn run_rendered_sweep(
    options: &StabilityOptions,
    config: &Config,
    progress: &mut dyn FnMut(usize, usize, &str),
) -> Result<Vec<RenderedResult>, BenchError> {
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
    renderer.set_scene(&scene)?;
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
