//! Face milling on the GPU (`shaders/milling.wgsl`).
//!
//! The split of work: the host finds, for each [`BLOCK`]² block of the region, the rings
//! that can reach it (the search the CPU fill makes per block,
//! [`MillingSurface::rings_reaching_rect`]), in milling order, and draws each ring's
//! random numbers once in f64; the GPU folds them at every pixel (and every point of a
//! footprint above 1 pixel), which is where the CPU spends its time.
//!
//! Deviation from "the region origin as an integer cell plus an f32 offset": milling has
//! no cells, so every column, row and ring centre is passed in millimetres relative to
//! the band's first sample, split into an f32 high and low part. Offsets from a centre
//! then keep about 2⁻²⁴ of the tool radius at any distance from the origin. Where a
//! pixel lies within `tol` (≈ 32 f32 ulps of the ring's reach) of a ring's part border,
//! where the model is discontinuous, the shader leaves it to the host, which computes it
//! in f64 as the CPU does; so the GPU fill matches the CPU's even at the borders.
//!
//! Far zoomed out, where a 32-sample block spans more than four ring reaches, the band
//! is filled by the CPU's O(1) sampler instead (per-block lists would grow with the
//! square of the block's extent).

use bytemuck::{Pod, Zeroable};
use std::collections::HashMap;

use super::helpers::{
    BandFill, bytes, check_scope, dispatch_fill, entry, pipeline, storage, uniform,
};
use crate::error::Result;
use crate::models::milling::MillingSurface;
use crate::models::milling::config::{InteractionKind, ShapeKind};
use crate::stream::{Region, Surface, default_threads};

/// Pixels across a block of one ring list.
pub(super) const BLOCK: usize = 32;

/// `shaders/milling.wgsl` `MillAxis`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct MillAxis {
    hi: f32,
    lo: f32,
    block: u32,
    pad: u32,
}

/// `shaders/milling.wgsl` `MillRing`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct MillRing {
    cx_hi: f32,
    cx_lo: f32,
    cy_hi: f32,
    cy_lo: f32,
    cos_t: f32,
    sin_t: f32,
    w_minus: f32,
    w_inner: f32,
    w_outer: f32,
    noise_word: u32,
    weight_a: f32,
    weight_b: f32,
    planes: [[f32; 2]; 3],
    pad: [u32; 2],
}

/// `shaders/milling.wgsl` `MillParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct MillParams {
    width: u32,
    height: u32,
    blocks_x: u32,
    n: u32,
    shape: u32,
    interaction: u32,
    adapt: u32,
    pad0: u32,
    r: f32,
    support_in: f32,
    support_out: f32,
    noise_scale: f32,
    tol: f32,
    adapt_scale: f32,
    model_mean: f32,
    target_mean: f32,
    offsets: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<MillAxis>() == 16);
const _: () = assert!(std::mem::size_of::<MillRing>() == 80);
const _: () = assert!(std::mem::size_of::<MillParams>() == 80);

/// v as an f32 high part and the f32 rest.
fn split(v: f64) -> (f32, f32) {
    let hi = v as f32;
    (hi, (v - hi as f64) as f32)
}

/// Points per footprint axis for `step` (`MillingSurface::sample_footprint`'s n).
fn footprint_points(step: f64) -> usize {
    if step <= 1.0 {
        1
    } else {
        step.ceil().min(4.0) as usize
    }
}

/// The ring table and per-block lists of one band.
struct Lists {
    rings: Vec<MillRing>,
    index: Vec<u32>,
    blocks: Vec<[u32; 2]>,
}

