//! The resolve of multisampled eye images whose samples the shaders stored sRGB-encoded:
//! decoded, averaged in linear light, encoded once (paired with `shaders/resolve.wgsl`).
//!
//! Why the samples are encoded by the shader: an sRGB attachment is converted by the
//! rasteriser for every sample it stores, and on a CPU rasteriser (lavapipe) that is about an
//! eighth of the desktop preview's frame with MSAA 4 (see the README's preview paragraph).
//! Encoding once per fragment in the shader and storing plain bytes costs one conversion
//! per pixel. The hardware resolve of plain bytes would average them in sRGB space, which
//! darkens and shifts anti-aliased edges; this pass averages in linear light as the resolve
//! of an sRGB attachment does, so the image is the same. Blending needs linear values in the
//! target, so a scene with blended draws keeps the sRGB attachment and the hardware resolve.

use super::shaders;

/// The resolve's layout and its pipeline for the current sample count.
#[derive(Debug)]
pub struct ResolvePass {
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    shader: wgpu::ShaderModule,
    /// `None` without MSAA (nothing to resolve).
    pipeline: Option<wgpu::RenderPipeline>,
    pipelines_built: u64,
}

impl ResolvePass {
    pub fn new(device: &wgpu::Device, msaa: u32) -> Self {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("ResolvePass::layout"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: true,
                },
                count: None,
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("ResolvePass::pipeline_layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let mut pass = Self {
            layout,
            pipeline_layout,
            shader: shaders::module(device, "ResolvePass::shader", shaders::RESOLVE),
            pipeline: None,
            pipelines_built: 0,
        };
        pass.build_pipeline(device, msaa);
        pass
    }

    /// Builds the pipeline for a sample count (at start-up and when MSAA changes).
    pub fn build_pipeline(&mut self, device: &wgpu::Device, msaa: u32) {
        self.pipeline = (msaa > 1).then(|| {
            let constants = [("SAMPLE_COUNT", f64::from(msaa))];
            let options = wgpu::PipelineCompilationOptions {
                constants: &constants,
                ..Default::default()
            };
            self.pipelines_built += 1;
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("ResolvePass::pipeline"),
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
                    entry_point: Some("fs_resolve"),
                    compilation_options: options,
                    targets: &[Some(wgpu::ColorTargetState {
                        format: super::targets::ENCODED_FORMAT,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        });
    }

    /// How many pipelines this pass has built.
    pub fn pipelines_built(&self) -> u64 {
        self.pipelines_built
    }

    /// Binds a multisampled image's encoded samples (a view in `targets::ENCODED_FORMAT`).
    pub fn bind(&self, device: &wgpu::Device, samples: &wgpu::TextureView) -> wgpu::BindGroup {
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ResolvePass::bind_group"),
            layout: &self.layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(samples),
            }],
        })
    }

    /// Records the resolve of `samples` (bound by [`ResolvePass::bind`]) into `target`: the
    /// eye image's bytes (an `ENCODED_FORMAT` view of it), of the same size.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        samples: &wgpu::BindGroup,
        target: &wgpu::TextureView,
    ) {
        let Some(pipeline) = &self.pipeline else {
            return;
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("ResolvePass::pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, samples, &[]);
        pass.draw(0..3, 0..1);
    }
}
