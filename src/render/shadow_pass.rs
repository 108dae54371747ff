//! Shadow maps (shaders/shadow.wgsl): which layers each shadow-casting light gets and where they
//! look from, the depth texture array they are drawn into, and drawing them again only when
//! a light, the scene or the shadowed region changes.

use bytemuck::{Pod, Zeroable};
use glam::camera::rh::{proj, view};
use glam::{Mat4, Vec3};

use super::scene_pass::{GpuVertex, SceneGpu};
use super::shaders;
use super::uniforms::UNIFORM_STRIDE;
use crate::scene::{Light, LightKind};

/// Shadow-map layers a frame holds at most (a directional or spot light takes one, a point
/// light six). Keep in sync with `MAX_SHADOW_LAYERS` in shaders/common.wgsl.
pub const MAX_SHADOW_LAYERS: usize = 8;

/// Depth format of the shadow maps.
const SHADOW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// How shadows are drawn (the config's `[shadows]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowSettings {
    pub enabled: bool,
    /// Side of each shadow map, texels.
    pub map_size: u32,
    /// Look-ups move this many texels along the surface normal (against shadow acne).
    pub normal_offset_texels: f32,
    /// 3×3 percentage-closer filtering (soft edges), else one comparison.
    pub pcf: bool,
    /// Directional lights shadow this far around the CAVE (metres, scene space).
    pub distance_m: f32,
}

impl Default for ShadowSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            map_size: 1024,
            normal_offset_texels: 1.5,
            pcf: true,
            distance_m: 25.0,
        }
    }
}

/// One light's shadow: its layers (consecutive) and how big a texel is.
#[derive(Debug, Clone, PartialEq)]
pub struct LightShadow {
    pub first_layer: usize,
    /// Per layer: scene space → the layer's clip space.
    pub shadow_from_world: Vec<Mat4>,
    /// Texel size at 1 m from a perspective light (spot, point); 0 for directional.
    pub texel_per_metre: f32,
    /// Texel size of an orthographic (directional) map; 0 for the others.
    pub texel: f32,
}

/// Where each light's shadow layers look from, in the light list's order, within
/// [`MAX_SHADOW_LAYERS`]: a light that does not fit casts no shadow. `bounds` are the scene's
/// (scene space); `centre` is the CAVE's centre in scene space, around which directional
/// shadows cover `settings.distance_m` (snapped to a quarter of it, so that moving a little
/// keeps the same maps).
pub fn plan_shadows(
    lights: &[Light],
    bounds: Option<(Vec3, Vec3)>,
    centre: Vec3,
    settings: &ShadowSettings,
) -> Vec<Option<LightShadow>> {
    let Some((lo, hi)) = bounds.filter(|_| settings.enabled) else {
        return vec![None; lights.len()];
    };
    let size = settings.map_size.max(1) as f32;
    let scene_centre = 0.5 * (lo + hi);
    let scene_radius = (0.5 * (hi - lo).length()).max(1e-3);
    // Farthest any part of the scene is from `p`: the far plane that holds every caster.
    let reach = |p: Vec3| (p - scene_centre).length() + scene_radius;
    let mut next = 0;
    lights
        .iter()
        .map(|light| {
            if !light.casts_shadows {
                return None;
            }
            let layers = match light.kind {
                LightKind::Point => 6,
                _ => 1,
            };
            if next + layers > MAX_SHADOW_LAYERS {
                return None;
            }
            let first_layer = next;
            next += layers;
            Some(match light.kind {
                LightKind::Directional => {
                    let (c, r) = if scene_radius <= settings.distance_m {
                        (scene_centre, scene_radius)
                    } else {
                        let step = settings.distance_m / 4.0;
                        ((centre / step).round() * step, settings.distance_m)
                    };
                    let dir = light.direction.normalize_or(Vec3::NEG_Y);
                    let back = reach(c);
                    let eye = c - dir * back;
                    let view = view::look_at_mat4(eye, c, any_perpendicular(dir));
                    let projection = proj::directx::orthographic(-r, r, -r, r, 0.0, back + r);
                    LightShadow {
                        first_layer,
                        shadow_from_world: vec![projection * view],
                        texel_per_metre: 0.0,
                        texel: 2.0 * r / size,
                    }
                }
                LightKind::Spot { outer_cone, .. } => {
                    let fov = (2.0 * outer_cone + 2f32.to_radians())
                        .clamp(2f32.to_radians(), 170f32.to_radians());
                    let far = light
                        .range
                        .unwrap_or_else(|| reach(light.position))
                        .max(0.2);
                    let dir = light.direction.normalize_or(Vec3::NEG_Y);
                    let view = view::look_at_mat4(
                        light.position,
                        light.position + dir,
                        any_perpendicular(dir),
                    );
                    LightShadow {
                        first_layer,
                        shadow_from_world: vec![
                            proj::directx::perspective(fov, 1.0, near(far), far) * view,
                        ],
                        texel_per_metre: 2.0 * (0.5 * fov).tan() / size,
                        texel: 0.0,
                    }
                }
                LightKind::Point => {
                    let far = light
                        .range
                        .unwrap_or_else(|| reach(light.position))
                        .max(0.2);
                    let projection = proj::directx::perspective(
                        // A hair over 90° so that neighbouring faces overlap at the edges.
                        91f32.to_radians(),
                        1.0,
                        near(far),
                        far,
                    );
                    let faces = [
                        (Vec3::X, Vec3::NEG_Y),
                        (Vec3::NEG_X, Vec3::NEG_Y),
                        (Vec3::Y, Vec3::Z),
                        (Vec3::NEG_Y, Vec3::NEG_Z),
                        (Vec3::Z, Vec3::NEG_Y),
                        (Vec3::NEG_Z, Vec3::NEG_Y),
                    ];
                    LightShadow {
                        first_layer,
                        shadow_from_world: faces
                            .iter()
                            .map(|&(d, up)| {
                                projection
                                    * view::look_at_mat4(light.position, light.position + d, up)
                            })
                            .collect(),
                        texel_per_metre: 2.0 * 45.5f32.to_radians().tan() / size,
                        texel: 0.0,
                    }
                }
            })
        })
        .collect()
}

