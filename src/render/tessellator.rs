//! Adaptive tessellation in compute (shaders/tessellate.wgsl): per view, culls and splits the
//! scene's triangles by conforming edge bisection into a fixed-size buffer, sorts the result by
//! draw and writes indirect draw arguments; the scene pass then draws it with `vs_tess`.
//! Dispatch sizes come from GPU counters (indirect dispatch): no CPU read-back per frame.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::bindings::{UNIFORM_STRIDE, storage_entry, uniform_entry};
use super::error::RenderError;
pub use super::error::TessError;
use super::frame_timer::TessMarks;
use super::shaders;
use super::vertex_windows::{VERTEX_WINDOWS, Window, plan_windows, window_entry};
use crate::cave::{ViewSetup, Wall};
use crate::tess::criteria::wall_is_vertical;
use crate::tess::{FALLBACK_DEPTH_LIMIT, MAX_DEPTH_LIMIT, TessSettings, TessStats};

/// Output entry. Keep in sync with `TessEntry` in shaders/common.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GpuTessEntry {
    pub source: u32,
    pub depth: u32,
    pub corners: [[u32; 2]; 3],
}

/// Per-view parameters. Keep in sync with `TessUniforms` in shaders/tessellate.wgsl
/// (tests/gpu_layout.rs checks).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct TessUniforms {
    /// 0 none, 1 uniform, 2 edge, 3 sphere, 4 error (`Criterion::gpu_code`).
    pub criterion: u32,
    /// The criterion's parameter: levels (uniform) or pixels.
    pub criterion_value: f32,
    /// Split rounds (the maximum depth).
    pub rounds: u32,
    /// 1 if edge lengths count along x only (a vertical wall, as the thesis measures).
    pub x_length_only: u32,
    /// Target pixels: the wall's or the panorama's.
    pub target_width: f32,
    pub target_height: f32,
    /// Pixels per metre on the wall, or per radian in a panorama.
    pub pixels_per_unit: f32,
    /// Distance of the view's centre of projection from the wall plane (1 in a panorama).
    pub eye_wall_distance: f32,
    pub near: f32,
    /// 1 = back-face culling.
    pub backface_cull: u32,
    /// 1 = frustum culling.
    pub frustum_cull: u32,
    /// The ball the eyes lie on: the head in omnistereo (radius IPD/2), else the eye (0).
    pub eye_ball_radius: f32,
    pub eye_ball_centre: [f32; 3],
    pub eye_ball_pad: u32,
    /// Filled in by `TessBuffers::write_uniforms`.
    pub source_triangles: u32,
    pub live_capacity: u32,
    pub output_capacity: u32,
    pub draws: u32,
    /// 1: cs_init runs a workgroup per cluster of this view's needy list; 0: a thread per
    /// source triangle. Set by the renderer per frame.
    pub cluster_mode: u32,
    pub needy_offset: u32,
    pub needy_count: u32,
    /// Source triangles cs_init may keep (every source triangle, or those of the view's needy
    /// clusters): splitting, which starts in cs_init before every triangle is kept, leaves an
    /// output slot for each of them, so an exhausted budget refines less but drops nothing.
    /// Set by `TessBuffers::write_uniforms` outside cluster mode, by the renderer in it.
    pub root_bound: u32,
    /// 1: one refinement serves this view and its wall's other eye (bound beside it, see
    /// `TessBuffers::encode`); set by [`TessUniforms::with_partner`].
    pub partner: u32,
    /// The partner's distance from the wall plane, and its near plane.
    pub partner_eye_wall_distance: f32,
    pub partner_near: f32,
    pub partner_pad: u32,
}

impl TessUniforms {
    /// Parameters of one view (the counts are filled in by `TessBuffers::write_uniforms`); the
    /// near plane is the view's, as in its matrix.
    pub fn new(view: &ViewSetup, wall: &Wall, settings: &TessSettings, omni: bool) -> Self {
        let (code, value) = settings.criterion.map_or((0, 0.0), |c| c.gpu_code());
        let [w, h] = wall.resolution.map(|v| v as f32);
        let (centre, radius) = crate::tess::eye_ball(view, None, omni);
        Self {
            criterion: code,
            criterion_value: value,
            rounds: rounds(settings),
            x_length_only: u32::from(wall_is_vertical(wall)),
            target_width: w,
            target_height: h,
            pixels_per_unit: w / wall.size_m().x,
            eye_wall_distance: wall.signed_distance(view.eye_position),
            near: view.near,
            backface_cull: u32::from(settings.backface_cull),
            frustum_cull: u32::from(settings.frustum_cull),
            eye_ball_radius: radius,
            eye_ball_centre: centre.to_array(),
            ..Zeroable::zeroed()
        }
    }

