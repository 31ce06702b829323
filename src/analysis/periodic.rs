//! Moisan's periodic + smooth decomposition ("Periodic plus smooth image
//! decomposition", J. Math. Imaging Vis. 39, 2011), used by seed 000 §3.1.5 so that the
//! FFT-based methods see no border cross in the spectrum.

use rustfft::num_complex::Complex64;

use crate::fft::RealFft2;

/// Splits a row-major `width × height` plane into (periodic, smooth) with
/// `periodic + smooth = plane`. The periodic component's periodic discrete Laplacian
/// equals the plane's interior Laplacian; the smooth component has zero mean.
pub fn periodic_smooth(plane: &[f64], width: usize, height: usize) -> (Vec<f64>, Vec<f64>) {
    let (w, h) = (width, height);
    // Boundary image v: the jumps across opposite borders (Moisan, eq. 9).
    let mut v = vec![0.0; w * h];
    for x in 0..w {
        let d = plane[(h - 1) * w + x] - plane[x];
        v[x] += d;
        v[(h - 1) * w + x] -= d;
    }
    for y in 0..h {
        let d = plane[y * w + w - 1] - plane[y * w];
        v[y * w] += d;
        v[y * w + w - 1] -= d;
    }
    // Half spectra (real FFTs): the divisor is even in each frequency.
    let mut plan = RealFft2::new(w, h);
    let hw = plan.half_width();
    let mut spec = plan.forward(&v);
    let two_pi = 2.0 * std::f64::consts::PI;
    for q in 0..h {
        let cy = 2.0 * (two_pi * q as f64 / h as f64).cos();
        for r in 0..hw {
            let denom = 2.0 * (two_pi * r as f64 / w as f64).cos() + cy - 4.0;
            let k = q * hw + r;
            spec[k] = if q == 0 && r == 0 {
                Complex64::default()
            } else {
                spec[k] / denom
            };
        }
    }
    let smooth = plan.inverse(spec);
    let periodic = plane.iter().zip(&smooth).map(|(u, s)| u - s).collect();
    (periodic, smooth)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn periodic_laplacian(p: &[f64], w: usize, h: usize, x: usize, y: usize) -> f64 {
        let at = |x: usize, y: usize| p[y * w + x];
        at((x + 1) % w, y) + at((x + w - 1) % w, y) + at(x, (y + 1) % h) + at(x, (y + h - 1) % h)
            - 4.0 * at(x, y)
    }

    /// Interior Laplacian: neighbours outside the image are replaced by the centre
    /// value (the definition Moisan's theorem uses).
    fn interior_laplacian(u: &[f64], w: usize, h: usize, x: usize, y: usize) -> f64 {
        let c = u[y * w + x];
        let mut s = 0.0;
        for (dx, dy) in [(1i64, 0i64), (-1, 0), (0, 1), (0, -1)] {
            let (nx, ny) = (x as i64 + dx, y as i64 + dy);
            if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                s += u[ny as usize * w + nx as usize] - c;
            }
        }
        s
    }

    #[test]
    fn periodic_component_has_the_interior_laplacian() {
        let (w, h) = (17, 12);
        let u: Vec<f64> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                0.3 * x - 0.2 * y + (0.9 * x).sin() * (0.4 * y).cos()
            })
            .collect();
        let (p, s) = periodic_smooth(&u, w, h);
        for y in 0..h {
            for x in 0..w {
                let lp = periodic_laplacian(&p, w, h, x, y);
                let lu = interior_laplacian(&u, w, h, x, y);
                assert!((lp - lu).abs() < 1e-9, "({x},{y}) {lp} vs {lu}");
                assert!((p[y * w + x] + s[y * w + x] - u[y * w + x]).abs() < 1e-12);
            }
        }
        assert!(s.iter().sum::<f64>().abs() < 1e-9);
    }
}
