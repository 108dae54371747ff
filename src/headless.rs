//! Headless rendering of a config + scene to PNG files: the `render` command's engine.

use std::path::{Path, PathBuf};

use crate::cave::{Eye, RenderMode};
use crate::config::{Config, ConfigError, ConfigFile};
use crate::output::formats::StereoFormat;
use crate::output::{self, OutputError};
use crate::render::present::PresentParams;
use crate::render::{Gpu, RenderError, WallImages};
use crate::scene::{Scene, SceneError};
use crate::setup::{load_config_sky, load_scene, render_frame, render_panorama};
use crate::sky::CubeMap;

/// Anything that stops a headless render.
#[derive(Debug, thiserror::Error)]
pub enum HeadlessError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Output(#[from] OutputError),
    #[error("no scene given: pass --scene or set [scene] path in {0}")]
    NoScene(PathBuf),
    #[error("--viewer {0}")]
    Viewer(String),
}

/// Per-run overrides of the config (what the CLI flags set).
#[derive(Debug, Clone, Default)]
pub struct Overrides {
    pub scene: Option<PathBuf>,
    pub mode: Option<RenderMode>,
    pub shading: Option<crate::scene::Shading>,
    pub fit: Option<crate::scene::SceneFit>,
    pub size_m: Option<f32>,
    pub offset_m: Option<glam::Vec3>,
    pub double_sided: bool,
    /// Start at this camera of the scene (name or index).
    pub camera: Option<String>,
    pub head: Option<glam::Vec3>,
    pub head_yaw_degrees: Option<f32>,
    pub eye_separation: Option<f32>,
    /// Replaces every wall's pixel size.
    pub size: Option<[u32; 2]>,
    pub msaa: Option<u32>,
    pub wireframe: bool,
    pub warp: Option<crate::cave::omni::WarpVariant>,
    /// `Some(None)` switches pole merging off; `Some(Some(..))` sets its angles.
    pub pole_merge: Option<Option<crate::cave::omni::PoleMerge>>,
    /// `Some(None)` switches tessellation off.
    pub tess: Option<Option<crate::tess::Criterion>>,
    pub tess_max_depth: Option<u32>,
    /// `Some(None)` removes the sky; `Some(Some(path))` replaces the config's sky file.
    pub sky: Option<Option<PathBuf>>,
    pub sky_mode: Option<crate::sky::SkyMode>,
    /// Render the panorama view instead of the walls.
    pub panorama: bool,
    pub pano_projection: Option<crate::pano::Projection>,
    pub pano_route: Option<crate::pano::PanoRoute>,
    pub pano_stereo: Option<crate::pano::PanoStereoKind>,
    /// Horizontal and vertical field of view, degrees.
    pub pano_fov_degrees: Option<[f32; 2]>,
    pub pano_yaw_degrees: Option<f32>,
    pub pano_size: Option<[u32; 2]>,
    /// Pose the scene's animation at this time, seconds (`render --time`).
    pub animation_time_s: Option<f32>,
    /// The animation to pose by (`render --animation`).
    pub animation: Option<String>,
}

