//! Phong/Blinn shading of a height field (seed 001, eqs. (1)–(4)): R = I_d + I_s + I_a
//! with I_d = N·L (eq. 2), I_s = (H·N)ⁿ (eq. 3), I_a = C_a (eq. 4).

use glam::Vec3;

use crate::error::{Error, Result};
use crate::raster::Raster;

/// Light and material for [`shade`].
#[derive(Clone, Copy, Debug)]
pub struct ShadeOptions {
    /// Direction toward the light (need not be normalised). Default: from the upper
    /// left, 45° above the surface.
    pub light: Vec3,
    /// Direction toward the viewer. Default: straight down the z axis.
    pub view: Vec3,
    /// Diffuse weight. Default 0.75.
    pub diffuse: f32,
    /// Specular weight. Default 0.2.
    pub specular: f32,
    /// Specular exponent n of eq. (3). Default 24.
    pub shininess: f32,
    /// Ambient constant C_a of eq. (4). Default 0.1.
    pub ambient: f32,
    /// Vertical exaggeration; `None` picks one that makes the rms slope 0.5, so any map
    /// (nanometre AFM or millimetre profilometer) shows its relief.
    pub exaggeration: Option<f32>,
}

impl Default for ShadeOptions {
    fn default() -> Self {
        ShadeOptions {
            light: Vec3::new(-1.0, -1.0, 2.0_f32.sqrt()),
            view: Vec3::Z,
            diffuse: 0.75,
            specular: 0.2,
            shininess: 24.0,
            ambient: 0.1,
            exaggeration: None,
        }
    }
}

impl ShadeOptions {
    /// The material presets of seed 001: `rock` (ambient, diffuse and specular: "powder
    /// like and crystal particles", Plate 1), `china` (unglazed china: no specular,
    /// Plate 2) and `casting` (aluminium casting: no diffuse, shiny, Plate 3; its light
    /// stands 20° off the view, so flat patches catch the highlight, as on a part
    /// held under a lamp).
    pub fn preset(name: &str) -> Result<ShadeOptions> {
        let d = ShadeOptions::default();
        Ok(match name {
            "rock" => ShadeOptions {
                diffuse: 0.7,
                specular: 0.25,
                shininess: 16.0,
                ..d
            },
            "china" => ShadeOptions {
                diffuse: 0.85,
                specular: 0.0,
                ..d
            },
            "casting" => ShadeOptions {
                light: Vec3::new(-0.25, -0.25, 1.0),
                diffuse: 0.0,
                specular: 0.9,
                shininess: 40.0,
                ambient: 0.15,
                ..d
            },
            other => {
                return Err(Error::param(
                    "material",
                    other,
                    "one of rock, china, casting",
                ));
            }
        })
    }

    /// Checks the light and view directions (finite, non-zero) and the weights.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [("light", self.light), ("view", self.view)] {
            if !(v.is_finite() && v.length() > 0.0) {
                return Err(Error::param(
                    name,
                    format!("({}, {}, {})", v.x, v.y, v.z),
                    "a direction of non-zero, finite length",
                ));
            }
        }
        for (name, v) in [
            ("diffuse", self.diffuse),
            ("specular", self.specular),
            ("shininess", self.shininess),
            ("ambient", self.ambient),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::param(name, v, "a finite weight ≥ 0"));
            }
        }
        Ok(())
    }
}

/// Shades a height field given with a one-pixel margin on every side
/// (`(w + 2) × (h + 2)`, channel 0), returning `w × h` 8-bit intensities. Slopes are
/// per pixel (height units per pixel) from central differences, times the
/// exaggeration.
pub fn shade(heights: &Raster, options: &ShadeOptions) -> Vec<u8> {
    let (w, h) = (
        heights.width.saturating_sub(2),
        heights.height.saturating_sub(2),
    );
    // Two passes over the central differences (the automatic exaggeration needs their
    // rms first) instead of a slope buffer of 8 bytes per pixel.
    let slopes = || (0..h).flat_map(move |y| (0..w).map(move |x| central_slope(heights, x, y)));
    let scale = options
        .exaggeration
        .unwrap_or_else(|| auto_exaggeration(slopes().map(slope_energy).sum(), w * h));
    let shader = Shader::new(options, scale);
    slopes().map(|[gx, gy]| shader.pixel(gx, gy)).collect()
}

