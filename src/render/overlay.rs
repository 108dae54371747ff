//! Composites a cached overlay image over a window's frame: the control panel, which egui
//! paints into the image only when it changes (paired with `shaders/overlay.wgsl`).
//!
//! Why: on a CPU rasteriser, painting the panel's few thousand text triangles every frame
//! cost about 5 ms of the desktop preview's frame; the panel changes about once a second (its
//! statistics) or when the user works it. Compositing the image costs one texel load per
//! pixel of the panel. The image is premultiplied, as egui paints, and blended as egui
//! blends, so where the panel is opaque the window shows the same bytes as before.

use super::fullscreen::{
    FullscreenPipeline, begin_colour_pass, build, texture_bind_group, texture_layout,
};
use super::shaders;

/// An overlay image of a window's size and format, bound for compositing.
#[derive(Debug)]
pub struct OverlayImage {
    pub view: wgpu::TextureView,
    bind_group: wgpu::BindGroup,
    pub size: [u32; 2],
}

/// The compositing pipeline for one target format.
#[derive(Debug)]
pub struct OverlayPass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    format: wgpu::TextureFormat,
}

/// egui's blending: premultiplied colour over the target (keep in sync with egui-wgpu's
/// renderer, which paints the image).
const PREMULTIPLIED_OVER: wgpu::BlendState = wgpu::BlendState {
    color: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
        operation: wgpu::BlendOperation::Add,
    },
    alpha: wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::OneMinusDstAlpha,
        dst_factor: wgpu::BlendFactor::One,
        operation: wgpu::BlendOperation::Add,
    },
};

impl OverlayPass {
    /// The pass for windows whose surface has `format` (built once per window).
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Self {
        let (layout, pipeline_layout) = texture_layout(device, "OverlayPass", false);
        let shader = shaders::module(device, "OverlayPass::shader", shaders::OVERLAY);
        let pipeline = build(
            device,
            &FullscreenPipeline {
                label: "OverlayPass::pipeline",
                layout: &pipeline_layout,
                shader: &shader,
                fragment: "fs_overlay",
                constants: &[],
                format,
                blend: Some(PREMULTIPLIED_OVER),
            },
        );
        Self {
            layout,
            pipeline,
            format,
        }
    }

    /// A new overlay image of `size` pixels (on creation and when the window is resized).
    pub fn image(&self, device: &wgpu::Device, size: [u32; 2]) -> OverlayImage {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("OverlayPass::image"),
            size: wgpu::Extent3d {
                width: size[0].max(1),
                height: size[1].max(1),
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: self.format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        let bind_group = texture_bind_group(device, "OverlayPass::bind_group", &self.layout, &view);
        OverlayImage {
            view,
            bind_group,
            size,
        }
    }

    /// Records `image` blended over `target` (of the image's size) inside `rect` (x, y,
    /// width, height in pixels; nothing is drawn outside it).
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        image: &OverlayImage,
        target: &wgpu::TextureView,
        rect: [u32; 4],
    ) {
        let [x, y, w, h] = rect;
        let x = x.min(image.size[0]);
        let y = y.min(image.size[1]);
        let w = w.min(image.size[0] - x);
        let h = h.min(image.size[1] - y);
        if w == 0 || h == 0 {
            return;
        }
        let mut pass = begin_colour_pass(encoder, "OverlayPass::pass", target, wgpu::LoadOp::Load);
        pass.set_scissor_rect(x, y, w, h);
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &image.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}
