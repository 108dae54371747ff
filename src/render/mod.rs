//! The multi-wall stereo renderer: owns the GPU resources and draws every wall for every eye.

pub mod bindings;
pub mod error;
pub mod formats;
pub mod frame_timer;
pub mod fullscreen;
pub mod gpu;
pub mod overlay;
pub mod panorama;
mod panorama_frame;
pub mod pbr;
pub mod pose_pass;
pub mod present;
pub mod readback;
pub mod resolve;
pub mod scene_chunks;
pub mod scene_gpu;
pub mod scene_pass;
pub mod shaders;
pub mod shadow_pass;
pub mod sky_pass;
pub mod targets;
pub mod tessellator;
pub mod uniforms;
pub mod vertex_windows;
pub mod view_set;
mod wall_frame;

use glam::Mat4;
use image::RgbaImage;

pub use error::RenderError;
pub use frame_timer::{FrameBreakdown, ViewStage};
use frame_timer::{FrameTimer, STAGES_PER_VIEW};
pub use gpu::Gpu;
use scene_gpu::{GpuVertex, SceneGpu};
use scene_pass::ScenePass;
use sky_pass::SkyPass;
use targets::WallTargets;
use tessellator::Tessellator;
use view_set::ViewSet;

use crate::cave::omni::OmniSettings;
use crate::cave::{Cave, Eye, Head, RenderMode, ViewSetup};
use crate::pano::PanoSettings;
use crate::scene::Scene;
use crate::scene::{Lighting, Shading};
use crate::sky::{CubeMap, SkySettings};
use crate::tess::clusters::ClusterSplit;
use crate::tess::{TessSettings, TessStats};

/// Settings that change pipelines or targets (rarely; never per frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RenderSettings {
    /// 1 (off) or 4.
    pub msaa: u32,
    pub wireframe: bool,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            msaa: 4,
            wireframe: false,
        }
    }
}

/// What one frame is rendered from.
#[derive(Debug, Clone)]
pub struct FrameParams<'a> {
    pub cave: &'a Cave,
    pub head: Head,
    pub mode: RenderMode,
    pub eye_separation: f32,
    pub world_from_cave: Mat4,
    pub lighting: Lighting,
    /// The shading model.
    pub shading: Shading,
    /// Shadow maps from the lights.
    pub shadows: crate::scene::shadows::ShadowSettings,
    /// Clear colour, sRGB 0..1.
    pub background: [f32; 3],
    /// Warp variant and pole merge (used by the omnistereo modes).
    pub omni: OmniSettings,
    /// Adaptive tessellation before the warp (on when a criterion is set).
    pub tess: TessSettings,
    /// Sky mode and parameters (drawn when a cube map is set with `Renderer::set_sky`).
    pub sky: SkySettings,
    /// The tracked wand's ray, drawn into every view (CAVE space).
    pub wand_ray: Option<crate::cave::wand::WandRay>,
    /// The animation and the clock's time the scene is posed at.
    pub animation: crate::scene::rig::Playback<'a>,
}

/// Milliseconds between two resolved timestamps (`None` if the counter wrapped or a driver
/// reordered them).
fn ticks_to_ms(bytes: &[u8], period_ns: f32) -> Option<f64> {
    let tick = |i: usize| {
        bytes
            .get(i * 8..i * 8 + 8)
            .and_then(|b| b.try_into().ok())
            .map(u64::from_le_bytes)
    };
    let (start, end) = (tick(0)?, tick(1)?);
    (end >= start).then(|| (end - start) as f64 * f64::from(period_ns) * 1e-6)
}

/// Counts from the last frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FrameStats {
    pub views: usize,
    pub triangles_submitted: usize,
    /// Compute dispatches recorded (the tessellator's, direct and indirect).
    pub dispatches: usize,
    /// Triangles drawn directly, untessellated, in a tessellated frame (all views): those of
    /// clusters proven to need no refinement.
    pub fine_triangles: usize,
    /// Source triangles that entered the tessellator (all refinements: one per view, or per
    /// wall where both eyes share it): those of the clusters that may need refining, or
    /// every triangle per refinement without `skip_fine`.
    pub refined_input: usize,
}

