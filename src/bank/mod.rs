//! Bank files: baked tiles plus everything the runtime needs to place them.
//!
//! # Format, version 1 (little-endian)
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `SURFTILE` |
//! | 4 | format version, u32 (= 1) |
//! | 4 | header length n, u32 |
//! | n | header: UTF-8 JSON, a [`BankHeader`] (rule, channels, tile size, lattice, mip levels, spacing, exemplar statistics, bake parameters…) |
//! | 4·m | payload: f32 texels of every mip level (level, tile, row, column, channel), then the T⁻¹ tables (level, channel, entry) |
//! | 4 | CRC-32 (IEEE) of every byte before it |
//!
//! The reader checks, in this order and before any of the data is used: magic, version,
//! length, checksum, header, sizes (the payload must be exactly what the header
//! describes) and values (all finite, tables monotone). A bank written by one build is
//! read by the next: `tests/data/golden-v1.bank` guards that.

use std::io::Write;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// File magic.
pub const MAGIC: &[u8; 8] = b"SURFTILE";
/// The format version this build writes and reads.
pub const VERSION: u32 = 1;

/// How cells pick tiles and how neighbours meet (DESIGN.md, "Runtime placement rules").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Rule {
    /// Variance-preserving triangle-grid blending of periodic Gaussian patches.
    Blend,
    /// Toroidal tiles with identical borders on a lattice (roller, seed 003): cell (i, j)
    /// shows tile `hash(seed, i, j) mod K`, stored in Hermite normal form.
    Toroidal,
    /// The procedural face-milling model (seed 000 §4): no tiles; the bank holds the
    /// configuration, the radial shape table and the angular noise profiles.
    Milling,
    /// Random sampling and gap filling (seed 002 §4): no tiles; the bank holds the
    /// exemplar (as one tile, with its mips), the lattice and the synthesis parameters.
    Rsgf,
    /// Wang tiles with hashed edge colours (quilt banks; Cohen et al. 2003): K⁴ square
    /// tiles, each edge's colour from the hash of the edge, the cell showing the tile
    /// whose four colours match. Stored like a toroidal bank on a square lattice.
    Wang,
    /// Parallel controllable texture synthesis (Lefebvre & Hoppe 2005/2006): the
    /// exemplar as one tile, and per synthesis level its Gaussian stack, appearance
    /// vectors and k-coherence candidates in the extra tables.
    Synth,
}

impl std::fmt::Display for Rule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Rule::Blend => "blend",
            Rule::Toroidal => "toroidal",
            Rule::Milling => "milling",
            Rule::Rsgf => "rsgf",
            Rule::Wang => "wang",
            Rule::Synth => "synth",
        })
    }
}

/// The analysis that made the tiles.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Random phase noise (seed 000 §3.1.2).
    Rpn,
    /// Asymptotic discrete spot noise (seed 000 §3.1.1).
    Adsn,
    /// Generalized roller: double toroidal tiles (seed 003).
    Roller,
    /// Procedural face milling (seed 000 §4); the exemplar is a milling TOML file.
    Milling,
    /// Near-regular random sampling and gap filling (seed 002 §4).
    Rsgf,
    /// Wang tiles quilted from crops with minimum-error seams (seed 000 §3.2.1 cuts,
    /// Cohen et al. 2003).
    Quilt,
    /// Parallel controllable texture synthesis on exemplar coordinates (Lefebvre &
    /// Hoppe 2005, appearance space 2006): structure kept, streamed in any split.
    Synth,
    /// Picks one from the exemplar and says why: a lattice → roller or rsgf,
    /// Gaussian-like → rpn, structured stochastic → synth. Bakes only; a bank records
    /// the method picked.
    Auto,
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Method::Rpn => "rpn",
            Method::Adsn => "adsn",
            Method::Roller => "roller",
            Method::Milling => "milling",
            Method::Rsgf => "rsgf",
            Method::Quilt => "quilt",
            Method::Synth => "synth",
            Method::Auto => "auto",
        })
    }
}

