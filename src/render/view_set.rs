//! The per-frame data of one set of views (the walls' eyes, or the panorama's eyes or cube
//! faces): its frame and view uniforms and its own tessellation output, so that neither set
//! can disturb the other's and no call order between them matters.

use super::bindings::UNIFORM_STRIDE;
use super::error::RenderError;
use super::scene_gpu::SceneGpu;
use super::tessellator::{TessBuffers, Tessellator};
use super::uniforms::{FrameUniforms, ViewUniforms};
use crate::tess::TessStats;

/// What bounds a set of views' tessellation buffers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TessLimits {
    /// The output budget, triangles per view.
    pub capacity: u32,
    /// The largest window the scene's vertices are bound in, bytes (see `vertex_windows`).
    pub vertex_window: u64,
}

/// Uniforms and tessellation output of one set of views.
#[derive(Debug)]
pub struct ViewSet {
    label: &'static str,
    frame_buffer: wgpu::Buffer,
    view_buffer: wgpu::Buffer,
    view_capacity: usize,
    bind_group: wgpu::BindGroup,
    /// Reused every frame to stage view uniforms (no per-frame allocation).
    staging: Vec<u8>,
    /// Created on the first tessellated frame of a scene (they are large); dropped when the
    /// scene, the budget or the view buffer changes.
    tess: Option<TessBuffers>,
    /// Views the last frame tessellated (0: it was not tessellated).
    tessellated_views: usize,
}

impl ViewSet {
    /// Uniform buffers for `capacity` views, bound with `layout` (the scene pass's group 0).
    pub fn new(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        capacity: usize,
        label: &'static str,
    ) -> Self {
        let frame_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(&format!("{label}::frame_buffer")),
            size: std::mem::size_of::<FrameUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let (view_buffer, bind_group) =
            Self::view_resources(device, layout, &frame_buffer, capacity, label);
        Self {
            label,
            frame_buffer,
            view_buffer,
            view_capacity: capacity.max(1),
            bind_group,
            staging: Vec::with_capacity(capacity.max(1) * UNIFORM_STRIDE as usize),
            tess: None,
            tessellated_views: 0,
        }
    }

    fn view_resources(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        frame_buffer: &wgpu::Buffer,
        capacity: usize,
        label: &str,
    ) -> (wgpu::Buffer, wgpu::BindGroup) {
        let view_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(&format!("{label}::view_buffer")),
            size: UNIFORM_STRIDE * capacity.max(1) as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&format!("{label}::bind_group")),
            layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: frame_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &view_buffer,
                        offset: 0,
                        size: wgpu::BufferSize::new(std::mem::size_of::<ViewUniforms>() as u64),
                    }),
                },
            ],
        });
        (view_buffer, bind_group)
    }

    /// Grows the view uniform buffer when more views are needed (not per frame); the
    /// tessellation buffers, which bind it, are rebuilt on their next use.
    pub fn ensure_capacity(
        &mut self,
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        views: usize,
    ) {
        if views <= self.view_capacity {
            return;
        }
        let (buffer, bind_group) =
            Self::view_resources(device, layout, &self.frame_buffer, views, self.label);
        self.view_buffer = buffer;
        self.bind_group = bind_group;
        self.view_capacity = views;
        self.tess = None;
    }

    /// The group-0 bind group (frame uniforms, and the view at a dynamic offset).
    pub fn bind_group(&self) -> &wgpu::BindGroup {
        &self.bind_group
    }

    /// Uploads a frame's uniforms: one write for the frame, one for all views.
    pub fn write_uniforms(
        &mut self,
        queue: &wgpu::Queue,
        frame: &FrameUniforms,
        views: impl Iterator<Item = ViewUniforms>,
    ) {
        queue.write_buffer(&self.frame_buffer, 0, bytemuck::bytes_of(frame));
        self.staging.clear();
        for view in views.take(self.view_capacity) {
            self.staging.extend_from_slice(bytemuck::bytes_of(&view));
            self.staging.resize(
                self.staging.len().next_multiple_of(UNIFORM_STRIDE as usize),
                0,
            );
        }
        if !self.staging.is_empty() {
            queue.write_buffer(&self.view_buffer, 0, &self.staging);
        }
    }

    /// Drops the tessellation buffers (a new scene or budget); they are rebuilt on next use.
    pub fn drop_tessellation(&mut self) {
        self.tess = None;
        self.tessellated_views = 0;
    }

    /// The tessellation buffers for `scene` within `limits`, built on first use.
    pub fn tessellation(
        &mut self,
        device: &wgpu::Device,
        tessellator: &Tessellator,
        scene: &SceneGpu,
        limits: TessLimits,
    ) -> Result<&mut TessBuffers, RenderError> {
        let buffers = match self.tess.take() {
            Some(buffers) => buffers,
            None => tessellator.buffers(
                device,
                &self.frame_buffer,
                &self.view_buffer,
                std::mem::size_of::<ViewUniforms>() as u64,
                &scene.whole()?.vertex_buffer,
                &scene.whole()?.index_buffer,
                &scene.tri_info,
                scene.draw_count(),
                scene.clusters.len(),
                limits.capacity,
                self.view_capacity,
                limits.vertex_window,
            )?,
        };
        Ok(self.tess.insert(buffers))
    }

    /// The tessellation output of the last frame, if it was tessellated.
    pub fn tessellated(&self) -> Option<&TessBuffers> {
        self.tess.as_ref().filter(|_| self.tessellated_views > 0)
    }

    /// Records how many views the frame just encoded tessellated (0: none).
    pub fn set_tessellated_views(&mut self, views: usize) {
        self.tessellated_views = views;
    }

    /// Tessellation statistics of the last frame, one per tessellated view (a blocking read,
    /// for the CLI and tests; empty when it was not tessellated).
    pub fn read_tess_stats(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        scene: Option<&SceneGpu>,
    ) -> Result<Vec<TessStats>, RenderError> {
        match (self.tessellated(), scene) {
            (Some(buffers), Some(scene)) => buffers.read_stats(
                device,
                queue,
                self.tessellated_views,
                scene.triangle_count as u32,
            ),
            _ => Ok(Vec::new()),
        }
    }
}
