//! The Gaussian L-filter (ISO 16610-61 weighting function, ISO 25178-3 scale-limited
//! surfaces): separates waviness (wavelengths longer than the cut-off) from roughness.
//!
//! The weighting function is s(x, y) = 1/(α²λc²) · exp(−π (x² + y²)/(α²λc²)) with
//! α = √(ln 2 / π), whose transfer function exp(−π (α λc f)²) passes 50% of a sine at
//! the cut-off wavelength λc. The filter is applied by FFT over a zero-padded grid and
//! normalised by the filtered mask of defined points: the zeroth-order Gaussian
//! regression filter (ISO 16610-71), which equals the plain Gaussian filter wherever the
//! whole weighting function lies on defined points, and stays unbiased at the map's
//! edges and around missing points instead of pulling them toward zero.

use crate::error::{Error, Result};
use crate::fft::RealFft2;
use crate::raster::Raster;

/// ISO 16610-61's α = √(ln 2 / π).
pub fn alpha() -> f64 {
    (std::f64::consts::LN_2 / std::f64::consts::PI).sqrt()
}

/// The Gaussian's transfer function at `f` cycles per unit for cut-off `lambda` (same
/// unit): 0.5 at f = 1/λc.
pub fn transmission(f: f64, lambda: f64) -> f64 {
    let a = alpha() * lambda * f;
    (-std::f64::consts::PI * a * a).exp()
}

/// Largest padded grid the filter transforms (2²⁶ points, 1 GiB of complex f64).
const MAX_PADDED: usize = 1 << 26;

/// The smallest n ≥ `at_least` whose only prime factors are 2, 3 and 5 (fast FFT sizes).
fn smooth_size(at_least: usize) -> usize {
    let mut n = at_least.max(1);
    loop {
        let mut m = n;
        for p in [2, 3, 5] {
            while m.is_multiple_of(p) {
                m /= p;
            }
        }
        if m == 1 {
            return n;
        }
        n += 1;
    }
}

/// The waviness of every channel of `raster`: its Gaussian low-pass at cut-off
/// wavelengths `(lambda_x, lambda_y)` in pixels (one λc in µm over the x and y
/// spacings). Missing points (NaN) stay missing and do not weigh on their neighbours.
/// Refuses cut-offs that are not positive and finite, and grids whose padded transform
/// would pass [`MAX_PADDED`] points.
pub fn waviness(raster: &Raster, (lambda_x, lambda_y): (f64, f64)) -> Result<Raster> {
    for (axis, l) in [("x", lambda_x), ("y", lambda_y)] {
        if !(l.is_finite() && l > 0.0) {
            return Err(Error::param(
                "lfilter",
                format!("{l} px along {axis}"),
                "a positive, finite cut-off wavelength",
            ));
        }
    }
    let (w, h) = (raster.width, raster.height);
    // The weighting function is below 10⁻⁶ of its peak beyond one cut-off wavelength, so
    // padding by λc keeps the circular convolution from folding one edge onto the other
    // (however long λc is against the map: the kernel's periodic copies must fall off
    // too).
    let pad = |side: usize, l: f64| {
        let l = l.ceil();
        if l < MAX_PADDED as f64 {
            side.checked_add(l as usize)
        } else {
            None
        }
    };
    let padded = match (pad(w, lambda_x), pad(h, lambda_y)) {
        (Some(a), Some(b)) if a <= MAX_PADDED && b <= MAX_PADDED => {
            Some((smooth_size(a), smooth_size(b)))
        }
        _ => None,
    };
    let Some((pw, ph)) = padded.filter(|(a, b)| a.checked_mul(*b).is_some_and(|n| n <= MAX_PADDED))
    else {
        return Err(Error::Limits(format!(
            "the L-filter of a {w}×{h} map at a cut-off of {lambda_x:.1}×{lambda_y:.1} px pads it past {MAX_PADDED} (2^26) points; give a shorter cut-off"
        )));
    };
    let mut fft = RealFft2::new(pw, ph);
    let half = fft.half_width();
    // The transfer function on the half spectrum (frequencies in cycles per pixel).
    let gain: Vec<f64> = (0..ph)
        .flat_map(|ky| {
            let fy = (if ky <= ph / 2 {
                ky as f64
            } else {
                ky as f64 - ph as f64
            }) / ph as f64;
            let gy = transmission(fy, lambda_y);
            (0..half).map(move |kx| gy * transmission(kx as f64 / pw as f64, lambda_x))
        })
        .collect();
    let mut filter = |plane: &[f64]| {
        let mut spectrum = fft.forward(plane);
        for (s, g) in spectrum.iter_mut().zip(&gain) {
            *s *= g;
        }
        fft.inverse(spectrum)
    };
    let mut out = raster.clone();
    let mut mask = vec![0.0f64; pw * ph];
    let mut values = vec![0.0f64; pw * ph];
    for c in 0..raster.channels {
        let plane = raster.channel_f64(c);
        for y in 0..h {
            for x in 0..w {
                let z = plane[y * w + x];
                let ok = z.is_finite();
                mask[y * pw + x] = if ok { 1.0 } else { 0.0 };
                values[y * pw + x] = if ok { z } else { 0.0 };
            }
        }
        let (num, den) = (filter(&values), filter(&mask));
        let mut smooth = vec![f64::NAN; w * h];
        for y in 0..h {
            for x in 0..w {
                let d = den[y * pw + x];
                if plane[y * w + x].is_finite() && d > 1e-9 {
                    smooth[y * w + x] = num[y * pw + x] / d;
                }
            }
        }
        out.set_channel_f64(c, &smooth);
    }
    Ok(out)
}