/// Statistics of the exemplar after preprocessing, kept for histogram checks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExemplarInfo {
    /// File the exemplar came from.
    pub source: String,
    /// Width in pixels after preprocessing.
    pub width: usize,
    /// Height in pixels after preprocessing.
    pub height: usize,
    /// Mean per channel (height units).
    pub mean: Vec<f64>,
    /// Standard deviation per channel (height units).
    pub std: Vec<f64>,
    /// Probabilities at which `quantiles` are given.
    pub quantile_levels: Vec<f64>,
    /// Quantiles per channel (height units), one row per channel.
    pub quantiles: Vec<Vec<f64>>,
}

/// One mip level of a bank.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LevelInfo {
    /// Tile size at this level, `[w, h]` texels; each texel covers 2^level pixels a side.
    /// For the toroidal rule, the level lattice's HNF rectangle `[A, C]`.
    pub size: [usize; 2],
    /// Mean of the tiles per channel (for the blend rule, of the Gaussian tiles).
    pub mean: Vec<f64>,
    /// Standard deviation of the tiles per channel.
    pub sigma: Vec<f64>,
    /// Toroidal rule: the row shift B of the level lattice's HNF (A, 0), (B, C).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shift: Option<usize>,
}

/// The self-describing header of a bank file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BankHeader {
    /// Placement rule.
    pub rule: Rule,
    /// Analysis method.
    pub method: Method,
    /// Values per pixel.
    pub channels: usize,
    /// Number of tiles (K).
    pub tiles: usize,
    /// Level-0 tile size `[w, h]` in pixels (powers of two).
    pub tile_size: [usize; 2],
    /// Lattice basis `[[ux, uy], [vx, vy]]` in pixels: for the blend rule, the
    /// triangle grid's edge vectors; for the toroidal rule, the reduced periodicity
    /// vectors u, v.
    pub lattice: [[f64; 2]; 2],
    /// Triangle edge length E in pixels (blend rule).
    pub triangle_edge: f64,
    /// Mip levels, level 0 first.
    pub levels: Vec<LevelInfo>,
    /// Pixel spacing in µm per pixel, if known.
    pub spacing_um: Option<f64>,
    /// Unit of the heights (e.g. "um"), or "" when unknown.
    pub height_unit: String,
    /// Seed of the bake (random phases, crop positions).
    pub seed: u64,
    /// Entries per T⁻¹ table.
    pub lut_size: usize,
    /// The tables cover standardised Gaussian values z ∈ [−lut_z_range, lut_z_range].
    pub lut_z_range: f64,
    /// The exemplar's statistics.
    pub exemplar: ExemplarInfo,
    /// The bake parameters, as text.
    pub bake: String,
    /// Toroidal rule: mean error per bin along each cut (u cut, v cut, then the closed
    /// cut of each further tile).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub seam_costs: Vec<f64>,
    /// Milling rule: the configuration and height adaptation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub milling: Option<crate::models::milling::MillingBankInfo>,
    /// RSGF rule: the synthesis parameters and the lattice.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rsgf: Option<crate::stream::RsgfParams>,
    /// Wang rule: colours per edge direction, K (the bank holds K⁴ tiles).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wang_colours: Option<usize>,
    /// Synth rule: the synthesis parameters; the extra tables hold one block per level.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub synth: Option<crate::stream::synth::SynthParams>,
}

/// A bank in memory: header, texels per level and T⁻¹ tables per level.
#[derive(Clone, Debug, PartialEq)]
pub struct Bank {
    /// What the bank is.
    pub header: BankHeader,
    /// Per level: `tiles × h × w × channels` texels.
    pub texels: Vec<Vec<f32>>,
    /// Per level: `channels × lut_size` table entries.
    pub luts: Vec<Vec<f32>>,
    /// Tables beyond texels and T⁻¹ that a rule needs (synth: one block per synthesis
    /// level, [`crate::stream::synth::SynthParams::values_per_pixel`] values per exemplar
    /// pixel); empty for the other rules. Written after the T⁻¹ tables.
    pub extra: Vec<Vec<f32>>,
}

impl Bank {
    /// A bank of `header`, `texels` and `luts`, validated ([`Bank::validate`]); `what`
    /// names it in errors.
    pub fn new(
        header: BankHeader,
        texels: Vec<Vec<f32>>,
        luts: Vec<Vec<f32>>,
        what: &str,
    ) -> Result<Bank> {
        Bank::with_extra(header, texels, luts, Vec::new(), what)
    }

