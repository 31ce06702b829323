//! The synth bank: the model built from the exemplar ([`crate::models::synth::synth_model`])
//! and its tables, in a bank.

use crate::bank::{Bank, BankHeader, ExemplarInfo, LevelInfo, Method, Record};
use crate::error::Result;
use crate::models::synth::{SynthParams, synth_model};
use crate::raster::Raster;

/// A synth bank of `ex`: the exemplar as its one tile, and per level the stack, the
/// appearance vectors and the candidates (as exact f32 integers).
pub fn bake_synth(
    ex: &Raster,
    params: &SynthParams,
    header_base: (ExemplarInfo, Option<f64>, u64, String),
    progress: &mut dyn FnMut(&str),
) -> Result<Bank> {
    let model = synth_model(ex, params)?;
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    let p = &model.params;
    progress(&format!("exemplar {w}×{h}×{c}: {}", p.describe()));
    let extra: Vec<Vec<f32>> = model
        .levels
        .iter()
        .map(|l| {
            let mut v = Vec::with_capacity(w * h * p.values_per_pixel(c));
            v.extend_from_slice(&l.stack);
            v.extend_from_slice(&l.appearance);
            v.extend(l.candidates.iter().map(|&i| i as f32));
            v
        })
        .collect();
    let (mean, sigma) = crate::bake::channel_stats(&ex.data, c);
    let (exemplar, spacing_um, seed, bake_text) = header_base;
    let header = BankHeader {
        method: Method::Synth,
        channels: c,
        tiles: 1,
        tile_size: [w, h],
        lattice: [[1.0, 0.0], [0.0, 1.0]],
        levels: vec![LevelInfo {
            size: [w, h],
            mean,
            sigma,
            shift: None,
        }],
        spacing_um,
        height_unit: crate::bake::height_unit(c, spacing_um),
        seed,
        exemplar,
        bake: format!(
            "method=synth levels={} k={} passes={} fine_passes={} jitter={} jitter_levels={} ragged={} coherence={} appearance_dims={} {bake_text}",
            p.levels,
            p.k,
            p.passes,
            p.fine_passes,
            p.jitter,
            p.jitter_levels,
            p.ragged,
            p.coherence,
            p.appearance_dims
        ),
        record: Record::Synth(
            serde_json::to_value(&model.params).map_err(|e| {
                crate::error::Error::bank("just baked", format!("synth section: {e}"))
            })?,
        ),
    };
    Bank::with_extra(
        header,
        vec![ex.data.clone()],
        vec![Vec::new()],
        extra,
        "just baked",
    )
}
