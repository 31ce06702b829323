//! Gap filling (seed 002 §4.2): the neighbours' border composed from wedges, matched
//! against lattice-similar positions within a tolerance, by squared differences
//! (eq. 10) or by the generalized NCC (eqs. 3–8) with the hole left out.
//!
//! **Both measures, fast.** Over the ring R (the E × E patch less its inner
//! (B − 2o)² square, where the neighbours overlap it),
//!
//!   χ(q) = Σ_R f(q + x)² − 2·Σ_R f(q + x)·g(x) + Σ_R g²,
//!
//! and the NCC needs Σ_R f, Σ_R f², Σ_R g, Σ_R g² and the same cross term. The sums of f
//! depend on q only: two rectangle sums of integral images per position, tabulated when
//! the model is built. The last term is the same for every q. Only the cross term
//! depends on the gap; it comes either directly (a dot product over the ring per
//! candidate) or, when the candidates are many (the stochastic mode, where every
//! position is one), for all positions at once by one FFT correlation of the exemplar
//! with the border — whichever costs less for the candidate count, a choice that depends
//! on the model and the block only, so every fill makes the same one.
//!
//! Ties go to the smallest position index (row, then column).
//!
//! **The correlation's FFTs** are real ([`RealFft2`]), on the exemplar padded with zeros
//! to sizes with no prime factor above 5 ([`fft_size`]); padding does not change a
//! correlation at the valid positions, only which FFT algorithms run. With several
//! channels kept apart (NCC), the direct dot products run per channel on planar copies.
//! Both round differently from the complex, unpadded FFTs and the interleaved sums
//! they replaced, so a near-tie could in principle go the other way; on five photos
//! no pick moved (their 1024² renders far from the origin are bit-identical to those
//! before, 2026-11-27), and `tests::fft_and_direct_cross_terms_agree` bounds the two
//! paths' difference.
//!
//! **Large exemplars, coarse to fine.** With every position a candidate (stochastic
//! mode), the FFT correlation costs O(W·H·log) per gap: 0.15 s on a 1024² RGB photo
//! (complex FFTs, before they were real).
//! Above [`COARSE_ABOVE`] pixels the search runs first on the exemplar box-filtered by
//! a power of two s (to at most 256² pixels), with the block, border and the gap's
//! border scaled alike; the [`COARSE_KEEP`] best coarse positions then have every fine
//! position within ±s of their own scored exactly, and the best of those wins. So the
//! pick is the exact best of a neighbourhood of the coarse winners, not of the whole
//! exemplar.

use std::sync::Mutex;

use rustfft::num_complex::Complex64;

use super::model::RsgfModel;
use super::{Metric, RsgfParams};
use crate::analysis::ncc::{FLAT, integral};
use crate::fft::RealFft2;
use crate::raster::Raster;

/// Exemplars above this many pixels search many-candidate gaps coarse to fine.
pub const COARSE_ABOVE: usize = 256 * 256;
/// Coarse positions whose fine neighbourhoods are scored exactly.
pub const COARSE_KEEP: usize = 8;

/// The coarse search of a large exemplar: its tables at 1/s.
struct Coarse {
    s: usize,
    tables: GapTables,
}

/// Per-exemplar tables of the gap search.
pub(crate) struct GapTables {
    /// Tables of the exemplar at 1/s, above [`COARSE_ABOVE`] pixels.
    coarse: Option<Box<Coarse>>,
    w: usize,
    h: usize,
    c: usize,
    ext: usize,
    block: usize,
    nx: usize,
    metric: Metric,
    /// Level 0 with each channel's mean removed, f64, interleaved.
    centred: Vec<f64>,
    /// The same per channel (planes of W × H), where the cross term is kept per
    /// channel (NCC of several channels); empty otherwise.
    planar: Vec<Vec<f64>>,
    /// Variance of each channel (for the flatness test of the NCC).
    var: Vec<f64>,
    /// The ring as row segments (y, x0, x1) of the patch, and its pixel count N.
    ring: Vec<(usize, usize, usize)>,
    ring_px: usize,
    /// Per position and channel: Σ_R f.
    sum_f: Vec<f64>,
    /// Per position and channel: √(N·Σ_R f² − (Σ_R f)²), the NCC's spread of f, or −1
    /// where the patch is flat (at most [`FLAT`]·N²·var): a pure function of the
    /// position, so tabulated rather than taken again for every gap.
    spread_f: Vec<f64>,
    /// Per position: Σ_c Σ_R f².
    ssd_base: Vec<f64>,
    /// Side of the correlation's FFTs: W × H padded with zeros to sizes whose only
    /// prime factors are 2, 3 and 5 ([`fft_size`]).
    fw: usize,
    fh: usize,
    /// Half spectrum ([`RealFft2`]) of each centred channel, padded to fw × fh.
    spectra: Vec<Vec<Complex64>>,
    /// Plans and buffers of the correlation, one per thread that has used one.
    scratch: Mutex<Vec<CrossScratch>>,
}

