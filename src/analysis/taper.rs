//! Tapering a crop so the FFT sees a periodic signal without a border jump.

/// Periodic Hann window value for sample i of n (the sample centres, so both ends are
/// small and equal).
pub(crate) fn hann(i: usize, n: usize) -> f64 {
    let t = (i as f64 + 0.5) / n as f64;
    0.5 - 0.5 * (2.0 * std::f64::consts::PI * t).cos()
}

/// Tapers a row-major `width × height` plane toward its mean with a separable Hann
/// window, then rescales the deviations so the variance about the mean is that of the
/// input. The mean is kept.
pub fn hann_taper(plane: &[f64], width: usize, height: usize) -> Vec<f64> {
    let n = plane.len().max(1) as f64;
    let mean = plane.iter().sum::<f64>() / n;
    let var_in: f64 = plane.iter().map(|v| (v - mean).powi(2)).sum();
    let wx: Vec<f64> = (0..width).map(|i| hann(i, width)).collect();
    let wy: Vec<f64> = (0..height).map(|i| hann(i, height)).collect();
    let mut out: Vec<f64> = plane
        .iter()
        .enumerate()
        .map(|(i, v)| (v - mean) * wx[i % width] * wy[i / width])
        .collect();
    // Keep the mean exactly: the window moves it when the deviations are not uniform.
    let shift = out.iter().sum::<f64>() / n;
    let var_out: f64 = out.iter().map(|v| (v - shift).powi(2)).sum();
    let gain = if var_out > 0.0 {
        (var_in / var_out).sqrt()
    } else {
        1.0
    };
    for v in &mut out {
        *v = mean + (*v - shift) * gain;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_mean_and_variance_and_quiets_the_border() {
        let (w, h) = (40, 24);
        let plane: Vec<f64> = (0..w * h)
            .map(|i| 3.0 + 0.1 * (i % w) as f64 + ((i * 31) % 7) as f64)
            .collect();
        let out = hann_taper(&plane, w, h);
        let stats = |v: &[f64]| {
            let m = v.iter().sum::<f64>() / v.len() as f64;
            (
                m,
                v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64,
            )
        };
        let ((m0, v0), (m1, v1)) = (stats(&plane), stats(&out));
        assert!((m0 - m1).abs() < 1e-12 && (v0 - v1).abs() < 1e-9 * v0);
        // The wrap-around jump between the last and first column is small.
        let jump_in: f64 = (0..h)
            .map(|y| (plane[y * w + w - 1] - plane[y * w]).abs())
            .sum();
        let jump_out: f64 = (0..h)
            .map(|y| (out[y * w + w - 1] - out[y * w]).abs())
            .sum();
        assert!(jump_out < 0.1 * jump_in, "{jump_out} vs {jump_in}");
    }
}
