//! Plane levelling: the metrology default before computing roughness (ISO 25178 "F
//! operator" of degree 1).

use crate::raster::Raster;

/// Fits z = a + b·x + c·y to the finite samples of `plane` (row-major, `width` wide) by
/// least squares and returns (a, b, c). NaN samples are ignored. Coordinates are pixels.
pub fn fit_plane(plane: &[f64], width: usize) -> (f64, f64, f64) {
    let height = plane.len() / width.max(1);
    // Centred coordinates keep the normal equations well conditioned.
    let (cx, cy) = ((width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0);
    let (mut n, mut sx, mut sy, mut sz) = (0.0, 0.0, 0.0, 0.0);
    let (mut sxx, mut syy, mut sxy, mut sxz, mut syz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for y in 0..height {
        for x in 0..width {
            let z = plane[y * width + x];
            if !z.is_finite() {
                continue;
            }
            let (u, v) = (x as f64 - cx, y as f64 - cy);
            n += 1.0;
            sx += u;
            sy += v;
            sz += z;
            sxx += u * u;
            syy += v * v;
            sxy += u * v;
            sxz += u * z;
            syz += v * z;
        }
    }
    if n < 3.0 {
        let mean = if n > 0.0 { sz / n } else { 0.0 };
        return (mean, 0.0, 0.0);
    }
    // Solve the 3×3 normal equations by Cramer's rule.
    let m = [[n, sx, sy], [sx, sxx, sxy], [sy, sxy, syy]];
    let r = [sz, sxz, syz];
    let det3 = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det3(m);
    if d.abs() < 1e-12 * n.powi(3) {
        return (sz / n, 0.0, 0.0);
    }
    let mut sol = [0.0; 3];
    for (k, s) in sol.iter_mut().enumerate() {
        let mut mk = m;
        for row in 0..3 {
            mk[row][k] = r[row];
        }
        *s = det3(mk) / d;
    }
    let (a0, b, c) = (sol[0], sol[1], sol[2]);
    // Back to uncentred coordinates.
    (a0 - b * cx - c * cy, b, c)
}

/// Subtracts the least-squares plane from every channel of `raster` (NaNs stay NaN).
pub fn level_plane(raster: &mut Raster) {
    for c in 0..raster.channels {
        let mut plane = raster.channel_f64(c);
        let (a, b, cc) = fit_plane(&plane, raster.width);
        for y in 0..raster.height {
            for x in 0..raster.width {
                plane[y * raster.width + x] -= a + b * x as f64 + cc * y as f64;
            }
        }
        raster.set_channel_f64(c, &plane);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_known_plane_with_nans() {
        let (w, h) = (13, 9);
        let mut plane: Vec<f64> = (0..w * h)
            .map(|i| 2.5 + 0.3 * (i % w) as f64 - 0.7 * (i / w) as f64)
            .collect();
        plane[5] = f64::NAN;
        plane[40] = f64::NAN;
        let (a, b, c) = fit_plane(&plane, w);
        assert!((a - 2.5).abs() < 1e-9 && (b - 0.3).abs() < 1e-9 && (c + 0.7).abs() < 1e-9);
    }

    #[test]
    fn levelled_map_has_zero_mean_and_no_tilt() {
        let (w, h) = (20, 10);
        let data: Vec<f32> = (0..w * h)
            .map(|i| (1.0 + 0.1 * (i % w) as f64 + ((i * 7919) % 13) as f64 * 0.01) as f32)
            .collect();
        let mut r = Raster::from_vec(w, h, 1, data).unwrap();
        level_plane(&mut r);
        let (a, b, c) = fit_plane(&r.channel_f64(0), w);
        assert!(
            a.abs() < 1e-5 && b.abs() < 1e-6 && c.abs() < 1e-6,
            "{a} {b} {c}"
        );
    }
}
