//! Abstract imperfection sources (seed 004 §4.1, eqs. 1–2): ambient, point,
//! directional, spotlight and slide projector, each with a cosine or Gaussian angular
//! falloff against the local surface normal and a scaling γ (negative: a scraping
//! source).
//!
//! Positions are in surface pixels, with z in the same pixels above the height field's
//! zero (heights scaled by the layer's `z_scale`).

use std::path::PathBuf;
use std::sync::Arc;

use glam::DVec3;

use crate::error::{Error, MAX_PARAMETER, Result, finite_param, positive_param};
use crate::raster::Raster;

/// Which form of eq. (1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SourceKind {
    /// (a) a constant.
    Ambient,
    /// (b) falloff / ρᶜ.
    Point,
    /// (c) falloff only, from a fixed direction.
    Directional,
    /// (d) smoothstep(c_out, c_in, SP·A) · falloff / ρᶜ.
    Spotlight,
    /// (e) map(SP) · falloff / ρᶜ: a mask image projected from the source.
    Projector,
}

/// The angular falloff of eq. (1) against the angle θ between the normal and PS.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Falloff {
    /// cos^η(θ), 0 from θ = 90° on.
    #[default]
    Cosine,
    /// exp(−θ²/(2η²)), η in radians.
    Gaussian,
}

fn one() -> f64 {
    1.0
}

/// One source as a configuration file gives it (`[[source]]` tables).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SourceConfig {
    /// The form.
    pub kind: SourceKind,
    /// γ of eq. (2); negative for a scraping source. Default 1.
    #[serde(default = "one")]
    pub gamma: f64,
    /// The ambient constant. Default 1.
    #[serde(default = "one")]
    pub value: f64,
    /// Position (x, y, z) in surface pixels: point, spotlight, projector.
    #[serde(default)]
    pub position: Option<[f64; 3]>,
    /// Directional: the direction toward the source. Spotlight and projector: the
    /// axis they point along, from the source.
    #[serde(default)]
    pub direction: Option<[f64; 3]>,
    /// Cosine or Gaussian angular falloff. Default cosine.
    #[serde(default)]
    pub falloff: Falloff,
    /// η_c (cosine exponent) or η_g (Gaussian σ, radians). Default 1.
    #[serde(default = "one")]
    pub eta: f64,
    /// c of the 1/ρᶜ distance falloff (point, spotlight, projector). Default 0.
    #[serde(default)]
    pub distance_power: f64,
    /// Spotlight: cosine of the inner cone's half angle (full flux within).
    #[serde(default)]
    pub cos_inner: Option<f64>,
    /// Spotlight: cosine of the outer cone's half angle (no flux outside).
    #[serde(default)]
    pub cos_outer: Option<f64>,
    /// Projector: the mask image (8/16-bit PNG, white = 1), relative to the
    /// configuration file.
    #[serde(default)]
    pub mask: Option<PathBuf>,
    /// Projector: the full field of view across the mask, in degrees. Default 60.
    #[serde(default)]
    pub fov_deg: Option<f64>,
}

/// A validated source, ready to evaluate.
#[derive(Clone, Debug)]
pub struct Source {
    kind: SourceKind,
    gamma: f64,
    value: f64,
    position: DVec3,
    /// Directional: unit vector toward the source; spotlight/projector: unit axis.
    direction: DVec3,
    /// Projector: unit right and up vectors across the mask.
    right: DVec3,
    up: DVec3,
    tan_half: f64,
    falloff: Falloff,
    eta: f64,
    power: f64,
    cos_in: f64,
    cos_out: f64,
    mask: Option<Arc<Raster>>,
}

/// smoothstep(a, b, v): 0 for v ≤ a, 1 for v ≥ b, 3t² − 2t³ between (a hard step when
/// a = b).
pub fn smoothstep(a: f64, b: f64, v: f64) -> f64 {
    if v <= a {
        0.0
    } else if v >= b {
        1.0
    } else {
        let t = (v - a) / (b - a);
        t * t * (3.0 - 2.0 * t)
    }
}

