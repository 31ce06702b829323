//! Translation vectors of a near-regular texture from its normalised autocorrelation
//! (seed 002, §3.3, steps 1–7 and eq. 9).
//!
//! 1. Mark the local maxima of the right half of the autocorrelation γ ([`crate::analysis::ncc`]).
//! 2. Form the candidate set c₁ of vectors from the origin to them.
//! 3. Sort c₁ by ascending length.
//! 4. For each v₁ in c₁, c₂ holds the vectors sorted after it.
//! 5. Reduce each v₂ in c₂ to v₂ − ⌊v₂·v₁/|v₁|²⌉·v₁ (negated if it falls in the left
//!    half), and drop duplicates and vectors shorter than v₁.
//! 6. Rate each pair by its goodness (eq. 9): g = (Σ γ(a·v₁ + b·v₂))^α / n over the n
//!    multiples in the right half, excluding the origin and shifts whose overlap is under
//!    85% of the candidate tile, with α = 1.12. g = 0 if v₁ or v₂ has no valid multiple.
//! 7. The pair with the highest goodness wins.
//!
//! Readings and bounds where the paper is silent (deviations, each named):
//! - "Overlappings of less than an 85% of the candidate tile": a multiple m counts when
//!   the image and its copy shifted by m overlap in at least 0.85·|v₁ × v₂| pixels, i.e.
//!   when γ(m) compares most of a tile's worth of texture (observation v of §3.3: maxima
//!   from small overlaps at the borders are spurious).
//! - A sum Σγ ≤ 0 has no real power α; its goodness is 0.
//! - Cost bounds: local maxima are taken within half the image in each axis (a repeat
//!   farther out cannot show twice), c₁ keeps the [`MAX_CANDIDATES`] maxima with the
//!   highest γ (the paper lists them all; on photographs most are noise, and the pairs
//!   grow quadratically), and tiles under [`MIN_TILE_AREA`] pixels are not considered.
//! - **No lattice.** The paper always returns a pair. We report none when the best pair's
//!   mean γ over its multiples is under [`MIN_MEAN_GAMMA`] (a stochastic texture), so the
//!   caller can say so and suggest `--stochastic` or `--lattice`.
//! - **Ridges.** Where γ does not dip on the way to a reported vector ([`dip_before`]),
//!   [`ridge_notes`] says so: the vector's length was picked along a ridge, not measured.

use crate::analysis::ncc::{NccMap, autocorrelation};
use crate::error::Result;
use crate::raster::Raster;

/// α of eq. (9).
pub const ALPHA: f64 = 1.12;
/// Least overlap of a counted multiple, as a share of the tile's area.
pub const MIN_OVERLAP: f64 = 0.85;
/// Most local maxima kept in c₁ (the highest).
pub const MAX_CANDIDATES: usize = 48;
/// Smallest tile considered, in pixels.
pub const MIN_TILE_AREA: i64 = 16;
/// Least mean γ over the multiples of the best pair for a lattice to be reported.
pub const MIN_MEAN_GAMMA: f64 = 0.3;

/// Least dip of γ between the origin and a lattice vector ([`dip_before`]) for the vector
/// to count as a repetition rather than a step along a ridge.
pub const RIDGE_DIP: f64 = 0.05;

/// How far γ dips on the way to `v`: γ(v) minus the least γ at ¼, ½ and ¾ of `v` (lags
/// rounded to whole pixels). A repetition at `v` shows a dip. Where γ stays up all the
/// way (a dip under [`RIDGE_DIP`]), γ is a ridge along `v` — stripes, a lay, the mortar
/// lines of a brick wall — on which any step repeats about as well, so eq. 9, which
/// favours small tiles, picks the step from noise and `v`'s length means little. Not in
/// seed 002: a check for the caller to report.
pub fn dip_before(map: &NccMap, v: (i64, i64)) -> f64 {
    let at = |t: f64| {
        map.at(
            (v.0 as f64 * t).round() as i64,
            (v.1 as f64 * t).round() as i64,
        )
    };
    at(1.0)
        - [0.25, 0.5, 0.75]
            .map(at)
            .into_iter()
            .fold(f64::MAX, f64::min)
}

