//! The resolve of multisampled eye images whose samples the shaders stored sRGB-encoded:
//! decoded, averaged in linear light, encoded once (paired with `shaders/resolve.wgsl`).
//!
//! Why the samples are encoded by the shader: an sRGB attachment is converted by the
//! rasteriser for every sample it stores, and on a CPU rasteriser (lavapipe) that is about an
//! eighth of the desktop preview's frame with MSAA 4 (see the book's performance page).
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
        let (layout, pipeline_layout) =
            super::fullscreen::texture_layout(device, "ResolvePass", true);
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
            self.pipelines_built += 1;
            super::fullscreen::build(
                device,
                &super::fullscreen::FullscreenPipeline {
                    label: "ResolvePass::pipeline",
                    layout: &self.pipeline_layout,
                    shader: &self.shader,
                    fragment: "fs_resolve",
                    constants: &constants,
                    format: super::formats::ENCODED_FORMAT,
                    blend: None,
                },
            )
        });
    }

    /// How many pipelines this pass has built.
    pub fn pipelines_built(&self) -> u64 {
        self.pipelines_built
    }

    /// Binds a multisampled image's encoded samples (a view in `formats::ENCODED_FORMAT`).
    pub fn bind(&self, device: &wgpu::Device, samples: &wgpu::TextureView) -> wgpu::BindGroup {
        super::fullscreen::texture_bind_group(
            device,
            "ResolvePass::bind_group",
            &self.layout,
            samples,
        )
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
        let mut pass = super::fullscreen::begin_colour_pass(
            encoder,
            "ResolvePass::pass",
            target,
            wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
        );
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, samples, &[]);
        pass.draw(0..3, 0..1);
    }
}