/// What one FFT correlation works in, kept between gaps: a plan, and buffers that
/// would otherwise be allocated and zeroed for every gap.
struct CrossScratch {
    plan: RealFft2,
    /// The border's rows (ext × fw), zero right of the border.
    plane: Vec<f64>,
    /// The border's half spectrum, and the sum of products over channels.
    spectrum: Vec<Complex64>,
    acc: Vec<Complex64>,
    /// The correlation's rows of valid positions (ny × fw), per cross channel.
    maps: Vec<Vec<f64>>,
}

/// The smallest even size ≥ n whose only prime factors are 2, 3 and 5: a correlation
/// padded with zeros to it is the same correlation, and its FFT avoids the slow paths
/// of large prime factors (the 144-px crack photo with its 10-px mirrored border is 164
/// = 4 · 41 a side, whose FFTs went through Rader's algorithm).
pub(crate) fn fft_size(n: usize) -> usize {
    let smooth = |mut m: usize| {
        for p in [2, 3, 5] {
            while m.is_multiple_of(p) {
                m /= p;
            }
        }
        m == 1
    };
    let mut m = n.max(2);
    while !m.is_multiple_of(2) || !smooth(m) {
        m += 1;
    }
    m
}

impl GapTables {
    pub(crate) fn new(ex: &Raster, params: &RsgfParams) -> GapTables {
        let (w, h, c) = (ex.width, ex.height, ex.channels);
        let (block, o2) = (params.block_px, 2 * params.border_px);
        let ext = block + o2;
        let (nx, ny) = (w + 1 - ext, h + 1 - ext);
        let mut centred = vec![0.0f64; w * h * c];
        let mut var = vec![0.0f64; c];
        for ch in 0..c {
            let mean = (0..w * h).map(|i| ex.data[i * c + ch] as f64).sum::<f64>() / (w * h) as f64;
            for i in 0..w * h {
                let v = ex.data[i * c + ch] as f64 - mean;
                centred[i * c + ch] = v;
                var[ch] += v * v;
            }
            var[ch] /= (w * h) as f64;
        }
        let ring: Vec<(usize, usize, usize)> = (0..ext)
            .flat_map(|y| {
                if y < o2 || y >= ext - o2 {
                    vec![(y, 0, ext)]
                } else {
                    vec![(y, 0, o2), (y, ext - o2, ext)]
                }
            })
            .collect();
        let ring_px = ring.iter().map(|&(_, a, b)| b - a).sum();
        let mut sum_f = vec![0.0; nx * ny * c];
        let mut spread_f = vec![0.0; nx * ny * c];
        let mut ssd_base = vec![0.0; nx * ny];
        let inner = block - o2;
        let n = ring_px as f64;
        let mut spectra = Vec::with_capacity(c);
        let (fw, fh) = (fft_size(w), fft_size(h));
        let mut plan = RealFft2::new(fw, fh);
        let planes: Vec<Vec<f64>> = (0..c)
            .map(|ch| (0..w * h).map(|i| centred[i * c + ch]).collect())
            .collect();
        for (ch, plane) in planes.iter().enumerate() {
            let t1 = integral(plane, w, h, false);
            let t2 = integral(plane, w, h, true);
            for qy in 0..ny {
                for qx in 0..nx {
                    let ring_sum = |t: &[f64]| {
                        rect(t, w, qx, qy, ext, ext) - rect(t, w, qx + o2, qy + o2, inner, inner)
                    };
                    let q = qy * nx + qx;
                    let (sf, sf2) = (ring_sum(&t1), ring_sum(&t2));
                    sum_f[q * c + ch] = sf;
                    ssd_base[q] += sf2;
                    let vf = n * sf2 - sf * sf;
                    spread_f[q * c + ch] = if vf <= FLAT * n * n * var[ch] {
                        -1.0
                    } else {
                        vf.sqrt()
                    };
                }
            }
            let mut padded = vec![0.0; fw * fh];
            for (row, src) in padded.chunks_exact_mut(fw).zip(plane.chunks_exact(w)) {
                row[..w].copy_from_slice(src);
            }
            spectra.push(plan.forward(&padded));
        }
        // The planes are kept only where the direct cross terms read them.
        let planar = if params.metric == Metric::Ncc && c > 1 {
            planes
        } else {
            Vec::new()
        };
        GapTables {
            coarse: coarse_tables(ex, params),
            planar,
            w,
            h,
            c,
            ext,
            block,
            nx,
            metric: params.metric,
            centred,
            var,
            ring,
            ring_px,
            sum_f,
            spread_f,
            ssd_base,
            fw,
            fh,
            spectra,
            scratch: Mutex::new(Vec::new()),
        }
    }

