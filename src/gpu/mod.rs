//! The GPU path: wgpu device setup on any adapter (software Vulkan included), banks
//! uploaded as storage buffers, region fills dispatched to `shaders/*.wgsl` and read back
//! as f32.
//!
//! Host functions take `&Device, &Queue`, so a caller that already has a device (the
//! viewer, an application's renderer) shares it; [`Gpu::new`] makes one for those that
//! do not. The shaders are twins of the CPU code, function for function; the parity
//! tests (`tests/gpu.rs`) hold them to the CPU fill within 1e-5 relative error, and to
//! the CPU hashes bit for bit.
//!
//! Set `SURFTILE_REQUIRE_GPU=1` (CI does) to turn a missing adapter from a skipped GPU
//! test into a failure.

mod fill;
mod shaders;

pub use fill::{GpuSurface, HashInput, HashOutput, gpu_hashes};
pub use shaders::{SHADER_FILES, composed_modules};

/// The environment variable that makes a missing GPU adapter an error in tests.
pub const REQUIRE_GPU_ENV: &str = "SURFTILE_REQUIRE_GPU";

/// True when `SURFTILE_REQUIRE_GPU` is set to anything but `0` or the empty string.
pub fn gpu_required() -> bool {
    std::env::var(REQUIRE_GPU_ENV).is_ok_and(|v| !v.is_empty() && v != "0")
}

/// A device and its queue on the best adapter found.
pub struct Gpu {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// What the adapter is (name, backend, software or hardware).
    pub info: wgpu::AdapterInfo,
}

impl Gpu {
    /// Opens a device on the best adapter: a hardware GPU if there is one, else any
    /// adapter, software Vulkan (lavapipe) included. The device gets the adapter's own
    /// limits, so large banks and regions fit where the hardware allows.
    ///
    /// `WGPU_BACKEND` (e.g. `vulkan`) and `WGPU_ADAPTER_NAME` narrow the choice.
    pub fn new() -> crate::Result<Gpu> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .or_else(|_| {
            pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                force_fallback_adapter: true,
                ..Default::default()
            }))
        })
        .map_err(|e| {
            crate::Error::Gpu(format!(
                "no GPU adapter found ({e}); install a Vulkan driver (on Debian, mesa-vulkan-drivers for software rendering)"
            ))
        })?;
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("surftile"),
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| crate::Error::Gpu(format!("adapter {} refused a device: {e}", info.name)))?;
        Ok(Gpu {
            device,
            queue,
            info,
        })
    }

    /// One line naming the adapter and its backend.
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?})",
            self.info.name, self.info.backend, self.info.device_type
        )
    }
}
