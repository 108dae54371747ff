//! The skybox pass (shaders/sky.wgsl): a cube map drawn behind the scene in every wall and
//! eye view, as an off-axis lookup, the thesis's omnistereo mesh, or exactly per pixel.

use bytemuck::{Pod, Zeroable};
use glam::{Mat3, Mat4, Vec3};

use super::bindings::UNIFORM_STRIDE;
use super::formats::{COLOR_FORMAT, DEPTH_FORMAT, ENCODED_FORMAT};
use super::shaders;
use crate::cave::omni::PoleMerge;
use crate::cave::{Cave, ViewSetup};
use crate::sky::cubemap::Texels;
use crate::sky::lookup::quad_slices;
use crate::sky::{CubeMap, SkyMode, SkySettings};

/// One wall from one eye. Keep in sync with `SkyUniforms` in shaders/sky.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct SkyUniforms {
    pub cube_from_cave: [[f32; 4]; 4],
    pub wall_origin: [f32; 4],
    pub wall_right: [f32; 4],
    pub wall_up: [f32; 4],
    pub eye: [f32; 4],
    pub head: [f32; 4],
    pub pole: [f32; 4],
    pub params: [f32; 4],
}

/// What the sky uniforms of a frame are made from, besides the view.
#[derive(Debug, Clone, Copy)]
pub struct SkyFrame {
    pub world_from_cave: Mat4,
    pub head: Vec3,
    pub eye_separation: f32,
    /// The eyes the `offaxis` sky looks from (the fixed-direction eyes in omnistereo modes,
    /// whose own views are centred elsewhere), left then right.
    pub offaxis_eyes: [Vec3; 2],
    pub pole_merge: Option<PoleMerge>,
    pub exposure: f32,
}

/// The hardware cube-map direction of a CAVE-space direction: directions only, the rotation
/// (and uniform scale, which a lookup ignores) of the placement, then the cube-map
/// convention's z flip (src/sky/cubemap.rs).
pub fn cube_from_cave(world_from_cave: Mat4) -> Mat4 {
    let flip = Mat3::from_diagonal(Vec3::new(1.0, 1.0, -1.0));
    Mat4::from_mat3(flip * Mat3::from_mat4(world_from_cave))
}

impl SkyUniforms {
    pub fn new(view: &ViewSetup, cave: &Cave, frame: &SkyFrame) -> Self {
        let wall = &cave.walls[view.wall];
        let cube_from_cave = cube_from_cave(frame.world_from_cave);
        let (eye, half) = match view.eye {
            Some(e) => (
                frame.offaxis_eyes[e as usize],
                e.sign() * 0.5 * frame.eye_separation,
            ),
            None => (view.eye_position, 0.0),
        };
        let pole = match frame.pole_merge {
            Some(p) => [
                0.0,
                p.start_degrees.to_radians(),
                p.end_degrees.to_radians(),
                1.0,
            ],
            None => [0.0; 4],
        };
        Self {
            cube_from_cave: cube_from_cave.to_cols_array_2d(),
            wall_origin: wall.lower_left.extend(1.0).to_array(),
            wall_right: (wall.lower_right - wall.lower_left).extend(0.0).to_array(),
            wall_up: (wall.upper_left - wall.lower_left).extend(0.0).to_array(),
            eye: eye.extend(1.0).to_array(),
            head: frame.head.extend(half).to_array(),
            pole,
            params: [frame.exposure, 0.0, 0.0, 0.0],
        }
    }
}

/// The omni-quad mesh of one wall, in wall coordinates (so it only depends on the slices).
#[derive(Debug)]
struct QuadMesh {
    slices: (u32, u32),
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
}

/// An uploaded cube map.
#[derive(Debug)]
struct CubeGpu {
    _texture: wgpu::Texture,
    bind_group: wgpu::BindGroup,
}

/// Which fragment path a pipeline runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Variant {
    Offaxis = 0,
    Exact = 1,
    Quad = 2,
}

