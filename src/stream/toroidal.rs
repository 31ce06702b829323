//! The toroidal placement rule (roller banks, seed 003; DESIGN.md "Runtime placement
//! rules" 1): the plane is cut into the cells of a lattice in Hermite normal form —
//! rectangles of A × C pixels whose rows shift by B — and cell (i, j) shows tile
//! `hash(seed, i, j) mod K` ([`hash_tile`], reduced by [`pick_tile`]). All tiles share their borders, so any arrangement is
//! seamless, and an oblique lattice costs the same as a square one (ALGORITHMS.md §1).

use std::ops::Range;

use super::{Region, Surface, fill_rows_by_sample, floor_split, in_range, mip_level};
use crate::bank::{Bank, Record, Rule};
use crate::error::{Error, Result};
use crate::hash::{hash_tile, hash_tile_keyed, pick_tile, tile_key, wang_tile};
use crate::lattice::Lattice;

/// One mip level: the level lattice's HNF and the tiles stored on it.
pub(crate) struct Level {
    pub(crate) a: i64,
    pub(crate) b: i64,
    pub(crate) c: i64,
    pub(crate) inv_a: f64,
    pub(crate) inv_c: f64,
    /// Largest |j| for which j·B fits comfortably in an i64.
    pub(crate) j_safe: u64,
    /// 2^−L and the level-L texel centre in level-0 pixels ((2^L − 1)/2).
    pub(crate) scale: f64,
    pub(crate) centre: f64,
    pub(crate) tile_stride: usize,
    pub(crate) texels: Vec<f32>,
}

/// ⌊v / d⌋ and v mod d for d > 0, from a floating-point estimate (an integer division
/// costs more than the rest of a sample): `None` where the estimate's single correction
/// is not enough (callers then divide exactly, or take a slow path).
///
/// # Safety
/// |v| ≤ 2⁶² + 2⁵³, so that v/d converts to i64 without overflow (callers pass in-range
/// coordinates, or such a coordinate minus j·B with |j·B| ≤ 2⁶² by `j_safe`).
#[inline(always)]
unsafe fn div_floor_est(v: i64, d: i64, inv_d: f64) -> Option<(i64, i64)> {
    debug_assert!(
        v.unsigned_abs() <= (1 << 62) + (1 << 53),
        "div_floor_est({v})"
    );
    // SAFETY: the caller's bound and 0 < 1/d ≤ 1 keep v/d inside the i64 range.
    let mut q = unsafe { (v as f64 * inv_d).to_int_unchecked::<i64>() };
    let mut r = v.wrapping_sub(q.wrapping_mul(d));
    let neg = r >> 63;
    q += neg;
    r += neg & d;
    let over = (r >= d) as i64;
    q += over;
    r -= over * d;
    ((r as u64) < d as u64).then_some((q, r))
}

/// ⌊v / d⌋ and v mod d for d > 0, for any v: the estimate, or exact division.
#[inline(always)]
fn div_floor(v: i64, d: i64, inv_d: f64) -> (i64, i64) {
    let est = if v.unsigned_abs() < 1 << 62 {
        // SAFETY: |v| < 2⁶².
        unsafe { div_floor_est(v, d, inv_d) }
    } else {
        None
    };
    est.unwrap_or_else(|| (v.div_euclid(d), v.rem_euclid(d)))
}

impl Level {
    /// x undone by the row shift of cell row j (x − j·B), or `None` on far rows of a long,
    /// thin cell, where j·B would overflow. Rectangular cells (B = 0) return x without
    /// waiting for j, so the x and y arithmetic run side by side.
    #[inline(always)]
    fn unshift(&self, x: i64, j: i64) -> Option<i64> {
        if self.b == 0 {
            Some(x)
        } else if j.unsigned_abs() <= self.j_safe {
            Some(x - j * self.b)
        } else {
            None
        }
    }

