//! Efros–Freeman stitching as seed 000 §3.2.1 states it: square patches placed in raster
//! order with overlap o, each joined to what is already there along an 8-connected
//! minimum-error path — vertical for a patch with only a left neighbour, horizontal for
//! one with only an upper neighbour, L-shaped otherwise — then a 3×3 mean filter on the
//! seam pixels.
//!
//! L-shapes use the paper's fix: the horizontal path of the previous patch in the row is
//! kept where it runs through the new patch's corner and extended optimally over the
//! rest of the new patch; the vertical path is the cheapest one that joins that
//! horizontal path (found by a dynamic programme from the bottom row up), so the seams of
//! successive patches always connect.

use crate::analysis::cut::min_cut_vertical;
use crate::error::{Error, Result};
use crate::raster::Raster;

/// Patch side and overlap, validated: 1 ≤ o < M_P (seed 000 §3.2.1 asks 1 < o < M_P; an
/// overlap of one pixel is allowed here, it just leaves the path no room).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StitchParams {
    patch: usize,
    overlap: usize,
    blend: usize,
}

impl StitchParams {
    /// `patch` × `patch` patches overlapping by `overlap` pixels.
    pub fn new(patch: usize, overlap: usize) -> Result<StitchParams> {
        if patch < 2 {
            return Err(Error::param(
                "patch",
                patch,
                "a patch side of at least 2 pixels",
            ));
        }
        if overlap == 0 || overlap >= patch {
            return Err(Error::param(
                "overlap",
                overlap,
                format!(
                    "1 to {} pixels: less than the patch size ({patch})",
                    patch - 1
                ),
            ));
        }
        Ok(StitchParams {
            patch,
            overlap,
            blend: 0,
        })
    }

    /// Multi-band seams (0, the default, is seed 000's hard cut): the difference between
    /// new and old patch is split into bands by a Gaussian pyramid down to a scale of
    /// about `radius` px; the finest band stays cut along the path, each coarser band is
    /// cross-faded by the cut mask blurred at its own scale (Burt and Adelson 1983). The
    /// cut alone leaves a step wherever two patches differ by a smooth offset, which on a
    /// map with a steep spectrum (a polished or smooth form) adds orders of magnitude of
    /// mid-frequency power.
    ///
    /// The fade reaches [`blend_reach`]`(radius)` px from the cut. Pixels beyond the
    /// overlap's outer edge belong to patches already placed and cannot be faded, so the
    /// paths keep that far from it: a cut nearer would leave the fade's remainder as a
    /// step along the edge. Refused unless the overlap leaves them room: reach + 1 < o.
    /// A lower row's horizontal cut runs out through the patch's right edge; there the
    /// fade goes on over the placed pixels beside the top strip, above the cut's
    /// continuation.
    pub fn with_blend(mut self, radius: usize) -> Result<StitchParams> {
        // The paths need a column at least reach + 1 px from the outer edge.
        let fits = |r: usize| blend_reach(r) + 1 < self.overlap;
        if radius > 0 && !fits(radius) {
            let most = (1..self.overlap)
                .take_while(|&r| fits(r))
                .last()
                .unwrap_or(0);
            return Err(Error::param(
                "seam-blend",
                radius,
                format!(
                    "a radius of at most {most} px: the blend reaches 4·2^⌊log₂ r⌋ px from the seam, which must stay inside the {} px overlap (0: hard cuts)",
                    self.overlap
                ),
            ));
        }
        self.blend = radius;
        Ok(self)
    }

    /// Overlap o in pixels.
    pub fn overlap(&self) -> usize {
        self.overlap
    }

    /// Seam blend radius in pixels (0: hard cuts).
    pub fn blend(&self) -> usize {
        self.blend
    }

    /// Patches needed along a side of `n` pixels: the least count with (M_P − o)·count + o ≥ n.
    pub fn count(&self, n: usize) -> usize {
        let step = self.patch - self.overlap;
        n.saturating_sub(self.overlap).div_ceil(step).max(1)
    }
}

/// How far from the cut, in pixels, the multi-band blend of radius `radius` may change
/// anything: 2^(⌊log₂ radius⌋ + 2), four samples of the pyramid's coarsest level (its
/// binomial footprint and the linear expansion back to full size); pixels further away
/// keep the cut's value. 0 for a hard cut.
pub fn blend_reach(radius: usize) -> usize {
    if radius == 0 {
        0
    } else {
        1 << (radius.ilog2() + 2)
    }
}

