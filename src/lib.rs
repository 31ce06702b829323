//! surftile: infinite, deterministic surfaces from a small exemplar or a set of machining
//! parameters, sampled by coordinate in constant time, identically however a region is
//! split.
//!
//! The front door is [`open`]: a bank file, a milling or model `.toml`, or a preset
//! name, and [`Source::surface`] for a seed.
//!
//! ```
//! use surftile::{Region, Surface};
//!
//! // A bank file, a milling or model `.toml`, or a preset name.
//! let source = surftile::open("china")?;
//! let surface = source.surface(7)?; // 7: placement seed
//! let h = surface.height(1e9 + 0.5, -42.25); // a billion pixels away, same cost
//! let mut tile = vec![0.0f32; 256 * 256 * surface.channels()];
//! surface.fill(&Region::new(-128.0, 0.0, 256, 256), &mut tile)?;
//! assert!(h.is_finite() && tile.iter().all(|v| v.is_finite()));
//! # Ok::<(), surftile::Error>(())
//! ```
//!
//! [`Open`] sets the options (the pixel spacing of procedural kinds, an imperfection
//! layer and its age). Baking an exemplar into a bank goes through
//! [`bake::Baker`]:
//!
//! ```
//! use surftile::bake::Baker;
//! use surftile::io::{ReadOptions, read_image};
//! use surftile::{Region, Surface};
//!
//! let exemplar = read_image("tiles/di-6.npy".as_ref(), &ReadOptions::default())?;
//! let bank = Baker::builder().seed(1).build()?.bake(&exemplar, "di-6", &mut |_| {})?;
//! let surface = surftile::kinds::open(&bank, 7)?; // any bank, whatever its kind
//! let mut tile = vec![0.0f32; 64 * 64 * surface.channels()];
//! surface.fill(&Region::new(1e9, 0.0, 64, 64), &mut tile)?;
//! # Ok::<(), surftile::Error>(())
//! ```
//!
//! Modules: [`io`] reads exemplars and writes outputs; [`analysis`] holds the offline
//! stages; [`bake`] runs them into a [`bank::Bank`]; [`models`] holds the procedural
//! surfaces; [`stream`] is the runtime ([`Surface`], [`Region`], the placement rules);
//! `gpu` (feature `gpu`) fills regions on any wgpu adapter from the WGSL twins in
//! `shaders/`; `view` (feature `view`) is the viewer; [`stats`] computes the quality
//! figures; [`shade`] and [`render`] make pictures.

pub mod analysis;
pub mod bake;
pub mod bank;
#[cfg(feature = "capi")]
pub mod capi;
pub mod dataset;
pub mod defects;
#[cfg(feature = "cli")]
pub mod demo;
pub mod error;
pub mod export;
pub mod fft;
pub mod front;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod hash;
pub mod imperfect;
pub mod io;
pub mod kinds;
pub mod lattice;
pub mod models;
pub(crate) mod nn;
pub mod normals;
pub mod prep;
pub mod raster;
pub mod render;
pub mod sandblast;
pub mod shade;
pub mod stats;
pub mod stream;
#[cfg(feature = "view")]
pub mod view;

pub use error::{Error, Result};
pub use front::{Open, Source, open};
pub use raster::Raster;
pub use stream::{Region, Surface};

/// The README's examples, compiled and run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