    /// The same refinement serving `partner` too, the other eye of the same `wall`: the
    /// back-face ball holds both eyes (as `tess::eye_ball`).
    pub fn with_partner(
        self,
        view: &ViewSetup,
        partner: &ViewSetup,
        wall: &Wall,
        omni: bool,
    ) -> Self {
        let (centre, radius) = crate::tess::eye_ball(view, Some(partner), omni);
        Self {
            partner: 1,
            partner_eye_wall_distance: wall.signed_distance(partner.eye_position),
            partner_near: partner.near,
            eye_ball_radius: radius,
            eye_ball_centre: centre.to_array(),
            ..self
        }
    }

    /// Parameters of one panorama eye: criteria measured in the panorama's pixels (the
    /// projection and its window come from the view uniforms), no frustum culling (the view
    /// surrounds the head), back faces culled against the ball the omnistereo eyes lie on.
    pub fn panorama(
        settings: &TessSettings,
        size: [u32; 2],
        pixels_per_radian: f32,
        head: glam::Vec3,
        eye_radius: f32,
    ) -> Self {
        let (code, value) = settings.criterion.map_or((0, 0.0), |c| c.gpu_code());
        Self {
            criterion: code,
            criterion_value: value,
            rounds: rounds(settings),
            target_width: size[0] as f32,
            target_height: size[1] as f32,
            pixels_per_unit: pixels_per_radian,
            eye_wall_distance: 1.0,
            backface_cull: u32::from(settings.backface_cull),
            eye_ball_radius: eye_radius,
            eye_ball_centre: head.to_array(),
            ..Zeroable::zeroed()
        }
    }
}

/// Per-view statistics from their bytes (`STATS_BYTES` a view) into `out` (appended), for
/// `input` source triangles and an output budget of `capacity`.
pub fn stats_from_bytes(bytes: &[u8], input: u32, capacity: u32, out: &mut Vec<TessStats>) {
    for view in bytes.chunks_exact(STATS_BYTES as usize) {
        let word = |i: usize| {
            view.get(i * 4..i * 4 + 4)
                .map_or(0, bytemuck::pod_read_unaligned::<u32>)
        };
        out.push(TessStats {
            input,
            culled_backface: word(C_BACK),
            culled_frustum: word(C_FRUSTUM),
            emitted: word(C_OUT).min(capacity),
            overflowed: word(C_OVERFLOW) != 0,
            fallback_depth: word(C_FALLBACK).checked_sub(1),
        });
    }
}

/// Levels of splitting one invocation does (keep in sync with `SPLIT_LEVELS` in
/// shaders/tessellate.wgsl): the culling dispatch splits each triangle it keeps, and its
/// children and grandchildren, this many levels deep, and each split dispatch as many again,
/// so few dispatches cover the same depth: at the default maximum depth of 12, none beyond
/// culling. Measured on lavapipe (living room and city, `error:32` and `edge:64`, `bench
/// --quick`): each dispatch and its preparation cost a fixed time whatever they hold (about
/// 50 µs), and one level per dispatch spent most of the tessellation stages on that; 10 levels
/// per dispatch instead of 5 took the split stage from 3.4–7.8 to 2.7–5.4 ms a frame, and
/// splitting in the culling dispatch saves one prepare and one split dispatch more per view.
/// 12 since the default depth went from 10 to 12, so that it still needs no split dispatch.
pub const SPLIT_LEVELS: u32 = 12;

/// Split dispatches that reach `rounds` levels after the culling dispatch's own.
pub fn split_dispatches(rounds: u32) -> u32 {
    rounds.div_ceil(SPLIT_LEVELS).saturating_sub(1)
}

/// Compute dispatches [`TessBuffers::encode`] records for one view: culling (with the first
/// `SPLIT_LEVELS` levels of splitting), a prepare and a split per further split dispatch, the
/// fallback check and its refinement (no workgroups unless the budget ran out), then prefix
/// and scatter (the last split finishes every triangle at the maximum depth itself: no flush
/// dispatch).
pub fn dispatches_per_view(rounds: u32) -> usize {
    1 + 2 * split_dispatches(rounds) as usize + 2 + 2
}

