//! Region division by stochastic models (seed 001, [Procedure 2]): Poisson centres, a
//! hemisphere on each, and the convex (max) or concave (min) envelope, whose region
//! boundaries form the Voronoi diagram of the centres. Endless and lazy.
//!
//! - **Centres** ([Procedure 2] step 1, "Poisson's arrangement"): the plane is cut into
//!   square grid cells of side c = 1/√density; each cell holds a Poisson(1) number of
//!   centres (hashed, at most 8), each uniform in the cell (hashed), so the centres are
//!   a Poisson process of the given density.
//! - **Hemispheres** (step 2) of radius R on every centre; the **convex** surface is
//!   their upper envelope, max_k √(R² − d_k²), the **concave** one the lower envelope of
//!   the inverted hemispheres (dents), min_k −√(R² − d_k²) (step 3). Both are decided by
//!   the nearest centre, so both have the Voronoi diagram as region boundaries ("the
//!   perpendicular bisectors between the neighbouring center points"). Beyond R from
//!   every centre the surface is 0.
//! - **Per-region texture** (Plates 4–6): none, a polar sinusoid a·sin(ω·d + φ) of the
//!   distance d to the region's centre, the modified sinusoid a·sin(ω·d + φ)·cos(m·θ)
//!   (θ the polar angle about the centre), with φ and the angle offset hashed per
//!   region, or a midpoint-displacement fractal read at an offset hashed per region.
//! - **Per-region colour** (Plate 7) comes from a second, independent partition
//!   ([`VoronoiSurface::colour`]), so colour regions do not follow the roughness regions.
//!
//! The nearest centre is searched in the 3 × 3 cells around the point: O(1). It is
//! exact whenever that centre is within one cell side (the 3 × 3 block then holds every
//! closer one); otherwise (a cell and its neighbours nearly empty, rare) the search
//! widens ring by ring until it is.

use crate::error::{Error, Result, finite_param, positive_param};
use crate::hash::{hash_cell, pcg4d};
use crate::models::fractal::{FractalKind, FractalParams, FractalSurface};
use crate::stream::{Surface, in_range};

/// Which envelope of the hemispheres.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Envelope {
    /// The highest hemisphere: domes, valleys on the region borders.
    Convex,
    /// The lowest inverted hemisphere: dents, ridges on the region borders.
    Concave,
}

/// A texture function inside each region (seed 001, Plates 5 and 6).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase", tag = "kind")]
pub enum RegionTexture {
    /// The hemispheres alone.
    None,
    /// a·sin(ω·d + φ): rings about the region's centre (Plate 5).
    Polar {
        /// Amplitude a, in height units.
        amplitude: f64,
        /// Wavelength 2π/ω in pixels.
        wavelength_px: f64,
    },
    /// a·sin(ω·d + φ)·cos(m·θ): rings cut into m-fold petals (Plate 6).
    Modified {
        /// Amplitude a, in height units.
        amplitude: f64,
        /// Wavelength 2π/ω in pixels.
        wavelength_px: f64,
        /// Petals m.
        petals: u32,
    },
    /// A midpoint-displacement fractal ([Procedure 1], eq. 5) of its own in each
    /// region: one endless fractal, read in every region at an offset hashed from the
    /// region, so neighbouring regions show unrelated relief (Plate 4's "rugged
    /// textures").
    Fractal {
        /// S⁽⁰⁾, the coarsest displacement scale, in height units.
        amplitude: f64,
        /// Self-similarity h ∈ (0, 1].
        h: f64,
        /// Levels L (the fractal's coarsest lattice is 2^L pixels).
        levels: u32,
    },
}

impl RegionTexture {
    /// The fractal of a [`RegionTexture::Fractal`].
    fn fractal_params(&self) -> Option<FractalParams> {
        match *self {
            RegionTexture::Fractal {
                amplitude,
                h,
                levels,
            } => Some(FractalParams {
                h,
                levels,
                kind: FractalKind::Rock,
                amplitude,
                smooth: false,
            }),
            _ => None,
        }
    }
}