/// The central-difference slope at (x + 1, y + 1) of `heights` (which has a one-sample
/// margin on every side): (∂h/∂x, ∂h/∂y) per sample.
#[inline]
pub fn central_slope(heights: &Raster, x: usize, y: usize) -> [f32; 2] {
    let gx = 0.5 * (heights.get(x + 2, y + 1, 0) - heights.get(x, y + 1, 0));
    let gy = 0.5 * (heights.get(x + 1, y + 2, 0) - heights.get(x + 1, y, 0));
    [gx, gy]
}

/// A slope's squared length, as the automatic exaggeration sums it (in f32, then
/// widened: the sum must come out the same however the slopes are visited in order).
#[inline]
pub fn slope_energy([gx, gy]: [f32; 2]) -> f64 {
    (gx * gx + gy * gy) as f64
}

/// The automatic exaggeration: 0.5 over the rms slope, from the sum of
/// [`slope_energy`] over `n` slopes (1 for a flat or non-finite field).
pub fn auto_exaggeration(energy_sum: f64, n: usize) -> f32 {
    let rms = (energy_sum / n.max(1) as f64).sqrt() as f32;
    if rms > 0.0 && rms.is_finite() {
        0.5 / rms
    } else {
        1.0
    }
}

/// Shades a field of slopes (∂h/∂x, ∂h/∂y per sample, row-major): from central
/// differences ([`shade`]) or from a model's analytic gradient
/// ([`crate::stream::Surface::gradient`]). One 8-bit intensity per slope.
pub fn shade_slopes(slopes: &[[f32; 2]], options: &ShadeOptions) -> Vec<u8> {
    let scale = options.exaggeration.unwrap_or_else(|| {
        auto_exaggeration(slopes.iter().copied().map(slope_energy).sum(), slopes.len())
    });
    let shader = Shader::new(options, scale);
    slopes
        .iter()
        .map(|&[gx, gy]| shader.pixel(gx, gy))
        .collect()
}

/// The Phong shading of one material, light and exaggeration, pixel by pixel.
pub struct Shader<'a> {
    options: &'a ShadeOptions,
    scale: f32,
    light: Vec3,
    half: Vec3,
}