/// The renderer: one scene pass, one scene, per-wall per-eye targets.
#[derive(Debug)]
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    settings: RenderSettings,
    scene_pass: ScenePass,
    scene: Option<SceneGpu>,
    /// The pose pass's pipeline (built once) and the scene's animation, if anything moves.
    pose_pipeline: pose_pass::PosePipeline,
    scene_pose: Option<pose_pass::ScenePose>,
    /// The largest buffer a scene is uploaded in (`None`: the device's limit).
    scene_buffer_limit: Option<u64>,
    sky_pass: SkyPass,
    /// Resolves the walls' shader-encoded samples (`resolve` says why).
    resolve_pass: resolve::ResolvePass,
    /// Whether the walls draw shader-encoded samples when they can (MSAA on, nothing
    /// blended); off only to compare with the hardware resolve.
    encoded_samples: bool,
    /// Whether the last frame's walls drew shader-encoded samples.
    drew_encoded: bool,
    /// `None` when the device cannot run it (too few storage buffers per stage).
    tessellator: Option<Tessellator>,
    /// Output budget of the tessellator, triangles per view.
    tess_capacity: u32,
    /// The largest window the tessellator binds the scene's vertices in (`None`: the
    /// device's largest storage binding).
    tess_vertex_window: Option<u64>,
    /// The walls' eyes: their uniforms and tessellation output.
    walls: ViewSet,
    /// The panorama's eyes or cube faces: their own uniforms and tessellation output.
    pano_set: ViewSet,
    targets: Vec<WallTargets>,
    wall_names: Vec<String>,
    last_views: Vec<ViewSetup>,
    /// The walls this renderer draws (cluster mode: the walls of this process); `None`: all.
    wall_filter: Option<Vec<bool>>,
    wireframe_supported: bool,
    /// GPU frame timer (`None` unless enabled).
    timer: Option<FrameTimer>,
    /// Timestamps the last timed render wrote (its walls' stages, or the panorama's two).
    timed_stamps: u32,
    /// Views of the last walls frame (the breakdown's layout).
    timed_views: usize,
    /// Compute dispatches the last walls frame recorded.
    last_dispatches: usize,
    /// Per view of the walls: the clusters drawn directly and those refined (reused).
    cluster_splits: Vec<ClusterSplit>,
    /// Per view: where its refined clusters lie in the tessellator's list (reused).
    needy_ranges: Vec<(u32, u32, u32)>,
    /// Per view: whether it shares its wall's other eye's refinement (reused).
    eye_shares: Vec<crate::tess::EyeShare>,
    /// Per view: its cluster test this frame (reused).
    cluster_tests: Vec<Option<crate::tess::clusters::ClusterTest>>,
    /// Frames rendered so far (the read-back ring tags results with it).
    frame_number: u64,
    /// Timestamps and tessellation counts of each frame, read back without waiting.
    readback: readback::ReadbackRing,
    /// The newest frame read back.
    latest: FrameReadback,
    /// Stereo output composition: the one present pass, for headless composition and every
    /// window's surface format.
    present: present::PresentPass,
    /// Bumped whenever an eye target is rebuilt (bindings of eye textures must follow).
    targets_generation: u64,
    /// The panorama view's targets and image route.
    pano: panorama::PanoPass,
    /// Eye images in the last panorama (1 mono, 2 stereo).
    pano_views: usize,
    /// The sky's irradiance (computed once per sky), for its light on the scene.
    sky_irradiance: Option<crate::sky::irradiance::SkyIrradiance>,
    /// The wand ray's mesh, uploaded once; its positions are rewritten in place each frame.
    wand: SceneGpu,
    /// The wand ray's vertices (reused every frame: nothing is allocated per frame).
    wand_positions: Vec<glam::Vec3>,
    wand_vertices: Vec<GpuVertex>,
}

/// The newest frame read back through the ring (see [`readback`]).
#[derive(Debug, Clone, Default)]
pub struct FrameReadback {
    /// The frame it belongs to (0: none has arrived yet).
    pub frame: u64,
    /// Its GPU time, ms (`None` without timestamps).
    pub gpu_ms: Option<f64>,
    /// Where that time went, per stage and view (empty without timestamps).
    pub breakdown: FrameBreakdown,
    /// The walls' tessellation statistics, one per view in `view_setups` order (empty when
    /// that frame was not tessellated).
    pub tess: Vec<TessStats>,
}