    /// Cell (i, j) of integer texel (x, y) and its position (lx, ly) in the HNF tile.
    #[inline(always)]
    pub(crate) fn locate(&self, x: i64, y: i64) -> (i64, i64, i64, i64) {
        let (j, ly) = div_floor(y, self.c, self.inv_c);
        let Some(xs) = self.unshift(x, j) else {
            // The same cell exactly, in i128.
            let xs = x as i128 - j as i128 * self.b as i128;
            let i = xs.div_euclid(self.a as i128);
            return (i as i64, j, (xs - i * self.a as i128) as i64, ly);
        };
        let (i, lx) = div_floor(xs, self.a, self.inv_a);
        (i, j, lx, ly)
    }
}

/// The rhomboid cells of a reduced basis B = [u v] (u, v as columns, det B > 0): cell
/// (s, t) = ⌊B⁻¹·p⌋ = (⌊(v₂x − v₁y)/det⌋, ⌊(u₁y − u₂x)/det⌋), in exact integer
/// arithmetic, so that the CPU and the GPU (`shaders/toroidal.wgsl`) put every pixel,
/// border pixels included, in the same cell.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rhomboid {
    pub(crate) u: (i64, i64),
    pub(crate) v: (i64, i64),
    pub(crate) det: i64,
    inv_det: f64,
}

impl Rhomboid {
    /// The numerators (v₂x − v₁y, u₁y − u₂x) of pixel (x, y)'s rhomboid coordinates.
    #[inline(always)]
    pub(crate) fn numerators(&self, x: i64, y: i64) -> (i128, i128) {
        let (x, y) = (x as i128, y as i128);
        (
            self.v.1 as i128 * x - self.v.0 as i128 * y,
            self.u.0 as i128 * y - self.u.1 as i128 * x,
        )
    }

    /// The rhomboid cell (s, t) of pixel (x, y).
    #[inline(always)]
    pub(crate) fn cell(&self, x: i64, y: i64) -> (i64, i64) {
        let (ns, nt) = self.numerators(x, y);
        let q = |n: i128| match i64::try_from(n) {
            Ok(n) => div_floor(n, self.det, self.inv_det).0,
            Err(_) => n.div_euclid(self.det as i128) as i64,
        };
        (q(ns), q(nt))
    }
}

/// A surface sampled from a toroidal bank ([`Rule::Toroidal`]) with a placement seed.
pub struct ToroidalSurface {
    pub(crate) seed: u32,
    pub(crate) channels: usize,
    pub(crate) tiles: u32,
    pub(crate) levels: Vec<Level>,
    /// For several tiles on an oblique lattice: the reduced basis whose rhomboid cells
    /// ⌊B⁻¹·p⌋ are what the tiles were cut in.
    pub(crate) rhomboid: Option<Rhomboid>,
    /// For a Wang bank ([`Rule::Wang`]): K, the colours per edge direction; the cell
    /// shows [`wang_tile`] instead of a hashed pick.
    pub(crate) wang: Option<u32>,
    /// Neither Wang nor rhomboid: the HNF cell's hash picks the tile (the lean path).
    hashed_by_cell: bool,
    /// [`tile_key`] of the seed.
    key: u32,
}

impl ToroidalSurface {
    /// A surface over `bank` (which must use the toroidal or the Wang rule), placed with
    /// `seed`. A Wang bank is a square lattice whose cells pick their tile by edge colours.
    pub fn new(bank: &Bank, seed: u32) -> Result<ToroidalSurface> {
        let h = &bank.header;
        if !matches!(h.rule(), Rule::Toroidal | Rule::Wang) {
            return Err(Error::Unsupported(format!(
                "rule {} in a toroidal surface",
                h.rule()
            )));
        }
        bank.validate("given to ToroidalSurface")?;
        let levels: Vec<Level> = h
            .levels
            .iter()
            .enumerate()
            .map(|(l, info)| {
                let [a, c] = info.size;
                let b = info.shift.unwrap_or(0) as i64;
                Level {
                    a: a as i64,
                    b,
                    c: c as i64,
                    inv_a: 1.0 / a as f64,
                    inv_c: 1.0 / c as f64,
                    j_safe: (1u64 << 62) / (b.max(1) as u64),
                    scale: 0.5f64.powi(l as i32),
                    centre: ((1u64 << l) as f64 - 1.0) / 2.0,
                    tile_stride: a * c * h.channels,
                    texels: bank.texels[l].clone(),
                }
            })
            .collect();
        let wang = match h.record {
            Record::Wang { colours, .. } => Some(colours as u32),
            _ => None,
        };
        Ok(Self::from_levels(
            seed,
            h.channels,
            h.tiles as u32,
            levels,
            wang,
        ))
    }