/// The squared difference, summed over channels, between a candidate patch and the
/// canvas over the overlap region Ω of the patch being placed (seed 000: e(p)).
pub type OverlapError<'a> = &'a dyn Fn(&[f32]) -> f64;

/// Stitches patches into a `width × height × channels` image (the patchwork is cropped
/// from its top-left corner). `patch(i, j, error)` returns patch (i, j) — column i, row j,
/// `M_P × M_P × channels` samples, row-major, interleaved — and may call `error` to rank
/// candidates against what is already placed (Efros and Freeman pick among crops that
/// way; seed 000's RPN patches are taken as they come).
pub fn stitch(
    width: usize,
    height: usize,
    channels: usize,
    params: StitchParams,
    mut patch: impl FnMut(usize, usize, OverlapError) -> Result<Vec<f32>>,
) -> Result<Raster> {
    if width == 0 || height == 0 || channels == 0 {
        return Err(Error::param(
            "size",
            format!("{width}×{height}×{channels}"),
            "a non-empty output",
        ));
    }
    let (p, o) = (params.patch, params.overlap);
    let step = p - o;
    let (nx, ny) = (params.count(width), params.count(height));
    let (cw, chh) = (step * nx + o, step * ny + o);
    let c = channels;
    // Paths keep the blend's reach from the overlap's outer edge (row 0 of the top strip,
    // column 0 of the left one): beyond it lie pixels of patches already placed, which
    // the fade cannot change.
    let margin = if params.blend > 0 {
        blend_reach(params.blend) + 1
    } else {
        0
    };
    let mut canvas = vec![0.0f32; cw * chh * c];
    // The horizontal path of the previous patch in this row, in its local columns.
    let mut prev_h: Option<Vec<usize>> = None;
    for j in 0..ny {
        for i in 0..nx {
            let (x0, y0) = (i * step, j * step);
            let at = |x: usize, y: usize| ((y0 + y) * cw + x0 + x) * c;
            let in_omega = |x: usize, y: usize| (i > 0 && x < o) || (j > 0 && y < o);
            let err_of = |pt: &[f32], x: usize, y: usize| -> f64 {
                let (a, b) = (at(x, y), (y * p + x) * c);
                (0..c)
                    .map(|k| (canvas[a + k] as f64 - pt[b + k] as f64).powi(2))
                    .sum()
            };
            let overlap_error = |pt: &[f32]| -> f64 {
                if pt.len() != p * p * c {
                    return f64::INFINITY;
                }
                let mut s = 0.0;
                for y in 0..p {
                    for x in 0..p {
                        if in_omega(x, y) {
                            s += err_of(pt, x, y);
                        }
                    }
                }
                s
            };
            let pt = patch(i, j, &overlap_error)?;
            if pt.len() != p * p * c {
                return Err(Error::param(
                    "patch",
                    format!("{} samples", pt.len()),
                    format!("{p}×{p}×{c} samples"),
                ));
            }
            // Paths: h[x] is the first new row of column x (top overlap), v[y] the first
            // new column of row y (left overlap).
            let h: Option<Vec<usize>> = (j > 0).then(|| {
                match prev_h.as_ref().filter(|_| i > 0) {
                    // L-shape: keep the previous path through the corner, extend it.
                    Some(prev) => {
                        let mut path = prev[step..].to_vec();
                        let start = prev[p - 1];
                        let mut err = vec![0.0; (p - o) * o];
                        for x in o..p {
                            for r in 0..o {
                                err[(x - o) * o + r] =
                                    if r < margin || (x == o && r.abs_diff(start) > 1) {
                                        f64::INFINITY
                                    } else {
                                        err_of(&pt, x, r)
                                    };
                            }
                        }
                        path.extend(min_cut_vertical(&err, o, p - o));
                        path
                    }
                    None => {
                        let mut err = vec![0.0; p * o];
                        for x in 0..p {
                            for r in 0..o {
                                err[x * o + r] = if r < margin {
                                    f64::INFINITY
                                } else {
                                    err_of(&pt, x, r)
                                };
                            }
                        }
                        min_cut_vertical(&err, o, p)
                    }
                }
            });
            let v: Option<Vec<usize>> = (i > 0).then(|| {
                let mut err = vec![0.0; p * o];
                for y in 0..p {
                    for x in 0..o {
                        err[y * o + x] = if x < margin {
                            f64::INFINITY
                        } else {
                            err_of(&pt, x, y)
                        };
                    }
                }
                match &h {
                    Some(h) => vertical_joining(&err, o, p, h),
                    None => min_cut_vertical(&err, o, p),
                }
            });
            let new = |x: usize, y: usize| {
                v.as_ref().is_none_or(|v| x >= v[y]) && h.as_ref().is_none_or(|h| y >= h[x])
            };
            // The fade, `fw` columns wide: the patch, and past its right edge, beside the
            // top strip, `pad` columns of a patch already placed (row j − 1). The
            // horizontal cut runs out through the patch's right edge, and its fade must go
            // on past it, or what it changed inside would stand as a step along the
            // edge. Out there the mask repeats the patch's last column and the difference
            // is the pyramid's extrapolation of the known one.
            let pad = if params.blend > 0 && j > 0 {
                margin.min(cw - (x0 + p))
            } else {
                0
            };
            let fw = p + pad;
            let fade = (params.blend > 0 && (i > 0 || j > 0)).then(|| {
                let mut diff = vec![0.0f32; fw * p * c];
                for y in 0..p {
                    for x in 0..p {
                        if in_omega(x, y) {
                            let (a, b) = (at(x, y), (y * p + x) * c);
                            for k in 0..c {
                                diff[(y * fw + x) * c + k] = pt[b + k] - canvas[a + k];
                            }
                        }
                    }
                }
                let mask: Vec<f32> = (0..fw * p)
                    .map(|k| new((k % fw).min(p - 1), k / fw) as u8 as f32)
                    .collect();
                let known: Vec<f32> = (0..fw * p)
                    .map(|k| (k % fw < p && in_omega(k % fw, k / fw)) as u8 as f32)
                    .collect();
                seam_blend(&diff, &mask, &known, (fw, p), c, params.blend)
            });
            for y in 0..p {
                for x in 0..p {
                    let (a, b) = (at(x, y), (y * p + x) * c);
                    if new(x, y) {
                        canvas[a..a + c].copy_from_slice(&pt[b..b + c]);
                    }
                    if let Some(corr) = &fade {
                        for k in 0..c {
                            canvas[a + k] += corr[(y * fw + x) * c + k];
                        }
                    }
                }
            }
            // Beside the top strip, above the cut's continuation: those pixels stay old.
            // Below it they stand for the new patch, which does not reach there; the next
            // patch in the row covers them. Lower down, nothing is placed yet.
            if let Some(corr) = &fade {
                for y in 0..o {
                    if new(p - 1, y) {
                        continue;
                    }
                    for x in p..fw {
                        let a = at(x, y);
                        for k in 0..c {
                            canvas[a + k] += corr[(y * fw + x) * c + k];
                        }
                    }
                }
            }
            // Seam pixels: both sides of every change between old and new, the column left
            // of the patch and the row above it counting as old where they exist.
            let (lx, ly) = ((i > 0) as usize, (j > 0) as usize);
            let is_new = |x: usize, y: usize| x >= lx && y >= ly && new(x - lx, y - ly);
            let mut seam = Vec::new();
            for y in 0..p + ly {
                for x in 0..p + lx {
                    let n = is_new(x, y);
                    let differs = (x > 0 && is_new(x - 1, y) != n)
                        || (x + 1 < p + lx && is_new(x + 1, y) != n)
                        || (y > 0 && is_new(x, y - 1) != n)
                        || (y + 1 < p + ly && is_new(x, y + 1) != n);
                    let inside_omega = (x < lx + o && lx == 1) || (y < ly + o && ly == 1);
                    if differs && inside_omega {
                        seam.push((x0 + x - lx, y0 + y - ly));
                    }
                }
            }
            mean_filter_at(&mut canvas, cw, chh, c, &seam);
            prev_h = h;
        }
        prev_h = None;
    }
    let full = Raster::from_vec(cw, chh, c, canvas)?;
    full.crop(0, 0, width, height)
}