impl Overrides {
    /// Applies the overrides to the settings model (validated again afterwards, so an override
    /// is checked exactly as the config file's value would be).
    pub fn apply(&self, settings: &mut ConfigFile) {
        if let Some(mode) = self.mode {
            settings.render.mode = mode;
        }
        if let Some(shading) = self.shading {
            settings.render.shading = shading;
        }
        if let Some(fit) = self.fit {
            settings.scene.fit = fit;
        }
        if let Some(size) = self.size_m {
            settings.scene.size_m = size;
        }
        if let Some(offset) = self.offset_m {
            settings.scene.offset_m = offset.to_array();
        }
        settings.scene.double_sided |= self.double_sided;
        if let Some(camera) = &self.camera {
            settings.scene.camera = camera.clone();
        }
        if let Some(p) = self.head {
            settings.head.position = p.to_array();
        }
        if let Some(yaw) = self.head_yaw_degrees {
            settings.head.yaw_degrees = yaw;
            settings.head.pitch_degrees = 0.0;
            settings.head.roll_degrees = 0.0;
        }
        if let Some(ipd) = self.eye_separation {
            settings.cave.eye_separation = ipd;
        }
        if let Some(size) = self.size {
            for wall in &mut settings.walls {
                wall.resolution = size;
            }
        }
        if let Some(msaa) = self.msaa {
            settings.render.msaa = msaa;
        }
        settings.render.wireframe |= self.wireframe;
        let omni = &mut settings.omnistereo;
        if let Some(warp) = self.warp {
            omni.warp = warp;
        }
        if let Some(pole) = self.pole_merge {
            omni.pole_merge = pole.is_some();
            if let Some(p) = pole {
                omni.pole_merge_start_degrees = p.start_degrees;
                omni.pole_merge_end_degrees = p.end_degrees;
            }
        }
        if let Some(criterion) = self.tess {
            settings.tessellation.criterion = criterion;
        }
        if let Some(depth) = self.tess_max_depth {
            settings.tessellation.max_depth = depth;
        }
        if let Some(mode) = self.sky_mode {
            settings.skybox.mode = mode;
        }
        let pano = &mut settings.panorama;
        if let Some(p) = self.pano_projection {
            pano.projection = p;
            if self.pano_fov_degrees.is_none() {
                // The config's field of view, as much of it as the projection shows.
                let (max_h, max_v) = p.max_fov();
                pano.h_fov_degrees = pano.h_fov_degrees.min(max_h.to_degrees().round());
                pano.v_fov_degrees = pano.v_fov_degrees.min(max_v.to_degrees().round());
            }
        }
        if let Some(r) = self.pano_route {
            pano.route = r;
        }
        // `--pano-stereo volume` keeps the config's volume parameters.
        if let Some(kind) = self.pano_stereo {
            pano.stereo = kind;
        }
        if let Some([h, v]) = self.pano_fov_degrees {
            pano.h_fov_degrees = h;
            pano.v_fov_degrees = v;
        }
        if let Some(yaw) = self.pano_yaw_degrees {
            pano.yaw_degrees = yaw;
        }
        if let Some(size) = self.pano_size {
            pano.size = size;
        }
        let animation = &mut settings.animation;
        if let Some(time) = self.animation_time_s {
            animation.enabled = true;
            animation.time_s = time;
        }
        if let Some(name) = &self.animation {
            animation.enabled = true;
            animation.clip = name.clone();
        }
    }
}

/// `render --viewer`: a guest standing at `position` (cyclopean eye, CAVE space), facing
/// `yaw_degrees`, seen through a perspective camera per eye.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewerRequest {
    pub position: glam::Vec3,
    /// Facing (positive turns left; 0 faces the front wall); default: the head's yaw.
    pub yaw_degrees: Option<f32>,
    /// The eye images' horizontal and vertical field of view, degrees (each below 180).
    pub fov_degrees: [f32; 2],
    pub size: [u32; 2],
}

impl ViewerRequest {
    /// 100° × 75°, 800 × 600: about what a pair of shutter glasses lets through.
    pub const DEFAULT_FOV_DEGREES: [f32; 2] = [100.0, 75.0];
    pub const DEFAULT_SIZE: [u32; 2] = [800, 600];
}

/// Files written by [`render_to_dir`].
#[derive(Debug, Clone)]
pub struct Written {
    pub files: Vec<PathBuf>,
}

/// What a headless render starts from.
struct Loaded {
    config: Config,
    scene: Scene,
    sky: Option<CubeMap>,
    gpu: Gpu,
}

/// The config with `overrides` applied and validated, its scene placed (at its camera if the
/// config says so), its sky, and a headless device.
fn load(config_path: &Path, overrides: &Overrides) -> Result<Loaded, HeadlessError> {
    let loaded = Config::load(config_path)?;
    let mut settings = loaded.settings;
    overrides.apply(&mut settings);
    let mut config = settings.validate(config_path)?;
    // A sky given on the command line is relative to the working directory, not the config.
    if let Some(sky) = &overrides.sky {
        config.sky_path = sky.clone();
    }
    let scene_path = overrides
        .scene
        .clone()
        .or_else(|| config.scene_path.clone())
        .ok_or_else(|| HeadlessError::NoScene(config_path.to_owned()))?;
    let scene = load_scene(&config.settings, &scene_path)?;
    crate::setup::place_at_camera(&mut config.settings, &scene)?;
    let sky = load_config_sky(&config);
    let gpu = Gpu::headless()?;
    gpu.apply_test_fault_hook();
    Ok(Loaded {
        config,
        scene,
        sky,
        gpu,
    })
}

