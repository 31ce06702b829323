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
//! length, checksum, header (each rule's own fields present, no other rule's), sizes
//! (the payload must be exactly what the header describes) and values (all finite,
//! tables monotone). That is the container; what a model kind's record must hold
//! (milling, RSGF, synth parameters and tables) its kind checks (`kinds::check`, run by
//! `kinds::read_bank`, `kinds::write_bank` and every open). A bank written by one build
//! is read by the next: `tests/data/golden-v1*.bank` guard that.

use std::io::Write;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, MAX_PARAMETER, Result, positive_param};

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
    /// Image quilting in a chessboard of tiles (Efros & Freeman 2001, made streamable):
    /// the exemplar as one tile, with its mips, and the quilting parameters.
    Quilting,
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
            Rule::Quilting => "quilting",
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
    /// Image quilting (Efros & Freeman 2001) made streamable: quilted tiles in a
    /// chessboard, free tiles alone, bound tiles matched and cut against their
    /// neighbours' margins; objects kept whole.
    Quilting,
    /// Picks one from the exemplar and says why: a lattice → roller or rsgf, a
    /// Gaussian-like height map → rpn, structured stochastic (or a photo that rpn
    /// scores worse on coherence) → rsgf --stochastic (on its torus repeated where it is
    /// too small for a patch; synth where it is over rsgf's size). Bakes only; a bank
    /// records the method picked.
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
            Method::Quilting => "quilting",
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
    /// A photo's full scale (255 for 8-bit levels): renders keep its values on [0, full]
    /// rather than stretching them ([`crate::io::photo_full_scale`]). None for heights,
    /// and in banks written before it was recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub levels: Option<f32>,
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

/// The self-describing header of a bank file: the fields every rule has, and the
/// rule's own [`Record`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(into = "HeaderV1", try_from = "HeaderV1")]
pub struct BankHeader {
    /// Analysis method.
    pub method: Method,
    /// Values per pixel.
    pub channels: usize,
    /// Number of tiles (K).
    pub tiles: usize,
    /// Level-0 tile size `[w, h]` in pixels.
    pub tile_size: [usize; 2],
    /// Lattice basis `[[ux, uy], [vx, vy]]` in pixels: for the blend rule, the
    /// triangle grid's edge vectors; for the toroidal rule, the reduced periodicity
    /// vectors u, v; for RSGF, its lattice; zero where a rule has none.
    pub lattice: [[f64; 2]; 2],
    /// Mip levels, level 0 first.
    pub levels: Vec<LevelInfo>,
    /// Pixel spacing in µm per pixel, if known.
    pub spacing_um: Option<f64>,
    /// Unit of the heights (e.g. "um"), or "" when unknown.
    pub height_unit: String,
    /// Seed of the bake (random phases, crop positions).
    pub seed: u64,
    /// The exemplar's statistics.
    pub exemplar: ExemplarInfo,
    /// The bake parameters, as text.
    pub bake: String,
    /// The placement rule and its own fields.
    pub record: Record,
}

/// Each placement rule's own header fields, tagged by the rule: plain data. The
/// sections of the model kinds (milling, RSGF, synth) are JSON that the kind's module
/// decodes and checks when it opens the bank; `bank/` only carries them.
#[derive(Clone, Debug, PartialEq)]
pub enum Record {
    /// Blend rule: triangle edge E in pixels, and T⁻¹ tables of `lut_size` entries per
    /// channel and level covering standardised z ∈ [−lut_z_range, lut_z_range].
    Blend {
        /// Triangle edge length E in pixels.
        triangle_edge: f64,
        /// Entries per T⁻¹ table.
        lut_size: usize,
        /// The tables' half range in standardised Gaussian values.
        lut_z_range: f64,
    },
    /// Toroidal rule: mean error per bin along each cut (u cut, v cut, then the closed
    /// cut of each further tile).
    Toroidal {
        /// Mean error per bin along each cut.
        seam_costs: Vec<f64>,
    },
    /// Wang rule: K colours per edge direction (the bank holds K⁴ tiles).
    Wang {
        /// Colours per edge direction.
        colours: usize,
        /// Mean error per bin along the vertical and the interior cuts.
        seam_costs: Vec<f64>,
    },
    /// Milling rule: a radial shape table of `lut_size` entries, and the configuration
    /// with its height adaptation (`models::milling::MillingBankInfo`).
    Milling {
        /// Entries of the radial shape table.
        lut_size: usize,
        /// The configuration and adaptation.
        info: serde_json::Value,
    },
    /// RSGF rule: the synthesis parameters and lattice (`models::rsgf::RsgfParams`).
    Rsgf(serde_json::Value),
    /// Synth rule: the synthesis parameters (`models::synth::SynthParams`); its extra
    /// tables hold one equal block per synthesis level (`levels`).
    Synth(serde_json::Value),
    /// Quilting rule: the parameters (`models::quilting::QuiltingParams`).
    Quilting(serde_json::Value),
}

