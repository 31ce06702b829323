//! The runtime: the [`Surface`] trait, [`Region`]s, and parallel, split-invariant fills.
//!
//! Contracts every surface keeps (DESIGN.md, "Core contracts"):
//! - **constant time**: a sample costs the same at x = 1e12 as at x = 0;
//! - **determinism**: the value at (x, y) depends only on (bank or model, seed, x, y),
//!   so filling a region in pieces, in any order, on any number of threads gives the
//!   same bits;
//! - coordinates are surface pixels, within ±[`MAX_COORDINATE`]; outside it (and for
//!   NaN) samples are NaN, never a panic.

pub(crate) mod blend;
pub mod pages;
pub(crate) mod toroidal;

use std::ops::Range;

pub use blend::BlendSurface;
pub use pages::{Page, PageKey, PageStats, PageStreamer, View};
pub use toroidal::ToroidalSurface;

use crate::error::{Error, Result, short};

/// Largest coordinate magnitude a surface samples: 2⁵² pixels (4.5·10¹⁵). Beyond it an
/// f64 has no fractional part left, so neighbouring pixels could not be told apart;
/// samples there are NaN and regions are refused.
pub const MAX_COORDINATE: f64 = 4_503_599_627_370_496.0;

/// A rectangle of samples on a regular grid: pixel (col, row) of the region lies at
/// `(x + (col0 + col)·step, y + (row0 + row)·step)`.
///
/// The origin (x, y) and step are shared by every sub-region made with
/// [`Region::sub`], which only moves the integer offsets (col0, row0): a split region
/// computes exactly the coordinates of the whole, bit for bit, whatever the step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Region {
    /// Origin x, in surface pixels.
    pub x: f64,
    /// Origin y, in surface pixels.
    pub y: f64,
    /// Distance between neighbouring samples, in surface pixels (> 0). Above 1 the
    /// surface is read from prefiltered mip levels.
    pub step: f64,
    /// Column offset from the origin, in samples.
    pub col0: i64,
    /// Row offset from the origin, in samples.
    pub row0: i64,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
}

impl Region {
    /// A `width × height` region with its first sample at (x, y) and step 1.
    pub fn new(x: f64, y: f64, width: usize, height: usize) -> Region {
        Region {
            x,
            y,
            step: 1.0,
            col0: 0,
            row0: 0,
            width,
            height,
        }
    }

    /// The same region sampled every `step` pixels.
    pub fn with_step(mut self, step: f64) -> Region {
        self.step = step;
        self
    }

    /// Checks that the region can be filled: finite origin, positive finite step,
    /// non-zero size.
    pub fn validate(&self) -> Result<()> {
        let far = |v: f64| v.is_nan() || v.abs() >= MAX_COORDINATE;
        let (x1, y1) = (
            self.x_at(self.width.saturating_sub(1)),
            self.y_at(self.height.saturating_sub(1)),
        );
        if far(self.x) || far(self.y) || far(x1) || far(y1) {
            return Err(Error::param(
                "region",
                format!(
                    "from ({}, {}) to ({}, {})",
                    short(self.x),
                    short(self.y),
                    short(x1),
                    short(y1)
                ),
                "finite coordinates within ±2^52 pixels",
            ));
        }
        if !(self.step.is_finite() && self.step > 0.0) {
            return Err(Error::param(
                "step",
                self.step,
                "a positive number of pixels",
            ));
        }
        if self.width == 0 || self.height == 0 {
            return Err(Error::param(
                "region size",
                format!("{}×{}", self.width, self.height),
                "at least 1×1 samples",
            ));
        }
        Ok(())
    }

    /// The sub-rectangle of `width × height` samples starting at (col, row) of this one.
    pub fn sub(&self, col: usize, row: usize, width: usize, height: usize) -> Result<Region> {
        if col + width > self.width || row + height > self.height {
            return Err(Error::param(
                "sub-region",
                format!("{width}×{height} at ({col}, {row})"),
                format!("a rectangle inside {}×{}", self.width, self.height),
            ));
        }
        Ok(Region {
            col0: self.col0 + col as i64,
            row0: self.row0 + row as i64,
            width,
            height,
            ..*self
        })
    }

    /// x coordinate of column `col`.
    #[inline(always)]
    pub fn x_at(&self, col: usize) -> f64 {
        self.x + (self.col0 + col as i64) as f64 * self.step
    }