/// The least-error vertical path through the `o × p` error strip (row-major, `o` columns)
/// that starts on the horizontal path `h` (h[x] = its row in column x, for x < o) and runs
/// down to the last row. Returns v[y], the path's column in each row; rows above the
/// junction keep the junction's column, so the L-mask `x ≥ v[y] and y ≥ h[x]` is exactly
/// the region below and right of the joined paths.
fn vertical_joining(err: &[f64], o: usize, p: usize, h: &[usize]) -> Vec<usize> {
    // cost[y][c]: least error of a path from (c, y) down to the last row; next[y][c]: its
    // column in row y + 1.
    let mut cost = vec![0.0; o * p];
    let mut next = vec![0usize; o * p];
    cost[(p - 1) * o..].copy_from_slice(&err[(p - 1) * o..]);
    for y in (0..p - 1).rev() {
        for c in 0..o {
            let (lo, hi) = (c.saturating_sub(1), (c + 1).min(o - 1));
            let best = (lo..=hi).fold(lo, |b, k| {
                if cost[(y + 1) * o + k] < cost[(y + 1) * o + b] {
                    k
                } else {
                    b
                }
            });
            cost[y * o + c] = err[y * o + c] + cost[(y + 1) * o + best];
            next[y * o + c] = best;
        }
    }
    let junction = (0..o).fold(0, |b, c| {
        if cost[h[c] * o + c] < cost[h[b] * o + b] {
            c
        } else {
            b
        }
    });
    let top = h[junction];
    let mut v = vec![junction; p];
    let mut c = junction;
    for (y, vy) in v.iter_mut().enumerate().skip(top) {
        *vy = c;
        if y + 1 < p {
            c = next[y * o + c];
        }
    }
    v
}

