//! Preprocessing, once for every consumer (bake, `stats`, sandblast, milling
//! adaptation): missing points refused or filled smoothly, infinite values refused, a
//! least-squares plane removed, integer down-sampling.

pub mod level;
pub mod missing;
pub mod resample;

use crate::error::{Error, Result};
use crate::raster::Raster;
use level::level_plane;
use missing::fill_missing;
use resample::{DownsampleFilter, downsample};

/// Largest magnitude a map's values may have (10³⁰): far beyond any height or colour,
/// and far enough below f32's 3.4·10³⁸ that the analysis' sums and tables stay finite.
pub const MAX_VALUE: f32 = 1e30;

/// Plane levelling before analysis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
// The names the CLI takes (clap's kebab-case), for the Python package's keywords.
#[serde(rename_all = "kebab-case")]
pub enum Leveling {
    /// Subtract the least-squares plane from height maps (1 channel), leave colour as is.
    Auto,
    /// Always subtract the least-squares plane.
    Plane,
    /// Keep the data as is.
    None,
}

impl Leveling {
    /// Whether a map of `channels` channels is levelled.
    pub fn levels(self, channels: usize) -> bool {
        match self {
            Leveling::Plane => true,
            Leveling::None => false,
            Leveling::Auto => channels == 1,
        }
    }
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
        let missing = r.count_nan();
        if missing > 0 {
            if !self.fill_missing {
                return Err(Error::MissingData {
                    what: what.to_string(),
                    count: missing,
                    total: r.data.len(),
                });
            }
            fill_missing(&mut r, what)?;
        }
        if r.data.iter().any(|v| v.is_infinite()) {
            return Err(Error::decode(what, "the map holds infinite values"));
        }
        let largest = r.data.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        if largest > MAX_VALUE {
            return Err(Error::decode(
                what,
                format!(
                    "values up to {largest:e}; expected magnitudes up to {MAX_VALUE:e} (the analysis sums and squares them in f32 tables)"
                ),
            ));
        }
        if self.leveling.levels(r.channels) {
            level_plane(&mut r);
        }
        if self.downsample == 1 {
            Ok(r)
        } else {
            downsample(&r, self.downsample, self.filter)
        }
    }
}
