//! Headless rendering of a config + scene to PNG files: the `render` command's engine.

use std::path::{Path, PathBuf};

use crate::cave::{Eye, Head, RenderMode};
use crate::config::{Config, ConfigError};
use crate::output::formats::StereoFormat;
use crate::output::{self, OutputError};
use crate::render::present::PresentParams;
use crate::render::{FrameParams, Gpu, RenderError, RenderSettings, Renderer, WallImages};
use crate::scene::{Scene, SceneError, load_gltf};
use crate::sky::{CubeMap, load_sky};

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
    #[error("head position {position} {problem}")]
    Head {
        position: glam::Vec3,
        problem: String,
    },
}

/// Per-run overrides of the config (what the CLI flags set).
#[derive(Debug, Clone, Default)]
pub struct Overrides {
    pub scene: Option<PathBuf>,
    pub mode: Option<RenderMode>,
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
}

impl Overrides {
    /// Applies the overrides to a loaded config.
    pub fn apply(&self, config: &mut Config) {
        if let Some(mode) = self.mode {
            config.mode = mode;
        }
        if let Some(p) = self.head {
            config.head.position = p;
        }
        if let Some(yaw) = self.head_yaw_degrees {
            config.head = Head {
                position: config.head.position,
                orientation: Head::orientation_from_degrees(yaw, 0.0, 0.0),
            };
        }
        if let Some(ipd) = self.eye_separation {
            config.eye_separation = ipd;
        }
        if let Some(size) = self.size {
            for wall in &mut config.cave.walls {
                wall.resolution = size;
            }
        }
        if let Some(msaa) = self.msaa {
            config.msaa = msaa;
        }
        config.wireframe |= self.wireframe;
        if let Some(warp) = self.warp {
            config.omni.warp = warp;
        }
        if let Some(pole) = self.pole_merge {
            config.omni.pole_merge = pole;
        }
        if let Some(criterion) = self.tess {
            config.tess.criterion = criterion;
        }
        if let Some(depth) = self.tess_max_depth {
            config.tess.max_depth = depth;
        }
        if let Some(sky) = &self.sky {
            config.sky_path = sky.clone();
        }
        let pano = &mut config.panorama;
        if let Some(p) = self.pano_projection {
            pano.projection = p;
        }
        if let Some(r) = self.pano_route {
            pano.route = r;
        }
        if let Some(kind) = self.pano_stereo {
            // `--pano-stereo volume` keeps the config's volume parameters.
            pano.stereo =
                crate::pano::PanoStereo::of_kind(kind, config.file.panorama.volume_ioid_d_offset);
        }
        if let Some([h, v]) = self.pano_fov_degrees {
            pano.h_fov = h.to_radians();
            pano.v_fov = v.to_radians();
        }
        if let Some(yaw) = self.pano_yaw_degrees {
            pano.yaw = yaw.to_radians();
        }
        if let Some(size) = self.pano_size {
            pano.size = size;
        }
        if let Some(mode) = self.sky_mode {
            config.sky.mode = mode;
        }
    }
}

/// Loads the config's sky, if it names one. A missing or malformed sky file is logged as an
/// error naming the file, and the scene renders without a sky.
pub fn load_config_sky(config: &Config) -> Option<CubeMap> {
    let path = config.sky_path.as_ref()?;
    match load_sky(path) {
        Ok(cube) => {
            tracing::info!(
                "sky {}: {}×{} per face, {} mip levels{}",
                path.display(),
                cube.size(),
                cube.size(),
                cube.levels.len(),
                if cube.is_hdr() { ", HDR" } else { "" }
            );
            Some(cube)
        }
        Err(e) => {
            tracing::error!("{e}; rendering without a sky");
            None
        }
    }
}

/// A renderer for `config` holding `scene` and `sky` (a sky the device cannot hold is reported
/// and left out).
fn renderer_for(
    gpu: &Gpu,
    config: &Config,
    scene: &Scene,
    sky: Option<&CubeMap>,
    wireframe: bool,
) -> Result<Renderer, RenderError> {
    let mut renderer = Renderer::new(
        gpu,
        &config.cave,
        RenderSettings {
            msaa: config.msaa,
            wireframe,
        },
    )?;
    renderer.set_scene(scene);
    if let Err(e) = renderer.set_sky(sky) {
        tracing::error!("{e}; rendering without a sky");
    }
    Ok(renderer)
}