/// Parameters of a region-division surface (in a model `.toml`, the `[cells]` table;
/// keys left out keep their defaults).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VoronoiParams {
    /// Centres per pixel² (> 0); the mean centre spacing is 1/√density.
    pub density: f64,
    /// Hemisphere radius R in pixels, as a multiple of the mean spacing (> 0).
    pub radius: f64,
    /// Convex or concave.
    pub envelope: Envelope,
    /// The texture inside each region.
    pub texture: RegionTexture,
}

impl Default for VoronoiParams {
    fn default() -> Self {
        VoronoiParams {
            density: 1.0 / 4096.0,
            radius: 1.5,
            envelope: Envelope::Convex,
            texture: RegionTexture::None,
        }
    }
}

/// Most centres a grid cell holds (Poisson(1) above 8 has probability 10⁻⁶).
const MAX_PER_CELL: usize = 8;

impl VoronoiParams {
    /// Checks every parameter, naming the first one out of range.
    pub fn validate(&self) -> Result<()> {
        // Centres 1 to 2³² px apart: one per pixel at most, and grid cells whose
        // coordinates stay exact in f64 anywhere in ±2^52.
        if !(self.density.is_finite() && (2f64.powi(-64)..=1.0).contains(&self.density)) {
            return Err(Error::param(
                "density",
                crate::error::short(self.density),
                "a cell density in centres per pixel² from 2⁻⁶⁴ (centres 2³² px apart) to 1 \
                 (one centre per pixel)",
            ));
        }
        positive_param(
            "radius",
            self.radius,
            "a positive hemisphere radius, in mean centre spacings",
        )?;
        let wave = |a: f64, w: f64| -> Result<()> {
            finite_param("texture.amplitude", a, "a finite amplitude")?;
            positive_param(
                "texture.wavelength_px",
                w,
                "a positive wavelength in pixels",
            )?;
            Ok(())
        };
        match self.texture {
            RegionTexture::None => Ok(()),
            RegionTexture::Polar {
                amplitude,
                wavelength_px,
            }
            | RegionTexture::Modified {
                amplitude,
                wavelength_px,
                ..
            } => wave(amplitude, wavelength_px),
            RegionTexture::Fractal { .. } => self
                .texture
                .fractal_params()
                .map_or(Ok(()), |p| p.validate())
                .map_err(|e| match e {
                    Error::InvalidParameter {
                        name,
                        value,
                        expected,
                    } => Error::InvalidParameter {
                        name: format!("texture.{name}"),
                        value,
                        expected,
                    },
                    e => e,
                }),
        }
    }
}

/// The nearest centre found for a point: its squared distance, position and id.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// Squared distance (px²).
    pub d2: f64,
    /// The centre (px).
    pub centre: (f64, f64),
    /// (cell x, cell y, index in the cell): the region's identity.
    pub id: (i64, i64, u32),
}

/// An endless region-division surface (seed 001, [Procedure 2]).
#[derive(Clone, Debug)]
pub struct VoronoiSurface {
    params: VoronoiParams,
    seed: u32,
    cell: f64,
    inv_cell: f64,
    radius_px: f64,
    /// The region texture's fractal, for [`RegionTexture::Fractal`].
    fractal: Option<std::sync::Arc<FractalSurface>>,
}

impl VoronoiSurface {
    /// The surface of `params` (validated here), with placement seed `seed`.
    pub fn new(params: VoronoiParams, seed: u32) -> Result<VoronoiSurface> {
        params.validate()?;
        let cell = 1.0 / params.density.sqrt();
        Ok(VoronoiSurface {
            params,
            seed,
            cell,
            inv_cell: 1.0 / cell,
            radius_px: params.radius * cell,
            fractal: params
                .texture
                .fractal_params()
                .map(|p| FractalSurface::new(p, seed ^ 0xF4AC_7A15).map(std::sync::Arc::new))
                .transpose()?,
        })
    }

