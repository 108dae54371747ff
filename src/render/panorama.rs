//! The panorama view's GPU side: its eye targets, the image route (scene into six cube faces,
//! then shaders/panorama.wgsl looks every pixel up through the inverse map) and the uniforms
//! of the geometric route (drawn by the scene pass's `vs_pano`/`fs_pano`).

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};

use super::formats::{COLOR_FORMAT, DEPTH_FORMAT};
use super::shaders;
use super::targets::{WallTargets, begin_scene_pass};
use super::uniforms::ViewUniforms;
use crate::cave::Eye;
use crate::pano::{PanoSettings, PanoStereo};

/// Cube face order and axes: (forward, up); the face's right is forward × up. Keep in step
/// with `FACE_FORWARD`/`FACE_UP` in shaders/panorama.wgsl.
pub const CUBE_FACES: [(Vec3, Vec3); 6] = [
    (Vec3::X, Vec3::Y),
    (Vec3::NEG_X, Vec3::Y),
    (Vec3::Y, Vec3::Z),
    (Vec3::NEG_Y, Vec3::NEG_Z),
    (Vec3::Z, Vec3::Y),
    (Vec3::NEG_Z, Vec3::Y),
];

/// Texels of guard band around each cube face: faces are rendered a little wider than 90° so
/// that filtering next to a face edge reads rendered texels, not clamped ones.
const FACE_GUARD_TEXELS: f32 = 2.0;

/// Tangent of half a face's field of view for faces of `size` texels.
pub fn face_half_extent(size: u32) -> f32 {
    let size = size.max(4) as f32;
    size / (size - 2.0 * FACE_GUARD_TEXELS)
}

/// Clip space from CAVE space of cube face `face` seen from `head`.
pub fn face_clip_from_cave(face: usize, head: Vec3, size: u32, near: f32, far: f32) -> Mat4 {
    let (forward, up) = CUBE_FACES[face % 6];
    let right = forward.cross(up);
    let e = face_half_extent(size) * near;
    let projection = glam::camera::rh::proj::directx::frustum(-e, e, -e, e, near, far);
    // Rows: the face's right, up and backward axes (the camera looks along −z).
    let rotation = Mat4::from_cols(
        glam::Vec4::new(right.x, up.x, -forward.x, 0.0),
        glam::Vec4::new(right.y, up.y, -forward.y, 0.0),
        glam::Vec4::new(right.z, up.z, -forward.z, 0.0),
        glam::Vec4::W,
    );
    projection * rotation * Mat4::from_translation(-head)
}

/// Uniforms of the image route's look-up. Keep in sync with `ResolveUniforms` in
/// shaders/panorama.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ResolveUniforms {
    pub cave_from_view: [[f32; 4]; 4],
    pub cube_from_cave: [[f32; 4]; 4],
    pub window: [f32; 4],
    pub params: [f32; 4],
    pub background: [f32; 4],
}

/// One eye of the geometric route: what `vs_pano`, `fs_pano` and the tessellator's panorama
/// criterion read (see `ViewUniforms` for the fields' panorama meaning).
pub fn pano_view_uniforms(
    settings: &PanoSettings,
    head: Vec3,
    eye: Option<Eye>,
    ipd: f32,
    near: f32,
    far: f32,
    msaa: u32,
) -> ViewUniforms {
    let sign = eye.map_or(0.0, Eye::sign);
    let (stereo_code, omni_half, volume) = match settings.stereo {
        PanoStereo::Mono => (0, 0.0, [0.0; 3]),
        PanoStereo::Volume { ioid, d, offset } => (1, 0.0, [sign * 0.5 * ioid, d, offset]),
        PanoStereo::Omni => (2, sign * 0.5 * ipd, [0.0; 3]),
    };
    let fitted = settings.fitted();
    ViewUniforms {
        clip_from_cave: settings.view_from_cave(head).to_cols_array_2d(),
        eye_position: head.extend(1.0).to_array(),
        wall_plane: [0.0; 4],
        omni_head: head.extend(omni_half).to_array(),
        pano_projection: fitted.projection.code() + 1,
        pano_near: near,
        pano_far: far,
        pano_stereo: stereo_code,
        pano_window: fitted.map_window(),
        pano_size: settings.size.map(|v| v as f32),
        volume_half_ioid: volume[0],
        volume_distance: volume[1],
        volume_zero_parallax: volume[2],
        pano_msaa: msaa,
        pano_pad: [0; 2],
    }
}

/// The six faces the image route renders the scene into, and their depth.
#[derive(Debug)]
struct CubeTargets {
    size: u32,
    msaa: u32,
    faces: Vec<wgpu::TextureView>,
    array_view: wgpu::TextureView,
    msaa_view: Option<wgpu::TextureView>,
    depth_view: wgpu::TextureView,
}

