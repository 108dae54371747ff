//! The present pass (shaders/present.wgsl): composes a wall's eye images into its stereo output
//! format, on the GPU, into a window's surface or any other target.

use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};
use image::RgbaImage;

use super::shaders;
use super::{RenderError, targets};
use crate::output::formats::{StereoFormat, frame_packing_gap};

/// Keep in sync with `PresentUniforms` in shaders/present.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct PresentUniforms {
    pub params: [u32; 4],
    pub size: [u32; 4],
}

/// What one composed frame shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PresentParams {
    pub format: StereoFormat,
    /// Index of the presented frame (frame-sequential: left eye on even frames).
    pub frame: u64,
    pub swap_eyes: bool,
}

/// One pair of eye images bound for composing (made when the eye textures change, not per
/// frame), with its own uniform buffer.
#[derive(Debug)]
pub struct PresentBinding {
    uniforms: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    eye_size: [u32; 2],
}

/// The compose pipelines, one per target format (built the first time a format is seen).
#[derive(Debug)]
pub struct PresentPass {
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    shader: wgpu::ShaderModule,
    pipelines: HashMap<wgpu::TextureFormat, wgpu::RenderPipeline>,
}

impl PresentPass {
    pub fn new(device: &wgpu::Device) -> Self {
        let texture = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("PresentPass::layout"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                texture(1),
                texture(2),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("PresentPass::pipeline_layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        Self {
            layout,
            pipeline_layout,
            shader: shaders::module(device, "PresentPass::shader", shaders::PRESENT),
            pipelines: HashMap::new(),
        }
    }

    /// Builds the pipeline for a target format if it does not exist yet (call when a window's
    /// surface is configured, not per frame).
    pub fn ensure_pipeline(&mut self, device: &wgpu::Device, format: wgpu::TextureFormat) {
        if self.pipelines.contains_key(&format) {
            return;
        }
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(&format!("PresentPass::pipeline {format:?}")),
            layout: Some(&self.pipeline_layout),
            vertex: wgpu::VertexState {
                module: &self.shader,
                entry_point: Some("vs_fullscreen"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &self.shader,
                entry_point: Some("fs_present"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        self.pipelines.insert(format, pipeline);
    }

    /// Binds a pair of eye textures (same size, single-sampled).
    pub fn bind(
        &self,
        device: &wgpu::Device,
        left: &wgpu::Texture,
        right: &wgpu::Texture,
    ) -> PresentBinding {
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("PresentPass::uniforms"),
            size: std::mem::size_of::<PresentUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let (lv, rv) = (
            left.create_view(&Default::default()),
            right.create_view(&Default::default()),
        );
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("PresentPass::bind_group"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniforms.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&lv),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&rv),
                },
            ],
        });
        PresentBinding {
            uniforms,
            bind_group,
            eye_size: [left.width(), left.height()],
        }
    }

    /// Records the composition into `target` (of `target_format`, whose pipeline must exist;
    /// nothing is drawn otherwise) and writes the binding's uniforms.
    pub fn encode(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        binding: &PresentBinding,
        target: &wgpu::TextureView,
        target_format: wgpu::TextureFormat,
        params: PresentParams,
    ) {
        let Some(pipeline) = self.pipelines.get(&target_format) else {
            tracing::warn!("no present pipeline for {target_format:?}");
            return;
        };
        let [w, h] = binding.eye_size;
        let uniforms = PresentUniforms {
            params: [
                params.format.code(),
                (params.frame % 2) as u32,
                u32::from(params.swap_eyes),
                frame_packing_gap(h),
            ],
            size: [w, h, u32::from(!target_format.is_srgb()), 0],
        };
        queue.write_buffer(&binding.uniforms, 0, bytemuck::bytes_of(&uniforms));
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("PresentPass::pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
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
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &binding.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }

    /// Composes into a new image on the CPU (headless output and tests; reads back).
    pub fn compose_to_image(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        left: &wgpu::Texture,
        right: &wgpu::Texture,
        params: PresentParams,
    ) -> Result<RgbaImage, RenderError> {
        let format = targets::COLOR_FORMAT;
        self.ensure_pipeline(device, format);
        let binding = self.bind(device, left, right);
        let [w, h] = params.format.output_size(binding.eye_size);
        let target = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("PresentPass::image"),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("PresentPass::compose_to_image"),
        });
        self.encode(
            queue,
            &mut encoder,
            &binding,
            &target.create_view(&Default::default()),
            format,
            params,
        );
        queue.submit([encoder.finish()]);
        let mut images = targets::read_textures(device, queue, &[&target])?;
        images
            .pop()
            .ok_or_else(|| RenderError::Readback("no composed image".into()))
    }
}
