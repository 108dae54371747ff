//! Shadow maps (shaders/shadow.wgsl): which layers each shadow-casting light gets and where they
//! look from, the depth texture array they are drawn into with each tile's depth range, and
//! drawing them again only when a light, the scene or the shadowed region changes.

use bytemuck::{Pod, Zeroable};
use glam::Mat4;

use super::bindings::{UNIFORM_STRIDE, storage_entry};
use super::error::RenderError;
use super::scene_gpu::{GpuVertex, SceneGpu};
use super::shaders;
use crate::scene::shadows::{LightShadow, MAX_SHADOW_LAYERS, SHADOW_TILE, range_tiles};

/// Depth format of the shadow maps.
const SHADOW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// A layout entry for the maps as a depth texture array.
fn maps_entry(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Depth,
            view_dimension: wgpu::TextureViewDimension::D2Array,
            multisampled: false,
        },
        count: None,
    }
}

/// The tiles' depth ranges for every layer: `range_tiles² × MAX_SHADOW_LAYERS` pairs of f32.
fn ranges_size(map_size: u32) -> u64 {
    u64::from(range_tiles(map_size)).pow(2) * MAX_SHADOW_LAYERS as u64 * 8
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
    /// Each tile's depth range per layer, written by `ranges_pipeline` after the maps are drawn.
    ranges: wgpu::Buffer,
    ranges_layout: wgpu::BindGroupLayout,
    ranges_group: wgpu::BindGroup,
    ranges_pipeline: wgpu::ComputePipeline,
    /// The layers' matrices the maps hold (`None`: to be drawn).
    drawn: Option<Vec<Mat4>>,
    /// The layers to draw at the next [`ShadowPass::encode`].
    pending: Option<Vec<Mat4>>,
    /// `ranges` holds the drawn maps' tiles.
    ranges_valid: bool,
    /// The next [`ShadowPass::encode`] computes the tiles (the filter's range test is on).
    ranges_pending: bool,
}

