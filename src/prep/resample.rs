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
