//! Draws the scene's triangles for one wall and eye (shaders/scene.wgsl): pipelines, scene
//! buffers, materials and textures, all created once and reused every frame.

use super::error::RenderError;
use super::scene_chunks::{ChunkPlan, plan_chunks};
use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};

use super::shaders;
use super::shadow_pass::{ShadowPass, ShadowSettings};
use super::targets::{COLOR_FORMAT, DEPTH_FORMAT, ENCODED_FORMAT};
use super::uniforms::{MaterialUniforms, UNIFORM_STRIDE};
use crate::scene::{
    AlphaMode, ColorSpace, Light, Scene, TEXTURE_SLOTS, Texture, TextureRef, Vertex, Wrap,
};
use crate::sky::cubemap::{linear_to_srgb, srgb_to_linear};

/// Vertex layout on the GPU. Keep in sync with `VertexInput` in shaders/scene.wgsl and with
/// `VERTEX_FLOATS` in shaders/common.wgsl (the tessellator reads it as storage).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GpuVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
    pub uv1: [f32; 2],
    pub color: [f32; 4],
    pub tangent: [f32; 4],
}

impl From<&Vertex> for GpuVertex {
    fn from(v: &Vertex) -> Self {
        Self {
            position: v.position,
            normal: v.normal,
            uv: v.uv,
            uv1: v.uv1,
            color: v.color,
            tangent: v.tangent,
        }
    }
}

const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 6] = wgpu::vertex_attr_array![
    0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Float32x2, 4 => Float32x4,
    5 => Float32x4
];

/// Which pipeline variant a draw needs. Pipelines are built once per key, never per frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct PipelineKey {
    double_sided: bool,
    wireframe: bool,
    /// Vertices pulled from the tessellator's output (`vs_tess`) instead of a vertex buffer.
    tessellated: bool,
    /// The panorama's geometric route (`vs_pano`/`fs_pano`; tessellated output, no
    /// wireframe).
    panorama: bool,
    /// Alpha-blended over what is drawn (no depth writes; never wireframe).
    blend: bool,
    /// Colour stored as sRGB bytes the shader encodes (`ENCODED_FORMAT` samples, resolved by
    /// `ResolvePass`) instead of through an sRGB target; never blended, never the panorama.
    encoded: bool,
}

impl PipelineKey {
    /// The variant `draw` needs in the shaded layer or the wireframe overlay (`wire`).
    fn of(draw: &GpuDraw, wire: bool, tessellated: bool, panorama: bool, encoded: bool) -> Self {
        Self {
            double_sided: draw.double_sided,
            wireframe: wire,
            tessellated,
            panorama,
            blend: draw.blend && !wire,
            encoded,
        }
    }
}

/// Where a draw's vertices come from and how they are projected (the walls' tessellated
/// draws are recorded by `ScenePass::draw_split`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Variant {
    /// The scene's own indexed vertices.
    Plain,
    /// The tessellator's output, projected and pre-clipped by the panorama's map.
    Panorama,
}

/// The scene pass: layouts, pipelines and per-frame uniform buffers.
#[derive(Debug)]
pub struct ScenePass {
    frame_layout: wgpu::BindGroupLayout,
    material_layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    /// `None` where the device cannot draw tessellated output (no vertex-stage storage).
    tess_pipeline_layout: Option<wgpu::PipelineLayout>,
    shader: wgpu::ShaderModule,
    /// Bumped whenever the view buffer is replaced (bind groups built on it must follow).
    pipelines: HashMap<PipelineKey, wgpu::RenderPipeline>,
    /// Pipelines built so far (switching settings must not build any).
    pub(crate) pipelines_built: u64,
    msaa: u32,
    /// The shadow maps every draw looks up (group 3).
    pub(crate) shadows: ShadowPass,
}

/// Vertex and index buffers holding a run of draws.
#[derive(Debug)]
pub(crate) struct SceneChunk {
    pub(crate) vertex_buffer: wgpu::Buffer,
    pub(crate) index_buffer: wgpu::Buffer,
}

/// A scene uploaded to the GPU.
#[derive(Debug)]
pub struct SceneGpu {
    /// One chunk holding the whole scene (as the file laid it out) when it fits the device's
    /// largest buffer; else runs of whole draws, each under the limit (see [`plan_chunks`]).
    chunks: Vec<SceneChunk>,
    draws: Vec<GpuDraw>,
    /// The order draws are issued in: opaque ones, then blended ones back to front (sorted
    /// each frame by [`SceneGpu::sort_blended`]).
    order: Vec<usize>,
    /// Draws before this position in `order` are opaque.
    opaque_count: usize,
    /// The scene file's lights (scene space), for the frame uniforms.
    pub(crate) lights: Vec<Light>,
    /// Axis-aligned bounds (scene space), for the shadow maps' extent.
    pub(crate) bounds: Option<(glam::Vec3, glam::Vec3)>,
    /// Per source triangle: its draw index (or `NO_DRAW`), bit 31 set when double-sided.
    pub(crate) tri_info: Vec<u32>,
    /// Clusters of the draws' triangles with their bounds (empty for a split scene, which is
    /// not tessellated): each frame, those provably fine in a view are drawn directly.
    pub(crate) clusters: Vec<crate::tess::clusters::Cluster>,
    material_bind_groups: Vec<wgpu::BindGroup>,
    /// Kept alive for the bind groups.
    _material_buffer: wgpu::Buffer,
    _textures: Vec<wgpu::Texture>,
    pub triangle_count: usize,
}