    /// The parameters.
    pub fn params(&self) -> VoronoiParams {
        self.params
    }

    /// The centres of grid cell (i, j): a Poisson(1) count and uniform positions.
    fn centres(&self, i: i64, j: i64, mut visit: impl FnMut(u32, f64, f64)) {
        let h = hash_cell(self.seed, i, j, 0x7011);
        // Poisson(1) by inversion of the CDF on 32 hashed bits.
        let u = h[0] as f64 * (1.0 / 4_294_967_296.0);
        let (mut k, mut p, mut cdf) = (0usize, (-1.0f64).exp(), (-1.0f64).exp());
        while u >= cdf && k < MAX_PER_CELL {
            k += 1;
            p /= k as f64;
            cdf += p;
        }
        for n in 0..k as u32 {
            let w = if n == 0 {
                [h[1], h[2], h[3], 0]
            } else {
                pcg4d([h[1], h[2], n, self.seed])
            };
            let fx = (w[0] >> 8) as f64 * (1.0 / (1u32 << 24) as f64);
            let fy = (w[1] >> 8) as f64 * (1.0 / (1u32 << 24) as f64);
            visit(n, (i as f64 + fx) * self.cell, (j as f64 + fy) * self.cell);
        }
    }

    /// The centre nearest to (x, y), exactly (ties: the first found, in a fixed order).
    pub fn nearest(&self, x: f64, y: f64) -> Nearest {
        let (ci, cj) = (
            (x * self.inv_cell).floor() as i64,
            (y * self.inv_cell).floor() as i64,
        );
        let mut best = Nearest {
            d2: f64::INFINITY,
            centre: (f64::NAN, f64::NAN),
            id: (0, 0, 0),
        };
        let mut ring = 1i64;
        let scan = |lo: i64, hi: i64, only_border: bool, best: &mut Nearest| {
            for j in cj + lo..=cj + hi {
                for i in ci + lo..=ci + hi {
                    if only_border && (i - ci).abs() < hi && (j - cj).abs() < hi {
                        continue;
                    }
                    self.centres(i, j, |n, px, py| {
                        let d2 = (x - px) * (x - px) + (y - py) * (y - py);
                        if d2 < best.d2 {
                            *best = Nearest {
                                d2,
                                centre: (px, py),
                                id: (i, j, n),
                            };
                        }
                    });
                }
            }
        };
        scan(-1, 1, false, &mut best);
        // Every point outside the scanned (2·ring + 1)² block is at least `ring` cells
        // plus the point's distance to the nearest side of its own cell away.
        loop {
            let fx = x * self.inv_cell - ci as f64;
            let fy = y * self.inv_cell - cj as f64;
            let margin = (ring as f64 + fx.min(1.0 - fx).min(fy).min(1.0 - fy)) * self.cell;
            if best.d2 <= margin * margin || ring >= 64 {
                return best;
            }
            ring += 1;
            scan(-ring, ring, true, &mut best);
        }
    }

    /// Height at (x, y) with its nearest centre known.
    fn height_with(&self, x: f64, y: f64, n: &Nearest) -> f64 {
        let r2 = self.radius_px * self.radius_px;
        let dome = (r2 - n.d2).max(0.0).sqrt();
        let base = match self.params.envelope {
            Envelope::Convex => dome,
            Envelope::Concave => -dome,
        };
        let texture = match self.params.texture {
            RegionTexture::None => 0.0,
            RegionTexture::Polar {
                amplitude,
                wavelength_px,
            } => {
                let phase = self.region_phase(n.id);
                amplitude * (std::f64::consts::TAU * n.d2.sqrt() / wavelength_px + phase).sin()
            }
            RegionTexture::Modified {
                amplitude,
                wavelength_px,
                petals,
            } => {
                let phase = self.region_phase(n.id);
                let theta = (y - n.centre.1).atan2(x - n.centre.0) + phase;
                amplitude
                    * (std::f64::consts::TAU * n.d2.sqrt() / wavelength_px + phase).sin()
                    * (petals as f64 * theta).cos()
            }
            RegionTexture::Fractal { .. } => match &self.fractal {
                Some(f) => {
                    // An integer offset keeps the fractal on its own lattice: the
                    // region reads an unrelated, equally lazy patch of it.
                    let (ox, oy) = self.fractal_offset(n);
                    f.height(x + ox, y + oy) as f64
                }
                None => 0.0,
            },
        };
        base + texture
    }

