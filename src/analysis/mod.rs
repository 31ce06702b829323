//! Offline analysis stages, one file per method. Everything here runs once, at bake time.

pub(crate) mod cut;
pub mod gauss;
pub(crate) mod heal;
pub mod ncc;
pub(crate) mod periodic;
pub(crate) mod periodicity;
pub(crate) mod quilt;
pub mod roller;
pub mod rpn;
pub(crate) mod stitch;
pub(crate) mod taper;
pub mod translation;