#[derive(Debug, Clone, Copy)]
struct GpuDraw {
    /// The chunk whose buffers hold it; `first_index` counts in that chunk's index buffer.
    chunk: usize,
    first_index: u32,
    index_count: u32,
    material: usize,
    double_sided: bool,
    blend: bool,
    /// Drawn into the shadow maps: not blended (glass) and not emitting light (a bulb around
    /// its own light must not shadow the room).
    casts_shadow: bool,
    /// Centre of the draw's bounding box (scene space): blended draws are sorted by its
    /// distance from the head.
    centre: glam::Vec3,
}

impl SceneGpu {
    /// Records the shadow casters into a depth-only pass whose pipeline is bound.
    pub(crate) fn draw_casters(&self, pass: &mut wgpu::RenderPass<'_>) {
        let bound = std::cell::Cell::new(None);
        for draw in self.draws.iter().filter(|d| d.casts_shadow) {
            self.bind_chunk(pass, draw.chunk, &bound);
            pass.draw_indexed(
                draw.first_index..draw.first_index + draw.index_count,
                0,
                0..1,
            );
        }
    }

    /// Binds chunk `chunk`'s buffers unless they are bound already (`bound`).
    fn bind_chunk(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        chunk: usize,
        bound: &std::cell::Cell<Option<usize>>,
    ) {
        if bound.get() == Some(chunk) {
            return;
        }
        if let Some(c) = self.chunks.get(chunk) {
            pass.set_vertex_buffer(0, c.vertex_buffer.slice(..));
            pass.set_index_buffer(c.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
            bound.set(Some(chunk));
        }
    }

    /// Overwrites the first vertices of the first buffer (the wand ray's per-frame positions;
    /// the counts never change, so nothing is allocated).
    pub(crate) fn write_vertices(&self, queue: &wgpu::Queue, vertices: &[GpuVertex]) {
        if let Some(c) = self.chunks.first() {
            queue.write_buffer(&c.vertex_buffer, 0, bytemuck::cast_slice(vertices));
        }
    }

    /// The buffers of the whole scene, if it is one chunk (the tessellator binds them whole).
    pub(crate) fn whole(&self) -> Result<&SceneChunk, super::error::TessError> {
        match self.chunks.as_slice() {
            [one] => Ok(one),
            chunks => Err(super::error::TessError::SplitScene(chunks.len())),
        }
    }

    /// How many buffers the scene is split over (1 when it fits the largest buffer).
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// Whether any draw is alpha-blended (blending needs linear colour in the target, so
    /// such a scene is not drawn into shader-encoded samples).
    pub fn has_blended_draws(&self) -> bool {
        self.opaque_count < self.order.len()
    }

    /// Number of draws (materials runs) the scene is drawn with.
    pub fn draw_count(&self) -> usize {
        self.draws.len()
    }

    /// Orders the blended draws back to front as seen from `head` (scene space): the farthest
    /// first, so that each is blended over what lies behind it. Sorting whole draws (a mesh
    /// primitive each: the loader never merges blended ones) is exact for separate
    /// transparent objects such as panes, visors and glass; crossing or self-overlapping
    /// transparent surfaces inside one primitive are not sorted. One order serves every view
    /// of a frame: the eyes differ from the head by millimetres.
    pub fn sort_blended(&mut self, head: glam::Vec3) {
        let draws = &self.draws;
        self.order[self.opaque_count..].sort_by(|&a, &b| {
            let da = draws[a].centre.distance_squared(head);
            let db = draws[b].centre.distance_squared(head);
            db.total_cmp(&da)
        });
    }
}

impl ScenePass {
    pub fn new(
        device: &wgpu::Device,
        msaa: u32,
        tess_draw_layout: Option<&wgpu::BindGroupLayout>,
    ) -> Self {
        let uniform_entry = |binding, dynamic| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: dynamic,
                min_binding_size: None,
            },
            count: None,
        };
        let frame_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("ScenePass::frame_layout"),
            entries: &[uniform_entry(0, false), uniform_entry(1, true)],
        });
        // Uniforms, then one texture and one sampler per slot (base colour,
        // metallic-roughness, normal, occlusion, emissive).
        let mut material_entries = vec![uniform_entry(0, true)];
        for slot in 0..TEXTURE_SLOTS as u32 {
            material_entries.push(wgpu::BindGroupLayoutEntry {
                binding: 1 + slot,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            });
        }
        for slot in 0..TEXTURE_SLOTS as u32 {
            material_entries.push(wgpu::BindGroupLayoutEntry {
                binding: 1 + TEXTURE_SLOTS as u32 + slot,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            });
        }
        let material_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("ScenePass::material_layout"),
            entries: &material_entries,
        });
        let shadows = ShadowPass::new(device, ShadowSettings::default().map_size);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("ScenePass::pipeline_layout"),
            bind_group_layouts: &[
                Some(&frame_layout),
                Some(&material_layout),
                None,
                Some(shadows.layout()),
            ],
            immediate_size: 0,
        });
        let tess_pipeline_layout = tess_draw_layout.map(|layout| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("ScenePass::tess_pipeline_layout"),
                bind_group_layouts: &[
                    Some(&frame_layout),
                    Some(&material_layout),
                    Some(layout),
                    Some(shadows.layout()),
                ],
                immediate_size: 0,
            })
        });
        let shader = shaders::module(device, "ScenePass::shader", shaders::SCENE);
        let mut pass = Self {
            frame_layout,
            material_layout,
            pipeline_layout,
            tess_pipeline_layout,
            shader,
            pipelines: HashMap::new(),
            pipelines_built: 0,
            msaa,
            shadows,
        };
        pass.build_pipelines(device, msaa);
        pass
    }

    /// Builds every pipeline variant for a sample count (at start-up and when MSAA changes);
    /// the variants for shader-encoded samples only with MSAA.
    pub fn build_pipelines(&mut self, device: &wgpu::Device, msaa: u32) {
        self.msaa = msaa;
        self.pipelines.clear();
        let wireframe_supported = device
            .features()
            .contains(wgpu::Features::POLYGON_MODE_LINE);
        for double_sided in [false, true] {
            for (wireframe, blend) in [(false, false), (true, false), (false, true)] {
                for (tessellated, panorama) in [(false, false), (true, false), (true, true)] {
                    for encoded in [false, true] {
                        if (wireframe && (panorama || !wireframe_supported))
                            || (tessellated && self.tess_pipeline_layout.is_none())
                            || (encoded && (msaa < 2 || blend || panorama))
                        {
                            continue;
                        }
                        let key = PipelineKey {
                            double_sided,
                            wireframe,
                            tessellated,
                            panorama,
                            blend,
                            encoded,
                        };
                        let pipeline = self.build_pipeline(device, key);
                        self.pipelines.insert(key, pipeline);
                        self.pipelines_built += 1;
                    }
                }
            }
        }
    }

    fn build_pipeline(&self, device: &wgpu::Device, key: PipelineKey) -> wgpu::RenderPipeline {
        let label = format!(
            "ScenePass::pipeline{}{}{}{}{}{}",
            if key.double_sided {
                " double-sided"
            } else {
                ""
            },
            if key.wireframe { " wireframe" } else { "" },
            if key.tessellated { " tessellated" } else { "" },
            if key.panorama { " panorama" } else { "" },
            if key.blend { " blended" } else { "" },
            if key.encoded { " encoded" } else { "" }
        );
        let constants = [
            ("PANO_CULL_BACK", if key.double_sided { 0.0 } else { 1.0 }),
            ("ENCODE_SRGB_OUTPUT", if key.encoded { 1.0 } else { 0.0 }),
        ];
        let compilation_options = wgpu::PipelineCompilationOptions {
            constants: &constants,
            ..Default::default()
        };
        let vertex_buffers = [Some(wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<GpuVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &VERTEX_ATTRIBUTES,
        })];
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(&label),
            layout: Some(match (&self.tess_pipeline_layout, key.tessellated) {
                (Some(layout), true) => layout,
                _ => &self.pipeline_layout,
            }),
            vertex: wgpu::VertexState {
                module: &self.shader,
                entry_point: Some(match (key.tessellated, key.panorama) {
                    (_, true) => "vs_pano",
                    (true, false) => "vs_tess",
                    (false, false) => "vs_main",
                }),
                compilation_options: compilation_options.clone(),
                buffers: if key.tessellated {
                    &[]
                } else {
                    &vertex_buffers
                },
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                // The panorama culls in its vertex shader (a pre-clipped triangle's band has
                // no meaningful winding).
                cull_mode: (!key.double_sided && !key.panorama).then_some(wgpu::Face::Back),
                polygon_mode: if key.wireframe {
                    wgpu::PolygonMode::Line
                } else {
                    wgpu::PolygonMode::Fill
                },
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                // Blended surfaces are tested against the depth of opaque ones but do not hide
                // what is drawn after them (they are sorted back to front instead).
                depth_write_enabled: Some(!key.wireframe && !key.blend),
                depth_compare: Some(if key.wireframe {
                    wgpu::CompareFunction::LessEqual
                } else {
                    wgpu::CompareFunction::Less
                }),
                stencil: Default::default(),
                // Pull the overlay's lines slightly towards the eye so they win against the
                // filled surface they outline.
                bias: if key.wireframe {
                    wgpu::DepthBiasState {
                        constant: -4,
                        slope_scale: -1.0,
                        clamp: 0.0,
                    }
                } else {
                    Default::default()
                },
            }),
            multisample: wgpu::MultisampleState {
                count: self.msaa,
                ..Default::default()
            },
            fragment: Some(wgpu::FragmentState {
                module: &self.shader,
                entry_point: Some(match (key.wireframe, key.panorama) {
                    (true, _) => "fs_wireframe",
                    (false, true) => "fs_pano",
                    (false, false) => "fs_main",
                }),
                compilation_options,
                targets: &[Some(wgpu::ColorTargetState {
                    format: if key.encoded {
                        ENCODED_FORMAT
                    } else {
                        COLOR_FORMAT
                    },
                    blend: key.blend.then_some(wgpu::BlendState::ALPHA_BLENDING),
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        })
    }

    pub fn msaa(&self) -> u32 {
        self.msaa
    }

    /// The layout of group 0 (frame uniforms and the view), which every view set binds.
    pub fn frame_layout(&self) -> &wgpu::BindGroupLayout {
        &self.frame_layout
    }

    /// Records the draws of `scene` for view slot `view_index` into an open render pass
    /// (`encoded`: whose colour attachment takes shader-encoded bytes).
    pub fn draw(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        scene: &SceneGpu,
        views: &wgpu::BindGroup,
        view_index: usize,
        wireframe: bool,
        encoded: bool,
    ) {
        let bound = std::cell::Cell::new(None);
        self.draw_materials(
            pass,
            scene,
            views,
            view_index,
            wireframe,
            Variant::Plain,
            encoded,
            |pass, _, draw| {
                scene.bind_chunk(pass, draw.chunk, &bound);
                pass.draw_indexed(
                    draw.first_index..draw.first_index + draw.index_count,
                    0,
                    0..1,
                );
            },
        );
    }

    /// Sets the pipeline of `key` unless it is `bound` already; false if there is none.
    fn bind_pipeline(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        bound: &mut Option<PipelineKey>,
        key: PipelineKey,
    ) -> bool {
        if *bound != Some(key) {
            let Some(pipeline) = self.pipelines.get(&key) else {
                return false;
            };
            pass.set_pipeline(pipeline);
            *bound = Some(key);
        }
        true
    }

    /// Records view slot `view_index` of a tessellated frame: per draw, in the scene's order
    /// (opaque, then blended back to front), its clusters proven fine through the ordinary
    /// path with the per-vertex warp (`fine`: (draw, first index, index count), sorted by
    /// draw), then its refined part from the tessellator's indirect draw (`tess`; `None` when
    /// the view refines nothing; `refined_draws`: the draws it can have output for, ascending,
    /// `None` for all; `encoded` as for [`ScenePass::draw`]).
    #[allow(clippy::too_many_arguments)]
    pub fn draw_split(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        scene: &SceneGpu,
        views: &wgpu::BindGroup,
        tess: Option<&super::tessellator::TessBuffers>,
        refined_draws: Option<&[u32]>,
        fine: &[(u32, u32, u32)],
        view_index: usize,
        wireframe: bool,
        encoded: bool,
    ) {
        let view_offset = (view_index as u64 * UNIFORM_STRIDE) as u32;
        pass.set_bind_group(0, views, &[view_offset]);
        pass.set_bind_group(3, self.shadows.bind_group(), &[]);
        if let Some(t) = tess {
            // Ignored by the ordinary pipelines, whose layout has no group 2.
            pass.set_bind_group(2, &t.draw_group, &[]);
        }
        let chunk = std::cell::Cell::new(None);
        let layers: &[bool] = if wireframe { &[false, true] } else { &[false] };
        for &wire in layers {
            let mut bound: Option<PipelineKey> = None;
            for &d in &scene.order {
                let draw = &scene.draws[d];
                let start = fine.partition_point(|f| (f.0 as usize) < d);
                let ranges = &fine[start..];
                let count = ranges.iter().take_while(|f| f.0 as usize == d).count();
                let ranges = &ranges[..count];
                // No refined cluster of this draw in this view: its indirect draw is empty.
                let tess = tess
                    .filter(|_| refined_draws.is_none_or(|r| r.binary_search(&(d as u32)).is_ok()));
                if ranges.is_empty() && tess.is_none() {
                    continue;
                }
                let material_offset = (draw.material as u64 * UNIFORM_STRIDE) as u32;
                pass.set_bind_group(
                    1,
                    &scene.material_bind_groups[draw.material],
                    &[material_offset],
                );
                for tessellated in [false, true] {
                    if (tessellated && tess.is_none()) || (!tessellated && ranges.is_empty()) {
                        continue;
                    }
                    let key = PipelineKey::of(draw, wire, tessellated, false, encoded);
                    if !self.bind_pipeline(pass, &mut bound, key) {
                        continue;
                    }
                    match tess {
                        Some(t) if tessellated => pass.draw_indirect(
                            &t.args,
                            super::tessellator::TessBuffers::draw_args_offset(d),
                        ),
                        _ => {
                            scene.bind_chunk(pass, draw.chunk, &chunk);
                            for &(_, first, count) in ranges {
                                pass.draw_indexed(first..first + count, 0, 0..1);
                            }
                        }
                    }
                }
            }
        }
    }

    /// Records the panorama's geometric route for view slot `view_index`: the tessellator's
    /// output for that view, projected and pre-clipped by `vs_pano`/`fs_pano`.
    pub fn draw_panorama(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        scene: &SceneGpu,
        views: &wgpu::BindGroup,
        tess: &super::tessellator::TessBuffers,
        view_index: usize,
    ) {
        let variant = Variant::Panorama;
        self.draw_indirect(pass, scene, views, tess, view_index, false, variant);
    }

    /// The tessellator's output for a view, one indirect draw per scene draw.
    #[allow(clippy::too_many_arguments)]
    fn draw_indirect(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        scene: &SceneGpu,
        views: &wgpu::BindGroup,
        tess: &super::tessellator::TessBuffers,
        view_index: usize,
        wireframe: bool,
        variant: Variant,
    ) {
        pass.set_bind_group(2, &tess.draw_group, &[]);
        self.draw_materials(
            pass,
            scene,
            views,
            view_index,
            wireframe,
            variant,
            false,
            |pass, d, _| {
                pass.draw_indirect(
                    &tess.args,
                    super::tessellator::TessBuffers::draw_args_offset(d),
                );
            },
        );
    }

    /// Binds the view, then for each layer (shaded, and the wireframe overlay if asked) and
    /// each draw: the pipeline variant (only when it changes), the material, and `issue`.
    #[allow(clippy::too_many_arguments)]
    fn draw_materials(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        scene: &SceneGpu,
        views: &wgpu::BindGroup,
        view_index: usize,
        wireframe: bool,
        variant: Variant,
        encoded: bool,
        issue: impl Fn(&mut wgpu::RenderPass<'_>, usize, &GpuDraw),
    ) {
        let view_offset = (view_index as u64 * UNIFORM_STRIDE) as u32;
        pass.set_bind_group(0, views, &[view_offset]);
        pass.set_bind_group(3, self.shadows.bind_group(), &[]);
        let layers: &[bool] = if wireframe { &[false, true] } else { &[false] };
        for &wire in layers {
            let mut bound: Option<PipelineKey> = None;
            for &d in &scene.order {
                let draw = &scene.draws[d];
                let panorama = variant == Variant::Panorama;
                let key = PipelineKey::of(draw, wire, panorama, panorama, encoded);
                if !self.bind_pipeline(pass, &mut bound, key) {
                    continue;
                }
                let material_offset = (draw.material as u64 * UNIFORM_STRIDE) as u32;
                pass.set_bind_group(
                    1,
                    &scene.material_bind_groups[draw.material],
                    &[material_offset],
                );
                issue(pass, d, draw);
            }
        }
    }

    /// Uploads a scene: vertex/index buffers, material uniforms, textures with mipmaps.
    /// Every size is checked against the device's limits first (the error names the limit),
    /// and the GPU running out of memory is an error, not a panic.
    /// A scene larger than `max_buffer_bytes` (or the device's largest buffer) is split
    /// into several buffers, by whole draws.
    pub fn upload_scene(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        scene: &Scene,
        max_buffer_bytes: Option<u64>,
    ) -> Result<SceneGpu, RenderError> {
        check_scene_limits(device, scene)?;
        let limit = max_buffer_bytes
            .unwrap_or(u64::MAX)
            .min(device.limits().max_buffer_size);
        let vertex_size = std::mem::size_of::<GpuVertex>() as u64;
        let plan =
            plan_chunks(scene, vertex_size, limit).map_err(|e| RenderError::SceneTooLarge {
                what: "vertices of one triangle",
                bytes: e.bytes,
                limit: e.limit,
            })?;
        if let ChunkPlan::Split(chunks) = &plan {
            tracing::info!(
                "the scene's geometry ({} vertices, {} indices) is split over {} buffers of at \
                 most {limit} bytes; tessellated modes cannot bind it whole",
                scene.vertices.len(),
                scene.indices.len(),
                chunks.len()
            );
        }
        // Out of memory, and the validation errors of filling what could not be made.
        let invalid = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out_of_memory = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let uploaded = self.upload_checked(device, queue, scene, plan);
        let errors = [
            pollster::block_on(out_of_memory.pop()),
            pollster::block_on(invalid.pop()),
        ];
        match errors.into_iter().flatten().next() {
            None => Ok(uploaded),
            Some(e) => Err(RenderError::OutOfMemory(format!(
                "uploading the scene ({} vertices, {} textures): {e}",
                scene.vertices.len(),
                scene.textures.len()
            ))),
        }
    }

    fn upload_checked(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        scene: &Scene,
        plan: ChunkPlan,
    ) -> SceneGpu {
        // (chunk, scene draw, first index, index count) of every piece drawn.
        let mut pieces: Vec<(usize, usize, u32, u32)> = Vec::new();
        let chunks: Vec<SceneChunk> = match &plan {
            ChunkPlan::Whole => {
                for (d, draw) in scene.draws.iter().enumerate() {
                    pieces.push((0, d, draw.first_index, draw.index_count));
                }
                vec![upload_chunk(
                    device,
                    queue,
                    "SceneGpu",
                    &scene.vertices,
                    &scene.indices,
                )]
            }
            ChunkPlan::Split(split) => split
                .iter()
                .enumerate()
                .map(|(c, chunk)| {
                    for p in &chunk.pieces {
                        pieces.push((c, p.draw, p.first_index, p.index_count));
                    }
                    let vertices: Vec<crate::scene::Vertex> = chunk
                        .vertices
                        .iter()
                        .filter_map(|&v| scene.vertices.get(v as usize).copied())
                        .collect();
                    let label = format!("SceneGpu::chunk {c}");
                    upload_chunk(device, queue, &label, &vertices, &chunk.indices)
                })
                .collect(),
        };
        // A piece's corner positions, for its bounding box.
        let corner = |chunk: usize, index: u32| -> glam::Vec3 {
            let vertex = match &plan {
                ChunkPlan::Whole => Some(index),
                ChunkPlan::Split(split) => split
                    .get(chunk)
                    .and_then(|c| c.vertices.get(index as usize).copied()),
            };
            vertex
                .and_then(|v| scene.vertices.get(v as usize))
                .map_or(glam::Vec3::ZERO, |v| glam::Vec3::from(v.position))
        };
        let chunk_indices = |chunk: usize| -> &[u32] {
            match &plan {
                ChunkPlan::Whole => &scene.indices,
                ChunkPlan::Split(split) => split.get(chunk).map_or(&[], |c| &c.indices),
            }
        };

        let textures: Vec<wgpu::Texture> = scene
            .textures
            .iter()
            .map(|t| upload_texture(device, queue, t))
            .collect();
        let white = upload_texture(
            device,
            queue,
            &Texture {
                name: "white".into(),
                width: 1,
                height: 1,
                rgba8: vec![255; 4],
                color_space: ColorSpace::Linear,
            },
        );
        let texture_views: Vec<wgpu::TextureView> = textures
            .iter()
            .map(|t| t.create_view(&Default::default()))
            .collect();
        let white_view = white.create_view(&Default::default());

        let mut material_bytes =
            Vec::with_capacity(scene.materials.len() * UNIFORM_STRIDE as usize);
        for m in &scene.materials {
            material_bytes.extend_from_slice(bytemuck::bytes_of(&MaterialUniforms::from(m)));
            material_bytes.resize(
                material_bytes
                    .len()
                    .next_multiple_of(UNIFORM_STRIDE as usize),
                0,
            );
        }
        if material_bytes.is_empty() {
            material_bytes.resize(UNIFORM_STRIDE as usize, 0);
        }
        let material_buffer = buffer_with(
            device,
            queue,
            "SceneGpu::material_buffer",
            &material_bytes,
            wgpu::BufferUsages::UNIFORM,
        );

        let mut samplers: HashMap<(Wrap, Wrap, bool), wgpu::Sampler> = HashMap::new();
        let mut material_bind_groups = Vec::with_capacity(scene.materials.len());
        for m in &scene.materials {
            let slots = m.texture_slots();
            // A slot without a (valid) texture binds white; the shader does not sample it.
            let bound = |t: &Option<TextureRef>| t.filter(|t| t.texture < texture_views.len());
            let views: Vec<&wgpu::TextureView> = slots
                .iter()
                .map(|t| bound(t).map_or(&white_view, |t| &texture_views[t.texture]))
                .collect();
            let keys: Vec<(Wrap, Wrap, bool)> = slots
                .iter()
                .map(|t| {
                    bound(t).map_or((Wrap::Repeat, Wrap::Repeat, false), |t| {
                        (t.wrap_u, t.wrap_v, t.nearest)
                    })
                })
                .collect();
            for &key in &keys {
                samplers
                    .entry(key)
                    .or_insert_with(|| make_sampler(device, key));
            }
            let mut entries = vec![wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &material_buffer,
                    offset: 0,
                    size: wgpu::BufferSize::new(std::mem::size_of::<MaterialUniforms>() as u64),
                }),
            }];
            for (slot, view) in views.iter().enumerate() {
                entries.push(wgpu::BindGroupEntry {
                    binding: 1 + slot as u32,
                    resource: wgpu::BindingResource::TextureView(view),
                });
            }
            for (slot, key) in keys.iter().enumerate() {
                if let Some(sampler) = samplers.get(key) {
                    entries.push(wgpu::BindGroupEntry {
                        binding: 1 + (TEXTURE_SLOTS + slot) as u32,
                        resource: wgpu::BindingResource::Sampler(sampler),
                    });
                }
            }
            material_bind_groups.push(device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(&format!("SceneGpu::material {}", m.name)),
                layout: &self.material_layout,
                entries: &entries,
            }));
        }

        let draws: Vec<GpuDraw> = pieces
            .iter()
            .filter_map(|&(chunk, d, first_index, index_count)| {
                let scene_draw = scene.draws.get(d)?;
                let material = scene.materials.get(scene_draw.material)?;
                let range = first_index as usize..(first_index + index_count) as usize;
                let (lo, hi) = chunk_indices(chunk).get(range).unwrap_or(&[]).iter().fold(
                    (glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY),
                    |(lo, hi), &i| {
                        let p = corner(chunk, i);
                        (lo.min(p), hi.max(p))
                    },
                );
                Some(GpuDraw {
                    chunk,
                    first_index,
                    index_count,
                    material: scene_draw.material,
                    double_sided: material.double_sided,
                    blend: material.alpha_mode == AlphaMode::Blend,
                    casts_shadow: material.alpha_mode != AlphaMode::Blend
                        && material.emissive == [0.0; 3],
                    centre: 0.5 * (lo + hi),
                })
            })
            .collect();
        // Triangles no valid draw covers get a draw index no draw has: never drawn. (A split
        // scene is not tessellated: it has no single buffer to bind.)
        let whole = chunks.len() == 1;
        let mut tri_info =
            vec![super::tessellator::NO_DRAW; if whole { scene.triangle_count() } else { 0 }];
        for (d, draw) in draws.iter().enumerate() {
            let flag = if draw.double_sided { 1 << 31 } else { 0 };
            let first = draw.first_index as usize / 3;
            let count = draw.index_count as usize / 3;
            for info in tri_info.iter_mut().skip(first).take(count) {
                *info = d as u32 | flag;
            }
        }
        let clusters = if whole {
            crate::tess::clusters::build_clusters(
                scene,
                draws
                    .iter()
                    .enumerate()
                    .map(|(d, g)| (d as u32, g.first_index, g.index_count)),
            )
        } else {
            Vec::new()
        };
        let mut order: Vec<usize> = (0..draws.len()).filter(|&d| !draws[d].blend).collect();
        let opaque_count = order.len();
        order.extend((0..draws.len()).filter(|&d| draws[d].blend));

        let mut all_textures = textures;
        all_textures.push(white);
        SceneGpu {
            chunks,
            draws,
            order,
            opaque_count,
            lights: scene.lights.clone(),
            bounds: scene.bounds(),
            tri_info,
            clusters,
            material_bind_groups,
            _material_buffer: material_buffer,
            _textures: all_textures,
            triangle_count: scene.triangle_count(),
        }
    }
}