    /// The gradient of [`Self::height_with`]: the hemisphere's and the sinusoids' in
    /// closed form; a fractal texture's by central differences (±1 px) inside the
    /// point's own region (its offset kept), so a region border stays a crease.
    fn gradient_with(&self, x: f64, y: f64, n: &Nearest) -> [f64; 2] {
        let (dx, dy) = (x - n.centre.0, y - n.centre.1);
        let r2 = self.radius_px * self.radius_px;
        let mut g = [0.0f64; 2];
        if n.d2 < r2 {
            // ∂√(R² − d²)/∂x = −dx/√(R² − d²), finite down to the rim.
            let dome = (r2 - n.d2).sqrt().max(1e-6);
            let sign = match self.params.envelope {
                Envelope::Convex => -1.0,
                Envelope::Concave => 1.0,
            };
            g = [sign * dx / dome, sign * dy / dome];
        }
        let d = n.d2.sqrt();
        // ∂d/∂x = dx/d and ∂θ/∂x = −dy/d², ∂θ/∂y = dx/d² (0 at the centre itself).
        let (ddx, ddy, dtx, dty) = if d > 0.0 {
            (dx / d, dy / d, -dy / n.d2, dx / n.d2)
        } else {
            (0.0, 0.0, 0.0, 0.0)
        };
        match self.params.texture {
            RegionTexture::None => {}
            RegionTexture::Polar {
                amplitude,
                wavelength_px,
            } => {
                let w = std::f64::consts::TAU / wavelength_px;
                let c = amplitude * w * (w * d + self.region_phase(n.id)).cos();
                g[0] += c * ddx;
                g[1] += c * ddy;
            }
            RegionTexture::Modified {
                amplitude,
                wavelength_px,
                petals,
            } => {
                let w = std::f64::consts::TAU / wavelength_px;
                let phase = self.region_phase(n.id);
                let m = petals as f64;
                let theta = dy.atan2(dx) + phase;
                let (s, c) = (w * d + phase).sin_cos();
                let (ms, mc) = (m * theta).sin_cos();
                // a·sin(ωd + φ)·cos(mθ): product rule.
                g[0] += amplitude * (w * c * mc * ddx - s * m * ms * dtx);
                g[1] += amplitude * (w * c * mc * ddy - s * m * ms * dty);
            }
            RegionTexture::Fractal { .. } => {
                if let Some(f) = &self.fractal {
                    let (ox, oy) = self.fractal_offset(n);
                    let (px, py) = (x + ox, y + oy);
                    g[0] += 0.5 * (f.height(px + 1.0, py) - f.height(px - 1.0, py)) as f64;
                    g[1] += 0.5 * (f.height(px, py + 1.0) - f.height(px, py - 1.0)) as f64;
                }
            }
        }
        g
    }

    /// The integer offset at which region `n` reads the fractal texture: hashed
    /// magnitudes below 2²⁷, each signed toward the origin from the region's centre, so
    /// that the read point stays within the coordinate range wherever the region lies
    /// (an offset away from the origin read NaN within 2²⁷ px of ±2⁵²).
    fn fractal_offset(&self, n: &Nearest) -> (f64, f64) {
        let id = n.id;
        let o = hash_cell(self.seed ^ id.2, id.0, id.1, 0xF4AC);
        let toward_origin = |w: u32, centre: f64| {
            let magnitude = (w >> 5) as f64;
            if centre > 0.0 { -magnitude } else { magnitude }
        };
        (
            toward_origin(o[0], n.centre.0),
            toward_origin(o[1], n.centre.1),
        )
    }

