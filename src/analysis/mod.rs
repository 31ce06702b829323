//! Offline analysis stages, one file per method. Everything here runs once, at bake time.

pub mod cut;
pub mod gauss;
pub mod heal;
pub mod ncc;
pub mod periodic;
pub mod periodicity;
pub mod quilt;
pub mod roller;
pub mod rpn;
pub mod stitch;
pub mod taper;
pub mod translation;

pub use crate::prep::{level, missing, resample};
