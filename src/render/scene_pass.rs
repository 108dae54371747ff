//! Draws the scene's triangles for one wall and eye (shaders/scene.wgsl): pipelines, scene
//! buffers, materials and textures, all created once and reused every frame.

use super::error::RenderError;
use super::scene_chunks::ChunkPlan;
use super::scene_chunks::plan_chunks;
use super::scene_gpu::{GpuDraw, GpuVertex, SceneGpu, VERTEX_ATTRIBUTES, check_scene_limits};
use std::collections::HashMap;

use super::bindings::UNIFORM_STRIDE;
use super::formats::{COLOR_FORMAT, DEPTH_FORMAT, ENCODED_FORMAT};
use super::shaders;
use super::shadow_pass::ShadowPass;
use crate::scene::shadows::ShadowSettings;
use crate::scene::{Scene, TEXTURE_SLOTS};

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
        let uploaded = SceneGpu::upload_checked(&self.material_layout, device, queue, scene, plan);
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
}