impl ShadowPass {
    pub fn new(device: &wgpu::Device, map_size: u32) -> Self {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("ShadowPass::layout"),
            entries: &[
                maps_entry(0, wgpu::ShaderStages::FRAGMENT),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison),
                    count: None,
                },
                storage_entry(2, true, wgpu::ShaderStages::FRAGMENT),
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
        let (layer_layout, layer_buffer, layer_group) = layer_uniforms(device);
        let module = shaders::module(device, "ShadowPass::shader", shaders::SHADOW);
        let pipeline = depth_pipeline(device, &module, &layer_layout);
        let (ranges_layout, ranges_pipeline) = ranges_pipeline(device, &module);
        let maps = Self::maps(device, &layout, &ranges_layout, &sampler, map_size);
        Self {
            layout,
            bind_group: maps.bind_group,
            sampler,
            texture: maps.texture,
            layer_views: maps.layer_views,
            map_size,
            pipeline,
            layer_buffer,
            layer_group,
            ranges: maps.ranges,
            ranges_layout,
            ranges_group: maps.ranges_group,
            ranges_pipeline,
            drawn: None,
            pending: None,
            ranges_valid: false,
            ranges_pending: false,
        }
    }

    /// The maps of `map_size` texels a side, their range tiles and the bind groups of both.
    fn maps(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        ranges_layout: &wgpu::BindGroupLayout,
        sampler: &wgpu::Sampler,
        map_size: u32,
    ) -> Maps {
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
            // COPY_SRC: the tests read the maps back.
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
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
        let ranges = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ShadowPass::ranges"),
            size: ranges_size(map_size),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
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
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: ranges.as_entire_binding(),
                },
            ],
        });
        let ranges_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ShadowPass::ranges_group"),
            layout: ranges_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&array_view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: ranges.as_entire_binding(),
                },
            ],
        });
        Maps {
            texture,
            layer_views,
            bind_group,
            ranges,
            ranges_group,
        }
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
        self.ranges_valid = false;
    }

    /// Asks for the layers of `plan` (a frame's shadows): drawn at the next
    /// [`ShadowPass::encode`] unless the maps already hold them, and their range tiles when
    /// `ranges` (the filter's range test is on) unless they hold those too. A new map size
    /// recreates the maps (a settings change, never per frame).
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        plan: &[Option<LightShadow>],
        map_size: u32,
        ranges: bool,
    ) {
        if map_size != self.map_size {
            let maps = Self::maps(
                device,
                &self.layout,
                &self.ranges_layout,
                &self.sampler,
                map_size,
            );
            self.texture = maps.texture;
            self.layer_views = maps.layer_views;
            self.bind_group = maps.bind_group;
            self.ranges = maps.ranges;
            self.ranges_group = maps.ranges_group;
            self.map_size = map_size;
            self.drawn = None;
            self.ranges_valid = false;
        }
        let layers: Vec<Mat4> = plan
            .iter()
            .flatten()
            .flat_map(|s| s.shadow_from_world.iter().copied())
            .collect();
        if self.drawn.as_ref() == Some(&layers) || layers.is_empty() {
            self.pending = None;
            self.ranges_pending = ranges && !self.ranges_valid && !layers.is_empty();
            return;
        }
        self.ranges_valid = false;
        self.ranges_pending = ranges;
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
        if let Some(layers) = self.pending.take() {
            self.draw_layers(encoder, scene, &layers);
            self.drawn = Some(layers);
        }
        if std::mem::take(&mut self.ranges_pending) {
            self.encode_ranges(encoder);
        }
    }

    /// The maps of `layers`, depth only.
    fn draw_layers(&self, encoder: &mut wgpu::CommandEncoder, scene: &SceneGpu, layers: &[Mat4]) {
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
    }

    /// The drawn layers' range tiles, for the filter's shortcut.
    fn encode_ranges(&mut self, encoder: &mut wgpu::CommandEncoder) {
        let layers = self
            .drawn
            .as_ref()
            .map_or(0, Vec::len)
            .min(MAX_SHADOW_LAYERS) as u32;
        if layers == 0 {
            return;
        }
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("ShadowPass::ranges pass"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.ranges_pipeline);
        pass.set_bind_group(0, &self.ranges_group, &[]);
        let groups = range_tiles(self.map_size).div_ceil(8);
        pass.dispatch_workgroups(groups, groups, layers);
        drop(pass);
        self.ranges_valid = true;
    }

    /// The first `layers` layers of the maps (row by row; at least one) and their range tiles,
    /// as the GPU holds them (blocking; for tests, never in the render path).
    pub fn read_maps(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        layers: usize,
    ) -> Result<ShadowMapsRead, RenderError> {
        let layers = layers.clamp(1, MAX_SHADOW_LAYERS);
        let size = self.map_size;
        let padded = (size * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ShadowPass::read_maps"),
            size: u64::from(padded) * u64::from(size) * layers as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("ShadowPass::read_maps"),
        });
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::DepthOnly,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(size),
                },
            },
            wgpu::Extent3d {
                width: size,
                height: size,
                depth_or_array_layers: layers as u32,
            },
        );
        queue.submit([encoder.finish()]);
        let data = super::targets::read_staging(device, &staging)?;
        let depths = (0..layers)
            .map(|layer| {
                let image = layer * padded as usize * size as usize;
                (0..size as usize)
                    .flat_map(|row| {
                        let at = image + row * padded as usize;
                        data[at..at + size as usize * 4]
                            .chunks_exact(4)
                            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    })
                    .collect()
            })
            .collect();
        let tiles = range_tiles(size) as usize;
        let bytes = super::targets::read_buffer(
            device,
            queue,
            &self.ranges,
            (tiles * tiles * layers * 8) as u64,
            "ShadowPass::read_ranges",
        )?;
        let ranges = bytes
            .chunks_exact(8)
            .take(tiles * tiles * layers)
            .map(|b| {
                [
                    f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                    f32::from_le_bytes([b[4], b[5], b[6], b[7]]),
                ]
            })
            .collect::<Vec<_>>()
            .chunks(tiles * tiles)
            .map(<[[f32; 2]]>::to_vec)
            .collect();
        Ok(ShadowMapsRead {
            map_size: size,
            depths,
            ranges,
        })
    }
}

/// Shadow maps read back: per layer, the depths (row by row) and the range tiles.
#[derive(Debug, Clone)]
pub struct ShadowMapsRead {
    pub map_size: u32,
    pub depths: Vec<Vec<f32>>,
    pub ranges: Vec<Vec<[f32; 2]>>,
}

