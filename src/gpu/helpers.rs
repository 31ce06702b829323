//! The wgpu helpers every GPU fill shares (a leaf: it knows no surface kind): buffers,
//! pipelines from the composed WGSL modules, error scopes, dispatch and read-back.

use std::sync::mpsc;

use bytemuck::Pod;
use wgpu::util::DeviceExt;

use super::shaders;
use crate::error::{Error, Result};
use crate::stream::{Region, Surface};

/// One kind's GPU fill (`crate::kinds::GpuFill` says which kinds have one): its data on
/// the device, filled a band of rows at a time, and its CPU twin.
pub(super) trait BandFill: Send + Sync {
    /// Fills `region` (one band, within the dispatch limits) into `out`.
    fn fill_band(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        region: &Region,
        out: &mut [f32],
    ) -> Result<()>;

    /// The CPU twin (the same data and seed), for single samples.
    fn cpu(&self) -> &dyn Surface;

    /// Samples the host computed in f64 because the GPU could not decide them in f32;
    /// 0 for kinds that never do.
    fn host_recomputed(&self) -> u64 {
        0
    }
}

/// Workgroup edge of the fill entry points (`@workgroup_size(16, 16)`).
pub(super) const GROUP: u32 = 16;
/// Largest output a single dispatch writes; larger regions go in bands of rows.
pub(super) const MAX_BAND_BYTES: u64 = 128 << 20;

pub(super) fn bytes<T: Pod>(v: &[T]) -> Vec<u8> {
    bytemuck::cast_slice(v).to_vec()
}

/// One storage buffer holding `parts` back to back, written through the queue (no
/// concatenated copy on the host), and the start of each part in elements of `elem`
/// bytes. Refused when the whole is over `limit` bytes.
pub(super) fn upload(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    what: &str,
    parts: &[&[u8]],
    elem: usize,
    limit: u64,
) -> Result<(wgpu::Buffer, Vec<u32>)> {
    let total: usize = parts.iter().map(|p| p.len()).sum();
    if total as u64 > limit {
        return Err(Error::Limits(format!(
            "{what} take {total} bytes, over this GPU's storage-buffer limit of {limit}"
        )));
    }
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(what),
        size: (total as u64).max(4),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut base = Vec::with_capacity(parts.len());
    let mut at = 0usize;
    for part in parts {
        base.push(u32::try_from(at / elem).map_err(|_| too_big(what))?);
        if !part.is_empty() {
            queue.write_buffer(&buffer, at as u64, part);
        }
        at += part.len();
    }
    Ok((buffer, base))
}

/// A read-only storage buffer holding `data`.
pub(super) fn storage(device: &wgpu::Device, label: &str, data: &[u8]) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: data,
        usage: wgpu::BufferUsages::STORAGE,
    })
}

/// A uniform buffer holding a fill's parameters.
pub(super) fn uniform(device: &wgpu::Device, data: &[u8]) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("surftile fill parameters"),
        contents: data,
        usage: wgpu::BufferUsages::UNIFORM,
    })
}

pub(super) fn too_big(what: &str) -> Error {
    Error::Limits(format!(
        "{what} is too large for the GPU path's 32-bit indices"
    ))
}

pub(super) fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// The compute pipeline of entry point `entry` in shader module `module`.
pub(super) fn pipeline(device: &wgpu::Device, module: &str, entry: &str) -> wgpu::ComputePipeline {
    let source = shaders::module(module);
    let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(module),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: None,
        module: &shader,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// Turns a validation error captured since `scope` was pushed into [`Error::Gpu`].
pub(super) fn check_scope(scope: wgpu::ErrorScopeGuard, doing: &str) -> Result<()> {
    match pollster::block_on(scope.pop()) {
        None => Ok(()),
        Some(e) => Err(Error::Gpu(format!(
            "{doing}: {}",
            e.to_string().lines().next().unwrap_or("validation error")
        ))),
    }
}

/// Copies little-endian f32 bytes into `out`.
pub(super) fn copy_f32(bytes: &[u8], out: &mut [f32]) {
    match bytemuck::try_cast_slice::<u8, f32>(bytes) {
        Ok(v) => out.copy_from_slice(v),
        Err(_) => {
            for (o, b) in out.iter_mut().zip(bytes.chunks_exact(4)) {
                *o = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            }
        }
    }
}

/// Runs a fill entry point (16 × 16 workgroups over `region`) and reads its f32 output
/// `target` into `out`; then turns a validation error caught since `scope` into
/// [`Error::Gpu`] saying what it was `doing`.
pub(super) fn dispatch_fill(
    (device, queue): (&wgpu::Device, &wgpu::Queue),
    pipeline: &wgpu::ComputePipeline,
    bind: &wgpu::BindGroup,
    region: &Region,
    target: &wgpu::Buffer,
    out: &mut [f32],
    (scope, doing): (wgpu::ErrorScopeGuard, &str),
) -> Result<()> {
    let groups = [
        (region.width as u32).div_ceil(GROUP),
        (region.height as u32).div_ceil(GROUP),
    ];
    let bytes = std::mem::size_of_val(out) as u64;
    let result = dispatch_and_read(device, queue, pipeline, bind, groups, target, bytes, |b| {
        copy_f32(b, out)
    });
    check_scope(scope, doing)?;
    result
}

/// Dispatches `groups` workgroups of `pipeline`, copies `bytes` of `target` to a mapped
/// buffer and hands them to `read`.
#[allow(clippy::too_many_arguments)]
pub(super) fn dispatch_and_read<T>(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    pipeline: &wgpu::ComputePipeline,
    bind: &wgpu::BindGroup,
    groups: [u32; 2],
    target: &wgpu::Buffer,
    bytes: u64,
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T> {
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("surftile read-back"),
        size: bytes,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bind, &[]);
        pass.dispatch_workgroups(groups[0], groups[1], 1);
    }
    encoder.copy_buffer_to_buffer(target, 0, &staging, 0, bytes);
    queue.submit([encoder.finish()]);
    read_mapped(device, &staging, "the fill", read)
}

/// Maps `buffer` (MAP_READ, its copy already submitted), waits for the device, hands
/// the bytes to `read` and unmaps; `what` names the data in errors.
pub(crate) fn read_mapped<T>(
    device: &wgpu::Device,
    buffer: &wgpu::Buffer,
    what: &str,
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T> {
    let slice = buffer.slice(..);
    let (tx, rx) = mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    let failed = |e: String| Error::Gpu(format!("reading {what} back: {e}"));
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| failed(e.to_string()))?;
    rx.recv()
        .map_err(|_| failed("the mapping was dropped".into()))?
        .map_err(|e| failed(e.to_string()))?;
    let data = read(
        &slice
            .get_mapped_range()
            .map_err(|e| failed(e.to_string()))?,
    );
    buffer.unmap();
    Ok(data)
}

pub(super) fn band_limit(device: &wgpu::Device) -> u64 {
    device
        .limits()
        .max_storage_buffer_binding_size
        .min(device.limits().max_buffer_size)
}
