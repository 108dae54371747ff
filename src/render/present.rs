//! The present pass (shaders/present.wgsl): composes a wall's eye images into its stereo output
//! format, on the GPU, into a window's surface or any other target.

use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};
use image::RgbaImage;

use super::error::RenderError;
use super::shaders;
use super::targets;
use crate::output::formats::{StereoFormat, frame_packing_gap};

/// Keep in sync with `PresentUniforms` in shaders/present.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct PresentUniforms {
    pub params: [u32; 4],
    pub size: [u32; 4],
    /// Tile origin (target pixels) and composed pixels per target pixel.
    pub viewport: [f32; 4],
    /// Offset of the image (composed pixels) and the crop's top-left in the eye image.
    pub shift: [i32; 4],
    /// The crop's size, and 1 if crop and shift apply.
    pub crop: [u32; 4],
}

/// A projector's alignment: the part of the eye image it shows and how far it is moved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Crop {
    /// x, y, width, height in eye-image pixels.
    pub rect: [u32; 4],
    /// Right and down, in eye-image pixels.
    pub offset: [i32; 2],
}

/// What one composed frame shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PresentParams {
    pub format: StereoFormat,
    /// Index of the presented frame (frame-sequential: left eye on even frames).
    pub frame: u64,
    pub swap_eyes: bool,
}

/// One composed image drawn into a rectangle of a target: a wall window's whole surface, or
/// one wall of the unfolded preview.
#[derive(Debug, Clone, Copy)]
pub struct Tile<'a> {
    pub binding: &'a PresentBinding,
    pub params: PresentParams,
    /// x, y, width, height in target pixels.
    pub rect: [f32; 4],
    /// Crop and offset (single-eye formats; the composed image is the crop's size).
    pub crop: Option<Crop>,
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
    /// Pipelines built so far (a switch must never build one per frame).
    pipelines_built: u64,
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
            pipelines_built: 0,
        }
    }

    /// Builds the pipeline for a target format if it does not exist yet (call when a window's
    /// surface is configured, not per frame).
    pub fn ensure_pipeline(&mut self, device: &wgpu::Device, format: wgpu::TextureFormat) {
        if self.pipelines.contains_key(&format) {
            return;
        }
        let pipeline = super::fullscreen::build(
            device,
            &super::fullscreen::FullscreenPipeline {
                label: &format!("PresentPass::pipeline {format:?}"),
                layout: &self.pipeline_layout,
                shader: &self.shader,
                fragment: "fs_present",
                constants: &[],
                format,
                blend: None,
            },
        );
        self.pipelines.insert(format, pipeline);
        self.pipelines_built += 1;
    }

    /// How many pipelines this pass has built.
    pub fn pipelines_built(&self) -> u64 {
        self.pipelines_built
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
    /// nothing is drawn otherwise) and writes the binding's uniforms. The target is the
    /// format's output size.
    pub fn encode(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        binding: &PresentBinding,
        target: &wgpu::TextureView,
        target_format: wgpu::TextureFormat,
        params: PresentParams,
    ) {
        let [w, h] = params.format.output_size(binding.eye_size);
        let tile = Tile {
            binding,
            params,
            rect: [0.0, 0.0, w as f32, h as f32],
            crop: None,
        };
        self.encode_tiles(
            queue,
            encoder,
            &[tile],
            target,
            target_format,
            wgpu::LoadOp::Clear(wgpu::Color::BLACK),
        );
    }

    /// Records one pass drawing each tile's composed image into its rectangle of `target`
    /// (scaled to fit it exactly), after `load` (clear or keep). Each binding's uniforms are
    /// rewritten, so a binding appears in at most one tile per submission.
    pub fn encode_tiles(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        tiles: &[Tile<'_>],
        target: &wgpu::TextureView,
        target_format: wgpu::TextureFormat,
        load: wgpu::LoadOp<wgpu::Color>,
    ) {
        let Some(pipeline) = self.pipelines.get(&target_format) else {
            tracing::warn!("no present pipeline for {target_format:?}");
            return;
        };
        for tile in tiles {
            let [w, h] = tile.binding.eye_size;
            let [out_w, out_h] = match tile.crop {
                Some(c) => [c.rect[2], c.rect[3]],
                None => tile.params.format.output_size([w, h]),
            };
            let [x, y, tw, th] = tile.rect;
            let (shift, crop) = match tile.crop {
                Some(c) => (
                    [
                        c.offset[0],
                        c.offset[1],
                        c.rect[0].min(i32::MAX as u32) as i32,
                        c.rect[1].min(i32::MAX as u32) as i32,
                    ],
                    [c.rect[2], c.rect[3], 1, 0],
                ),
                None => ([0; 4], [0; 4]),
            };
            let uniforms = PresentUniforms {
                params: [
                    tile.params.format.code(),
                    (tile.params.frame % 2) as u32,
                    u32::from(tile.params.swap_eyes),
                    frame_packing_gap(h),
                ],
                size: [w, h, u32::from(!target_format.is_srgb()), 0],
                viewport: [x, y, out_w as f32 / tw.max(1.0), out_h as f32 / th.max(1.0)],
                shift,
                crop,
            };
            queue.write_buffer(&tile.binding.uniforms, 0, bytemuck::bytes_of(&uniforms));
        }
        let mut pass =
            super::fullscreen::begin_colour_pass(encoder, "PresentPass::pass", target, load);
        pass.set_pipeline(pipeline);
        for tile in tiles {
            let [x, y, w, h] = tile.rect;
            if w < 1.0 || h < 1.0 {
                continue;
            }
            pass.set_viewport(x, y, w, h, 0.0, 1.0);
            pass.set_bind_group(0, &tile.binding.bind_group, &[]);
            pass.draw(0..3, 0..1);
        }
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
        let format = super::formats::COLOR_FORMAT;
        self.ensure_pipeline(device, format);
        let binding = self.bind(device, left, right);
        let [w, h] = params.format.output_size(binding.eye_size);
        targets::check_texture_size(
            device,
            &format!("the {} output", params.format.name()),
            w,
            h,
        )?;
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