/// Pipelines per colour encoding.
const VARIANTS: usize = 3;

/// Pipelines, uniforms, per-wall meshes and the cube texture of the sky.
#[derive(Debug)]
pub struct SkyPass {
    uniform_layout: wgpu::BindGroupLayout,
    cube_layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    shader: wgpu::ShaderModule,
    /// Indexed by `Variant`.
    pipelines: Vec<wgpu::RenderPipeline>,
    /// Pipelines built so far (switching settings must not build any).
    pub(crate) pipelines_built: u64,
    sampler: wgpu::Sampler,
    uniform_buffer: wgpu::Buffer,
    uniform_bind_group: wgpu::BindGroup,
    capacity: usize,
    staging: Vec<u8>,
    meshes: Vec<Option<QuadMesh>>,
    cube: Option<CubeGpu>,
    /// The mode resolved for the frame being drawn (`None`: no sky this frame).
    active: Option<SkyMode>,
}

impl SkyPass {
    pub fn new(device: &wgpu::Device, msaa: u32, view_capacity: usize) -> Self {
        let uniform_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("SkyPass::uniform_layout"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: true,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let cube_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("SkyPass::cube_layout"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::Cube,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("SkyPass::pipeline_layout"),
            bind_group_layouts: &[Some(&uniform_layout), Some(&cube_layout)],
            immediate_size: 0,
        });
        let shader = shaders::module(device, "SkyPass::shader", shaders::SKY);
        // Vulkan, Metal and D3D12 filter cube maps seamlessly across faces by definition.
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("SkyPass::sampler"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            // No anisotropic filtering: lavapipe's anisotropic cube-map sampling draws a
            // one-pixel seam along face edges (caught by tests/sky.rs).
            ..Default::default()
        });
        let (uniform_buffer, uniform_bind_group) =
            Self::uniform_resources(device, &uniform_layout, view_capacity);
        let mut pass = Self {
            uniform_layout,
            cube_layout,
            pipeline_layout,
            shader,
            pipelines: Vec::new(),
            pipelines_built: 0,
            sampler,
            uniform_buffer,
            uniform_bind_group,
            capacity: view_capacity.max(1),
            staging: Vec::with_capacity(view_capacity * UNIFORM_STRIDE as usize),
            meshes: Vec::new(),
            cube: None,
            active: None,
        };
        pass.build_pipelines(device, msaa);
        pass
    }

    fn uniform_resources(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        capacity: usize,
    ) -> (wgpu::Buffer, wgpu::BindGroup) {
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("SkyPass::uniform_buffer"),
            size: UNIFORM_STRIDE * capacity.max(1) as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("SkyPass::uniform_bind_group"),
            layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &buffer,
                    offset: 0,
                    size: wgpu::BufferSize::new(std::mem::size_of::<SkyUniforms>() as u64),
                }),
            }],
        });
        (buffer, bind_group)
    }

    /// Builds the three pipelines for a sample count (at start-up and when MSAA changes), and
    /// with MSAA their variants for shader-encoded samples (`render::resolve`).
    pub fn build_pipelines(&mut self, device: &wgpu::Device, msaa: u32) {
        let mesh_layout = [Some(wgpu::VertexBufferLayout {
            array_stride: 8,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x2],
        })];
        let build = |label: &str, vs: &str, fs: &str, mesh: bool, encoded: bool| {
            let constants = [("ENCODE_SRGB_OUTPUT", if encoded { 1.0 } else { 0.0 })];
            let label = format!("{label}{}", if encoded { " encoded" } else { "" });
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(&label),
                layout: Some(&self.pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &self.shader,
                    entry_point: Some(vs),
                    compilation_options: Default::default(),
                    buffers: if mesh { &mesh_layout } else { &[] },
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    cull_mode: None,
                    ..Default::default()
                },
                // Behind everything: only pixels the scene left at the cleared depth.
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(false),
                    depth_compare: Some(wgpu::CompareFunction::LessEqual),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: wgpu::MultisampleState {
                    count: msaa,
                    ..Default::default()
                },
                fragment: Some(wgpu::FragmentState {
                    module: &self.shader,
                    entry_point: Some(fs),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &constants,
                        ..Default::default()
                    },
                    targets: &[Some(wgpu::ColorTargetState {
                        format: if encoded {
                            ENCODED_FORMAT
                        } else {
                            COLOR_FORMAT
                        },
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let encodings: &[bool] = if msaa > 1 { &[false, true] } else { &[false] };
        self.pipelines = encodings
            .iter()
            .flat_map(|&encoded| {
                [
                    (
                        "SkyPass::offaxis_pipeline",
                        "vs_fullscreen",
                        "fs_offaxis",
                        false,
                    ),
                    (
                        "SkyPass::exact_pipeline",
                        "vs_fullscreen",
                        "fs_exact",
                        false,
                    ),
                    ("SkyPass::quad_pipeline", "vs_quad", "fs_quad", true),
                ]
                .map(|(label, vs, fs, mesh)| build(label, vs, fs, mesh, encoded))
            })
            .collect();
        self.pipelines_built += self.pipelines.len() as u64;
    }

    /// Uploads a cube map (all mip levels), replacing any previous one; `None` removes the sky.
    pub fn set_cube(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, cube: Option<&CubeMap>) {
        self.cube = cube.map(|cube| self.upload(device, queue, cube));
    }

    pub fn has_cube(&self) -> bool {
        self.cube.is_some()
    }

    /// Layout of the sky's cube map and sampler (group 1 of shaders/sky.wgsl; the panorama
    /// binds the same group).
    pub fn cube_layout(&self) -> &wgpu::BindGroupLayout {
        &self.cube_layout
    }

    /// The sky's cube map and sampler, if a sky is set.
    pub fn cube_bind_group(&self) -> Option<&wgpu::BindGroup> {
        self.cube.as_ref().map(|c| &c.bind_group)
    }

    fn upload(&self, device: &wgpu::Device, queue: &wgpu::Queue, cube: &CubeMap) -> CubeGpu {
        let (format, texel_bytes) = if cube.is_hdr() {
            (wgpu::TextureFormat::Rgba16Float, 8)
        } else {
            (wgpu::TextureFormat::Rgba8UnormSrgb, 4)
        };
        let size = cube.size().max(1);
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some(&format!("SkyPass::cube {}", cube.source.display())),
            size: wgpu::Extent3d {
                width: size,
                height: size,
                depth_or_array_layers: 6,
            },
            mip_level_count: cube.levels.len().max(1) as u32,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        for (mip, level) in cube.levels.iter().enumerate() {
            let bytes: &[u8] = match &level.texels {
                Texels::Srgb8(b) => b,
                Texels::LinearF16(h) => bytemuck::cast_slice(h),
            };
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
                    bytes_per_row: Some(level.size * texel_bytes),
                    rows_per_image: Some(level.size),
                },
                wgpu::Extent3d {
                    width: level.size,
                    height: level.size,
                    depth_or_array_layers: 6,
                },
            );
        }
        let view = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("SkyPass::cube_view"),
            dimension: Some(wgpu::TextureViewDimension::Cube),
            ..Default::default()
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("SkyPass::cube_bind_group"),
            layout: &self.cube_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&self.sampler),
                },
            ],
        });
        CubeGpu {
            _texture: texture,
            bind_group,
        }
    }

    /// Prepares a frame: resolves the mode, writes every view's uniforms (one buffer write),
    /// and (re)builds a wall's omni-quad mesh only when its slice count changed.
    #[allow(clippy::too_many_arguments)]
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        cave: &Cave,
        views: &[ViewSetup],
        settings: &SkySettings,
        mode: SkyMode,
        frame: &SkyFrame,
    ) {
        self.active = None;
        if self.cube.is_none() || mode == SkyMode::Off {
            return;
        }
        if views.len() > self.capacity {
            let (buffer, bind_group) =
                Self::uniform_resources(device, &self.uniform_layout, views.len());
            self.uniform_buffer = buffer;
            self.uniform_bind_group = bind_group;
            self.capacity = views.len();
        }
        self.staging.clear();
        for view in views {
            self.staging
                .extend_from_slice(bytemuck::bytes_of(&SkyUniforms::new(view, cave, frame)));
            self.staging.resize(
                self.staging.len().next_multiple_of(UNIFORM_STRIDE as usize),
                0,
            );
        }
        if !self.staging.is_empty() {
            queue.write_buffer(&self.uniform_buffer, 0, &self.staging);
        }
        if mode == SkyMode::OmniQuad {
            self.meshes.resize_with(cave.walls.len(), || None);
            for (wall, slot) in cave.walls.iter().zip(&mut self.meshes) {
                let slices =
                    quad_slices(wall, settings.pixels_per_slice, frame.pole_merge.is_some());
                if slot.as_ref().is_none_or(|m| m.slices != slices) {
                    *slot = Some(build_mesh(device, slices));
                }
            }
        }
        self.active = Some(mode);
    }

    /// Draws the sky of view `index` (a view of wall `wall`) into the open scene pass
    /// (`encoded`: whose colour attachment takes shader-encoded bytes).
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>, index: usize, wall: usize, encoded: bool) {
        let (Some(mode), Some(cube)) = (self.active, &self.cube) else {
            return;
        };
        let variant = match mode {
            SkyMode::OmniQuad => Variant::Quad,
            SkyMode::OmniExact => Variant::Exact,
            SkyMode::Offaxis | SkyMode::Auto | SkyMode::Off => Variant::Offaxis,
        };
        let Some(pipeline) = self
            .pipelines
            .get(variant as usize + if encoded { VARIANTS } else { 0 })
        else {
            return;
        };
        pass.set_pipeline(pipeline);
        pass.set_bind_group(
            0,
            &self.uniform_bind_group,
            &[(index as u64 * UNIFORM_STRIDE) as u32],
        );
        pass.set_bind_group(1, &cube.bind_group, &[]);
        if variant == Variant::Quad {
            let Some(Some(mesh)) = self.meshes.get(wall) else {
                return;
            };
            pass.set_vertex_buffer(0, mesh.vertices.slice(..));
            pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..mesh.index_count, 0, 0..1);
        } else {
            pass.draw(0..3, 0..1);
        }
    }
}