/// Number of split levels (the maximum depth) a setting asks for.
pub fn rounds(settings: &TessSettings) -> u32 {
    if settings.criterion.is_some() {
        settings.max_depth.min(MAX_DEPTH_LIMIT)
    } else {
        0
    }
}

/// Counter slots (keep in sync with shaders/tessellate.wgsl; tests/gpu_layout.rs checks).
/// Triangles emitted.
pub const C_OUT: usize = 0;
/// Source triangles culled as back faces.
pub const C_BACK: usize = 1;
/// Source triangles culled outside the view.
pub const C_FRUSTUM: usize = 2;
/// 1 when the output budget ran out.
pub const C_OVERFLOW: usize = 3;
/// 0, or 1 + the maximum depth of the view's fallback refinement.
pub const C_FALLBACK: usize = 4;
// Slots 5, 6 and 7 hold the triangles added by splits (the budget), the source triangles kept
// for splitting and those of them left whole; they never leave the GPU.
/// Per-draw triangle counts from here.
pub const C_DRAWS: usize = 8;
/// Argument slots: 3 split dispatch, 3 scatter dispatch, 3 fallback refinement, then 4 per draw.
/// The fallback refinement's dispatch.
pub const ARGS_FALLBACK: usize = 6;
/// The first draw's indirect arguments.
pub const ARGS_DRAWS: usize = 9;
/// Bytes of per-view statistics copied out of the counters (C_OUT..=C_FALLBACK).
pub const STATS_BYTES: u64 = 20;
// The fallback refinement runs in one culling dispatch: it must not need a split dispatch.
const _: () = assert!(FALLBACK_DEPTH_LIMIT <= SPLIT_LEVELS);
const WORKGROUP: u32 = 64;
/// Largest workgroup count of one dispatch dimension (keep in sync with
/// shaders/tessellate.wgsl).
const MAX_GROUPS_X: u32 = 65_535;

/// Default output budget: triangles per view (32 bytes each, live lists alike).
pub const DEFAULT_CAPACITY: u32 = 1 << 20;

/// `tri_info` draw index of a triangle that belongs to no draw (cs_init skips it).
pub const NO_DRAW: u32 = 0x7fff_ffff;

/// Largest budget the device can bind (each list is one storage binding) and dispatch
/// (one thread per live triangle, at most 65 535 workgroups).
pub fn max_capacity(device: &wgpu::Device) -> u32 {
    let by_binding = device.limits().max_storage_buffer_binding_size
        / std::mem::size_of::<GpuTessEntry>() as u64;
    let by_dispatch = 65_535 * u64::from(WORKGROUP);
    by_binding.min(by_dispatch).min(u64::from(u32::MAX)) as u32
}

/// The compute pipelines and their layouts (built once).
#[derive(Debug)]
pub struct Tessellator {
    shared_layout: wgpu::BindGroupLayout,
    lists_layout: wgpu::BindGroupLayout,
    args_layout: wgpu::BindGroupLayout,
    init: wgpu::ComputePipeline,
    prepare: wgpu::ComputePipeline,
    split: wgpu::ComputePipeline,
    fallback: wgpu::ComputePipeline,
    prefix: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    /// Layout for drawing tessellated output (group 2 of the scene pass).
    pub draw_layout: wgpu::BindGroupLayout,
}

/// Per-scene buffers and bind groups, reused by every view and frame.
#[derive(Debug)]
pub struct TessBuffers {
    capacity: u32,
    source_triangles: u32,
    draws: u32,
    counters: wgpu::Buffer,
    count_a: wgpu::Buffer,
    pub args: wgpu::Buffer,
    uniforms: wgpu::Buffer,
    uniform_capacity: usize,
    shared_group: wgpu::BindGroup,
    lists_ab: wgpu::BindGroup,
    lists_ba: wgpu::BindGroup,
    args_group: wgpu::BindGroup,
    pub draw_group: wgpu::BindGroup,
    sorted: wgpu::Buffer,
    /// Per-view statistics (STATS_BYTES each), copied from the counters after each view.
    pub stats: wgpu::Buffer,
    stats_capacity: usize,
    staging: Vec<u8>,
    /// Every view's clusters to refine (see `tess::clusters`), and their staging copy.
    needy: wgpu::Buffer,
    needy_staging: Vec<[u32; 2]>,
}

