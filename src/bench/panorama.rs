//! The panorama methods in the benchmark: the geometric route (with and without tessellation,
//! equirectangular and Hammer) against the image route (cube maps of two sizes), timed on the
//! GPU and compared with the CPU ray caster; 360° images of every scene for the report.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::error::BenchError;
use super::measure::percentile;
use super::report::write_csv;
use crate::config::Config;
use crate::output;
use crate::pano::raycast::{Comparison, compare, flat_reference};
use crate::pano::{PanoRoute, PanoSettings, PanoStereo, Projection};
use crate::render::{FrameParams, Gpu, RenderSettings, Renderer};
use crate::scene::Scene;
use crate::setup::frame_params;
use crate::tess::{Criterion, TessSettings};

/// The ray caster's colour at each pixel (`None`: nothing hit).
type Reference = Vec<Option<[u8; 3]>>;

/// One panorama method.
#[derive(Debug, Clone, PartialEq)]
pub struct PanoMethod {
    pub name: String,
    pub projection: Projection,
    pub route: PanoRoute,
    /// Geometric route: the tessellation criterion (`None`: drawn untessellated).
    pub criterion: Option<Criterion>,
    /// Image route: cube face pixels.
    pub cube_size: u32,
}

/// The methods of a run (`quick`: one of each kind).
pub fn pano_methods(quick: bool) -> Vec<PanoMethod> {
    let geometric = |projection: Projection, criterion: Option<Criterion>| PanoMethod {
        name: format!(
            "geometric {} {}",
            projection.name(),
            criterion.map_or("untessellated".into(), |c| c.to_string())
        ),
        projection,
        route: PanoRoute::Geometric,
        criterion,
        cube_size: 0,
    };
    let image = |projection: Projection, cube_size: u32| PanoMethod {
        name: format!("image {} cube {cube_size}", projection.name()),
        projection,
        route: PanoRoute::Image,
        criterion: None,
        cube_size,
    };
    let mut v = vec![
        geometric(Projection::Equirectangular, Some(Criterion::Error(0.5))),
        geometric(Projection::Equirectangular, None),
        image(Projection::Equirectangular, 512),
    ];
    if !quick {
        v.extend([
            geometric(Projection::Equirectangular, Some(Criterion::Error(2.0))),
            geometric(Projection::Hammer, Some(Criterion::Error(0.5))),
            image(Projection::Equirectangular, 1024),
            image(Projection::Hammer, 512),
        ]);
    }
    v
}

/// One measured panorama method on one scene.
#[derive(Debug, Clone)]
pub struct PanoRow {
    pub scene: String,
    pub method: PanoMethod,
    /// Sorted GPU (or wall-clock) frame times, ms.
    pub times_ms: Vec<f64>,
    pub gpu_timed: bool,
    /// Triangles the tessellator emitted (geometric route).
    pub emitted: Option<u32>,
    /// Against the CPU ray caster, on the scene in flat colours.
    pub comparison: Comparison,
}

impl PanoRow {
    pub fn median(&self) -> f64 {
        percentile(&self.times_ms, 0.5)
    }
}

/// Panorama size of a run.
pub fn pano_size(quick: bool) -> [u32; 2] {
    if quick { [256, 128] } else { [1024, 512] }
}

fn settings(method: &PanoMethod, size: [u32; 2]) -> PanoSettings {
    PanoSettings {
        projection: method.projection,
        h_fov: std::f32::consts::TAU,
        v_fov: std::f32::consts::PI,
        route: method.route,
        stereo: PanoStereo::Mono,
        yaw: 0.0,
        size,
        cube_size: method.cube_size.max(4),
    }
}

/// What measuring the panorama methods shares: the GPU, the config, the output folder, the
/// panorama size and the frames timed.
struct PanoRun<'a> {
    gpu: &'a Gpu,
    config: &'a Config,
    out: &'a Path,
    size: [u32; 2],
    frames: usize,
}

/// Per projection, the scene in flat colours and the ray caster's picture of it.
type References = Vec<(Projection, Scene, Reference)>;