    /// [`Bank::new`] with extra tables (the synth rule's).
    pub fn with_extra(
        header: BankHeader,
        texels: Vec<Vec<f32>>,
        luts: Vec<Vec<f32>>,
        extra: Vec<Vec<f32>>,
        what: &str,
    ) -> Result<Bank> {
        let bank = Bank {
            header,
            texels,
            luts,
            extra,
        };
        bank.validate(what)?;
        Ok(bank)
    }

    /// Checks that the header is coherent and the data matches it. `what` names the
    /// bank in errors.
    pub fn validate(&self, what: &str) -> Result<()> {
        let h = &self.header;
        let bad = |m: String| Err(Error::bank(what, m));
        if !(1..=4).contains(&h.channels) {
            return bad(format!("{} channels; expected 1 to 4", h.channels));
        }
        if h.tiles == 0 || h.tiles > 4096 {
            return bad(format!("{} tiles; expected 1 to 4096", h.tiles));
        }
        if h.rule == Rule::Milling {
            return self.validate_milling(what);
        }
        if h.rule == Rule::Rsgf {
            return self.validate_rsgf(what);
        }
        if h.rule == Rule::Synth {
            return self.validate_synth(what);
        }
        if !self.extra.is_empty() || h.synth.is_some() {
            return bad(format!("a {} bank with synthesis tables", h.rule));
        }
        let [w, ht] = h.tile_size;
        let toroidal = matches!(h.rule, Rule::Toroidal | Rule::Wang);
        if h.rule == Rule::Wang {
            let k = h.wang_colours.unwrap_or(0);
            let b = h.levels.first().and_then(|l| l.shift);
            if k == 0 || k.checked_pow(4) != Some(h.tiles) || w != ht || b != Some(0) {
                return bad(format!(
                    "Wang bank with {:?} colours, {} tiles of {w}×{ht}, row shift {b:?}; expected K⁴ square tiles on a square lattice",
                    h.wang_colours, h.tiles
                ));
            }
        }
        let lattice = if toroidal {
            if w == 0 || ht == 0 || w.saturating_mul(ht) > 1 << 26 {
                return bad(format!(
                    "tile size {w}×{ht}; expected a lattice cell of 1 to 2^26 pixels"
                ));
            }
            let b = h.levels.first().and_then(|l| l.shift).unwrap_or(usize::MAX);
            if b >= w {
                return bad(format!("row shift {b}; expected 0 to {}", w - 1));
            }
            Some(crate::lattice::Lattice {
                a: w as i64,
                b: b as i64,
                c: ht as i64,
            })
        } else {
            if !w.is_power_of_two()
                || !ht.is_power_of_two()
                || w < 4
                || ht < 4
                || w > 8192
                || ht > 8192
            {
                return bad(format!(
                    "tile size {w}×{ht}; expected powers of two from 4 to 8192"
                ));
            }
            if !(h.triangle_edge.is_finite() && h.triangle_edge >= 1.0) {
                return bad(format!(
                    "triangle edge {}; expected ≥ 1 pixel",
                    h.triangle_edge
                ));
            }
            None
        };
        if h.levels.is_empty() || h.levels.len() > 14 {
            return bad(format!("{} mip levels; expected 1 to 14", h.levels.len()));
        }
        if toroidal && h.lut_size != 0 {
            return bad(format!(
                "T⁻¹ table of {} entries; the toroidal rule has none",
                h.lut_size
            ));
        }
        if !toroidal
            && (h.lut_size < 2
                || h.lut_size > 1 << 20
                || !(h.lut_z_range > 0.0 && h.lut_z_range.is_finite()))
        {
            return bad(format!(
                "T⁻¹ table of {} entries over ±{}",
                h.lut_size, h.lut_z_range
            ));
        }
        if let Some(s) = h.spacing_um
            && !(s.is_finite() && s > 0.0)
        {
            return bad(format!("pixel spacing {s} µm; expected a positive number"));
        }
        if self.texels.len() != h.levels.len() || self.luts.len() != h.levels.len() {
            return bad("level count differs between header and data".into());
        }
        for (l, info) in h.levels.iter().enumerate() {
            let expected = match lattice {
                Some(lat) => {
                    let ll = lat.at_level(l as u32);
                    if info.shift != Some(ll.b as usize) {
                        return bad(format!(
                            "level {l} row shift {:?}; expected {}",
                            info.shift, ll.b
                        ));
                    }
                    [ll.a as usize, ll.c as usize]
                }
                None => [(w >> l).max(1), (ht >> l).max(1)],
            };
            if info.size != expected {
                return bad(format!(
                    "level {l} is {:?}; expected {expected:?}",
                    info.size
                ));
            }
            if info.mean.len() != h.channels || info.sigma.len() != h.channels {
                return bad(format!(
                    "level {l} statistics do not have {} channels",
                    h.channels
                ));
            }
            if info.mean.iter().chain(&info.sigma).any(|v| !v.is_finite())
                || info.sigma.iter().any(|&s| s < 0.0)
            {
                return bad(format!("level {l} statistics are not finite"));
            }
            if self.texels[l].len() != h.tiles * expected[0] * expected[1] * h.channels {
                return bad(format!("level {l} holds {} texels", self.texels[l].len()));
            }
            if self.luts[l].len() != h.channels * h.lut_size {
                return bad(format!(
                    "level {l} table holds {} entries",
                    self.luts[l].len()
                ));
            }
            if self.texels[l].iter().any(|v| !v.is_finite()) {
                return bad(format!("level {l} has non-finite texels"));
            }
            for table in self.luts[l].chunks_exact(h.lut_size.max(1)) {
                if table.iter().any(|v| !v.is_finite()) || table.windows(2).any(|p| p[1] < p[0]) {
                    return bad(format!(
                        "level {l} T⁻¹ table is not finite and non-decreasing"
                    ));
                }
            }
        }
        Ok(())
    }