/// Multi-band seam blending (Burt and Adelson 1983) of one `width × height × c`
/// rectangle: `diff` is new − old where `known` is 1 (the overlap Ω) and 0 elsewhere,
/// `mask` the cut (1 = new).
/// Returns Δ, to add to the cut image: below the finest scale the seam stays cut; each
/// coarser band of the difference, down to a scale of about `radius` px, is cross-faded
/// by the mask's Gaussian-pyramid level of the same scale.
///
/// With Ĝₗ the difference's Gaussian pyramid by normalised convolution (the reduced
/// diff over the reduced `known`: a local mean of the difference where it is known,
/// carried past Ω's edge instead of pulled to zero), Lₗ = Ĝₗ − up(Ĝₗ₊₁) and the mask's
/// pyramid Mₗ: Δ = collapse(Mₗ·Lₗ) − M·Ĝ₀. The collapse telescopes, so Δ = 0 wherever
/// every Mₗ is 0 (old kept) or 1 (new kept): only the pixels near the cut change.
fn seam_blend(
    diff: &[f32],
    mask: &[f32],
    known: &[f32],
    (width, height): (usize, usize),
    c: usize,
    radius: usize,
) -> Vec<f32> {
    let levels = (usize::BITS - 1 - radius.leading_zeros()) as usize; // ⌊log₂ r⌋
    // Pyramids, level 0 first: sizes, reduced diff·known (diff is already 0 off Ω), known,
    // mask.
    let mut sizes = vec![(width, height)];
    let mut dk = vec![diff.to_vec()];
    let mut kn = vec![known.to_vec()];
    let mut mk = vec![mask.to_vec()];
    for l in 0..levels {
        let (w, h) = sizes[l];
        if w < 2 && h < 2 {
            break;
        }
        let (d2, w2, h2) = reduce(&dk[l], w, h, c);
        dk.push(d2);
        kn.push(reduce(&kn[l], w, h, 1).0);
        mk.push(reduce(&mk[l], w, h, 1).0);
        sizes.push((w2, h2));
    }
    // Ĝₗ = reduced diff / reduced known (0 where nothing is known nearby).
    let g: Vec<Vec<f32>> = dk
        .iter()
        .zip(&kn)
        .map(|(d, k)| {
            d.iter()
                .enumerate()
                .map(|(i, &v)| {
                    let w = k[i / c];
                    if w > 1e-3 { v / w } else { 0.0 }
                })
                .collect()
        })
        .collect();
    let top = g.len() - 1;
    // Collapse: R_top = M_top·Ĝ_top; Rₗ = Mₗ·(Ĝₗ − up(Ĝₗ₊₁)) + up(Rₗ₊₁). At level 0, off Ω
    // Ĝ₀ is taken as up(Ĝ₁) (its band is empty there).
    let mut r: Vec<f32> = g[top]
        .iter()
        .enumerate()
        .map(|(i, &v)| mk[top][i / c] * v)
        .collect();
    for l in (0..top).rev() {
        let (w, h) = sizes[l];
        let (w2, h2) = sizes[l + 1];
        let up_g = expand(&g[l + 1], w2, h2, c, w, h);
        let up_r = expand(&r, w2, h2, c, w, h);
        r = (0..w * h * c)
            .map(|i| {
                let gl = if l == 0 && known[i / c] == 0.0 {
                    up_g[i]
                } else {
                    g[l][i]
                };
                mk[l][i / c] * (gl - up_g[i]) + up_r[i]
            })
            .collect();
        if l == 0 {
            for (i, v) in r.iter_mut().enumerate() {
                let g0 = if known[i / c] == 0.0 {
                    up_g[i]
                } else {
                    g[0][i]
                };
                *v -= mask[i / c] * g0;
            }
        }
    }
    if top == 0 {
        r.iter_mut().for_each(|v| *v = 0.0);
    }
    r
}

