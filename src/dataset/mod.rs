//! Training-data generation (issue 35): a dataset spec (TOML) turned into WebDataset
//! tar shards of samples, each a region of a source under drawn layers and defects.
//!
//! - **The spec**: `[dataset]` (counts, seed, size, spacing, outputs), `[[source]]`
//!   entries (a bank, a `.toml` or a preset, each with a weight), `[[layer]]` entries
//!   (a seed 004 layer with a probability and an age range) and `[[defect]]` entries (a
//!   [`DefectKind`] with a probability per sample). Unknown keys are refused and every
//!   value is checked with its range before anything is written ([`Dataset::load`]).
//! - **Determinism**: sample k is a pure function of (spec, k): its source, seed,
//!   region, layer and defects come from a counter hash of (spec seed, k)
//!   ([`Dataset::draw`]), so any shard can be made on any machine, in any order, with
//!   any number of threads, with the same bytes.
//! - **Output** ([`shard`]): `shard-{s:06}.tar` holds samples [s·n, (s+1)·n), each as
//!   `{key}.height.npy`, `{key}.mask.png`, `{key}.json` and `{key}.shaded.png` as the
//!   spec's outputs ask; `dataset.json` beside them records the spec, its hash, the
//!   counts and the mask legend.

pub mod shard;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::defects::{DefectConfig, DefectKind, Defects};
use crate::error::{Error, Result};
use crate::imperfect::{ImperfectConfig, Pattern};
use crate::{Open, Source};

pub use shard::{Members, Prepared, RunProgress, Sample, ShardWritten};

/// Most samples in a dataset.
pub const MAX_SAMPLES: u64 = 1_000_000_000;

/// Most samples in one shard.
pub const MAX_SAMPLES_PER_SHARD: u64 = 100_000;

/// Largest side of a sample, in pixels: a 4096² sample holds 64 MiB of heights (and an
/// imperfection layer about 30 bytes a sample while it is computed).
pub const MAX_SIDE: u64 = 4096;

/// Largest extent of the region origins, in pixels.
pub const MAX_EXTENT_PX: f64 = 1e9;

/// Default extent: origins are drawn in [-10⁶, 10⁶) pixels.
pub const DEFAULT_EXTENT_PX: f64 = 1e6;

/// Largest age drawn for a layer (seed 004's growth; the presets are at 1).
pub const MAX_AGE: f64 = 100.0;

/// Mask ids an imperfection layer may use: 1 to 15 (defects use 16 and up).
pub const MAX_LAYER_IDS: u8 = 15;

/// The name of the index file beside the shards.
pub const INDEX_FILE: &str = "dataset.json";

/// What each sample holds, in the order of its members in a shard.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Output {
    /// `{key}.height.npy`: float32 heights in the source's unit, (H, W) or (H, W, C).
    Height,
    /// `{key}.mask.png`: 8-bit mask ids, 0 = clean.
    Mask,
    /// `{key}.json`: what was drawn.
    Json,
    /// `{key}.shaded.png`: the heights shaded (8-bit grey).
    Shaded,
}

impl Output {
    /// The member's extension after the key.
    pub fn extension(self) -> &'static str {
        match self {
            Output::Height => "height.npy",
            Output::Mask => "mask.png",
            Output::Json => "json",
            Output::Shaded => "shaded.png",
        }
    }
}

fn default_spacing() -> f64 {
    crate::front::DEFAULT_SPACING_UM
}

fn default_extent() -> f64 {
    DEFAULT_EXTENT_PX
}

fn one() -> f64 {
    1.0
}

