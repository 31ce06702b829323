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
        Ok(StitchParams { patch, overlap })
    }

    /// Patch side M_P in pixels.
    pub fn patch(&self) -> usize {
        self.patch
    }

    /// Overlap o in pixels.
    pub fn overlap(&self) -> usize {
        self.overlap
    }

    /// Patches needed along a side of `n` pixels: the least count with (M_P − o)·count + o ≥ n.
    pub fn count(&self, n: usize) -> usize {
        let step = self.patch - self.overlap;
        n.saturating_sub(self.overlap).div_ceil(step).max(1)
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
                                err[(x - o) * o + r] = if x == o && r.abs_diff(start) > 1 {
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
                                err[x * o + r] = err_of(&pt, x, r);
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
                        err[y * o + x] = err_of(&pt, x, y);
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
            for y in 0..p {
                for x in 0..p {
                    if new(x, y) {
                        let (a, b) = (at(x, y), (y * p + x) * c);
                        canvas[a..a + c].copy_from_slice(&pt[b..b + c]);
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
}