/// Measures every panorama method on every scene from the config's head, writes
/// `panorama.csv` and 360° equirectangular and Hammer images of each scene into `out`, and
/// returns the rows and the files written.
pub fn run_panorama(
    gpu: &Gpu,
    config: &Config,
    scenes: &[(String, Scene)],
    out: &Path,
    quick: bool,
    frames: usize,
) -> Result<(Vec<PanoRow>, Vec<PathBuf>), BenchError> {
    std::fs::create_dir_all(out).map_err(|source| BenchError::Write {
        path: out.to_owned(),
        source,
    })?;
    let run = PanoRun {
        gpu,
        config,
        out,
        size: pano_size(quick),
        frames,
    };
    let methods = pano_methods(quick);
    let mut rows = Vec::new();
    let mut files = Vec::new();
    for (scene_name, scene) in scenes {
        // The reference: the ray caster on the scene in flat colours, once per projection
        // (mono, full sphere, from the head).
        let mut references: References = Vec::new();
        for method in &methods {
            let row = run.measure_method(scene_name, scene, method, &mut references, &mut files)?;
            rows.extend(row);
        }
    }
    let csv_path = out.join("panorama.csv");
    write_pano_csv(&csv_path, &rows)?;
    files.insert(0, csv_path);
    Ok((rows, files))
}

impl PanoRun<'_> {
    /// Times one method on one scene, writes its report image where it is the recommended
    /// route (appending the path to `files`) and compares it with the ray caster.
    fn measure_method(
        &self,
        scene_name: &str,
        scene: &Scene,
        method: &PanoMethod,
        references: &mut References,
        files: &mut Vec<PathBuf>,
    ) -> Result<Option<PanoRow>, BenchError> {
        let config = self.config;
        let pano = settings(method, self.size);
        let tess = TessSettings {
            criterion: method.criterion,
            ..config.settings.tess()
        };
        let mut renderer = Renderer::new(
            self.gpu,
            &config.cave,
            RenderSettings {
                msaa: 1,
                wireframe: false,
            },
        )?;
        let gpu_timed = renderer.enable_gpu_timing(self.gpu);
        renderer.set_scene(scene)?;
        let mut frame = frame_params(config);
        frame.tess = tess;
        let times = self.time_frames(&mut renderer, &frame, &pano, gpu_timed)?;
        let emitted = renderer
            .read_panorama_tess_stats()?
            .first()
            .map(|s| s.emitted);
        files.extend(self.write_report_image(&renderer, scene_name, method)?);
        // Accuracy: the same method on the flat-coloured scene against the ray caster.
        if !references.iter().any(|(p, _, _)| *p == method.projection) {
            let (flat, reference) = flat_reference(
                scene,
                config.settings.world_from_cave().inverse(),
                &pano,
                config.settings.head().position,
                config.cave.near,
                config.cave.far,
            );
            references.push((method.projection, flat, reference));
        }
        let Some((_, flat, reference)) =
            references.iter().find(|(p, _, _)| *p == method.projection)
        else {
            return Ok(None);
        };
        renderer.set_scene(flat)?;
        renderer.render_panorama(&frame, &pano)?;
        let comparison = self.compare_with(&renderer, reference)?;
        tracing::info!(
            "panorama {scene_name}, {}: {:.2} ms, {:.3} % of pixels off the ray caster",
            method.name,
            percentile(&times, 0.5),
            comparison.differ_pct()
        );
        Ok(Some(PanoRow {
            scene: scene_name.to_owned(),
            method: method.clone(),
            times_ms: times,
            gpu_timed,
            emitted,
            comparison,
        }))
    }

    /// One frame to build buffers, then the timed ones; returns their sorted times (GPU
    /// where timed, else wall-clock), ms.
    fn time_frames(
        &self,
        renderer: &mut Renderer,
        frame: &FrameParams<'_>,
        pano: &PanoSettings,
        gpu_timed: bool,
    ) -> Result<Vec<f64>, BenchError> {
        let mut times = Vec::with_capacity(self.frames);
        renderer.render_panorama(frame, pano)?;
        renderer.wait_idle()?;
        for _ in 0..self.frames {
            let start = std::time::Instant::now();
            renderer.render_panorama(frame, pano)?;
            renderer.wait_idle()?;
            let wall = start.elapsed().as_secs_f64() * 1e3;
            times.push(match renderer.read_gpu_time_ms()? {
                Some(ms) if gpu_timed => ms,
                _ => wall,
            });
        }
        times.sort_by(f64::total_cmp);
        Ok(times)
    }

    /// The textured, lit image for the report (recommended route only): writes the panorama
    /// just rendered and returns its path.
    fn write_report_image(
        &self,
        renderer: &Renderer,
        scene_name: &str,
        method: &PanoMethod,
    ) -> Result<Option<PathBuf>, BenchError> {
        if (method.projection == Projection::Equirectangular
            || method.projection == Projection::Hammer)
            && method.route == PanoRoute::Geometric
            && method.criterion == Some(Criterion::Error(0.5))
        {
            let [image, _] = renderer.read_panorama()?;
            let path = self.out.join(format!(
                "panorama-{scene_name}-{}.png",
                method.projection.name()
            ));
            output::write_png(&path, &image).map_err(|e| BenchError::Write {
                path: path.clone(),
                source: std::io::Error::other(e.to_string()),
            })?;
            return Ok(Some(path));
        }
        Ok(None)
    }

    /// The panorama just rendered against the ray caster's `reference`.
    fn compare_with(
        &self,
        renderer: &Renderer,
        reference: &Reference,
    ) -> Result<Comparison, BenchError> {
        let [image, _] = renderer.read_panorama()?;
        let pixels: Vec<[u8; 3]> = image.pixels().map(|p| [p[0], p[1], p[2]]).collect();
        let bg = self
            .config
            .settings
            .render
            .background
            .map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
        Ok(compare(&pixels, reference, self.size[0] as usize, bg))
    }
}