/// `[dataset]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DatasetSection {
    /// Samples in all (1 to [`MAX_SAMPLES`]).
    pub samples: u64,
    /// Samples per shard (1 to [`MAX_SAMPLES_PER_SHARD`]); the last shard may hold fewer.
    pub samples_per_shard: u64,
    /// The seed every draw comes from.
    pub seed: u64,
    /// Sample size [W, H] in pixels (1 to [`MAX_SIDE`] each).
    pub size: [u64; 2],
    /// Pixel spacing in µm for the sources that take one (milling) and for the defects
    /// over sources without one (banks keep their own spacing). Default 6.1.
    #[serde(default = "default_spacing")]
    pub spacing_um: f64,
    /// Which members each sample has (default: height and json, and mask when there
    /// are layers or defects).
    #[serde(default)]
    pub outputs: Option<Vec<Output>>,
    /// Region origins are drawn in [-extent, extent) pixels (default 10⁶).
    #[serde(default = "default_extent")]
    pub extent_px: f64,
}

/// A `[[source]]` entry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SourceEntry {
    /// A bank file, a milling or model `.toml` (relative to the spec's folder), or a
    /// preset name.
    pub path: String,
    /// Relative weight (> 0; default 1): a sample draws its source with probability
    /// weight / total.
    #[serde(default = "one")]
    pub weight: f64,
}

/// A `[[layer]]` entry: a seed 004 imperfection layer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerEntry {
    /// A layer `.toml` (relative to the spec's folder) or a preset (dust, patina,
    /// peeling).
    pub config: String,
    /// Probability that a sample has this layer. A sample has at most one layer, so the
    /// entries' probabilities add up to at most 1.
    pub probability: f64,
    /// The age's range [low, high] (0 to 100); default: the configuration's age.
    #[serde(default)]
    pub age: Option<[f64; 2]>,
}

/// A `[[defect]]` entry: the keys of a defect configuration's entry
/// ([`DefectKind`]), where the per-cell probability is called `cell_probability`, and
/// `probability`, the probability that a sample has this kind of defect at all.
#[derive(Clone, Debug, PartialEq)]
pub struct DefectEntry {
    /// Probability that a sample has these defects.
    pub probability: f64,
    /// The defects' placement and parameter ranges.
    pub defect: DefectKind,
}

impl<'de> Deserialize<'de> for DefectEntry {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        use serde::de::Error as _;
        let mut table = toml::Table::deserialize(d)?;
        let probability = match table.remove("probability") {
            Some(toml::Value::Float(p)) => p,
            Some(toml::Value::Integer(p)) => p as f64,
            Some(other) => {
                return Err(D::Error::custom(format!(
                    "probability = {other}: expected a number from 0 to 1"
                )));
            }
            None => return Err(D::Error::missing_field("probability")),
        };
        match table.remove("cell_probability") {
            Some(p) => table.insert("probability".into(), p),
            None => return Err(D::Error::missing_field("cell_probability")),
        };
        let defect = DefectKind::deserialize(toml::Value::Table(table))
            .map_err(|e| D::Error::custom(one_line(&e.to_string())))?;
        Ok(DefectEntry {
            probability,
            defect,
        })
    }
}

impl Serialize for DefectEntry {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::Error as _;
        let mut v = serde_json::to_value(&self.defect).map_err(S::Error::custom)?;
        if let Some(map) = v.as_object_mut() {
            if let Some(p) = map.remove("probability") {
                map.insert("cell_probability".into(), p);
            }
            map.insert("probability".into(), self.probability.into());
        }
        v.serialize(s)
    }
}

/// A dataset spec as written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DatasetSpec {
    /// Counts, seed, size, spacing and outputs.
    pub dataset: DatasetSection,
    /// The sources, at least one.
    #[serde(default)]
    pub source: Vec<SourceEntry>,
    /// Imperfection layers (at most one per sample).
    #[serde(default)]
    pub layer: Vec<LayerEntry>,
    /// Defect kinds (any number per sample).
    #[serde(default)]
    pub defect: Vec<DefectEntry>,
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Prefixes the parameter name of an error with where it sits in the spec.
fn within(prefix: &str, e: Error) -> Error {
    match e {
        Error::InvalidParameter {
            name,
            value,
            expected,
        } => Error::InvalidParameter {
            name: format!("{prefix}: {name}"),
            value,
            expected,
        },
        other => other,
    }
}