/// A note for each of `t`'s vectors that γ does not dip on the way to
/// ([`dip_before`] under [`RIDGE_DIP`]), for the user: its length is not a measured
/// repetition.
pub fn ridge_notes(map: &NccMap, t: &Translation) -> Vec<String> {
    [("v1", t.v1), ("v2", t.v2)]
        .into_iter()
        .filter_map(|(name, v)| {
            let (dip, at) = (dip_before(map, v), map.at(v.0, v.1));
            (dip < RIDGE_DIP).then(|| {
                format!(
                    "note: the autocorrelation does not dip on the way to {name} = ({}, {}) (γ {:.3} at least, {at:.3} at {name}): a ridge, as of stripes or mortar lines, along which any step repeats about as well, so {name}'s length is not a measured repetition; give the lattice with `lattice` \"ux,uy;vx,vy\" if it is wrong",
                    v.0,
                    v.1,
                    at - dip
                )
            })
        })
        .collect()
}

/// Two translation vectors and their goodness (eq. 9).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Translation {
    /// First vector (pixels; the shorter).
    pub v1: (i64, i64),
    /// Second vector (pixels).
    pub v2: (i64, i64),
    /// g({v₁, v₂}).
    pub goodness: f64,
    /// Mean γ over the multiples counted in the goodness.
    pub mean_gamma: f64,
}

/// In the right half-plane: x > 0, or x = 0 and y > 0.
fn right_half((x, y): (i64, i64)) -> bool {
    x > 0 || (x == 0 && y > 0)
}

fn len2((x, y): (i64, i64)) -> i64 {
    x * x + y * y
}

/// Steps 1–3: local maxima of the right half (within half the image), the
/// [`MAX_CANDIDATES`] highest, sorted by length (then by position).
pub fn candidates(map: &NccMap) -> Vec<(i64, i64)> {
    let (x0, x1) = map.dx_range();
    let (y0, y1) = map.dy_range();
    let (hx, hy) = ((x1 - x0) / 4, (y1 - y0) / 4);
    let mut found: Vec<((i64, i64), f64)> = Vec::new();
    for dy in -hy..=hy {
        for dx in 0..=hx {
            if !right_half((dx, dy)) {
                continue;
            }
            let g = map.at(dx, dy);
            if g <= 0.0 {
                continue;
            }
            // A maximum: above the neighbours before it in scan order, not below those
            // after it (one point per plateau).
            let mut is_max = true;
            for (ox, oy) in [
                (-1, -1),
                (0, -1),
                (1, -1),
                (-1, 0),
                (1, 0),
                (-1, 1),
                (0, 1),
                (1, 1),
            ] {
                let n = map.at(dx + ox, dy + oy);
                let before = oy < 0 || (oy == 0 && ox < 0);
                if (before && n >= g) || (!before && n > g) {
                    is_max = false;
                    break;
                }
            }
            if is_max {
                found.push(((dx, dy), g));
            }
        }
    }
    found.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    found.truncate(MAX_CANDIDATES);
    let mut c1: Vec<(i64, i64)> = found.into_iter().map(|(v, _)| v).collect();
    c1.sort_by_key(|&v| (len2(v), v));
    c1
}

/// Eq. (9) for the pair {v₁, v₂}: (goodness, mean γ), both 0 without valid multiples.
pub fn goodness(map: &NccMap, v1: (i64, i64), v2: (i64, i64)) -> (f64, f64) {
    let det = v1.0 * v2.1 - v1.1 * v2.0;
    if det.abs() < MIN_TILE_AREA {
        return (0.0, 0.0);
    }
    let need = (MIN_OVERLAP * det.abs() as f64).ceil() as usize;
    let (x0, x1) = map.dx_range();
    let (y0, y1) = map.dy_range();
    let (mx, my) = (x1.max(-x0), y1.max(-y0));
    // |a| = |m × v₂|/|det| ≤ (mx·|v₂y| + my·|v₂x|)/|det|, and b likewise.
    let ra = (mx * v2.1.abs() + my * v2.0.abs()) / det.abs() + 1;
    let rb = (mx * v1.1.abs() + my * v1.0.abs()) / det.abs() + 1;
    let (mut sum, mut n) = (0.0, 0usize);
    let (mut on_v1, mut on_v2) = (false, false);
    for a in -ra..=ra {
        for b in -rb..=rb {
            let m = (a * v1.0 + b * v2.0, a * v1.1 + b * v2.1);
            if !right_half(m) || map.overlap(m.0, m.1) < need {
                continue;
            }
            sum += map.at(m.0, m.1);
            n += 1;
            on_v1 |= b == 0;
            on_v2 |= a == 0;
        }
    }
    if n == 0 || !on_v1 || !on_v2 || sum <= 0.0 {
        return (0.0, 0.0);
    }
    (sum.powf(ALPHA) / n as f64, sum / n as f64)
}

