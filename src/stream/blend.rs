//! The variance-preserving triangle-grid blend rule over a bank of periodic Gaussian
//! patches (Heitz & Neyret, "High-Performance By-Example Noise using a
//! Histogram-Preserving Blending Operator", HPG 2018; Deliot & Heitz 2019), applied to
//! the RPN/ADSN banks of seed 000 §3.1.
//!
//! Space is covered by equilateral triangles of edge E. Each triangle vertex picks, by
//! hash, a patch and an offset; a sample blends the three patches of its triangle with
//! barycentric weights w and renormalises around the mean by √(Σw²), which keeps the
//! mean and variance of the Gaussian patches exactly. The result is mapped through the
//! stored T⁻¹ table back to the exemplar's height distribution.

use std::ops::Range;

use super::{Region, Surface, floor_split, in_range, mip_level};
use crate::bank::{Bank, Rule};
use crate::error::{Error, Result};
use crate::hash::{hash_vertex, pick_tile};

const SQRT3: f64 = 1.732_050_807_568_877_2;

/// A surface sampled from a blend bank ([`Rule::Blend`]) with a placement seed.
pub struct BlendSurface {
    pub(crate) seed: u32,
    pub(crate) channels: usize,
    pub(crate) tiles: u32,
    pub(crate) levels: Vec<Level>,
    pub(crate) edge: f64,
    // Skew to the square grid: s = (x/E − y/(√3·E), 2y/(√3·E)). ALGORITHMS.md §3 prints
    // this matrix transposed (a GLSL column-major listing read as rows), which gives a
    // non-equilateral grid; this is the equilateral one (Heitz & Neyret 2018, listing 1).
    pub(crate) skew_a: f64,
    pub(crate) skew_b: f64,
    pub(crate) skew_c: f64,
    pub(crate) offset_mask_x: i64,
    pub(crate) offset_mask_y: i64,
    /// 16 − log2 K when K is a power of two below 2¹⁶, else 0 (see [`Self::vertex`]).
    pub(crate) tile_shift: u32,
    pub(crate) lut_size: usize,
    /// `lut_size − 1` as f32: the last fractional table index.
    pub(crate) lut_last: f32,
    /// Table index of z = 0.
    pub(crate) lut_centre: f32,
}

pub(crate) struct Level {
    pub(crate) w: usize,
    pub(crate) wmask: i64,
    pub(crate) hmask: i64,
    /// 2^−L: level-0 pixels to level-L texels.
    pub(crate) scale: f64,
    /// (2^L − 1)/2: a level-L texel's centre in level-0 pixels, relative to its first pixel.
    pub(crate) centre: f64,
    pub(crate) tile_stride: usize,
    pub(crate) texels: Vec<f32>,
    pub(crate) mean: [f32; 4],
    /// 1/σ times the T⁻¹ table's entries per standard deviation: Gaussian value to
    /// table index, before the blend normalisation.
    pub(crate) lut_scale: [f32; 4],
    /// T⁻¹ per channel as (value, next value − value) pairs, the last pair's slope 0:
    /// one load and one multiply-add per lookup.
    pub(crate) lut: Vec<[f32; 2]>,
}

#[derive(Clone, Copy, Default)]
struct Vertex {
    tile: u32,
    ox: i64,
    oy: i64,
}

/// The hashed choices of the last triangle visited; reused while a row stays in it.
#[derive(Clone, Copy, Default)]
struct VertexCache {
    key: (i64, i64, bool),
    valid: bool,
    verts: [Vertex; 3],
}

impl BlendSurface {
    /// A surface over `bank` (which must use the blend rule), placed with `seed`.
    pub fn new(bank: &Bank, seed: u32) -> Result<BlendSurface> {
        let h = &bank.header;
        if h.rule() != Rule::Blend {
            return Err(Error::Unsupported(format!(
                "rule {:?} in a blend surface",
                h.rule()
            )));
        }
        bank.validate("given to BlendSurface")?;
        let c = h.channels;
        let levels = h
            .levels
            .iter()
            .enumerate()
            .map(|(l, info)| {
                let mut mean = [0.0f32; 4];
                let mut lut_scale = [0.0f32; 4];
                let per_sigma = (h.lut_size() - 1) as f64 / (2.0 * h.lut_z_range());
                for ch in 0..c {
                    mean[ch] = info.mean[ch] as f32;
                    lut_scale[ch] = if info.sigma[ch] > 1e-12 {
                        (per_sigma / info.sigma[ch]) as f32
                    } else {
                        0.0
                    };
                }
                let [w, ht] = info.size;
                Level {
                    w,
                    wmask: w as i64 - 1,
                    hmask: ht as i64 - 1,
                    scale: 0.5f64.powi(l as i32),
                    centre: ((1u64 << l) as f64 - 1.0) / 2.0,
                    tile_stride: w * ht * c,
                    texels: bank.texels[l].clone(),
                    mean,
                    lut_scale,
                    lut: bank.luts[l]
                        .chunks_exact(h.lut_size())
                        .flat_map(|table| {
                            (0..table.len()).map(|k| {
                                let next = table.get(k + 1).copied().unwrap_or(table[k]);
                                [table[k], next - table[k]]
                            })
                        })
                        .collect(),
                }
            })
            .collect();
        let e = h.triangle_edge();
        Ok(BlendSurface {
            seed,
            channels: c,
            tiles: h.tiles as u32,
            levels,
            edge: e,
            skew_a: 1.0 / e,
            skew_b: 1.0 / (SQRT3 * e),
            skew_c: 2.0 / (SQRT3 * e),
            offset_mask_x: h.tile_size[0] as i64 - 1,
            offset_mask_y: h.tile_size[1] as i64 - 1,
            tile_shift: if h.tiles.is_power_of_two() {
                16 - h.tiles.trailing_zeros()
            } else {
                0
            },
            lut_size: h.lut_size(),
            lut_last: (h.lut_size() - 1) as f32,
            lut_centre: (h.lut_size() - 1) as f32 / 2.0,
        })
    }

