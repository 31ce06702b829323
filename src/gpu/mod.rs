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
mod helpers;
mod milling;
mod shaders;

pub(crate) use fill::blend_sampler_params;
pub use fill::{GpuSurface, HashInput, HashOutput, gpu_hashes};
pub(crate) use helpers::read_mapped;
pub use shaders::{SHADER_FILES, composed_modules};

/// The WGSL source of shader module `name` (`shade`, `blend`, …), as the GPU path compiles it.
pub(crate) fn module_source(name: &str) -> String {
    shaders::module(name)
}

/// The environment variable that makes a missing GPU adapter an error in tests.
pub const REQUIRE_GPU_ENV: &str = "SURFTILE_REQUIRE_GPU";

/// True when `SURFTILE_REQUIRE_GPU` is set to anything but `0` or the empty string.
pub fn gpu_required() -> bool {
    std::env::var(REQUIRE_GPU_ENV).is_ok_and(|v| !v.is_empty() && v != "0")
}

/// A device and its queue on the best adapter found. Clones share the device.
#[derive(Clone)]
pub struct Gpu {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// What the adapter is (name, backend, software or hardware).
    pub info: wgpu::AdapterInfo,
    /// The adapter.
    pub adapter: wgpu::Adapter,
}

/// The backend sets to try in turn: all of them when `WGPU_BACKEND` narrows the choice,
/// else the primary backends (Vulkan, Metal, DX12) and then GL.
pub(crate) fn backend_tries() -> Vec<wgpu::Backends> {
    if std::env::var_os("WGPU_BACKEND").is_some() {
        vec![wgpu::Backends::all()]
    } else {
        vec![wgpu::Backends::PRIMARY, wgpu::Backends::SECONDARY]
    }
}

/// An instance on `backends`, with the `WGPU_*` environment applied.
pub(crate) fn instance(backends: wgpu::Backends) -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = backends;
    wgpu::Instance::new(desc.with_env())
}

impl Gpu {
    /// Opens a device on the best adapter: a hardware GPU if there is one, else any
    /// adapter, software Vulkan (lavapipe) included. The device gets the adapter's own
    /// limits, so large banks and regions fit where the hardware allows.
    ///
    /// `WGPU_BACKEND` (e.g. `vulkan`) and `WGPU_ADAPTER_NAME` narrow the choice.
    pub fn new() -> crate::Result<Gpu> {
        // The primary backends (Vulkan, Metal, DX12) first; GL only where none of them
        // has an adapter, as probing GL without a display prints warnings of its own.
        let tries = backend_tries();
        let mut failure = String::new();
        let mut found = None;
        for backends in tries {
            let instance = instance(backends);
            match pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                ..Default::default()
            })) {
                Ok(a) => {
                    found = Some(a);
                    break;
                }
                Err(e) => failure = e.to_string(),
            }
        }
        let adapter = found.ok_or_else(|| {
            crate::Error::Gpu(format!(
                "no GPU adapter found ({failure}); install a Vulkan driver (on Debian, mesa-vulkan-drivers for software rendering)"
            ))
        })?;
        Gpu::from_adapter(adapter)
    }

    /// Opens a device on `adapter`, with the adapter's own limits.
    pub fn from_adapter(adapter: wgpu::Adapter) -> crate::Result<Gpu> {
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
            adapter,
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

/// A surface whose region fills (and row fills, which are regions too) run on the GPU,
/// with single samples on its CPU twin: what `surftile render --gpu` renders through,
/// and what the viewer's page workers fill GPU pages with.
pub struct GpuFilled {
    gpu: Gpu,
    surface: GpuSurface,
}

impl GpuFilled {
    /// Opens a device ([`Gpu::new`]) and uploads `bank` for fills placed with `seed`.
    /// Fails with [`crate::Error::Gpu`] where there is no adapter and
    /// [`crate::Error::Unsupported`] for rules the GPU does not run (RSGF), so a
    /// caller can fall back to the CPU.
    pub fn open(bank: &crate::bank::Bank, seed: u32) -> crate::Result<GpuFilled> {
        let gpu = Gpu::new()?;
        let surface = GpuSurface::new(&gpu.device, &gpu.queue, bank, seed)?;
        Ok(GpuFilled { gpu, surface })
    }

    /// Opens a device and uploads what `source` needs, as its kind's
    /// [`crate::kinds::GpuFill`] says. Fails with [`crate::Error::Unsupported`] for a
    /// kind without a GPU twin (before looking for an adapter) and with
    /// [`crate::Error::Gpu`] where there is no adapter, so a caller can fall back to
    /// the CPU.
    pub fn for_source(source: &dyn crate::kinds::Loaded, seed: u32) -> crate::Result<GpuFilled> {
        if let crate::kinds::GpuFill::Cpu(why) = source.kind().gpu() {
            return Err(crate::Error::Unsupported(format!(
                "{} sources on the GPU ({why})",
                source.kind().name()
            )));
        }
        let gpu = Gpu::new()?;
        let surface = GpuSurface::for_source(&gpu.device, &gpu.queue, source, seed)?;
        Ok(GpuFilled { gpu, surface })
    }

    /// A surface already on `gpu`'s device, filling there.
    pub fn from_parts(gpu: Gpu, surface: GpuSurface) -> GpuFilled {
        GpuFilled { gpu, surface }
    }

    /// The device in use.
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }
}

impl crate::stream::Surface for GpuFilled {
    fn channels(&self) -> usize {
        self.surface.cpu().channels()
    }

    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        self.surface.cpu().sample_footprint(x, y, footprint, out)
    }

    fn fill_rows(
        &self,
        region: &crate::stream::Region,
        rows: std::ops::Range<usize>,
        out: &mut [f32],
    ) {
        // Rows of a region are a region too: the GPU fills them (the page streamer's
        // workers fill pages this way). Should the GPU fail (a lost device), the CPU
        // twin gives the same values.
        let on_gpu = region
            .sub(0, rows.start, region.width, rows.len())
            .and_then(|sub| {
                self.surface
                    .fill(&self.gpu.device, &self.gpu.queue, &sub, out)
            });
        if on_gpu.is_err() {
            self.surface.cpu().fill_rows(region, rows, out)
        }
    }

    fn fill(&self, region: &crate::stream::Region, out: &mut [f32]) -> crate::Result<()> {
        self.surface
            .fill(&self.gpu.device, &self.gpu.queue, region, out)
    }
}
