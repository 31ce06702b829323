//! Samples, shards and the output folder of a [`Dataset`]: rendering sample k,
//! writing a shard atomically (a temporary name, then a rename), and preparing a folder
//! for a run (its `dataset.json`, resuming from complete shards).

use std::io::Write;
use std::path::{Path, PathBuf};

use super::{Dataset, Draw, INDEX_FILE, Output};
use crate::defects::{DefectConfig, Defected, Defects};
use crate::error::{Error, Result};
use crate::imperfect::Imperfect;
use crate::raster::Raster;
use crate::stream::{Region, Surface};

/// One sample, in memory.
#[derive(Clone, Debug)]
pub struct Sample {
    /// What it drew.
    pub draw: Draw,
    /// Its key in the shard.
    pub key: String,
    /// Its heights (in the source's unit), W × H × channels.
    pub heights: Raster,
    /// Mask ids per pixel (0 clean), where the spec has layers or defects.
    pub mask: Option<Vec<u8>>,
    /// The heights shaded, when the spec asks for it.
    pub shaded: Option<Vec<u8>>,
    /// `{key}.json`.
    pub meta: serde_json::Value,
}

/// A shard written by [`Dataset::write_shard`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShardWritten {
    /// Its index.
    pub shard: u64,
    /// Samples in it.
    pub samples: u64,
    /// Its size in bytes.
    pub bytes: u64,
}

/// What [`Dataset::prepare`] found in the output folder.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Prepared {
    /// Shards of the range still to write, in order.
    pub todo: Vec<u64>,
    /// Shards of the range already complete (skipped).
    pub complete: Vec<u64>,
    /// Shards found but not matching the index (rewritten).
    pub broken: Vec<u64>,
}

/// A placed defect as `{key}.json` records it: kind, mask id, box (pixels) and its
/// drawn parameters in µm (angles in radians).
fn defect_json(
    p: &crate::defects::Placed,
    kind: &str,
    entry: usize,
    spacing: f64,
) -> serde_json::Value {
    use crate::defects::Shape;
    let um = |v: f64| v * spacing;
    let mut v = serde_json::json!({
        "entry": entry,
        "kind": kind,
        "mask_id": p.id,
        "bbox": p.bbox,
    });
    let params = match &p.shape {
        Shape::Scratch {
            c,
            theta,
            kappa,
            length,
            half_width,
            depth,
            pile_up,
            profile,
        } => serde_json::json!({
            "centre": c,
            "angle": theta,
            "turn": kappa * length,
            "length_um": um(*length),
            "width_um": um(2.0 * half_width),
            "depth_um": um(*depth),
            "pile_up_um": um(*pile_up),
            "profile": profile,
        }),
        Shape::Dent {
            c, r0, depth, rim, ..
        } => serde_json::json!({
            "centre": c,
            "diameter_um": um(2.0 * r0),
            "depth_um": um(*depth),
            "rim_um": um(*rim),
        }),
        Shape::Pits { pits } => serde_json::json!({
            "pits": pits.iter().map(|(c, r0, depth, _)| serde_json::json!({
                "centre": c,
                "diameter_um": um(2.0 * r0),
                "depth_um": um(*depth),
            })).collect::<Vec<_>>(),
        }),
    };
    if let (Some(v), Some(p)) = (v.as_object_mut(), params.as_object()) {
        v.extend(p.clone());
    }
    v
}

