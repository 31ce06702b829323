//! Down-sampling to a coarser pixel spacing (seed 000 §3.2: down-sample the input before
//! synthesis).

use crate::error::{Error, Result};
use crate::raster::Raster;

/// How to down-sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DownsampleFilter {
    /// Keep every `factor`-th sample (seed 000's choice).
    Nearest,
    /// Average each `factor × factor` block (less aliasing).
    Area,
}

/// Down-samples by an integer `factor` ≥ 1; the result is ⌊w/factor⌋ × ⌊h/factor⌋.
pub fn downsample(raster: &Raster, factor: usize, filter: DownsampleFilter) -> Result<Raster> {
    if factor == 0 {
        return Err(Error::param("downsample", factor, "an integer factor ≥ 1"));
    }
    if factor == 1 {
        return Ok(raster.clone());
    }
    let (w, h, c) = (
        raster.width / factor,
        raster.height / factor,
        raster.channels,
    );
    if w == 0 || h == 0 {
        return Err(Error::param(
            "downsample",
            factor,
            format!(
                "a factor that leaves at least one pixel of {}×{}",
                raster.width, raster.height
            ),
        ));
    }
    let mut out = Raster::zeros(w, h, c);
    for y in 0..h {
        for x in 0..w {
            for ch in 0..c {
                let v = match filter {
                    DownsampleFilter::Nearest => raster.get(x * factor, y * factor, ch),
                    DownsampleFilter::Area => {
                        let mut s = 0.0f64;
                        for dy in 0..factor {
                            for dx in 0..factor {
                                s += raster.get(x * factor + dx, y * factor + dy, ch) as f64;
                            }
                        }
                        (s / (factor * factor) as f64) as f32
                    }
                };
                out.set(x, y, ch, v);
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_and_area_on_a_ramp() {
        let r = Raster::from_vec(4, 2, 1, vec![0., 1., 2., 3., 4., 5., 6., 7.]).unwrap();
        let n = downsample(&r, 2, DownsampleFilter::Nearest).unwrap();
        assert_eq!(n.data, vec![0., 2.]);
        let a = downsample(&r, 2, DownsampleFilter::Area).unwrap();
        assert_eq!(a.data, vec![2.5, 4.5]);
        assert!(downsample(&r, 5, DownsampleFilter::Area).is_err());
    }
}

/// `raster` resampled to square pixels at the finer of its spacings `dx` and `dy` (any
/// unit): the coarser axis is interpolated linearly (a sample next to a missing one is
/// missing). Returns the raster and the common spacing; a raster whose spacings agree
/// within 1e-9 comes back as it is. Refuses a result of more than
/// [`crate::io::MAX_IMAGE_PIXELS`] pixels.
pub fn square_pixels(raster: &Raster, dx: f64, dy: f64) -> Result<(Raster, f64)> {
    if !(dx.is_finite() && dy.is_finite() && dx > 0.0 && dy > 0.0) {
        return Err(Error::param(
            "spacing",
            format!("{dx} × {dy}"),
            "positive, finite x and y spacings",
        ));
    }
    if (dx - dy).abs() <= 1e-9 * dx.max(dy) {
        return Ok((raster.clone(), dx));
    }
    let d = dx.min(dy);
    let (w, h, c) = (raster.width, raster.height, raster.channels);
    // The new grid covers the same extent: (n − 1)·spacing, at the finer spacing.
    let side = |n: usize, s: f64| ((n.saturating_sub(1)) as f64 * s / d).floor() as usize + 1;
    let (nw, nh) = (side(w, dx), side(h, dy));
    crate::io::check_shape("the square-pixel resampling", nw, nh, c)?;
    let mut out = Raster::zeros(nw, nh, c);
    let sample = |x: usize, y: usize, k: usize| raster.data[(y * w + x) * c + k];
    for ny in 0..nh {
        let fy = ny as f64 * d / dy;
        let y0 = (fy.floor() as usize).min(h - 1);
        let y1 = (y0 + 1).min(h - 1);
        let ty = (fy - y0 as f64) as f32;
        for nx in 0..nw {
            let fx = nx as f64 * d / dx;
            let x0 = (fx.floor() as usize).min(w - 1);
            let x1 = (x0 + 1).min(w - 1);
            let tx = (fx - x0 as f64) as f32;
            for k in 0..c {
                let top = sample(x0, y0, k) * (1.0 - tx) + sample(x1, y0, k) * tx;
                let bottom = sample(x0, y1, k) * (1.0 - tx) + sample(x1, y1, k) * tx;
                out.data[(ny * nw + nx) * c + k] = top * (1.0 - ty) + bottom * ty;
            }
        }
    }
    Ok((out, d))
}

#[cfg(test)]
mod square_tests {
    use super::*;

    /// A plane z = x·dx + 2·y·dy (in physical units) stays that plane on the square grid,
    /// over the same extent.
    #[test]
    fn a_plane_keeps_its_physical_slope() {
        let (w, h, dx, dy) = (10, 4, 0.5, 1.5);
        let data = (0..w * h)
            .map(|i| ((i % w) as f64 * dx + 2.0 * (i / w) as f64 * dy) as f32)
            .collect();
        let r = Raster::from_vec(w, h, 1, data).unwrap();
        let (sq, d) = square_pixels(&r, dx, dy).unwrap();
        assert_eq!(d, 0.5);
        assert_eq!((sq.width, sq.height), (10, 10));
        for y in 0..sq.height {
            for x in 0..sq.width {
                let want = x as f64 * d + 2.0 * y as f64 * d;
                assert!((sq.get(x, y, 0) as f64 - want).abs() < 1e-5, "{x},{y}");
            }
        }
    }
}