/// CPU twin of `cs_ranges` (shaders/shadow.wgsl): one layer's range tiles from its depths
/// (`map_size²`, row by row). Each tile holds the least and greatest depth of its texels and
/// one more row and column before them and two after, clamped to the map: all a 3×3 filter
/// gathers from a corner in the tile.
pub fn tile_ranges(depths: &[f32], map_size: u32) -> Vec<[f32; 2]> {
    let tiles = range_tiles(map_size);
    let last = map_size.saturating_sub(1) as i64;
    let mut out = Vec::with_capacity((tiles * tiles) as usize);
    for ty in 0..tiles {
        for tx in 0..tiles {
            let first = [i64::from(tx * SHADOW_TILE), i64::from(ty * SHADOW_TILE)];
            let mut range = [f32::MAX, f32::MIN];
            for y in (first[1] - 1).max(0)..=(first[1] + i64::from(SHADOW_TILE) + 1).min(last) {
                for x in (first[0] - 1).max(0)..=(first[0] + i64::from(SHADOW_TILE) + 1).min(last) {
                    let d = depths
                        .get((y * (last + 1) + x) as usize)
                        .copied()
                        .unwrap_or(1.0);
                    range = [range[0].min(d), range[1].max(d)];
                }
            }
            out.push(range);
        }
    }
    out
}

/// What [`ShadowPass::maps`] creates for one map size.
struct Maps {
    texture: wgpu::Texture,
    layer_views: Vec<wgpu::TextureView>,
    bind_group: wgpu::BindGroup,
    ranges: wgpu::Buffer,
    ranges_group: wgpu::BindGroup,
}

/// The layers' matrices: their layout, their buffer (one uniform slot a layer) and its bind
/// group, bound at each layer's offset.
fn layer_uniforms(device: &wgpu::Device) -> (wgpu::BindGroupLayout, wgpu::Buffer, wgpu::BindGroup) {
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
    (layer_layout, layer_buffer, layer_group)
}

/// The depth-only pipeline that draws the casters into one layer.
fn depth_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layer_layout: &wgpu::BindGroupLayout,
) -> wgpu::RenderPipeline {
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("ShadowPass::pipeline_layout"),
        bind_group_layouts: &[Some(layer_layout)],
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("ShadowPass::pipeline"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module,
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
    })
}