/// Steps 4–7 on an autocorrelation map: the best pair, or None when no pair has a
/// positive goodness or the best one's mean γ is under [`MIN_MEAN_GAMMA`].
pub fn from_autocorrelation(map: &NccMap) -> Option<Translation> {
    best_pair(map).filter(|b| b.mean_gamma >= MIN_MEAN_GAMMA)
}

/// Steps 4–7 without the lattice test: the pair of highest goodness, None only when no
/// pair has a positive one.
pub fn best_pair(map: &NccMap) -> Option<Translation> {
    let c1 = candidates(map);
    let mut best: Option<Translation> = None;
    for (k, &v1) in c1.iter().enumerate() {
        let l1 = len2(v1);
        let mut c2: Vec<(i64, i64)> = Vec::new();
        for &v in &c1[k + 1..] {
            // ⌊v₂·v₁/|v₁|²⌉: round to nearest, halves away from zero.
            let dot = v.0 * v1.0 + v.1 * v1.1;
            let q = (dot as f64 / l1 as f64).round() as i64;
            let mut r = (v.0 - q * v1.0, v.1 - q * v1.1);
            if !right_half(r) {
                r = (-r.0, -r.1);
            }
            if r == (0, 0) || len2(r) < l1 || c2.contains(&r) {
                continue;
            }
            c2.push(r);
        }
        for v2 in c2 {
            let (g, mean) = goodness(map, v1, v2);
            if g > best.map_or(0.0, |b| b.goodness) {
                best = Some(Translation {
                    v1,
                    v2,
                    goodness: g,
                    mean_gamma: mean,
                });
            }
        }
    }
    best
}

/// What `surftile bake --method rsgf` can do for an exemplar without a lattice.
pub const BAKE_WITHOUT_LATTICE: &str = "for a stochastic texture pass `stochastic`, or give the vectors with `lattice` \"ux,uy;vx,vy\"";

/// The error for an exemplar `what` without a detectable lattice: the figure that
/// decided it, and `advice`, what to do instead (e.g. [`BAKE_WITHOUT_LATTICE`]).
pub fn no_lattice(what: &str, best: Option<Translation>, advice: &str) -> crate::error::Error {
    crate::error::Error::Analysis {
        what: what.to_string(),
        message: format!(
            "no lattice detected (the best pair's mean autocorrelation at its multiples is {:.3}, under {MIN_MEAN_GAMMA}): {advice}",
            best.map_or(0.0, |t| t.mean_gamma),
        ),
    }
}

/// The translation vectors of `image` (all channels, eqs. 6–8), or None for a texture
/// without a detectable lattice.
pub fn estimate(image: &Raster) -> Result<Option<Translation>> {
    Ok(from_autocorrelation(&autocorrelation(image)?))
}

/// Advice for `surftile lattice` on a texture without a lattice.
pub const SYNTHESISE_WITHOUT_LATTICE: &str = "to synthesise it anyway, bake it with `method` rsgf and `stochastic`, or with `lattice` \"ux,uy;vx,vy\"";

/// The lattice of a near-regular image `what` (missing points refused): its
/// autocorrelation map, the best translation pair, and notes on ridges along which the
/// pair's lengths are not measured repetitions. A texture without a lattice is refused
/// with [`SYNTHESISE_WITHOUT_LATTICE`].
pub fn estimate_lattice(image: &Raster, what: &str) -> Result<(NccMap, Translation, Vec<String>)> {
    if image.data.iter().any(|v| v.is_nan()) {
        return Err(crate::error::Error::Analysis {
            what: what.to_string(),
            message: format!(
                "{} of {} points are missing (NaN); the autocorrelation needs a complete map",
                image.count_nan(),
                image.data.len()
            ),
        });
    }
    let map = autocorrelation(image)?;
    let t = match best_pair(&map) {
        Some(t) if t.mean_gamma >= MIN_MEAN_GAMMA => t,
        other => return Err(no_lattice(what, other, SYNTHESISE_WITHOUT_LATTICE)),
    };
    let notes = ridge_notes(&map, &t);
    Ok((map, t, notes))
}