/// Loads config and scene, renders, writes `<wall>-left.png`, `<wall>-right.png` for every wall,
/// `unfolded-anaglyph.png`, and `<wall>-<format>.png` for each of `formats` into `out_dir`.
pub fn render_to_dir(
    config_path: &Path,
    overrides: &Overrides,
    out_dir: &Path,
    formats: &[StereoFormat],
) -> Result<Written, HeadlessError> {
    let Loaded {
        config,
        scene,
        sky,
        gpu,
    } = load(config_path, overrides)?;
    let written = if overrides.panorama {
        render_panorama_to_dir(&gpu, &config, &scene, sky.as_ref(), out_dir, formats)
    } else {
        render_walls_to_dir(&gpu, &config, &scene, sky.as_ref(), out_dir, formats)
    };
    // A device fault makes whatever was written untrustworthy, and explains a failure.
    gpu.check()?;
    written
}

/// `render --viewer`: renders the walls for the config's head and mode, and the walls a
/// tracked-stereo render for the viewer would show; re-projects both to the viewer's eyes.
/// Writes `seen-left.png`, `seen-right.png` (what the viewer sees of the walls rendered for
/// the head), `correct-left.png`, `correct-right.png` (what they would see if tracked), their
/// anaglyphs, `compare.png` (seen | correct, anaglyphs side by side) and `viewer.md` (the
/// ray-intersection model's figures for this viewer over the scene).
pub fn render_viewer_to_dir(
    config_path: &Path,
    overrides: &Overrides,
    viewer: &ViewerRequest,
    out_dir: &Path,
) -> Result<Written, HeadlessError> {
    let Loaded {
        config,
        scene,
        sky,
        gpu,
    } = load(config_path, overrides)?;
    let images = viewer_images(&gpu, &config, &scene, sky.as_ref(), viewer)?;
    gpu.check()?;
    let [seen_left, seen_right] = &images.seen;
    let [correct_left, correct_right] = &images.correct;
    output::ensure_dir(out_dir)?;
    let mut files = Vec::new();
    let mut write = |name: &str, img: &image::RgbaImage| -> Result<(), OutputError> {
        let path = out_dir.join(name);
        output::write_png(&path, img)?;
        files.push(path);
        Ok(())
    };
    write("seen-left.png", seen_left)?;
    write("seen-right.png", seen_right)?;
    write("correct-left.png", correct_left)?;
    write("correct-right.png", correct_right)?;
    let seen_anaglyph = output::anaglyph(seen_left, seen_right)?;
    let correct_anaglyph = output::anaglyph(correct_left, correct_right)?;
    write("seen-anaglyph.png", &seen_anaglyph)?;
    write("correct-anaglyph.png", &correct_anaglyph)?;
    write(
        "compare.png",
        &output::unfold(&[&seen_anaglyph, &correct_anaglyph]),
    )?;
    let path = out_dir.join("viewer.md");
    let text = viewer_figures_text(&config, &scene, viewer.position);
    std::fs::write(&path, text).map_err(|source| {
        HeadlessError::Viewer(format!("cannot write {}: {source}", path.display()))
    })?;
    files.push(path);
    Ok(Written { files })
}

/// What a guest sees ([`viewer_images`]): per eye (left, right) the walls rendered for the
/// config's head and those rendered for the guest as a tracked head, through `cameras`.
#[derive(Debug, Clone)]
pub struct ViewerImages {
    pub seen: [image::RgbaImage; 2],
    pub correct: [image::RgbaImage; 2],
    pub cameras: [crate::guests::reproject::EyeCamera; 2],
}