impl Tessellator {
    /// Layout of the tessellated output as the scene pass reads it (group 2 of `vs_tess`).
    pub fn draw_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
        let v = wgpu::ShaderStages::VERTEX;
        device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("Tessellator::draw_layout"),
            entries: &[
                storage_entry(0, true, v),
                storage_entry(1, true, v),
                storage_entry(2, true, v),
                storage_entry(3, true, v),
                storage_entry(4, true, v),
                storage_entry(5, true, v),
            ],
        })
    }

    /// Compute pipelines built by [`Tessellator::new`] (once per renderer).
    pub const PIPELINES: u64 = 7;

    pub fn new(device: &wgpu::Device) -> Self {
        let c = wgpu::ShaderStages::COMPUTE;
        let shared_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("Tessellator::shared_layout"),
            entries: &[
                uniform_entry(0, false),
                uniform_entry(1, true),
                uniform_entry(2, true),
                storage_entry(3, true, c),
                storage_entry(4, true, c),
                storage_entry(5, true, c),
                storage_entry(6, false, c),
                storage_entry(7, false, c),
                storage_entry(8, false, c),
                storage_entry(9, true, c),
                uniform_entry(10, true),
                storage_entry(11, true, c),
                storage_entry(12, true, c),
                storage_entry(13, true, c),
            ],
        });
        let lists_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("Tessellator::lists_layout"),
            entries: &[
                storage_entry(0, false, c),
                storage_entry(1, false, c),
                storage_entry(2, false, c),
                storage_entry(3, false, c),
            ],
        });
        let args_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("Tessellator::args_layout"),
            entries: &[storage_entry(0, false, c)],
        });
        let draw_layout = Self::draw_layout(device);
        // Dispatches that are themselves indirect must not also bind the argument buffer as
        // storage, so the argument writers get a layout of their own.
        let work_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("Tessellator::work_layout"),
            bind_group_layouts: &[Some(&shared_layout), Some(&lists_layout)],
            immediate_size: 0,
        });
        let args_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("Tessellator::args_pipeline_layout"),
            bind_group_layouts: &[
                Some(&shared_layout),
                Some(&lists_layout),
                Some(&args_layout),
            ],
            immediate_size: 0,
        });
        let module = shaders::module(device, "Tessellator::shader", shaders::TESSELLATE);
        let pipeline = |name: &str, layout: &wgpu::PipelineLayout| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(&format!("Tessellator::{name}")),
                layout: Some(layout),
                module: &module,
                entry_point: Some(name),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        Self {
            init: pipeline("cs_init", &work_layout),
            prepare: pipeline("cs_prepare", &args_pipeline_layout),
            split: pipeline("cs_split", &work_layout),
            fallback: pipeline("cs_fallback", &args_pipeline_layout),
            prefix: pipeline("cs_prefix", &args_pipeline_layout),
            scatter: pipeline("cs_scatter", &work_layout),
            shared_layout,
            lists_layout,
            args_layout,
            draw_layout,
        }
    }

    /// Allocates the per-scene buffers. `tri_info[t]` = draw index of source triangle t, bit 31
    /// set for double-sided materials. The vertices are bound in windows of at most
    /// `vertex_binding_limit` bytes (the device's largest storage binding, or less).
    #[allow(clippy::too_many_arguments)]
    pub fn buffers(
        &self,
        device: &wgpu::Device,
        frame_buffer: &wgpu::Buffer,
        view_buffer: &wgpu::Buffer,
        view_binding_size: u64,
        vertex_buffer: &wgpu::Buffer,
        index_buffer: &wgpu::Buffer,
        tri_info: &[u32],
        draws: usize,
        clusters: usize,
        capacity: u32,
        views: usize,
        vertex_binding_limit: u64,
    ) -> Result<TessBuffers, TessError> {
        let vertex_windows = bind_vertices(device, vertex_buffer, vertex_binding_limit)?;
        let inputs = BoundInputs {
            frame_buffer,
            view_buffer,
            view_binding_size,
            vertex_buffer,
            vertex_windows,
            index_buffer,
        };
        check_indices(device, index_buffer)?;
        let storage = TessStorage::allocate(device, tri_info, draws, clusters, capacity, views);
        let shared_group = self.shared_group(device, &inputs, &storage);
        let lists = |label, a: &wgpu::Buffer, b: &wgpu::Buffer, ca: &wgpu::Buffer, cb| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &self.lists_layout,
                entries: &[whole(a, 0), whole(b, 1), whole(ca, 2), whole(cb, 3)],
            })
        };
        let s = &storage;
        let lists_ab = lists(
            "TessBuffers::lists_ab",
            &s.live_a,
            &s.live_b,
            &s.count_a,
            &s.count_b,
        );
        let lists_ba = lists(
            "TessBuffers::lists_ba",
            &s.live_b,
            &s.live_a,
            &s.count_b,
            &s.count_a,
        );
        let args_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("TessBuffers::args_group"),
            layout: &self.args_layout,
            entries: &[whole(&storage.args, 0)],
        });
        let draw_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("TessBuffers::draw_group"),
            layout: &self.draw_layout,
            entries: &[
                whole(&storage.sorted, 0),
                window_entry(vertex_buffer, 1, vertex_windows[0]),
                whole(index_buffer, 2),
                window_entry(vertex_buffer, 3, vertex_windows[1]),
                window_entry(vertex_buffer, 4, vertex_windows[2]),
                window_entry(vertex_buffer, 5, vertex_windows[3]),
            ],
        });
        Ok(TessBuffers {
            capacity,
            source_triangles: tri_info.len() as u32,
            draws: draws as u32,
            counters: storage.counters,
            count_a: storage.count_a,
            args: storage.args,
            uniforms: storage.uniforms,
            uniform_capacity: views.max(1),
            shared_group,
            lists_ab,
            lists_ba,
            args_group,
            draw_group,
            sorted: storage.sorted,
            stats: storage.stats,
            stats_capacity: views.max(1),
            staging: Vec::with_capacity(views.max(1) * UNIFORM_STRIDE as usize),
            needy: storage.needy,
            needy_staging: Vec::with_capacity(storage.needy_capacity),
        })
    }

    /// Group 0 of every stage: the frame's and views' uniforms, the scene and the lists
    /// every round shares.
    fn shared_group(
        &self,
        device: &wgpu::Device,
        inputs: &BoundInputs<'_>,
        s: &TessStorage,
    ) -> wgpu::BindGroup {
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("TessBuffers::shared_group"),
            layout: &self.shared_layout,
            entries: &[
                whole(inputs.frame_buffer, 0),
                sized(inputs.view_buffer, 1, inputs.view_binding_size),
                sized(&s.uniforms, 2, std::mem::size_of::<TessUniforms>() as u64),
                window_entry(inputs.vertex_buffer, 3, inputs.vertex_windows[0]),
                whole(inputs.index_buffer, 4),
                whole(&s.tri_info, 5),
                whole(&s.counters, 6),
                whole(&s.output, 7),
                whole(&s.sorted, 8),
                whole(&s.needy, 9),
                sized(inputs.view_buffer, 10, inputs.view_binding_size),
                window_entry(inputs.vertex_buffer, 11, inputs.vertex_windows[1]),
                window_entry(inputs.vertex_buffer, 12, inputs.vertex_windows[2]),
                window_entry(inputs.vertex_buffer, 13, inputs.vertex_windows[3]),
            ],
        })
    }
}

