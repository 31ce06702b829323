//! Preprocessing, once for every consumer (bake, `stats`, sandblast, milling
//! adaptation): missing points refused or filled smoothly, infinite values refused, a
//! least-squares plane removed, integer down-sampling.

pub mod filter;
pub mod level;
pub mod missing;
pub mod resample;

use crate::error::{Error, Result};
use crate::raster::Raster;
use level::level_plane;
use resample::{DownsampleFilter, downsample};

/// Largest magnitude a map's values may have (10³⁰): far beyond any height or colour,
/// and far enough below f32's 3.4·10³⁸ that the analysis' sums and tables stay finite.
pub const MAX_VALUE: f32 = 1e30;

/// Form removal before analysis: the ISO 25178-2 F-operator as a least-squares
/// polynomial. Written `auto`, `plane`, `poly:N` (`poly:1` is `plane`) or `none`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Leveling {
    /// Subtract the least-squares plane from height maps (1 channel), leave colour as is.
    /// Bake flat-fields photos instead (colour, or grey in 8-bit levels: the light
    /// falling across the frame goes, the mean stays; a colour photo whose form changes
    /// its colour, not only its brightness, is content and stays as read;
    /// [`level::flatten_illumination`]).
    Auto,
    /// Always subtract the least-squares plane (`poly:1`).
    Plane,
    /// Always subtract the least-squares polynomial of this total degree (0: the mean;
    /// 2 or more; 1 is [`Leveling::Plane`]), at most [`level::MAX_POLY_DEGREE`].
    Poly(u8),
    /// Keep the data as is.
    None,
}

impl Leveling {
    /// Whether a map of `channels` channels is levelled.
    pub fn levels(self, channels: usize) -> bool {
        match self {
            Leveling::Plane | Leveling::Poly(_) => true,
            Leveling::None => false,
            Leveling::Auto => channels == 1,
        }
    }

    /// The polynomial degree removed from a map of `channels` channels (`None`: nothing).
    pub fn degree(self, channels: usize) -> Option<u8> {
        match self {
            Leveling::Poly(n) => Some(n),
            _ if self.levels(channels) => Some(1),
            _ => None,
        }
    }

    /// The operator as applied to a height map: `auto` is the plane there.
    pub fn for_heights(self) -> Leveling {
        match self {
            Leveling::Auto => Leveling::Plane,
            other => other,
        }
    }

    /// Removes the form from `raster` as this operator says.
    pub fn apply(self, raster: &mut Raster) {
        match self.degree(raster.channels) {
            Some(1) => level_plane(raster),
            Some(n) => level::level_poly(raster, n),
            None => {}
        }
    }
}

impl std::fmt::Display for Leveling {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Leveling::Auto => f.write_str("auto"),
            Leveling::Plane => f.write_str("plane"),
            Leveling::Poly(1) => f.write_str("plane"),
            Leveling::Poly(n) => write!(f, "poly:{n}"),
            Leveling::None => f.write_str("none"),
        }
    }
}

impl std::str::FromStr for Leveling {
    type Err = String;
    fn from_str(text: &str) -> std::result::Result<Leveling, String> {
        let bad = || {
            format!(
                "'{text}' is not a form removal; expected auto, plane, none or poly:N with N from 0 to {}",
                level::MAX_POLY_DEGREE
            )
        };
        match text.trim() {
            "auto" => Ok(Leveling::Auto),
            "plane" | "poly:1" => Ok(Leveling::Plane),
            "none" => Ok(Leveling::None),
            t => {
                let n: u8 = t
                    .strip_prefix("poly:")
                    .and_then(|n| n.parse().ok())
                    .ok_or_else(bad)?;
                if n > level::MAX_POLY_DEGREE {
                    return Err(bad());
                }
                Ok(Leveling::Poly(n))
            }
        }
    }
}

impl serde::Serialize for Leveling {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> serde::Deserialize<'de> for Leveling {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Leveling, D::Error> {
        let text = String::deserialize(d)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

/// Refuses infinite values and magnitudes over [`MAX_VALUE`] (missing points, NaN, are
/// let through).
pub fn check_values(r: &Raster, what: &str) -> Result<()> {
    if r.data.iter().any(|v| v.is_infinite()) {
        return Err(Error::decode(what, "the map holds infinite values"));
    }
    let largest = r
        .data
        .iter()
        .filter(|v| v.is_finite())
        .fold(0.0f32, |m, v| m.max(v.abs()));
    if largest > MAX_VALUE {
        return Err(Error::decode(
            what,
            format!(
                "values up to {largest:e}; expected magnitudes up to {MAX_VALUE:e} (the analysis sums and squares them in f32 tables)"
            ),
        ));
    }
    Ok(())
}

/// The scale-limited surface of a height map (ISO 25178-3): the form removed by the
/// F-operator `form` (`auto` is the plane), then, where `lfilter_px` gives the cut-off
/// in pixels along x and y, the waviness removed by the Gaussian L-filter, both over the
/// defined points only; then missing points filled smoothly (`fill_missing`) or refused.
pub fn scale_limited(
    raster: &Raster,
    what: &str,
    form: Leveling,
    lfilter_px: Option<(f64, f64)>,
    fill_missing: bool,
) -> Result<Raster> {
    check_values(raster, what)?;
    let mut r = raster.clone();
    form.for_heights().apply(&mut r);
    if let Some(cutoff) = lfilter_px {
        r = filter::roughness(&r, cutoff)?;
    }
    fill_or_refuse(&mut r, what, fill_missing)?;
    Ok(r)
}

/// Fills the missing points (NaN) of `r` smoothly where `fill` says so, else refuses a
/// map with any.
fn fill_or_refuse(r: &mut Raster, what: &str, fill: bool) -> Result<()> {
    let missing = r.count_nan();
    if missing > 0 {
        if !fill {
            return Err(Error::MissingData {
                what: what.to_string(),
                count: missing,
                total: r.data.len(),
            });
        }
        missing::fill_missing(r, what)?;
    }
    Ok(())
}

/// The preprocessing steps and their options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prep {
    /// Fill missing (NaN) points smoothly; refuse a map with any when false.
    pub fill_missing: bool,
    /// Plane levelling.
    pub leveling: Leveling,
    /// Integer down-sampling factor (1: none).
    pub downsample: usize,
    /// How down-sampling combines pixels.
    pub filter: DownsampleFilter,
}

impl Default for Prep {
    fn default() -> Prep {
        Prep {
            fill_missing: false,
            leveling: Leveling::Auto,
            downsample: 1,
            filter: DownsampleFilter::Nearest,
        }
    }
}

impl Prep {
    /// `raster` preprocessed; `what` names it in errors.
    pub fn apply(&self, raster: &Raster, what: &str) -> Result<Raster> {
        let mut r = raster.clone();
        fill_or_refuse(&mut r, what, self.fill_missing)?;
        check_values(&r, what)?;
        self.leveling.apply(&mut r);
        if self.downsample == 1 {
            Ok(r)
        } else {
            downsample(&r, self.downsample, self.filter)
        }
    }
}