impl Source {
    /// Validates `c` (source number `index`, from 1, in messages); a mask path is read
    /// relative to `base`.
    pub fn new(c: &SourceConfig, index: usize, base: Option<&std::path::Path>) -> Result<Source> {
        let mut s = Source::check(c, index)?;
        if let (SourceKind::Projector, Some(path)) = (c.kind, c.mask.as_ref()) {
            let path = match base {
                Some(b) if path.is_relative() => b.join(path),
                _ => path.clone(),
            };
            if !path.exists() {
                return Err(Error::param(
                    format!("source {index}: mask"),
                    path.display(),
                    "an existing PNG mask image (the file is missing)",
                ));
            }
            s.mask = Some(Arc::new(crate::io::read_unit(&path)?.channel(0)));
        }
        Ok(s)
    }

    /// Checks every value of `c` that needs no file (a projector's mask is read by
    /// [`Source::new`]): what [`crate::imperfect::ImperfectConfig::validate`] checks, so
    /// a configuration is refused when it is read, not when the layer is built.
    pub fn check(c: &SourceConfig, index: usize) -> Result<Source> {
        let name = |key: &str| format!("source {index}: {key}");
        let finite3 = |key: &str, v: Option<[f64; 3]>| -> Result<DVec3> {
            let v = v.ok_or_else(|| {
                Error::param(
                    name(key),
                    "missing",
                    format!("[x, y, z] for a {:?} source", c.kind).to_lowercase(),
                )
            })?;
            let d = DVec3::from_array(v);
            if !v.iter().all(|x| x.is_finite() && x.abs() <= MAX_PARAMETER) {
                return Err(Error::param(
                    name(key),
                    format!("{v:?}"),
                    "finite numbers, at most 1e30 in magnitude",
                ));
            }
            Ok(d)
        };
        let unit = |key: &str, v: Option<[f64; 3]>| -> Result<DVec3> {
            let d = finite3(key, v)?;
            if d.length() == 0.0 {
                return Err(Error::param(
                    name(key),
                    format!("{:?}", d.to_array()),
                    "a direction of non-zero length",
                ));
            }
            Ok(d.normalize())
        };
        finite_param(&name("gamma"), c.gamma, "a finite scaling γ")?;
        positive_param(
            &name("eta"),
            c.eta,
            "a positive falloff η (cosine exponent, or Gaussian σ in radians)",
        )?;
        if !(c.distance_power.is_finite() && (0.0..=16.0).contains(&c.distance_power)) {
            return Err(Error::param(
                name("distance_power"),
                c.distance_power,
                "c from 0 to 16 for the 1/ρᶜ falloff",
            ));
        }
        let mut s = Source {
            kind: c.kind,
            gamma: c.gamma,
            value: c.value,
            position: DVec3::ZERO,
            direction: DVec3::Z,
            right: DVec3::X,
            up: DVec3::Y,
            tan_half: 1.0,
            falloff: c.falloff,
            eta: c.eta,
            power: c.distance_power,
            cos_in: 1.0,
            cos_out: 1.0,
            mask: None,
        };
        match c.kind {
            SourceKind::Ambient => {
                finite_param(&name("value"), c.value, "a finite constant")?;
            }
            SourceKind::Directional => s.direction = unit("direction", c.direction)?,
            SourceKind::Point => s.position = finite3("position", c.position)?,
            SourceKind::Spotlight => {
                s.position = finite3("position", c.position)?;
                s.direction = unit("direction", c.direction)?;
                let (ci, co) = match (c.cos_inner, c.cos_outer) {
                    (Some(i), Some(o)) => (i, o),
                    _ => {
                        return Err(Error::param(
                            name("cos_inner, cos_outer"),
                            "missing",
                            "the cosines of the inner and outer cones' half angles",
                        ));
                    }
                };
                if !((-1.0..=1.0).contains(&ci) && (-1.0..=1.0).contains(&co) && co <= ci) {
                    return Err(Error::param(
                        name("cos_outer, cos_inner"),
                        format!("{co}, {ci}"),
                        "cosines in [−1, 1] with c_out ≤ c_in (the outer cone is the wider)",
                    ));
                }
                s.cos_in = ci;
                s.cos_out = co;
            }
            SourceKind::Projector => {
                s.position = finite3("position", c.position)?;
                s.direction = unit("direction", c.direction)?;
                let fov = c.fov_deg.unwrap_or(60.0);
                if !(fov > 0.0 && fov < 179.0) {
                    return Err(Error::param(
                        name("fov_deg"),
                        fov,
                        "a field of view in (0, 179) degrees",
                    ));
                }
                s.tan_half = (fov.to_radians() * 0.5).tan();
                // The mask's right is perpendicular to the axis and to the surface's z
                // (x for an axis straight down); its up completes the frame.
                let r = s.direction.cross(DVec3::Z);
                s.right = if r.length() > 1e-9 {
                    r.normalize()
                } else {
                    DVec3::X
                };
                s.up = s.right.cross(s.direction).normalize();
                if c.mask.is_none() {
                    return Err(Error::param(
                        name("mask"),
                        "missing",
                        "a mask image (PNG) to project",
                    ));
                }
            }
        }
        Ok(s)
    }

