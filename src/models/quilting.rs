//! Image quilting made streamable: quilted tiles in a chessboard.
//!
//! Efros & Freeman's image quilting (SIGGRAPH 2001) copies square blocks of the
//! exemplar in raster order, each chosen so that its overlap with the blocks already
//! placed matches, and joins it to them along a minimum-error cut. It keeps objects
//! whole, but it is sequential. Here the plane is cut into `tile_px` cells in a
//! chessboard ("Quilted tiles" in `docs/structure.md`):
//! - a **free** cell (I + J even) is quilted alone over the cell grown by
//!   `overlap_px` on each side, from its own hashed stream;
//! - a **bound** cell (I + J odd) is quilted with the margins its four free neighbours
//!   grew into it as known pixels, so that its blocks match and cut against them.
//!
//! A pixel therefore depends on one tile, and a bound tile on its four free neighbours:
//! any region, in any split and on any thread count, is the same pixels of one infinite
//! texture. The output is the exemplar's value at each pixel's source, so heights stay
//! f32 in their units and colour stays exact.
//!
//! The search is not the paper's exhaustive one. Every block side's strip
//! (`block_px × overlap_px`) is projected on its leading principal directions (`dims`,
//! by subspace iteration; the projections of every exemplar position by FFT
//! correlation), and four k-d trees, one per side, give `candidates` near positions
//! for each side of a block whose overlap is known (a best-bin-first search that looks
//! at `search` points; 0: the exact nearest). Their exact SSD over the
//! known pixels, plus a footprint penalty, picks the block: within `tolerance` of the
//! least, at random. The penalty, `penalty` · (the mean count of the tile's earlier
//! blocks over the candidate's exemplar footprint) · a median SSD, keeps a tile from
//! growing as one crop of the exemplar (Efros & Freeman pick among the best matches at
//! random for the same reason).

use std::collections::HashMap;
use std::num::NonZeroUsize;
use std::sync::{Arc, Mutex};

use lru::LruCache;
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use crate::bank::{Bank, BankHeader, Record};
use crate::error::{Error, Result};
use crate::nn::{KdTree, sq_dist};
use crate::raster::Raster;
use crate::stream::{Region, Surface, fill_rows_by_sample, in_range, mip_level};

/// The parameters of quilted tiles.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QuiltingParams {
    /// Block side in pixels (at least 3 × the overlap, at most 256).
    pub block_px: usize,
    /// Overlap between neighbouring blocks, and the margin a free tile grows into its
    /// bound neighbours, in pixels (2 to 64).
    pub overlap_px: usize,
    /// Cell side of the chessboard in pixels (at least 2 blocks, at most 2048).
    pub tile_px: usize,
    /// Weight of the footprint penalty (0 to 100; 0: none).
    pub penalty: f32,
    /// Nearest positions taken per known block side (1 to 256).
    pub candidates: usize,
    /// Principal directions a strip is projected on (1 to 64).
    pub dims: usize,
    /// Blocks within this fraction of the least error are drawn from (0 to 1).
    pub tolerance: f32,
    /// Points a candidate search looks at per known block side (best bin first; 0:
    /// all, an exact search).
    #[serde(default)]
    pub search: usize,
}

impl Default for QuiltingParams {
    fn default() -> Self {
        QuiltingParams {
            block_px: 56,
            overlap_px: 14,
            tile_px: 224,
            penalty: 0.2,
            candidates: 16,
            dims: 24,
            tolerance: 0.1,
            search: 2048,
        }
    }
}

/// The λ ladder a bake tries, smallest first ([`choose_penalty`]).
pub const PENALTY_LADDER: [f32; 11] = [0.1, 0.15, 0.2, 0.3, 0.4, 0.6, 0.8, 1.2, 2.0, 3.0, 5.0];

/// The self-repetition a trial fill may show ([`choose_penalty`]) for its λ to be
/// taken: under the bar of 0.15 by a margin for the spread between seeds.
pub const PENALTY_TARGET: f64 = 0.12;

/// The share of a trial window's pixels that must continue one exemplar offset for
/// [`choose_penalty`] to count the window (and its repeat): 95%, so that copies a cut
/// crosses count too. On the same fills it reads above `stats`' self-repetition (by
/// 0.05–0.07 on four photos at λ = 0.1), where 99% reads about at it or under; a trial
/// at another seed than the render's reads under it by up to 0.1 more (eight photos
/// at 1024², `docs/structure.md`).
pub const TRIAL_PERCENT: usize = 95;

/// Side of the trial fills that choose λ.
pub const TRIAL_SIDE: usize = 1024;

impl QuiltingParams {
    /// Checks every parameter on its own.
    pub fn validate(&self) -> Result<()> {
        let o = self.overlap_px;
        if !(2..=64).contains(&o) {
            return Err(Error::param("overlap", o, "2 to 64 px"));
        }
        if self.block_px < 3 * o || self.block_px > 256 {
            return Err(Error::param(
                "block",
                self.block_px,
                format!("{} to 256 px (at least 3 × the overlap of {o} px)", 3 * o),
            ));
        }
        if self.tile_px < 2 * self.block_px || self.tile_px > 2048 {
            return Err(Error::param(
                "tile",
                self.tile_px,
                format!(
                    "{} to 2048 px (at least two blocks of {} px)",
                    2 * self.block_px,
                    self.block_px
                ),
            ));
        }
        if !(self.penalty.is_finite() && (0.0..=100.0).contains(&self.penalty)) {
            return Err(Error::param("penalty", self.penalty, "0 to 100"));
        }
        if !(1..=256).contains(&self.candidates) {
            return Err(Error::param(
                "candidates",
                self.candidates,
                "1 to 256 per block side",
            ));
        }
        if !(1..=64).contains(&self.dims) {
            return Err(Error::param("dims", self.dims, "1 to 64"));
        }
        if !(self.tolerance.is_finite() && (0.0..=1.0).contains(&self.tolerance)) {
            return Err(Error::param("tolerance", self.tolerance, "0 to 1"));
        }
        if self.search != 0 && !(self.candidates..=1 << 24).contains(&self.search) {
            return Err(Error::param(
                "search",
                self.search,
                format!(
                    "0 (exact) or {} (the candidates) to 2^24 points",
                    self.candidates
                ),
            ));
        }
        Ok(())
    }

    /// Checks that a `w × h` exemplar holds a block.
    pub fn check_exemplar(&self, w: usize, h: usize) -> Result<()> {
        let b = self.block_px;
        if w < b || h < b {
            return Err(Error::param(
                "exemplar",
                format!("{w}×{h}"),
                format!("at least one block of {b}×{b} px (or a smaller --block)"),
            ));
        }
        Ok(())
    }

    fn step(&self) -> usize {
        self.block_px - self.overlap_px
    }
}

