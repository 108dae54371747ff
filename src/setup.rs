//! What the render command, the application and the bench share: the renderer for a config
//! with its scene and sky, and the per-frame parameters the settings describe (built here
//! once, for every caller).

use glam::Mat4;

use crate::cave::{Cave, Head};
use crate::config::{Config, ConfigFile};
use crate::render::gpu::Gpu;
use crate::render::{FrameParams, RenderError, RenderSettings, Renderer, WallImages};
use std::path::Path;

use crate::scene::{Scene, SceneError, load_gltf_within};
use crate::sky::{CubeMap, load_sky_within};

/// The per-frame parameters `settings` describe, for the walls `cave` and `head` where they
/// are now (the application moves both) and the CAVE placed in the scene by `world_from_cave`
/// (navigation moves it).
pub fn frame_params_from<'a>(
    settings: &'a ConfigFile,
    cave: &'a Cave,
    head: Head,
    world_from_cave: Mat4,
) -> FrameParams<'a> {
    FrameParams {
        cave,
        head,
        mode: settings.render.mode,
        eye_separation: settings.cave.eye_separation,
        world_from_cave,
        lighting: settings.lighting(),
        shading: settings.render.shading,
        shadows: settings.shadows(),
        background: settings.render.background,
        omni: settings.omni(),
        tess: settings.tess(),
        sky: settings.sky(),
        wand_ray: None,
        animation: settings.playback(),
    }
}

/// The frame parameters a config describes, as loaded.
pub fn frame_params(config: &Config) -> FrameParams<'_> {
    let settings = &config.settings;
    frame_params_from(
        settings,
        &config.cave,
        settings.head(),
        settings.world_from_cave(),
    )
}

/// The settings that change pipelines or targets.
pub fn render_settings(settings: &ConfigFile) -> RenderSettings {
    RenderSettings {
        msaa: settings.render.msaa,
        wireframe: settings.render.wireframe,
    }
}

/// Loads the scene at `path` ("none": an empty scene, the sky alone) as the settings' `[scene]`
/// section asks, and logs what it holds.
pub fn load_scene(settings: &ConfigFile, path: &Path) -> Result<Scene, SceneError> {
    if path.as_os_str() == "none" {
        return Ok(Scene::default());
    }
    let _loading = tracing::info_span!("loading scene", file = %path.display()).entered();
    let mut scene = load_gltf_within(path, &settings.scene_budget())?;
    let placed = &settings.scene;
    let fit = Mat4::from_translation(glam::Vec3::from(placed.offset_m))
        * scene.fit_transform(placed.fit, placed.size_m);
    if fit != Mat4::IDENTITY {
        scene.transform(fit);
        tracing::info!(
            "scene {}: placed (fit {}, size {} m, offset {:?} m): scaled ×{:.4}",
            path.display(),
            placed.fit,
            placed.size_m,
            placed.offset_m,
            fit.x_axis.x
        );
    }
    for camera in &scene.cameras {
        tracing::info!(
            "scene {}: camera {:?} at {:.2?} looking {:.2?}",
            path.display(),
            camera.name,
            camera.position.to_array(),
            camera.forward.to_array()
        );
    }
    // The frame holds eight lights: the config's first, then the file's.
    let config_lights = crate::render::uniforms::FrameLights {
        config: &settings.lighting(),
        scene: &[],
        shading: settings.render.shading,
    }
    .all()
    .len();
    let room = crate::render::uniforms::MAX_LIGHTS.saturating_sub(config_lights);
    if scene.lights.len() > room {
        let left_out: Vec<&str> = scene.lights[room..]
            .iter()
            .map(|l| l.name.as_str())
            .collect();
        tracing::warn!(
            "scene {}: {} lights, but only {room} fit beside the config's {config_lights} (eight \
             in all); not drawn: {}",
            path.display(),
            scene.lights.len(),
            left_out.join(", ")
        );
    }
    if settings.scene.double_sided {
        for material in &mut scene.materials {
            material.double_sided = true;
        }
    }
    tracing::info!(
        "scene {}: {} triangles, {} materials, {} textures, {} lights",
        path.display(),
        scene.triangle_count(),
        scene.materials.len(),
        scene.textures.len(),
        scene.lights.len()
    );
    log_animation(&scene, path);
    // An animation the config names must be one the file has.
    if settings.animation.enabled {
        scene
            .rig
            .clip_named(&settings.animation.clip)
            .map_err(|why| SceneError::Invalid {
                path: path.to_owned(),
                what: format!("[animation] clip: {why}"),
            })?;
    }
    Ok(scene)
}