/// What the tessellator binds that is not its own: the frame's and views' uniforms and the
/// scene's vertices (in windows) and indices.
struct BoundInputs<'a> {
    frame_buffer: &'a wgpu::Buffer,
    view_buffer: &'a wgpu::Buffer,
    view_binding_size: u64,
    vertex_buffer: &'a wgpu::Buffer,
    vertex_windows: [Window; VERTEX_WINDOWS],
    index_buffer: &'a wgpu::Buffer,
}

/// The windows the scene's vertices are bound in, each at most `binding_limit` bytes (and
/// the device's largest storage binding); a scene whose vertices four windows cannot hold
/// is refused, naming the limit.
fn bind_vertices(
    device: &wgpu::Device,
    vertex_buffer: &wgpu::Buffer,
    binding_limit: u64,
) -> Result<[Window; VERTEX_WINDOWS], TessError> {
    let limits = device.limits();
    let bytes = vertex_buffer.size();
    plan_windows(
        bytes,
        std::mem::size_of::<super::scene_gpu::GpuVertex>() as u64,
        binding_limit.min(limits.max_storage_buffer_binding_size),
        u64::from(limits.min_storage_buffer_offset_alignment),
    )
    .map_err(|e| TessError::BindingTooLarge {
        what: "vertices",
        bytes,
        limit: e.limit,
    })
}