/// The compute pipeline that writes each tile's depth range after the maps are drawn, with
/// its layout.
fn ranges_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
) -> (wgpu::BindGroupLayout, wgpu::ComputePipeline) {
    let ranges_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("ShadowPass::ranges_layout"),
        entries: &[
            maps_entry(1, wgpu::ShaderStages::COMPUTE),
            storage_entry(2, false, wgpu::ShaderStages::COMPUTE),
        ],
    });
    let ranges_pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("ShadowPass::ranges_pipeline"),
        layout: Some(
            &device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("ShadowPass::ranges_pipeline_layout"),
                bind_group_layouts: &[Some(&ranges_layout)],
                immediate_size: 0,
            }),
        ),
        module,
        entry_point: Some("cs_ranges"),
        compilation_options: Default::default(),
        cache: None,
    });
    (ranges_layout, ranges_pipeline)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::shadows::{ShadowSettings, plan_shadows};
    use crate::scene::{Light, LightKind};
    use glam::Vec3;

    /// `light_visibility` (shaders/scene.wgsl) picks a point light's face from three clip
    /// w's: it takes the faces as +X, -X, +Y, -Y, +Z, -Z, each negative face's w as its
    /// positive one's negated, and the face with the largest w as one whose map holds the
    /// point. Checked on the planned matrices, turned and moved as `shadow_from_cave` is.
    #[test]
    fn a_point_lights_largest_w_names_the_face_that_holds_the_point() {
        let light = Light {
            name: "lamp".into(),
            kind: LightKind::Point,
            position: Vec3::new(0.3, 2.1, -0.8),
            direction: Vec3::NEG_Y,
            color: Vec3::ONE,
            range: Some(9.0),
            casts_shadows: true,
        };
        let plan = plan_shadows(
            std::slice::from_ref(&light),
            Some((Vec3::splat(-5.0), Vec3::splat(5.0))),
            Vec3::ZERO,
            &ShadowSettings::default(),
        );
        let faces = &plan[0]
            .as_ref()
            .expect("a point light's shadow")
            .shadow_from_world;
        assert_eq!(faces.len(), 6);
        let world_from_cave = Mat4::from_scale_rotation_translation(
            Vec3::splat(1.3),
            glam::Quat::from_rotation_y(0.52),
            Vec3::new(0.4, 0.0, -0.7),
        );
        let from_cave: Vec<Mat4> = faces.iter().map(|m| *m * world_from_cave).collect();
        let w = |face: usize, p: Vec3| from_cave[face].row(3).dot(p.extend(1.0));
        let cave_light = world_from_cave.inverse().transform_point3(light.position);
        let mut seed = 0x2545_f491_u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32 * 2.0 - 1.0
        };
        for i in 0..2000 {
            let p = cave_light + Vec3::new(next(), next(), next()) * 4.0;
            let ws = [w(0, p), w(2, p), w(4, p)];
            for axis in 0..3 {
                let (pos, neg) = (w(2 * axis, p), w(2 * axis + 1, p));
                assert!(
                    (pos + neg).abs() <= 1e-4 * pos.abs().max(1.0),
                    "{i}: {pos} {neg}"
                );
            }
            // The shader's choice, ties as it breaks them.
            let a = ws.map(f32::abs);
            let face = if a[1] > a[0] && a[1] >= a[2] {
                2 + usize::from(ws[1] < 0.0)
            } else if a[2] > a[0] && a[2] > a[1] {
                4 + usize::from(ws[2] < 0.0)
            } else {
                usize::from(ws[0] < 0.0)
            };
            let clip = from_cave[face] * p.extend(1.0);
            let ndc = clip.truncate() / clip.w;
            assert!(
                clip.w > 0.0 && ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0,
                "{i}: {p} in face {face} at {ndc}"
            );
            // And along the scene's axis that face looks down.
            let d = world_from_cave.transform_point3(p) - light.position;
            let sign = if face % 2 == 0 { 1.0 } else { -1.0 };
            assert!(
                sign * d[face / 2] >= d.abs().max_element() * 0.999,
                "{i}: {d} face {face}"
            );
        }
    }

    /// `pcf_3x3` (shaders/scene.wgsl) takes the tile of its corner, clamped to the map; every
    /// texel its four gathers read (corner − 1 ..= corner + 2 on each axis, clamped as the
    /// sampler clamps) must lie in that tile's window as `cs_ranges` and [`tile_ranges`] take it.
    #[test]
    fn every_texel_the_filter_gathers_lies_in_its_tiles_window() {
        for size in [64u32, 100, 203, 1024] {
            let last = i64::from(size) - 1;
            // Every corner the filter can have: uv in [0, 1] gives st in [-0.5, size - 0.5].
            for corner in -1..=last {
                let tile = corner.clamp(0, last) / i64::from(SHADOW_TILE);
                let first = tile * i64::from(SHADOW_TILE);
                let window = (
                    (first - 1).max(0),
                    (first + i64::from(SHADOW_TILE) + 1).min(last),
                );
                for texel in corner - 1..=corner + 2 {
                    let read = texel.clamp(0, last);
                    assert!(
                        (window.0..=window.1).contains(&read),
                        "size {size}, corner {corner}: texel {read} outside {window:?}"
                    );
                }
                assert!(tile < i64::from(range_tiles(size)));
            }
        }
    }

    #[test]
    fn tile_ranges_take_the_least_and_greatest_depth_of_the_window() {
        // An 8×8 map, depth = x + 10 y (distinct everywhere): tile (1, 0) covers x 3..=7,
        // y 0..=5 (one before, two after, clamped at 7).
        let depths: Vec<f32> = (0..64).map(|i| (i % 8 + 10 * (i / 8)) as f32).collect();
        let ranges = tile_ranges(&depths, 8);
        assert_eq!(ranges.len(), 4);
        assert_eq!(ranges[1], [3.0, 57.0]);
        assert_eq!(ranges[0], [0.0, 55.0]);
        assert_eq!(ranges[3], [33.0, 77.0]);
    }
}