fn probability(key: &str, p: f64) -> Result<()> {
    if (0.0..=1.0).contains(&p) {
        Ok(())
    } else {
        Err(Error::param(
            key,
            crate::error::short(p),
            "a probability from 0 to 1",
        ))
    }
}

/// A source of the dataset, opened.
struct OpenSource {
    source: Source,
    channels: usize,
}

/// An imperfection layer of the dataset, loaded.
struct Layer {
    config: ImperfectConfig,
    base: Option<PathBuf>,
    /// Added to its non-zero ids in the mask, so that every layer entry has ids of its
    /// own.
    id_offset: u8,
}

/// What sample k drew ([`Dataset::draw`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Draw {
    /// Its index.
    pub index: u64,
    /// The `[[source]]` entry.
    pub source: usize,
    /// The surface's seed (its placement, a model's draws, the layer's noise and the
    /// defects' cells).
    pub seed: u32,
    /// The region's first sample, in pixels.
    pub x: i64,
    /// See [`Draw::x`].
    pub y: i64,
    /// The `[[layer]]` entry and its age, if any.
    pub layer: Option<(usize, f64)>,
    /// The `[[defect]]` entries it has.
    pub defects: Vec<usize>,
}

/// A counter hash of (seed, k): the draws of sample k, in a fixed order.
struct Draws {
    key: [u32; 3],
    round: u32,
    words: [u32; 4],
    used: usize,
}

impl Draws {
    fn new(seed: u64, k: u64) -> Draws {
        Draws {
            key: [seed as u32, (seed >> 32) as u32, k as u32 ^ 0x4441_5441],
            round: (k >> 32) as u32 ^ 0x5EED_0000,
            words: [0; 4],
            used: 4,
        }
    }

    fn word(&mut self) -> u32 {
        if self.used == 4 {
            self.words = crate::hash::pcg4d([self.key[0], self.key[1], self.key[2], self.round]);
            self.round = self.round.wrapping_add(0x0001_0000);
            self.used = 0;
        }
        self.used += 1;
        self.words[self.used - 1]
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        self.word() as f64 / 4294967296.0
    }
}

/// Picks an index from cumulative weights `c` (its last value the total) with `u` in
/// [0, 1).
fn pick(c: &[f64], u: f64) -> usize {
    let t = u * c[c.len() - 1];
    c.iter().position(|&v| t < v).unwrap_or(c.len() - 1)
}

/// A checked, opened dataset spec: sources opened, layers loaded, hash computed.
pub struct Dataset {
    spec: DatasetSpec,
    /// The spec's name in messages.
    what: String,
    sources: Vec<OpenSource>,
    layers: Vec<Layer>,
    outputs: Vec<Output>,
    /// Cumulative source weights.
    weights: Vec<f64>,
    /// What `dataset.json` holds.
    index: serde_json::Value,
    hash: String,
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

impl Dataset {
    /// Reads and checks a spec file; relative paths in it start from its folder.
    pub fn load(path: &Path) -> Result<Dataset> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let base = path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        Dataset::from_toml(&text, &base, &path.display().to_string())
    }

    /// Parses and checks a spec (`what` names it in errors); relative paths start from
    /// `base`. Opens every source and layer configuration, so that a bad one is refused
    /// before any sample is made.
    pub fn from_toml(text: &str, base: &Path, what: &str) -> Result<Dataset> {
        let spec: DatasetSpec =
            toml::from_str(text).map_err(|e| crate::models::toml_error(text, what, e))?;
        Dataset::new(spec, base, what)
    }