    /// The source's kind.
    pub fn kind(&self) -> SourceKind {
        self.kind
    }

    /// γ.
    pub fn gamma(&self) -> f64 {
        self.gamma
    }

    /// The same source with γ scaled by `age` (growth, seed 004 §4.1).
    pub fn aged(&self, age: f64) -> Source {
        Source {
            gamma: self.gamma * age,
            ..self.clone()
        }
    }

    /// Its position, for sources that have one.
    pub fn position(&self) -> Option<DVec3> {
        matches!(
            self.kind,
            SourceKind::Point | SourceKind::Spotlight | SourceKind::Projector
        )
        .then_some(self.position)
    }

    /// The angular falloff for unit normal `n` and unit direction `to_source`.
    fn angular(&self, n: DVec3, to_source: DVec3) -> f64 {
        let c = n.dot(to_source).clamp(-1.0, 1.0);
        match self.falloff {
            Falloff::Cosine => {
                if c <= 0.0 {
                    0.0
                } else {
                    c.powf(self.eta)
                }
            }
            Falloff::Gaussian => {
                let theta = c.acos();
                (-theta * theta / (2.0 * self.eta * self.eta)).exp()
            }
        }
    }

    /// F_Sᵢ of eq. (1) at point `p` with unit normal `n`, without γ.
    pub fn flux(&self, p: DVec3, n: DVec3) -> f64 {
        match self.kind {
            SourceKind::Ambient => self.value,
            SourceKind::Directional => self.angular(n, self.direction),
            _ => {
                let ps = self.position - p;
                let rho = ps.length();
                if rho == 0.0 {
                    return 0.0;
                }
                let to_source = ps / rho;
                let scale = match self.kind {
                    SourceKind::Spotlight => {
                        smoothstep(self.cos_out, self.cos_in, (-to_source).dot(self.direction))
                    }
                    SourceKind::Projector => self.map(-to_source),
                    _ => 1.0,
                };
                if scale == 0.0 {
                    return 0.0;
                }
                scale * self.angular(n, to_source) / rho.powf(self.power)
            }
        }
    }