    /// The full neighbouring border of a gap (E × E × channels, centred values, zero in
    /// the hole): each ring pixel from the neighbour whose wedge holds it — split by the
    /// diagonals, the left and right neighbours taking the diagonals themselves.
    /// `nb` holds the positions of the left, right, upper and lower neighbours.
    pub(crate) fn border(&self, nb: [(usize, usize); 4]) -> Vec<f64> {
        let (ext, c, b) = (self.ext, self.c, self.block);
        let mut g = vec![0.0f64; ext * ext * c];
        for &(y, x0, x1) in &self.ring {
            let dy2 = 2 * y as i64 + 1 - ext as i64;
            for x in x0..x1 {
                let dx2 = 2 * x as i64 + 1 - ext as i64;
                // Neighbour and the pixel's coordinates in that neighbour's patch.
                let (k, lx, ly) = if dx2.abs() >= dy2.abs() {
                    if dx2 < 0 {
                        (0, x + b, y)
                    } else {
                        (1, x - b, y)
                    }
                } else if dy2 < 0 {
                    (2, x, y + b)
                } else {
                    (3, x, y - b)
                };
                let (qx, qy) = nb[k];
                let src = ((qy + ly) * self.w + qx + lx) * c;
                let dst = (y * ext + x) * c;
                g[dst..dst + c].copy_from_slice(&self.centred[src..src + c]);
            }
        }
        g
    }

    /// Channels of the cross term the metric needs: 1 (summed) for SSD, all for NCC.
    fn cross_channels(&self) -> usize {
        match self.metric {
            Metric::Ssd => 1,
            Metric::Ncc => self.c,
        }
    }

    /// Σ_R f(q + x)·g(x) for each candidate, by dot products over the ring: over all
    /// channels at once where one cross term is kept (SSD, or one channel), per
    /// channel on planar copies otherwise.
    pub(crate) fn cross_direct(&self, g: &[f64], cands: &[u32]) -> Vec<f64> {
        let (c, cc, ext) = (self.c, self.cross_channels(), self.ext);
        let mut out = vec![0.0; cands.len() * cc];
        if cc == 1 {
            for (acc, &q) in out.iter_mut().zip(cands) {
                let (qx, qy) = (q as usize % self.nx, q as usize / self.nx);
                for &(y, x0, x1) in &self.ring {
                    let f0 = ((qy + y) * self.w + qx + x0) * c;
                    let g0 = (y * ext + x0) * c;
                    let len = (x1 - x0) * c;
                    *acc += dot(&self.centred[f0..f0 + len], &g[g0..g0 + len]);
                }
            }
            return out;
        }
        let planes: Vec<Vec<f64>> = (0..c)
            .map(|ch| (0..ext * ext).map(|i| g[i * c + ch]).collect())
            .collect();
        for (n, &q) in cands.iter().enumerate() {
            let (qx, qy) = (q as usize % self.nx, q as usize / self.nx);
            let acc = &mut out[n * cc..(n + 1) * cc];
            for &(y, x0, x1) in &self.ring {
                let f0 = (qy + y) * self.w + qx + x0;
                let g0 = y * ext + x0;
                let len = x1 - x0;
                for ((a, f), gp) in acc.iter_mut().zip(&self.planar).zip(&planes) {
                    *a += dot(&f[f0..f0 + len], &gp[g0..g0 + len]);
                }
            }
        }
        out
    }

