//! surftile: infinite, deterministic surfaces from a small exemplar.
pub mod analysis;
pub mod bake;
pub mod bank;
pub mod demo;
pub mod error;
pub mod fft;
pub mod hash;
pub mod io;
pub mod raster;
pub mod render;
pub mod shade;
pub mod stats;
pub mod stream;
pub use error::{Error, Result};
pub use raster::Raster;