impl CubeTargets {
    fn new(device: &wgpu::Device, size: u32, msaa: u32) -> Self {
        let texture = |label: &str, layers, format, samples, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: size,
                    height: size,
                    depth_or_array_layers: layers,
                },
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color = texture(
            "PanoPass::cube_faces",
            6,
            COLOR_FORMAT,
            1,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let faces = (0..6)
            .map(|f| {
                color.create_view(&wgpu::TextureViewDescriptor {
                    label: Some("PanoPass::cube_face"),
                    dimension: Some(wgpu::TextureViewDimension::D2),
                    base_array_layer: f,
                    array_layer_count: Some(1),
                    ..Default::default()
                })
            })
            .collect();
        let array_view = color.create_view(&wgpu::TextureViewDescriptor {
            label: Some("PanoPass::cube_array"),
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let msaa_view = (msaa > 1).then(|| {
            texture(
                "PanoPass::cube_msaa",
                1,
                COLOR_FORMAT,
                msaa,
                wgpu::TextureUsages::RENDER_ATTACHMENT,
            )
            .create_view(&Default::default())
        });
        let depth_view = texture(
            "PanoPass::cube_depth",
            1,
            DEPTH_FORMAT,
            msaa,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        )
        .create_view(&Default::default());
        Self {
            size,
            msaa,
            faces,
            array_view,
            msaa_view,
            depth_view,
        }
    }
}

/// The panorama's resources: eye targets, cube faces, the look-up and sky pipelines (built
/// once; the sky's again when MSAA changes).
#[derive(Debug)]
pub struct PanoPass {
    uniform_group: wgpu::BindGroup,
    faces_layout: wgpu::BindGroupLayout,
    /// The image route's look-up, without and with a sky.
    resolve_pipeline: wgpu::RenderPipeline,
    resolve_sky_pipeline: wgpu::RenderPipeline,
    /// The geometric route's sky, behind the scene in the eye targets.
    sky_pipeline: wgpu::RenderPipeline,
    sky_layout: wgpu::PipelineLayout,
    module: wgpu::ShaderModule,
    sampler: wgpu::Sampler,
    resolve_uniforms: wgpu::Buffer,
    cube: Option<CubeTargets>,
    faces_group: Option<wgpu::BindGroup>,
    /// The eye targets and their sample count.
    targets: Option<(WallTargets, u32)>,
    /// Bumped whenever the eye targets are replaced.
    pub generation: u64,
    /// Pipelines built so far.
    pub pipelines_built: u64,
}

/// A fragment-stage binding of a layout.
fn fragment_entry(binding: u32, ty: wgpu::BindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty,
        count: None,
    }
}

impl PanoPass {
    /// `sky_layout`: the sky pass's cube-map layout (the sky is bound as the sky pass has
    /// it); `msaa`: the eye targets' sample count.
    pub fn new(device: &wgpu::Device, sky_layout: &wgpu::BindGroupLayout, msaa: u32) -> Self {
        let uniform_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("PanoPass::uniform_layout"),
            entries: &[fragment_entry(
                0,
                wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
            )],
        });
        let faces_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("PanoPass::faces_layout"),
            entries: &[
                fragment_entry(
                    0,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                ),
                fragment_entry(
                    1,
                    wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                ),
            ],
        });
        let pipeline_layout = |label: &str, groups: &[Option<&wgpu::BindGroupLayout>]| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: groups,
                immediate_size: 0,
            })
        };
        let resolve_layout = pipeline_layout(
            "PanoPass::resolve_pipeline_layout",
            &[Some(&uniform_layout), Some(&faces_layout)],
        );
        let resolve_sky_layout = pipeline_layout(
            "PanoPass::resolve_sky_pipeline_layout",
            &[Some(&uniform_layout), Some(&faces_layout), Some(sky_layout)],
        );
        let sky_pipeline_layout = pipeline_layout(
            "PanoPass::sky_pipeline_layout",
            &[Some(&uniform_layout), None, Some(sky_layout)],
        );
        let module = shaders::module(device, "PanoPass::shader", shaders::PANORAMA);
        let resolve_pipeline =
            fullscreen_pipeline(device, &module, &resolve_layout, "fs_resolve", None);
        let resolve_sky_pipeline =
            fullscreen_pipeline(device, &module, &resolve_sky_layout, "fs_resolve_sky", None);
        let sky_pipeline =
            fullscreen_pipeline(device, &module, &sky_pipeline_layout, "fs_sky", Some(msaa));
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("PanoPass::face_sampler"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let resolve_uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("PanoPass::resolve_uniforms"),
            size: std::mem::size_of::<ResolveUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let uniform_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("PanoPass::uniform_group"),
            layout: &uniform_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: resolve_uniforms.as_entire_binding(),
            }],
        });
        Self {
            uniform_group,
            faces_layout,
            resolve_pipeline,
            resolve_sky_pipeline,
            sky_pipeline,
            sky_layout: sky_pipeline_layout,
            module,
            sampler,
            resolve_uniforms,
            cube: None,
            faces_group: None,
            targets: None,
            generation: 0,
            pipelines_built: 3,
        }
    }

    /// Rebuilds the sky pipeline for a new sample count (when MSAA changes, not per frame).
    pub fn set_msaa(&mut self, device: &wgpu::Device, msaa: u32) {
        self.sky_pipeline =
            fullscreen_pipeline(device, &self.module, &self.sky_layout, "fs_sky", Some(msaa));
        self.pipelines_built += 1;
    }

    /// Makes the eye targets match the image size and sample count (rebuilt only on change).
    pub fn ensure_targets(&mut self, device: &wgpu::Device, size: [u32; 2], msaa: u32) {
        let current = self
            .targets
            .as_ref()
            .is_some_and(|(t, m)| t.size == size && *m == msaa);
        if !current {
            self.targets = Some((WallTargets::new(device, "panorama", size, msaa, None), msaa));
            self.generation += 1;
        }
    }

    /// Makes the cube faces match the face size and sample count (rebuilt only on change).
    pub fn ensure_cube(&mut self, device: &wgpu::Device, size: u32, msaa: u32) {
        if self
            .cube
            .as_ref()
            .is_some_and(|c| c.size == size && c.msaa == msaa)
        {
            return;
        }
        let cube = CubeTargets::new(device, size, msaa);
        self.faces_group = Some(device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("PanoPass::faces_group"),
            layout: &self.faces_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&cube.array_view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&self.sampler),
                },
            ],
        }));
        self.cube = Some(cube);
    }

    pub fn targets(&self) -> Option<&WallTargets> {
        self.targets.as_ref().map(|(t, _)| t)
    }

    pub fn write_resolve(&self, queue: &wgpu::Queue, uniforms: &ResolveUniforms) {
        queue.write_buffer(&self.resolve_uniforms, 0, bytemuck::bytes_of(uniforms));
    }

    /// Records the six face passes: `draw_face(pass, face)` draws the scene into each.
    pub fn encode_faces(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        clear: wgpu::Color,
        mut draw_face: impl FnMut(&mut wgpu::RenderPass<'_>, usize),
    ) {
        let Some(cube) = &self.cube else {
            return;
        };
        for (face, face_view) in cube.faces.iter().enumerate() {
            let mut pass = begin_scene_pass(
                encoder,
                "PanoPass::face_pass",
                face_view,
                cube.msaa_view.as_ref(),
                &cube.depth_view,
                clear,
            );
            draw_face(&mut pass, face);
        }
    }

    /// Records the look-up of every pixel of the (left) eye target in the cube faces, with
    /// the sky (its cube-map group) where the faces show nothing.
    pub fn encode_resolve(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        sky: Option<&wgpu::BindGroup>,
    ) {
        let (Some(targets), Some(faces)) = (self.targets(), &self.faces_group) else {
            return;
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("PanoPass::resolve_pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &targets.eyes[0].color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_bind_group(0, &self.uniform_group, &[]);
        pass.set_bind_group(1, faces, &[]);
        match sky {
            Some(sky) => {
                pass.set_pipeline(&self.resolve_sky_pipeline);
                pass.set_bind_group(2, sky, &[]);
            }
            None => pass.set_pipeline(&self.resolve_pipeline),
        }
        pass.draw(0..3, 0..1);
    }

    /// Records the sky behind what an eye pass has drawn (the geometric route).
    pub fn draw_sky(&self, pass: &mut wgpu::RenderPass<'_>, sky: &wgpu::BindGroup) {
        pass.set_pipeline(&self.sky_pipeline);
        pass.set_bind_group(0, &self.uniform_group, &[]);
        pass.set_bind_group(2, sky, &[]);
        pass.draw(0..3, 0..1);
    }

    /// Opens a render pass on eye `eye`'s target (MSAA and depth as the scene pass needs).
    pub fn begin_eye_pass<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        eye: usize,
        clear: wgpu::Color,
    ) -> Option<wgpu::RenderPass<'e>> {
        let target = &self.targets()?.eyes[eye.min(1)];
        Some(begin_scene_pass(
            encoder,
            "PanoPass::eye_pass",
            &target.color_view,
            target.msaa_view.as_ref(),
            &target.depth_view,
            clear,
        ))
    }
}

/// A full-screen pipeline of shaders/panorama.wgsl: the look-up into a single-sampled target
/// (`msaa` `None`), or the sky behind a scene (`Some(samples)`: depth tested less-equal at
/// the far plane, not written).
fn fullscreen_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layout: &wgpu::PipelineLayout,
    fragment: &str,
    msaa: Option<u32>,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(&format!("PanoPass::{fragment}_pipeline")),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_fullscreen"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: msaa.map(|_| wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(false),
            depth_compare: Some(wgpu::CompareFunction::LessEqual),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: wgpu::MultisampleState {
            count: msaa.unwrap_or(1),
            ..Default::default()
        },
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fragment),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: COLOR_FORMAT,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}