    /// The same cross terms from one FFT correlation of the exemplar with the border
    /// per channel, through real FFTs of the planes padded with zeros to fw × fh (no
    /// wrap-around: a patch at a valid position stays inside W × H).
    pub(crate) fn cross_fft(&self, g: &[f64], cands: &[u32]) -> Vec<f64> {
        let (fw, fh, c, ext) = (self.fw, self.fh, self.c, self.ext);
        let ny = self.h + 1 - ext;
        let cc = self.cross_channels();
        let mut s = self
            .scratch
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .pop()
            .unwrap_or_else(|| {
                let plan = RealFft2::new(fw, fh);
                let half = plan.half_width() * fh;
                CrossScratch {
                    plan,
                    plane: vec![0.0; ext * fw],
                    spectrum: vec![Complex64::default(); half],
                    acc: vec![Complex64::default(); half],
                    maps: vec![vec![0.0; ny * fw]; cc],
                }
            });
        let CrossScratch {
            plan,
            plane,
            spectrum,
            acc,
            maps,
        } = &mut s;
        acc.fill(Complex64::default());
        let mut k = 0;
        for ch in 0..c {
            for (y, row) in plane.chunks_exact_mut(fw).enumerate() {
                for (x, v) in row[..ext].iter_mut().enumerate() {
                    *v = g[(y * ext + x) * c + ch];
                }
            }
            plan.forward_top(plane, ext, spectrum);
            for ((a, f), gv) in acc.iter_mut().zip(&self.spectra[ch]).zip(spectrum.iter()) {
                *a += f * gv.conj();
            }
            if cc > 1 || ch == c - 1 {
                plan.inverse_top(acc, ny, &mut maps[k]);
                acc.fill(Complex64::default());
                k += 1;
            }
        }
        let mut out = vec![0.0; cands.len() * cc];
        for (n, &q) in cands.iter().enumerate() {
            let (qx, qy) = (q as usize % self.nx, q as usize / self.nx);
            for (k, map) in maps.iter().enumerate() {
                out[n * cc + k] = map[qy * fw + qx];
            }
        }
        self.scratch
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(s);
        out
    }

    /// Whether the FFT costs less than direct dot products for `n` candidates: c + cc
    /// real transforms of fw × fh, each about half a complex one.
    fn use_fft(&self, n: usize) -> bool {
        let direct = n as f64 * (self.ring_px * self.c) as f64;
        let px = (self.fw * self.fh) as f64;
        let fft = (self.c + self.cross_channels()) as f64 * px * px.log2();
        direct > fft
    }

    /// Scores of the candidates for border `g` (lower is better): χ less its constant
    /// term for SSD, −γ for NCC.
    pub(crate) fn scores(&self, g: &[f64], cands: &[u32]) -> Vec<f64> {
        let cross = if self.use_fft(cands.len()) {
            self.cross_fft(g, cands)
        } else {
            self.cross_direct(g, cands)
        };
        self.scores_from(g, cands, &cross)
    }

    /// The best candidate for border `g` (lowest score, ties to the first in `cands`,
    /// which is sorted): by scoring every one, or coarse to fine when the exemplar is
    /// large and the candidates are more than a quarter of all positions.
    pub(crate) fn best(&self, g: &[f64], cands: &[u32]) -> u32 {
        let ny = self.h + 1 - self.ext;
        if let Some(coarse) = &self.coarse
            && cands.len() * 4 > self.nx * ny
        {
            let fine = coarse.candidates(self, g, cands);
            if !fine.is_empty() {
                return argmin(&fine, &self.scores(g, &fine));
            }
        }
        argmin(cands, &self.scores(g, cands))
    }