/// The autocorrelation `map` as an RGB image (`width × height × 3` bytes), γ from −1
/// (black) to 1 (white), zero shift at the centre in green, the multiples of `t`'s
/// vectors in red.
pub fn lattice_plot(map: &NccMap, t: &Translation) -> (usize, usize, Vec<u8>) {
    let (w, h) = (map.width, map.height);
    let mut px: Vec<u8> = map
        .gamma
        .iter()
        .flat_map(|g| {
            let v = ((g + 1.0) * 127.5).round().clamp(0.0, 255.0) as u8;
            [v, v, v]
        })
        .collect();
    let (x0, _) = map.dx_range();
    let (y0, _) = map.dy_range();
    let mut mark = |dx: i64, dy: i64, colour: [u8; 3]| {
        for (ox, oy) in [
            (0, 0),
            (-1, 0),
            (1, 0),
            (0, -1),
            (0, 1),
            (-2, 0),
            (2, 0),
            (0, -2),
            (0, 2),
        ] {
            let (i, j) = (dx - x0 + ox, dy - y0 + oy);
            if i >= 0 && j >= 0 && (i as usize) < w && (j as usize) < h {
                let k = (j as usize * w + i as usize) * 3;
                px[k..k + 3].copy_from_slice(&colour);
            }
        }
    };
    // |a| = |m × v₂|/|det| and |b| = |v₁ × m|/|det| over the map's shifts m.
    let det = (t.v1.0 * t.v2.1 - t.v1.1 * t.v2.0).abs().max(1);
    let (mx, my) = (w as i64, h as i64);
    let ra = (mx * t.v2.1.abs() + my * t.v2.0.abs()) / det + 1;
    let rb = (mx * t.v1.1.abs() + my * t.v1.0.abs()) / det + 1;
    for a in -ra..=ra {
        for b in -rb..=rb {
            let (dx, dy) = (a * t.v1.0 + b * t.v2.0, a * t.v1.1 + b * t.v2.1);
            if dx >= x0 && dx <= -x0 + w as i64 && dy >= y0 && dy <= -y0 + h as i64 {
                mark(dx, dy, [230, 30, 30]);
            }
        }
    }
    mark(0, 0, [30, 200, 30]);
    (w, h, px)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::Lattice;
    use crate::lattice::periodic_pattern as periodic;

    /// The roller issue's synthetic lattices, from the same generator, are recovered
    /// exactly: the estimated pair spans the same lattice (equal Hermite normal forms).
    #[test]
    fn synthetic_lattices_are_recovered_exactly() {
        for (u, v) in [
            ((32, 0), (0, 24)),
            ((40, 0), (13, 29)),
            ((-17, 31), (29, 11)),
        ] {
            let image = periodic(200, 180, u, v);
            let t = estimate(&image).unwrap().expect("a lattice");
            let want = Lattice::from_basis(u, v).unwrap();
            let got = Lattice::from_basis(t.v1, t.v2).unwrap();
            assert_eq!(got, want, "{u:?}/{v:?}: found {:?}/{:?}", t.v1, t.v2);
            assert!(t.mean_gamma > 0.9, "{t:?}");
        }
    }

    /// Eq. (9) prefers the smallest tile: on an exact lattice a doubled tile has the same
    /// mean γ (1) over fewer multiples, so its goodness n^(α−1) is lower; a wrong
    /// vector's is lower still.
    #[test]
    fn goodness_prefers_the_smallest_tile() {
        let image = periodic(200, 180, (32, 0), (0, 24));
        let map = autocorrelation(&image).unwrap();
        let (g, mean) = goodness(&map, (32, 0), (0, 24));
        let (g2, mean2) = goodness(&map, (64, 0), (0, 24));
        let (g3, _) = goodness(&map, (32, 0), (0, 17));
        assert!(mean > 0.99 && mean2 > 0.99, "{mean} {mean2}");
        assert!(g > g2 && g2 > g3, "{g} {g2} {g3}");
        assert_eq!(
            goodness(&map, (3, 0), (0, 4)),
            (0.0, 0.0),
            "tile under 16 px"
        );
    }

    /// White noise has no lattice.
    #[test]
    fn noise_has_no_lattice() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(3);
        let data = (0..128 * 96)
            .map(|_| rng.random_range(0.0f32..1.0))
            .collect();
        let image = Raster::from_vec(128, 96, 1, data).unwrap();
        assert_eq!(estimate(&image).unwrap(), None);
    }
}
