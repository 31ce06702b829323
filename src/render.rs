//! Rendering regions of a surface to rasters and files (what `surftile render` and the
//! demo call).

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::{Format, write_heights, write_png8};
use crate::raster::Raster;
use crate::shade::{ShadeOptions, shade, shade_slopes};
use crate::stream::{Region, Surface};

/// Largest region one render may hold in memory: 2²⁸ samples (1 GiB of f32).
pub const MAX_RENDER_SAMPLES: usize = 1 << 28;

/// Rows filled per progress report.
const STRIP_ROWS: usize = 256;

/// Checks a requested size from user input (signed, so that negative sizes get a clear
/// message) and returns it as a region size.
pub fn checked_size(name: &str, value: i64) -> Result<usize> {
    if value <= 0 {
        return Err(Error::param(name, value, "a positive number of samples"));
    }
    usize::try_from(value).map_err(|_| Error::param(name, value, "a size that fits in memory"))
}

/// Fills `region` into a new raster, strip by strip, calling `progress` with the done
/// fraction after each strip. The result is identical to one [`Surface::fill`] call.
pub fn render_region(
    surface: &dyn Surface,
    region: &Region,
    progress: &mut dyn FnMut(f64),
) -> Result<Raster> {
    region.validate()?;
    let c = surface.channels();
    let samples = region
        .width
        .checked_mul(region.height)
        .filter(|&n| n <= MAX_RENDER_SAMPLES)
        .ok_or_else(|| {
            Error::Limits(format!(
                "a {}×{} region is over the limit of {MAX_RENDER_SAMPLES} samples per render; render it in tiles",
                region.width, region.height
            ))
        })?;
    let mut data = vec![0.0f32; samples * c];
    let row_len = region.width * c;
    for (s, strip) in data.chunks_mut(STRIP_ROWS * row_len).enumerate() {
        let rows = strip.len() / row_len;
        let sub = region.sub(0, s * STRIP_ROWS, region.width, rows)?;
        surface.fill(&sub, strip)?;
        progress(((s * STRIP_ROWS + rows) as f64 / region.height as f64).min(1.0));
    }
    Raster::from_vec(region.width, region.height, c, data)
}

/// A surface's analytic gradient as a two-channel surface of slopes per sample
/// (∂h/∂x·step, ∂h/∂y·step), so that it fills in parallel like any other.
struct Slopes<'a>(&'a dyn Surface);

impl Surface for Slopes<'_> {
    fn channels(&self) -> usize {
        2
    }

    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        let g = self.0.gradient(x, y).unwrap_or([f64::NAN; 2]);
        out[0] = (g[0] * footprint) as f32;
        out[1] = (g[1] * footprint) as f32;
    }
}

/// Renders `region` to `out`: heights as 16-bit PNG, f32 TIFF or f32 `.npy` by
/// extension; with `shading`, an 8-bit Phong-shaded PNG of channel 0 instead, its
/// normals from the surface's analytic gradient where it has one, else from central
/// differences of the heights (an explicit exaggeration is per surface pixel, so it is
/// divided by the step).
pub fn render_to_file(
    surface: &dyn Surface,
    region: &Region,
    out: &Path,
    shading: Option<&ShadeOptions>,
    spacing_um: Option<f64>,
    progress: &mut dyn FnMut(f64),
) -> Result<()> {
    let format = Format::from_path(out)?;
    if let Some(options) = shading {
        options.validate()?;
        if format != Format::Png {
            return Err(Error::param(
                "out",
                out.display(),
                "a .png file with --shade (the shading is an 8-bit image)",
            ));
        }
        let options = ShadeOptions {
            exaggeration: options.exaggeration.map(|e| e / region.step as f32),
            ..*options
        };
        let pixels = if surface.gradient(region.x, region.y).is_some() {
            // The model's own gradient, per sample.
            let g = render_region(&Slopes(surface), region, progress)?;
            let slopes: Vec<[f32; 2]> = g.data.chunks_exact(2).map(|p| [p[0], p[1]]).collect();
            shade_slopes(&slopes, &options)
        } else {
            // One sample of margin on every side for the central differences.
            let grown = Region {
                col0: region.col0 - 1,
                row0: region.row0 - 1,
                width: region.width + 2,
                height: region.height + 2,
                ..*region
            };
            let heights = render_region(surface, &grown, progress)?.channel(0);
            shade(&heights, &options)
        };
        return write_png8(out, region.width, region.height, 1, &pixels);
    }
    let raster = render_region(surface, region, progress)?;
    write_heights(out, &raster, spacing_um.map(|s| s * region.step))
}