    /// Checks `spec` key by key and opens what it names.
    pub fn new(spec: DatasetSpec, base: &Path, what: &str) -> Result<Dataset> {
        let d = &spec.dataset;
        let inside = |key: &str, v: u64, lo: u64, hi: u64| {
            if (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(Error::param(
                    format!("dataset.{key}"),
                    v,
                    format!("{lo} to {hi}"),
                ))
            }
        };
        inside("samples", d.samples, 1, MAX_SAMPLES)?;
        inside(
            "samples_per_shard",
            d.samples_per_shard,
            1,
            MAX_SAMPLES_PER_SHARD,
        )?;
        inside("size[0] (width)", d.size[0], 1, MAX_SIDE)?;
        inside("size[1] (height)", d.size[1], 1, MAX_SIDE)?;
        if !(d.spacing_um.is_finite() && d.spacing_um > 0.0 && d.spacing_um <= 1e6) {
            return Err(Error::param(
                "dataset.spacing_um",
                crate::error::short(d.spacing_um),
                "a pixel spacing in µm above 0 and at most 1e6",
            ));
        }
        if !(d.extent_px.is_finite() && (1.0..=MAX_EXTENT_PX).contains(&d.extent_px)) {
            return Err(Error::param(
                "dataset.extent_px",
                crate::error::short(d.extent_px),
                format!("1 to {MAX_EXTENT_PX:e} pixels"),
            ));
        }
        let masked = !spec.layer.is_empty() || !spec.defect.is_empty();
        let mut outputs = match &d.outputs {
            None if masked => vec![Output::Height, Output::Mask, Output::Json],
            None => vec![Output::Height, Output::Json],
            Some(list) => list.clone(),
        };
        outputs.sort();
        outputs.dedup();
        if outputs.is_empty() {
            return Err(Error::param(
                "dataset.outputs",
                "[]",
                "at least one of \"height\", \"mask\", \"json\", \"shaded\"",
            ));
        }
        if outputs.contains(&Output::Mask) && !masked {
            return Err(Error::param(
                "dataset.outputs",
                "\"mask\"",
                "a [[layer]] or [[defect]] entry as well (the mask marks their pixels)",
            ));
        }
        if spec.source.is_empty() {
            return Err(Error::param(
                "source",
                "no entries",
                "at least one [[source]] entry (a bank, a .toml or a preset)",
            ));
        }
        let resolve = |p: &str| {
            let joined = base.join(p);
            if joined.exists() {
                joined
            } else {
                PathBuf::from(p)
            }
        };
        let mut files = Vec::new();
        let digest = |path: &Path| -> Result<serde_json::Value> {
            Ok(if path.is_file() {
                let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
                serde_json::Value::from(sha256_hex(&bytes))
            } else {
                serde_json::Value::Null
            })
        };
        let mut sources = Vec::new();
        let mut weights = Vec::new();
        let mut total = 0.0;
        for (n, s) in spec.source.iter().enumerate() {
            let key = format!("source {}", n + 1);
            if !(s.weight.is_finite() && s.weight > 0.0 && s.weight <= 1e12) {
                return Err(Error::param(
                    format!("{key}: weight"),
                    crate::error::short(s.weight),
                    "a weight above 0 (and at most 1e12)",
                ));
            }
            let path = resolve(&s.path);
            let source = Open::new(&path)
                .spacing_um(d.spacing_um)
                .open()
                .map_err(|e| within(&key, e))?;
            let channels = source.surface(0).map_err(|e| within(&key, e))?.channels();
            if masked && channels != 1 {
                return Err(Error::param(
                    format!("{key}: path"),
                    &s.path,
                    format!(
                        "a height source (one channel) under layers or defects; it has {channels}"
                    ),
                ));
            }
            files.push(serde_json::json!({
                "path": s.path,
                "kind": source.kind().name(),
                "sha256": digest(&path)?,
                "spacing_um": source.spacing_um(),
                "height_unit": source.height_unit(),
                "channels": channels,
            }));
            total += s.weight;
            weights.push(total);
            sources.push(OpenSource { source, channels });
        }
        let mut layers = Vec::new();
        let mut legend = BTreeMap::new();
        legend.insert(0u8, "clean".to_string());
        let mut next_id = 1u32;
        let mut sum = 0.0;
        for (n, l) in spec.layer.iter().enumerate() {
            let key = format!("layer {}", n + 1);
            probability(&format!("{key}: probability"), l.probability)?;
            sum += l.probability;
            if let Some(age) = l.age
                && !(age
                    .iter()
                    .all(|a| a.is_finite() && (0.0..=MAX_AGE).contains(a))
                    && age[0] <= age[1])
            {
                return Err(Error::param(
                    format!("{key}: age"),
                    format!(
                        "[{}, {}]",
                        crate::error::short(age[0]),
                        crate::error::short(age[1])
                    ),
                    format!("[low, high] with 0 ≤ low ≤ high ≤ {MAX_AGE}"),
                ));
            }
            let path = resolve(&l.config);
            let (config, layer_base) = ImperfectConfig::load(&path).map_err(|e| within(&key, e))?;
            let levels = match config.pattern {
                Pattern::Dust | Pattern::Patina => 1,
                Pattern::Peeling => config.layers.thresholds.len() as u32,
            };
            if next_id + levels - 1 > MAX_LAYER_IDS as u32 {
                return Err(Error::param(
                    format!("{key}: config"),
                    &l.config,
                    format!(
                        "layers with at most {MAX_LAYER_IDS} mask ids in all (this one would use ids {next_id} to {})",
                        next_id + levels - 1
                    ),
                ));
            }
            let pattern = format!("{:?}", config.pattern).to_lowercase();
            for level in 1..=levels {
                let name = if levels == 1 {
                    format!("layer {}: {pattern}", n + 1)
                } else {
                    format!("layer {}: {pattern} level {level}", n + 1)
                };
                legend.insert((next_id + level - 1) as u8, name);
            }
            files.push(serde_json::json!({"path": l.config, "sha256": digest(&path)?}));
            layers.push(Layer {
                config,
                base: layer_base,
                id_offset: (next_id - 1) as u8,
            });
            next_id += levels;
        }
        if sum > 1.0 + 1e-12 {
            return Err(Error::param(
                "layer: probability",
                format!("{} in all", crate::error::short(sum)),
                "at most 1 in all (a sample has at most one imperfection layer)",
            ));
        }
        for (n, e) in spec.defect.iter().enumerate() {
            let key = format!("defect {}", n + 1);
            probability(&format!("{key}: probability"), e.probability)?;
            probability(
                &format!("{key} ({}): cell_probability", e.defect.name()),
                e.defect.probability(),
            )?;
            DefectConfig {
                defect: vec![e.defect.clone()],
            }
            .validate()
            .map_err(|err| within(&key, err))?;
            let id = e.defect.mask_id();
            match legend.get(&id) {
                Some(name) if name != e.defect.name() => {
                    return Err(Error::param(
                        format!("{key} ({}): mask_id", e.defect.name()),
                        id,
                        format!("an id no other entry uses ({id} is {name})"),
                    ));
                }
                _ => {
                    legend.insert(id, e.defect.name().to_string());
                }
            }
        }
        // Defects need a height unit they can convert µm to (checked per source).
        if !spec.defect.is_empty() {
            let config = DefectConfig {
                defect: spec.defect.iter().map(|e| e.defect.clone()).collect(),
            };
            for (n, s) in sources.iter().enumerate() {
                let spacing = s.source.spacing_um().unwrap_or(d.spacing_um);
                Defects::new(&config, spacing, &s.source.height_unit(), 0)
                    .map_err(|e| within(&format!("source {}", n + 1), e))?;
            }
        }
        let canonical = serde_json::to_value(&spec)
            .map_err(|e| Error::decode(what, format!("cannot encode the spec: {e}")))?;
        let hashed = serde_json::json!({
            "surftile": env!("CARGO_PKG_VERSION"),
            "spec": canonical,
            "files": files,
        });
        let hash = format!(
            "sha256:{}",
            sha256_hex(&serde_json::to_vec(&hashed).expect("JSON values encode"))
        );
        let shards = d.samples.div_ceil(d.samples_per_shard);
        let members: Vec<&str> = outputs.iter().map(|o| o.extension()).collect();
        let mut index = serde_json::json!({
            "format": "surftile-dataset/1",
            "spec_hash": hash,
            "surftile": env!("CARGO_PKG_VERSION"),
            "samples": d.samples,
            "samples_per_shard": d.samples_per_shard,
            "shards": shards,
            "shard_pattern": format!("shard-{{000000..{:06}}}.tar", shards - 1),
            "members": members,
            "spec": canonical,
            "files": files,
        });
        if outputs.contains(&Output::Mask) {
            index["mask_legend"] = legend
                .iter()
                .map(|(id, name)| (id.to_string(), serde_json::Value::from(name.clone())))
                .collect::<serde_json::Map<_, _>>()
                .into();
        }
        Ok(Dataset {
            spec,
            what: what.to_string(),
            sources,
            layers,
            outputs,
            weights,
            index,
            hash,
        })
    }