/// The principal directions of one strip shape: the mean strip and `d` orthonormal
/// rows of `dim` values.
#[derive(Clone, Debug)]
struct Basis {
    rows: usize,
    cols: usize,
    mean: Vec<f32>,
    dirs: Vec<f32>,
    d: usize,
}

impl Basis {
    fn dim(&self) -> usize {
        self.mean.len()
    }

    /// The projection of a strip (`dim` values).
    fn project(&self, v: &[f32], out: &mut [f32]) {
        let dim = self.dim();
        for (k, o) in out.iter_mut().enumerate().take(self.d) {
            let row = &self.dirs[k * dim..(k + 1) * dim];
            let mut acc = [0.0f32; 8];
            let mut tail = 0.0;
            let (rc, vc, mc) = (
                row.chunks_exact(8),
                v.chunks_exact(8),
                self.mean.chunks_exact(8),
            );
            for ((a, b), m) in rc
                .remainder()
                .iter()
                .zip(vc.remainder())
                .zip(mc.remainder())
            {
                tail += a * (b - m);
            }
            for ((a, b), m) in rc.zip(vc).zip(mc) {
                for l in 0..8 {
                    acc[l] += a[l] * (b[l] - m[l]);
                }
            }
            *o = acc.iter().sum::<f32>() + tail;
        }
    }
}

