//! Full-screen passes: pipelines that draw one triangle over the whole target
//! (`vs_fullscreen` of `shaders/fullscreen.wgsl`) and work pixel by pixel, their one-texture
//! layouts and their colour-only render passes.

/// What differs between the full-screen pipelines.
pub struct FullscreenPipeline<'a> {
    pub label: &'a str,
    pub layout: &'a wgpu::PipelineLayout,
    /// A module compiled with `fullscreen.wgsl`.
    pub shader: &'a wgpu::ShaderModule,
    pub fragment: &'a str,
    /// Override constants of the fragment stage.
    pub constants: &'a [(&'a str, f64)],
    pub format: wgpu::TextureFormat,
    pub blend: Option<wgpu::BlendState>,
}

/// Builds a full-screen pipeline (once, never per frame).
pub fn build(device: &wgpu::Device, p: &FullscreenPipeline<'_>) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(p.label),
        layout: Some(p.layout),
        vertex: wgpu::VertexState {
            module: p.shader,
            entry_point: Some("vs_fullscreen"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: None,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: p.shader,
            entry_point: Some(p.fragment),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: p.constants,
                ..Default::default()
            },
            targets: &[Some(wgpu::ColorTargetState {
                format: p.format,
                blend: p.blend,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// A bind group layout of one texture (non-filterable float, read with `textureLoad`) for the
/// fragment stage, and a pipeline layout of it alone.
pub fn texture_layout(
    device: &wgpu::Device,
    label: &str,
    multisampled: bool,
) -> (wgpu::BindGroupLayout, wgpu::PipelineLayout) {
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(&format!("{label}::layout")),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled,
            },
            count: None,
        }],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(&format!("{label}::pipeline_layout")),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    (layout, pipeline_layout)
}

/// A bind group of one texture view for a [`texture_layout`].
pub fn texture_bind_group(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    view: &wgpu::TextureView,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::TextureView(view),
        }],
    })
}

/// A render pass into one colour target, no depth, after `load`; the result is stored.
pub fn begin_colour_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    target: &wgpu::TextureView,
    load: wgpu::LoadOp<wgpu::Color>,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: target,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load,
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
