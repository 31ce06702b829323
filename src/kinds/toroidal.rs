//! Toroidal banks (the roller, seed 003): double toroidal tiles on a lattice in Hermite
//! normal form, cell (i, j) showing tile hash(seed, i, j) mod K.

use super::{GpuFill, Kind};
use crate::bank::{Bank, Rule};
use crate::error::Result;
use crate::stream::{Surface, ToroidalSurface};

/// The toroidal rule's kind.
pub struct Toroidal;

impl Kind for Toroidal {
    fn name(&self) -> &'static str {
        "toroidal"
    }

    fn rule(&self) -> Option<Rule> {
        Some(Rule::Toroidal)
    }

    fn check_bank(&self, bank: &Bank, what: &str) -> Result<()> {
        bank.validate(what)
    }

    fn open_bank(&self, bank: &Bank, seed: u32) -> Result<Box<dyn Surface>> {
        Ok(Box::new(ToroidalSurface::new(bank, seed)?))
    }

    fn describe_bank(&self, bank: &Bank) -> Result<Vec<String>> {
        let h = &bank.header;
        let [u, v] = h.lattice;
        let mut lines = vec![format!(
            "rule        toroidal on lattice u = ({}, {}), v = ({}, {}); HNF cell {}×{}, row shift {}",
            u[0],
            u[1],
            v[0],
            v[1],
            h.tile_size[0],
            h.tile_size[1],
            h.levels[0].shift.unwrap_or(0)
        )];
        let mut costs = h.seam_costs().iter();
        if let (Some(cu), Some(cv)) = (costs.next(), costs.next()) {
            lines.push(format!(
                "seam cost   u cut {cu:.4e}, v cut {cv:.4e} (mean squared error per bin)"
            ));
        }
        for (k, c) in costs.enumerate() {
            lines.push(format!("seam cost   tile {} border cut {c:.4e}", k + 2));
        }
        Ok(lines)
    }

    fn gpu(&self) -> GpuFill {
        GpuFill::Toroidal
    }
}