fn address_mode(w: Wrap) -> wgpu::AddressMode {
    match w {
        Wrap::Repeat => wgpu::AddressMode::Repeat,
        Wrap::MirroredRepeat => wgpu::AddressMode::MirrorRepeat,
        Wrap::ClampToEdge => wgpu::AddressMode::ClampToEdge,
    }
}

fn make_sampler(device: &wgpu::Device, (u, v, nearest): (Wrap, Wrap, bool)) -> wgpu::Sampler {
    device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("SceneGpu::sampler"),
        address_mode_u: address_mode(u),
        address_mode_v: address_mode(v),
        mag_filter: if nearest {
            wgpu::FilterMode::Nearest
        } else {
            wgpu::FilterMode::Linear
        },
        min_filter: wgpu::FilterMode::Linear,
        mipmap_filter: wgpu::MipmapFilterMode::Linear,
        anisotropy_clamp: 8,
        ..Default::default()
    })
}

/// Uploads a texture with a full mip chain, box-filtered on the CPU once at load: in linear
/// light for sRGB textures (averaging the encoded bytes would darken every mip level).
/// Vertex and index buffers for `vertices` and `indices` (wgpu refuses empty buffers: an
/// empty scene gets valid, unused ones).
fn upload_chunk(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    vertices: &[crate::scene::Vertex],
    indices: &[u32],
) -> SceneChunk {
    let mut gpu: Vec<GpuVertex> = vertices.iter().map(GpuVertex::from).collect();
    if gpu.is_empty() {
        gpu.push(GpuVertex::zeroed());
    }
    let index_bytes: &[u8] = if indices.is_empty() {
        &[0; 12]
    } else {
        bytemuck::cast_slice(indices)
    };
    SceneChunk {
        vertex_buffer: buffer_with(
            device,
            queue,
            &format!("{label}::vertex_buffer"),
            bytemuck::cast_slice(&gpu),
            wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::STORAGE,
        ),
        index_buffer: buffer_with(
            device,
            queue,
            &format!("{label}::index_buffer"),
            index_bytes,
            wgpu::BufferUsages::INDEX | wgpu::BufferUsages::STORAGE,
        ),
    }
}