    /// The surface over checked levels (level 0 first, at least one).
    fn from_levels(
        seed: u32,
        channels: usize,
        tiles: u32,
        levels: Vec<Level>,
        wang: Option<u32>,
    ) -> ToroidalSurface {
        // The tiles differ only inside their rhomboid {s·u + t·v : s, t ∈ [0, 1)} of the
        // reduced basis (outside it, in the cut band, they are identical). On a
        // rectangular lattice the rhomboids are the HNF cells (up to which side a
        // border pixel falls on, where the tiles agree); on an oblique one the HNF rows
        // cut through them, so the tile is chosen by rhomboid cell instead.
        let l0 = &levels[0];
        let rhomboid = (tiles > 1 && l0.b != 0 && wang.is_none()).then(|| {
            let [u, v] = Lattice {
                a: l0.a,
                b: l0.b,
                c: l0.c,
            }
            .reduced_basis();
            let det = u.0 * v.1 - u.1 * v.0;
            Rhomboid {
                u,
                v,
                det,
                inv_det: 1.0 / det as f64,
            }
        });
        ToroidalSurface {
            seed,
            channels,
            tiles,
            levels,
            hashed_by_cell: rhomboid.is_none() && wang.is_none(),
            key: tile_key(seed),
            rhomboid,
            wang,
        }
    }

    /// The lattice cell that pixel (x, y) lies in (for seam scores): the HNF cell
    /// `(i, j, false)`, or for several tiles on an oblique lattice the rhomboid cell
    /// `(s, t, true)` that chooses the tile. Points outside the coordinate range share
    /// the id `(i64::MIN, i64::MIN, false)`.
    pub fn cell_id(&self, x: f64, y: f64) -> (i64, i64, bool) {
        if !in_range(x, y) {
            return (i64::MIN, i64::MIN, false);
        }
        // SAFETY: in range, so |x|, |y| < 2⁵².
        let ((xi, _), (yi, _)) = unsafe { (floor_split(x), floor_split(y)) };
        match self.rhomboid_cell(xi, yi) {
            Some((s, t)) => (s, t, true),
            None => {
                let (i, j, _, _) = self.levels[0].locate(xi, yi);
                (i, j, false)
            }
        }
    }

    /// The rhomboid cell of level-0 position (x, y), where tiles are chosen by rhomboid.
    #[inline(always)]
    fn rhomboid_cell(&self, x: i64, y: i64) -> Option<(i64, i64)> {
        Some(self.rhomboid?.cell(x, y))
    }

    /// Tile shown at texel (x, y) of level `l` in HNF cell (i, j).
    #[inline(always)]
    fn tile_of(&self, l: usize, i: i64, j: i64, x: i64, y: i64) -> usize {
        if self.tiles == 1 {
            return 0;
        }
        if self.hashed_by_cell {
            return pick_tile(hash_tile_keyed(self.key, i, j), self.tiles) as usize;
        }
        self.tile_of_special(l, i, j, x, y)
    }

    /// [`Self::tile_of`] for Wang banks and rhomboid cells, kept out of line: inlined,
    /// its registers made every `height` call save and restore three more registers.
    #[inline(never)]
    fn tile_of_special(&self, l: usize, i: i64, j: i64, x: i64, y: i64) -> usize {
        if let Some(k) = self.wang {
            return wang_tile(self.seed, i, j, k) as usize;
        }
        let (i, j) = self.rhomboid_cell(x << l, y << l).unwrap_or((i, j));
        pick_tile(hash_tile(self.seed, i, j), self.tiles) as usize
    }

    /// Offset of texel (x, y) of level `lv` in its texel array.
    #[inline(always)]
    fn texel_at(&self, l: usize, x: i64, y: i64) -> usize {
        let lv = &self.levels[l];
        let (i, j, lx, ly) = lv.locate(x, y);
        self.tile_of(l, i, j, x, y) * lv.tile_stride + (ly * lv.a + lx) as usize * self.channels
    }