    /// The projector's mask value along the unit direction `sp` from the source:
    /// bilinear, 0 outside the image or behind the projector.
    fn map(&self, sp: DVec3) -> f64 {
        let Some(mask) = &self.mask else { return 0.0 };
        let a = sp.dot(self.direction);
        if a <= 0.0 {
            return 0.0;
        }
        let u = sp.dot(self.right) / (a * self.tan_half);
        let v = sp.dot(self.up) / (a * self.tan_half);
        // u, v in [−1, 1] span the image; its top row is up.
        let (w, h) = (mask.width as f64, mask.height as f64);
        let fx = (u + 1.0) * 0.5 * w - 0.5;
        let fy = (1.0 - v) * 0.5 * h - 0.5;
        if !(fx > -0.5 && fx < w - 0.5 && fy > -0.5 && fy < h - 0.5) {
            return 0.0;
        }
        let (x0, y0) = (fx.floor().max(0.0), fy.floor().max(0.0));
        let (tx, ty) = ((fx - x0).clamp(0.0, 1.0), (fy - y0).clamp(0.0, 1.0));
        let (x0, y0) = (x0 as usize, y0 as usize);
        let (x1, y1) = ((x0 + 1).min(mask.width - 1), (y0 + 1).min(mask.height - 1));
        let g = |x: usize, y: usize| mask.get(x, y, 0) as f64;
        let top = g(x0, y0) + (g(x1, y0) - g(x0, y0)) * tx;
        let bottom = g(x0, y1) + (g(x1, y1) - g(x0, y1)) * tx;
        top + (bottom - top) * ty
    }
}