impl Renderer {
    /// Creates targets for every wall of `cave` and builds all pipelines.
    pub fn new(gpu: &Gpu, cave: &Cave, settings: RenderSettings) -> Result<Self, RenderError> {
        if !matches!(settings.msaa, 1 | 4) {
            return Err(RenderError::Msaa(settings.msaa));
        }
        if settings.wireframe && !gpu.wireframe_supported {
            tracing::warn!("wireframe requested but the adapter lacks POLYGON_MODE_LINE; off");
        }
        let tessellator = gpu
            .tessellation_supported()
            .then(|| Tessellator::new(&gpu.device));
        if tessellator.is_none() {
            tracing::warn!(
                "the adapter binds fewer than {} storage buffers per stage: tessellation is \
                 unavailable and will be skipped",
                gpu::TESSELLATOR_STORAGE_BUFFERS
            );
        }
        let scene_pass = ScenePass::new(
            &gpu.device,
            settings.msaa,
            tessellator.as_ref().map(|t| &t.draw_layout),
        );
        let walls = ViewSet::new(
            &gpu.device,
            scene_pass.frame_layout(),
            cave.walls.len() * 2,
            "Renderer::walls",
        );
        // Six cube faces (image route) or two eyes (geometric route).
        let pano_set = ViewSet::new(
            &gpu.device,
            scene_pass.frame_layout(),
            6,
            "Renderer::panorama",
        );
        let sky_pass = SkyPass::new(&gpu.device, settings.msaa, cave.walls.len() * 2);
        let pano = panorama::PanoPass::new(&gpu.device, sky_pass.cube_layout(), settings.msaa);
        let wand_template = crate::scene::wand_mesh::template();
        let wand = scene_pass.upload_scene(&gpu.device, &gpu.queue, &wand_template, None)?;
        let wand_vertices: Vec<GpuVertex> =
            wand_template.vertices.iter().map(GpuVertex::from).collect();
        let mut renderer = Self {
            device: gpu.device.clone(),
            queue: gpu.queue.clone(),
            settings,
            wand,
            wand_positions: vec![glam::Vec3::ZERO; crate::scene::wand_mesh::VERTICES],
            wand_vertices,
            scene_pass,
            scene: None,
            pose_pipeline: pose_pass::PosePipeline::new(&gpu.device),
            scene_pose: None,
            scene_buffer_limit: None,
            sky_pass,
            resolve_pass: resolve::ResolvePass::new(&gpu.device, settings.msaa),
            encoded_samples: true,
            drew_encoded: false,
            tessellator,
            tess_capacity: tessellator::DEFAULT_CAPACITY,
            tess_vertex_window: None,
            walls,
            pano_set,
            targets: Vec::new(),
            wall_names: Vec::new(),
            last_views: Vec::new(),
            wall_filter: None,
            wireframe_supported: gpu.wireframe_supported,
            timer: None,
            timed_stamps: 0,
            timed_views: 0,
            last_dispatches: 0,
            cluster_splits: Vec::new(),
            needy_ranges: Vec::new(),
            eye_shares: Vec::new(),
            cluster_tests: Vec::new(),
            frame_number: 0,
            readback: readback::ReadbackRing::new(
                &gpu.device,
                u64::from(frame_timer::timestamp_count(cave.walls.len() * 2)) * 8
                    + tessellator::STATS_BYTES * (cave.walls.len() * 2) as u64,
            ),
            latest: FrameReadback::default(),
            present: present::PresentPass::new(&gpu.device),
            targets_generation: 0,
            pano,
            pano_views: 0,
            sky_irradiance: None,
        };
        renderer.sync_walls(cave);
        Ok(renderer)
    }

    /// Splits the next scenes' geometry into buffers of at most `bytes` (`None`: the device's
    /// largest buffer): to leave room beside a large scene, and to test the split on a
    /// device whose largest buffer is large.
    pub fn limit_scene_buffers(&mut self, bytes: Option<u64>) {
        self.scene_buffer_limit = bytes;
    }