impl Record {
    /// The placement rule of this record.
    pub fn rule(&self) -> Rule {
        match self {
            Record::Blend { .. } => Rule::Blend,
            Record::Toroidal { .. } => Rule::Toroidal,
            Record::Wang { .. } => Rule::Wang,
            Record::Milling { .. } => Rule::Milling,
            Record::Rsgf(_) => Rule::Rsgf,
            Record::Synth(_) => Rule::Synth,
            Record::Quilting(_) => Rule::Quilting,
        }
    }
}

impl BankHeader {
    /// The placement rule.
    pub fn rule(&self) -> Rule {
        self.record.rule()
    }

    /// Entries per channel of each level's table: T⁻¹ (blend) or the shape table
    /// (milling); 0 for the other rules.
    pub fn lut_size(&self) -> usize {
        match self.record {
            Record::Blend { lut_size, .. } | Record::Milling { lut_size, .. } => lut_size,
            _ => 0,
        }
    }

    /// The triangle edge E in pixels of a blend bank; 0 for the other rules.
    pub fn triangle_edge(&self) -> f64 {
        match self.record {
            Record::Blend { triangle_edge, .. } => triangle_edge,
            _ => 0.0,
        }
    }

    /// The half range of a blend bank's T⁻¹ tables in standardised values; 0 for the
    /// other rules.
    pub fn lut_z_range(&self) -> f64 {
        match self.record {
            Record::Blend { lut_z_range, .. } => lut_z_range,
            _ => 0.0,
        }
    }

    /// The cut errors of a toroidal or Wang bank; empty for the other rules.
    pub fn seam_costs(&self) -> &[f64] {
        match &self.record {
            Record::Toroidal { seam_costs } | Record::Wang { seam_costs, .. } => seam_costs,
            _ => &[],
        }
    }

    /// Decodes the JSON section of a model kind as `T`; `section` names it in errors.
    pub fn decode<T: serde::de::DeserializeOwned>(
        value: &serde_json::Value,
        section: &str,
        what: &str,
    ) -> Result<T> {
        T::deserialize(value)
            .map_err(|e| Error::bank(what, format!("the {section} section is not valid: {e}")))
    }
}

/// The header as format version 1 writes it: every rule's fields side by side, those
/// of other rules absent or zero.
#[derive(Serialize, Deserialize)]
struct HeaderV1 {
    rule: Rule,
    method: Method,
    channels: usize,
    tiles: usize,
    tile_size: [usize; 2],
    lattice: [[f64; 2]; 2],
    triangle_edge: f64,
    levels: Vec<LevelInfo>,
    spacing_um: Option<f64>,
    height_unit: String,
    seed: u64,
    lut_size: usize,
    lut_z_range: f64,
    exemplar: ExemplarInfo,
    bake: String,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    seam_costs: Vec<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    milling: Option<serde_json::Value>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rsgf: Option<serde_json::Value>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    wang_colours: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    synth: Option<serde_json::Value>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    quilting: Option<serde_json::Value>,
}