    /// Scores from precomputed cross terms.
    pub(crate) fn scores_from(&self, g: &[f64], cands: &[u32], cross: &[f64]) -> Vec<f64> {
        let c = self.c;
        match self.metric {
            Metric::Ssd => cands
                .iter()
                .zip(cross)
                .map(|(&q, x)| self.ssd_base[q as usize] - 2.0 * x)
                .collect(),
            Metric::Ncc => {
                let n = self.ring_px as f64;
                let (mut sg, mut sg2) = (vec![0.0; c], vec![0.0; c]);
                for &(y, x0, x1) in &self.ring {
                    for x in x0..x1 {
                        for ch in 0..c {
                            let v = g[(y * self.ext + x) * c + ch];
                            sg[ch] += v;
                            sg2[ch] += v * v;
                        }
                    }
                }
                // The border's spread per channel, or −1 where it is flat.
                let spread_g: Vec<f64> = (0..c)
                    .map(|ch| {
                        let vg = n * sg2[ch] - sg[ch] * sg[ch];
                        if vg <= FLAT * n * n * self.var[ch] {
                            -1.0
                        } else {
                            vg.sqrt()
                        }
                    })
                    .collect();
                cands
                    .iter()
                    .enumerate()
                    .map(|(k, &q)| {
                        let (mut num, mut den) = (0.0, 0.0);
                        let at = q as usize * c;
                        for ch in 0..c {
                            let (sf, spread) = (self.sum_f[at + ch], self.spread_f[at + ch]);
                            if spread < 0.0 || spread_g[ch] < 0.0 {
                                continue;
                            }
                            num += n * cross[k * c + ch] - sf * sg[ch];
                            den += spread * spread_g[ch];
                        }
                        if den > 0.0 { -(num / den) } else { 0.0 }
                    })
                    .collect()
            }
        }
    }
}

impl RsgfModel {
    /// Candidate positions of a gap whose patch origin is p: those within ±tolerance
    /// (per axis) of a lattice-similar position, in position order; the nearest similar
    /// ones when there are none.
    pub(crate) fn gap_candidates(&self, p: (i64, i64)) -> Vec<u32> {
        let t = self.params.tolerance_px as i64;
        let mut residues: Vec<usize> = Vec::with_capacity(((2 * t + 1) * (2 * t + 1)) as usize);
        for dy in -t..=t {
            for dx in -t..=t {
                residues.push(self.residue((p.0 + dx, p.1 + dy)));
            }
        }
        residues.sort_unstable();
        residues.dedup();
        let mut out: Vec<u32> = Vec::new();
        for r in residues {
            out.extend_from_slice(self.exact_list(r));
        }
        if out.is_empty() {
            out.extend_from_slice(self.near_candidates(p));
        }
        out.sort_unstable();
        out.dedup();
        out
    }

    /// The border of gap (i, j) and its candidates, for the solver and the tests.
    pub(crate) fn gap_problem(&self, seed: u32, i: i64, j: i64) -> (Vec<f64>, Vec<u32>) {
        let nb = [(i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1)]
            .map(|(a, b)| self.position(self.random_pick(seed, a, b)));
        (self.gap.border(nb), self.gap_candidates(self.origin(i, j)))
    }

    /// The position of gap block (i, j) (I + J odd): the candidate whose ring best
    /// matches the border its four random neighbours compose (§4.2).
    pub fn solve_gap(&self, seed: u32, i: i64, j: i64) -> u32 {
        let (g, cands) = self.gap_problem(seed, i, j);
        self.gap.best(&g, &cands)
    }
}

/// The candidate of the lowest score, ties to the first.
fn argmin(cands: &[u32], scores: &[f64]) -> u32 {
    let mut best = 0;
    for (k, s) in scores.iter().enumerate() {
        if *s < scores[best] {
            best = k;
        }
    }
    cands[best]
}

/// The coarse tables of an exemplar above [`COARSE_ABOVE`] pixels: box-filtered by the
/// smallest power of two s that brings it to at most that many, with block and border
/// divided by s (at least 2 and 1 px). None for smaller exemplars, or where the
/// scaled patch does not fit.
fn coarse_tables(ex: &Raster, params: &RsgfParams) -> Option<Box<Coarse>> {
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    if w * h <= COARSE_ABOVE {
        return None;
    }
    let mut s = 2;
    while (w / s) * (h / s) > COARSE_ABOVE {
        s *= 2;
    }
    let border = (params.border_px / s).max(1);
    let block = (params.block_px / s).max(2 * border + 1);
    let (cw, ch) = (w / s, h / s);
    if block + 2 * border > cw.min(ch) {
        return None;
    }
    let mut data = vec![0.0f32; cw * ch * c];
    let norm = 1.0 / (s * s) as f64;
    for y in 0..ch {
        for x in 0..cw {
            for k in 0..c {
                let mut acc = 0.0f64;
                for yy in y * s..(y + 1) * s {
                    for xx in x * s..(x + 1) * s {
                        acc += ex.data[(yy * w + xx) * c + k] as f64;
                    }
                }
                data[(y * cw + x) * c + k] = (acc * norm) as f32;
            }
        }
    }
    let small = Raster::from_vec(cw, ch, c, data).ok()?;
    let coarse_params = RsgfParams {
        block_px: block,
        border_px: border,
        ..params.clone()
    };
    Some(Box::new(Coarse {
        s,
        tables: GapTables::new(&small, &coarse_params),
    }))
}