/// Ring lists for the block rows `brows` of `region` (blocks of [`BLOCK`] pixels,
/// `blocks_x` across), with centres relative to `origin` (mm) and each block's
/// rectangle widened by `widen` mm (the footprint's reach).
fn block_lists(
    s: &MillingSurface,
    region: &Region,
    brows: std::ops::Range<usize>,
    blocks_x: usize,
    origin: (f64, f64),
    widen: f64,
) -> Lists {
    let mm = s.mm_per_px();
    let spiral = s.tool_path().is_spiral();
    let sort = s.ring_model().interaction != InteractionKind::Min;
    let mut lists = Lists {
        rings: Vec::new(),
        index: Vec::new(),
        blocks: Vec::with_capacity(brows.len() * blocks_x),
    };
    let mut seen: HashMap<(i64, i64), u32> = HashMap::new();
    let mut found = Vec::with_capacity(64);
    for by in brows {
        let r0 = by * BLOCK;
        let r1 = (r0 + BLOCK).min(region.height);
        for bx in 0..blocks_x {
            let c0 = bx * BLOCK;
            let c1 = (c0 + BLOCK).min(region.width);
            let rect = (
                region.x_at(c0) * mm - widen,
                region.y_at(r0) * mm - widen,
                region.x_at(c1 - 1) * mm + widen,
                region.y_at(r1 - 1) * mm + widen,
            );
            found.clear();
            s.rings_reaching_rect(rect, spiral, |id, d| found.push((id, d)));
            if sort {
                found.sort_unstable_by_key(|(_, d)| d.key);
            }
            let start = lists.index.len() as u32;
            for (id, d) in &found {
                let k = *seen.entry(*id).or_insert_with(|| {
                    let (cx_hi, cx_lo) = split(d.centre.0 - origin.0);
                    let (cy_hi, cy_lo) = split(d.centre.1 - origin.1);
                    let p = |(l, h): (f64, f64)| [l as f32, h as f32];
                    lists.rings.push(MillRing {
                        cx_hi,
                        cx_lo,
                        cy_hi,
                        cy_lo,
                        cos_t: d.dir.0 as f32,
                        sin_t: d.dir.1 as f32,
                        w_minus: d.w_minus as f32,
                        w_inner: d.w_inner as f32,
                        w_outer: d.w_outer as f32,
                        noise_word: d.noise_word,
                        weight_a: d.weights.0 as f32,
                        weight_b: d.weights.1 as f32,
                        planes: [p(d.planes[0]), p(d.planes[1]), p(d.planes[2])],
                        pad: [0; 2],
                    });
                    (lists.rings.len() - 1) as u32
                });
                lists.index.push(k);
            }
            lists.blocks.push([start, lists.index.len() as u32 - start]);
        }
    }
    lists
}

/// The milling model's constant tables on the GPU and its pipeline.
pub(super) struct GpuMilling {
    pub(super) surface: MillingSurface,
    lut: wgpu::Buffer,
    noise: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    /// Pixels the host recomputed at ring borders, over every fill so far.
    pub(super) recomputed: std::sync::atomic::AtomicU64,
}

impl GpuMilling {
    pub(super) fn new(device: &wgpu::Device, surface: MillingSurface) -> Result<GpuMilling> {
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let (lut, noise) = surface.tables();
        let noise: Vec<i32> = noise.iter().map(|&v| v as i32).collect();
        let lut = storage(device, "milling shape table", &bytes(lut));
        let noise = storage(device, "milling noise profiles", &bytes(&noise));
        let pipeline = pipeline(device, "milling", "fill_milling");
        check_scope(scope, "uploading the milling tables")?;
        Ok(GpuMilling {
            surface,
            lut,
            noise,
            pipeline,
            recomputed: Default::default(),
        })
    }