    /// y coordinate of row `row`.
    #[inline(always)]
    pub fn y_at(&self, row: usize) -> f64 {
        self.y + (self.row0 + row as i64) as f64 * self.step
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// True when the region has no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// ⌊x⌋ as an integer and x − ⌊x⌋, for finite x.
///
/// Equal to `(x.floor() as i64, x - x.floor())` wherever ⌊x⌋ fits in an i64 (beyond
/// 2⁵³ every f64 is an integer and the fraction is 0 either way).
///
/// Where the target has a floor instruction (SSE4.1's `roundsd`, which the repository's
/// `.cargo/config.toml` enables with x86-64-v2, or AArch64's `frintm`) it is one
/// instruction and a subtraction. Elsewhere — a crate that builds surftile for baseline
/// x86-64, where `f64::floor` is a libm call — it is [`floor_split_trunc`], with the same
/// bits (`floor_split_matches_its_truncating_twin` checks this).
///
/// # Safety
/// `x` must be finite with |x| < 2⁶³: the conversion skips the saturation and NaN
/// handling that `as` adds (five instructions per call on the sample path). Callers reach
/// it only with coordinates checked against [`MAX_COORDINATE`] by [`in_range`], scaled by
/// at most 2/(√3·E) with E ≥ 1, or with offsets reduced into a tile.
#[inline(always)]
pub(crate) unsafe fn floor_split(x: f64) -> (i64, f64) {
    debug_assert!(x.abs() < 9.2e18, "floor_split({x})");
    #[cfg(any(target_feature = "sse4.1", target_arch = "aarch64"))]
    {
        let f = x.floor();
        // SAFETY: the caller guarantees x is finite and inside the i64 range, and so is
        // its floor.
        (unsafe { f.to_int_unchecked::<i64>() }, x - f)
    }
    #[cfg(not(any(target_feature = "sse4.1", target_arch = "aarch64")))]
    {
        // SAFETY: as for this function.
        unsafe { floor_split_trunc(x) }
    }
}

/// [`floor_split`] from a truncating conversion, for targets without a floor
/// instruction. The correction is arithmetic, not a branch: for random coordinates its
/// sign is a coin flip, and each mispredicted branch flushes the overlap between
/// consecutive samples.
///
/// # Safety
/// As for [`floor_split`].
#[inline(always)]
#[cfg_attr(
    any(target_feature = "sse4.1", target_arch = "aarch64"),
    allow(dead_code)
)]
pub(crate) unsafe fn floor_split_trunc(x: f64) -> (i64, f64) {
    // SAFETY: the caller guarantees x is finite and inside the i64 range.
    let t = unsafe { x.to_int_unchecked::<i64>() };
    let i = t.wrapping_sub((t as f64 > x) as i64);
    // `+ 0.0` turns the −0 fraction of x = −0 into the +0 that x − ⌊x⌋ gives; it leaves
    // every other value as it is.
    (i, (x - i as f64) + 0.0)
}

/// True when (x, y) is inside the surface's coordinate range (NaN is not).
#[inline(always)]
pub(crate) fn in_range(x: f64, y: f64) -> bool {
    x.abs() < MAX_COORDINATE && y.abs() < MAX_COORDINATE
}

/// Level index and blend weight toward the next level for a footprint, over `levels`
/// mip levels (trilinear between the two levels that bracket log2(footprint)).
#[inline(always)]
pub(crate) fn mip_level(footprint: f64, levels: usize) -> (usize, f32) {
    let top = levels - 1;
    if footprint.is_nan() || footprint <= 1.0 || top == 0 {
        return (0, 0.0);
    }
    let lambda = footprint.log2().min(top as f64);
    let l0 = lambda.floor() as usize;
    if l0 >= top {
        (top, 0.0)
    } else {
        (l0, (lambda - l0 as f64) as f32)
    }
}

/// An infinite surface that can be sampled anywhere in constant time.
pub trait Surface: Send + Sync {
    /// Values per sample: 1 for heights, 3 for RGB.
    fn channels(&self) -> usize;

    /// Samples at (x, y) with a square footprint of `footprint` pixels (1 = full
    /// resolution, bilinear between texels; larger reads prefiltered levels). Writes
    /// `channels()` values to `out`.
    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]);

    /// Samples at (x, y) at full resolution.
    fn sample(&self, x: f64, y: f64, out: &mut [f32]) {
        self.sample_footprint(x, y, 1.0, out);
    }

    /// Channel 0 at (x, y), full resolution.
    fn height(&self, x: f64, y: f64) -> f32 {
        let mut buf = [0.0f32; 4];
        let c = self.channels().min(4);
        self.sample(x, y, &mut buf[..c]);
        buf[0]
    }

    /// The gradient (∂h/∂x, ∂h/∂y) of channel 0 at (x, y), in height units per surface
    /// pixel, where the model knows it in closed form (seed 001: normals "analytic where
    /// a model provides it"); shading then uses it instead of central differences. A
    /// surface answers `Some` everywhere or nowhere; the default is `None`.
    fn gradient(&self, _x: f64, _y: f64) -> Option<[f64; 2]> {
        None
    }

    /// Fills rows `rows` of `region` into `out` (those rows only, row-major,
    /// interleaved channels). The single-threaded kernel behind [`Surface::fill`];
    /// the default samples pixel by pixel with a footprint of `region.step`.
    fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        fill_rows_by_sample(self, region, rows, out);
    }

    /// Fills `region` into `out` (row-major, interleaved channels) on all cores.
    fn fill(&self, region: &Region, out: &mut [f32]) -> Result<()> {
        fill_parallel(self, region, out, default_threads())
    }
}

