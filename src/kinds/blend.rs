//! Blend banks (RPN and ADSN): variance-preserving blending of periodic Gaussian tiles
//! on a triangle grid (seed 000 §3.1, DESIGN.md's blend rule).

use super::{GpuFill, Kind};
use crate::bank::{Bank, Rule};
use crate::error::Result;
use crate::stream::{BlendSurface, Surface};

/// The blend rule's kind.
pub struct Blend;

impl Kind for Blend {
    fn name(&self) -> &'static str {
        "blend"
    }

    fn rule(&self) -> Option<Rule> {
        Some(Rule::Blend)
    }

    fn check_bank(&self, bank: &Bank, what: &str) -> Result<()> {
        bank.validate(what)
    }

    fn open_bank(&self, bank: &Bank, seed: u32) -> Result<Box<dyn Surface>> {
        Ok(Box::new(BlendSurface::new(bank, seed)?))
    }

    fn describe_bank(&self, bank: &Bank) -> Result<Vec<String>> {
        Ok(vec![format!(
            "rule        blend (triangle edge {} px)",
            bank.header.triangle_edge()
        )])
    }

    fn gpu(&self) -> GpuFill {
        GpuFill::Blend
    }
}