impl From<BankHeader> for HeaderV1 {
    fn from(h: BankHeader) -> HeaderV1 {
        let rule = h.rule();
        let lut_size = h.lut_size();
        let seam_costs = h.seam_costs().to_vec();
        let (mut triangle_edge, mut lut_z_range) = (0.0, 0.0);
        let (mut milling, mut rsgf, mut synth, mut wang_colours) = (None, None, None, None);
        let mut quilting = None;
        match h.record {
            Record::Blend {
                triangle_edge: e,
                lut_z_range: z,
                ..
            } => (triangle_edge, lut_z_range) = (e, z),
            Record::Toroidal { .. } => {}
            Record::Wang { colours, .. } => wang_colours = Some(colours),
            Record::Milling { info, .. } => {
                // Version 1 milling banks record their shape table's range as 1.
                lut_z_range = 1.0;
                milling = Some(info);
            }
            Record::Rsgf(v) => rsgf = Some(v),
            Record::Synth(v) => synth = Some(v),
            Record::Quilting(v) => quilting = Some(v),
        }
        HeaderV1 {
            rule,
            method: h.method,
            channels: h.channels,
            tiles: h.tiles,
            tile_size: h.tile_size,
            lattice: h.lattice,
            triangle_edge,
            levels: h.levels,
            spacing_um: h.spacing_um,
            height_unit: h.height_unit,
            seed: h.seed,
            lut_size,
            lut_z_range,
            exemplar: h.exemplar,
            bake: h.bake,
            seam_costs,
            milling,
            rsgf,
            wang_colours,
            synth,
            quilting,
        }
    }
}

impl TryFrom<HeaderV1> for BankHeader {
    type Error = String;