    /// The spec as written.
    pub fn spec(&self) -> &DatasetSpec {
        &self.spec
    }

    /// Its hash: of the spec, the bytes of the files it names and the crate version.
    pub fn hash(&self) -> &str {
        &self.hash
    }

    /// What `dataset.json` holds.
    pub fn index(&self) -> &serde_json::Value {
        &self.index
    }

    /// The members each sample has, in their order in a shard.
    pub fn outputs(&self) -> &[Output] {
        &self.outputs
    }

    /// Samples in all.
    pub fn samples(&self) -> u64 {
        self.spec.dataset.samples
    }

    /// Shards in all.
    pub fn shards(&self) -> u64 {
        self.spec
            .dataset
            .samples
            .div_ceil(self.spec.dataset.samples_per_shard)
    }

    /// The samples of shard `s`.
    pub fn shard_samples(&self, s: u64) -> std::ops::Range<u64> {
        let n = self.spec.dataset.samples_per_shard;
        let start = s.saturating_mul(n).min(self.samples());
        start..(start + n).min(self.samples())
    }

    /// The file name of shard `s`.
    pub fn shard_name(s: u64) -> String {
        format!("shard-{s:06}.tar")
    }

    /// The key of sample k in its shard.
    pub fn key(k: u64) -> String {
        format!("{k:010}")
    }