    /// Validation of an RSGF bank: one tile (the exemplar) with its halvings, valid
    /// parameters that fit it, finite texels.
    fn validate_rsgf(&self, what: &str) -> Result<()> {
        let h = &self.header;
        let bad = |m: String| Err(Error::bank(what, m));
        let Some(params) = &h.rsgf else {
            return bad("rsgf rule without an rsgf section".into());
        };
        let [w, ht] = h.tile_size;
        if h.tiles != 1 || w == 0 || ht == 0 || w.saturating_mul(ht) > 1 << 22 {
            return bad(format!(
                "{} tiles of {w}×{ht}; expected one exemplar of 1 to 2^22 pixels",
                h.tiles
            ));
        }
        params
            .validate()
            .and_then(|_| params.check_exemplar(w, ht))
            .map_err(|e| Error::bank(what, format!("parameters: {e}")))?;
        if h.levels.is_empty() || h.levels.len() > 14 || h.lut_size != 0 {
            return bad(format!(
                "{} levels and a table of {}; expected 1 to 14 levels and none",
                h.levels.len(),
                h.lut_size
            ));
        }
        if self.texels.len() != h.levels.len() || self.luts.len() != h.levels.len() {
            return bad("level count differs between header and data".into());
        }
        for (l, info) in h.levels.iter().enumerate() {
            let expected = [w >> l, ht >> l];
            if info.size != expected
                || self.texels[l].len() != expected[0] * expected[1] * h.channels
            {
                return bad(format!(
                    "level {l} is {:?} with {} texels; expected {expected:?}",
                    info.size,
                    self.texels[l].len()
                ));
            }
            if self.texels[l].iter().any(|v| !v.is_finite()) {
                return bad(format!("level {l} has non-finite texels"));
            }
        }
        Ok(())
    }