/// A surface's `SIZE²` sample at the origin (channel 0) and its height statistics:
/// what the viewer's grey ramp and shading scale, and an imperfection layer's depth
/// unit and slope scale, are measured on.
#[derive(Clone, Debug)]
pub struct OriginSample {
    /// The heights, row-major, `SIZE × SIZE`.
    pub heights: Vec<f32>,
    /// Mean height over the interior samples with finite central differences.
    pub mean: f64,
    /// Their standard deviation.
    pub sd: f64,
    /// Their rms slope (height units per pixel, central differences).
    pub rms_slope: f64,
    /// The least and greatest finite value of the sample over every channel (a colour
    /// source's levels: the viewer's colour scale).
    pub range: (f32, f32),
}

impl OriginSample {
    /// Side of the sample, in pixels.
    pub const SIZE: usize = 256;

    /// Fills and measures the sample of `s`.
    pub fn of<S: Surface + ?Sized>(s: &S) -> Result<OriginSample> {
        let n = Self::SIZE;
        let c = s.channels();
        let mut v = vec![0.0f32; n * n * c];
        s.fill(&Region::new(0.0, 0.0, n, n), &mut v)?;
        let range = v
            .iter()
            .filter(|x| x.is_finite())
            .fold((f32::MAX, f32::MIN), |(l, u), &x| (l.min(x), u.max(x)));
        let heights: Vec<f32> = v.iter().step_by(c).copied().collect();
        let h = |x: usize, y: usize| heights[y * n + x] as f64;
        let (mut sum, mut sq, mut slope2, mut count) = (0.0f64, 0.0f64, 0.0f64, 0usize);
        for y in 1..n - 1 {
            for x in 1..n - 1 {
                let z = h(x, y);
                let gx = 0.5 * (h(x + 1, y) - h(x - 1, y));
                let gy = 0.5 * (h(x, y + 1) - h(x, y - 1));
                if z.is_finite() && gx.is_finite() && gy.is_finite() {
                    sum += z;
                    sq += z * z;
                    slope2 += gx * gx + gy * gy;
                    count += 1;
                }
            }
        }
        let count = count.max(1) as f64;
        let mean = sum / count;
        Ok(OriginSample {
            mean,
            sd: (sq / count - mean * mean).max(0.0).sqrt(),
            rms_slope: (slope2 / count).sqrt(),
            range,
            heights,
        })
    }

    /// The factor that makes the rms slope 0.5 (1 for a flat or undefined one): the
    /// automatic exaggeration of shading and height scale of an imperfection layer.
    pub fn half_slope_scale(&self) -> f64 {
        if self.rms_slope > 0.0 && self.rms_slope.is_finite() {
            0.5 / self.rms_slope
        } else {
            1.0
        }
    }
}

/// Boxed and shared surfaces are surfaces (so wrappers such as
/// [`crate::imperfect::Imperfect`] take whatever `open` returns, or an `Arc` a viewer
/// also holds).
macro_rules! forward_surface {
    ($($ptr:ident),*) => {$(
        impl<S: Surface + ?Sized> Surface for $ptr<S> {
            fn channels(&self) -> usize {
                (**self).channels()
            }

            fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
                (**self).sample_footprint(x, y, footprint, out)
            }

            fn sample(&self, x: f64, y: f64, out: &mut [f32]) {
                (**self).sample(x, y, out)
            }

            fn height(&self, x: f64, y: f64) -> f32 {
                (**self).height(x, y)
            }

            fn gradient(&self, x: f64, y: f64) -> Option<[f64; 2]> {
                (**self).gradient(x, y)
            }

            fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
                (**self).fill_rows(region, rows, out)
            }

            fn fill(&self, region: &Region, out: &mut [f32]) -> Result<()> {
                (**self).fill(region, out)
            }
        }
    )*};
}

use std::sync::Arc;
forward_surface!(Box, Arc);