/// A near plane for a perspective shadow map reaching `far` (depth precision).
fn near(far: f32) -> f32 {
    (far * 1e-4).clamp(0.01, 0.1)
}

/// A unit vector not parallel to `v` (an up vector for looking along it).
fn any_perpendicular(v: Vec3) -> Vec3 {
    if v.y.abs() > 0.9 { Vec3::Z } else { Vec3::Y }
}

/// One layer's matrix. Keep in sync with `ShadowLayerUniforms` in shaders/shadow.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ShadowLayerUniforms {
    pub shadow_from_world: [[f32; 4]; 4],
}

/// The shadow maps and the pass that draws them.
#[derive(Debug)]
pub struct ShadowPass {
    /// Group 3 of the scene pipelines: the maps and their comparison sampler.
    layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    sampler: wgpu::Sampler,
    texture: wgpu::Texture,
    layer_views: Vec<wgpu::TextureView>,
    map_size: u32,
    pipeline: wgpu::RenderPipeline,
    layer_buffer: wgpu::Buffer,
    layer_group: wgpu::BindGroup,
    /// The layers' matrices the maps hold (`None`: to be drawn).
    drawn: Option<Vec<Mat4>>,
    /// The layers to draw at the next [`ShadowPass::encode`].
    pending: Option<Vec<Mat4>>,
}

