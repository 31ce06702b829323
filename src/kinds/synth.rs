//! Synth banks: parallel controllable texture synthesis on exemplar coordinates
//! (Lefebvre & Hoppe 2005, appearance space 2006), streamed in any split.

use super::{GpuFill, Kind};
use crate::bank::{Bank, Rule};
use crate::error::Result;
use crate::models::synth::{SynthSurface, check_bank};
use crate::stream::Surface;

/// The synth rule's kind.
pub struct Synth;

impl Kind for Synth {
    fn name(&self) -> &'static str {
        "synth"
    }

    fn rule(&self) -> Option<Rule> {
        Some(Rule::Synth)
    }

    fn check_bank(&self, bank: &Bank, what: &str) -> Result<()> {
        check_bank(bank, what).map(|_| ())
    }

    fn open_bank(&self, bank: &Bank, seed: u32) -> Result<Box<dyn Surface>> {
        Ok(Box::new(SynthSurface::from_bank(bank, seed)?))
    }

    fn describe_bank(&self, bank: &Bank) -> Result<Vec<String>> {
        let p = check_bank(bank, "bank")?;
        Ok(vec![format!("rule        synth: {}", p.describe())])
    }

    fn gpu(&self) -> GpuFill {
        GpuFill::Cpu("synth banks have no GPU twin yet")
    }
}
