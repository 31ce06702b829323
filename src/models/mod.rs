//! Procedural surfaces: models evaluated directly at any point, without tiles.

pub mod fractal;
pub mod milling;
pub mod rugged;
pub mod voronoi;

use crate::error::Error;

/// A TOML parse error as a one-line decode error naming the file and line.
pub(crate) fn toml_error(text: &str, what: &str, e: toml::de::Error) -> Error {
    let line = e
        .span()
        .map(|s| format!("line {}: ", text[..s.start].lines().count().max(1)))
        .unwrap_or_default();
    Error::decode(what, format!("{line}{}", e.message().trim()))
}