/// A dot product in eight lanes, so that it vectorises (the order is fixed, so the
/// result is too).
fn dot8(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (ac, bc) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f32 = ac
        .remainder()
        .iter()
        .zip(bc.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ac.zip(bc) {
        for l in 0..8 {
            acc[l] += x[l] * y[l];
        }
    }
    acc.iter().sum::<f32>() + tail
}

/// Makes the `d` rows of `q` (`dim` values each) orthonormal in order (Gram–Schmidt);
/// a row that vanishes stays zero.
fn orthonormalise(q: &mut [f32], d: usize, dim: usize) {
    for k in 0..d {
        for j in 0..k {
            let (a, b) = q.split_at_mut(k * dim);
            let qj = &a[j * dim..(j + 1) * dim];
            let qk = &mut b[..dim];
            let p = dot8(qj, qk);
            for (y, x) in qk.iter_mut().zip(qj) {
                *y -= p * x;
            }
        }
        let qk = &mut q[k * dim..(k + 1) * dim];
        let n = dot8(qk, qk).sqrt();
        let inv = if n > 1e-20 { 1.0 / n } else { 0.0 };
        for y in qk.iter_mut() {
            *y *= inv;
        }
    }
}

/// Copies the `rows × cols` strip at (x, y) of a `w`-wide image of `c` channels.
fn strip(
    px: &[f32],
    w: usize,
    c: usize,
    (x, y): (usize, usize),
    (rows, cols): (usize, usize),
    out: &mut Vec<f32>,
) {
    out.clear();
    for r in 0..rows {
        let at = ((y + r) * w + x) * c;
        out.extend_from_slice(&px[at..at + cols * c]);
    }
}

/// The leading `d` principal directions of the exemplar's `rows × cols` strips, by
/// four rounds of subspace iteration on up to 2000 strips drawn from `rng`.
fn fit_basis(
    ex: &Raster,
    (rows, cols): (usize, usize),
    d: usize,
    rng: &mut Xoshiro256PlusPlus,
) -> Basis {
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    let dim = rows * cols * c;
    let positions = (h - rows + 1) * (w - cols + 1);
    let n = positions.min(2000);
    let d = d.min(dim).min(n);
    let mut x = Vec::with_capacity(n * dim);
    let mut v = Vec::new();
    for _ in 0..n {
        let y0 = rng.random_range(0..=h - rows);
        let x0 = rng.random_range(0..=w - cols);
        strip(&ex.data, w, c, (x0, y0), (rows, cols), &mut v);
        x.extend_from_slice(&v);
    }
    let mut mean = vec![0.0f64; dim];
    for r in x.chunks_exact(dim) {
        for (m, &a) in mean.iter_mut().zip(r) {
            *m += a as f64;
        }
    }
    let mean: Vec<f32> = mean.iter().map(|m| (m / n as f64) as f32).collect();
    for r in x.chunks_exact_mut(dim) {
        for (a, m) in r.iter_mut().zip(&mean) {
            *a -= m;
        }
    }
    let mut q: Vec<f32> = (0..d * dim)
        .map(|_| rng.random_range(-1.0f32..1.0))
        .collect();
    let mut y = vec![0.0f32; n * d];
    for _ in 0..4 {
        orthonormalise(&mut q, d, dim);
        for (i, r) in x.chunks_exact(dim).enumerate() {
            for k in 0..d {
                y[i * d + k] = dot8(r, &q[k * dim..(k + 1) * dim]);
            }
        }
        let mut z = vec![0.0f32; d * dim];
        for (i, r) in x.chunks_exact(dim).enumerate() {
            for k in 0..d {
                let s = y[i * d + k];
                for (a, b) in z[k * dim..(k + 1) * dim].iter_mut().zip(r) {
                    *a += s * b;
                }
            }
        }
        q = z;
    }
    orthonormalise(&mut q, d, dim);
    Basis {
        rows,
        cols,
        mean,
        dirs: q,
        d,
    }
}

/// The projections of every `rows × cols` strip position of the exemplar
/// (`(h − rows + 1) × (w − cols + 1)` positions, row-major, `d` values each), by FFT
/// correlation: each direction, split into its channel kernels, correlated with the
/// exemplar's channels on the exemplar's own size (valid positions never wrap), less
/// its dot with the mean. The same for any thread count.
fn project_all(ex: &Raster, basis: &Basis, threads: usize) -> Vec<f32> {
    use crate::fft::RealFft2;
    use rustfft::num_complex::Complex64;
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    let (rows, cols, d, dim) = (basis.rows, basis.cols, basis.d, basis.dim());
    let (ny, nx) = (h - rows + 1, w - cols + 1);
    let mut plan = RealFft2::new(w, h);
    let hw = plan.half_width();
    let spectra: Vec<Vec<Complex64>> = (0..c).map(|ch| plan.forward(&ex.channel_f64(ch))).collect();
    let ks: Vec<usize> = (0..d).collect();
    let planes = crate::nn::par_map_threads(&ks, threads, |&k| {
        let mut plan = RealFft2::new(w, h);
        let row = &basis.dirs[k * dim..(k + 1) * dim];
        let off = dot8(row, &basis.mean);
        let mut kern = vec![0.0f64; w * rows];
        let mut kf = vec![Complex64::default(); hw * h];
        let mut acc = vec![Complex64::default(); hw * h];
        for (ch, spec) in spectra.iter().enumerate() {
            for r in 0..rows {
                for cc in 0..cols {
                    kern[r * w + cc] = row[(r * cols + cc) * c + ch] as f64;
                }
            }
            plan.forward_top(&kern, rows, &mut kf);
            for ((a, s), kv) in acc.iter_mut().zip(spec).zip(&kf) {
                *a += s * kv.conj();
            }
        }
        let plane = plan.inverse(acc);
        let mut o = vec![0.0f32; ny * nx];
        for yy in 0..ny {
            for xx in 0..nx {
                o[yy * nx + xx] = plane[yy * w + xx] as f32 - off;
            }
        }
        o
    });
    let mut out = vec![0.0f32; ny * nx * d];
    for (k, o) in planes.iter().enumerate() {
        for (i, v) in o.iter().enumerate() {
            out[i * d + k] = *v;
        }
    }
    out
}

/// An exemplar made ready to quilt: its mips, the strip bases, one k-d tree per block
/// side over every block position, and the penalty's SSD scale. Everything follows
/// from the exemplar and the parameters, deterministically.
pub struct QuiltingModel {
    /// The parameters.
    pub params: QuiltingParams,
    /// Values per pixel.
    pub c: usize,
    /// The exemplar, then its 2 × 2 halvings.
    levels: Vec<MipLevel>,
    /// Block positions per column and row: (w − B + 1, h − B + 1).
    pw: usize,
    ph: usize,
    vert: Basis,
    horz: Basis,
    /// Left, right, top and bottom strips of every block position.
    trees: Vec<KdTree>,
    /// The median SSD of one side's overlap against a random position.
    medk: f32,
}

/// One level of the exemplar's mip chain.
struct MipLevel {
    w: usize,
    h: usize,
    data: Vec<f32>,
}

/// Sides of a block, in the order of [`QuiltingModel::trees`].
const LEFT: usize = 0;
const RIGHT: usize = 1;
const TOP: usize = 2;
const BOTTOM: usize = 3;

/// Checks `params` and that `exemplar` fits them: a block, 1 to 4 channels, at most
/// [`crate::models::rsgf::MAX_EXEMPLAR_PIXELS`] pixels, finite values.
pub fn check_input(exemplar: &Raster, params: &QuiltingParams) -> Result<()> {
    params.validate()?;
    let (w, h, c) = (exemplar.width, exemplar.height, exemplar.channels);
    params.check_exemplar(w, h)?;
    if !(1..=4).contains(&c) {
        return Err(Error::param("exemplar channels", c, "1 to 4"));
    }
    if w * h > crate::models::rsgf::MAX_EXEMPLAR_PIXELS {
        return Err(Error::param(
            "exemplar",
            format!("{w}×{h}"),
            format!(
                "at most {} pixels",
                crate::models::rsgf::MAX_EXEMPLAR_PIXELS
            ),
        ));
    }
    if let Some(i) = exemplar.data.iter().position(|v| !v.is_finite()) {
        return Err(Error::param(
            "exemplar",
            format!("a non-finite value at pixel {}", i / c),
            "finite values everywhere (fill or crop missing points first)",
        ));
    }
    Ok(())
}

impl QuiltingModel {
    /// Prepares `exemplar` (1 to 4 channels, finite) with `params`, on up to `threads`
    /// threads (the result does not depend on them).
    pub fn new(
        exemplar: &Raster,
        params: &QuiltingParams,
        threads: usize,
    ) -> Result<QuiltingModel> {
        check_input(exemplar, params)?;
        let (w, h, c) = (exemplar.width, exemplar.height, exemplar.channels);
        let (b, o, s) = (params.block_px, params.overlap_px, params.step());
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(0x5155_494c_5449_4e47);
        let vert = fit_basis(exemplar, (b, o), params.dims, &mut rng);
        let horz = fit_basis(exemplar, (o, b), params.dims, &mut rng);
        let vp = project_all(exemplar, &vert, threads);
        let hp = project_all(exemplar, &horz, threads);
        let (pw, ph) = (w - b + 1, h - b + 1);
        let (vnx, hnx) = (w - o + 1, w - b + 1);
        let (dv, dh) = (vert.d, horz.d);
        let mut feats: Vec<Vec<f32>> = vec![
            Vec::with_capacity(ph * pw * dv),
            Vec::with_capacity(ph * pw * dv),
            Vec::with_capacity(ph * pw * dh),
            Vec::with_capacity(ph * pw * dh),
        ];
        for y in 0..ph {
            for x in 0..pw {
                feats[LEFT].extend_from_slice(&vp[(y * vnx + x) * dv..][..dv]);
                feats[RIGHT].extend_from_slice(&vp[(y * vnx + x + s) * dv..][..dv]);
                feats[TOP].extend_from_slice(&hp[(y * hnx + x) * dh..][..dh]);
                feats[BOTTOM].extend_from_slice(&hp[((y + s) * hnx + x) * dh..][..dh]);
            }
        }
        let dims = [dv, dv, dh, dh];
        let sides: Vec<usize> = (0..4).collect();
        let trees =
            crate::nn::par_map_threads(&sides, threads, |&k| KdTree::new(&feats[k], dims[k]));
        // The penalty's scale: the median over 8 random left overlaps of their median
        // SSD against 1000 random positions.
        let px = &exemplar.data;
        let mut meds = Vec::with_capacity(8);
        for _ in 0..8 {
            let (ty, tx) = (rng.random_range(0..ph), rng.random_range(0..pw));
            let mut e: Vec<f32> = (0..1000)
                .map(|_| {
                    let (cy, cx) = (rng.random_range(0..ph), rng.random_range(0..pw));
                    let mut sum = 0.0;
                    for r in 0..b {
                        let ta = ((ty + r) * w + tx) * c;
                        let ca = ((cy + r) * w + cx) * c;
                        for (p, q) in px[ta..ta + o * c].iter().zip(&px[ca..ca + o * c]) {
                            sum += (p - q) * (p - q);
                        }
                    }
                    sum
                })
                .collect();
            e.sort_by(f32::total_cmp);
            meds.push(e[e.len() / 2]);
        }
        meds.sort_by(f32::total_cmp);
        Ok(QuiltingModel {
            params: params.clone(),
            c,
            levels: crate::models::rsgf::mip_chain(exemplar)
                .into_iter()
                .map(|l| MipLevel {
                    w: l.w,
                    h: l.h,
                    data: l.data,
                })
                .collect(),
            pw,
            ph,
            vert,
            horz,
            trees,
            medk: meds[meds.len() / 2],
        })
    }

    /// The same model with another λ (the bake's trials).
    pub fn with_penalty(mut self, penalty: f32) -> Result<QuiltingModel> {
        self.params.penalty = penalty;
        self.params.validate()?;
        Ok(self)
    }

    /// Exemplar width.
    pub fn width(&self) -> usize {
        self.levels[0].w
    }

    /// Exemplar height.
    pub fn height(&self) -> usize {
        self.levels[0].h
    }

    /// The stream of tile (i, j) (row i, column j) for `seed`.
    fn rng(seed: u32, i: i64, j: i64) -> Xoshiro256PlusPlus {
        let h = crate::hash::hash_cell(seed, j, i, 0x5155_494c);
        Xoshiro256PlusPlus::seed_from_u64(
            ((h[0] as u64) << 32 | h[1] as u64) ^ ((h[2] as u64) << 17),
        )
    }

    /// Whether cell (i, j) is free (quilted alone).
    pub fn is_free(i: i64, j: i64) -> bool {
        (i + j).rem_euclid(2) == 0
    }

    /// Side of a free tile's canvas: its cell grown by the overlap on each side.
    fn free_side(&self) -> usize {
        self.params.tile_px + 2 * self.params.overlap_px
    }

    /// The sources (exemplar pixel indices) of free tile (i, j): its cell grown by the
    /// overlap on each side, row-major.
    pub fn free_tile(&self, seed: u32, i: i64, j: i64) -> Vec<u32> {
        let l = self.free_side();
        let mut canvas = Canvas::new(l, self.c);
        self.quilt(&mut canvas, &mut Self::rng(seed, i, j));
        canvas.src
    }

    /// The sources of bound tile (i, j) (its cell, row-major), given its free
    /// neighbours' tiles `[above, below, left, right]`.
    pub fn bound_tile(&self, seed: u32, (i, j): (i64, i64), free: [&[u32]; 4]) -> Vec<u32> {
        let [up, down, left, right] = free;
        let (t, m) = (self.params.tile_px, self.params.overlap_px);
        let l = self.free_side();
        let mut canvas = Canvas::new(t, self.c);
        // A ring pixel's value from the free tile whose margin holds it; in a corner,
        // from the neighbour whose edge is nearer (the vertical one on the diagonal's
        // near side), so that no margin overwrites another along a straight line.
        for r in 0..t {
            for col in 0..t {
                let (top, bottom) = (r < m, r >= t - m);
                let (lft, rgt) = (col < m, col >= t - m);
                if !(top || bottom || lft || rgt) {
                    continue;
                }
                let a = if top { r } else { t - 1 - r };
                let bdist = if lft { col } else { t - 1 - col };
                let vertical = (top || bottom) && (!(lft || rgt) || a < bdist);
                // Local coordinates in the neighbour's canvas (its cell starts m in).
                let s = if vertical {
                    let (tile, y) = if top {
                        (up, t + m + r)
                    } else {
                        (down, r + m - t)
                    };
                    tile[y * l + col + m]
                } else {
                    let (tile, x) = if lft {
                        (left, t + m + col)
                    } else {
                        (right, col + m - t)
                    };
                    tile[(r + m) * l + x]
                };
                canvas.set(r * t + col, s, self.value(s));
            }
        }
        self.quilt(&mut canvas, &mut Self::rng(seed, i, j));
        canvas.src
    }

    /// The level-0 values of source `s`.
    #[inline]
    fn value(&self, s: u32) -> &[f32] {
        let c = self.c;
        &self.levels[0].data[s as usize * c..s as usize * c + c]
    }

    /// Writes the value of source `s` at mip `level` (nearest texel) to `out`.
    fn value_at_level(&self, s: u32, level: usize, out: &mut [f32]) {
        let c = self.c;
        let w = self.levels[0].w;
        let (sx, sy) = (s as usize % w, s as usize / w);
        let lv = &self.levels[level];
        let (x, y) = ((sx >> level).min(lv.w - 1), (sy >> level).min(lv.h - 1));
        out[..c].copy_from_slice(&lv.data[(y * lv.w + x) * c..][..c]);
    }

    /// Quilts `canvas` in raster order: each block's candidates from the trees of its
    /// known sides, the pick within the tolerance of the least error (SSD over known
    /// pixels plus the footprint penalty), cut along minimum-error paths on every fully
    /// known side.
    fn quilt(&self, cv: &mut Canvas, rng: &mut Xoshiro256PlusPlus) {
        let p = &self.params;
        let (b, o, c) = (p.block_px, p.overlap_px, self.c);
        let l = cv.side;
        let ew = self.levels[0].w;
        let ex = &self.levels[0].data;
        let mut placed: Vec<(usize, usize)> = Vec::new();
        let mut v = Vec::new();
        let mut f = vec![0.0f32; self.vert.d.max(self.horz.d)];
        let mut cands: Vec<u32> = Vec::new();
        let mut mask = vec![true; b * b];
        let mut runs: Vec<(usize, usize, usize, usize)> = Vec::new();
        let mut known_vals: Vec<f32> = Vec::new();
        let starts = block_starts(l, b, p.step());
        for &y0 in &starts {
            for &x0 in &starts {
                let kw = |r: usize, col: usize| cv.known[(y0 + r) * l + x0 + col];
                let side = [
                    (0..b).all(|r| (0..o).all(|col| kw(r, col))),
                    (0..b).all(|r| (b - o..b).all(|col| kw(r, col))),
                    (0..o).all(|r| (0..b).all(|col| kw(r, col))),
                    (b - o..b).all(|r| (0..b).all(|col| kw(r, col))),
                ];
                cands.clear();
                for (s, &on) in side.iter().enumerate() {
                    if !on {
                        continue;
                    }
                    let (ry, rx, basis) = match s {
                        LEFT => (0, 0, &self.vert),
                        RIGHT => (0, b - o, &self.vert),
                        TOP => (0, 0, &self.horz),
                        _ => (b - o, 0, &self.horz),
                    };
                    strip(
                        &cv.val,
                        l,
                        c,
                        (x0 + rx, y0 + ry),
                        (basis.rows, basis.cols),
                        &mut v,
                    );
                    basis.project(&v, &mut f);
                    let near = if p.search == 0 {
                        self.trees[s].nearest(&f[..basis.d], p.candidates, |_| true)
                    } else {
                        self.trees[s].nearest_within_budget(
                            &f[..basis.d],
                            p.candidates,
                            p.search,
                            |_| true,
                        )
                    };
                    cands.extend(near.iter().map(|&(_, id)| id));
                }
                cands.sort_unstable();
                cands.dedup();
                let (cy, cx) = if cands.is_empty() {
                    (rng.random_range(0..self.ph), rng.random_range(0..self.pw))
                } else {
                    // The known pixels in runs along the block's rows, their values
                    // gathered once: each candidate's SSD is then a few contiguous
                    // slices.
                    runs.clear();
                    known_vals.clear();
                    for r in 0..b {
                        let mut col = 0;
                        while col < b {
                            if !kw(r, col) {
                                col += 1;
                                continue;
                            }
                            let start = col;
                            while col < b && kw(r, col) {
                                col += 1;
                            }
                            let at = ((y0 + r) * l + x0 + start) * c;
                            runs.push((r, start, col, known_vals.len()));
                            known_vals.extend_from_slice(&cv.val[at..at + (col - start) * c]);
                        }
                    }
                    let nk = (known_vals.len() / c) as f32;
                    let scale = p.penalty * self.medk * nk / (b * o) as f32;
                    let errs: Vec<f32> = cands
                        .iter()
                        .map(|&id| {
                            let (cy, cx) = (id as usize / self.pw, id as usize % self.pw);
                            let mut e = 0.0f32;
                            for &(r, c0, c1, k) in &runs {
                                let at = ((cy + r) * ew + cx + c0) * c;
                                let n = (c1 - c0) * c;
                                e += sq_dist(&known_vals[k..k + n], &ex[at..at + n]);
                            }
                            let used: usize = placed
                                .iter()
                                .map(|&(py, px)| {
                                    b.saturating_sub(py.abs_diff(cy))
                                        * b.saturating_sub(px.abs_diff(cx))
                                })
                                .sum();
                            e + scale * used as f32 / (b * b) as f32
                        })
                        .collect();
                    let lo = errs.iter().copied().fold(f32::INFINITY, f32::min);
                    let ok: Vec<usize> = (0..errs.len())
                        .filter(|&k| errs[k] <= lo * (1.0 + p.tolerance) + 1e-9)
                        .collect();
                    let id = cands[ok[rng.random_range(0..ok.len())]] as usize;
                    (id / self.pw, id % self.pw)
                };
                let d = |r: usize, col: usize| -> f32 {
                    let a = &cv.val[((y0 + r) * l + x0 + col) * c..][..c];
                    let q = &ex[((cy + r) * ew + cx + col) * c..][..c];
                    a.iter().zip(q).map(|(u, w)| (u - w) * (u - w)).sum()
                };
                mask.fill(true);
                for (s, &on) in side.iter().enumerate() {
                    if !on {
                        continue;
                    }
                    // (i along the side, j across it from the known edge) → block (row, col)
                    let at = |i: usize, j: usize| match s {
                        LEFT => (i, j),
                        RIGHT => (i, b - 1 - j),
                        TOP => (j, i),
                        _ => (b - 1 - j, i),
                    };
                    let path = min_cut(b, o, |i, j| {
                        let (r, col) = at(i, j);
                        d(r, col)
                    });
                    for (i, &pj) in path.iter().enumerate() {
                        for j in 0..pj {
                            let (r, col) = at(i, j);
                            mask[r * b + col] = false;
                        }
                    }
                }
                for r in 0..b {
                    for col in 0..b {
                        let k = (y0 + r) * l + x0 + col;
                        if mask[r * b + col] || !cv.known[k] {
                            let s = ((cy + r) * ew + cx + col) as u32;
                            cv.set(k, s, &ex[s as usize * c..s as usize * c + c]);
                        }
                    }
                }
                placed.push((cy, cx));
            }
        }
    }
}

/// A square canvas being quilted: values, sources and which pixels are known.
struct Canvas {
    side: usize,
    c: usize,
    val: Vec<f32>,
    src: Vec<u32>,
    known: Vec<bool>,
}

impl Canvas {
    fn new(side: usize, c: usize) -> Canvas {
        Canvas {
            side,
            c,
            val: vec![0.0; side * side * c],
            src: vec![0; side * side],
            known: vec![false; side * side],
        }
    }

    #[inline]
    fn set(&mut self, k: usize, s: u32, v: &[f32]) {
        self.val[k * self.c..(k + 1) * self.c].copy_from_slice(v);
        self.src[k] = s;
        self.known[k] = true;
    }
}

/// Block starts along a canvas side of `l`: every `step`, and a last block flush with
/// the end.
fn block_starts(l: usize, b: usize, step: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (0..=l - b).step_by(step).collect();
    if v.last() != Some(&(l - b)) {
        v.push(l - b);
    }
    v
}

/// A minimum-error cut (Efros & Freeman 2001) along a strip `len` long and `width`
/// wide: `err(i, j)` with j = 0 on the known side. Returns, per i, the first j the new
/// block takes. Ties go to the smaller j, so the path is fixed by the errors.
fn min_cut(len: usize, width: usize, err: impl Fn(usize, usize) -> f32) -> Vec<usize> {
    let mut cost = vec![0.0f32; len * width];
    for i in 0..len {
        for j in 0..width {
            let prev = if i == 0 {
                0.0
            } else {
                let (lo, hi) = (j.saturating_sub(1), (j + 1).min(width - 1));
                (lo..=hi)
                    .map(|k| cost[(i - 1) * width + k])
                    .fold(f32::INFINITY, f32::min)
            };
            cost[i * width + j] = err(i, j) + prev;
        }
    }
    let argmin = |row: usize, lo: usize, hi: usize| {
        (lo..=hi)
            .min_by(|&a, &b| cost[row * width + a].total_cmp(&cost[row * width + b]))
            .unwrap_or(lo)
    };
    let mut path = vec![0usize; len];
    path[len - 1] = argmin(len - 1, 0, width - 1);
    for i in (0..len - 1).rev() {
        let x = path[i + 1];
        path[i] = argmin(i, x.saturating_sub(1), (x + 1).min(width - 1));
    }
    path
}

/// Tiles kept by default (a free tile of the default parameters holds 252² sources,
/// about 254 KB).
pub const DEFAULT_CACHE_TILES: usize = 256;

/// Cells a fill composes at once, per side: its tiles (with the free neighbours of its
/// bound cells) stay within (16 + 2)² tiles, about 80 MB at the defaults.
const CHUNK_CELLS: i64 = 16;

/// Tiles by cell (row, column): a free tile's grown canvas or a bound tile's cell, as
/// sources.
type TileCache = LruCache<(i64, i64), Arc<[u32]>>;

/// The lazy quilted surface: a [`QuiltingModel`], a seed, and an LRU of tiles.
pub struct QuiltingSurface {
    model: QuiltingModel,
    seed: u32,
    cache: Mutex<TileCache>,
}

impl QuiltingSurface {
    /// The quilted surface of `model`, placed with `seed`.
    pub fn new(model: QuiltingModel, seed: u32) -> QuiltingSurface {
        let cap = NonZeroUsize::new(DEFAULT_CACHE_TILES).unwrap_or(NonZeroUsize::MIN);
        QuiltingSurface {
            model,
            seed,
            cache: Mutex::new(LruCache::new(cap)),
        }
    }

    /// The surface a quilting bank describes, checked by [`check_bank`].
    pub fn from_bank(bank: &Bank, seed: u32) -> Result<QuiltingSurface> {
        let params = check_bank(bank, "quilting bank")?;
        let h = &bank.header;
        let [w, ht] = h.tile_size;
        let ex = Raster::from_vec(w, ht, h.channels, bank.texels[0].clone())?;
        let model = QuiltingModel::new(&ex, &params, crate::stream::default_threads())?;
        Ok(QuiltingSurface::new(model, seed))
    }

    /// The model behind the surface.
    pub fn model(&self) -> &QuiltingModel {
        &self.model
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, TileCache> {
        self.cache.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The tiles of cells `is × js` (rows, columns; inclusive), and of the free
    /// neighbours of their bound cells, computed on `threads` threads (free ones first,
    /// each once) or taken from the cache.
    fn tiles(
        &self,
        (i0, i1): (i64, i64),
        (j0, j1): (i64, i64),
        threads: usize,
    ) -> HashMap<(i64, i64), Arc<[u32]>> {
        let mut have: HashMap<(i64, i64), Arc<[u32]>> = HashMap::new();
        let mut free_todo = Vec::new();
        let mut bound_todo = Vec::new();
        {
            let mut cache = self.lock();
            let mut want = |i: i64,
                            j: i64,
                            have: &mut HashMap<(i64, i64), Arc<[u32]>>,
                            todo: &mut Vec<(i64, i64)>| {
                if have.contains_key(&(i, j)) || todo.contains(&(i, j)) {
                    return;
                }
                match cache.get(&(i, j)) {
                    Some(t) => {
                        have.insert((i, j), t.clone());
                    }
                    None => todo.push((i, j)),
                }
            };
            for i in i0..=i1 {
                for j in j0..=j1 {
                    if QuiltingModel::is_free(i, j) {
                        want(i, j, &mut have, &mut free_todo);
                    } else {
                        want(i, j, &mut have, &mut bound_todo);
                    }
                }
            }
            // Bound tiles to compute need their free neighbours.
            for &(i, j) in &bound_todo.clone() {
                for (a, b) in [(i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1)] {
                    want(a, b, &mut have, &mut free_todo);
                }
            }
        }
        let free = crate::nn::par_map_threads(&free_todo, threads, |&(i, j)| {
            Arc::<[u32]>::from(self.model.free_tile(self.seed, i, j))
        });
        for (&key, t) in free_todo.iter().zip(free) {
            have.insert(key, t);
        }
        let bound = crate::nn::par_map_threads(&bound_todo, threads, |&(i, j)| {
            let g = |a: i64, b: i64| have[&(a, b)].clone();
            let (up, down, left, right) = (g(i - 1, j), g(i + 1, j), g(i, j - 1), g(i, j + 1));
            Arc::<[u32]>::from(self.model.bound_tile(
                self.seed,
                (i, j),
                [&up, &down, &left, &right],
            ))
        });
        for (&key, t) in bound_todo.iter().zip(bound) {
            have.insert(key, t);
        }
        let mut cache = self.lock();
        for key in free_todo.iter().chain(&bound_todo) {
            cache.put(*key, have[key].clone());
        }
        have
    }

    /// The source of pixel (x, y) in the tiles `tiles`.
    #[inline]
    fn source(&self, tiles: &HashMap<(i64, i64), Arc<[u32]>>, x: i64, y: i64) -> u32 {
        let t = self.model.params.tile_px as i64;
        let (i, j) = (y.div_euclid(t), x.div_euclid(t));
        let (r, col) = ((y - i * t) as usize, (x - j * t) as usize);
        let tile = &tiles[&(i, j)];
        if QuiltingModel::is_free(i, j) {
            let m = self.model.params.overlap_px;
            tile[(r + m) * self.model.free_side() + col + m]
        } else {
            tile[r * t as usize + col]
        }
    }

    /// The sources of the `width × height` pixels from (x0, y0), row-major, on
    /// `threads` threads: chunks of at most 16 × 16 cells at a time.
    pub fn sources(
        &self,
        (x0, y0): (i64, i64),
        width: usize,
        height: usize,
        threads: usize,
    ) -> Result<Vec<u32>> {
        let mut out = vec![0u32; width * height];
        self.sources_into((x0, y0), width, height, threads, &mut |x, y, s| {
            out[(y * width) + x] = s;
        })?;
        Ok(out)
    }

    /// Calls `put(col, row, source)` for every pixel of the `width × height` region from
    /// (x0, y0), composing chunks of at most 16 × 16 cells at a time.
    fn sources_into(
        &self,
        (x0, y0): (i64, i64),
        width: usize,
        height: usize,
        threads: usize,
        put: &mut dyn FnMut(usize, usize, u32),
    ) -> Result<()> {
        let t = self.model.params.tile_px as i64;
        let (x1, y1) = (x0 + width as i64 - 1, y0 + height as i64 - 1);
        let (ci0, ci1) = (y0.div_euclid(t), y1.div_euclid(t));
        let (cj0, cj1) = (x0.div_euclid(t), x1.div_euclid(t));
        let cells = (ci1 - ci0 + 1) as u128 * (cj1 - cj0 + 1) as u128;
        if cells > 1 << 24 {
            return Err(Error::Limits(format!(
                "a quilting fill over {cells} tiles (at most 2^24)"
            )));
        }
        let mut i = ci0;
        while i <= ci1 {
            let ie = (i + CHUNK_CELLS - 1).min(ci1);
            let mut j = cj0;
            while j <= cj1 {
                let je = (j + CHUNK_CELLS - 1).min(cj1);
                let tiles = self.tiles((i, ie), (j, je), threads);
                let (ya, yb) = ((i * t).max(y0), ((ie + 1) * t - 1).min(y1));
                let (xa, xb) = ((j * t).max(x0), ((je + 1) * t - 1).min(x1));
                for y in ya..=yb {
                    for x in xa..=xb {
                        put(
                            (x - x0) as usize,
                            (y - y0) as usize,
                            self.source(&tiles, x, y),
                        );
                    }
                }
                j = je + 1;
            }
            i = ie + 1;
        }
        Ok(())
    }

    /// Fills an aligned region's rows from `sources_into`, on `threads` threads.
    fn fill_aligned(
        &self,
        (x0, y0): (i64, i64),
        region: &Region,
        out: &mut [f32],
        threads: usize,
    ) -> Result<()> {
        let c = self.model.c;
        let w = region.width;
        self.sources_into((x0, y0), w, region.height, threads, &mut |x, y, s| {
            let at = (y * w + x) * c;
            out[at..at + c].copy_from_slice(self.model.value(s));
        })
    }

    /// [`Surface::fill`] on `threads` threads: the same values for any count.
    pub fn fill_threads(&self, region: &Region, out: &mut [f32], threads: usize) -> Result<()> {
        let Some((x0, y0)) = Self::pixel_aligned(region) else {
            return crate::stream::fill_parallel(self, region, out, threads);
        };
        region.validate()?;
        crate::stream::check_buffer(region, self.model.c, out)?;
        self.fill_aligned((x0, y0), region, out, threads)
    }

    /// Keeps at most `tiles` tiles (≥ 1) instead of [`DEFAULT_CACHE_TILES`].
    pub fn with_cache_capacity(self, tiles: usize) -> QuiltingSurface {
        let cap = NonZeroUsize::new(tiles).unwrap_or(NonZeroUsize::MIN);
        QuiltingSurface {
            cache: Mutex::new(LruCache::new(cap)),
            ..self
        }
    }

    /// Whether `region` samples integer pixels at step 1, and its first pixel.
    fn pixel_aligned(region: &Region) -> Option<(i64, i64)> {
        let (x, y) = (region.x_at(0), region.y_at(0));
        (region.step == 1.0 && x.fract() == 0.0 && y.fract() == 0.0).then_some((x as i64, y as i64))
    }
}

impl Surface for QuiltingSurface {
    fn channels(&self) -> usize {
        self.model.c
    }

    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        let c = self.model.c;
        if !in_range(x, y) || out.len() < c {
            out.iter_mut().for_each(|v| *v = f32::NAN);
            return;
        }
        let (ix, iy) = (x.floor() as i64, y.floor() as i64);
        let (fx, fy) = ((x - ix as f64) as f32, (y - iy as f64) as f32);
        let t = self.model.params.tile_px as i64;
        let (i0, j0) = (iy.div_euclid(t), ix.div_euclid(t));
        let (level, lt) = mip_level(footprint, self.model.levels.len());
        if fx == 0.0 && fy == 0.0 && level == 0 && lt == 0.0 {
            // A pixel exactly: its value, as a fill gives it, from its own cell's tile.
            let tiles = self.tiles((i0, i0), (j0, j0), 1);
            let s = self.source(&tiles, ix, iy);
            out[..c].copy_from_slice(self.model.value(s));
            return;
        }
        let (i1, j1) = ((iy + 1).div_euclid(t), (ix + 1).div_euclid(t));
        let tiles = self.tiles((i0, i1), (j0, j1), 1);
        let mut v = [[0.0f32; 4]; 4];
        for (k, (dx, dy)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
            let s = self.source(&tiles, ix + dx, iy + dy);
            self.model.value_at_level(s, level, &mut v[k]);
            if lt > 0.0 {
                let mut b = [0.0f32; 4];
                self.model.value_at_level(s, level + 1, &mut b);
                for ch in 0..c {
                    v[k][ch] += lt * (b[ch] - v[k][ch]);
                }
            }
        }
        for ch in 0..c {
            let top = v[0][ch] + fx * (v[1][ch] - v[0][ch]);
            let bottom = v[2][ch] + fx * (v[3][ch] - v[2][ch]);
            out[ch] = top + fy * (bottom - top);
        }
    }

    fn fill_rows(&self, region: &Region, rows: std::ops::Range<usize>, out: &mut [f32]) {
        let Some((x0, y0)) = Self::pixel_aligned(region) else {
            return fill_rows_by_sample(self, region, rows, out);
        };
        if rows.is_empty() {
            return;
        }
        let sub = Region {
            row0: region.row0 + rows.start as i64,
            height: rows.len(),
            ..*region
        };
        let y = y0 + rows.start as i64;
        if self.fill_aligned((x0, y), &sub, out, 1).is_err() {
            out.iter_mut().for_each(|v| *v = f32::NAN);
        }
    }

    fn fill(&self, region: &Region, out: &mut [f32]) -> Result<()> {
        self.fill_threads(region, out, crate::stream::default_threads())
    }
}

/// Self-repetition estimated from a fill's sources: the fraction of 32 × 32 windows (on
/// a 32-px grid) at least 99% of whose pixels continue one exemplar offset, and whose
/// centre's exemplar pixel is shown again more than 32 px away (in x or y) at the centre
/// of a window that continues its own offset as much. Exact copies only, so it reads
/// under `stats`' self-repetition, which counts near-copies too.
pub fn exact_repetition(src: &[u32], side: usize, exemplar_width: usize) -> f64 {
    repetition_from_sources(src, side, exemplar_width, 99)
}

/// [`exact_repetition`] with windows that continue one offset over at least `percent`
/// of their pixels.
pub fn repetition_from_sources(
    src: &[u32],
    side: usize,
    exemplar_width: usize,
    percent: usize,
) -> f64 {
    const P: usize = 32;
    if side < P {
        return 0.0;
    }
    let ew = exemplar_width as i64;
    let coherent = |x0: usize, y0: usize, ey: i64, ex: i64| -> bool {
        let mut hit = 0;
        for y in y0..y0 + P {
            for x in x0..x0 + P {
                let e = src[y * side + x] as i64;
                hit += usize::from(e / ew == y as i64 + ey && e % ew == x as i64 + ex);
            }
        }
        hit * 100 >= P * P * percent
    };
    let mut shown: HashMap<u32, Vec<u32>> = HashMap::new();
    for (i, &e) in src.iter().enumerate() {
        shown.entry(e).or_default().push(i as u32);
    }
    let (mut n, mut rep) = (0usize, 0usize);
    for y0 in (0..=side - P).step_by(P) {
        for x0 in (0..=side - P).step_by(P) {
            n += 1;
            let (cy, cx) = (y0 + P / 2, x0 + P / 2);
            let e = src[cy * side + cx];
            let (ey, ex) = (e as i64 / ew - cy as i64, e as i64 % ew - cx as i64);
            if !coherent(x0, y0, ey, ex) {
                continue;
            }
            let found = shown[&e].iter().any(|&q| {
                let (qy, qx) = (q as usize / side, q as usize % side);
                if qy.abs_diff(cy) <= P && qx.abs_diff(cx) <= P {
                    return false;
                }
                if qy < P / 2 || qx < P / 2 || qy + P / 2 > side || qx + P / 2 > side {
                    return false;
                }
                let (fy, fx) = (e as i64 / ew - qy as i64, e as i64 % ew - qx as i64);
                coherent(qx - P / 2, qy - P / 2, fy, fx)
            });
            rep += usize::from(found);
        }
    }
    rep as f64 / n.max(1) as f64
}

/// The smallest λ of [`PENALTY_LADDER`] whose [`TRIAL_SIDE`]² trial fill (at the origin,
/// with a seed of its own) shows at most [`PENALTY_TARGET`] by
/// [`repetition_from_sources`] at [`TRIAL_PERCENT`],
/// found by bisection (the estimate falls with λ, not always strictly); the largest
/// rung where none does. Returns the model with it, and per trial (λ, estimate).
pub fn choose_penalty(
    model: QuiltingModel,
    threads: usize,
) -> Result<(QuiltingModel, Vec<(f32, f64)>)> {
    let (mut lo, mut hi) = (0usize, PENALTY_LADDER.len() - 1);
    let mut trials = Vec::new();
    let mut model = Some(model);
    let mut best = hi;
    while lo <= hi {
        let mid = (lo + hi) / 2;
        let penalty = PENALTY_LADDER[mid];
        let m = model.take().map(|m| m.with_penalty(penalty)).transpose()?;
        let surface = QuiltingSurface::new(
            m.ok_or_else(|| Error::Unsupported("no model".into()))?,
            0x7f4a_7c15,
        );
        let src = surface.sources((0, 0), TRIAL_SIDE, TRIAL_SIDE, threads)?;
        let est = repetition_from_sources(&src, TRIAL_SIDE, surface.model.width(), TRIAL_PERCENT);
        trials.push((penalty, est));
        model = Some(surface.model);
        if est <= PENALTY_TARGET {
            best = mid;
            if mid == 0 {
                break;
            }
            hi = mid - 1;
        } else {
            lo = mid + 1;
        }
    }
    let m = model.ok_or_else(|| Error::Unsupported("no model".into()))?;
    Ok((m.with_penalty(PENALTY_LADDER[best])?, trials))
}

/// The parameters of a quilting bank, checked: one tile (the exemplar) with its
/// halvings, valid parameters that fit it. `what` names the bank in errors.
pub fn check_bank(bank: &Bank, what: &str) -> Result<QuiltingParams> {
    let h = &bank.header;
    let bad = |m: String| Err(Error::bank(what, m));
    let Record::Quilting(section) = &h.record else {
        return bad(format!("a {} bank; expected the quilting rule", h.rule()));
    };
    bank.validate(what)?;
    let params: QuiltingParams = BankHeader::decode(section, "quilting", what)?;
    let [w, ht] = h.tile_size;
    params
        .validate()
        .and_then(|_| params.check_exemplar(w, ht))
        .map_err(|e| Error::bank(what, format!("parameters: {e}")))?;
    crate::models::rsgf::check_halvings(bank, what)?;
    Ok(params)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The minimum-error cut is the cheapest 8-connected path across the strip: checked
    /// against every path of small strips (brute force), on random errors.
    #[test]
    fn min_cut_is_the_cheapest_path() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(5);
        for (len, width) in [(1, 3), (4, 2), (5, 3), (6, 4)] {
            for _ in 0..20 {
                let e: Vec<f32> = (0..len * width)
                    .map(|_| rng.random_range(0.0..10.0))
                    .collect();
                let cost = |p: &[usize]| {
                    p.iter()
                        .enumerate()
                        .map(|(i, &j)| e[i * width + j])
                        .sum::<f32>()
                };
                let path = min_cut(len, width, |i, j| e[i * width + j]);
                assert!(
                    path.windows(2).all(|w| w[0].abs_diff(w[1]) <= 1),
                    "{path:?}: not connected"
                );
                // Every path: width^len sequences, the connected ones kept.
                let mut best = f32::INFINITY;
                for code in 0..width.pow(len as u32) {
                    let p: Vec<usize> = (0..len)
                        .map(|i| code / width.pow(i as u32) % width)
                        .collect();
                    if p.windows(2).all(|w| w[0].abs_diff(w[1]) <= 1) {
                        best = best.min(cost(&p));
                    }
                }
                assert!(
                    (cost(&path) - best).abs() <= 1e-4,
                    "{len}×{width}: {} against {best}",
                    cost(&path)
                );
            }
        }
    }

    /// The FFT projections equal direct dot products of the strips with the basis.
    #[test]
    fn fft_projections_equal_direct_ones() {
        let (w, h, c) = (37, 29, 2);
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(9);
        let data: Vec<f32> = (0..w * h * c).map(|_| rng.random_range(0.0..1.0)).collect();
        let ex = Raster::from_vec(w, h, c, data).unwrap();
        for shape in [(12, 4), (4, 12)] {
            let basis = fit_basis(&ex, shape, 5, &mut rng);
            let got = project_all(&ex, &basis, 2);
            let (ny, nx) = (h - shape.0 + 1, w - shape.1 + 1);
            let mut v = Vec::new();
            let mut want = vec![0.0f32; basis.d];
            for y in 0..ny {
                for x in 0..nx {
                    strip(&ex.data, w, c, (x, y), shape, &mut v);
                    basis.project(&v, &mut want);
                    for k in 0..basis.d {
                        let g = got[(y * nx + x) * basis.d + k];
                        assert!(
                            (g - want[k]).abs() < 1e-4,
                            "{shape:?} at ({x}, {y}), {k}: {g} against {}",
                            want[k]
                        );
                    }
                }
            }
        }
    }

    /// The basis is orthonormal.
    #[test]
    fn basis_rows_are_orthonormal() {
        let (w, h) = (40, 40);
        let data: Vec<f32> = (0..w * h)
            .map(|i| ((i % 7) as f32 * 0.3).sin() + (i / 13) as f32 * 0.01)
            .collect();
        let ex = Raster::from_vec(w, h, 1, data).unwrap();
        let b = fit_basis(&ex, (10, 3), 6, &mut Xoshiro256PlusPlus::seed_from_u64(1));
        let dim = b.dim();
        for i in 0..b.d {
            for j in 0..b.d {
                let d = dot8(
                    &b.dirs[i * dim..(i + 1) * dim],
                    &b.dirs[j * dim..(j + 1) * dim],
                );
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((d - want).abs() < 1e-4, "({i}, {j}): {d}");
            }
        }
    }

    /// Known answers: a source map that tiles the exemplar repeats everywhere; one that
    /// shows each exemplar pixel once repeats nowhere; one of scattered pixels is not
    /// coherent anywhere.
    #[test]
    fn exact_repetition_known_answers() {
        let side = 256;
        let ew = 64;
        let tiled: Vec<u32> = (0..side * side)
            .map(|i| ((i / side % ew) * ew + i % side % ew) as u32)
            .collect();
        assert_eq!(exact_repetition(&tiled, side, ew), 1.0);
        let once: Vec<u32> = (0..(side * side) as u32).collect();
        assert_eq!(exact_repetition(&once, side, side), 0.0);
        let scattered: Vec<u32> = (0..side * side)
            .map(|i| ((i * 7919) % 4096) as u32)
            .collect();
        assert_eq!(exact_repetition(&scattered, side, ew), 0.0);
    }
}