/// Renders one frame of `scene` (and `sky`, if any) as configured; returns the renderer holding
/// the frame (to read or compose its images).
pub fn render_frame(
    gpu: &Gpu,
    config: &Config,
    scene: &Scene,
    sky: Option<&CubeMap>,
) -> Result<Renderer, RenderError> {
    let mut renderer = renderer_for(gpu, config, scene, sky, config.wireframe)?;
    renderer.render(&frame_params(config))?;
    for (view, stats) in renderer
        .last_views()
        .iter()
        .zip(renderer.read_tess_stats()?)
    {
        tracing::info!(
            "tessellation {} {}: {} input, {} back-face culled, {} frustum culled, {} emitted{}",
            config.cave.walls[view.wall].name,
            view.eye.map_or("mono", |e| e.name()),
            stats.input,
            stats.culled_backface,
            stats.culled_frustum,
            stats.emitted,
            if stats.overflowed {
                " (budget exceeded: less refined than asked)"
            } else {
                ""
            }
        );
    }
    Ok(renderer)
}

/// Renders one frame as [`render_frame`] and returns every wall's eye images.
pub fn render_images(
    gpu: &Gpu,
    config: &Config,
    scene: &Scene,
    sky: Option<&CubeMap>,
) -> Result<Vec<WallImages>, RenderError> {
    render_frame(gpu, config, scene, sky)?.read_images()
}

/// The frame parameters a config describes.
pub fn frame_params(config: &Config) -> FrameParams<'_> {
    FrameParams {
        cave: &config.cave,
        head: config.head,
        mode: config.mode,
        eye_separation: config.eye_separation,
        world_from_cave: config.world_from_cave,
        lighting: config.lighting,
        background: config.background,
        omni: config.omni,
        tess: config.tess,
        sky: config.sky,
    }
}

/// Files written by [`render_to_dir`].
#[derive(Debug, Clone)]
pub struct Written {
    pub files: Vec<PathBuf>,
}

/// Loads config and scene, renders, writes `<wall>-left.png`, `<wall>-right.png` for every wall,
/// `unfolded-anaglyph.png`, and `<wall>-<format>.png` for each of `formats` into `out_dir`.
pub fn render_to_dir(
    config_path: &Path,
    overrides: &Overrides,
    out_dir: &Path,
    formats: &[StereoFormat],
) -> Result<Written, HeadlessError> {
    let mut config = Config::load(config_path)?;
    overrides.apply(&mut config);
    if let Some(problem) = config.cave.head_problem(config.head.position) {
        return Err(HeadlessError::Head {
            position: config.head.position,
            problem,
        });
    }
    let scene_path = overrides
        .scene
        .clone()
        .or_else(|| config.scene_path.clone())
        .ok_or_else(|| HeadlessError::NoScene(config_path.to_owned()))?;
    // "none": an empty scene (the sky alone).
    let scene = if scene_path.as_os_str() == "none" {
        Scene::default()
    } else {
        load_gltf(&scene_path)?
    };
    tracing::info!(
        "scene {}: {} triangles, {} materials, {} textures",
        scene_path.display(),
        scene.triangle_count(),
        scene.materials.len(),
        scene.textures.len()
    );
    let sky = load_config_sky(&config);
    let gpu = Gpu::headless()?;
    if overrides.panorama {
        return render_panorama_to_dir(&gpu, &config, &scene, sky.as_ref(), out_dir, formats);
    }
    let mut renderer = render_frame(&gpu, &config, &scene, sky.as_ref())?;
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

/// Renders the panorama view of a config and scene (its `[panorama]` settings, and `sky`
/// behind it if any) and returns the renderer holding it.
pub fn render_panorama(
    gpu: &Gpu,
    config: &Config,
    scene: &Scene,
    sky: Option<&CubeMap>,
) -> Result<Renderer, RenderError> {
    let mut renderer = renderer_for(gpu, config, scene, sky, false)?;
    let pano = &config.panorama;
    renderer.render_panorama(&frame_params(config), pano)?;
    let fitted = pano.fitted();
    tracing::info!(
        "panorama: {} {:.0}°×{:.0}°, {} route, {}, {}×{} px",
        fitted.projection.name(),
        fitted.fov().x.to_degrees(),
        fitted.fov().y.to_degrees(),
        pano.effective_route().name(),
        if pano.effective_route() == crate::pano::PanoRoute::Geometric {
            pano.stereo.name()
        } else {
            "mono"
        },
        pano.size[0],
        pano.size[1]
    );
    for stats in renderer.read_panorama_tess_stats()? {
        tracing::info!(
            "panorama tessellation: {} input, {} back-face culled, {} emitted{}",
            stats.input,
            stats.culled_backface,
            stats.emitted,
            if stats.overflowed {
                " (budget exceeded: less refined than asked)"
            } else {
                ""
            }
        );
    }
    Ok(renderer)
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