/// Rows `rows` of `region`, sample by sample with a footprint of `region.step`: the
/// default [`Surface::fill_rows`], and the fallback of surfaces with faster special cases.
pub fn fill_rows_by_sample<S: Surface + ?Sized>(
    surface: &S,
    region: &Region,
    rows: Range<usize>,
    out: &mut [f32],
) {
    let c = surface.channels();
    for (r, row) in rows.enumerate() {
        let y = region.y_at(row);
        for col in 0..region.width {
            let at = (r * region.width + col) * c;
            surface.sample_footprint(region.x_at(col), y, region.step, &mut out[at..at + c]);
        }
    }
}

/// Worker threads used by [`Surface::fill`]: the machine's available parallelism.
pub fn default_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Rows per work item of a parallel fill.
const BAND_ROWS: usize = 8;

/// Checks that `out` holds exactly `region`'s samples of `c` channels.
pub(crate) fn check_buffer(region: &Region, c: usize, out: &[f32]) -> Result<()> {
    let expected = region
        .len()
        .checked_mul(c)
        .ok_or_else(|| Error::Limits(format!("region {}×{}", region.width, region.height)))?;
    if out.len() != expected {
        return Err(Error::param(
            "output buffer length",
            out.len(),
            format!("{expected} = {}×{}×{c}", region.width, region.height),
        ));
    }
    Ok(())
}

/// Fills `region` on `threads` threads (crossbeam scoped workers taking bands of rows
/// from a shared counter). Each sample is computed independently, so the result is
/// the same bits for any thread count.
pub fn fill_parallel<S: Surface + ?Sized>(
    surface: &S,
    region: &Region,
    out: &mut [f32],
    threads: usize,
) -> Result<()> {
    region.validate()?;
    let c = surface.channels();
    check_buffer(region, c, out)?;
    for_bands(region, c, out, threads, BAND_ROWS, |rows, chunk| {
        surface.fill_rows(region, rows, chunk)
    })
}

/// Runs `f(rows, chunk)` over bands of `band_rows` rows of `region` (`out` holding
/// `c` channels per sample), on `threads` crossbeam workers taking bands from a shared
/// queue. Each band is written by exactly one call, so the result does not depend on
/// the thread count.
pub(crate) fn for_bands(
    region: &Region,
    c: usize,
    out: &mut [f32],
    threads: usize,
    band_rows: usize,
    f: impl Fn(Range<usize>, &mut [f32]) + Sync,
) -> Result<()> {
    let band_len = band_rows * region.width * c;
    let bands: Vec<(usize, &mut [f32])> = out.chunks_mut(band_len).enumerate().collect();
    let rows = |b: usize| b * band_rows..((b + 1) * band_rows).min(region.height);
    let threads = threads.clamp(1, bands.len().max(1));
    if threads == 1 {
        for (b, chunk) in bands {
            f(rows(b), chunk);
        }
        return Ok(());
    }
    let queue = crossbeam::queue::ArrayQueue::new(bands.len());
    for band in bands {
        // Capacity equals the number of bands, so this cannot fail.
        let _ = queue.push(band);
    }
    crossbeam::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|_| {
                while let Some((b, chunk)) = queue.pop() {
                    f(rows(b), chunk);
                }
            });
        }
    })
    .map_err(|_| Error::Unsupported("a fill worker thread panicked".into()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both floor paths against the plain definition, bit for bit, on integers, values
    /// just beside them, negative zero, halves, and magnitudes up to 2⁶².
    #[test]
    fn floor_split_matches_its_truncating_twin() {
        let mut xs = vec![0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 2.5, -2.5, 1e-300, -1e-300];
        for k in 0..63 {
            let p = (k as f64).exp2();
            for x in [p, p + 0.25, p - 0.25, p * 1.5] {
                xs.extend([
                    x,
                    -x,
                    x.next_up(),
                    x.next_down(),
                    -x.next_up(),
                    -x.next_down(),
                ]);
            }
        }
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        for _ in 0..10_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let u = (state >> 11) as f64 / (1u64 << 53) as f64;
            xs.push((u - 0.5) * 2.0 * (1u64 << (state % 60)) as f64);
        }
        for x in xs.into_iter().filter(|x: &f64| x.abs() < 4.6e18) {
            let want = (x.floor() as i64, (x - x.floor()).to_bits());
            // SAFETY: x is finite and below 2⁶² in magnitude.
            let (fast, slow) = unsafe { (floor_split(x), floor_split_trunc(x)) };
            assert_eq!((fast.0, fast.1.to_bits()), want, "floor_split({x:e})");
            assert_eq!((slow.0, slow.1.to_bits()), want, "floor_split_trunc({x:e})");
        }
    }
}
