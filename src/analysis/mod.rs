//! Offline analysis stages, one file per method. Everything here runs once, at bake time.

pub mod cut;
pub mod gauss;
pub mod heal;
pub mod level;
pub mod missing;
pub mod ncc;
pub mod periodic;
pub mod periodicity;
pub mod quilt;
pub mod resample;
pub mod roller;
pub mod rpn;
pub mod stitch;
pub mod taper;
pub mod translation;