    /// Validation of a synth bank: one tile (the exemplar), parameters that fit it, one
    /// table block per level of the right length, finite values, candidate indices that
    /// are whole numbers inside the exemplar.
    fn validate_synth(&self, what: &str) -> Result<()> {
        let h = &self.header;
        let bad = |m: String| Err(Error::bank(what, m));
        let Some(params) = &h.synth else {
            return bad("synth rule without a synth section".into());
        };
        let [w, ht] = h.tile_size;
        if h.tiles != 1 || w == 0 || ht == 0 || w.saturating_mul(ht) > 1 << 22 {
            return bad(format!(
                "{} tiles of {w}×{ht}; expected one exemplar of 1 to 2^22 pixels",
                h.tiles
            ));
        }
        params
            .validate()
            .and_then(|_| params.check_exemplar(w, ht, h.channels))
            .map_err(|e| Error::bank(what, format!("parameters: {e}")))?;
        if h.levels.len() != 1
            || h.levels[0].size != [w, ht]
            || h.lut_size != 0
            || self.texels.len() != 1
            || self.luts.len() != 1
            || self.texels[0].len() != w * ht * h.channels
            || !self.luts[0].is_empty()
        {
            return bad("synth layout: expected the exemplar as one level and no table".into());
        }
        if self.extra.len() != params.levels {
            return bad(format!(
                "{} table blocks; expected one per synthesis level ({})",
                self.extra.len(),
                params.levels
            ));
        }
        let per = params.values_per_pixel(h.channels);
        let values = (h.channels + params.appearance_dims) * w * ht;
        for (l, block) in self.extra.iter().enumerate() {
            if block.len() != per * w * ht {
                return bad(format!("level {l} holds {} table values", block.len()));
            }
            if block[..values].iter().any(|v| !v.is_finite())
                || block[values..]
                    .iter()
                    .any(|&v| !(v >= 0.0 && v < (w * ht) as f32 && v.fract() == 0.0))
            {
                return bad(format!(
                    "level {l} has non-finite values or candidates outside the exemplar"
                ));
            }
        }
        if self.texels[0].iter().any(|v| !v.is_finite()) {
            return bad("the exemplar has non-finite texels".into());
        }
        Ok(())
    }

    /// Validation of a milling bank: one level of noise profiles, one shape table, and
    /// a configuration that passes its own checks.
    fn validate_milling(&self, what: &str) -> Result<()> {
        use crate::models::milling::ring::{NOISE_PROFILES, NOISE_SAMPLES, SHAPE_LUT};
        let h = &self.header;
        let bad = |m: String| Err(Error::bank(what, m));
        let Some(info) = &h.milling else {
            return bad("milling rule without a milling section".into());
        };
        info.config
            .validate()
            .map_err(|e| Error::bank(what, format!("configuration: {e}")))?;
        if h.channels != 1
            || h.tiles != NOISE_PROFILES
            || h.tile_size != [NOISE_SAMPLES, 1]
            || h.levels.len() != 1
            || h.levels[0].size != [NOISE_SAMPLES, 1]
            || h.lut_size != SHAPE_LUT
        {
            return bad(format!(
                "milling layout: expected 1 channel, {NOISE_PROFILES} noise profiles of {NOISE_SAMPLES} samples, 1 level and a shape table of {SHAPE_LUT}"
            ));
        }
        if !h.spacing_um.is_some_and(|s| s.is_finite() && s > 0.0) {
            return bad("milling bank without a positive pixel spacing".into());
        }
        if let Some(a) = &info.adaptation
            && !(a.model_std_um > 0.0
                && a.target_std_um > 0.0
                && [
                    a.model_mean_um,
                    a.model_std_um,
                    a.target_mean_um,
                    a.target_std_um,
                ]
                .iter()
                .all(|v| v.is_finite()))
        {
            return bad(format!(
                "height adaptation {a:?} is not finite and positive"
            ));
        }
        if self.texels.len() != 1 || self.luts.len() != 1 {
            return bad("level count differs between header and data".into());
        }
        if self.texels[0].len() != NOISE_PROFILES * NOISE_SAMPLES || self.luts[0].len() != SHAPE_LUT
        {
            return bad("milling tables have the wrong length".into());
        }
        if self.texels[0]
            .iter()
            .chain(&self.luts[0])
            .any(|v| v.is_nan() || v.abs() > 1.0)
        {
            return bad("milling tables hold values outside [−1, 1]".into());
        }
        Ok(())
    }