    /// One band: ring lists on the host (in parallel over block rows), the fold on the
    /// GPU, and the pixels it left (NaN) recomputed on the host.
    fn dispatch(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        region: &Region,
        out: &mut [f32],
    ) -> Result<()> {
        let s = &self.surface;
        let m = s.ring_model();
        let mm = s.mm_per_px();
        // A block's ring list grows with the square of its extent. Once a block spans
        // several tool diameters (far zoomed out: 32 samples > 4 reaches), the lists would
        // hold thousands of rings each, while the CPU's sampler stays O(1) per point: fill
        // such bands there, with the same values.
        if BLOCK as f64 * region.step * mm > 4.0 * m.reach_out {
            s.fill_rows(region, 0..region.height, out);
            return Ok(());
        }
        let n = footprint_points(region.step);
        let origin = (region.x_at(0) * mm, region.y_at(0) * mm);
        // Footprint point offsets, as sample_footprint places them (mm).
        let mut offsets = [0.0f32; 4];
        let mut widen = 0.0;
        if n > 1 {
            for (a, o) in offsets.iter_mut().take(n).enumerate() {
                let px = ((a as f64 + 0.5) / n as f64 - 0.5) * region.step;
                *o = (px * mm) as f32;
                widen = f64::max(widen, px.abs() * mm);
            }
        }
        widen = widen * (1.0 + 1e-9) + 1e-12;
        let blocks_x = region.width.div_ceil(BLOCK);
        let blocks_y = region.height.div_ceil(BLOCK);
        let axis = |v: f64, i: usize| {
            let (hi, lo) = split(v);
            MillAxis {
                hi,
                lo,
                block: (i / BLOCK) as u32,
                pad: 0,
            }
        };
        let cols: Vec<MillAxis> = (0..region.width)
            .map(|c| axis(region.x_at(c) * mm - origin.0, c))
            .collect();
        let rows: Vec<MillAxis> = (0..region.height)
            .map(|r| axis(region.y_at(r) * mm - origin.1, r))
            .collect();
        let threads = default_threads().min(blocks_y).max(1);
        let per = blocks_y.div_ceil(threads);
        let parts: Vec<Lists> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..threads)
                .map(|t| {
                    let brows = (t * per).min(blocks_y)..((t + 1) * per).min(blocks_y);
                    scope.spawn(move || block_lists(s, region, brows, blocks_x, origin, widen))
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("ring-list workers do not panic"))
                .collect()
        });
        let mut lists = Lists {
            rings: Vec::new(),
            index: Vec::new(),
            blocks: Vec::with_capacity(blocks_x * blocks_y),
        };
        for part in parts {
            let (rb, ib) = (lists.rings.len() as u32, lists.index.len() as u32);
            lists.rings.extend_from_slice(&part.rings);
            lists.index.extend(part.index.iter().map(|k| k + rb));
            lists.blocks.extend(
                part.blocks
                    .iter()
                    .map(|&[start, count]| [start + ib, count]),
            );
        }
        let (s_in, s_out) = m.support2;
        let tol = 32.0 * f32::EPSILON as f64 * (m.reach_out + widen).max(m.r);
        let (adapt, adapt_scale, model_mean, target_mean) = match s.adaptation() {
            Some(a) => (
                1,
                (a.target_std_um / a.model_std_um) as f32,
                a.model_mean_um as f32,
                a.target_mean_um as f32,
            ),
            None => (0, 1.0, 0.0, 0.0),
        };
        let params = MillParams {
            width: region.width as u32,
            height: region.height as u32,
            blocks_x: blocks_x as u32,
            n: n as u32,
            shape: match m.shape {
                ShapeKind::Indicator => 0,
                ShapeKind::Cosine => 1,
                ShapeKind::Bump => 2,
            },
            interaction: match m.interaction {
                InteractionKind::Min => 0,
                InteractionKind::Latest => 1,
                InteractionKind::Convex => 2,
            },
            adapt,
            pad0: 0,
            r: m.r as f32,
            support_in: (s_in.sqrt() - tol).max(0.0).powi(2) as f32,
            support_out: (s_out.sqrt() + tol).powi(2) as f32,
            noise_scale: (m.noise_amplitude * crate::models::milling::ring::NOISE_UNIT) as f32,
            tol: tol as f32,
            adapt_scale,
            model_mean,
            target_mean,
            offsets,
        };
        if lists.rings.is_empty() {
            lists.rings.push(MillRing::default());
        }
        if lists.index.is_empty() {
            lists.index.push(0);
        }
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let uniform = uniform(device, &bytes(&[params]));
        let ring_buf = storage(device, "milling rings", &bytes(&lists.rings));
        let block_buf = storage(device, "milling block lists", &bytes(&lists.blocks));
        let index_buf = storage(device, "milling ring index", &bytes(&lists.index));
        let col_buf = storage(device, "milling columns", &bytes(&cols));
        let row_buf = storage(device, "milling rows", &bytes(&rows));
        let size = std::mem::size_of_val(out) as u64;
        let target = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("surftile milling fill"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("surftile milling fill"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                entry(0, &uniform),
                entry(1, &ring_buf),
                entry(2, &block_buf),
                entry(3, &index_buf),
                entry(4, &col_buf),
                entry(5, &row_buf),
                entry(6, &target),
                entry(7, &self.lut),
                entry(8, &self.noise),
            ],
        });
        dispatch_fill(
            (device, queue),
            &self.pipeline,
            &bind,
            region,
            &target,
            out,
            (scope, "filling a milling region"),
        )?;
        // The pixels at ring borders, in f64 on the host.
        let mut left = 0u64;
        for (r, row) in out.chunks_mut(region.width).enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                if v.is_nan() {
                    let mut one = [0.0f32];
                    s.sample_footprint(region.x_at(c), region.y_at(r), region.step, &mut one);
                    *v = one[0];
                    left += 1;
                }
            }
        }
        self.recomputed
            .fetch_add(left, std::sync::atomic::Ordering::Relaxed);
        Ok(())
    }
}

impl BandFill for GpuMilling {
    fn fill_band(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        region: &Region,
        out: &mut [f32],
    ) -> Result<()> {
        self.dispatch(device, queue, region, out)
    }

    fn cpu(&self) -> &dyn Surface {
        &self.surface
    }

    fn host_recomputed(&self) -> u64 {
        self.recomputed.load(std::sync::atomic::Ordering::Relaxed)
    }
}
