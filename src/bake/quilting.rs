//! The quilting bank: the exemplar with its mips and the quilting parameters, λ chosen
//! by trial fills where it is not given ([`crate::models::quilting`]).

use crate::bank::{Bank, BankHeader, Method, Record};
use crate::error::{Error, Result};
use crate::models::quilting::{QuiltingModel, QuiltingParams, choose_penalty};
use crate::raster::Raster;

/// What a user may set of a quilting bake; the rest are [`QuiltingParams::default`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QuiltingOptions {
    /// The footprint penalty's weight; `None`: the smallest of
    /// [`crate::models::quilting::PENALTY_LADDER`] whose trial fill repeats little.
    pub penalty: Option<f32>,
    /// Block side in pixels.
    pub block_px: Option<usize>,
    /// Overlap (and margin) in pixels.
    pub overlap_px: Option<usize>,
}

impl QuiltingOptions {
    /// The parameters these options give (λ at its default where it is to be chosen).
    pub fn params(&self) -> QuiltingParams {
        let d = QuiltingParams::default();
        let block_px = self.block_px.unwrap_or(d.block_px);
        let overlap_px = self.overlap_px.unwrap_or(if self.block_px.is_some() {
            (block_px / 4).clamp(2, 64)
        } else {
            d.overlap_px
        });
        QuiltingParams {
            block_px,
            overlap_px,
            tile_px: (4 * block_px).max(d.tile_px.min(2048)),
            penalty: self.penalty.unwrap_or(d.penalty),
            ..d
        }
    }

    /// Checks the parameters the options give.
    pub fn validate(&self) -> Result<()> {
        self.params().validate()
    }
}

/// A quilting bank of `ex`.
pub fn bake(
    ex: &Raster,
    options: &QuiltingOptions,
    header_base: crate::bake::HeaderBase,
    progress: &mut dyn FnMut(&str),
) -> Result<Bank> {
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    let threads = crate::stream::default_threads();
    let params = options.params();
    let model = QuiltingModel::new(ex, &params, threads)?;
    let model = match options.penalty {
        Some(_) => model,
        None => {
            let (m, trials) = choose_penalty(model, threads)?;
            let list: Vec<String> = trials
                .iter()
                .map(|(l, e)| format!("λ {l}: {e:.3}"))
                .collect();
            progress(&format!(
                "λ {} from trial fills of {}² (windows repeated, 95% from one offset; at most {}): {}",
                m.params.penalty,
                crate::models::quilting::TRIAL_SIDE,
                crate::models::quilting::PENALTY_TARGET,
                list.join(", ")
            ));
            m
        }
    };
    let p = model.params.clone();
    let (levels, texels) = crate::bake::rsgf::exemplar_levels(ex);
    progress(&format!(
        "exemplar {w}×{h}×{c}, {} mip levels; blocks of {} px, overlap {} px, tiles of {} px, λ {}",
        levels.len(),
        p.block_px,
        p.overlap_px,
        p.tile_px,
        p.penalty
    ));
    let (exemplar, spacing_um, seed, bake_text) = header_base;
    let header = BankHeader {
        method: Method::Quilting,
        channels: c,
        tiles: 1,
        tile_size: [w, h],
        lattice: [[1.0, 0.0], [0.0, 1.0]],
        levels,
        spacing_um,
        height_unit: crate::bake::height_unit(c, spacing_um),
        seed,
        exemplar,
        bake: format!(
            "method=quilting block={} overlap={} tile={} penalty={} candidates={} dims={} tolerance={} {bake_text}",
            p.block_px, p.overlap_px, p.tile_px, p.penalty, p.candidates, p.dims, p.tolerance
        ),
        record: Record::Quilting(
            serde_json::to_value(&p)
                .map_err(|e| Error::bank("just baked", format!("quilting section: {e}")))?,
        ),
    };
    let luts = vec![Vec::new(); texels.len()];
    Bank::new(header, texels, luts, "just baked")
}