    /// φ of a region's texture, uniform in [0, 2π).
    fn region_phase(&self, id: (i64, i64, u32)) -> f64 {
        let h = hash_cell(
            self.seed ^ id.2.wrapping_mul(0x9E37_79B9),
            id.0,
            id.1,
            0x9A5E,
        )[0];
        h as f64 * (std::f64::consts::TAU / 4_294_967_296.0)
    }

    /// The region colour at (x, y) (Plate 7): an RGB triple in [0.35, 1]³ hashed from
    /// the region of a second partition of the same density, independent of the
    /// roughness regions.
    pub fn colour(&self, x: f64, y: f64) -> [f32; 3] {
        let other = VoronoiSurface {
            seed: self.seed ^ 0xC010_0125,
            ..self.clone()
        };
        let id = other.nearest(x, y).id;
        let h = hash_cell(other.seed ^ id.2, id.0, id.1, 0xC0);
        let c = |w: u32| 0.35 + 0.65 * (w >> 8) as f32 / (1u32 << 24) as f32;
        [c(h[0]), c(h[1]), c(h[2])]
    }
}

impl Surface for VoronoiSurface {
    fn channels(&self) -> usize {
        1
    }

    fn sample_footprint(&self, x: f64, y: f64, _footprint: f64, out: &mut [f32]) {
        out[0] = self.height(x, y);
    }

    fn height(&self, x: f64, y: f64) -> f32 {
        if !in_range(x, y) {
            return f32::NAN;
        }
        let n = self.nearest(x, y);
        self.height_with(x, y, &n) as f32
    }