/// A buffer holding `contents`, created unmapped and filled through the queue: should the
/// device be out of memory, the failure lands in the caller's error scope (wgpu's
/// `create_buffer_init` maps at creation and panics when the buffer could not be made).
fn buffer_with(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    let align = wgpu::COPY_BUFFER_ALIGNMENT;
    let size = (contents.len() as u64).next_multiple_of(align).max(align);
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: usage | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let aligned = contents.len() - contents.len() % align as usize;
    if aligned > 0 {
        queue.write_buffer(&buffer, 0, &contents[..aligned]);
    }
    if aligned < contents.len() {
        let mut tail = [0u8; wgpu::COPY_BUFFER_ALIGNMENT as usize];
        tail[..contents.len() - aligned].copy_from_slice(&contents[aligned..]);
        queue.write_buffer(&buffer, aligned as u64, &tail);
    }
    buffer
}

/// Refuses a scene whose textures pass this device's limits, naming the limit (its geometry
/// is split over buffers by [`plan_chunks`]).
fn check_scene_limits(device: &wgpu::Device, scene: &Scene) -> Result<(), RenderError> {
    let limits = device.limits();
    let material_bytes = scene.materials.len() as u64 * UNIFORM_STRIDE;
    if material_bytes > limits.max_buffer_size {
        return Err(RenderError::SceneTooLarge {
            what: "materials",
            bytes: material_bytes,
            limit: limits.max_buffer_size,
        });
    }
    let max_side = limits.max_texture_dimension_2d;
    if let Some(t) = scene
        .textures
        .iter()
        .find(|t| t.width > max_side || t.height > max_side)
    {
        return Err(RenderError::TextureTooLarge {
            name: t.name.clone(),
            width: t.width,
            height: t.height,
            max: max_side,
        });
    }
    Ok(())
}