    /// Triangle edge length E in pixels.
    pub fn triangle_edge(&self) -> f64 {
        self.edge
    }

    /// The triangle that contains (x, y): skewed cell (i, j) and which half. Pixels with
    /// different ids lie in different triangles (used by seam scores). Points outside
    /// the coordinate range (±[`MAX_COORDINATE`](super::MAX_COORDINATE), NaN) share the id `(i64::MIN, i64::MIN,
    /// false)`.
    pub fn triangle_id(&self, x: f64, y: f64) -> (i64, i64, bool) {
        if !in_range(x, y) {
            return (i64::MIN, i64::MIN, false);
        }
        let (i, j, lower, _) = self.triangle(x, y);
        (i, j, lower)
    }

    /// Skewed cell, half (true = the one holding the cell's origin) and barycentric
    /// weights of the three vertices (ALGORITHMS.md §3). Only for points that passed
    /// [`in_range`].
    ///
    /// Which half a random point falls in is a coin flip, and the compiler turns these
    /// `if`s into a jump on it. That measured faster (about 1 ns per `height()`) than a
    /// branch-free form with fixed vertex slots and min/abs weights: a right guess lets
    /// all three vertex hashes start before the half is known.
    #[inline(always)]
    fn triangle(&self, x: f64, y: f64) -> (i64, i64, bool, [f32; 3]) {
        debug_assert!(in_range(x, y));
        let sy = y * self.skew_c;
        let sx = x * self.skew_a - y * self.skew_b;
        // SAFETY: |x|, |y| < 2⁵² (in_range) and E ≥ 1 (Bank::validate), so |sx|, |sy| < 2⁵⁴.
        let ((bx, fx), (by, fy)) = unsafe { (floor_split(sx), floor_split(sy)) };
        let z = 1.0 - fx - fy;
        let lower = z > 0.0;
        let w0 = if lower { z } else { -z };
        let w1 = if lower { fy } else { 1.0 - fy };
        let w2 = if lower { fx } else { 1.0 - fx };
        (bx, by, lower, [w0 as f32, w1 as f32, w2 as f32])
    }

    /// Hashed patch and offset of each vertex of a triangle.
    #[inline(always)]
    fn vertices(&self, i: i64, j: i64, lower: bool) -> [Vertex; 3] {
        // Lower half: (i, j), (i, j+1), (i+1, j); upper: (i+1, j+1), (i+1, j), (i, j+1).
        let u = (!lower) as i64;
        let pts = [
            (i.wrapping_add(u), j.wrapping_add(u)),
            (i.wrapping_add(u), j.wrapping_add(1 - u)),
            (i.wrapping_add(1 - u), j.wrapping_add(u)),
        ];
        // Three explicit calls: `[_; 3].map` went through `array::Drain` and cost a third
        // of a sample's instructions.
        [
            self.vertex(pts[0]),
            self.vertex(pts[1]),
            self.vertex(pts[2]),
        ]
    }

    /// Hashed tile and offset of the triangle-grid vertex (i, j).
    #[inline(always)]
    fn vertex(&self, (i, j): (i64, i64)) -> Vertex {
        let h = hash_vertex(self.seed, i, j);
        Vertex {
            // For K = 2ᵏ, pick_tile is a shift by 32 − k: the same tile, one cycle
            // sooner on the latency chain that ends in the texel loads.
            tile: if self.tile_shift != 0 {
                (h[0] >> 16) >> self.tile_shift
            } else {
                pick_tile(h[0], self.tiles)
            },
            ox: h[1] as i64 & self.offset_mask_x,
            oy: (h[1] >> 16) as i64 & self.offset_mask_y,
        }
    }