    /// What sample `k` draws, from the hash of (spec seed, k) in a fixed order (every
    /// value is drawn whether used or not, so one entry's choice never shifts
    /// another's): source, seed, x, y, the layer and its age, then one value per
    /// defect entry.
    pub fn draw(&self, k: u64) -> Draw {
        let d = &self.spec.dataset;
        let mut h = Draws::new(d.seed, k);
        let source = pick(&self.weights, h.unit());
        let seed = h.word();
        let e = d.extent_px;
        let coordinate = |h: &mut Draws| ((h.unit() * 2.0 * e).floor() - e) as i64;
        let x = coordinate(&mut h);
        let y = coordinate(&mut h);
        let (u, a) = (h.unit(), h.unit());
        let mut layer = None;
        let mut acc = 0.0;
        for (n, l) in self.spec.layer.iter().enumerate() {
            acc += l.probability;
            if u < acc {
                let age = match l.age {
                    Some([lo, hi]) => lo + (hi - lo) * a,
                    None => self.layers[n].config.age,
                };
                layer = Some((n, age));
                break;
            }
        }
        let defects = self
            .spec
            .defect
            .iter()
            .enumerate()
            .filter_map(|(n, e)| (h.unit() < e.probability).then_some(n))
            .collect();
        Draw {
            index: k,
            source,
            seed,
            x,
            y,
            layer,
            defects,
        }
    }
}