impl Dataset {
    /// Renders sample `k` (< [`Dataset::samples`]) on the calling thread (an
    /// imperfection layer uses every core).
    pub fn sample(&self, k: u64) -> Result<Sample> {
        if k >= self.samples() {
            return Err(Error::param(
                "sample",
                k,
                format!("an index below {} (the dataset's samples)", self.samples()),
            ));
        }
        let draw = self.draw(k);
        let d = &self.spec.dataset;
        let (w, h) = (d.size[0] as usize, d.size[1] as usize);
        let open = &self.sources[draw.source];
        let source = &open.source;
        let spacing = source.spacing_um().unwrap_or(d.spacing_um);
        let unit = source.height_unit();
        let inner = source.loaded().surface(draw.seed)?;
        let defects = if draw.defects.is_empty() {
            None
        } else {
            let config = DefectConfig {
                defect: draw
                    .defects
                    .iter()
                    .map(|&e| self.spec.defect[e].defect.clone())
                    .collect(),
            };
            Some(Defects::new(&config, spacing, &unit, draw.seed)?)
        };
        let region = Region::new(draw.x as f64, draw.y as f64, w, h);
        // One sample of margin for the shading's central differences.
        let shaded = self.outputs.contains(&Output::Shaded);
        let pad = shaded as usize;
        let grown = Region {
            col0: -(pad as i64),
            row0: -(pad as i64),
            width: w + 2 * pad,
            height: h + 2 * pad,
            ..region
        };
        let c = open.channels;
        let mut heights = vec![0.0f32; grown.width * grown.height * c];
        let masked = self.outputs.contains(&Output::Mask);
        let mut mask = masked.then(|| vec![0u8; w * h]);
        match draw.layer {
            Some((e, age)) => {
                let layer = &self.layers[e];
                let mut config = layer.config.clone();
                config.age = age;
                let surface: Box<dyn Surface> = match &defects {
                    Some(found) => Box::new(Defected::new(inner, found.clone())?),
                    None => inner,
                };
                let imperfect = Imperfect::new(surface, &config, layer.base.as_deref(), draw.seed)?;
                let fill = imperfect.fill_layers(&grown)?;
                heights = fill.heights;
                if let Some(m) = &mut mask {
                    for (row, out) in m.chunks_exact_mut(w).enumerate() {
                        let from = &fill.layers[(row + pad) * grown.width + pad..][..w];
                        for (o, &id) in out.iter_mut().zip(from) {
                            *o = if id == 0 { 0 } else { id + layer.id_offset };
                        }
                    }
                    if let Some(found) = &defects {
                        let mut ids = vec![0u8; w * h];
                        found.fill_ids(&region, &mut ids)?;
                        for (o, &id) in m.iter_mut().zip(&ids) {
                            if id != 0 {
                                *o = id;
                            }
                        }
                    }
                }
            }
            None => {
                inner.fill_rows(&grown, 0..grown.height, &mut heights);
                if let Some(found) = &defects {
                    let mut ids = vec![0u8; grown.width * grown.height];
                    found.apply(&grown, &mut heights, &mut ids)?;
                    if let Some(m) = &mut mask {
                        for (row, out) in m.chunks_exact_mut(w).enumerate() {
                            out.copy_from_slice(&ids[(row + pad) * grown.width + pad..][..w]);
                        }
                    }
                }
            }
        }
        let grown_raster = Raster::from_vec(grown.width, grown.height, c, heights)?;
        let shaded = shaded.then(|| crate::shade::shade(&grown_raster, &source.material()));
        let heights = if pad == 0 {
            grown_raster
        } else {
            grown_raster.crop(pad, pad, w, h)?
        };
        if heights.data.iter().any(|v| !v.is_finite()) {
            return Err(Error::param(
                "sample heights",
                format!("non-finite in sample {k}"),
                "finite heights from every source (this is a bug of the source; please report it)",
            ));
        }
        let mut meta = serde_json::json!({
            "key": Dataset::key(k),
            "index": k,
            "source": {
                "entry": draw.source,
                "path": self.spec.source[draw.source].path,
                "kind": source.kind().name(),
            },
            "seed": draw.seed,
            "region": {"x": draw.x, "y": draw.y, "width": w, "height": h, "step": 1.0},
            "spacing_um": spacing,
            "height_unit": unit,
            "layer": serde_json::Value::Null,
            "defects": [],
        });
        if let Some((e, age)) = draw.layer {
            meta["layer"] = serde_json::json!({
                "entry": e,
                "config": self.spec.layer[e].config,
                "pattern": self.layers[e].config.pattern,
                "age": age,
                "mask_id_offset": self.layers[e].id_offset,
            });
        }
        if let Some(found) = &defects {
            meta["defect_entries"] = serde_json::json!(draw.defects);
            // A placed defect's entry is its index among the drawn ones.
            let list: Vec<_> = found
                .placed_over(&region)
                .iter()
                .map(|p| {
                    let entry = draw.defects[p.entry];
                    let kind = self.spec.defect[entry].defect.name();
                    defect_json(p, kind, entry, spacing)
                })
                .collect();
            meta["defects"] = list.into();
        }
        Ok(Sample {
            key: Dataset::key(k),
            draw,
            heights,
            mask,
            shaded,
            meta,
        })
    }

