//! Quilting banks: image quilting (Efros & Freeman 2001) in a chessboard of tiles,
//! streamed in any split ([`crate::models::quilting`]).

use super::{GpuFill, Kind};
use crate::bank::{Bank, Rule};
use crate::error::Result;
use crate::models::quilting::{QuiltingSurface, check_bank};
use crate::stream::Surface;

/// The quilting rule's kind.
pub struct Quilting;

impl Kind for Quilting {
    fn name(&self) -> &'static str {
        "quilting"
    }

    fn rule(&self) -> Option<Rule> {
        Some(Rule::Quilting)
    }

    fn check_bank(&self, bank: &Bank, what: &str) -> Result<()> {
        check_bank(bank, what).map(|_| ())
    }

    fn open_bank(&self, bank: &Bank, seed: u32) -> Result<Box<dyn Surface>> {
        Ok(Box::new(QuiltingSurface::from_bank(bank, seed)?))
    }

    fn describe_bank(&self, bank: &Bank) -> Result<Vec<String>> {
        let p = check_bank(bank, "bank")?;
        Ok(vec![format!(
            "rule        quilting: tiles of {} px in a chessboard, blocks of {} px with {} px overlaps, penalty λ {}, {} candidates per side from {}-number projections",
            p.tile_px, p.block_px, p.overlap_px, p.penalty, p.candidates, p.dims
        )])
    }

    fn gpu(&self) -> GpuFill {
        GpuFill::Cpu("quilting banks have no GPU twin: their tiles are quilted on the CPU")
    }
}
