//! A toroidal (roller) or Wang (quilt) bank's tile set for an engine that places tiles
//! itself: each level-0 tile as a float EXR or a 16-bit PNG, and `layout.json` with the
//! lattice, the edge colours of every tile and the hash rule, enough to reproduce
//! `render`'s pixels exactly (`tests/exports.rs` does, from the JSON alone).
//!
//! The layout, for pixel (x, y) at integer coordinates (texel centres):
//! - lattice cell j = ⌊y / C⌋, i = ⌊(x − j·B) / A⌋, texel (x − j·B − i·A, y − j·C) of the
//!   tile shown there (seed 003's Hermite normal form (A, 0), (B, C); DESIGN.md
//!   "Runtime placement rules" 1);
//! - the tile: `pick(hash_tile(seed, i, j), K)`; on an oblique lattice with several
//!   tiles, the same of the rhomboid cell of the reduced basis; for Wang banks, the tile
//!   whose edge colours match the hashed colours of the cell's four edges;
//! - between integer positions, bilinear over the four texels, each from its own cell.

use std::path::Path;

use serde_json::{Value, json};

use super::StagedDir;
use crate::bank::{Bank, Record, Rule};
use crate::error::{Error, Result};
use crate::hash::tile_key;
use crate::io::WriteMeta;
use crate::lattice::Lattice;
use crate::raster::Raster;

/// How the tiles are written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum TileFormat {
    /// Float32 OpenEXR: Y for heights, RGB for colour; the bank's values exactly.
    Exr,
    /// 16-bit PNG (grey or RGB) on one scale for all tiles: value = offset + scale·level,
    /// with offset and scale in `layout.json`.
    Png,
}

impl TileFormat {
    fn extension(self) -> &'static str {
        match self {
            TileFormat::Exr => "exr",
            TileFormat::Png => "png",
        }
    }
}

/// What [`export_tiles`] wrote.
#[derive(Clone, Debug)]
pub struct TileSet {
    /// The rule: "toroidal" or "wang".
    pub rule: &'static str,
    /// Tiles written.
    pub tiles: usize,
    /// Tile size [A, C] in pixels.
    pub size: [usize; 2],
    /// `layout.json` as written.
    pub layout: Value,
}

/// The rules whose banks this export handles, for errors.
const EXPORTABLE: &str = "toroidal (roller) and Wang (quilt) banks";

/// Writes `bank`'s level-0 tiles and `layout.json` (with the placement of `seed`) into
/// the new directory `dir`, all or nothing. Refuses banks of other rules, naming those
/// it takes.
pub fn export_tiles(bank: &Bank, seed: u32, dir: &Path, format: TileFormat) -> Result<TileSet> {
    let h = &bank.header;
    let rule = match h.rule() {
        Rule::Toroidal => "toroidal",
        Rule::Wang => "wang",
        other => {
            return Err(Error::Unsupported(format!(
                "export-tiles of a {other} bank: it has no tile set an engine can place; \
                 export-tiles takes {EXPORTABLE}"
            )));
        }
    };
    bank.validate("given to export-tiles")?;
    if !matches!(h.channels, 1 | 3) {
        return Err(Error::Unsupported(format!(
            "export-tiles of a {}-channel bank; expected 1 (heights) or 3 (RGB)",
            h.channels
        )));
    }
    let level = &h.levels[0];
    let [a, c] = level.size;
    let b = level.shift.unwrap_or(0);
    let k = h.tiles;
    let texels = &bank.texels[0];
    let stride = a * c * h.channels;

    let staged = StagedDir::new(dir, "--out")?;
    // Heights stay in the bank's unit (µm, or grey levels without one): as `render` writes them.
    let meta = WriteMeta::um(h.spacing_um);
    let (lo, hi) = texels
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, u), &v| (l.min(v), u.max(v)));
    let mut entries = Vec::with_capacity(k);
    for t in 0..k {
        let file = format!("tile-{t:04}.{}", format.extension());
        let raster = Raster::from_vec(
            a,
            c,
            h.channels,
            texels[t * stride..(t + 1) * stride].to_vec(),
        )?;
        let path = staged.path(&file);
        match format {
            TileFormat::Exr => crate::io::write_heights_with(&path, &raster, &meta)?,
            TileFormat::Png => crate::io::write_png16_range(&path, &raster, &meta, lo, hi)?,
        }
        let mut entry = json!({ "index": t, "file": file });
        if let Record::Wang { colours, .. } = h.record {
            // Tile ((x0·K + x1)·K + y0)·K + y1 (hash::wang_tile).
            let digit = |p: u32| (t / colours.pow(p)) % colours;
            entry["edges"] =
                json!({ "x0": digit(3), "x1": digit(2), "y0": digit(1), "y1": digit(0) });
        }
        entries.push(entry);
    }

    let mut layout = json!({
        "format": "surftile-tiles",
        "version": 1,
        "rule": rule,
        "channels": h.channels,
        "height_unit": h.height_unit,
        "spacing_um": h.spacing_um,
        "tile_size": [a, c],
        "lattice": {
            "a": a, "b": b, "c": c,
            "cell": "pixel (x, y) at integer coordinates lies in cell j = floor(y / c), \
                     i = floor((x - j*b) / a), at texel (x - j*b - i*a, y - j*c) of its tile \
                     (row-major, row y - j*c)",
        },
        "sampling": "texel centres at integer coordinates; between them, bilinear over the \
                     four texels (each located in its own cell), in f32: fx = x - floor(x), \
                     top = t00 + (t10 - t00)*fx, bottom = t01 + (t11 - t01)*fx, \
                     value = top + (bottom - top)*fy",
        "choice": choice(bank, seed, a as i64, b as i64, c as i64),
        "tiles": entries,
    });
    if format == TileFormat::Png {
        let span = if hi > lo { (hi - lo) as f64 } else { 0.0 };
        layout["png"] = json!({
            "offset": lo as f64,
            "scale": span / 65535.0,
            "decode": "value = offset + scale * level (16-bit level); the EXR export holds the exact values",
        });
    }
    let text = serde_json::to_string_pretty(&layout).expect("a JSON value prints");
    let path = staged.path("layout.json");
    crate::io::write_atomically(&path, |w| {
        std::io::Write::write_all(w, text.as_bytes()).map_err(|e| Error::io(&path, e))
    })?;
    staged.commit()?;
    Ok(TileSet {
        rule,
        tiles: k,
        size: [a, c],
        layout,
    })
}

