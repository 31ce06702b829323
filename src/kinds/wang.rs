//! Wang banks (quilt; Cohen et al. 2003): K⁴ square tiles whose edges take the colour
//! hashed from the edge, stored like a toroidal bank on a square lattice.

use super::{GpuFill, Kind};
use crate::bank::{Bank, Record, Rule};
use crate::error::Result;
use crate::stream::{Surface, ToroidalSurface};

/// The Wang rule's kind.
pub struct Wang;

impl Kind for Wang {
    fn name(&self) -> &'static str {
        "wang"
    }

    fn rule(&self) -> Option<Rule> {
        Some(Rule::Wang)
    }

    fn check_bank(&self, bank: &Bank, what: &str) -> Result<()> {
        bank.validate(what)
    }

    fn open_bank(&self, bank: &Bank, seed: u32) -> Result<Box<dyn Surface>> {
        Ok(Box::new(ToroidalSurface::new(bank, seed)?))
    }

    fn describe_bank(&self, bank: &Bank) -> Result<Vec<String>> {
        let h = &bank.header;
        let colours = match h.record {
            Record::Wang { colours, .. } => colours,
            _ => 0,
        };
        let mut lines = vec![format!(
            "rule        wang: {colours} colours per edge direction, {} tiles of {}×{} px on a square lattice",
            h.tiles, h.tile_size[0], h.tile_size[1]
        )];
        if let [v, i] = h.seam_costs()[..] {
            lines.push(format!(
                "seam cost   vertex cuts {v:.4e}, interior cuts {i:.4e} (mean squared error per seam pixel)"
            ));
        }
        Ok(lines)
    }

    /// The toroidal fill, its cells choosing their tile by `wang_tile` (shaders/hash.wgsl).
    fn gpu(&self) -> GpuFill {
        GpuFill::Toroidal
    }
}