impl ShadowPass {
    pub fn new(device: &wgpu::Device, map_size: u32) -> Self {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("ShadowPass::layout"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison),
                    count: None,
                },
            ],
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("ShadowPass::sampler"),
            address_mode_u: wgpu::AddressMode::ClampToEdge,
            address_mode_v: wgpu::AddressMode::ClampToEdge,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::LessEqual),
            ..Default::default()
        });
        let layer_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("ShadowPass::layer_layout"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: true,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let layer_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ShadowPass::layer_buffer"),
            size: UNIFORM_STRIDE * MAX_SHADOW_LAYERS as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layer_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ShadowPass::layer_group"),
            layout: &layer_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &layer_buffer,
                    offset: 0,
                    size: wgpu::BufferSize::new(std::mem::size_of::<ShadowLayerUniforms>() as u64),
                }),
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("ShadowPass::pipeline_layout"),
            bind_group_layouts: &[Some(&layer_layout)],
            immediate_size: 0,
        });
        let module = shaders::module(device, "ShadowPass::shader", shaders::SHADOW);
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("ShadowPass::pipeline"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_shadow"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<GpuVertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x3],
                })],
            },
            // Both faces cast: single-sided walls and thin panels must not leak light.
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: SHADOW_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                // Slope-scaled bias against acne on surfaces at grazing angles to the light
                // (the look-up adds a normal offset for the rest).
                bias: wgpu::DepthBiasState {
                    constant: 2,
                    slope_scale: 2.0,
                    clamp: 0.0,
                },
            }),
            multisample: Default::default(),
            fragment: None,
            multiview_mask: None,
            cache: None,
        });
        let (texture, layer_views, bind_group) = Self::maps(device, &layout, &sampler, map_size);
        Self {
            layout,
            bind_group,
            sampler,
            texture,
            layer_views,
            map_size,
            pipeline,
            layer_buffer,
            layer_group,
            drawn: None,
            pending: None,
        }
    }

    fn maps(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        sampler: &wgpu::Sampler,
        map_size: u32,
    ) -> (wgpu::Texture, Vec<wgpu::TextureView>, wgpu::BindGroup) {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("ShadowPass::maps"),
            size: wgpu::Extent3d {
                width: map_size,
                height: map_size,
                depth_or_array_layers: MAX_SHADOW_LAYERS as u32,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: SHADOW_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let layer_views = (0..MAX_SHADOW_LAYERS as u32)
            .map(|layer| {
                texture.create_view(&wgpu::TextureViewDescriptor {
                    label: Some("ShadowPass::layer"),
                    dimension: Some(wgpu::TextureViewDimension::D2),
                    base_array_layer: layer,
                    array_layer_count: Some(1),
                    ..Default::default()
                })
            })
            .collect();
        let array_view = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("ShadowPass::array"),
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ShadowPass::bind_group"),
            layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&array_view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(sampler),
                },
            ],
        });
        (texture, layer_views, bind_group)
    }

    /// The layout of group 3 of the scene pipelines.
    pub fn layout(&self) -> &wgpu::BindGroupLayout {
        &self.layout
    }

    /// The maps and their sampler, bound as group 3.
    pub fn bind_group(&self) -> &wgpu::BindGroup {
        &self.bind_group
    }

    /// Side of each map, texels.
    pub fn map_size(&self) -> u32 {
        self.map_size
    }

    /// The maps must be drawn again (a new scene).
    pub fn invalidate(&mut self) {
        self.drawn = None;
    }

    /// Asks for the layers of `plan` (a frame's shadows): drawn at the next
    /// [`ShadowPass::encode`] unless the maps already hold them. A new map size recreates the
    /// maps (a settings change, never per frame).
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        plan: &[Option<LightShadow>],
        map_size: u32,
    ) {
        if map_size != self.map_size {
            let (texture, views, group) = Self::maps(device, &self.layout, &self.sampler, map_size);
            self.texture = texture;
            self.layer_views = views;
            self.bind_group = group;
            self.map_size = map_size;
            self.drawn = None;
        }
        let layers: Vec<Mat4> = plan
            .iter()
            .flatten()
            .flat_map(|s| s.shadow_from_world.iter().copied())
            .collect();
        if self.drawn.as_ref() == Some(&layers) || layers.is_empty() {
            self.pending = None;
            return;
        }
        let mut bytes = vec![0u8; UNIFORM_STRIDE as usize * MAX_SHADOW_LAYERS];
        for (i, m) in layers.iter().enumerate().take(MAX_SHADOW_LAYERS) {
            let u = ShadowLayerUniforms {
                shadow_from_world: m.to_cols_array_2d(),
            };
            let at = i * UNIFORM_STRIDE as usize;
            bytes[at..at + std::mem::size_of::<ShadowLayerUniforms>()]
                .copy_from_slice(bytemuck::bytes_of(&u));
        }
        queue.write_buffer(&self.layer_buffer, 0, &bytes);
        self.pending = Some(layers);
    }

    /// Draws the pending layers: the scene's opaque and masked triangles (blended ones cast
    /// no shadow), depth only.
    pub fn encode(&mut self, encoder: &mut wgpu::CommandEncoder, scene: &SceneGpu) {
        let Some(layers) = self.pending.take() else {
            return;
        };
        for (i, view) in self.layer_views.iter().enumerate().take(layers.len()) {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("ShadowPass::layer pass"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.layer_group, &[(i as u64 * UNIFORM_STRIDE) as u32]);
            scene.draw_casters(&mut pass);
        }
        self.drawn = Some(layers);
    }
}