    /// Refuses a header with another rule's fields, or without its own.
    fn try_from(v: HeaderV1) -> std::result::Result<BankHeader, String> {
        let rule = v.rule;
        let foreign = |present: bool, field: &str| -> std::result::Result<(), String> {
            if present {
                Err(format!(
                    "a {rule} bank with the field {field} of another rule"
                ))
            } else {
                Ok(())
            }
        };
        let missing = |field: &str| format!("a {rule} bank without its {field} section");
        foreign(rule != Rule::Milling && v.milling.is_some(), "milling")?;
        foreign(rule != Rule::Rsgf && v.rsgf.is_some(), "rsgf")?;
        foreign(rule != Rule::Synth && v.synth.is_some(), "synth")?;
        foreign(rule != Rule::Quilting && v.quilting.is_some(), "quilting")?;
        foreign(
            rule != Rule::Wang && v.wang_colours.is_some(),
            "wang_colours",
        )?;
        foreign(
            !matches!(rule, Rule::Toroidal | Rule::Wang) && !v.seam_costs.is_empty(),
            "seam_costs",
        )?;
        foreign(
            !matches!(rule, Rule::Blend | Rule::Milling) && v.lut_size != 0,
            "lut_size",
        )?;
        let record = match rule {
            Rule::Blend => Record::Blend {
                triangle_edge: v.triangle_edge,
                lut_size: v.lut_size,
                lut_z_range: v.lut_z_range,
            },
            Rule::Toroidal => Record::Toroidal {
                seam_costs: v.seam_costs,
            },
            Rule::Wang => Record::Wang {
                colours: v.wang_colours.ok_or_else(|| missing("wang_colours"))?,
                seam_costs: v.seam_costs,
            },
            Rule::Milling => Record::Milling {
                lut_size: v.lut_size,
                info: v.milling.ok_or_else(|| missing("milling"))?,
            },
            Rule::Rsgf => Record::Rsgf(v.rsgf.ok_or_else(|| missing("rsgf"))?),
            Rule::Synth => Record::Synth(v.synth.ok_or_else(|| missing("synth"))?),
            Rule::Quilting => Record::Quilting(v.quilting.ok_or_else(|| missing("quilting"))?),
        };
        Ok(BankHeader {
            method: v.method,
            channels: v.channels,
            tiles: v.tiles,
            tile_size: v.tile_size,
            lattice: v.lattice,
            levels: v.levels,
            spacing_um: v.spacing_um,
            height_unit: v.height_unit,
            seed: v.seed,
            exemplar: v.exemplar,
            bake: v.bake,
            record,
        })
    }
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
    /// level, the synth kind's values per exemplar pixel); empty for the other rules. Written after the T⁻¹ tables.
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
        if matches!(
            h.rule(),
            Rule::Milling | Rule::Rsgf | Rule::Synth | Rule::Quilting
        ) {
            return self.validate_model_layout(what);
        }
        if !self.extra.is_empty() {
            return bad(format!("a {} bank with synthesis tables", h.rule()));
        }
        let [w, ht] = h.tile_size;
        let toroidal = matches!(h.rule(), Rule::Toroidal | Rule::Wang);
        if let Record::Wang { colours: k, .. } = h.record {
            let b = h.levels.first().and_then(|l| l.shift);
            if k == 0 || k.checked_pow(4) != Some(h.tiles) || w != ht || b != Some(0) {
                return bad(format!(
                    "Wang bank with {k} colours, {} tiles of {w}×{ht}, row shift {b:?}; expected K⁴ square tiles on a square lattice",
                    h.tiles
                ));
            }
        }
        let (triangle_edge, lut_size, lut_z_range) = match h.record {
            Record::Blend {
                triangle_edge,
                lut_size,
                lut_z_range,
            } => (triangle_edge, lut_size, lut_z_range),
            _ => (0.0, 0, 0.0),
        };
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
            if !(in_range(triangle_edge) && triangle_edge >= 1.0) {
                return bad(format!(
                    "triangle edge {}; expected 1 to 1e30 pixels",
                    crate::error::short(triangle_edge)
                ));
            }
            None
        };
        if h.levels.is_empty() || h.levels.len() > 14 {
            return bad(format!("{} mip levels; expected 1 to 14", h.levels.len()));
        }
        let tables_fit =
            (2..=1 << 20).contains(&lut_size) && positive_param("", lut_z_range, "").is_ok();
        if !toroidal && !tables_fit {
            return bad(format!(
                "T⁻¹ table of {lut_size} entries over ±{lut_z_range}"
            ));
        }
        if let Some(s) = h.spacing_um
            && positive_param("spacing_um", s, "").is_err()
        {
            return bad(format!(
                "pixel spacing {} µm; expected a positive number within 1e-30 to 1e30",
                crate::error::short(s)
            ));
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
            if info.mean.iter().chain(&info.sigma).any(|v| !in_range(*v))
                || info.sigma.iter().any(|&s| s < 0.0)
            {
                return bad(format!(
                    "level {l} statistics are not finite within ±1e30 (σ ≥ 0)"
                ));
            }
            if self.texels[l].len() != h.tiles * expected[0] * expected[1] * h.channels {
                return bad(format!("level {l} holds {} texels", self.texels[l].len()));
            }
            if self.luts[l].len() != h.channels * lut_size {
                return bad(format!(
                    "level {l} table holds {} entries",
                    self.luts[l].len()
                ));
            }
            if !values_in_range(&self.texels[l]) {
                return bad(format!(
                    "level {l} has texels that are not finite within ±1e30"
                ));
            }
            for table in self.luts[l].chunks_exact(lut_size.max(1)) {
                if !values_in_range(table) || table.windows(2).any(|p| p[1] < p[0]) {
                    return bad(format!(
                        "level {l} T⁻¹ table is not finite within ±1e30 and non-decreasing"
                    ));
                }
            }
        }
        Ok(())
    }

    /// The layout checks of the model kinds' banks (milling, RSGF, synth): one block of
    /// texels and one table per level with the sizes the header gives, finite values,
    /// extra tables (synth only) in equal blocks. What the numbers must be for the kind
    /// is checked by the kind's module when it opens the bank.
    fn validate_model_layout(&self, what: &str) -> Result<()> {
        let h = &self.header;
        let bad = |m: String| Err(Error::bank(what, m));
        // RSGF and synth banks hold their exemplar as their one tile.
        let [w, ht] = h.tile_size;
        if matches!(
            h.record,
            Record::Rsgf(_) | Record::Synth(_) | Record::Quilting(_)
        ) && (h.tiles != 1 || w == 0 || ht == 0 || w.saturating_mul(ht) > 1 << 22)
        {
            return bad(format!(
                "{} tiles of {w}×{ht}; expected one exemplar of 1 to 2^22 pixels",
                h.tiles
            ));
        }
        if h.levels.is_empty() || h.levels.len() > 14 {
            return bad(format!("{} levels; expected 1 to 14", h.levels.len()));
        }
        if self.texels.len() != h.levels.len() || self.luts.len() != h.levels.len() {
            return bad("level count differs between header and data".into());
        }
        for (l, info) in h.levels.iter().enumerate() {
            let count = [info.size[0], info.size[1], h.channels]
                .iter()
                .try_fold(h.tiles, |n, &m| n.checked_mul(m));
            let table = h.channels.checked_mul(h.lut_size());
            if count != Some(self.texels[l].len()) || table != Some(self.luts[l].len()) {
                return bad(format!(
                    "level {l} holds {} texels and {} table entries",
                    self.texels[l].len(),
                    self.luts[l].len()
                ));
            }
            if !values_in_range(&self.texels[l]) || !values_in_range(&self.luts[l]) {
                return bad(format!(
                    "level {l} has values that are not finite within ±1e30"
                ));
            }
        }
        if !self.extra.iter().all(|b| values_in_range(b)) {
            return bad("synthesis tables hold values that are not finite within ±1e30".into());
        }
        match &h.record {
            Record::Synth(_)
                if self.extra.is_empty()
                    || self.extra.iter().any(|b| b.len() != self.extra[0].len()) =>
            {
                return bad("synthesis tables: expected one equal block per level".into());
            }
            Record::Synth(_) => {}
            _ if !self.extra.is_empty() => {
                return bad(format!("a {} bank with synthesis tables", h.rule()));
            }
            _ => {}
        }
        if let Some(s) = h.spacing_um
            && positive_param("spacing_um", s, "").is_err()
        {
            return bad(format!(
                "pixel spacing {} µm; expected a positive number within 1e-30 to 1e30",
                crate::error::short(s)
            ));
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
                .filter(|&n| {
                    offset
                        .checked_add(n)
                        .is_some_and(|end| end <= payload.len())
                })
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
            luts.push(take(
                header
                    .channels
                    .checked_mul(header.lut_size())
                    .ok_or_else(|| bad("header sizes overflow"))?,
            )?);
        }
        let mut extra = Vec::new();
        if let Record::Synth(p) = &header.record {
            // The rest of the payload, in one equal block per synthesis level.
            let levels = p
                .get("levels")
                .and_then(|v| v.as_u64())
                .filter(|&n| (1..=12).contains(&n))
                .ok_or_else(|| bad("the synth section needs 1 to 12 levels"))?
                as usize;
            let used: usize = texels.iter().chain(&luts).map(|v| v.len() * 4).sum();
            let rest = (payload.len() - used) / 4;
            if !rest.is_multiple_of(levels) {
                return Err(bad("synthesis tables do not split into equal levels"));
            }
            for _ in 0..levels {
                extra.push(take(rest / levels)?);
            }
        }
        if offset != payload.len() {
            return Err(bad("the data is longer than the header says"));
        }
        Bank::with_extra(header, texels, luts, extra, what)
    }

    /// Reads a bank file and checks its container ([`Bank::validate`]); the record of a
    /// model kind is checked by its kind when the bank is opened
    /// (`kinds::read_bank` checks both at once).
    pub fn read(path: &Path) -> Result<Bank> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Bank::from_bytes(&bytes, &path.display().to_string())
    }

    /// Writes the bank atomically (temporary file, then rename). A name with an image's
    /// extension (`.png`, `.tif`, `.npy`, …) is refused: a bank there would pass for an
    /// image.
    pub fn write(&self, path: &Path) -> Result<()> {
        if crate::io::Format::from_path(path).is_ok() {
            return Err(Error::param(
                "bank",
                path.display(),
                "a bank file name (e.g. .bank), not an image's",
            ));
        }
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
            "rule": h.rule(),
            "method": h.method,
            "channels": h.channels,
            "tiles": h.tiles,
            "tile_size": h.tile_size,
            "lattice": h.lattice,
            "triangle_edge": h.triangle_edge(),
            "seam_costs": h.seam_costs(),
            "mip_levels": h.levels.len(),
            "spacing_um": h.spacing_um,
            "height_unit": h.height_unit,
            "seed": h.seed,
            "lut_size": h.lut_size(),
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

/// A header number as the bake would have written it: finite, within ±10³⁰
/// ([`MAX_PARAMETER`], the bound every configuration's real parameters have).
fn in_range(v: f64) -> bool {
    v.is_finite() && v.abs() <= MAX_PARAMETER
}

/// Stored values as the bake would have written them: finite, within ±10³⁰ (the bake
/// refuses maps beyond [`crate::prep::MAX_VALUE`], the same bound), so a checksum-correct
/// bank cannot carry values whose blends and interpolations overflow.
fn values_in_range(v: &[f32]) -> bool {
    v.iter()
        .all(|x| x.is_finite() && x.abs() <= MAX_PARAMETER as f32)
}