fn upload_texture(device: &wgpu::Device, queue: &wgpu::Queue, t: &Texture) -> wgpu::Texture {
    let mip_count = 32 - t.width.max(t.height).max(1).leading_zeros();
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some(&format!("SceneGpu::texture {}", t.name)),
        size: wgpu::Extent3d {
            width: t.width,
            height: t.height,
            depth_or_array_layers: 1,
        },
        mip_level_count: mip_count,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: match t.color_space {
            ColorSpace::Srgb => wgpu::TextureFormat::Rgba8UnormSrgb,
            ColorSpace::Linear => wgpu::TextureFormat::Rgba8Unorm,
        },
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (mip, (width, height, bytes)) in mip_chain(t).iter().enumerate() {
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: mip as u32,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(width * 4),
                rows_per_image: Some(*height),
            },
            wgpu::Extent3d {
                width: *width,
                height: *height,
                depth_or_array_layers: 1,
            },
        );
    }
    texture
}

/// Every mip level of a texture (width, height, RGBA8), level 0 first down to 1×1, each
/// filtered from the one above in linear light.
pub fn mip_chain(t: &Texture) -> Vec<(u32, u32, Vec<u8>)> {
    let mut out = Vec::new();
    let mut level = image::Rgba32FImage::from_raw(
        t.width,
        t.height,
        t.rgba8
            .chunks_exact(4)
            .flat_map(|px| decode_texel(px, t.color_space))
            .collect(),
    );
    while let Some(img) = level.take() {
        let bytes: Vec<u8> = img
            .as_raw()
            .chunks_exact(4)
            .flat_map(|px| encode_texel(px, t.color_space))
            .collect();
        out.push((img.width(), img.height(), bytes));
        if img.width() == 1 && img.height() == 1 {
            break;
        }
        let (w, h) = ((img.width() / 2).max(1), (img.height() / 2).max(1));
        level = Some(image::imageops::resize(
            &img,
            w,
            h,
            image::imageops::FilterType::Triangle,
        ));
    }
    out
}

