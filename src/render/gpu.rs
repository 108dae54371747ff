//! The one wgpu device: adapter selection, the optional features the renderer uses, and the
//! device's fatal problems (an uncaptured validation error, a lost device) caught, not panicked.

use std::sync::{Arc, Mutex};

use super::error::RenderError;

/// The first fatal problem the device reported (wgpu's default is to panic on an uncaptured
/// error): the render loops check it each frame and stop with its message.
#[derive(Debug, Default)]
pub struct GpuFault(Mutex<Option<String>>);

impl GpuFault {
    /// Keeps the first problem (the later ones follow from it) and logs each.
    pub fn record(&self, problem: String) {
        tracing::error!("{problem}");
        self.keep(problem);
    }

    fn keep(&self, problem: String) {
        let mut slot = self
            .0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        slot.get_or_insert(problem);
    }

    pub fn get(&self) -> Option<String> {
        self.0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone()
    }
}

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
    /// The device's first fatal problem, if any ([`Gpu::check`]).
    pub fault: Arc<GpuFault>,
}

/// Storage buffers the compute tessellator binds in one stage (12, and three more windows
/// of the scene's vertices, see `vertex_windows`).
pub const TESSELLATOR_STORAGE_BUFFERS: u32 = 12 + super::vertex_windows::VERTEX_WINDOWS as u32 - 1;

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
        // The tessellator binds 15 storage buffers in one compute stage; WebGPU's default is 8
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
        let fault = Arc::new(GpuFault::default());
        let on_error = fault.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            // wgpu's Display says only "Validation Error"; the description says what and where.
            let problem = match &e {
                wgpu::Error::Validation { description, .. } => {
                    format!("GPU validation error: {}", description.trim())
                }
                wgpu::Error::Internal { description, .. } => {
                    format!("GPU internal error: {}", description.trim())
                }
                other => format!("GPU error: {other}"),
            };
            on_error.record(problem);
        }));
        let on_lost = fault.clone();
        device.set_device_lost_callback(move |reason, message| {
            let problem = format!("the GPU device was lost ({reason:?}): {message}");
            // Destroyed: `Device::destroy`, or the device dropped at the end of a run, when
            // nothing checks any more; kept for a check, logged only when unexpected.
            if reason == wgpu::DeviceLostReason::Destroyed {
                on_lost.keep(problem);
            } else {
                on_lost.record(problem);
            }
        });
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
            fault,
        })
    }

    /// `Err` once the device has reported a fatal problem (a validation error wgpu did not
    /// return to a caller, or the device lost): whatever was rendered since is not to be
    /// trusted.
    pub fn check(&self) -> Result<(), RenderError> {
        // Device-lost callbacks run from a poll: one that never waits delivers them now.
        let _ = self.device.poll(wgpu::PollType::Poll);
        self.fault
            .get()
            .map_or(Ok(()), |f| Err(RenderError::GpuFault(f)))
    }

    /// The test hook `OMNICAVE_TEST_GPU_FAULT`: `validation` makes a real validation error
    /// (a buffer both mapped for reading and writing), `lost` destroys the device, as a driver
    /// reset would. Anything else, or unset: nothing.
    pub fn apply_test_fault_hook(&self) {
        match std::env::var("OMNICAVE_TEST_GPU_FAULT").as_deref() {
            Ok("validation") => {
                let _invalid = self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("Gpu::test_fault_hook invalid buffer"),
                    size: 4,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::MAP_WRITE,
                    mapped_at_creation: false,
                });
            }
            Ok("lost") => self.device.destroy(),
            _ => {}
        }
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