    /// The members of a sample as (name, bytes), in their order in a shard.
    pub fn encode(&self, sample: &Sample) -> Result<Vec<(String, Vec<u8>)>> {
        let (w, h) = (sample.heights.width, sample.heights.height);
        let mut out = Vec::with_capacity(self.outputs.len());
        for &o in &self.outputs {
            let bytes = match o {
                Output::Height => crate::io::npy_bytes(&sample.heights)?,
                Output::Mask => {
                    let m = sample.mask.as_deref().unwrap_or(&[]);
                    crate::io::png8_bytes(w, h, 1, m)?
                }
                Output::Json => {
                    let mut v = serde_json::to_vec(&sample.meta)
                        .map_err(|e| Error::decode("sample JSON", e.to_string()))?;
                    v.push(b'\n');
                    v
                }
                Output::Shaded => {
                    let s = sample.shaded.as_deref().unwrap_or(&[]);
                    crate::io::png8_bytes(w, h, 1, s)?
                }
            };
            out.push((format!("{}.{}", sample.key, o.extension()), bytes));
        }
        Ok(out)
    }

    /// The member names shard `s` holds, in order.
    pub fn shard_members(&self, s: u64) -> Vec<String> {
        self.shard_samples(s)
            .flat_map(|k| {
                self.outputs
                    .iter()
                    .map(move |o| format!("{}.{}", Dataset::key(k), o.extension()))
            })
            .collect()
    }

    /// Writes shard `s` to `out/shard-{s:06}.tar` through a temporary name, rendering
    /// its samples on `threads` threads (the bytes do not depend on it); `progress` is
    /// called with the number of samples written so far. Checks `out/dataset.json`
    /// against this spec where it exists (it does not write it: see
    /// [`Dataset::prepare`]).
    pub fn write_shard(
        &self,
        s: u64,
        out: &Path,
        threads: usize,
        progress: &mut dyn FnMut(u64),
    ) -> Result<ShardWritten> {
        if s >= self.shards() {
            return Err(Error::param(
                "shard",
                s,
                format!("an index below {} (the dataset's shards)", self.shards()),
            ));
        }
        if !out.is_dir() {
            return Err(Error::param(
                "out",
                out.display(),
                "an existing folder (prepare it with `surftile dataset` or generate())",
            ));
        }
        self.check_index(out, false)?;
        let threads = threads.max(1);
        let path = out.join(Dataset::shard_name(s));
        let samples = self.shard_samples(s);
        let count = samples.end - samples.start;
        crate::io::write_atomically(&path, |file| {
            let mut tar = tar::Builder::new(file);
            let batch = (4 * threads) as u64;
            let mut k = samples.start;
            while k < samples.end {
                let end = (k + batch).min(samples.end);
                for members in self.render_batch(k..end, threads)? {
                    for (name, bytes) in members {
                        append(&mut tar, &name, &bytes).map_err(|e| Error::io(&path, e))?;
                    }
                }
                progress(end - samples.start);
                k = end;
            }
            let file = tar.into_inner().map_err(|e| Error::io(&path, e))?;
            file.flush().map_err(|e| Error::io(&path, e))
        })?;
        let bytes = std::fs::metadata(&path)
            .map_err(|e| Error::io(&path, e))?
            .len();
        Ok(ShardWritten {
            shard: s,
            samples: count,
            bytes,
        })
    }

