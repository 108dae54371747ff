//! Measuring one case: every method's frame times (GPU timestamps, interleaved frame by
//! frame), its accuracy from the CPU twin, and its picture against the reference render.

use std::time::Instant;

use super::accuracy::{self, Accuracy};
use super::cases::Case;
use super::error::BenchError;
use super::methods::{Method, MethodShadows, Timer, reference_method};
use crate::cave::Head;
use crate::config::Config;
use crate::render::frame_timer::STAGES_PER_VIEW;
use crate::render::{FrameParams, Gpu, RenderSettings, Renderer, ViewStage, WallImages};
use crate::scene::Scene;
use crate::setup::frame_params;
use crate::sky::{CubeMap, SkyMode};

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
    /// The same times in the order measured: one per round, each round rendering every
    /// method once (see [`Row::ratio_to`]).
    pub rounds_ms: Vec<f64>,
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
    /// Median over the frames of each stage's GPU time, ms, summed over the views: the pose
    /// pass, the shadow maps, then [`ViewStage::ALL`] (`None` without timestamps).
    pub stages_ms: Option<[f64; STAGE_COLUMNS]>,
    /// Compute dispatches per frame.
    pub dispatches: usize,
    /// Source triangles that entered the tessellator per frame (all refinements: one per
    /// wall where both eyes share it).
    pub refined_input: usize,
}

/// Stage columns: the pose pass, the shadow maps, then each view stage.
pub const STAGE_COLUMNS: usize = 2 + STAGES_PER_VIEW;

/// Names of the stage columns.
pub fn stage_names() -> [&'static str; STAGE_COLUMNS] {
    let mut out = ["shadows"; STAGE_COLUMNS];
    out[0] = "pose";
    for (o, s) in out[2..].iter_mut().zip(ViewStage::ALL) {
        *o = s.name();
    }
    out
}

/// Seconds the animation clock advances per rendered frame of an animated scene (every
/// frame a new instant, so that every frame pays the pose pass and redraws the shadows, as
/// in a running application at 60 Hz).
const ANIMATION_STEP_S: f64 = 1.0 / 60.0;
/// The instant the accuracy and the picture of an animated scene are taken at, seconds.
const ANIMATION_CHECK_S: f64 = 1.0;

impl Row {
    pub fn median(&self) -> f64 {
        percentile(&self.times_ms, 0.5)
    }