    /// Binds the scene's vertices for the tessellator in windows of at most `bytes` (`None`:
    /// the device's largest storage binding): to test the windows on a device whose storage
    /// bindings are large. Takes effect at the next tessellated frame.
    pub fn limit_tess_vertex_windows(&mut self, bytes: Option<u64>) {
        self.tess_vertex_window = bytes;
        self.walls.drop_tessellation();
        self.pano_set.drop_tessellation();
    }

    /// What bounds the tessellation buffers: the output budget and the largest window the
    /// scene's vertices are bound in.
    fn tess_limits(&self) -> view_set::TessLimits {
        let device = self.device.limits().max_storage_buffer_binding_size;
        view_set::TessLimits {
            capacity: self.tess_capacity,
            vertex_window: self.tess_vertex_window.map_or(device, |w| w.min(device)),
        }
    }

    /// How many buffers the current scene's geometry is split over (0: no scene).
    pub fn scene_chunks(&self) -> usize {
        self.scene.as_ref().map_or(0, SceneGpu::chunk_count)
    }

    /// Replaces the scene (uploads buffers and textures once). A scene the device cannot
    /// hold is an error naming the limit; the previous scene stays.
    pub fn set_scene(&mut self, scene: &Scene) -> Result<(), RenderError> {
        let uploaded = self.scene_pass.upload_scene(
            &self.device,
            &self.queue,
            scene,
            self.scene_buffer_limit,
        )?;
        self.scene_pose = pose_pass::ScenePose::new(
            &self.device,
            &self.queue,
            &self.pose_pipeline,
            scene,
            &uploaded,
        );
        self.scene = Some(uploaded);
        self.scene_pass.shadows.invalidate();
        self.walls.drop_tessellation();
        self.pano_set.drop_tessellation();
        Ok(())
    }

    /// Times every following frame on the GPU (for the benchmark: reading the time back
    /// blocks). Returns false when the adapter has no timestamps.
    pub fn enable_gpu_timing(&mut self, gpu: &Gpu) -> bool {
        if !gpu.timestamps_supported {
            return false;
        }
        self.timer = Some(FrameTimer::new(
            &self.device,
            &self.queue,
            self.targets.len() * 2,
            gpu.timestamps_inside_passes,
        ));
        true
    }

    /// Collects the frames the GPU has finished (their timestamps and the walls' tessellation
    /// counts), without waiting, and returns the newest.
    pub fn poll_readbacks(&mut self) -> &FrameReadback {
        // Only collects callbacks of finished work; never blocks.
        let _ = self.device.poll(wgpu::PollType::Poll);
        let period_ns = self.timer.as_ref().map_or(0.0, |t| t.period_ns);
        let inside = self.timer.as_ref().is_some_and(|t| t.inside_passes);
        let input = self.scene.as_ref().map_or(0, |s| s.triangle_count as u32);
        let capacity = self.tess_capacity;
        let latest = &mut self.latest;
        self.readback.collect(|frame, layout, bytes| {
            if frame <= latest.frame {
                return;
            }
            latest.frame = frame;
            let offset = layout.stats_offset() as usize;
            let stamps = bytes.get(..offset).unwrap_or(&[]);
            let views = (layout.timestamps as usize).saturating_sub(2) / STAGES_PER_VIEW;
            latest.gpu_ms = (layout.timestamps > 0
                && latest.breakdown.read(stamps, views, period_ns, inside))
            .then_some(latest.breakdown.total_ms);
            if latest.gpu_ms.is_none() {
                latest.breakdown.views.clear();
            }
            latest.tess.clear();
            let stats_bytes = tessellator::STATS_BYTES as usize * layout.tess_views;
            if let Some(stats) = bytes.get(offset..offset + stats_bytes) {
                tessellator::stats_from_bytes(stats, input, capacity, &mut latest.tess);
            }
        });
        &self.latest
    }

    /// The newest frame read back by [`Self::poll_readbacks`].
    pub fn latest_readback(&self) -> &FrameReadback {
        &self.latest
    }

    /// The GPU time (ms) of the newest frame whose timestamps have arrived, without waiting.
    /// `None` until timing is enabled and a frame has finished.
    pub fn poll_gpu_time_ms(&mut self) -> Option<f64> {
        self.poll_readbacks().gpu_ms
    }

