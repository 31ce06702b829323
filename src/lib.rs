//! surftile: infinite, deterministic surfaces from a small exemplar.
//!
//! Bake a measured height map once into a bank of periodic Gaussian tiles, then sample
//! the surface anywhere, in constant time, identically however a region is split:
//!
//! ```
//! use surftile::bake::Baker;
//! use surftile::io::{ReadOptions, read_image};
//! use surftile::stream::{BlendSurface, Region, Surface};
//!
//! let exemplar = read_image("tiles/di-6.npy".as_ref(), &ReadOptions::default())?;
//! let bank = Baker::builder().seed(1).build()?.bake(&exemplar, "di-6", &mut |_| {})?;
//! let surface = BlendSurface::new(&bank, 7)?; // 7: placement seed
//! let h = surface.height(1e9 + 0.5, -42.25); // a billion pixels away, same cost
//! let mut tile = vec![0.0f32; 256 * 256];
//! surface.fill(&Region::new(-128.0, 0.0, 256, 256), &mut tile)?;
//! assert!(h.is_finite() && tile.iter().all(|v| v.is_finite()));
//! # Ok::<(), surftile::Error>(())
//! ```
//!
//! Modules: [`io`] reads exemplars and writes outputs; [`analysis`] holds the offline
//! stages (levelling, missing points, periodic + smooth, Gaussianisation, RPN/ADSN,
//! periodicity detection, roller cuts); [`bake`] runs them into a [`bank::Bank`];
//! [`lattice`] holds integer lattices in Hermite normal form; [`models`] holds procedural surfaces (face milling, seed 000 §4); [`stream`] is the runtime
//! ([`stream::Surface`], [`stream::Region`], the blend and toroidal rules, [`stream::open`]); [`gpu`] fills regions on any wgpu adapter from the WGSL twins in `shaders/`; [`stats`] computes the quality figures; [`shade`]
//! and [`render`] make pictures; [`demo`] is `surftile demo`.

pub mod analysis;
pub mod bake;
pub mod bank;
#[cfg(feature = "cli")]
pub mod demo;
pub mod error;
pub mod fft;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod hash;
pub mod imperfect;
pub mod io;
pub mod lattice;
pub mod models;
pub mod nn;
pub mod raster;
pub mod render;
pub mod sandblast;
pub mod shade;
pub mod source;
pub mod stats;
pub mod stream;
#[cfg(feature = "view")]
pub mod view;

pub use error::{Error, Result};
pub use raster::Raster;