/// One Gaussian-pyramid step: the 5-tap binomial filter (1 4 6 4 1)/16 along each axis,
/// clamped at the border, keeping every second sample (sample k of the result sits on
/// sample 2k of the input).
fn reduce(img: &[f32], w: usize, h: usize, c: usize) -> (Vec<f32>, usize, usize) {
    const TAPS: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
    let (w2, h2) = (w.div_ceil(2), h.div_ceil(2));
    let clampi = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
    // Source samples of output sample k along an axis of n: 2k − 2 … 2k + 2, clamped.
    let taps_of = |k: usize, n: usize| -> [usize; 5] {
        std::array::from_fn(|t| clampi(2 * k as isize + t as isize - 2, n))
    };
    let xs: Vec<[usize; 5]> = (0..w2).map(|k| taps_of(k, w)).collect();
    let mut rows = vec![0.0f32; w2 * h * c];
    for (src, dst) in img.chunks_exact(w * c).zip(rows.chunks_exact_mut(w2 * c)) {
        for (x2, xt) in xs.iter().enumerate() {
            for k in 0..c {
                dst[x2 * c + k] = xt
                    .iter()
                    .zip(TAPS)
                    .map(|(&x, wt)| wt * src[x * c + k])
                    .sum();
            }
        }
    }
    let mut out = vec![0.0f32; w2 * h2 * c];
    for (y2, dst) in out.chunks_exact_mut(w2 * c).enumerate() {
        for (y, wt) in taps_of(y2, h).into_iter().zip(TAPS) {
            for (o, &v) in dst.iter_mut().zip(&rows[y * w2 * c..(y + 1) * w2 * c]) {
                *o += wt * v;
            }
        }
    }
    (out, w2, h2)
}

/// The inverse step of [`reduce`]'s sampling: fine sample x lies at coarse position x/2,
/// linearly interpolated along each axis (clamped at the border).
fn expand(img: &[f32], w2: usize, h2: usize, c: usize, w: usize, h: usize) -> Vec<f32> {
    let lerp_at = |x: usize, n2: usize| -> (usize, usize, f32) {
        let a = (x / 2).min(n2 - 1);
        if x.is_multiple_of(2) {
            (a, a, 0.0)
        } else {
            (a, (a + 1).min(n2 - 1), 0.5)
        }
    };
    let mut rows = vec![0.0f32; w * h2 * c];
    for y2 in 0..h2 {
        for x in 0..w {
            let (a, b, t) = lerp_at(x, w2);
            for k in 0..c {
                let (va, vb) = (img[(y2 * w2 + a) * c + k], img[(y2 * w2 + b) * c + k]);
                rows[(y2 * w + x) * c + k] = va + t * (vb - va);
            }
        }
    }
    let mut out = vec![0.0f32; w * h * c];
    for y in 0..h {
        let (a, b, t) = lerp_at(y, h2);
        for i in 0..w * c {
            let (va, vb) = (rows[a * w * c + i], rows[b * w * c + i]);
            out[y * w * c + i] = va + t * (vb - va);
        }
    }
    out
}