/// Refuses indices the tessellator cannot bind in one storage binding, naming the limit (any
/// number of triangles dispatches: a thread each over a two-dimensional grid of workgroups).
fn check_indices(device: &wgpu::Device, index_buffer: &wgpu::Buffer) -> Result<(), TessError> {
    let limit = device.limits().max_storage_buffer_binding_size;
    if index_buffer.size() > limit {
        return Err(TessError::BindingTooLarge {
            what: "indices",
            bytes: index_buffer.size(),
            limit,
        });
    }
    Ok(())
}

/// The tessellator's own buffers for one scene, before they are bound.
struct TessStorage {
    live_a: wgpu::Buffer,
    live_b: wgpu::Buffer,
    count_a: wgpu::Buffer,
    count_b: wgpu::Buffer,
    output: wgpu::Buffer,
    sorted: wgpu::Buffer,
    counters: wgpu::Buffer,
    args: wgpu::Buffer,
    tri_info: wgpu::Buffer,
    uniforms: wgpu::Buffer,
    needy: wgpu::Buffer,
    /// Entries `needy` holds: at most all clusters per view.
    needy_capacity: usize,
    stats: wgpu::Buffer,
}

impl TessStorage {
    /// Allocates the lists (`capacity` triangles each), counters, indirect arguments and
    /// per-view uniforms, needy lists and statistics.
    fn allocate(
        device: &wgpu::Device,
        tri_info: &[u32],
        draws: usize,
        clusters: usize,
        capacity: u32,
        views: usize,
    ) -> Self {
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let buffer = |label: &str, size: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size.max(16),
                usage,
                mapped_at_creation: false,
            })
        };
        let entry_bytes = std::mem::size_of::<GpuTessEntry>() as u64;
        let list_bytes = entry_bytes * u64::from(capacity);
        // wgpu refuses empty buffers; an empty scene gets one unused entry.
        let info: &[u32] = if tri_info.is_empty() { &[0] } else { tri_info };
        let needy_capacity = clusters * views.max(1);
        Self {
            live_a: buffer("TessBuffers::live_a", list_bytes, storage),
            live_b: buffer("TessBuffers::live_b", list_bytes, storage),
            count_a: buffer("TessBuffers::count_a", 4, storage),
            count_b: buffer("TessBuffers::count_b", 4, storage),
            output: buffer("TessBuffers::output", list_bytes, storage),
            sorted: buffer(
                "TessBuffers::sorted",
                list_bytes,
                storage | wgpu::BufferUsages::COPY_SRC,
            ),
            counters: buffer(
                "TessBuffers::counters",
                4 * (C_DRAWS + draws) as u64,
                storage | wgpu::BufferUsages::COPY_SRC,
            ),
            args: buffer(
                "TessBuffers::args",
                4 * (ARGS_DRAWS + 4 * draws) as u64,
                storage | wgpu::BufferUsages::INDIRECT,
            ),
            tri_info: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("TessBuffers::tri_info"),
                contents: bytemuck::cast_slice(info),
                usage: wgpu::BufferUsages::STORAGE,
            }),
            uniforms: buffer(
                "TessBuffers::uniforms",
                UNIFORM_STRIDE * views.max(1) as u64,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            ),
            needy: buffer(
                "TessBuffers::needy",
                8 * needy_capacity as u64,
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            ),
            needy_capacity,
            stats: buffer(
                "TessBuffers::stats",
                STATS_BYTES * views.max(1) as u64,
                wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
            ),
        }
    }
}

/// A bind group entry for a whole buffer.
fn whole(b: &wgpu::Buffer, binding: u32) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: b.as_entire_binding(),
    }
}

/// A bind group entry for the first `size` bytes of a buffer (bound at dynamic offsets).
fn sized(b: &wgpu::Buffer, binding: u32, size: u64) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: b,
            offset: 0,
            size: wgpu::BufferSize::new(size),
        }),
    }
}

impl TessBuffers {
    pub fn capacity(&self) -> u32 {
        self.capacity
    }

    /// Number of views the uniform and statistics buffers hold.
    pub fn view_capacity(&self) -> usize {
        self.uniform_capacity.min(self.stats_capacity)
    }