    /// Serialises the bank (validating it first).
    pub fn to_bytes(&self) -> Result<Vec<u8>> {
        self.validate("being written")?;
        let header = serde_json::to_vec(&self.header)
            .map_err(|e| Error::bank("being written", format!("header: {e}")))?;
        let payload: usize = self
            .texels
            .iter()
            .chain(&self.luts)
            .chain(&self.extra)
            .map(|v| v.len() * 4)
            .sum();
        let mut out = Vec::with_capacity(20 + header.len() + payload);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
        out.extend_from_slice(&header);
        for block in self.texels.iter().chain(&self.luts).chain(&self.extra) {
            out.extend_from_slice(bytemuck::cast_slice::<f32, u8>(block));
        }
        let crc = crc32fast::hash(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        Ok(out)
    }

    /// Parses and validates a bank from bytes (`what` names it in errors).
    pub fn from_bytes(bytes: &[u8], what: &str) -> Result<Bank> {
        let bad = |m: &str| Error::bank(what, m.to_string());
        if bytes.len() < 20 || &bytes[..8] != MAGIC {
            return Err(bad("not a surftile bank (bad magic or too short)"));
        }
        let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap_or_default());
        if version != VERSION {
            return Err(Error::bank(
                what,
                format!("format version {version}; this build reads version {VERSION}"),
            ));
        }
        let header_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap_or_default()) as usize;
        let body_end = bytes.len() - 4;
        if 16 + header_len > body_end {
            return Err(bad("truncated: the header runs past the end of the file"));
        }
        let stored = u32::from_le_bytes(bytes[body_end..].try_into().unwrap_or_default());
        if crc32fast::hash(&bytes[..body_end]) != stored {
            return Err(bad("checksum mismatch: the file is truncated or corrupt"));
        }
        let header: BankHeader = serde_json::from_slice(&bytes[16..16 + header_len])
            .map_err(|e| Error::bank(what, format!("header is not valid: {e}")))?;
        if !(1..=4).contains(&header.channels) || header.levels.len() > 14 {
            return Err(bad("header describes an impossible layout"));
        }
        let payload = &bytes[16 + header_len..body_end];
        let mut offset = 0usize;
        let mut take = |count: usize| -> Result<Vec<f32>> {
            let n = count
                .checked_mul(4)
                .filter(|n| offset + n <= payload.len())
                .ok_or_else(|| bad("truncated: the data is shorter than the header says"))?;
            let v = bytemuck::pod_collect_to_vec::<u8, f32>(&payload[offset..offset + n]);
            offset += n;
            Ok(v)
        };
        let mut texels = Vec::new();
        for info in &header.levels {
            let count = header
                .tiles
                .checked_mul(info.size[0])
                .and_then(|n| n.checked_mul(info.size[1]))
                .and_then(|n| n.checked_mul(header.channels))
                .ok_or_else(|| bad("header sizes overflow"))?;
            texels.push(take(count)?);
        }
        let mut luts = Vec::new();
        for _ in &header.levels {
            luts.push(take(header.channels * header.lut_size)?);
        }
        let mut extra = Vec::new();
        if let Some(p) = &header.synth {
            let per_level = header.tile_size[0]
                .checked_mul(header.tile_size[1])
                .and_then(|n| n.checked_mul(p.values_per_pixel(header.channels)))
                .filter(|_| p.levels <= 12 && p.k <= 16 && p.appearance_dims <= 32)
                .ok_or_else(|| bad("synthesis table sizes overflow"))?;
            for _ in 0..p.levels {
                extra.push(take(per_level)?);
            }
        }
        if offset != payload.len() {
            return Err(bad("the data is longer than the header says"));
        }
        Bank::with_extra(header, texels, luts, extra, what)
    }

    /// Reads and validates a bank file.
    pub fn read(path: &Path) -> Result<Bank> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Bank::from_bytes(&bytes, &path.display().to_string())
    }

    /// Writes the bank atomically (temporary file, then rename).
    pub fn write(&self, path: &Path) -> Result<()> {
        let bytes = self.to_bytes()?;
        crate::io::write_atomically(path, |w| {
            w.write_all(&bytes).map_err(|e| Error::io(path, e))
        })
    }

    /// The summary `surftile info --json` prints.
    pub fn info_json(&self, file_bytes: Option<u64>) -> serde_json::Value {
        let h = &self.header;
        serde_json::json!({
            "format_version": VERSION,
            "rule": h.rule,
            "method": h.method,
            "channels": h.channels,
            "tiles": h.tiles,
            "tile_size": h.tile_size,
            "lattice": h.lattice,
            "triangle_edge": h.triangle_edge,
            "seam_costs": h.seam_costs,
            "mip_levels": h.levels.len(),
            "spacing_um": h.spacing_um,
            "height_unit": h.height_unit,
            "seed": h.seed,
            "lut_size": h.lut_size,
            "exemplar": h.exemplar,
            "bake": h.bake,
            "file_bytes": file_bytes,
        })
    }
}

#[cfg(target_endian = "big")]
compile_error!(
    "the bank format is little-endian and is cast with bytemuck; big-endian targets need byte swapping"
);
