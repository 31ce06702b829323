//! Procedural surfaces: models evaluated directly at any point, without tiles.

pub mod fractal;
pub mod milling;
pub mod voronoi;