impl Coarse {
    /// The fine candidates worth scoring exactly for fine border `g`: every position of
    /// `cands` within ±s (per axis) of s × one of the [`COARSE_KEEP`] best coarse
    /// positions, sorted.
    fn candidates(&self, fine: &GapTables, g: &[f64], cands: &[u32]) -> Vec<u32> {
        let (s, t, c) = (self.s, &self.tables, fine.c);
        // The border at 1/s: each coarse ring pixel the mean of its s × s fine pixels.
        let mut gc = vec![0.0f64; t.ext * t.ext * c];
        let norm = 1.0 / (s * s) as f64;
        for &(y, x0, x1) in &t.ring {
            for x in x0..x1 {
                for k in 0..c {
                    let mut acc = 0.0;
                    for yy in (y * s..(y + 1) * s).filter(|&v| v < fine.ext) {
                        for xx in (x * s..(x + 1) * s).filter(|&v| v < fine.ext) {
                            acc += g[(yy * fine.ext + xx) * c + k];
                        }
                    }
                    gc[(y * t.ext + x) * c + k] = acc * norm;
                }
            }
        }
        let all: Vec<u32> = (0..(t.nx * (t.h + 1 - t.ext)) as u32).collect();
        let scores = t.scores(&gc, &all);
        // The COARSE_KEEP best (score, then index): a partial selection; their order
        // does not matter, the fine candidates are sorted below.
        let mut order: Vec<u32> = all;
        if order.len() > COARSE_KEEP {
            order.select_nth_unstable_by(COARSE_KEEP - 1, |a, b| {
                scores[*a as usize]
                    .total_cmp(&scores[*b as usize])
                    .then(a.cmp(b))
            });
        }
        let fny = fine.h + 1 - fine.ext;
        let mut out = Vec::new();
        for &q in order.iter().take(COARSE_KEEP) {
            let (qx, qy) = ((q as usize % t.nx) * s, (q as usize / t.nx) * s);
            for y in qy.saturating_sub(s)..=(qy + s).min(fny - 1) {
                for x in qx.saturating_sub(s)..=(qx + s).min(fine.nx - 1) {
                    out.push((y * fine.nx + x) as u32);
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out.retain(|q| cands.binary_search(q).is_ok());
        out
    }
}

/// Dot product with four accumulators (fixed order: the same bits on every call).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let mut ca = a.chunks_exact(4);
    let mut cb = b.chunks_exact(4);
    for (x, y) in (&mut ca).zip(&mut cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Sum of the `rw × rh` rectangle at (x, y) of the image behind table `t`.
fn rect(t: &[f64], w: usize, x: usize, y: usize, rw: usize, rh: usize) -> f64 {
    let s = w + 1;
    t[(y + rh) * s + x + rw] - t[y * s + x + rw] - t[(y + rh) * s + x] + t[y * s + x]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The FFT correlation and the direct dot products give the same cross terms at
    /// every position (relative 1e-9), for one and for three channels, and both metrics.
    #[test]
    fn fft_and_direct_cross_terms_agree() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut rnd = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for (c, metric) in [(1, Metric::Ssd), (3, Metric::Ssd), (3, Metric::Ncc)] {
            let (w, h) = (97, 83);
            let data: Vec<f32> = (0..w * h * c).map(|_| rnd() as f32 * 4.0 + 7.0).collect();
            let ex = Raster::from_vec(w, h, c, data).unwrap();
            let params = RsgfParams {
                metric,
                block_px: 30,
                border_px: 7,
                ..RsgfParams::stochastic()
            };
            let t = GapTables::new(&ex, &params);
            let ext = 44;
            let mut g = vec![0.0; ext * ext * c];
            for &(y, x0, x1) in &t.ring {
                for x in x0..x1 {
                    for ch in 0..c {
                        g[(y * ext + x) * c + ch] = rnd() - 0.5;
                    }
                }
            }
            let cands: Vec<u32> = (0..((w - ext + 1) * (h - ext + 1)) as u32).collect();
            let a = t.cross_direct(&g, &cands);
            let b = t.cross_fft(&g, &cands);
            let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let worst = a
                .iter()
                .zip(&b)
                .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            assert!(
                worst <= 1e-9 * scale,
                "c = {c}, {metric:?}: worst {worst:e} of {scale:e}"
            );
            let (sa, sb) = (t.scores_from(&g, &cands, &a), t.scores_from(&g, &cands, &b));
            assert!(sa.iter().all(|s| s.is_finite()) && sa.len() == sb.len());
            // The buffers kept between gaps carry nothing over: another border first,
            // then this one again, gives the same bits.
            let other: Vec<f64> = g.iter().map(|v| 3.0 * v + 1.0).collect();
            let _ = t.cross_fft(&other, &cands);
            let again = t.cross_fft(&g, &cands);
            assert!(
                again
                    .iter()
                    .zip(&b)
                    .all(|(x, y)| x.to_bits() == y.to_bits()),
                "c = {c}, {metric:?}: a second correlation differs from the first"
            );
        }
    }

    /// fft_size against its definition, by brute force: the smallest even m ≥ n with no
    /// prime factor above 5; and the sizes the photos of the structure figures meet.
    #[test]
    fn fft_sizes_are_the_next_even_5_smooth_numbers() {
        // The twin by definition: no divisor above 5 is prime.
        let is_prime = |p: usize| {
            (2..p)
                .take_while(|d| d * d <= p)
                .all(|d| !p.is_multiple_of(d))
        };
        let five_smooth = |m: usize| (7..=m).all(|d| !m.is_multiple_of(d) || !is_prime(d));
        for n in 0..1200 {
            let want = (n.max(1)..)
                .find(|&m: &usize| m.is_multiple_of(2) && five_smooth(m))
                .unwrap();
            assert_eq!(fft_size(n), want, "n = {n}");
        }
        // The crack photo (144 + 2 · 10 mirrored) and a 256² one (276): 41 and 23 were
        // the prime factors whose FFTs were slow.
        assert_eq!(
            (fft_size(164), fft_size(276), fft_size(120)),
            (180, 288, 120)
        );
    }

    /// Coarse to fine on a large exemplar (a 320² crop of the measured AFM map di-6, so
    /// s = 2) against the full search, stochastic mode, NCC and SSD: every pick ranks
    /// among the best 0.1% of all positions, and most are the exact best.
    #[test]
    fn coarse_to_fine_finds_the_best_gaps() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tiles/di-6.npy");
        let image = crate::io::read_image(&path, &crate::io::ReadOptions::default()).unwrap();
        let ex = image.raster.crop(40, 100, 320, 320).unwrap();
        for metric in [Metric::Ncc, Metric::Ssd] {
            let params = RsgfParams {
                metric,
                ..RsgfParams::stochastic()
            };
            let model = RsgfModel::new(&ex, &params).unwrap();
            assert_eq!(model.gap.coarse.as_ref().map(|c| c.s), Some(2));
            let mut exact = 0;
            let gaps = [(1, 0), (0, 1), (-3, 2), (7, -4), (11, 20), (-40, 9)];
            for (i, j) in gaps {
                let (g, cands) = model.gap_problem(5, i, j);
                let scores = model.gap.scores(&g, &cands);
                let full = argmin(&cands, &scores);
                let pick = model.gap.best(&g, &cands);
                let at = cands.binary_search(&pick).unwrap();
                let rank = scores.iter().filter(|&&v| v < scores[at]).count();
                assert!(
                    rank * 1000 <= cands.len(),
                    "{metric:?} gap ({i}, {j}): rank {rank} of {}",
                    cands.len()
                );
                exact += usize::from(pick == full);
            }
            eprintln!(
                "{metric:?}: {exact} of {} picks are the full search's",
                gaps.len()
            );
            assert!(
                2 * exact >= gaps.len(),
                "{metric:?}: {exact} exact picks of {}",
                gaps.len()
            );
        }
    }
}