/// Writes `panorama.csv`: one line per measured method and scene.
fn write_pano_csv(path: &Path, rows: &[PanoRow]) -> Result<(), BenchError> {
    write_csv(
        path,
        &[
            "scene",
            "method",
            "projection",
            "route",
            "criterion",
            "cube_size",
            "median_ms",
            "p25_ms",
            "p75_ms",
            "timer",
            "emitted_triangles",
            "pixels_off_pct",
            "off_away_from_edges_pct",
        ],
        rows.iter().map(|r| {
            vec![
                r.scene.clone(),
                r.method.name.clone(),
                r.method.projection.name().to_owned(),
                r.method.route.name().to_owned(),
                r.method.criterion.map_or("none".into(), |c| c.to_string()),
                r.method.cube_size.to_string(),
                format!("{:.3}", r.median()),
                format!("{:.3}", percentile(&r.times_ms, 0.25)),
                format!("{:.3}", percentile(&r.times_ms, 0.75)),
                if r.gpu_timed { "gpu" } else { "wall" }.to_owned(),
                r.emitted.map_or(String::new(), |e| e.to_string()),
                format!("{:.4}", r.comparison.differ_pct()),
                format!("{:.4}", r.comparison.away_pct()),
            ]
        }),
    )
}

/// The report's panorama section: the table and the 360° images.
pub fn pano_markdown(rows: &[PanoRow], size: [u32; 2], images: &[PathBuf]) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "\n## Panorama (360° × 180°, {}×{} px, mono, from the config's head)\n",
        size[0], size[1]
    );
    let _ = writeln!(
        md,
        "Accuracy: the same method on the scene in flat colours against the CPU ray caster \
         (`src/pano/raycast.rs`); \"off\" counts pixels of another colour, \"away from \
         edges\" those not next to a colour edge of the reference. Time relative to the \
         image route with 512 px faces on the same scene.\n"
    );
    let _ = writeln!(
        md,
        "| scene | method | median ms | × image 512 | triangles | off % | away from edges % |\n\
         |---|---|---:|---:|---:|---:|---:|"
    );
    for r in rows {
        let baseline = rows.iter().find(|b| {
            b.scene == r.scene
                && b.method.route == PanoRoute::Image
                && b.method.cube_size == 512
                && b.method.projection == Projection::Equirectangular
        });
        let _ = writeln!(
            md,
            "| {} | {} | {:.2} | {} | {} | {:.3} | {:.4} |",
            r.scene,
            r.method.name,
            r.median(),
            baseline.map_or("–".into(), |b| format!("{:.2}", r.median() / b.median())),
            r.emitted.map_or("–".into(), |e| e.to_string()),
            r.comparison.differ_pct(),
            r.comparison.away_pct(),
        );
    }
    if !images.is_empty() {
        let _ = writeln!(md);
        for path in images {
            if let Some(name) = path.file_name().map(|n| n.to_string_lossy()) {
                let _ = writeln!(md, "![{name}]({name})\n");
            }
        }
    }
    md
}