/// F_S = Σ γᵢ F_Sᵢ (eq. 2).
pub fn total_flux(sources: &[Source], p: DVec3, n: DVec3) -> f64 {
    sources.iter().map(|s| s.gamma * s.flux(p, n)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(kind: SourceKind) -> SourceConfig {
        SourceConfig {
            kind,
            gamma: 1.0,
            value: 1.0,
            position: None,
            direction: None,
            falloff: Falloff::Cosine,
            eta: 1.0,
            distance_power: 0.0,
            cos_inner: None,
            cos_outer: None,
            mask: None,
            fov_deg: None,
        }
    }

    /// A spotlight at height 100 pointing straight down: exactly 0 outside the outer
    /// cone, exactly the unattenuated flux inside the inner one, in between between.
    #[test]
    fn a_spotlight_is_zero_outside_and_full_inside() {
        let (ci, co) = (20f64.to_radians().cos(), 35f64.to_radians().cos());
        let spot = Source::new(
            &SourceConfig {
                position: Some([0.0, 0.0, 100.0]),
                direction: Some([0.0, 0.0, -1.0]),
                cos_inner: Some(ci),
                cos_outer: Some(co),
                distance_power: 1.0,
                ..config(SourceKind::Spotlight)
            },
            1,
            None,
        )
        .unwrap();
        let point = Source::new(
            &SourceConfig {
                position: Some([0.0, 0.0, 100.0]),
                distance_power: 1.0,
                ..config(SourceKind::Point)
            },
            2,
            None,
        )
        .unwrap();
        let n = DVec3::Z;
        for r in 0..400 {
            let x = r as f64 * 0.5;
            let p = DVec3::new(x, 0.3 * x, 0.0);
            let angle = (p.truncate().length() / 100.0).atan().to_degrees();
            let f = spot.flux(p, n);
            if angle > 35.0 + 1e-9 {
                assert_eq!(f, 0.0, "at {angle}°");
            } else if angle < 20.0 - 1e-9 {
                assert_eq!(f, point.flux(p, n), "at {angle}°");
            } else {
                assert!(f >= 0.0 && f <= point.flux(p, n), "at {angle}°");
            }
        }
    }

    /// A negative (scraping) source lowers the sum; the sum is linear in every γ.
    #[test]
    fn negative_sources_lower_the_flux_and_sums_are_linear() {
        let dir = Source::new(
            &SourceConfig {
                direction: Some([0.2, -0.1, 1.0]),
                eta: 2.0,
                ..config(SourceKind::Directional)
            },
            1,
            None,
        )
        .unwrap();
        let point = Source::new(
            &SourceConfig {
                position: Some([30.0, 40.0, 50.0]),
                falloff: Falloff::Gaussian,
                eta: 0.7,
                distance_power: 0.5,
                ..config(SourceKind::Point)
            },
            2,
            None,
        )
        .unwrap();
        let n = DVec3::new(0.1, 0.3, 1.0).normalize();
        let p = DVec3::new(3.0, -7.0, 1.5);
        let with = |g1: f64, g2: f64| {
            total_flux(
                &[
                    Source {
                        gamma: g1,
                        ..dir.clone()
                    },
                    Source {
                        gamma: g2,
                        ..point.clone()
                    },
                ],
                p,
                n,
            )
        };
        assert!(with(1.0, -0.5) < with(1.0, 0.0));
        let (a, b) = (dir.flux(p, n), point.flux(p, n));
        for (g1, g2) in [(0.0, 0.0), (1.0, 2.0), (-3.0, 0.25), (7.5, -1.5)] {
            let want = g1 * a + g2 * b;
            assert!((with(g1, g2) - want).abs() <= 1e-12 * (1.0 + want.abs()));
        }
        // Doubling every γ doubles the sum.
        assert!((with(2.0, 1.0) - 2.0 * with(1.0, 0.5)).abs() < 1e-12);
    }

    /// A slide projector 200 px above the plane, pointing straight down with a 60°
    /// field, projects a mask whose left half is white and right half black: the flux
    /// is the bare cosine falloff (mask 1, no distance falloff) under the white half,
    /// 0 under the black half and outside the field.
    #[test]
    fn a_projector_projects_its_mask() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("half.png");
        let px: Vec<u8> = (0..32 * 32)
            .map(|i| if i % 32 < 16 { 255 } else { 0 })
            .collect();
        crate::io::write_png8(&path, 32, 32, 1, &px).unwrap();
        let s = Source::new(
            &SourceConfig {
                position: Some([0.0, 0.0, 200.0]),
                direction: Some([0.0, 0.0, -1.0]),
                mask: Some("half.png".into()),
                fov_deg: Some(60.0),
                ..config(SourceKind::Projector)
            },
            1,
            Some(dir.path()),
        )
        .unwrap();
        // The field's half width on the plane: 200·tan 30° ≈ 115 px.
        let f = |x: f64, y: f64| s.flux(DVec3::new(x, y, 0.0), DVec3::Z);
        // Straight down, the mask's right is +x: its white left half lands at x < 0.
        for (x, y) in [(-60.0, 20.0), (-100.0, -90.0), (-20.0, 70.0)] {
            let cos = 200.0 / (x * x + y * y + 200.0f64 * 200.0).sqrt();
            assert!(
                (f(x, y) - cos).abs() < 1e-12,
                "({x}, {y}): {} vs cos θ {cos}",
                f(x, y)
            );
        }
        assert_eq!(f(60.0, 20.0), 0.0);
        assert_eq!(f(100.0, -90.0), 0.0);
        assert_eq!(f(300.0, 0.0), 0.0, "outside the field");
        assert_eq!(f(0.0, -300.0), 0.0, "outside the field");
    }

    #[test]
    fn bad_sources_are_refused_with_the_reason() {
        let cases = [
            (
                SourceConfig {
                    direction: Some([0.0, 0.0, 0.0]),
                    ..config(SourceKind::Directional)
                },
                "non-zero",
            ),
            (config(SourceKind::Point), "position"),
            (
                SourceConfig {
                    position: Some([0.0, 0.0, 9.0]),
                    direction: Some([0.0, 0.0, -1.0]),
                    cos_inner: Some(0.5),
                    cos_outer: Some(0.9),
                    ..config(SourceKind::Spotlight)
                },
                "c_out ≤ c_in",
            ),
            (
                SourceConfig {
                    position: Some([0.0, 0.0, 9.0]),
                    direction: Some([0.0, 0.0, -1.0]),
                    mask: Some("no-such-mask.png".into()),
                    ..config(SourceKind::Projector)
                },
                "missing",
            ),
            (
                SourceConfig {
                    eta: 0.0,
                    ..config(SourceKind::Ambient)
                },
                "eta",
            ),
        ];
        for (c, needle) in cases {
            let e = Source::new(&c, 3, None).unwrap_err().to_string();
            assert!(e.contains(needle) && e.contains("source 3"), "{e}");
        }
    }
}