/// Renders `scene` for the config's head and mode and for the viewer as a tracked head
/// (tracked stereo, facing the viewer's yaw), and re-projects both to the viewer's eyes.
pub fn viewer_images(
    gpu: &Gpu,
    config: &Config,
    scene: &Scene,
    sky: Option<&CubeMap>,
    viewer: &ViewerRequest,
) -> Result<ViewerImages, HeadlessError> {
    use crate::guests::reproject::{EyeCamera, reproject};

    let (lo, hi) = crate::cave::Cave::head_bounds(&config.cave.walls);
    if viewer.position.cmplt(lo).any() || viewer.position.cmpgt(hi).any() {
        return Err(HeadlessError::Viewer(format!(
            "{:?} is outside the CAVE (a guest stands between {:?} and {:?})",
            viewer.position.to_array(),
            lo.to_array(),
            hi.to_array()
        )));
    }
    if let Some(problem) = config.cave.head_problem(viewer.position) {
        return Err(HeadlessError::Viewer(format!(
            "{:?} {problem}",
            viewer.position.to_array()
        )));
    }
    if !viewer.fov_degrees.iter().all(|f| (1.0..=170.0).contains(f)) {
        return Err(HeadlessError::Viewer(format!(
            "field of view {:?}° must be 1 to 170 degrees each way (a perspective image)",
            viewer.fov_degrees
        )));
    }
    if !viewer.size.iter().all(|s| (16..=8192).contains(s)) {
        return Err(HeadlessError::Viewer(format!(
            "image size {:?} must be 16 to 8192 pixels each way",
            viewer.size
        )));
    }
    // The viewer as a tracked head: what correct stereo for them would draw.
    let mut for_viewer = config.settings.clone();
    for_viewer.head.position = viewer.position.to_array();
    let yaw = viewer.yaw_degrees.unwrap_or(for_viewer.head.yaw_degrees);
    for_viewer.head.yaw_degrees = yaw;
    for_viewer.head.pitch_degrees = 0.0;
    for_viewer.head.roll_degrees = 0.0;
    for_viewer.render.mode = RenderMode::TrackedStereo;
    let mut correct_config = for_viewer.validate(&config.source)?;
    correct_config.sky_path = config.sky_path.clone();
    let seen = crate::setup::render_images(gpu, config, scene, sky)?;
    let correct = crate::setup::render_images(gpu, &correct_config, scene, sky)?;

    let ipd = f64::from(config.settings.cave.eye_separation);
    let forward =
        (crate::cave::Head::orientation_from_degrees(yaw, 0.0, 0.0) * glam::Vec3::NEG_Z).as_dvec3();
    let g = viewer.position.as_dvec3();
    let ([left_eye, right_eye], _) =
        crate::guests::viewer_eyes(g, ipd, crate::guests::Gaze::Along(forward), g + forward)
            .ok_or_else(|| HeadlessError::Viewer("has no horizontal facing".into()))?;
    let fov = viewer.fov_degrees.map(f64::from);
    let camera = |eye| {
        EyeCamera::new(eye, forward, fov, viewer.size)
            .ok_or_else(|| HeadlessError::Viewer("has no horizontal facing".into()))
    };
    let cameras = [camera(left_eye)?, camera(right_eye)?];
    let eye_images = |images: &[WallImages]| {
        let lefts: Vec<&image::RgbaImage> = images.iter().map(|w| &w.left).collect();
        let rights: Vec<&image::RgbaImage> = images.iter().map(|w| &w.right).collect();
        [
            reproject(&config.cave, &lefts, &cameras[0]),
            reproject(&config.cave, &rights, &cameras[1]),
        ]
    };
    Ok(ViewerImages {
        seen: eye_images(&seen),
        correct: eye_images(&correct),
        cameras,
    })
}

/// The ray-intersection model's figures for a viewer at `viewer` (turning to each point) over
/// what the config's head sees of `scene`, for the config's mode.
fn viewer_figures_text(config: &Config, scene: &Scene, viewer: glam::Vec3) -> String {
    use crate::guests::grid::{Scratch, Thresholds, drawn, viewer_figures};
    use crate::guests::{Assumed, Gaze, Method, Setup, points};

    let settings = &config.settings;
    let head = settings.head();
    let ipd = f64::from(settings.cave.eye_separation);
    let setup = Setup::new(&config.cave, head, ipd, settings.omni().pole_merge);
    let method = Method {
        mode: settings.render.mode,
        assumed: Assumed::Head,
    };
    let points = points::visible_surface(
        scene,
        settings.world_from_cave().inverse(),
        head.position.as_dvec3(),
        4000,
        f64::from(config.cave.far),
    );
    let drawn = drawn(&setup, method, &points);
    let figures = viewer_figures(
        ipd,
        viewer.as_dvec3(),
        Gaze::AtPoint,
        &drawn,
        &mut Scratch::default(),
    );
    let limits = Thresholds::default();
    match figures {
        None => format!(
            "# Viewer at {:?}\n\nNone of the {} scene points {} draws is in front of this viewer.\n",
            viewer.to_array(),
            drawn.len(),
            method.name()
        ),
        Some(f) => format!(
            "# Viewer at {:?}\n\nMethod {} (head at {:?}): of {} scene points the head sees, {} are drawn on the walls for both eyes and {} are in front of this viewer, who turns to each.\n\n\
             | figure | 95th percentile |\n|---|---|\n\
             | vertical disparity (arcmin) | {:.2} |\n\
             | direction error (arcmin) | {:.2} |\n\
             | horizontal disparity error (arcmin) | {:.2} |\n\n\
             Depth ratio: 5th percentile {:.3}, median {:.3}, 95th percentile {:.3}.\n\n\
             Within the sweet-area limits (vertical < {} arcmin, direction < {}°): {}.\n",
            viewer.to_array(),
            method.name(),
            head.position.to_array(),
            points.len(),
            drawn.len(),
            f.seen,
            f.vertical_p95,
            f.direction_p95,
            f.horizontal_p95,
            f.depth_p5,
            f.depth_median,
            f.depth_p95,
            limits.vertical_arcmin,
            limits.direction_degrees,
            if f.within(&limits) { "yes" } else { "no" }
        ),
    }
}