    /// Bilinear sample of level `l` at texel coordinates (px, py) (texel centres at
    /// integers), added to `out` with weight `w`.
    #[inline(always)]
    fn bilinear<const C: usize>(&self, l: usize, px: f64, py: f64, w: f32, out: &mut [f32; C]) {
        let lv = &self.levels[l];
        // SAFETY: callers pass coordinates checked by in_range, scaled by 2^−L ≤ 1.
        let ((xi, fx), (yi, fy)) = unsafe { (floor_split(px), floor_split(py)) };
        let (fx, fy) = (fx as f32, fy as f32);
        let (i, j, lx, ly) = lv.locate(xi, yi);
        let t = &lv.texels;
        let (p00, p10, p01, p11) = if lx + 1 < lv.a && ly + 1 < lv.c {
            // All four corners in one cell (all but a border row and column).
            let p = self.tile_of(l, i, j, xi, yi) * lv.tile_stride + (ly * lv.a + lx) as usize * C;
            let row = lv.a as usize * C;
            (p, p + C, p + row, p + row + C)
        } else {
            (
                self.texel_at(l, xi, yi),
                self.texel_at(l, xi + 1, yi),
                self.texel_at(l, xi, yi + 1),
                self.texel_at(l, xi + 1, yi + 1),
            )
        };
        debug_assert!(p11.max(p10).max(p01).max(p00) + C <= t.len());
        for (c, o) in out.iter_mut().enumerate() {
            // SAFETY: tile < K (pick_tile), 0 ≤ lx < A and 0 ≤ ly < C (locate), c < C =
            // channels, and Bank::validate checked K·A·C·channels texels per level.
            let (a, b, d, e) = unsafe {
                (
                    *t.get_unchecked(p00 + c),
                    *t.get_unchecked(p10 + c),
                    *t.get_unchecked(p01 + c),
                    *t.get_unchecked(p11 + c),
                )
            };
            let top = a + (b - a) * fx;
            let bottom = d + (e - d) * fx;
            *o += w * (top + (bottom - top) * fy);
        }
    }

    fn sample_c<const C: usize>(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        if !in_range(x, y) {
            out[..C].fill(f32::NAN);
            return;
        }
        let (l0, t) = mip_level(footprint, self.levels.len());
        // −0.0 + v = v for every v, so a weight of 1 returns the texel's exact bits.
        let mut acc = [-0.0f32; C];
        let at = |l: usize| {
            let lv = &self.levels[l];
            ((x - lv.centre) * lv.scale, (y - lv.centre) * lv.scale)
        };
        let (px, py) = at(l0);
        self.bilinear::<C>(l0, px, py, 1.0 - t, &mut acc);
        if t > 0.0 {
            let (px, py) = at(l0 + 1);
            self.bilinear::<C>(l0 + 1, px, py, t, &mut acc);
        }
        out[..C].copy_from_slice(&acc);
    }