/// One RGBA8 texel as linear-light floats (alpha is always linear).
fn decode_texel(px: &[u8], space: ColorSpace) -> [f32; 4] {
    let unit = |b: u8| f32::from(b) / 255.0;
    let colour = |b: u8| match space {
        ColorSpace::Srgb => srgb_to_linear(b),
        ColorSpace::Linear => unit(b),
    };
    [colour(px[0]), colour(px[1]), colour(px[2]), unit(px[3])]
}

/// The inverse of [`decode_texel`], rounded to the nearest byte.
fn encode_texel(px: &[f32], space: ColorSpace) -> [u8; 4] {
    let byte = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    let colour = |v: f32| match space {
        ColorSpace::Srgb => linear_to_srgb(v),
        ColorSpace::Linear => byte(v),
    };
    [colour(px[0]), colour(px[1]), colour(px[2]), byte(px[3])]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mipmaps_average_light_not_srgb_bytes() {
        // Black and white stripes: their average is half the light, sRGB 188, not the byte
        // average 128 (which is 22 % of the light: every distant texture would darken).
        let stripes = |space| Texture {
            name: "stripes".into(),
            width: 4,
            height: 2,
            rgba8: (0..8)
                .flat_map(|i| if i % 2 == 0 { [0, 0, 0, 255] } else { [255; 4] })
                .collect(),
            color_space: space,
        };
        let chain = mip_chain(&stripes(ColorSpace::Srgb));
        assert_eq!(
            chain.iter().map(|(w, h, _)| (*w, *h)).collect::<Vec<_>>(),
            vec![(4, 2), (2, 1), (1, 1)]
        );
        let last = &chain[2].2;
        assert!((i32::from(last[0]) - 188).abs() <= 1, "{last:?}");
        assert_eq!(last[3], 255);
        // Data (a normal or roughness map) is averaged as it is.
        let data = mip_chain(&stripes(ColorSpace::Linear));
        assert!(
            (i32::from(data[2].2[0]) - 128).abs() <= 1,
            "{:?}",
            data[2].2
        );
    }
}