/// The `choice` section of the layout: which tile a cell shows, as the runtime picks it
/// (`stream::toroidal`), spelled out for an engine.
fn choice(bank: &Bank, seed: u32, a: i64, b: i64, c: i64) -> Value {
    let h = &bank.header;
    let k = h.tiles;
    let fold = "fold(i) = u32(i) ^ (u32(i >> 32) * 0x9E3779B9)  (i a signed 64-bit cell index; \
                all arithmetic on u32 wraps)";
    let pick = "pick(h, K) = ((h >> 16) * K) >> 16";
    let hash_tile = "hash_tile(key, i, j): h = fold(i)*0x9E3779B1 ^ fold(j)*0x85EBCA77 ^ key; \
                     h ^= h >> 16; h *= 0x7FEB352D; h ^= h >> 15; h *= 0x846CA68B; h ^= h >> 16";
    if let Record::Wang { colours, .. } = h.record {
        return json!({
            "by": "wang",
            "seed": seed,
            "tiles": k,
            "colours": colours,
            "rule": "the cell (i, j) shows the tile whose edges are x0 = colour(i, j, 1), \
                     x1 = colour(i + 1, j, 1), y0 = colour(i, j, 2), y1 = colour(i, j + 1, 2); \
                     its index is ((x0*K + x1)*K + y0)*K + y1 with K = colours",
            "colour": "colour(i, j, stream) = pick(pcg4d(seed, fold(i), fold(j), stream)[0], K)",
            "pcg4d": "v = (v * 1664525 + 1013904223) for each word; x += y*w; y += z*x; \
                      z += x*y; w += y*z; each word ^= word >> 16; x += y*w; y += z*x; \
                      z += x*y; w += y*z; returns (x, y, z, w) (Jarzynski & Olano 2020)",
            "fold": fold,
            "pick": pick,
            "any_placement": "any arrangement whose neighbouring tiles agree on the colour \
                              of their shared edge is seamless",
        });
    }
    if k == 1 {
        return json!({
            "by": "single",
            "seed": seed,
            "tiles": 1,
            "rule": "every cell shows tile 0",
            "any_placement": "the one tile is periodic on the lattice",
        });
    }
    let key = tile_key(seed);
    if b == 0 {
        return json!({
            "by": "cell",
            "seed": seed,
            "key": key,
            "tiles": k,
            "rule": "cell (i, j) shows tile pick(hash_tile(key, i, j), K), K = tiles",
            "key_of_seed": "key = seed * 0xC2B2AE3D + 0x2545F491",
            "hash_tile": hash_tile,
            "fold": fold,
            "pick": pick,
            "any_placement": "all tiles share their borders: any tile in any cell is seamless",
        });
    }
    let [u, v] = Lattice { a, b, c }.reduced_basis();
    let det = u.0 * v.1 - u.1 * v.0;
    json!({
        "by": "rhomboid",
        "seed": seed,
        "key": key,
        "tiles": k,
        "u": [u.0, u.1],
        "v": [v.0, v.1],
        "det": det,
        "rule": "pixel (x, y) at integer coordinates shows tile pick(hash_tile(key, s, t), K), \
                 with its rhomboid cell s = floor((v[1]*x - v[0]*y) / det), \
                 t = floor((u[0]*y - u[1]*x) / det) (exact integer division); the texel is \
                 still found through the lattice cell (lattice.cell)",
        "key_of_seed": "key = seed * 0xC2B2AE3D + 0x2545F491",
        "hash_tile": hash_tile,
        "fold": fold,
        "pick": pick,
        "any_placement": "the tiles differ only inside their rhomboid s*u + t*v, s, t in \
                          [0, 1): choose one tile per rhomboid cell, any tile is seamless",
    })
}