/// The pre-tessellated full-screen mesh: (cols + 1) × (rows + 1) vertices at wall coordinates,
/// each cell split along its (u0, v0)–(u1, v1) diagonal (as `sky::lookup::quad_lookup`).
fn build_mesh(device: &wgpu::Device, (cols, rows): (u32, u32)) -> QuadMesh {
    use wgpu::util::DeviceExt;
    let mut vertices = Vec::with_capacity(((cols + 1) * (rows + 1)) as usize);
    for j in 0..=rows {
        for i in 0..=cols {
            vertices.push([i as f32 / cols as f32, j as f32 / rows as f32]);
        }
    }
    let at = |i: u32, j: u32| j * (cols + 1) + i;
    let mut indices = Vec::with_capacity((cols * rows * 6) as usize);
    for j in 0..rows {
        for i in 0..cols {
            indices.extend_from_slice(&[
                at(i, j),
                at(i + 1, j),
                at(i + 1, j + 1),
                at(i, j),
                at(i + 1, j + 1),
                at(i, j + 1),
            ]);
        }
    }
    QuadMesh {
        slices: (cols, rows),
        vertices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("SkyPass::quad_vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX,
        }),
        indices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("SkyPass::quad_indices"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        }),
        index_count: indices.len() as u32,
    }
}