    /// The sample at (x, y) from level `l0` (blended toward `l0 + 1` by `t`).
    #[inline(always)]
    fn sample_cached<const C: usize>(
        &self,
        x: f64,
        y: f64,
        l0: usize,
        t: f32,
        cache: &mut VertexCache,
        out: &mut [f32],
    ) {
        if !in_range(x, y) {
            out[..C].fill(f32::NAN);
            return;
        }
        let (i, j, lower, w) = self.triangle(x, y);
        if !cache.valid || cache.key != (i, j, lower) {
            cache.verts = self.vertices(i, j, lower);
            cache.key = (i, j, lower);
            cache.valid = true;
        }
        self.blend_levels::<C>(x, y, l0, t, &cache.verts, &w, out);
    }

    /// Blend of the three vertices' patches at level `l`, mapped through T⁻¹.
    ///
    /// Variance-preserving blend (Heitz & Neyret 2018, eq. 4 with the mean restored):
    /// μ + Σ wₖ(Gₖ − μ)/√(Σ wₖ²). Written as one weighted sum of the twelve texels (three
    /// vertices × four bilinear corners) whose weights — corner × vertex weight ×
    /// 1/√(Σ wₖ²) × table scale — are known before the texels arrive, so the latency
    /// after the loads is one multiply and a four-deep addition tree, then the table.
    #[inline(always)]
    fn eval_level<const C: usize>(
        &self,
        l: usize,
        x: f64,
        y: f64,
        verts: &[Vertex; 3],
        w: &[f32; 3],
        out: &mut [f32; C],
    ) {
        let lv = &self.levels[l];
        // SAFETY: every caller checked (x, y) with in_range: |x|, |y| < 2⁵².
        let ((xi, fx), (yi, fy)) = unsafe { (floor_split(x), floor_split(y)) };
        let norm = 1.0 / (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
        let wsum = w[0] + w[1] + w[2];
        let mut g = [[0.0f32; C]; 3];
        for (k, v) in verts.iter().enumerate() {
            let (xr, yr) = (xi.wrapping_add(v.ox), yi.wrapping_add(v.oy));
            let (ix, iy, tx, ty) = if l == 0 {
                (xr, yr, fx as f32, fy as f32)
            } else {
                // Reduce modulo the level-0 period first so the f64 stays small and exact.
                let px = ((xr & self.offset_mask_x) as f64 + fx - lv.centre) * lv.scale;
                let py = ((yr & self.offset_mask_y) as f64 + fy - lv.centre) * lv.scale;
                // SAFETY: px, py lie within a tile (a few thousand texels at most).
                let ((ix, tx), (iy, ty)) = unsafe { (floor_split(px), floor_split(py)) };
                (ix, iy, tx as f32, ty as f32)
            };
            let wk = w[k] * norm;
            let corner = [
                (1.0 - tx) * (1.0 - ty) * wk,
                tx * (1.0 - ty) * wk,
                (1.0 - tx) * ty * wk,
                tx * ty * wk,
            ];
            g[k] = bilinear::<C>(lv, v.tile, ix, iy, &corner);
        }
        for c in 0..C {
            // t = (Σ wₖGₖ/√Σw² − μ·Σw/√Σw²)·scale + centre, the offset folded off the path.
            let offset = self.lut_centre - lv.mean[c] * wsum * norm * lv.lut_scale[c];
            let t = ((g[0][c] + g[1][c]) + g[2][c]) * lv.lut_scale[c] + offset;
            out[c] = self.lut_eval(&lv.lut, c, t);
        }
    }

    /// Linear interpolation in channel `c`'s T⁻¹ table at fractional index `t`, clamped to
    /// the table (NaN reads entry 0): the values of
    /// [`lut_at`](crate::analysis::gauss::lut_at) up to rounding, without its bounds
    /// checks and saturating conversions, which on the sample path cost as much as the
    /// blend itself.
    #[inline(always)]
    fn lut_eval(&self, lut: &[[f32; 2]], c: usize, t: f32) -> f32 {
        // `max` returns 0 for NaN; `lut_last` = n − 1 > 0.
        let t = t.max(0.0).min(self.lut_last);
        // SAFETY: t ∈ [0, n − 1] is finite and small, so the conversion is exact.
        let i = unsafe { t.to_int_unchecked::<u32>() } as usize;
        let f = t - i as f32;
        let at = c * self.lut_size + i;
        debug_assert!(at < lut.len());
        // SAFETY: i ≤ n − 1 and c < C ≤ channels, and Bank::validate checked that each
        // level holds channels × n entries, so at < lut.len().
        let [a, slope] = unsafe { *lut.get_unchecked(at) };
        a + slope * f
    }

    fn sample_c<const C: usize>(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        if !in_range(x, y) {
            out[..C].fill(f32::NAN);
            return;
        }
        let (l0, t) = mip_level(footprint, self.levels.len());
        let (i, j, lower, w) = self.triangle(x, y);
        let verts = self.vertices(i, j, lower);
        self.blend_levels::<C>(x, y, l0, t, &verts, &w, out);
    }

    /// Level `l0` blended toward `l0 + 1` by `t`, for a triangle already resolved.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn blend_levels<const C: usize>(
        &self,
        x: f64,
        y: f64,
        l0: usize,
        t: f32,
        verts: &[Vertex; 3],
        w: &[f32; 3],
        out: &mut [f32],
    ) {
        let mut a = [0.0f32; C];
        self.eval_level::<C>(l0, x, y, verts, w, &mut a);
        if t > 0.0 {
            let mut b = [0.0f32; C];
            self.eval_level::<C>(l0 + 1, x, y, verts, w, &mut b);
            for c in 0..C {
                a[c] += (b[c] - a[c]) * t;
            }
        }
        out[..C].copy_from_slice(&a);
    }

