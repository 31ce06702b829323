//! The blemish pattern's noise (seed 004 §5: "Perlin's noise function" and "fBm"), in
//! [0, 1], hashed from (seed, lattice point): lazy, endless and the same however a
//! region is split. Two-dimensional in the surface plane (the paper uses solid
//! texturing on 3-D positions; a height field's plane is its natural, distortion-free
//! parameterisation).

use crate::hash::hash_cell;

/// Which lattice noise.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NoiseKind {
    /// Hashed values at lattice points, quintic interpolation.
    Value,
    /// Perlin's gradient noise (hashed unit gradients, quintic fade).
    Perlin,
}

/// Noise parameters: a fractional Brownian motion of `octaves` lattice noises.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NoiseParams {
    /// Value or Perlin noise.
    pub noise: NoiseKind,
    /// Lattice spacing of the first octave, in surface pixels (> 0).
    pub scale_px: f64,
    /// Octaves of the fBm (1 to 12); 1 is the plain noise.
    pub octaves: u32,
    /// Amplitude ratio between octaves, in (0, 1).
    pub gain: f64,
    /// Frequency ratio between octaves (> 1).
    pub lacunarity: f64,
}

impl Default for NoiseParams {
    fn default() -> Self {
        NoiseParams {
            noise: NoiseKind::Perlin,
            scale_px: 24.0,
            octaves: 4,
            gain: 0.5,
            lacunarity: 2.0,
        }
    }
}

/// The 256 unit gradients of Perlin noise, at angles k·2π/256.
fn gradients() -> &'static [[f64; 2]; 256] {
    static TABLE: std::sync::OnceLock<[[f64; 2]; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|k| {
            let (s, c) = (k as f64 * (std::f64::consts::TAU / 256.0)).sin_cos();
            [c, s]
        })
    })
}

/// Quintic fade 6t⁵ − 15t⁴ + 10t³.
#[inline(always)]
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

impl NoiseParams {
    /// Checks every parameter, naming the first one out of range.
    pub fn validate(&self) -> crate::Result<()> {
        use crate::error::Error;
        crate::error::positive_param(
            "noise.scale_px",
            self.scale_px,
            "a positive noise scale in surface pixels",
        )?;
        if !(1..=12).contains(&self.octaves) {
            return Err(Error::param("noise.octaves", self.octaves, "1 to 12"));
        }
        if !(self.gain > 0.0 && self.gain < 1.0) {
            return Err(Error::param("noise.gain", self.gain, "a ratio in (0, 1)"));
        }
        // 64¹¹ · 2⁵² stays far inside f64: the finest octave's coordinates are finite.
        if !(self.lacunarity.is_finite() && self.lacunarity > 1.0 && self.lacunarity <= 64.0) {
            return Err(Error::param(
                "noise.lacunarity",
                self.lacunarity,
                "a frequency ratio above 1, at most 64",
            ));
        }
        Ok(())
    }

    /// The fBm at (x, y) surface pixels, in [0, 1].
    pub fn at(&self, seed: u32, x: f64, y: f64) -> f64 {
        let (mut f, mut a, mut sum, mut norm) = (1.0 / self.scale_px, 1.0, 0.0, 0.0);
        for o in 0..self.octaves {
            sum += a * self.octave(seed.wrapping_add(o.wrapping_mul(0x9E37_79B9)), x * f, y * f);
            norm += a;
            a *= self.gain;
            f *= self.lacunarity;
        }
        (sum / norm).clamp(0.0, 1.0)
    }

    /// One lattice noise at (u, v) lattice units, in [0, 1].
    fn octave(&self, seed: u32, u: f64, v: f64) -> f64 {
        let (iu, iv) = (u.floor(), v.floor());
        let (fu, fv) = (u - iu, v - iv);
        let (i, j) = (iu as i64, iv as i64);
        let (su, sv) = (fade(fu), fade(fv));
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        match self.noise {
            NoiseKind::Value => {
                let val = |di: i64, dj: i64| {
                    (hash_cell(seed, i + di, j + dj, 0x0A1E)[0] >> 8) as f64
                        * (1.0 / (1u32 << 24) as f64)
                };
                lerp(
                    lerp(val(0, 0), val(1, 0), su),
                    lerp(val(0, 1), val(1, 1), su),
                    sv,
                )
            }
            NoiseKind::Perlin => {
                // Unit gradients at 256 hashed angles; the dot with the offset.
                let grad = |di: i64, dj: i64, ou: f64, ov: f64| {
                    let h = hash_cell(seed, i + di, j + dj, 0x9E41)[0] >> 24;
                    let [c, s] = gradients()[h as usize];
                    c * ou + s * ov
                };
                let n = lerp(
                    lerp(grad(0, 0, fu, fv), grad(1, 0, fu - 1.0, fv), su),
                    lerp(grad(0, 1, fu, fv - 1.0), grad(1, 1, fu - 1.0, fv - 1.0), su),
                    sv,
                );
                // |n| ≤ √½ for unit gradients in 2-D.
                (0.5 + n * std::f64::consts::FRAC_1_SQRT_2).clamp(0.0, 1.0)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both kinds stay in [0, 1], use most of it, and are continuous (neighbouring
    /// points 10⁻³ lattice units apart differ by little).
    #[test]
    fn noise_is_in_the_unit_interval_and_continuous() {
        for noise in [NoiseKind::Value, NoiseKind::Perlin] {
            let p = NoiseParams {
                noise,
                octaves: 1,
                scale_px: 10.0,
                ..Default::default()
            };
            let (mut lo, mut hi, mut jump) = (1.0f64, 0.0f64, 0.0f64);
            for k in 0..20000 {
                let (x, y) = (
                    (k % 200) as f64 * 1.37 - 130.0,
                    (k / 200) as f64 * 2.11 - 90.0,
                );
                let v = p.at(3, x, y);
                assert!((0.0..=1.0).contains(&v), "{noise:?} {v}");
                lo = lo.min(v);
                hi = hi.max(v);
                jump = jump.max((p.at(3, x + 0.01, y) - v).abs());
            }
            assert!(hi - lo > 0.6, "{noise:?}: range {lo}..{hi}");
            assert!(jump < 0.01, "{noise:?}: jump {jump}");
        }
    }
}