impl<'a> Shader<'a> {
    /// The shader of `options` with heights scaled by `scale`.
    pub fn new(options: &'a ShadeOptions, scale: f32) -> Shader<'a> {
        let light = options.light.normalize();
        let half = half_vector(light, options.view.normalize());
        Shader {
            options,
            scale,
            light,
            half,
        }
    }

    /// The 8-bit intensity of a sample with slopes (gx, gy).
    #[inline]
    pub fn pixel(&self, gx: f32, gy: f32) -> u8 {
        let n = normal_from_gradient(gx, gy, self.scale);
        let r = reflectance(n, self.light, self.half, self.options);
        (r.clamp(0.0, 1.0) * 255.0).round() as u8
    }
}

/// The unit normal of a height field with slopes (gx, gy) (height per pixel), heights
/// scaled by `exaggeration`. Twin: `normal_from_gradient` in `shaders/shade.wgsl`.
#[inline]
pub fn normal_from_gradient(gx: f32, gy: f32, exaggeration: f32) -> Vec3 {
    Vec3::new(-gx * exaggeration, -gy * exaggeration, 1.0).normalize()
}

/// H, the unit bisector of the unit vectors toward the light `l` and the viewer `v`
/// (seed 001, eq. (3)). Twin: `half_vector` in `shaders/shade.wgsl`.
#[inline]
pub fn half_vector(l: Vec3, v: Vec3) -> Vec3 {
    (l + v).normalize()
}

/// R = C_a + k_d·max(N·L, 0) + k_s·max(H·N, 0)ⁿ (seed 001, eqs. (1)–(4)) for unit N, L
/// and H. Twin: `reflectance` in `shaders/shade.wgsl`.
#[inline]
pub fn reflectance(n: Vec3, l: Vec3, half: Vec3, options: &ShadeOptions) -> f32 {
    let diffuse = n.dot(l).max(0.0);
    let specular = n.dot(half).max(0.0).powf(options.shininess);
    options.ambient + options.diffuse * diffuse + options.specular * specular
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The central-difference normal of the shader against analytic normals: a sphere
    /// cap z = √(R² − x² − y²) (normal (x, y, z)/R) and a plane wave z = A·sin(kx)
    /// (normal ∝ (−Ak·cos kx, 0, 1)), within 0.3° at every sampled point.
    #[test]
    fn normals_match_analytic_surfaces() {
        let angle = |a: Vec3, b: Vec3| a.dot(b).clamp(-1.0, 1.0).acos().to_degrees();
        let r = 200.0f64;
        let cap = |x: f64, y: f64| (r * r - x * x - y * y).sqrt();
        let mut worst = 0.0f32;
        for k in 0..400 {
            let (x, y) = ((k % 20) as f64 * 7.0 - 70.0, (k / 20) as f64 * 7.0 - 70.0);
            let gx = (cap(x + 1.0, y) - cap(x - 1.0, y)) * 0.5;
            let gy = (cap(x, y + 1.0) - cap(x, y - 1.0)) * 0.5;
            let n = normal_from_gradient(gx as f32, gy as f32, 1.0);
            let want = Vec3::new(x as f32, y as f32, cap(x, y) as f32) / r as f32;
            worst = worst.max(angle(n, want));
        }
        let (amp, kw) = (3.0f64, std::f64::consts::TAU / 64.0);
        let wave = |x: f64| amp * (kw * x).sin();
        for i in 0..128 {
            let x = i as f64 * 0.5;
            let gx = (wave(x + 1.0) - wave(x - 1.0)) * 0.5;
            let n = normal_from_gradient(gx as f32, 0.0, 1.0);
            let want = Vec3::new((-amp * kw * (kw * x).cos()) as f32, 0.0, 1.0).normalize();
            worst = worst.max(angle(n, want));
        }
        assert!(worst < 0.3, "worst normal error {worst}°");
    }

    /// A flat plane shades to exactly I_a + k_d·N·L + k_s·(H·N)ⁿ with N = z.
    #[test]
    fn a_flat_plane_shades_to_the_formula() {
        let o = ShadeOptions {
            light: Vec3::new(0.3, -0.4, 0.8),
            view: Vec3::new(0.0, 0.2, 1.0),
            diffuse: 0.6,
            specular: 0.3,
            shininess: 12.0,
            ambient: 0.05,
            exaggeration: Some(1.0),
        };
        let (l, v) = (o.light.normalize(), o.view.normalize());
        let h = (l + v).normalize();
        let want = o.ambient + o.diffuse * l.z + o.specular * h.z.powf(o.shininess);
        let got = reflectance(
            normal_from_gradient(0.0, 0.0, 1.0),
            l,
            half_vector(l, v),
            &o,
        );
        assert_eq!(got, want);
        let flat = Raster::zeros(6, 6, 1);
        let px = shade(&flat, &o);
        assert!(
            px.iter().all(|&p| p == (want * 255.0).round() as u8),
            "{px:?}"
        );
    }

    #[test]
    fn presets_follow_the_paper_and_bad_directions_are_refused() {
        assert_eq!(ShadeOptions::preset("china").unwrap().specular, 0.0);
        assert_eq!(ShadeOptions::preset("casting").unwrap().diffuse, 0.0);
        let rock = ShadeOptions::preset("rock").unwrap();
        assert!(rock.diffuse > 0.0 && rock.specular > 0.0 && rock.ambient > 0.0);
        assert!(
            ShadeOptions::preset("marble")
                .unwrap_err()
                .to_string()
                .contains("rock, china, casting")
        );
        let e = ShadeOptions {
            light: Vec3::ZERO,
            ..Default::default()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(e.contains("light") && e.contains("non-zero"), "{e}");
    }

    #[test]
    fn a_slope_facing_the_light_is_brighter_than_one_facing_away() {
        // A ridge: rising toward −x on the left half (faces the light), falling on the right.
        let (w, h) = (22, 6);
        let data: Vec<f32> = (0..w * h).map(|i| -((i % w) as f32 - 10.5).abs()).collect();
        let r = Raster::from_vec(w, h, 1, data).unwrap();
        let img = shade(
            &r,
            &ShadeOptions {
                exaggeration: Some(1.0),
                ..Default::default()
            },
        );
        let (lit, dark) = (img[2 * 20 + 3], img[2 * 20 + 16]);
        assert!(lit > dark + 50, "lit {lit} dark {dark}");
        // A flat field is ambient + diffuse·cos 45° + specular at the half vector.
        let flat = Raster::zeros(5, 5, 1);
        let l = Vec3::new(-1.0, -1.0, 2.0f32.sqrt()).normalize();
        let hv = (l + Vec3::Z).normalize();
        let expected = 0.1 + 0.75 * l.z + 0.2 * hv.z.powf(24.0);
        let got = shade(&flat, &ShadeOptions::default())[0] as f32 / 255.0;
        assert!((got - expected).abs() < 1.0 / 255.0, "{got} vs {expected}");
    }
}