    /// Renders and encodes samples `range` on `threads` threads, in order.
    fn render_batch(
        &self,
        range: std::ops::Range<u64>,
        threads: usize,
    ) -> Result<Vec<Vec<(String, Vec<u8>)>>> {
        let make = |k: u64| self.sample(k).and_then(|s| self.encode(&s));
        if threads == 1 || range.end - range.start == 1 {
            return range.map(make).collect();
        }
        let next = std::sync::atomic::AtomicU64::new(range.start);
        let mut done: Vec<(u64, Result<Vec<(String, Vec<u8>)>>)> = std::thread::scope(|scope| {
            let workers: Vec<_> = (0..threads)
                .map(|_| {
                    scope.spawn(|| {
                        let mut mine = Vec::new();
                        loop {
                            let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            if k >= range.end {
                                return mine;
                            }
                            mine.push((k, make(k)));
                        }
                    })
                })
                .collect();
            workers
                .into_iter()
                .flat_map(|w| w.join().expect("a sample worker panicked"))
                .collect()
        });
        done.sort_by_key(|(k, _)| *k);
        done.into_iter().map(|(_, r)| r).collect()
    }

    /// Refuses an output folder whose `dataset.json` was written for another spec
    /// (unless `force`) or cannot be read. Returns whether it exists and matches.
    fn check_index(&self, out: &Path, force: bool) -> Result<bool> {
        let path = out.join(INDEX_FILE);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
            Err(e) => return Err(Error::io(&path, e)),
        };
        let found = serde_json::from_str::<serde_json::Value>(&text)
            .ok()
            .and_then(|v| {
                v.get("spec_hash")
                    .and_then(|h| h.as_str())
                    .map(String::from)
            });
        match found {
            Some(h) if h == self.hash => Ok(true),
            _ if force => Ok(false),
            Some(h) => Err(Error::param(
                "out",
                out.display(),
                format!(
                    "a folder of this spec's dataset: its {INDEX_FILE} is of another spec or surftile version ({h}, this one is {}); pass --force (force=True) to replace that dataset, or choose another folder",
                    self.hash
                ),
            )),
            None => Err(Error::param(
                "out",
                out.display(),
                format!(
                    "a folder whose {INDEX_FILE} is a surftile dataset index (it cannot be read as one); pass --force (force=True) to replace it"
                ),
            )),
        }
    }

    /// Readies `out` for writing shards `range`: refuses a path that is a file, or a
    /// dataset of another spec unless `force` (which removes its shards); creates the
    /// folder and writes `dataset.json` (atomically; its bytes depend on the spec only,
    /// so runs on several machines write the same); removes the temporary files of
    /// interrupted runs for the shards of `range`; and sorts the shards of `range` into
    /// complete ones (every member present, in order, readable) and ones to write.
    pub fn prepare(
        &self,
        out: &Path,
        range: std::ops::Range<u64>,
        force: bool,
    ) -> Result<Prepared> {
        if range.start >= range.end || range.end > self.shards() {
            return Err(Error::param(
                "shards",
                format!("{}..{}", range.start, range.end),
                format!(
                    "a non-empty range A..B within 0..{} (the dataset's shards)",
                    self.shards()
                ),
            ));
        }
        if out.exists() && !out.is_dir() {
            return Err(Error::param(
                "out",
                out.display(),
                "a folder (or a path where one can be made); this is a file",
            ));
        }
        let matches = out.is_dir() && self.check_index(out, force)?;
        if force && out.is_dir() && !matches {
            for entry in std::fs::read_dir(out).map_err(|e| Error::io(out, e))? {
                let entry = entry.map_err(|e| Error::io(out, e))?;
                let name = entry.file_name().to_string_lossy().into_owned();
                let shard_file = name.starts_with("shard-") && name.ends_with(".tar");
                let temp = name.starts_with(".shard-") && name.contains(".tar.part-");
                if shard_file || temp {
                    std::fs::remove_file(entry.path()).map_err(|e| Error::io(&entry.path(), e))?;
                }
            }
        }
        std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
        let index = out.join(INDEX_FILE);
        if !matches {
            let mut text = serde_json::to_vec_pretty(&self.index)
                .map_err(|e| Error::decode(INDEX_FILE, e.to_string()))?;
            text.push(b'\n');
            crate::io::write_atomically(&index, |w| {
                w.write_all(&text).map_err(|e| Error::io(&index, e))
            })?;
        }
        self.remove_temporaries(out, range.clone())?;
        let mut p = Prepared::default();
        for s in range {
            let path = out.join(Dataset::shard_name(s));
            if !path.exists() {
                p.todo.push(s);
            } else if self.shard_is_complete(&path, s) {
                p.complete.push(s);
            } else {
                p.broken.push(s);
                p.todo.push(s);
            }
        }
        Ok(p)
    }

    /// Removes the temporary files that interrupted writes of shards `range` left in
    /// `out` (`.shard-NNNNNN.tar.part-PID`).
    pub fn remove_temporaries(&self, out: &Path, range: std::ops::Range<u64>) -> Result<()> {
        let Ok(entries) = std::fs::read_dir(out) else {
            return Ok(());
        };
        for entry in entries.flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            let Some(rest) = name.strip_prefix(".shard-") else {
                continue;
            };
            let Some((number, _)) = rest.split_once(".tar.part-") else {
                continue;
            };
            if let Ok(s) = number.parse::<u64>()
                && range.contains(&s)
            {
                std::fs::remove_file(entry.path()).map_err(|e| Error::io(&entry.path(), e))?;
            }
        }
        Ok(())
    }

    /// Whether the file at `path` is shard `s` complete: a tar archive with exactly
    /// the members the index expects, in order, each readable to its end.
    pub fn shard_is_complete(&self, path: &Path, s: u64) -> bool {
        let Ok(file) = std::fs::File::open(path) else {
            return false;
        };
        let expected = self.shard_members(s);
        let mut archive = tar::Archive::new(std::io::BufReader::new(file));
        let Ok(entries) = archive.entries() else {
            return false;
        };
        let mut n = 0;
        for entry in entries {
            let Ok(mut entry) = entry else {
                return false;
            };
            let name = entry.path().ok().map(|p| p.to_string_lossy().into_owned());
            if n >= expected.len() || name.as_deref() != Some(expected[n].as_str()) {
                return false;
            }
            let size = entry.header().size().unwrap_or(u64::MAX);
            match std::io::copy(&mut entry, &mut std::io::sink()) {
                Ok(read) if read == size => {}
                _ => return false,
            }
            n += 1;
        }
        n == expected.len()
    }

    /// Writes shards `range` of this dataset into `out` after [`Dataset::prepare`],
    /// skipping complete ones, on `threads` threads; `progress(samples, shards)` is
    /// called as samples and shards complete. Returns what was prepared and written.
    pub fn run(
        &self,
        out: &Path,
        range: std::ops::Range<u64>,
        threads: usize,
        force: bool,
        progress: &mut dyn FnMut(RunProgress),
    ) -> Result<(Prepared, Vec<ShardWritten>)> {
        let prepared = self.prepare(out, range, force)?;
        let mut written = Vec::with_capacity(prepared.todo.len());
        let mut samples_before = 0;
        for &s in &prepared.todo {
            let done = self.write_shard(s, out, threads, &mut |n| {
                progress(RunProgress {
                    samples: samples_before + n,
                    shards: written.len() as u64,
                })
            })?;
            samples_before += done.samples;
            written.push(done);
            progress(RunProgress {
                samples: samples_before,
                shards: written.len() as u64,
            });
        }
        Ok((prepared, written))
    }

    /// The samples of `shards`.
    pub fn samples_in(&self, shards: &[u64]) -> u64 {
        shards
            .iter()
            .map(|&s| {
                let r = self.shard_samples(s);
                r.end - r.start
            })
            .sum()
    }

    /// The spec's name in messages.
    pub fn name(&self) -> &str {
        &self.what
    }
}

/// Progress of [`Dataset::run`]: samples and shards written in this run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RunProgress {
    /// Samples written.
    pub samples: u64,
    /// Shards complete.
    pub shards: u64,
}

/// Appends one member with fixed metadata (mode 644, owner 0, time 0), so that a
/// shard's bytes depend on its samples only.
fn append<W: Write>(tar: &mut tar::Builder<W>, name: &str, bytes: &[u8]) -> std::io::Result<()> {
    let mut header = tar::Header::new_ustar();
    header.set_entry_type(tar::EntryType::Regular);
    header.set_size(bytes.len() as u64);
    header.set_mode(0o644);
    header.set_uid(0);
    header.set_gid(0);
    header.set_mtime(0);
    tar.append_data(&mut header, name, bytes)
}

/// Where a shard of `out` lives.
pub fn shard_path(out: &Path, s: u64) -> PathBuf {
    out.join(Dataset::shard_name(s))
}