    /// The one-channel, level-0 bilinear sample at (x, y) when its four texels lie
    /// inside one cell: the lean path of `height` (all but one row and one column of
    /// each tile; [`Self::height_slow`] takes the rest, and far rows of a sheared
    /// lattice).
    ///
    /// The cell comes from ⌊y/C⌋ and ⌊(x − j·B)/A⌋ estimated in floating point, without
    /// the exact division's corrections: a wrong estimate puts the texel offset outside
    /// [0, A − 1) or [0, C − 1), which the same unsigned compare that keeps the texel off
    /// the cell's last row and column rejects, so the answer is always the exact cell's.
    ///
    /// # Safety
    /// (x, y) is in range (|x|, |y| < 2⁵²), and the surface has one channel.
    #[inline(always)]
    unsafe fn bilinear_inside(&self, x: f64, y: f64) -> Option<f32> {
        // SAFETY: `new` builds at least one level (Bank::validate).
        let lv = unsafe { self.levels.get_unchecked(0) };
        let (xf, yf) = (x.floor(), y.floor());
        // SAFETY: |x|, |y| < 2⁵², so their floors and the quotients by A, C ≥ 1 (and by
        // A of x − j·B, |j·B| ≤ 2⁶² by `unshift`) fit in an i64.
        let (xi, yi, j) = unsafe {
            (
                xf.to_int_unchecked::<i64>(),
                yf.to_int_unchecked::<i64>(),
                (y * lv.inv_c).floor().to_int_unchecked::<i64>(),
            )
        };
        let ly = yi.wrapping_sub(j.wrapping_mul(lv.c));
        let xs = lv.unshift(xi, j)?;
        // SAFETY: as above.
        // ⌊x/A⌋ = ⌊⌊x⌋/A⌋: on rectangular lattices the estimate need not wait for ⌊x⌋.
        let xs_f = if lv.b == 0 { x } else { xs as f64 };
        let i = unsafe { (xs_f * lv.inv_a).floor().to_int_unchecked::<i64>() };
        let lx = xs.wrapping_sub(i.wrapping_mul(lv.a));
        if (lx as u64) >= (lv.a - 1) as u64 || (ly as u64) >= (lv.c - 1) as u64 {
            return None;
        }
        let (fx, fy) = ((x - xf) as f32, (y - yf) as f32);
        let p = self.tile_of(0, i, j, xi, yi) * lv.tile_stride + (ly * lv.a + lx) as usize;
        let row = lv.a as usize;
        let t = &lv.texels;
        debug_assert!(p + row + 1 < t.len());
        // SAFETY: one channel; tile < K (pick_tile), 0 ≤ lx < A − 1 and 0 ≤ ly < C − 1,
        // and Bank::validate checked K·A·C texels per level.
        let (a, b, d, e) = unsafe {
            (
                *t.get_unchecked(p),
                *t.get_unchecked(p + 1),
                *t.get_unchecked(p + row),
                *t.get_unchecked(p + row + 1),
            )
        };
        let top = a + (b - a) * fx;
        let bottom = d + (e - d) * fx;
        // −0.0 + v = v: the same bits as the general path's accumulator.
        Some(-0.0 + (top + (bottom - top) * fy))
    }

    /// `height` through the general sampler (cell borders, far rows, colour, NaN).
    #[cold]
    #[inline(never)]
    fn height_slow(&self, x: f64, y: f64) -> f32 {
        if self.channels != 1 || !in_range(x, y) {
            let mut buf = [0.0f32; 4];
            self.sample_footprint(x, y, 1.0, &mut buf[..self.channels]);
            return buf[0];
        }
        let mut acc = [-0.0f32; 1];
        self.bilinear::<1>(0, x, y, 1.0, &mut acc);
        acc[0]
    }

    /// Step-1 rows at integer coordinates: each row is a run of copies, one per cell.
    fn copy_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        let c = self.channels;
        let lv = &self.levels[0];
        let x0 = region.x_at(0) as i64;
        for (r, row) in rows.enumerate() {
            let y = region.y_at(row) as i64;
            let line = &mut out[r * region.width * c..(r + 1) * region.width * c];
            let (mut i, j, mut lx, ly) = lv.locate(x0, y);
            let row_base = (ly * lv.a) as usize * c;
            let mut done = 0;
            while done < region.width {
                let run = ((lv.a - lx) as usize).min(region.width - done);
                // Only reached without rhomboids (see `fill_rows`): the HNF cell decides
                // and the position is not looked at.
                let start =
                    self.tile_of(0, i, j, 0, 0) * lv.tile_stride + row_base + lx as usize * c;
                line[done * c..(done + run) * c]
                    .copy_from_slice(&lv.texels[start..start + run * c]);
                done += run;
                i += 1;
                lx = 0;
            }
        }
    }
}

impl Surface for ToroidalSurface {
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

    /// `#[inline]`: the lean path is short, and callers in other crates (the renderers
    /// that call this millions of times) can then interleave consecutive samples.
    #[inline]
    fn height(&self, x: f64, y: f64) -> f32 {
        if self.channels != 1 || !in_range(x, y) {
            return self.height_slow(x, y);
        }
        // SAFETY: in range, and one channel.
        unsafe { self.bilinear_inside(x, y) }.unwrap_or_else(|| self.height_slow(x, y))
    }

    fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        let (x0, y0) = (region.x_at(0), region.y_at(rows.start));
        let (x1, y1) = (
            region.x_at(region.width.saturating_sub(1)),
            region.y_at(rows.end.saturating_sub(1)),
        );
        if region.step == 1.0
            && x0.fract() == 0.0
            && y0.fract() == 0.0
            && in_range(x0, y0)
            && in_range(x1, y1)
        {
            // Integer samples at full resolution are stored texels: copy them, one run
            // per HNF cell. Several tiles on an oblique lattice change tile at rhomboid
            // borders, which cut across HNF rows: those are sampled one by one.
            if self.rhomboid.is_none() {
                return self.copy_rows(region, rows, out);
            }
        }
        fill_rows_by_sample(self, region, rows, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One level of `tiles` random tiles on the HNF lattice (A, B, C).
    fn random_level(a: i64, b: i64, c: i64, tiles: usize, seed: u32) -> Level {
        let n = (a * c) as usize;
        let texels = (0..tiles * n)
            .map(|k| (hash_tile(seed, k as i64, 0) >> 8) as f32 / 65_536.0 - 128.0)
            .collect();
        Level {
            a,
            b,
            c,
            inv_a: 1.0 / a as f64,
            inv_c: 1.0 / c as f64,
            j_safe: (1u64 << 62) / (b.max(1) as u64),
            scale: 1.0,
            centre: 0.0,
            tile_stride: n,
            texels,
        }
    }

    /// The lean `height` path (floating-point cell estimates, no corrections) returns
    /// the general sampler's bits everywhere: near 0, on cell borders, at 2⁴⁰ and near
    /// the coordinate limit, on rectangular and sheared lattices, with 1 and 3 tiles.
    #[test]
    fn lean_height_equals_the_general_sampler() {
        let edge = super::super::MAX_COORDINATE;
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for (a, b, c) in [
            (32, 0, 24),
            (40, 13, 29),
            (437, 0, 437),
            (7, 5, 3),
            (1086, 1000, 2),
        ] {
            for tiles in [1u32, 3] {
                let level = random_level(a, b, c, tiles as usize, a as u32);
                let s = ToroidalSurface::from_levels(5, 1, tiles, vec![level], None);
                let mut checked = 0;
                for centre in [
                    0.0,
                    -1e3,
                    1.1e12,
                    -((1u64 << 40) as f64),
                    edge - 3e4,
                    3e4 - edge,
                ] {
                    for k in 0..4000 {
                        let (x, y) = (centre + 2e4 * (next() - 0.5), centre + 2e4 * (next() - 0.5));
                        // Every tenth point on a texel corner, where cells meet.
                        let (x, y) = if k % 10 == 0 {
                            (x.floor(), y.floor())
                        } else {
                            (x, y)
                        };
                        let mut general = [0.0f32];
                        s.sample_footprint(x, y, 1.0, &mut general);
                        let lean = s.height(x, y);
                        assert_eq!(
                            lean.to_bits(),
                            general[0].to_bits(),
                            "({x}, {y}) on ({a}, {b}, {c}) with {tiles} tiles"
                        );
                        checked += lean.is_finite() as usize;
                    }
                }
                assert!(checked > 20_000, "{checked} finite samples");
            }
        }
    }

    #[test]
    fn div_floor_matches_euclid_everywhere() {
        let ds = [1i64, 3, 24, 29, 40, 1086, 65_536, 1 << 26];
        let vs = [
            0i64,
            1,
            -1,
            23,
            24,
            -24,
            -25,
            1 << 40,
            -(1 << 40) - 7,
            (1 << 52) - 1,
            -(1 << 52) + 1,
            (1 << 53) + 5,
            i64::MAX / 3,
            -i64::MAX / 3,
        ];
        for &d in &ds {
            for &v in &vs {
                for dv in -3..=3 {
                    let v = v.saturating_add(dv);
                    assert_eq!(
                        div_floor(v, d, 1.0 / d as f64),
                        (v.div_euclid(d), v.rem_euclid(d)),
                        "{v} / {d}"
                    );
                }
            }
        }
    }
}