/// Logs what moves in `scene`: its animations (with their lengths), skins and morph targets.
fn log_animation(scene: &Scene, path: &Path) {
    let rig = &scene.rig;
    if rig.is_empty() {
        return;
    }
    let clips: Vec<String> = rig
        .clips
        .iter()
        .map(|c| format!("{} ({:.2} s)", c.name, c.duration()))
        .collect();
    let targets: usize = rig.deformers.iter().map(|d| d.targets.len()).sum();
    let vertices: usize = rig.deformers.iter().map(|d| d.rest.len()).sum();
    tracing::info!(
        "scene {}: {} posed vertices in {} primitives, {} skins, {} morph targets; animations: {}",
        path.display(),
        vertices,
        rig.deformers.len(),
        rig.skins.len(),
        targets,
        if clips.is_empty() {
            "none".to_owned()
        } else {
            clips.join(", ")
        }
    );
}

/// Places the CAVE at the scene's camera that `settings.scene.camera` names (if any): the
/// configured head at the camera, the front wall (−z) turned towards its horizontal view,
/// scale kept. Refuses a name the scene has no camera of, listing those it has.
pub fn place_at_camera(settings: &mut ConfigFile, scene: &Scene) -> Result<(), SceneError> {
    let wanted = settings.scene.camera.trim();
    if wanted.is_empty() {
        return Ok(());
    }
    let camera = scene
        .cameras
        .iter()
        .enumerate()
        .find(|(i, c)| c.name == wanted || i.to_string() == wanted)
        .map(|(_, c)| c.clone())
        .ok_or_else(|| SceneError::Invalid {
            path: "[scene] camera".into(),
            what: format!(
                "the scene has no camera {wanted:?}; it has {}",
                if scene.cameras.is_empty() {
                    "none".to_owned()
                } else {
                    scene
                        .cameras
                        .iter()
                        .enumerate()
                        .map(|(i, c)| format!("{i}: {:?}", c.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                }
            ),
        })?;
    let f = camera.forward;
    // A camera looking straight up or down keeps the configured yaw.
    let yaw = if f.x.abs() + f.z.abs() > 1e-6 {
        (-f.x).atan2(-f.z)
    } else {
        settings.scene.world_from_cave.yaw_degrees.to_radians()
    };
    let placement = &mut settings.scene.world_from_cave;
    let rotated = glam::Quat::from_rotation_y(yaw)
        * (glam::Vec3::from(settings.head.position) * placement.scale);
    placement.yaw_degrees = yaw.to_degrees();
    placement.translation = (camera.position - rotated).to_array();
    tracing::info!(
        "starting at camera {:?}: CAVE placed at {:.2?}, turned {:.1}°",
        camera.name,
        placement.translation,
        placement.yaw_degrees
    );
    Ok(())
}

/// Loads the config's sky, if it names one. A missing or malformed sky file is logged as an
/// error naming the file, and the scene renders without a sky.
pub fn load_config_sky(config: &Config) -> Option<CubeMap> {
    let path = config.sky_path.as_ref()?;
    let _loading = tracing::info_span!("loading sky", file = %path.display()).entered();
    match load_sky_within(path, config.settings.scene_budget().max_file_bytes) {
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
            wireframe,
            ..render_settings(&config.settings)
        },
    )?;
    renderer.set_scene(scene)?;
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
    let mut renderer = renderer_for(gpu, config, scene, sky, config.settings.render.wireframe)?;
    renderer.render(&frame_params(config))?;
    let tess = config.settings.tess();
    for (view, stats) in renderer
        .last_views()
        .iter()
        .zip(renderer.read_tess_stats()?)
    {
        let wall = &config.cave.walls[view.wall].name;
        let eye = view.eye.map_or("mono", |e| e.name());
        tracing::info!(
            "tessellation {wall} {eye}: {} input, {} back-face culled, {} frustum culled, {} emitted",
            stats.input,
            stats.culled_backface,
            stats.culled_frustum,
            stats.emitted,
        );
        if let Some(note) = stats.shortfall(&tess, renderer.tess_capacity()) {
            let view_name = view
                .eye
                .map_or("mono".to_string(), |e| format!("{} eye", e.name()));
            tracing::warn!("tessellation, wall {wall}, {view_name}: {note}");
        }
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

/// Renders the panorama view of a config and scene (its `[panorama]` settings, and `sky`
/// behind it if any) and returns the renderer holding it.
pub fn render_panorama(
    gpu: &Gpu,
    config: &Config,
    scene: &Scene,
    sky: Option<&CubeMap>,
) -> Result<Renderer, RenderError> {
    let mut renderer = renderer_for(gpu, config, scene, sky, false)?;
    let pano = &config.settings.pano();
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
    let tess = config.settings.tess();
    for stats in renderer.read_panorama_tess_stats()? {
        tracing::info!(
            "panorama tessellation: {} input, {} back-face culled, {} emitted",
            stats.input,
            stats.culled_backface,
            stats.emitted,
        );
        if let Some(note) = stats.shortfall(&tess, renderer.tess_capacity()) {
            tracing::warn!("panorama tessellation: {note}");
        }
    }
    Ok(renderer)
}
