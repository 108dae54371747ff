//! The one wgpu device: adapter selection and the optional features the renderer uses.

use super::error::RenderError;

/// Instance, adapter, device and queue, plus what the adapter can do.
#[derive(Debug, Clone)]
pub struct Gpu {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// Wireframe rendering (`POLYGON_MODE_LINE`) is available.
    pub wireframe_supported: bool,
    /// GPU timestamps between passes (for the benchmark's frame times) are available.
    pub timestamps_supported: bool,
    /// GPU timestamps inside passes (between dispatches and draws): the per-stage breakdown.
    pub timestamps_inside_passes: bool,
}

/// Storage buffers the compute tessellator binds in one stage.
pub const TESSELLATOR_STORAGE_BUFFERS: u32 = 12;

impl Gpu {
    /// Opens the default adapter without a window (honours `WGPU_BACKEND`, `WGPU_ADAPTER_NAME`).
    pub fn headless() -> Result<Self, RenderError> {
        // Vulkan/Metal/DX12 by default (probing GL only adds noise where EGL is absent);
        // WGPU_BACKEND=gl still selects GL.
        let instance = wgpu::Instance::new(
            wgpu::InstanceDescriptor {
                backends: wgpu::Backends::PRIMARY,
                ..wgpu::InstanceDescriptor::new_without_display_handle()
            }
            .with_env(),
        );
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        Self::from_adapter(instance, adapter)
    }

    /// Opens an adapter that can present to `surface`, on the instance that made it.
    pub fn for_surface(
        instance: wgpu::Instance,
        surface: &wgpu::Surface<'_>,
    ) -> Result<Self, RenderError> {
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            compatible_surface: Some(surface),
            ..Default::default()
        }))
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        Self::from_adapter(instance, adapter)
    }

    /// Creates the device on a chosen adapter, enabling the optional features it offers.
    pub fn from_adapter(
        instance: wgpu::Instance,
        adapter: wgpu::Adapter,
    ) -> Result<Self, RenderError> {
        let wanted = wgpu::Features::POLYGON_MODE_LINE
            | wgpu::Features::TIMESTAMP_QUERY
            | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS
            | wgpu::Features::TIMESTAMP_QUERY_INSIDE_PASSES;
        let features = adapter.features() & wanted;
        // The tessellator binds 12 storage buffers in one compute stage; WebGPU's default is 8
        // but desktop adapters (and lavapipe) offer far more.
        let mut limits = wgpu::Limits::default().using_resolution(adapter.limits());
        limits.max_storage_buffers_per_shader_stage = adapter
            .limits()
            .max_storage_buffers_per_shader_stage
            .clamp(limits.max_storage_buffers_per_shader_stage, 16);
        // Large scenes: as large a buffer and storage binding as the adapter offers (WebGPU's
        // defaults, 256 and 128 MiB, hold only 3.7 M and 1.9 M vertices). Every use checks
        // its size against these first and says which limit a scene passes.
        limits.max_buffer_size = limits.max_buffer_size.max(adapter.limits().max_buffer_size);
        limits.max_storage_buffer_binding_size = limits
            .max_storage_buffer_binding_size
            .max(adapter.limits().max_storage_buffer_binding_size);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("omnicave device"),
            required_features: features,
            required_limits: limits,
            ..Default::default()
        }))
        .map_err(|e| RenderError::Device(e.to_string()))?;
        let info = adapter.get_info();
        tracing::info!(
            "GPU: {} ({:?}, {:?}, driver {})",
            info.name,
            info.device_type,
            info.backend,
            info.driver
        );
        Ok(Self {
            instance,
            adapter,
            device,
            queue,
            wireframe_supported: features.contains(wgpu::Features::POLYGON_MODE_LINE),
            timestamps_supported: features.contains(
                wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS,
            ),
            timestamps_inside_passes: features
                .contains(wgpu::Features::TIMESTAMP_QUERY_INSIDE_PASSES),
        })
    }

    /// Whether the device can run the compute tessellator and draw its output (storage
    /// buffers in the vertex stage).
    pub fn tessellation_supported(&self) -> bool {
        self.device.limits().max_storage_buffers_per_shader_stage >= TESSELLATOR_STORAGE_BUFFERS
            && self
                .adapter
                .get_downlevel_capabilities()
                .flags
                .contains(wgpu::DownlevelFlags::VERTEX_STORAGE)
            && self
                .adapter
                .get_downlevel_capabilities()
                .flags
                .contains(wgpu::DownlevelFlags::INDIRECT_EXECUTION)
    }
}