    /// How many render and compute pipelines this renderer has built (tests check that
    /// switching settings builds none).
    pub fn pipelines_built(&self) -> u64 {
        self.scene_pass.pipelines_built
            + self.sky_pass.pipelines_built
            + self.resolve_pass.pipelines_built()
            + self.present.pipelines_built()
            + self.pano.pipelines_built
            + pose_pass::PosePipeline::PIPELINES
            + if self.tessellator.is_some() {
                Tessellator::PIPELINES
            } else {
                0
            }
    }

    /// Changes whenever an eye texture is replaced (wall resized, MSAA changed): anything
    /// bound to [`Renderer::eye_texture`] must be rebound.
    pub fn targets_generation(&self) -> u64 {
        self.targets_generation
    }

    /// GPU time of the last frame in milliseconds (blocks until it is done), if timing is on.
    pub fn read_gpu_time_ms(&self) -> Result<Option<f64>, RenderError> {
        let Some(timer) = &self.timer else {
            return Ok(None);
        };
        let last = u64::from(self.timed_stamps.max(2) - 1);
        let bytes = targets::read_buffer(
            &self.device,
            &self.queue,
            &timer.resolve,
            (last + 1) * 8,
            "Renderer::frame_timer_readback",
        )?;
        let mut ends = bytes.get(..8).unwrap_or(&[]).to_vec();
        ends.extend_from_slice(bytes.get(last as usize * 8..).unwrap_or(&[]));
        Ok(ticks_to_ms(&ends, timer.period_ns))
    }

    /// Where the last walls frame's GPU time went (blocking read; the bench's). `None`
    /// without timestamps or when they came back out of order.
    pub fn read_gpu_breakdown(&self) -> Result<Option<FrameBreakdown>, RenderError> {
        let Some(timer) = &self.timer else {
            return Ok(None);
        };
        let count = frame_timer::timestamp_count(self.timed_views);
        let bytes = targets::read_buffer(
            &self.device,
            &self.queue,
            &timer.resolve,
            u64::from(count) * 8,
            "Renderer::frame_timer_breakdown",
        )?;
        let mut b = FrameBreakdown::default();
        Ok(b.read(
            &bytes,
            self.timed_views,
            timer.period_ns,
            timer.inside_passes,
        )
        .then_some(b))
    }