/// Replaces each listed pixel by the 3×3 mean of the image around it (clipped at the
/// image border), all read before any is written.
pub(crate) fn mean_filter_at(
    img: &mut [f32],
    w: usize,
    h: usize,
    c: usize,
    pixels: &[(usize, usize)],
) {
    let means: Vec<f32> = pixels
        .iter()
        .flat_map(|&(x, y)| {
            let img = &*img;
            (0..c).map(move |k| {
                let (mut s, mut n) = (0.0f64, 0usize);
                for yy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                    for xx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                        s += img[(yy * w + xx) * c + k] as f64;
                        n += 1;
                    }
                }
                (s / n as f64) as f32
            })
        })
        .collect();
    for (i, &(x, y)) in pixels.iter().enumerate() {
        img[(y * w + x) * c..(y * w + x + 1) * c].copy_from_slice(&means[i * c..(i + 1) * c]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The slow twin of `vertical_joining`: every start column on the horizontal path,
    /// every 8-connected path down from it, enumerated.
    fn brute_joining(err: &[f64], o: usize, p: usize, h: &[usize]) -> f64 {
        fn walk(err: &[f64], o: usize, p: usize, y: usize, c: usize, acc: f64) -> f64 {
            let acc = acc + err[y * o + c];
            if y + 1 == p {
                return acc;
            }
            (c.saturating_sub(1)..=(c + 1).min(o - 1))
                .map(|n| walk(err, o, p, y + 1, n, acc))
                .fold(f64::INFINITY, f64::min)
        }
        (0..o)
            .map(|c| walk(err, o, p, h[c], c, 0.0))
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn the_joined_vertical_path_is_the_cheapest_one() {
        let (o, p) = (3, 6);
        for seed in 0..40u64 {
            let err: Vec<f64> = (0..o * p)
                .map(|i| ((i as u64 * 2654435761 + seed * 97) % 1000) as f64 * 0.001)
                .collect();
            let h: Vec<usize> = (0..o).map(|x| ((seed as usize + x) * 7) % o).collect();
            let v = vertical_joining(&err, o, p, &h);
            let top = (0..o).find(|&c| v[h[c]] == c && v[..h[c]].iter().all(|&k| k == c));
            let top = top.expect("the path starts on the horizontal path");
            let got: f64 = (h[top]..p).map(|y| err[y * o + v[y]]).sum();
            assert!(v.windows(2).all(|w| w[0].abs_diff(w[1]) <= 1), "{v:?}");
            let best = brute_joining(&err, o, p, &h);
            assert!((got - best).abs() < 1e-12, "seed {seed}: {got} vs {best}");
        }
    }

    #[test]
    fn an_overlap_not_below_the_patch_is_refused() {
        for (p, o) in [(32, 32), (32, 40), (32, 0), (1, 0)] {
            let e = StitchParams::new(p, o).unwrap_err().to_string();
            assert!(e.contains("overlap") || e.contains("patch"), "{e}");
        }
        let e = StitchParams::new(64, 64).unwrap_err().to_string();
        assert_eq!(
            e,
            "invalid overlap = 64: expected 1 to 63 pixels: less than the patch size (64)"
        );
    }

    /// Patches cut from one plane at their own positions agree on every overlap, and the
    /// 3×3 mean of a plane is the plane: the stitched image is the plane, except within
    /// a few pixels of the image's top and left borders, where the mean is clipped.
    #[test]
    fn patches_of_one_plane_stitch_back_into_the_plane() {
        let (w, h) = (150, 110);
        let plane = |x: usize, y: usize| 0.5 * x as f32 - 0.25 * y as f32;
        let params = StitchParams::new(40, 12).unwrap();
        let out = stitch(w, h, 1, params, |i, j, _| {
            let (x0, y0) = (i * 28, j * 28);
            Ok((0..40 * 40)
                .map(|k| plane(x0 + k % 40, y0 + k / 40))
                .collect())
        })
        .unwrap();
        for y in 4..h {
            for x in 4..w {
                assert!((out.get(x, y, 0) - plane(x, y)).abs() < 1e-3, "({x}, {y})");
            }
        }
    }

    /// Two constant patches: every pixel is one of the two values except seam pixels,
    /// which the 3×3 mean puts strictly between them; each new patch's region is
    /// connected to its bottom-right corner (the mask is one region, not scattered).
    #[test]
    fn seams_separate_old_from_new_and_only_seam_pixels_are_filtered() {
        let params = StitchParams::new(16, 6).unwrap();
        let out = stitch(36, 36, 1, params, |i, j, _| {
            Ok(vec![((i + j) % 2) as f32 * 10.0; 256])
        })
        .unwrap();
        let mixed = out.data.iter().filter(|&&v| v > 0.0 && v < 10.0).count();
        assert!(mixed > 0, "the seam pixels were filtered");
        // Mixed values only next to a change between 0 and 10 (seam pixels).
        for y in 0..36 {
            for x in 0..36 {
                let v = out.get(x, y, 0);
                if v > 0.0 && v < 10.0 {
                    let near = (y.saturating_sub(2)..=(y + 2).min(35))
                        .flat_map(|yy| {
                            (x.saturating_sub(2)..=(x + 2).min(35)).map(move |xx| (xx, yy))
                        })
                        .map(|(xx, yy)| out.get(xx, yy, 0));
                    let (lo, hi) =
                        near.fold((f32::MAX, f32::MIN), |(a, b), v| (a.min(v), b.max(v)));
                    assert!(lo < 5.0 && hi > 5.0, "({x}, {y}) = {v} away from a seam");
                }
            }
        }
        // Far from the overlaps each patch is itself.
        assert_eq!(out.get(4, 4, 0), 0.0);
        assert_eq!(out.get(14, 4, 0), 10.0);
        assert_eq!(out.get(4, 14, 0), 10.0);
        assert_eq!(out.get(14, 14, 0), 0.0);
    }

    /// A vertical cut at column `cut` of a `p × p` patch whose left `o` columns are the
    /// overlap, with new − old = `d(x, y)` there: (diff, mask, known).
    fn vertical_case(
        p: usize,
        o: usize,
        cut: usize,
        d: impl Fn(usize, usize) -> f32,
    ) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
        let idx = 0..p * p;
        let diff = idx
            .clone()
            .map(|k| if k % p < o { d(k % p, k / p) } else { 0.0 })
            .collect();
        let mask = idx.clone().map(|k| (k % p >= cut) as u8 as f32).collect();
        let known = idx.map(|k| (k % p < o) as u8 as f32).collect();
        (diff, mask, known)
    }

    /// Multi-band blending changes only pixels near the cut: beyond the reach of the
    /// coarsest band (2^(levels + 2) px) the telescoping collapse gives back the cut
    /// exactly (to 1e-5 of the difference), on a random difference.
    #[test]
    fn blending_changes_only_pixels_near_the_cut() {
        let (p, o, cut, radius) = (96, 48, 20, 4);
        let mut s = 7u64;
        let mut rnd = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 40) as f32 / (1u64 << 24) as f32 - 0.5
        };
        let noise: Vec<f32> = (0..p * p).map(|_| rnd()).collect();
        let (diff, mask, known) = vertical_case(p, o, cut, |x, y| noise[y * p + x]);
        let delta = seam_blend(&diff, &mask, &known, (p, p), 1, radius);
        let reach = 1usize << (2 + 2); // levels = ⌊log₂ 4⌋ = 2
        let mut near = 0.0f32;
        for y in 0..p {
            for x in 0..p {
                let v = delta[y * p + x].abs();
                if x.abs_diff(cut) > reach {
                    assert!(
                        v <= 1e-5,
                        "Δ({x}, {y}) = {v}, {} px from the cut",
                        x.abs_diff(cut)
                    );
                } else {
                    near = near.max(v);
                }
            }
        }
        assert!(near > 0.01, "nothing blended near the cut (max |Δ| {near})");
    }

    /// A smooth offset between old and new (new − old = 1 over the overlap) leaves a step
    /// of 1 at a hard cut; blended, it becomes a ramp: no step between neighbours above
    /// 0.2, and the two sides keep their values (0 and 1) away from the cut.
    #[test]
    fn a_smooth_offset_becomes_a_ramp() {
        let (p, o, cut) = (96, 48, 24);
        let (diff, mask, known) = vertical_case(p, o, cut, |_, _| 1.0);
        let delta = seam_blend(&diff, &mask, &known, (p, p), 1, 8);
        let out: Vec<f32> = mask.iter().zip(&delta).map(|(m, d)| m + d).collect();
        let y = p / 2;
        let row = &out[y * p..(y + 1) * p];
        let step = row
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f32::max);
        assert!(step <= 0.2, "largest step {step} (hard cut: 1)");
        assert!(
            row[0].abs() < 1e-5 && (row[o - 1] - 1.0).abs() < 1e-5,
            "{row:?}"
        );
        assert!(
            row.iter().all(|v| (-1e-5..=1.0 + 1e-5).contains(v)),
            "{row:?}"
        );
    }

    /// Two rows of two patches, the upper row 0 and the lower 1, so the only offset is
    /// across the horizontal seams. The horizontal cut of patch (0, 1) runs out through
    /// its right edge, beside patch (1, 0), already placed: its fade goes on past that
    /// edge, and nowhere in the result do neighbours differ by more than 0.2 (the blend's
    /// ramp). Before the fade went past the edge, what it changed inside stood as a step
    /// along it (0.29 here).
    #[test]
    fn a_horizontal_seams_fade_goes_on_past_the_patchs_right_edge() {
        let (p, o) = (64, 32);
        let params = StitchParams::new(p, o).unwrap().with_blend(4).unwrap();
        let out = stitch(2 * p - o, 2 * p - o, 1, params, |_, j, _| {
            Ok(vec![j as f32; p * p])
        })
        .unwrap();
        let (w, h) = (out.width, out.height);
        let mut worst = (0.0f32, 0, 0);
        for y in 0..h {
            for x in 0..w {
                let v = out.data[y * w + x];
                for (nx, ny) in [(x + 1, y), (x, y + 1)] {
                    if nx < w && ny < h {
                        let d = (out.data[ny * w + nx] - v).abs();
                        if d > worst.0 {
                            worst = (d, x, y);
                        }
                    }
                }
            }
        }
        assert!(
            worst.0 <= 0.2,
            "a step of {} at ({}, {})",
            worst.0,
            worst.1,
            worst.2
        );
    }

    /// A 20 px overlap holds a blend of radius 7 (reach 16, the path from column 17) but
    /// not 8 (reach 32).
    #[test]
    fn a_blend_reaching_past_the_overlap_is_refused() {
        let e = StitchParams::new(64, 20)
            .unwrap()
            .with_blend(8)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("seam-blend") && e.contains("at most 7 px"),
            "{e}"
        );
        assert_eq!(
            StitchParams::new(64, 20)
                .unwrap()
                .with_blend(7)
                .unwrap()
                .blend(),
            7
        );
    }

    /// The old patch is 0, the new one differs from it least at the overlap's outer edge
    /// (new − old = 0.5 + 0.5·x/o), so the least-error cut hugs that edge. A hard cut
    /// there leaves the whole offset as a step along the edge (≥ 0.45 over 5 px: the check
    /// that the set-up does what it says). Blended, the path keeps the blend's reach from
    /// the edge, so the pixels either side of the edge keep the old patch's 0 (to 1e-6),
    /// and the offset becomes a ramp with no step between neighbours above 0.2. Before the
    /// path kept that margin, the fade's remainder stood as a step along the edge, where
    /// the pixels of placed patches cannot fade.
    #[test]
    fn blended_seams_leave_no_step_at_the_overlaps_edge() {
        let (p, o) = (64, 32);
        let edge = p - o;
        let run = |blend: usize| -> Vec<f32> {
            let params = StitchParams::new(p, o).unwrap().with_blend(blend).unwrap();
            let out = stitch(2 * p - o, p, 1, params, |i, _, _| {
                Ok((0..p * p)
                    .map(|k| {
                        let x = k % p;
                        if i == 0 {
                            0.0
                        } else {
                            0.5 + 0.5 * x.min(o) as f32 / o as f32
                        }
                    })
                    .collect())
            })
            .unwrap();
            out.data[(p / 2) * out.width..(p / 2 + 1) * out.width].to_vec()
        };
        let cut = run(0);
        let at_edge = (cut[edge + 2] - cut[edge - 3]).abs();
        assert!(at_edge >= 0.45, "hard cut: {:?}", &cut[edge - 3..edge + 3]);
        let blended = run(4);
        assert!(
            blended[edge - 3..edge + 3].iter().all(|v| v.abs() < 1e-6),
            "blended: the edge moved: {:?}",
            &blended[edge - 3..edge + 3]
        );
        let step = blended
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f32::max);
        assert!(step <= 0.2, "blended: largest step {step}");
    }
}
