//! Periodicity detection (seed 003, "Periodicity Detection"): the two vectors u, v of the
//! lattice a near-regular exemplar repeats on.
//!
//! Deviation from the seed: it takes the two strongest Fourier coefficients as bisectors of
//! two sectors and searches the autocorrelation inside them, without saying how wide a
//! sector is. The spectral peaks of an oblique lattice lie along the *reciprocal* vectors,
//! which are perpendicular to the other basis vector and can be far from u and v (24° for
//! (40,0)/(13,29)), so we search the whole autocorrelation instead: in two dimensions the
//! two shortest linearly independent lattice vectors always form a basis, so the shortest
//! strong ACF maximum is u and the shortest strong maximum not collinear with it is v —
//! the seed's "smallest periodicity" rule, without the sectors.

use crate::raster::Raster;
use crate::stats::Acf;

/// A detected lattice and how strongly the exemplar repeats on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Periodicity {
    /// First periodicity vector, in pixels (the shortest).
    pub u: (i64, i64),
    /// Second periodicity vector, in pixels (the shortest not collinear with u).
    pub v: (i64, i64),
    /// The smaller of the normalised autocorrelations at u and v (1 = exact repetition).
    pub strength: f64,
}

/// Normalised autocorrelation above which a maximum counts as a repetition.
const MIN_STRENGTH: f64 = 0.5;
/// A candidate must reach this fraction of the strongest maximum.
const RELATIVE_STRENGTH: f64 = 0.9;

/// Detects the periodicity lattice of `image` (its channels averaged), or `None` for a
/// stochastic exemplar without strong repetition. Lags up to half the image in each axis
/// are searched, so the image must hold at least two periods in each direction.
pub fn detect_lattice(image: &Raster) -> Option<Periodicity> {
    let c = image.channels;
    let grey = Raster {
        width: image.width,
        height: image.height,
        channels: 1,
        data: image
            .data
            .chunks_exact(c)
            .map(|px| px.iter().sum::<f32>() / c as f32)
            .collect(),
    };
    let acf = Acf::new(&grey);
    let (hx, hy) = ((grey.width / 2) as i64, (grey.height / 2) as i64);
    // The ACF is symmetric (R(−d) = R(d)); its values over the window, by lag.
    let at = |dx: i64, dy: i64| acf.unbiased(dx, dy);
    let mut maxima: Vec<((i64, i64), f64)> = Vec::new();
    for dy in 0..=hy {
        for dx in -hx..=hx {
            if (dy == 0 && dx <= 1) || dx.abs() == hx || dy == hy {
                continue;
            }
            let value = at(dx, dy);
            if value < MIN_STRENGTH {
                continue;
            }
            let is_max = (-1..=1)
                .all(|ey| (-1..=1).all(|ex| (ex == 0 && ey == 0) || at(dx + ex, dy + ey) <= value));
            if is_max {
                maxima.push(((dx, dy), value));
            }
        }
    }
    let best = maxima.iter().map(|m| m.1).fold(0.0, f64::max);
    let len2 = |p: (i64, i64)| p.0 * p.0 + p.1 * p.1;
    let mut strong: Vec<((i64, i64), f64)> = maxima
        .into_iter()
        .filter(|m| m.1 >= RELATIVE_STRENGTH * best)
        .collect();
    strong.sort_by(|a, b| len2(a.0).cmp(&len2(b.0)).then(b.1.total_cmp(&a.1)));
    let &(u, su) = strong.first()?;
    let &(v, sv) = strong.iter().find(|(p, _)| u.0 * p.1 - u.1 * p.0 != 0)?;
    Some(Periodicity {
        u,
        v,
        strength: su.min(sv),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::same_lattice;
    use rand::{RngExt, SeedableRng};
    use rand_distr::StandardNormal;
    use rand_xoshiro::Xoshiro256PlusPlus;

    /// A smooth pattern exactly periodic on the lattice (u, v): a random sum of cosines
    /// of the lattice coordinates (s, t) = [u v]⁻¹·p, plus Gaussian noise at 10% of its
    /// standard deviation.
    fn periodic_pattern(u: (i64, i64), v: (i64, i64), side: usize, seed: u64) -> Raster {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let det = (u.0 * v.1 - u.1 * v.0) as f64;
        let mut terms = Vec::new();
        for m in -3i64..=3 {
            for n in -3i64..=3 {
                if m == 0 && n == 0 {
                    continue;
                }
                let amp = rng.random_range(0.5..1.0) / (1 + m * m + n * n) as f64;
                terms.push((
                    m as f64,
                    n as f64,
                    amp,
                    rng.random_range(0.0..std::f64::consts::TAU),
                ));
            }
        }
        let mut data: Vec<f64> = (0..side * side)
            .map(|i| {
                let (x, y) = ((i % side) as f64, (i / side) as f64);
                let s = (v.1 as f64 * x - v.0 as f64 * y) / det;
                let t = (-(u.1 as f64) * x + u.0 as f64 * y) / det;
                terms
                    .iter()
                    .map(|&(m, n, a, ph)| a * (std::f64::consts::TAU * (m * s + n * t) + ph).cos())
                    .sum()
            })
            .collect();
        let mean = data.iter().sum::<f64>() / data.len() as f64;
        let sd = (data.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / data.len() as f64).sqrt();
        for d in &mut data {
            *d += 0.1 * sd * rng.sample::<f64, _>(StandardNormal);
        }
        Raster::from_vec(side, side, 1, data.into_iter().map(|x| x as f32).collect()).unwrap()
    }

    /// Acceptance (issue 3, known answers): on (32,0)/(0,24), (40,0)/(13,29) and
    /// (−17,31)/(29,11), with 10% noise and 3 seeds each, the detected lattice is the same
    /// lattice up to a change of basis.
    #[test]
    fn detects_known_lattices_under_noise() {
        for (u, v) in [
            ((32, 0), (0, 24)),
            ((40, 0), (13, 29)),
            ((-17, 31), (29, 11)),
        ] {
            for seed in 1..=3 {
                let image = periodic_pattern(u, v, 256, seed);
                let found = detect_lattice(&image).expect("a periodic pattern must be detected");
                assert!(
                    same_lattice(u, v, found.u, found.v),
                    "lattice {u:?}/{v:?} seed {seed}: detected {:?}/{:?}",
                    found.u,
                    found.v
                );
                assert!(found.strength > 0.9, "strength {}", found.strength);
            }
        }
    }

    #[test]
    fn white_noise_has_no_lattice() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(4);
        let data = (0..128 * 128)
            .map(|_| rng.sample::<f32, _>(StandardNormal))
            .collect();
        let image = Raster::from_vec(128, 128, 1, data).unwrap();
        assert_eq!(detect_lattice(&image), None);
    }
}
