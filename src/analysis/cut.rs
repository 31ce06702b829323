//! Minimum-error boundary cuts: the dynamic programme that follows seed 003's eq. (2)
//! (the paper's A* search is only a speed-up of it), used by the roller's double
//! toroidal tiles and by Efros–Freeman stitching.

#[cfg(test)]
use crate::error::{Error, Result};

#[cfg(test)]
/// Overlap error of seed 003, eq. (1), for an axis-aligned period u = (m, 0): over the
/// strip of `overlap` columns, ψ(r, k) = Σ_c (Y(r, k) − Y(r, m + k))² summed over
/// channels. `plane` is row-major `width × height × channels`; needs m + overlap ≤ width.
/// Returns a row-major `overlap × height` error matrix.
pub fn overlap_error_horizontal(
    plane: &[f32],
    width: usize,
    height: usize,
    channels: usize,
    m: usize,
    overlap: usize,
) -> Result<Vec<f64>> {
    if m + overlap > width || plane.len() < width * height * channels {
        return Err(Error::TooSmall {
            what: "exemplar".into(),
            message: format!(
                "a period of {m} px plus an overlap of {overlap} px needs {} columns; the exemplar has {width}",
                m + overlap
            ),
        });
    }
    let mut err = vec![0.0; overlap * height];
    for r in 0..height {
        for k in 0..overlap {
            err[r * overlap + k] = (0..channels)
                .map(|c| {
                    let a = plane[(r * width + k) * channels + c] as f64;
                    let b = plane[(r * width + m + k) * channels + c] as f64;
                    (a - b).powi(2)
                })
                .sum();
        }
    }
    Ok(err)
}

/// The 8-connected top-to-bottom path through a row-major `width × height` error matrix
/// (one column per row, neighbouring rows at most one column apart) with the least total
/// error. Returns the column of each row. Ties go to the leftmost column, so the result is
/// deterministic. An empty matrix gives an empty path.
pub fn min_cut_vertical(err: &[f64], width: usize, height: usize) -> Vec<usize> {
    if width == 0 || height == 0 {
        return Vec::new();
    }
    // cost[r][c]: least error of a path from row 0 to (r, c); from[r][c]: its column in r − 1.
    let mut cost = err[..width].to_vec();
    let mut from = vec![0usize; width * height];
    for r in 1..height {
        let mut next = vec![0.0; width];
        for c in 0..width {
            let lo = c.saturating_sub(1);
            let hi = (c + 1).min(width - 1);
            let mut best = lo;
            for p in lo + 1..=hi {
                if cost[p] < cost[best] {
                    best = p;
                }
            }
            next[c] = cost[best] + err[r * width + c];
            from[r * width + c] = best;
        }
        cost = next;
    }
    let mut c = (1..width).fold(0, |b, i| if cost[i] < cost[b] { i } else { b });
    let mut path = vec![0; height];
    for r in (0..height).rev() {
        path[r] = c;
        c = from[r * width + c];
    }
    path
}

#[cfg(test)]
/// Total error of a path (the quantity [`min_cut_vertical`] minimises).
pub fn path_error(err: &[f64], width: usize, path: &[usize]) -> f64 {
    path.iter()
        .enumerate()
        .map(|(r, &c)| err[r * width + c])
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The slow twin: every 8-connected path, enumerated.
    fn brute_force_best(err: &[f64], width: usize, height: usize) -> f64 {
        fn walk(err: &[f64], w: usize, h: usize, r: usize, c: usize, acc: f64, best: &mut f64) {
            let acc = acc + err[r * w + c];
            if r + 1 == h {
                *best = best.min(acc);
                return;
            }
            for n in c.saturating_sub(1)..=(c + 1).min(w - 1) {
                walk(err, w, h, r + 1, n, acc, best);
            }
        }
        let mut best = f64::INFINITY;
        for c in 0..width {
            walk(err, width, height, 0, c, 0.0, &mut best);
        }
        best
    }

    proptest! {
        /// The dynamic programme finds a valid path whose error equals the brute-force
        /// optimum over all paths.
        #[test]
        fn dp_cut_matches_brute_force(width in 1usize..5, height in 1usize..6,
                                      seed in proptest::collection::vec(0u32..1000, 30)) {
            let err: Vec<f64> = (0..width * height).map(|i| seed[i % seed.len()] as f64 * 0.01).collect();
            let path = min_cut_vertical(&err, width, height);
            prop_assert_eq!(path.len(), height);
            prop_assert!(path.iter().all(|&c| c < width));
            prop_assert!(path.windows(2).all(|p| p[0].abs_diff(p[1]) <= 1));
            let got = path_error(&err, width, &path);
            let best = brute_force_best(&err, width, height);
            prop_assert!((got - best).abs() < 1e-9, "dp {} vs brute force {}", got, best);
        }
    }

    /// On an exactly periodic exemplar with the true period the overlap error is zero
    /// everywhere (ALGORITHMS.md §2: ψ ≡ 0), and off the period it is not.
    #[test]
    fn overlap_error_vanishes_at_the_true_period() {
        let (w, h, m) = (40, 6, 12);
        let plane: Vec<f32> = (0..w * h)
            .map(|i| ((i % w) % m) as f32 * 0.5 + (i / w) as f32)
            .collect();
        let err = overlap_error_horizontal(&plane, w, h, 1, m, 8).unwrap();
        assert!(err.iter().all(|&e| e == 0.0));
        let off = overlap_error_horizontal(&plane, w, h, 1, m + 1, 8).unwrap();
        assert!(off.iter().sum::<f64>() > 1.0);
        let e = overlap_error_horizontal(&plane, w, h, 1, 36, 8)
            .unwrap_err()
            .to_string();
        assert!(e.contains("needs 44 columns"), "{e}");
    }
}