/// Writes each wall's eye images, the anaglyph and each of `formats`.
fn render_walls_to_dir(
    gpu: &Gpu,
    config: &Config,
    scene: &Scene,
    sky: Option<&CubeMap>,
    out_dir: &Path,
    formats: &[StereoFormat],
) -> Result<Written, HeadlessError> {
    let mut renderer = render_frame(gpu, config, scene, sky)?;
    let images = renderer.read_images()?;
    let mut written = write_images(&images, out_dir)?;
    // Each wall in each asked-for stereo output format, composed on the GPU as a window would.
    for (index, wall) in images.iter().enumerate() {
        for &format in formats {
            let img = renderer.compose(
                index,
                PresentParams {
                    format,
                    frame: 0,
                    swap_eyes: false,
                },
            )?;
            let path = out_dir.join(format!("{}-{}.png", wall.wall, format.name()));
            output::write_png(&path, &img)?;
            written.files.push(path);
        }
    }
    Ok(written)
}

/// Writes `panorama.png` (mono) or `panorama-left.png`, `panorama-right.png` and
/// `panorama-anaglyph.png` (stereo), and `panorama-<format>.png` for each of `formats`.
fn render_panorama_to_dir(
    gpu: &Gpu,
    config: &Config,
    scene: &Scene,
    sky: Option<&CubeMap>,
    out_dir: &Path,
    formats: &[StereoFormat],
) -> Result<Written, HeadlessError> {
    let mut renderer = render_panorama(gpu, config, scene, sky)?;
    let [left, right] = renderer.read_panorama()?;
    output::ensure_dir(out_dir)?;
    let mut files = Vec::new();
    let mut write = |name: String, img: &image::RgbaImage| -> Result<(), OutputError> {
        let path = out_dir.join(name);
        output::write_png(&path, img)?;
        files.push(path);
        Ok(())
    };
    if renderer.panorama_is_stereo() {
        write("panorama-left.png".into(), &left)?;
        write("panorama-right.png".into(), &right)?;
        write(
            "panorama-anaglyph.png".into(),
            &output::anaglyph(&left, &right)?,
        )?;
    } else {
        write("panorama.png".into(), &left)?;
    }
    for &format in formats {
        let img = renderer.compose_panorama(PresentParams {
            format,
            frame: 0,
            swap_eyes: false,
        })?;
        write(format!("panorama-{}.png", format.name()), &img)?;
    }
    Ok(Written { files })
}

/// Writes eye images and the unfolded anaglyph.
pub fn write_images(images: &[WallImages], out_dir: &Path) -> Result<Written, OutputError> {
    output::ensure_dir(out_dir)?;
    let mut files = Vec::new();
    let mut anaglyphs = Vec::with_capacity(images.len());
    for wall in images {
        for eye in Eye::BOTH {
            let path = out_dir.join(format!("{}-{}.png", wall.wall, eye.name()));
            output::write_png(&path, wall.eye(eye))?;
            files.push(path);
        }
        anaglyphs.push(output::anaglyph(&wall.left, &wall.right)?);
    }
    let refs: Vec<_> = anaglyphs.iter().collect();
    let path = out_dir.join("unfolded-anaglyph.png");
    output::write_png(&path, &output::unfold(&refs))?;
    files.push(path);
    Ok(Written { files })
}