/// The roughness (scale-limited SL surface) of every channel of `raster`: the raster
/// less its [`waviness`] at cut-offs `(lambda_x, lambda_y)` in pixels.
pub fn roughness(raster: &Raster, lambdas: (f64, f64)) -> Result<Raster> {
    let wavy = waviness(raster, lambdas)?;
    let mut out = raster.clone();
    for (z, s) in out.data.iter_mut().zip(&wavy.data) {
        *z -= s;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Amplitude of a sine along x of wavelength `period` px, by projection over the
    /// columns at least `margin` from the left and right edges (the sine is constant
    /// along y, where the edges bias nothing).
    fn amplitude(r: &Raster, period: f64, margin: usize) -> f64 {
        let (mut s, mut c, mut n) = (0.0, 0.0, 0.0);
        for y in 0..r.height {
            for x in margin..r.width - margin {
                let p = 2.0 * std::f64::consts::PI * x as f64 / period;
                let z = r.data[y * r.width + x] as f64;
                s += z * p.sin();
                c += z * p.cos();
                n += 1.0;
            }
        }
        2.0 * (s * s + c * c).sqrt() / n
    }

    fn sine(w: usize, h: usize, period: f64) -> Raster {
        let data = (0..w * h)
            .map(|i| (2.0 * std::f64::consts::PI * (i % w) as f64 / period).sin() as f32)
            .collect();
        Raster::from_vec(w, h, 1, data).unwrap()
    }

    /// ISO 16610-61: a sine at the cut-off wavelength passes with 50% ± 1% of its
    /// amplitude into the waviness, and so into the roughness too (issue 36's
    /// acceptance). A sine at a fifth of the cut-off is all roughness, one at five
    /// cut-offs all waviness.
    #[test]
    fn transmission_at_the_cut_off_is_one_half() {
        let (w, h, lambda) = (400, 64, 40.0);
        let r = sine(w, h, lambda);
        let margin = lambda as usize;
        let wavy = waviness(&r, (lambda, lambda)).unwrap();
        let rough = roughness(&r, (lambda, lambda)).unwrap();
        let (tw, tr) = (
            amplitude(&wavy, lambda, margin),
            amplitude(&rough, lambda, margin),
        );
        eprintln!("transmission at the cut-off: waviness {tw:.4}, roughness {tr:.4}");
        assert!((tw - 0.5).abs() < 0.01, "waviness transmission {tw}");
        assert!((tr - 0.5).abs() < 0.01, "roughness transmission {tr}");
        let short = sine(w, h, lambda / 5.0);
        let t = amplitude(
            &waviness(&short, (lambda, lambda)).unwrap(),
            lambda / 5.0,
            margin,
        );
        assert!(t < 1e-6, "a fifth of the cut-off passes {t}");
        // 1000 px between the margins: whole periods, so the projection is exact.
        let long = sine(1080, 8, 200.0);
        let t = amplitude(&waviness(&long, (lambda, lambda)).unwrap(), 200.0, margin);
        let want = transmission(1.0 / 200.0, lambda);
        assert!(
            (t - want).abs() < 0.01,
            "five cut-offs pass {t}, expected {want}"
        );
    }

    /// Edges and holes do not bias the waviness: a constant stays that constant.
    #[test]
    fn a_constant_with_holes_stays_constant() {
        let mut r = Raster::from_vec(50, 30, 1, vec![3.0; 1500]).unwrap();
        r.data[7] = f32::NAN;
        r.data[800] = f32::NAN;
        let wavy = waviness(&r, (25.0, 25.0)).unwrap();
        for (i, v) in wavy.data.iter().enumerate() {
            if i == 7 || i == 800 {
                assert!(v.is_nan());
            } else {
                assert!((v - 3.0).abs() < 1e-5, "{i}: {v}");
            }
        }
    }

    /// The waviness at every point equals the directly summed, edge-normalised Gaussian
    /// mean (the slow reference), also for cut-offs longer than the map, where a kernel
    /// wrapped around the padded grid would pull each end toward the other.
    #[test]
    fn matches_the_direct_weighted_mean_at_any_cut_off() {
        let (w, h) = (100, 3);
        let z = |x: usize| (x as f64 * 0.37).sin() + x as f64 * 0.05;
        let data = (0..w * h).map(|i| z(i % w) as f32).collect();
        let r = Raster::from_vec(w, h, 1, data).unwrap();
        for lambda in [10.0, 60.0, 200.0, 400.0] {
            let wavy = waviness(&r, (lambda, 1e-3)).unwrap();
            let g = |d: f64| (-std::f64::consts::PI * (d / (alpha() * lambda)).powi(2)).exp();
            for x in [0, 1, 37, 98, 99] {
                let (num, den) = (0..w).fold((0.0, 0.0), |(n, d), t| {
                    let k = g(t as f64 - x as f64);
                    (n + k * z(t), d + k)
                });
                let want = num / den;
                let got = wavy.data[w + x] as f64;
                assert!(
                    (got - want).abs() < 1e-4,
                    "λc {lambda}, x {x}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn refuses_a_bad_cut_off() {
        let r = Raster::from_vec(8, 8, 1, vec![0.0; 64]).unwrap();
        assert!(waviness(&r, (0.0, 1.0)).is_err());
        assert!(waviness(&r, (f64::NAN, 1.0)).is_err());
    }
}