    /// In closed form (the hemisphere and the sinusoids; see `gradient_with`).
    fn gradient(&self, x: f64, y: f64) -> Option<[f64; 2]> {
        if !in_range(x, y) {
            return Some([f64::NAN; 2]);
        }
        let n = self.nearest(x, y);
        Some(self.gradient_with(x, y, &n))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 3 × 3 search with its widening gives the true nearest centre: compared with a
    /// brute-force scan of all centres in a 21 × 21-cell block around random points.
    #[test]
    fn nearest_matches_a_brute_force_scan() {
        let s = VoronoiSurface::new(
            VoronoiParams {
                density: 1.0 / 400.0,
                ..Default::default()
            },
            4,
        )
        .unwrap();
        let mut state = 77u64;
        for _ in 0..300 {
            let mut u = || {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 4000.0
            };
            let (x, y) = (u(), u());
            let got = s.nearest(x, y);
            let (ci, cj) = ((x / 20.0).floor() as i64, (y / 20.0).floor() as i64);
            let mut best = f64::INFINITY;
            for j in cj - 10..=cj + 10 {
                for i in ci - 10..=ci + 10 {
                    s.centres(i, j, |_, px, py| {
                        best = best.min((x - px).powi(2) + (y - py).powi(2));
                    });
                }
            }
            assert_eq!(got.d2, best, "at ({x}, {y})");
        }
    }

    /// The closed-form gradient against central differences (±10⁻⁴ px, in f64) of the
    /// heights, for both envelopes and the sinusoidal textures, at 400 random points
    /// whose ±10⁻⁴ neighbours lie in the same region and off the hemisphere's rim:
    /// relative error under 10⁻⁵.
    #[test]
    fn analytic_gradients_match_finite_differences() {
        let textures = [
            RegionTexture::None,
            RegionTexture::Polar {
                amplitude: 3.0,
                wavelength_px: 17.0,
            },
            RegionTexture::Modified {
                amplitude: 2.0,
                wavelength_px: 23.0,
                petals: 5,
            },
        ];
        let mut state = 9u64;
        let mut worst = 0.0f64;
        let mut checked = 0;
        for envelope in [Envelope::Convex, Envelope::Concave] {
            for texture in textures {
                let s = VoronoiSurface::new(
                    VoronoiParams {
                        density: 1.0 / 1600.0,
                        radius: 1.2,
                        envelope,
                        texture,
                    },
                    11,
                )
                .unwrap();
                let r2 = s.radius_px * s.radius_px;
                for _ in 0..400 {
                    let mut u = || {
                        state = state
                            .wrapping_mul(6_364_136_223_846_793_005)
                            .wrapping_add(1_442_695_040_888_963_407);
                        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 3000.0
                    };
                    let (x, y) = (u(), u());
                    let n = s.nearest(x, y);
                    let e = 1e-4;
                    let near = [(x + e, y), (x - e, y), (x, y + e), (x, y - e)];
                    if near.iter().any(|&(a, b)| s.nearest(a, b).id != n.id)
                        || r2 - n.d2 < 1.0
                        || n.d2 < 1.0
                    {
                        continue;
                    }
                    let h = |a: f64, b: f64| s.height_with(a, b, &s.nearest(a, b));
                    let fd = [
                        (h(x + e, y) - h(x - e, y)) / (2.0 * e),
                        (h(x, y + e) - h(x, y - e)) / (2.0 * e),
                    ];
                    let g = s.gradient(x, y).unwrap();
                    for k in 0..2 {
                        worst = worst.max((g[k] - fd[k]).abs() / (1.0 + g[k].abs()));
                    }
                    checked += 1;
                }
            }
        }
        assert!(checked > 1000, "only {checked} points checked");
        assert!(worst < 1e-5, "worst relative error {worst}");
    }

    /// Why shading takes the analytic gradient: at pixels on a region border, its
    /// normal is the exact normal of the pixel's own hemisphere (within 0.01°), where
    /// central differences, straddling two regions, are off by degrees.
    #[test]
    fn analytic_normals_stay_exact_on_region_borders() {
        use crate::shade::normal_from_gradient;
        let s = VoronoiSurface::new(
            VoronoiParams {
                density: 1.0 / 1024.0,
                radius: 2.0,
                ..Default::default()
            },
            5,
        )
        .unwrap();
        // atan2(|a × b|, a · b): well conditioned near 0°, where acos is not in f32.
        let angle = |a: glam::Vec3, b: glam::Vec3| a.cross(b).length().atan2(a.dot(b)).to_degrees();
        let (mut analytic, mut central, mut borders) = (0.0f32, 0.0f32, 0);
        for py in 0..200 {
            for px in 0..200 {
                let (x, y) = (px as f64, py as f64);
                let n = s.nearest(x, y);
                let others = [(x + 1.0, y), (x - 1.0, y), (x, y + 1.0), (x, y - 1.0)];
                if others.iter().all(|&(a, b)| s.nearest(a, b).id == n.id) {
                    continue;
                }
                borders += 1;
                let (dx, dy) = (x - n.centre.0, y - n.centre.1);
                let dome = (s.radius_px * s.radius_px - n.d2).sqrt();
                let want = glam::DVec3::new(dx, dy, dome).normalize().as_vec3();
                let g = s.gradient(x, y).unwrap();
                let got = normal_from_gradient(g[0] as f32, g[1] as f32, 1.0);
                analytic = analytic.max(angle(got, want));
                let h = |a: f64, b: f64| s.height(a, b);
                let cd = normal_from_gradient(
                    0.5 * (h(x + 1.0, y) - h(x - 1.0, y)),
                    0.5 * (h(x, y + 1.0) - h(x, y - 1.0)),
                    1.0,
                );
                central = central.max(angle(cd, want));
            }
        }
        assert!(borders > 500, "{borders} border pixels");
        assert!(analytic < 0.01, "analytic normals off by {analytic}°");
        assert!(central > 5.0, "central differences off by only {central}°");
    }

    #[test]
    fn bad_parameters_are_refused() {
        for density in [0.0, -1.0, f64::NAN, 4.0] {
            let e = VoronoiSurface::new(
                VoronoiParams {
                    density,
                    ..Default::default()
                },
                0,
            )
            .unwrap_err()
            .to_string();
            assert!(e.contains("density"), "{e}");
        }
    }
}
