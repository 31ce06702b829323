//! Missing points (NaN) in measured maps: counting and smooth (harmonic) filling.

use std::collections::VecDeque;

use crate::error::{Error, Result};
use crate::raster::Raster;

/// Fills every NaN sample of every channel with a harmonic interpolant of its finite
/// neighbours: each filled point ends as the mean of its 4 neighbours (Laplace's
/// equation, Neumann at the image border), the measured points unchanged.
///
/// Starts from nearest-neighbour values (multi-source breadth-first search), then runs
/// successive over-relaxation until the largest update is below 1e-7 of the data range
/// or 2000 sweeps. Returns the number of points filled per raster.
pub fn fill_missing(raster: &mut Raster, what: &str) -> Result<usize> {
    let (w, h) = (raster.width, raster.height);
    let mut filled = 0;
    for c in 0..raster.channels {
        let mut plane = raster.channel_f64(c);
        let missing: Vec<usize> = (0..w * h).filter(|&i| !plane[i].is_finite()).collect();
        if missing.is_empty() {
            continue;
        }
        if missing.len() == w * h {
            return Err(Error::decode(what, "every height point is missing (NaN)"));
        }
        filled = filled.max(missing.len());
        nearest_init(&mut plane, w, h);
        let (lo, hi) = plane
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, u), &v| (l.min(v), u.max(v)));
        let tol = 1e-7 * (hi - lo).max(f64::MIN_POSITIVE);
        let omega = 1.9;
        for _ in 0..2000 {
            let mut max_change: f64 = 0.0;
            for &i in &missing {
                let (x, y) = (i % w, i / w);
                let mut sum = 0.0;
                let mut n = 0.0;
                if x > 0 {
                    sum += plane[i - 1];
                    n += 1.0;
                }
                if x + 1 < w {
                    sum += plane[i + 1];
                    n += 1.0;
                }
                if y > 0 {
                    sum += plane[i - w];
                    n += 1.0;
                }
                if y + 1 < h {
                    sum += plane[i + w];
                    n += 1.0;
                }
                if n == 0.0 {
                    continue;
                }
                let delta = sum / n - plane[i];
                plane[i] += omega * delta;
                max_change = max_change.max(delta.abs());
            }
            if max_change < tol {
                break;
            }
        }
        raster.set_channel_f64(c, &plane);
    }
    Ok(filled)
}

/// Replaces non-finite samples by the value of the nearest finite one (4-connected BFS).
fn nearest_init(plane: &mut [f64], w: usize, h: usize) {
    let mut queue: VecDeque<usize> = (0..w * h).filter(|&i| plane[i].is_finite()).collect();
    while let Some(i) = queue.pop_front() {
        let (x, y) = (i % w, i / w);
        let v = plane[i];
        let mut visit = |j: usize| {
            if !plane[j].is_finite() {
                plane[j] = v;
                queue.push_back(j);
            }
        };
        if x > 0 {
            visit(i - 1);
        }
        if x + 1 < w {
            visit(i + 1);
        }
        if y > 0 {
            visit(i - w);
        }
        if y + 1 < h {
            visit(i + w);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A harmonic function (x² − y²) is reproduced inside a hole, since its discrete
    /// Laplacian is zero: the fill must find it.
    #[test]
    fn fills_a_hole_in_a_harmonic_function_exactly() {
        let (w, h) = (24, 20);
        let f = |x: usize, y: usize| (x as f64 - 10.0).powi(2) - (y as f64 - 9.0).powi(2);
        let mut data: Vec<f32> = (0..w * h).map(|i| f(i % w, i / w) as f32).collect();
        for y in 6..13 {
            for x in 7..15 {
                data[y * w + x] = f32::NAN;
            }
        }
        let mut r = Raster::from_vec(w, h, 1, data).unwrap();
        assert_eq!(fill_missing(&mut r, "test").unwrap(), 56);
        for y in 6..13 {
            for x in 7..15 {
                let got = r.get(x, y, 0) as f64;
                assert!(
                    (got - f(x, y)).abs() < 1e-3,
                    "({x},{y}): {got} vs {}",
                    f(x, y)
                );
            }
        }
    }

    #[test]
    fn all_missing_is_an_error() {
        let mut r = Raster::from_vec(3, 3, 1, vec![f32::NAN; 9]).unwrap();
        assert!(fill_missing(&mut r, "x").is_err());
    }
}
