//! Tangent-space normal maps from heights and the physical spacing, for renderers that
//! shade with a normal texture: +X right, +Z out of the surface, and +Y up the image
//! (OpenGL, as Blender and Unity read them) or down it (DirectX, as Unreal reads them).

use crate::error::{Error, Result};
use crate::raster::Raster;

/// Which way a normal map's green channel points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum NormalConvention {
    /// Green is +Y up the image (OpenGL; Blender, Unity, Godot).
    Gl,
    /// Green is +Y down the image (DirectX; Unreal).
    Dx,
}

/// Samples of border a [`normal_map`] needs on each side of the region it describes.
pub const NORMAL_BORDER: usize = 2;

/// The unit normal of a height field with slopes `gx` = ∂h/∂x and `gy` = ∂h/∂row
/// (height per unit length, rows running down the image), in `convention`.
pub fn tangent_normal(gx: f64, gy: f64, convention: NormalConvention) -> [f64; 3] {
    // z = h(x, y_up): n ∝ (−∂h/∂x, −∂h/∂y_up, 1), and ∂h/∂y_up = −∂h/∂row.
    let ny = match convention {
        NormalConvention::Gl => gy,
        NormalConvention::Dx => -gy,
    };
    let len = (gx * gx + ny * ny + 1.0).sqrt();
    [-gx / len, ny / len, 1.0 / len]
}

/// The normals of the inner `(w − 4) × (h − 4)` samples of `padded` (one channel of
/// heights, [`NORMAL_BORDER`] samples of border on every side), the samples `spacing`
/// apart in the heights' unit: slopes by fourth-order central differences
/// (f(x−2) − 8 f(x−1) + 8 f(x+1) − f(x+2)) / 12d. Returns three channels (x, y, z).
pub fn normal_map(padded: &Raster, spacing: f64, convention: NormalConvention) -> Result<Raster> {
    if padded.channels != 1 {
        return Err(Error::param(
            "normal map",
            format!("{} channels", padded.channels),
            "heights (one channel)",
        ));
    }
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(Error::param("spacing", spacing, "a positive spacing"));
    }
    let b = NORMAL_BORDER;
    let (pw, ph) = (padded.width, padded.height);
    if pw <= 2 * b || ph <= 2 * b {
        return Err(Error::param(
            "normal map",
            format!("{pw}×{ph} samples"),
            format!("more than {} samples a side (a border of {b})", 2 * b),
        ));
    }
    let (w, h) = (pw - 2 * b, ph - 2 * b);
    let at = |x: usize, y: usize| padded.data[y * pw + x] as f64;
    let mut out = Raster::zeros(w, h, 3);
    for y in 0..h {
        for x in 0..w {
            let (cx, cy) = (x + b, y + b);
            let gx = (at(cx - 2, cy) - 8.0 * at(cx - 1, cy) + 8.0 * at(cx + 1, cy)
                - at(cx + 2, cy))
                / (12.0 * spacing);
            let gy = (at(cx, cy - 2) - 8.0 * at(cx, cy - 1) + 8.0 * at(cx, cy + 1)
                - at(cx, cy + 2))
                / (12.0 * spacing);
            let n = tangent_normal(gx, gy, convention);
            for (o, v) in out.data[(y * w + x) * 3..][..3].iter_mut().zip(n) {
                *o = v as f32;
            }
        }
    }
    Ok(out)
}