    /// Waits until the GPU has finished all submitted work.
    pub fn wait_idle(&self) -> Result<(), RenderError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| RenderError::Readback(e.to_string()))
    }

    /// Sets the sky's cube map (uploaded once with its mip chain); `None` removes the sky. A
    /// cube map larger than the device's textures is refused (and any previous sky removed).
    pub fn set_sky(&mut self, cube: Option<&CubeMap>) -> Result<(), RenderError> {
        let max = self.device.limits().max_texture_dimension_2d;
        match cube {
            Some(c) if c.size() > max => {
                self.sky_pass.set_cube(&self.device, &self.queue, None);
                self.sky_irradiance = None;
                Err(RenderError::SkyTooLarge {
                    size: c.size(),
                    max,
                })
            }
            _ => {
                self.sky_pass.set_cube(&self.device, &self.queue, cube);
                self.sky_irradiance = cube.map(crate::sky::irradiance::SkyIrradiance::from_cube);
                Ok(())
            }
        }
    }

    /// The present pass that composes eye images into outputs (windows bind it too).
    pub fn present_pass(&self) -> &present::PresentPass {
        &self.present
    }

    /// Builds the present pipeline for a window's surface format (once per format).
    pub fn ensure_present_format(&mut self, format: wgpu::TextureFormat) {
        self.present.ensure_pipeline(&self.device, format);
    }

    /// Whether a sky is set.
    pub fn has_sky(&self) -> bool {
        self.sky_pass.has_cube()
    }

    /// The tessellation output budget (triangles per view).
    pub fn tess_capacity(&self) -> u32 {
        self.tess_capacity
    }

    /// Sets the tessellation output budget (triangles per view); takes effect on the next
    /// tessellated frame.
    pub fn set_tess_capacity(&mut self, capacity: u32) {
        let max = tessellator::max_capacity(&self.device);
        if capacity > max {
            tracing::warn!(
                "tessellation budget {capacity} exceeds what this device binds; using {max}"
            );
        }
        self.tess_capacity = capacity.clamp(1, max);
        self.walls.drop_tessellation();
        self.pano_set.drop_tessellation();
    }

    /// Changes MSAA or wireframe; rebuilds pipelines and targets only when MSAA changes.
    pub fn set_settings(
        &mut self,
        settings: RenderSettings,
        cave: &Cave,
    ) -> Result<(), RenderError> {
        if !matches!(settings.msaa, 1 | 4) {
            return Err(RenderError::Msaa(settings.msaa));
        }
        let msaa_changed = settings.msaa != self.settings.msaa;
        self.settings = settings;
        if msaa_changed {
            self.scene_pass.build_pipelines(&self.device, settings.msaa);
            self.sky_pass.build_pipelines(&self.device, settings.msaa);
            self.resolve_pass
                .build_pipeline(&self.device, settings.msaa);
            self.pano.set_msaa(&self.device, settings.msaa);
            self.targets.clear();
            self.sync_walls(cave);
        }
        Ok(())
    }

    pub fn settings(&self) -> RenderSettings {
        self.settings
    }

    /// Whether the walls, with MSAA and nothing blended, store shader-encoded samples and
    /// resolve them in a pass of their own (the default), or let the rasteriser encode every
    /// sample and resolve the sRGB attachment itself (`false`: to compare the two).
    pub fn set_encoded_samples(&mut self, on: bool) {
        self.encoded_samples = on;
    }

    /// Whether the last frame's walls drew shader-encoded samples (see
    /// [`Renderer::set_encoded_samples`]).
    pub fn drew_encoded_samples(&self) -> bool {
        self.drew_encoded
    }

    /// Makes the targets match the walls' names and pixel sizes (only changed walls are rebuilt).
    fn sync_walls(&mut self, cave: &Cave) {
        self.walls.ensure_capacity(
            &self.device,
            self.scene_pass.frame_layout(),
            cave.walls.len() * 2,
        );
        self.targets.truncate(cave.walls.len());
        self.wall_names.truncate(cave.walls.len());
        for (i, wall) in cave.walls.iter().enumerate() {
            // Another process's wall (cluster mode) keeps a 1×1 placeholder, not its memory.
            let drawn = self
                .wall_filter
                .as_ref()
                .is_none_or(|w| w.get(i).copied().unwrap_or(false));
            let size = if drawn { wall.resolution } else { [1, 1] };
            let up_to_date = self.targets.get(i).is_some_and(|t| t.size == size)
                && self.wall_names.get(i) == Some(&wall.name);
            if up_to_date {
                continue;
            }
            self.targets_generation += 1;
            let targets = WallTargets::new(
                &self.device,
                &wall.name,
                size,
                self.settings.msaa,
                Some(&self.resolve_pass),
            );
            if i < self.targets.len() {
                self.targets[i] = targets;
                self.wall_names[i] = wall.name.clone();
            } else {
                self.targets.push(targets);
                self.wall_names.push(wall.name.clone());
            }
        }
    }

    /// Records the pose pass when the frame's animation time moved the scene's pose (the
    /// shadow maps are then drawn again), and the timestamp ending it.
    fn pose_scene(&mut self, encoder: &mut wgpu::CommandEncoder, frame: &FrameParams<'_>) {
        if let (Some(pose), Some(scene)) = (&mut self.scene_pose, &mut self.scene)
            && pose.update(
                &self.queue,
                encoder,
                &self.pose_pipeline,
                &frame.animation,
                scene,
            )
        {
            self.scene_pass.shadows.invalidate();
        }
        if let Some(timer) = &self.timer {
            encoder.write_timestamp(&timer.queries, frame_timer::POSE_END);
        }
    }

    /// The scene's vertices as the GPU holds them now (posed by the last frame), or `None`
    /// for a split scene (blocking read; for tests and the CLI).
    pub fn read_scene_vertices(&self) -> Result<Option<Vec<GpuVertex>>, RenderError> {
        let Some(chunk) = self.scene.as_ref().and_then(|s| s.whole().ok()) else {
            return Ok(None);
        };
        let bytes = targets::read_buffer(
            &self.device,
            &self.queue,
            &chunk.vertex_buffer,
            chunk.vertex_buffer.size(),
            "Renderer::read_scene_vertices",
        )?;
        let size = std::mem::size_of::<GpuVertex>();
        Ok(Some(
            bytes
                .chunks_exact(size)
                .map(bytemuck::pod_read_unaligned)
                .collect(),
        ))
    }

    /// The pose the scene's vertices hold (`None`: a static scene, or not posed yet).
    pub fn scene_pose(&self) -> Option<crate::scene::rig::PoseAt> {
        self.scene_pose
            .as_ref()
            .and_then(pose_pass::ScenePose::current)
    }

    /// Renders every view of the frame and submits the work (no CPU read-back).
    pub fn render(&mut self, frame: &FrameParams<'_>) -> Result<FrameStats, RenderError> {
        let result = self.render_walls(frame);
        self.forget_unsubmitted(result)
    }

    /// A frame that failed dropped its encoder: the shadow maps it drew (and their range
    /// tiles) never reached the GPU, so they are drawn again at the next frame.
    fn forget_unsubmitted<T>(&mut self, result: Result<T, RenderError>) -> Result<T, RenderError> {
        if result.is_err() {
            self.scene_pass.shadows.invalidate();
            if let Some(pose) = &mut self.scene_pose {
                pose.forget();
            }
        }
        result
    }

    /// Renders the panorama view of `frame` (its scene, head, lighting, tessellation and
    /// omnistereo settings) into the panorama's own eye targets and submits the work (no CPU
    /// read-back). Independent of the walls: call it after `render` in the same frame.
    pub fn render_panorama(
        &mut self,
        frame: &FrameParams<'_>,
        pano: &PanoSettings,
    ) -> Result<(), RenderError> {
        let result = self.render_panorama_frame(frame, pano);
        self.forget_unsubmitted(result)
    }

    /// [`Renderer::render_panorama`]'s frame.
    /// The colour texture of the last panorama for `eye` (mono: one image for both).
    pub fn panorama_texture(&self, eye: Eye) -> Option<&wgpu::Texture> {
        let slot = if self.pano_views > 1 { eye as usize } else { 0 };
        self.pano.targets().map(|t| &t.eyes[slot].color)
    }

    /// Changes whenever the panorama's textures are replaced (a new size or MSAA).
    pub fn panorama_generation(&self) -> u64 {
        self.pano.generation
    }

    /// Whether the last panorama had two different eye images.
    pub fn panorama_is_stereo(&self) -> bool {
        self.pano_views > 1
    }

    /// Reads the last panorama's left and right images back (identical in mono).
    pub fn read_panorama(&self) -> Result<[RgbaImage; 2], RenderError> {
        let (Some(left), Some(right)) = (
            self.panorama_texture(Eye::Left),
            self.panorama_texture(Eye::Right),
        ) else {
            return Err(RenderError::Readback("no panorama rendered yet".into()));
        };
        let mut images = targets::read_textures(&self.device, &self.queue, &[left, right])?;
        let (Some(right), Some(left)) = (images.pop(), images.pop()) else {
            return Err(RenderError::Readback("missing panorama image".into()));
        };
        Ok([left, right])
    }

    /// Composes the last panorama's eyes into a stereo output format and reads it back.
    pub fn compose_panorama(
        &mut self,
        params: present::PresentParams,
    ) -> Result<RgbaImage, RenderError> {
        let (Some(left), Some(right)) = (
            self.panorama_texture(Eye::Left).cloned(),
            self.panorama_texture(Eye::Right).cloned(),
        ) else {
            return Err(RenderError::Readback("no panorama rendered yet".into()));
        };
        self.present
            .compose_to_image(&self.device, &self.queue, &left, &right, params)
    }

    /// Tessellation statistics of the last panorama's eyes (geometric route; blocking read).
    pub fn read_panorama_tess_stats(&self) -> Result<Vec<TessStats>, RenderError> {
        self.pano_set
            .read_tess_stats(&self.device, &self.queue, self.scene.as_ref())
    }

    /// Tessellation statistics of the last frame, one per view in `last_views()` order
    /// (blocking read; for the CLI and tests). Empty when the frame was not tessellated.
    pub fn read_tess_stats(&self) -> Result<Vec<TessStats>, RenderError> {
        self.walls
            .read_tess_stats(&self.device, &self.queue, self.scene.as_ref())
    }

    /// The output triangles of the last view of the last tessellated frame (tests).
    pub fn read_tess_entries(&self) -> Result<Vec<tessellator::GpuTessEntry>, RenderError> {
        let stats = self.read_tess_stats()?;
        match (self.walls.tessellated(), stats.last()) {
            (Some(buffers), Some(last)) => {
                buffers.read_entries(&self.device, &self.queue, last.emitted)
            }
            _ => Ok(Vec::new()),
        }
    }

    /// Draws only the walls whose entry is true (cluster mode: a process draws its own
    /// walls; the others' targets shrink to 1×1 at the next frame). `None`: every wall.
    pub fn set_wall_filter(&mut self, walls: Option<Vec<bool>>) {
        self.wall_filter = walls;
    }

    /// The views of the last rendered frame.
    pub fn last_views(&self) -> &[ViewSetup] {
        &self.last_views
    }

    /// The colour texture holding `wall`'s image for `eye` in the last frame (in mono both eyes
    /// share one image).
    pub fn eye_texture(&self, wall: usize, eye: Eye) -> Option<&wgpu::Texture> {
        let mono = self.last_views.iter().any(|v| v.eye.is_none());
        let slot = if mono { 0 } else { eye as usize };
        self.targets.get(wall).map(|t| &t.eyes[slot].color)
    }

    /// Composes wall `wall`'s eye images of the last frame into a stereo output format on the
    /// GPU and reads the result back (headless output and tests).
    pub fn compose(
        &mut self,
        wall: usize,
        params: present::PresentParams,
    ) -> Result<RgbaImage, RenderError> {
        let (Some(left), Some(right)) = (
            self.eye_texture(wall, Eye::Left),
            self.eye_texture(wall, Eye::Right),
        ) else {
            return Err(RenderError::Readback(format!("no wall {wall}")));
        };
        let (left, right) = (left.clone(), right.clone());
        self.present
            .compose_to_image(&self.device, &self.queue, &left, &right, params)
    }

    /// The shadow maps' first `layers` layers and their range tiles as last drawn (blocking;
    /// tests).
    pub fn read_shadow_maps(
        &self,
        layers: usize,
    ) -> Result<shadow_pass::ShadowMapsRead, RenderError> {
        self.scene_pass
            .shadows
            .read_maps(&self.device, &self.queue, layers)
    }

    /// Reads every wall's left and right image back to the CPU (headless output and tests).
    pub fn read_images(&self) -> Result<Vec<WallImages>, RenderError> {
        let mut textures = Vec::with_capacity(self.targets.len() * 2);
        for wall in 0..self.targets.len() {
            for eye in Eye::BOTH {
                if let Some(t) = self.eye_texture(wall, eye) {
                    textures.push(t);
                }
            }
        }
        let mut images = targets::read_textures(&self.device, &self.queue, &textures)?.into_iter();
        let mut out = Vec::with_capacity(self.targets.len());
        for name in &self.wall_names {
            let (Some(left), Some(right)) = (images.next(), images.next()) else {
                return Err(RenderError::Readback("missing eye image".into()));
            };
            out.push(WallImages {
                wall: name.clone(),
                left,
                right,
            });
        }
        Ok(out)
    }
}

/// One wall's pair of eye images on the CPU.
#[derive(Debug, Clone)]
pub struct WallImages {
    pub wall: String,
    pub left: RgbaImage,
    pub right: RgbaImage,
}

impl WallImages {
    pub fn eye(&self, eye: Eye) -> &RgbaImage {
        match eye {
            Eye::Left => &self.left,
            Eye::Right => &self.right,
        }
    }
}

/// sRGB-encoded colour → the linear clear value an sRGB target needs to store exactly it.
/// An sRGB colour as the clear value of a linear (sRGB-format) target.
pub fn srgb_to_linear_color(c: [f32; 3]) -> wgpu::Color {
    let lin = |v: f32| {
        let v = f64::from(v);
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    wgpu::Color {
        r: lin(c[0]),
        g: lin(c[1]),
        b: lin(c[2]),
        a: 1.0,
    }
}
