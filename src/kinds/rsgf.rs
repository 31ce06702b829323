//! RSGF banks (seed 002 §4): random sampling and gap filling of blocks on a lattice, or
//! on the unit lattice for stochastic exemplars, joined along minimum-error cuts.

use super::{GpuFill, Kind};
use crate::bank::{Bank, Rule};
use crate::error::Result;
use crate::models::rsgf::RsgfSurface;
use crate::models::rsgf::check_bank;
use crate::stream::Surface;

/// The RSGF rule's kind.
pub struct Rsgf;

impl Kind for Rsgf {
    fn name(&self) -> &'static str {
        "rsgf"
    }

    fn rule(&self) -> Option<Rule> {
        Some(Rule::Rsgf)
    }

    fn check_bank(&self, bank: &Bank, what: &str) -> Result<()> {
        check_bank(bank, what).map(|_| ())
    }

    fn open_bank(&self, bank: &Bank, seed: u32) -> Result<Box<dyn Surface>> {
        Ok(Box::new(RsgfSurface::from_bank(bank, seed)?))
    }

    fn describe_bank(&self, bank: &Bank) -> Result<Vec<String>> {
        let p = check_bank(bank, "bank")?;
        Ok(vec![format!(
            "rule        rsgf on lattice v1 = ({}, {}), v2 = ({}, {}); blocks of {} px, border {} px, tolerance ±{} px, {:?} matching, joined by {}{}",
            p.v1.0,
            p.v1.1,
            p.v2.0,
            p.v2.1,
            p.block_px,
            p.border_px,
            p.tolerance_px,
            p.metric,
            crate::bake::rsgf::join_text(&p),
            if p.histogram.is_some() {
                ", values mapped to the exemplar's histogram"
            } else {
                ""
            }
        )])
    }

    fn gpu(&self) -> GpuFill {
        GpuFill::Cpu("RSGF banks have no GPU twin yet")
    }
}
