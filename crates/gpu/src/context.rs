//! Device setup: take an existing wgpu device and queue, or create them on the best
//! adapter with only the limits the scene needs.

use thiserror::Error;

/// Why the GPU backend could not be used.
#[derive(Debug, Error)]
pub enum GpuError {
    /// No adapter (no Vulkan, Metal or DX12 driver, or none that wgpu accepts).
    #[error(
        "no GPU adapter found ({0}); on Linux without a GPU install Mesa's software Vulkan driver \
         (apt-get install mesa-vulkan-drivers)"
    )]
    NoAdapter(String),
    /// The adapter refused the device.
    #[error("the GPU adapter {adapter} cannot create a device: {message}")]
    Device {
        /// Adapter name.
        adapter: String,
        /// wgpu's message.
        message: String,
    },
    /// A buffer of the scene is larger than the adapter allows in one binding.
    #[error(
        "the scene needs {needed} bytes in one storage buffer ({buffer}), the adapter {adapter} \
         allows {allowed}"
    )]
    TooLarge {
        /// The buffer.
        buffer: &'static str,
        /// Bytes needed.
        needed: u64,
        /// Bytes allowed per storage binding.
        allowed: u64,
        /// Adapter name.
        adapter: String,
    },
    /// Mapping a readback buffer failed.
    #[error("GPU readback failed: {0}")]
    Readback(String),
    /// The device cannot time kernels: wgpu's `TIMESTAMP_QUERY` feature is missing (the
    /// adapter lacks it, or the device was created without it).
    #[error(
        "kernel profiling is unsupported: the GPU device on {adapter} has no timestamp queries \
         (wgpu feature TIMESTAMP_QUERY)"
    )]
    ProfilingUnsupported {
        /// Adapter name.
        adapter: String,
    },
    /// The scene asks for something the GPU kernels do not compute yet.
    #[error("the GPU backend does not support {feature} yet: run this scene on the CPU backend")]
    Unsupported {
        /// What is missing.
        feature: &'static str,
    },
}

/// A device, its queue and what it is.
#[derive(Debug, Clone)]
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter it runs on.
    pub adapter: wgpu::AdapterInfo,
}

impl GpuContext {
    /// Uses an existing device and queue (for applications that already render with wgpu).
    /// The device must allow 8 storage buffers per shader stage and bindings as large as
    /// the scene's largest buffer; kernel profiling needs its `TIMESTAMP_QUERY` feature.
    pub fn from_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        adapter: wgpu::AdapterInfo,
    ) -> GpuContext {
        GpuContext {
            device,
            queue,
            adapter,
        }
    }

    /// Creates a device on the highest-performance adapter, asking for the downlevel
    /// defaults plus what [`GpuContext::on_adapter`] adds for the kernels.
    pub fn new(largest_buffer: u64) -> Result<GpuContext, GpuError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            ..Default::default()
        }))
        .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        GpuContext::on_adapter(&adapter, largest_buffer, wgpu::Limits::downlevel_defaults())
    }

    /// Creates a device on `adapter` (one chosen by the caller, e.g. able to present to a
    /// window) with the limits `base` raised to what the kernels need: 8 storage buffers
    /// per stage and a storage binding of `largest_buffer` bytes (at least the default
    /// 128 MiB where the adapter allows it); timestamp queries where the adapter has them
    /// (kernel profiling). `base` carries the caller's own needs (texture sizes, say).
    pub fn on_adapter(
        adapter: &wgpu::Adapter,
        largest_buffer: u64,
        base: wgpu::Limits,
    ) -> Result<GpuContext, GpuError> {
        let info = adapter.get_info();
        let available = adapter.limits();
        if largest_buffer > available.max_storage_buffer_binding_size {
            return Err(GpuError::TooLarge {
                buffer: "largest",
                needed: largest_buffer,
                allowed: available.max_storage_buffer_binding_size,
                adapter: info.name.clone(),
            });
        }
        let binding = largest_buffer
            .max(128 << 20)
            .max(base.max_storage_buffer_binding_size)
            .min(available.max_storage_buffer_binding_size);
        let limits = wgpu::Limits {
            max_storage_buffers_per_shader_stage: base.max_storage_buffers_per_shader_stage.max(8),
            max_storage_buffer_binding_size: binding,
            max_buffer_size: binding
                .max(largest_buffer)
                .max(base.max_buffer_size)
                .min(available.max_buffer_size),
            max_compute_workgroups_per_dimension: available
                .max_compute_workgroups_per_dimension
                .min(65535)
                .max(base.max_compute_workgroups_per_dimension),
            ..base
        };
        let features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("needlesim"),
            required_features: features,
            required_limits: limits,
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device {
            adapter: info.name.clone(),
            message: e.to_string(),
        })?;
        Ok(GpuContext {
            device,
            queue,
            adapter: info,
        })
    }

    /// One line naming the adapter, its driver and the graphics API.
    pub fn describe(&self) -> String {
        let a = &self.adapter;
        format!(
            "{} ({:?}, {:?}, driver {} {})",
            a.name, a.device_type, a.backend, a.driver, a.driver_info
        )
    }
}