    fn fill_rows_c<const C: usize>(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        let (l0, t) = mip_level(region.step, self.levels.len());
        let mut cache = VertexCache::default();
        for (r, row) in rows.enumerate() {
            let y = region.y_at(row);
            let line = &mut out[r * region.width * C..(r + 1) * region.width * C];
            for (col, px) in line.chunks_exact_mut(C).enumerate() {
                self.sample_cached::<C>(region.x_at(col), y, l0, t, &mut cache, px);
            }
        }
    }
}

/// Σ corner weights × texels of tile `tile` around texel (ix, iy) (periodic wrap),
/// per channel: `corner` weighs (ix, iy), (ix+1, iy), (ix, iy+1), (ix+1, iy+1).
#[inline(always)]
fn bilinear<const C: usize>(
    lv: &Level,
    tile: u32,
    ix: i64,
    iy: i64,
    corner: &[f32; 4],
) -> [f32; C] {
    let (x0, x1) = (
        (ix & lv.wmask) as usize,
        (ix.wrapping_add(1) & lv.wmask) as usize,
    );
    let (y0, y1) = (
        (iy & lv.hmask) as usize,
        (iy.wrapping_add(1) & lv.hmask) as usize,
    );
    let base = tile as usize * lv.tile_stride;
    let (r0, r1) = (base + y0 * lv.w * C, base + y1 * lv.w * C);
    let t = &lv.texels;
    debug_assert!(r1.max(r0) + lv.w * C <= t.len() && (tile as usize) < t.len() / lv.tile_stride);
    let mut acc = [0.0f32; C];
    for (c, slot) in acc.iter_mut().enumerate() {
        // SAFETY: `tile` < K (pick_tile), x0, x1 ≤ w − 1 and y0, y1 ≤ h − 1 (masked),
        // c < C, and `Bank::validate` checked that each level holds exactly K·w·h·C
        // texels, so every index is below `t.len()`.
        let (a, b, d, e) = unsafe {
            (
                *t.get_unchecked(r0 + x0 * C + c),
                *t.get_unchecked(r0 + x1 * C + c),
                *t.get_unchecked(r1 + x0 * C + c),
                *t.get_unchecked(r1 + x1 * C + c),
            )
        };
        *slot = (a * corner[0] + b * corner[1]) + (d * corner[2] + e * corner[3]);
    }
    acc
}

impl Surface for BlendSurface {
    fn channels(&self) -> usize {
        self.channels
    }

    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        match self.channels {
            1 => self.sample_c::<1>(x, y, footprint, out),
            2 => self.sample_c::<2>(x, y, footprint, out),
            3 => self.sample_c::<3>(x, y, footprint, out),
            _ => self.sample_c::<4>(x, y, footprint, out),
        }
    }

    #[inline]
    fn height(&self, x: f64, y: f64) -> f32 {
        if self.channels != 1 {
            let mut buf = [0.0f32; 4];
            self.sample_footprint(x, y, 1.0, &mut buf[..self.channels]);
            return buf[0];
        }
        if !in_range(x, y) {
            return f32::NAN;
        }
        // The same arithmetic as `sample_c::<1>` at footprint 1 (level 0, no blend toward
        // level 1), with the level fixed at compile time.
        let (i, j, lower, w) = self.triangle(x, y);
        let verts = self.vertices(i, j, lower);
        let mut out = [0.0f32; 1];
        self.eval_level::<1>(0, x, y, &verts, &w, &mut out);
        out[0]
    }

    fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        match self.channels {
            1 => self.fill_rows_c::<1>(region, rows, out),
            2 => self.fill_rows_c::<2>(region, rows, out),
            3 => self.fill_rows_c::<3>(region, rows, out),
            _ => self.fill_rows_c::<4>(region, rows, out),
        }
    }
}