    /// The per-view parameters for this frame: one write for all views.
    pub fn write_uniforms(
        &mut self,
        queue: &wgpu::Queue,
        views: impl Iterator<Item = TessUniforms>,
    ) {
        self.staging.clear();
        for u in views.take(self.uniform_capacity) {
            let u = TessUniforms {
                root_bound: if u.cluster_mode == 0 {
                    self.source_triangles
                } else {
                    u.root_bound
                },
                source_triangles: self.source_triangles,
                live_capacity: self.capacity,
                output_capacity: self.capacity,
                draws: self.draws,
                ..u
            };
            self.staging.extend_from_slice(bytemuck::bytes_of(&u));
            let stride = UNIFORM_STRIDE as usize;
            self.staging
                .resize(self.staging.len().next_multiple_of(stride), 0);
        }
        if !self.staging.is_empty() {
            queue.write_buffer(&self.uniforms, 0, &self.staging);
        }
    }

    /// Records the tessellation of view `view_index` (its uniform slot and view slot), with
    /// timestamps ending its culling, split rounds and sort when `marks` is given. `needy`:
    /// the number of clusters this view refines (its uniforms say where they are), or `None`
    /// for every source triangle. `partner`: the view slot of the wall's other eye when one
    /// refinement serves both (its uniforms say so). A view with no cluster to refine records
    /// nothing but its (empty) statistics, and returns false: there is no output to draw.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        tess: &Tessellator,
        encoder: &mut wgpu::CommandEncoder,
        view_index: usize,
        partner: Option<usize>,
        rounds: u32,
        needy: Option<u32>,
        marks: Option<TessMarks<'_>>,
    ) -> bool {
        if needy == Some(0) {
            if view_index < self.stats_capacity {
                let at = view_index as u64 * STATS_BYTES;
                encoder.clear_buffer(&self.stats, at, Some(STATS_BYTES));
            }
            if let Some(m) = marks {
                for index in [m.cull, m.split, m.sort] {
                    encoder.write_timestamp(m.queries, index);
                }
            }
            return false;
        }
        let inside = marks.filter(|m| m.inside_passes);
        encoder.clear_buffer(&self.counters, 0, None);
        encoder.clear_buffer(&self.count_a, 0, None);
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("Tessellator::pass"),
                timestamp_writes: None,
            });
            let offset = (view_index as u64 * UNIFORM_STRIDE) as u32;
            let partner_offset = partner.map_or(offset, |p| (p as u64 * UNIFORM_STRIDE) as u32);
            pass.set_bind_group(0, &self.shared_group, &[offset, offset, partner_offset]);
            // cs_init appends to list A (the "out" side of the B→A group).
            pass.set_bind_group(1, &self.lists_ba, &[]);
            pass.set_pipeline(&tess.init);
            match needy {
                Some(n) => {
                    pass.dispatch_workgroups(n.min(MAX_GROUPS_X), n.div_ceil(MAX_GROUPS_X), 1)
                }
                None => {
                    let groups = self.source_triangles.div_ceil(WORKGROUP);
                    pass.dispatch_workgroups(
                        groups.min(MAX_GROUPS_X),
                        groups.div_ceil(MAX_GROUPS_X),
                        1,
                    )
                }
            }
            if let Some(m) = inside {
                pass.write_timestamp(m.queries, m.cull);
            }
            pass.set_bind_group(2, &self.args_group, &[]);
            let splits = split_dispatches(rounds);
            for round in 0..splits {
                let lists = if round.is_multiple_of(2) {
                    &self.lists_ab
                } else {
                    &self.lists_ba
                };
                pass.set_bind_group(1, lists, &[]);
                pass.set_pipeline(&tess.prepare);
                pass.dispatch_workgroups(1, 1, 1);
                pass.set_pipeline(&tess.split);
                pass.dispatch_workgroups_indirect(&self.args, 0);
            }
            // A view whose budget ran out is refined again, shallower but conforming (see
            // cs_fallback); otherwise the second culling dispatch has no workgroups.
            pass.set_bind_group(1, &self.lists_ba, &[]);
            pass.set_pipeline(&tess.fallback);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_pipeline(&tess.init);
            pass.dispatch_workgroups_indirect(&self.args, 4 * ARGS_FALLBACK as u64);
            if let Some(m) = inside {
                pass.write_timestamp(m.queries, m.split);
            }
            pass.set_pipeline(&tess.prefix);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_pipeline(&tess.scatter);
            pass.dispatch_workgroups_indirect(&self.args, 12);
            if let Some(m) = inside {
                pass.write_timestamp(m.queries, m.sort);
            }
        }
        if let Some(m) = marks.filter(|m| !m.inside_passes) {
            for index in [m.cull, m.split, m.sort] {
                encoder.write_timestamp(m.queries, index);
            }
        }
        if view_index < self.stats_capacity {
            encoder.copy_buffer_to_buffer(
                &self.counters,
                0,
                &self.stats,
                view_index as u64 * STATS_BYTES,
                STATS_BYTES,
            );
        }
        true
    }

    /// Records view `view_index`, which draws the refinement its wall's other eye just made
    /// (`leader_drew`: whether that one has output): no dispatch, its tessellation stages end
    /// where they begin, and its statistics are the leader's.
    pub fn encode_follower(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        view_index: usize,
        leader_drew: bool,
        marks: Option<TessMarks<'_>>,
    ) {
        if let Some(m) = marks {
            for index in [m.cull, m.split, m.sort] {
                encoder.write_timestamp(m.queries, index);
            }
        }
        if view_index < self.stats_capacity {
            let at = view_index as u64 * STATS_BYTES;
            if leader_drew {
                encoder.copy_buffer_to_buffer(&self.counters, 0, &self.stats, at, STATS_BYTES);
            } else {
                encoder.clear_buffer(&self.stats, at, Some(STATS_BYTES));
            }
        }
    }

    /// Uploads every view's clusters to refine, one after the other (one write per frame;
    /// the staging copy never grows past all clusters of all views), and returns each view's
    /// (offset, clusters, source triangles in them) for its uniforms.
    pub fn write_needy<'a>(
        &mut self,
        queue: &wgpu::Queue,
        views: impl Iterator<Item = &'a [[u32; 2]]>,
        out: &mut Vec<(u32, u32, u32)>,
    ) {
        self.needy_staging.clear();
        out.clear();
        let capacity = (self.needy.size() / 8) as usize;
        for list in views {
            let offset = self.needy_staging.len();
            let n = list.len().min(capacity.saturating_sub(offset));
            self.needy_staging.extend_from_slice(&list[..n]);
            let triangles = list[..n].iter().map(|c| c[1]).sum();
            out.push((offset as u32, n as u32, triangles));
        }
        if !self.needy_staging.is_empty() {
            queue.write_buffer(&self.needy, 0, bytemuck::cast_slice(&self.needy_staging));
        }
    }

    /// Reads the first `count` output triangles of the last tessellated view, sorted by draw
    /// (blocking; tests compare them with the CPU twin).
    pub fn read_entries(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        count: u32,
    ) -> Result<Vec<GpuTessEntry>, RenderError> {
        let count = count.min(self.capacity) as usize;
        let size = (std::mem::size_of::<GpuTessEntry>() * count) as u64;
        let bytes = super::targets::read_buffer(
            device,
            queue,
            &self.sorted,
            size,
            "TessBuffers::read_entries",
        )?;
        // A Vec<u8> need not be aligned for the entry type: read each one unaligned.
        let entries: Vec<GpuTessEntry> = bytes
            .chunks_exact(std::mem::size_of::<GpuTessEntry>())
            .take(count)
            .map(bytemuck::pod_read_unaligned)
            .collect();
        Ok(entries)
    }

    /// Byte offset of draw `d`'s indirect arguments.
    pub fn draw_args_offset(d: usize) -> u64 {
        4 * (ARGS_DRAWS + 4 * d) as u64
    }

    /// Reads the last frame's per-view statistics (blocking; for the CLI and tests, never in
    /// the render loop).
    pub fn read_stats(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        views: usize,
        input: u32,
    ) -> Result<Vec<TessStats>, RenderError> {
        let views = views.min(self.stats_capacity);
        let bytes = super::targets::read_buffer(
            device,
            queue,
            &self.stats,
            STATS_BYTES * views as u64,
            "TessBuffers::read_stats",
        )?;
        let mut stats = Vec::with_capacity(views);
        stats_from_bytes(&bytes, input, self.capacity, &mut stats);
        Ok(stats)
    }

    /// The per-view statistics the frame's views wrote (`STATS_BYTES` each), for copying into
    /// a read-back; `None` when it holds fewer than `views`.
    pub fn stats_buffer(&self, views: usize) -> Option<&wgpu::Buffer> {
        (views <= self.stats_capacity).then_some(&self.stats)
    }
}