    /// This method's time relative to `other`'s in the same case: the median over rounds of
    /// the ratio of the two frames each round rendered, seconds apart. A shared machine (a
    /// software rasteriser on a virtual machine) drifts by tens of percent within a minute;
    /// pairing frames cancels what the two frames of a round share, which a ratio of medians
    /// over the whole run does not. A ratio of medians when the rounds do not pair up.
    pub fn ratio_to(&self, other: &Row) -> f64 {
        if self.rounds_ms.len() != other.rounds_ms.len() || self.rounds_ms.is_empty() {
            return self.median() / other.median();
        }
        let mut ratios: Vec<f64> = self
            .rounds_ms
            .iter()
            .zip(&other.rounds_ms)
            .map(|(a, b)| a / b)
            .collect();
        ratios.sort_by(f64::total_cmp);
        percentile(&ratios, 0.5)
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

/// Per method, what its warm-up and timed frames collected.
#[derive(Debug, Clone)]
struct MethodTimes {
    /// GPU frame times (ms) in the order measured (empty without timestamps).
    gpu: Vec<f64>,
    /// Wall-clock frame times (ms) in the order measured.
    wall: Vec<f64>,
    /// Per frame, each stage's GPU time (ms).
    stages: Vec<[f64; STAGE_COLUMNS]>,
    /// Triangles drawn over all views.
    drawn: usize,
    dispatches: usize,
    refined_input: usize,
}

/// What the steps of measuring one case share: the config, the scene, the case, its methods
/// and the timer read.
struct CaseRun<'a> {
    config: &'a Config,
    scene_name: &'a str,
    scene: Option<&'a Scene>,
    case: &'a Case,
    methods: &'a [Method],
    timer: Timer,
    /// The animation clock (seconds) the next frame is rendered at.
    instant: std::cell::Cell<f64>,
    /// The scene posed at [`ANIMATION_CHECK_S`], for the accuracy (`None`: nothing moves).
    posed: Option<Scene>,
}

#[allow(clippy::too_many_arguments)]
pub(super) fn measure(
    gpu: &Gpu,
    config: &Config,
    scene_name: &str,
    scene: Option<&Scene>,
    sky: &CubeMap,
    case: &Case,
    methods: &[Method],
    frames: usize,
) -> Result<Vec<Row>, BenchError> {
    let (mut renderer, timer) = bench_renderer(gpu, config, scene, sky)?;
    let posed = scene.filter(|s| !s.rig.is_empty()).map(|s| {
        let mut posed = s.clone();
        let mut pose = crate::scene::rig::Pose::default();
        let at = s
            .rig
            .pose_at(&crate::scene::rig::Playback {
                seconds: ANIMATION_CHECK_S,
                ..config.settings.playback()
            })
            .unwrap_or(crate::scene::rig::PoseAt::REST);
        s.rig.deform_all(&mut pose, at, &mut posed.vertices);
        posed
    });
    let run = CaseRun {
        config,
        scene_name,
        scene,
        case,
        methods,
        timer,
        instant: std::cell::Cell::new(0.0),
        posed,
    };
    let mut times = run.warm_up(&mut renderer, frames)?;
    run.time_rounds(&mut renderer, frames, &mut times)?;
    run.instant.set(ANIMATION_CHECK_S);
    let accuracies = run.accuracies();
    let diffs = run.image_diffs(&mut renderer)?;
    Ok(methods
        .iter()
        .zip(times)
        .zip(accuracies.into_iter().zip(diffs))
        .map(|((m, t), (accuracy, diff))| run.row(m, t, accuracy, diff))
        .collect())
}

/// A renderer of the config's CAVE with the scene and sky loaded and GPU timing on where the
/// adapter has timestamps; returns it with the timer the bench reads.
fn bench_renderer(
    gpu: &Gpu,
    config: &Config,
    scene: Option<&Scene>,
    sky: &CubeMap,
) -> Result<(Renderer, Timer), BenchError> {
    let mut renderer = Renderer::new(
        gpu,
        &config.cave,
        RenderSettings {
            msaa: config.settings.render.msaa,
            wireframe: false,
        },
    )?;
    if let Some(scene) = scene {
        renderer.set_scene(scene)?;
    }
    renderer.set_sky(Some(sky))?;
    let timer = if renderer.enable_gpu_timing(gpu) {
        Timer::Gpu
    } else {
        Timer::Wall
    };
    Ok((renderer, timer))
}

impl CaseRun<'_> {
    /// The frame parameters of method `m` in this case.
    fn params(&self, m: &Method) -> FrameParams<'_> {
        let mut p = frame_params(self.config);
        p.head = Head::at(self.case.head);
        p.world_from_cave = self.case.world_from_cave;
        p.mode = m.mode;
        p.tess = m.tess;
        p.animation.seconds = self.instant.get();
        p.sky.mode = m.sky.unwrap_or(SkyMode::Off);
        p.shading = m.shading;
        match m.shadows {
            MethodShadows::Config => {}
            MethodShadows::Off => p.shadows.enabled = false,
            MethodShadows::FilterEverywhere => p.shadows.pcf_range_test = false,
        }
        p
    }

    /// One warm-up frame per method (first-use costs), which also counts its drawn
    /// triangles, dispatches and refined input.
    fn warm_up(
        &self,
        renderer: &mut Renderer,
        frames: usize,
    ) -> Result<Vec<MethodTimes>, BenchError> {
        let mut times = Vec::with_capacity(self.methods.len());
        for m in self.methods {
            let stats = renderer.render(&self.params(m))?;
            renderer.wait_idle()?;
            let tess: usize = renderer
                .read_tess_stats()?
                .iter()
                .map(|s| s.emitted as usize)
                .sum();
            times.push(MethodTimes {
                gpu: Vec::with_capacity(frames),
                wall: Vec::with_capacity(frames),
                stages: Vec::with_capacity(frames),
                drawn: if m.tess.criterion.is_some() {
                    tess + stats.fine_triangles
                } else {
                    stats.triangles_submitted
                },
                dispatches: stats.dispatches,
                refined_input: stats.refined_input,
            });
        }
        Ok(times)
    }

    /// The timed frames: round-robin over the methods so that any drift of the machine
    /// spreads over all methods alike.
    fn time_rounds(
        &self,
        renderer: &mut Renderer,
        frames: usize,
        times: &mut [MethodTimes],
    ) -> Result<(), BenchError> {
        for _ in 0..frames {
            for (t, m) in times.iter_mut().zip(self.methods) {
                self.instant.set(self.instant.get() + ANIMATION_STEP_S);
                let start = Instant::now();
                renderer.render(&self.params(m))?;
                renderer.wait_idle()?;
                t.wall.push(start.elapsed().as_secs_f64() * 1e3);
                if let Some(b) = renderer.read_gpu_breakdown()? {
                    t.gpu.push(b.total_ms);
                    let mut stages = [b.shadows_ms; STAGE_COLUMNS];
                    stages[0] = b.pose_ms;
                    for (slot, stage) in stages[2..].iter_mut().zip(ViewStage::ALL) {
                        *slot = b.stage_ms(stage);
                    }
                    t.stages.push(stages);
                }
            }
        }
        Ok(())
    }

    /// Accuracy from the CPU twin; a sky does not change the geometry, so sky methods share
    /// the accuracy of the same method without one. The distinct methods are measured on
    /// every core (each is independent; at a GPU's wall sizes the CPU twin takes longer than
    /// the frames).
    fn accuracies(&self) -> Vec<Option<Accuracy>> {
        let methods = self.methods;
        let mut accuracies: Vec<Option<Accuracy>> = vec![None; methods.len()];
        // An animated scene's accuracy is that of its pose at the checked instant.
        let Some(scene) = self.posed.as_ref().or(self.scene) else {
            return accuracies;
        };
        // Each method's first twin (same mode and tessellation), itself for the distinct ones.
        let first: Vec<usize> = methods
            .iter()
            .enumerate()
            .map(|(i, m)| {
                methods[..i]
                    .iter()
                    .position(|o| o.mode == m.mode && o.tess == m.tess)
                    .unwrap_or(i)
            })
            .collect();
        let distinct: Vec<usize> = (0..methods.len()).filter(|&i| first[i] == i).collect();
        let threads = std::thread::available_parallelism()
            .map_or(1, |n| n.get())
            .clamp(1, distinct.len().max(1));
        let case = self.case;
        let config = self.config;
        let measured: Vec<(usize, Accuracy)> = std::thread::scope(|scope| {
            let workers: Vec<_> = (0..threads)
                .map(|t| {
                    let mine: Vec<usize> =
                        distinct.iter().copied().skip(t).step_by(threads).collect();
                    scope.spawn(move || {
                        mine.into_iter()
                            .map(|i| {
                                let m = &methods[i];
                                (
                                    i,
                                    accuracy::accuracy(
                                        config,
                                        scene,
                                        case.head,
                                        case.world_from_cave,
                                        m,
                                    ),
                                )
                            })
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            workers
                .into_iter()
                .flat_map(|w| {
                    w.join()
                        .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
                })
                .collect()
        });
        for (i, a) in measured {
            accuracies[i] = Some(a);
        }
        for (i, &f) in first.iter().enumerate() {
            if accuracies[i].is_none() {
                accuracies[i] = accuracies[f];
            }
        }
        accuracies
    }

    /// The picture against the reference render (one read-back per method, outside the
    /// timing).
    fn image_diffs(&self, renderer: &mut Renderer) -> Result<Vec<Option<f64>>, BenchError> {
        let methods = self.methods;
        let mut diffs: Vec<Option<f64>> = vec![None; methods.len()];
        if self.scene.is_some() {
            renderer.render(&self.params(&reference_method(self.config.settings.tess())))?;
            let reference = renderer.read_images()?;
            check_reference(self.scene_name, &reference)?;
            for (i, m) in methods.iter().enumerate() {
                let base = methods[..i]
                    .iter()
                    .position(|o| o.mode == m.mode && o.tess == m.tess)
                    .and_then(|j| diffs[j]);
                diffs[i] = Some(match base {
                    Some(d) => d,
                    None => {
                        // Without the sky, as the reference: the comparison is of the
                        // geometry, and methods differing only by their sky share it.
                        let mut p = self.params(m);
                        p.sky.mode = SkyMode::Off;
                        renderer.render(&p)?;
                        image_difference_pct(&renderer.read_images()?, &reference)
                    }
                });
            }
        }
        Ok(diffs)
    }

    /// The row of method `m`: its times sorted, their medians and its counts.
    fn row(
        &self,
        m: &Method,
        t: MethodTimes,
        accuracy: Option<Accuracy>,
        image_diff_pct: Option<f64>,
    ) -> Row {
        let timer = self.timer;
        let rounds_ms = if timer == Timer::Gpu {
            t.gpu.clone()
        } else {
            t.wall.clone()
        };
        let mut wall = t.wall;
        wall.sort_by(f64::total_cmp);
        let mut times = t.gpu;
        times.sort_by(f64::total_cmp);
        let wall_median_ms = percentile(&wall, 0.5);
        let stages = &t.stages;
        let stages_ms = (!stages.is_empty()).then(|| {
            std::array::from_fn(|k| {
                let mut v: Vec<f64> = stages.iter().map(|s| s[k]).collect();
                v.sort_by(f64::total_cmp);
                percentile(&v, 0.5)
            })
        });
        Row {
            scene: self.scene_name.to_owned(),
            viewpoint: self.case.viewpoint.clone(),
            head: self.case.head_name.clone(),
            method: m.clone(),
            timer,
            times_ms: if timer == Timer::Gpu { times } else { wall },
            rounds_ms,
            wall_median_ms,
            input_triangles: self.scene.map_or(0, Scene::triangle_count),
            drawn_triangles: t.drawn,
            accuracy,
            image_diff_pct,
            stages_ms,
            dispatches: t.dispatches,
            refined_input: t.refined_input,
        }
    }
}

/// A pixel differs visibly when a channel is off by more than this (of 255): a different
/// surface or a shifted texture, not a shading nuance (lighting from the per-vertex eye differs
/// by a few levels at most).
pub const VISIBLE_DIFFERENCE: u8 = 24;

/// The one colour every pixel of `images` has (within 2 levels), if so: a render with nothing
/// to compare (a model out of view, unlit or drawn black).
pub fn uniform_colour(images: &[WallImages]) -> Option<[u8; 3]> {
    let mut pixels = images
        .iter()
        .flat_map(|w| [&w.left, &w.right])
        .flat_map(|img| img.pixels());
    let first = pixels.next()?;
    let same = |p: &image::Rgba<u8>| (0..3).all(|c| p.0[c].abs_diff(first.0[c]) <= 2);
    pixels
        .all(same)
        .then_some([first.0[0], first.0[1], first.0[2]])
}

/// Refuses a reference render of one flat colour: every method would read 0 % off it.
pub fn check_reference(scene_name: &str, reference: &[WallImages]) -> Result<(), BenchError> {
    match uniform_colour(reference) {
        Some(colour) => Err(BenchError::DegenerateRender {
            scene: scene_name.to_owned(),
            colour,
        }),
        None => Ok(()),
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    fn walls(colour: impl Fn(u32, u32) -> [u8; 3]) -> Vec<WallImages> {
        let img = image::RgbaImage::from_fn(8, 6, |x, y| {
            let [r, g, b] = colour(x, y);
            image::Rgba([r, g, b, 255])
        });
        vec![WallImages {
            wall: "front".into(),
            left: img.clone(),
            right: img,
        }]
    }

    #[test]
    fn a_flat_reference_is_refused_instead_of_reading_zero_percent_off() {
        let black = walls(|_, _| [0, 0, 0]);
        // The comparison alone would call any flat render identical to it.
        assert_eq!(image_difference_pct(&black, &black), 0.0);
        let err = check_reference("city", &black).unwrap_err().to_string();
        assert!(err.contains("city") && err.contains("[0, 0, 0]"), "{err}");
        // Shading noise within 2 levels is still flat; one visible feature is not.
        assert!(check_reference("city", &walls(|x, _| [(x % 2) as u8, 0, 0])).is_err());
        assert!(
            check_reference(
                "city",
                &walls(|x, y| [u8::from(x == 3 && y == 2) * 200, 0, 0])
            )
            .is_ok()
        );
    }

    #[test]
    fn ratios_pair_the_frames_of_each_round() {
        let row = |rounds: &[f64]| {
            let mut times = rounds.to_vec();
            times.sort_by(f64::total_cmp);
            Row {
                scene: "s".into(),
                viewpoint: "v".into(),
                head: "h".into(),
                method: super::super::methods::methods(true, crate::tess::TessSettings::default())
                    [0]
                .clone(),
                timer: Timer::Gpu,
                times_ms: times,
                rounds_ms: rounds.to_vec(),
                wall_median_ms: 0.0,
                input_triangles: 0,
                drawn_triangles: 0,
                accuracy: None,
                image_diff_pct: None,
                stages_ms: None,
                dispatches: 0,
                refined_input: 0,
            }
        };
        // The machine slows down in round 2 for both; round 3 has a hiccup for one.
        let stereo = row(&[100.0, 200.0, 140.0]);
        let method = row(&[120.0, 240.0, 300.0]);
        assert!((method.ratio_to(&stereo) - 1.2).abs() < 1e-12);
        // The ratio of medians reads the drift and the hiccup as cost: 240 / 140.
        assert!((method.median() / stereo.median() - 240.0 / 140.0).abs() < 1e-12);
        // Rounds that do not pair up fall back to the ratio of medians.
        let short = row(&[120.0, 240.0]);
        assert!((short.ratio_to(&stereo) - 180.0 / 140.0).abs() < 1e-12);
    }

    #[test]
    fn percentiles_interpolate() {
        let v = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(percentile(&v, 0.5), 2.5);
        assert_eq!(percentile(&v, 0.0), 1.0);
        assert_eq!(percentile(&v, 1.0), 4.0);
        assert!(percentile(&[], 0.5).is_nan());
    }
}
