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

/// A sample's members as (name, bytes), in their order in a shard.
pub type Members = Vec<(String, Vec<u8>)>;

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
        // The defects placed with their mask boxes, in a region grown by `boxed_in`.
        let mut boxed = Vec::new();
        let mut boxed_in = 0;
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
                let mut ids = vec![0u8; w * h];
                if let Some(found) = &defects {
                    boxed = found.fill_ids_boxed(&region, &mut ids)?;
                }
                if let Some(m) = &mut mask {
                    for (row, out) in m.chunks_exact_mut(w).enumerate() {
                        let from = &fill.layers[(row + pad) * grown.width + pad..][..w];
                        for (o, &id) in out.iter_mut().zip(from) {
                            *o = if id == 0 { 0 } else { id + layer.id_offset };
                        }
                    }
                    // The defects' ids over the layer's, where they are set.
                    for (o, &id) in m.iter_mut().zip(&ids) {
                        if id != 0 {
                            *o = id;
                        }
                    }
                }
            }
            None => {
                inner.fill_rows(&grown, 0..grown.height, &mut heights);
                if let Some(found) = &defects {
                    let mut ids = vec![0u8; grown.width * grown.height];
                    boxed = found.apply(&grown, &mut heights, &mut ids)?;
                    boxed_in = pad;
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
        if defects.is_some() {
            meta["defect_entries"] = serde_json::json!(draw.defects);
            // A placed defect's entry is its index among the drawn ones; those whose
            // boxes meet the region (not only its margin) are listed.
            let (xa, ya) = (draw.x as f64, draw.y as f64);
            let (xb, yb) = (xa + (w - 1) as f64, ya + (h - 1) as f64);
            let list: Vec<_> = boxed
                .iter()
                .filter(|(p, _)| {
                    let b = p.bbox;
                    b[0] <= xb && b[2] >= xa && b[1] <= yb && b[3] >= ya
                })
                .map(|(p, mask_box)| {
                    let entry = draw.defects[p.entry];
                    let kind = self.spec.defect[entry].defect.name();
                    let mut v = defect_json(p, kind, entry, spacing);
                    v["mask_box"] = match mask_box.and_then(|b| in_sample(b, boxed_in, w, h)) {
                        Some(b) => serde_json::json!(b),
                        None => serde_json::Value::Null,
                    };
                    v
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
    pub fn encode(&self, sample: &Sample) -> Result<Members> {
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
        let written = self.write_shards(&[s], out, threads, &mut |p| progress(p.samples))?;
        Ok(written[0])
    }

    /// Writes `shards` (in this order) into `out` as [`Dataset::write_shard`] does, as
    /// one stream of samples: the workers render on across shard boundaries while a
    /// completed shard is synced to disk and renamed on a thread of its own. `progress`
    /// is called as samples are written and shards complete. Returns the shards
    /// written, in order.
    pub fn write_shards(
        &self,
        shards: &[u64],
        out: &Path,
        threads: usize,
        progress: &mut dyn FnMut(RunProgress),
    ) -> Result<Vec<ShardWritten>> {
        if let Some(&s) = shards.iter().find(|&&s| s >= self.shards()) {
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
        // Position p of the stream is sample k of shard parts[i].
        let mut parts = Vec::with_capacity(shards.len());
        let mut total = 0u64;
        for &s in shards {
            let r = self.shard_samples(s);
            parts.push((s, r.clone(), total));
            total += r.end - r.start;
        }
        let locate = |p: u64| parts.partition_point(|part| part.2 <= p) - 1;
        let sample_at = |p: u64| {
            let (_, r, first) = &parts[locate(p)];
            r.start + (p - first)
        };
        let (done_tx, done_rx) = crossbeam::channel::unbounded::<Result<ShardWritten>>();
        let (finish_tx, finish_rx) = crossbeam::channel::unbounded::<Finish>();
        let mut open: Option<OpenShard> = None;
        let mut finished = Vec::with_capacity(shards.len());
        let result = std::thread::scope(|scope| {
            // Syncs and renames completed shards while the next ones render.
            scope.spawn(move || {
                for f in finish_rx {
                    let _ = done_tx.send(f.complete());
                }
            });
            let mut count = 0u64;
            let streamed = self.render_in_order(total, &sample_at, threads, &mut |p, members| {
                let i = locate(p);
                let (s, ref r, first) = parts[i];
                if p == first {
                    open = Some(OpenShard::create(out, s)?);
                }
                let shard = open.as_mut().expect("a shard is open");
                for (name, bytes) in members {
                    shard.append(&name, &bytes)?;
                }
                count += 1;
                if p + 1 == first + (r.end - r.start) {
                    let shard = open.take().expect("a shard is open");
                    let _ = finish_tx.send(shard.close(r.end - r.start)?);
                }
                while let Ok(done) = done_rx.try_recv() {
                    finished.push(done?);
                }
                progress(RunProgress {
                    samples: count,
                    shards: finished.len() as u64,
                });
                Ok(())
            });
            drop(finish_tx);
            streamed
        });
        // An error leaves the open shard's temporary file: remove it.
        drop(open);
        for done in done_rx {
            finished.push(done?);
        }
        result?;
        progress(RunProgress {
            samples: total,
            shards: finished.len() as u64,
        });
        // The finisher completes shards in the order they were handed to it: `shards`'.
        Ok(finished)
    }

    /// Renders and encodes the samples `sample_at(0..count)` on `threads` threads and
    /// hands each to `write(position, members)` in order, on the calling thread, while
    /// the next ones render. Workers run at most a window of 2 × threads samples ahead
    /// of the writer, which bounds the samples held. The first error stops the work and
    /// is returned.
    fn render_in_order(
        &self,
        count: u64,
        sample_at: &(dyn Fn(u64) -> u64 + Sync),
        threads: usize,
        write: &mut dyn FnMut(u64, Members) -> Result<()>,
    ) -> Result<()> {
        use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
        let make = |p: u64| {
            let sample = self.sample(sample_at(p))?;
            self.encode(&sample)
        };
        if threads == 1 {
            for p in 0..count {
                write(p, make(p)?)?;
            }
            return Ok(());
        }
        let window = 2 * threads as u64;
        let next = AtomicU64::new(0);
        let written = AtomicU64::new(0);
        let stop = AtomicBool::new(false);
        let (tx, rx) = crossbeam::channel::unbounded();
        std::thread::scope(|scope| {
            for _ in 0..threads {
                let tx = tx.clone();
                let (next, written, stop, make) = (&next, &written, &stop, &make);
                scope.spawn(move || {
                    loop {
                        let p = next.fetch_add(1, Ordering::Relaxed);
                        if p >= count {
                            return;
                        }
                        while p >= written.load(Ordering::Acquire) + window {
                            if stop.load(Ordering::Relaxed) {
                                return;
                            }
                            std::thread::sleep(std::time::Duration::from_micros(200));
                        }
                        if stop.load(Ordering::Relaxed) || tx.send((p, make(p))).is_err() {
                            return;
                        }
                    }
                });
            }
            drop(tx);
            let mut pending = std::collections::BTreeMap::new();
            let mut want = 0;
            let result = (|| {
                for (p, members) in &rx {
                    pending.insert(p, members);
                    while let Some(members) = pending.remove(&want) {
                        write(want, members?)?;
                        want += 1;
                        written.store(want, Ordering::Release);
                    }
                }
                Ok(())
            })();
            if result.is_err() {
                stop.store(true, Ordering::Relaxed);
            }
            drop(rx);
            result
        })
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
        let written = self.write_shards(&prepared.todo, out, threads, progress)?;
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

/// A shard being written: its tar stream into a temporary file beside its final name,
/// removed if dropped before [`OpenShard::close`].
struct OpenShard {
    shard: u64,
    tmp: PathBuf,
    path: PathBuf,
    tar: Option<tar::Builder<std::io::BufWriter<std::fs::File>>>,
}

impl OpenShard {
    fn create(out: &Path, shard: u64) -> Result<OpenShard> {
        let path = shard_path(out, shard);
        let tmp = crate::io::temp_sibling(&path, &format!(".part-{}", std::process::id()));
        let file = std::fs::File::create(&tmp).map_err(|e| Error::io(&tmp, e))?;
        Ok(OpenShard {
            shard,
            tmp,
            path,
            tar: Some(tar::Builder::new(std::io::BufWriter::with_capacity(
                1 << 20,
                file,
            ))),
        })
    }

    fn append(&mut self, name: &str, bytes: &[u8]) -> Result<()> {
        let tar = self.tar.as_mut().expect("an open shard");
        append(tar, name, bytes).map_err(|e| Error::io(&self.tmp, e))
    }

    /// Ends the archive and flushes it; the file still has to be synced and renamed.
    fn close(mut self, samples: u64) -> Result<Finish> {
        let tar = self.tar.take().expect("an open shard");
        let file = tar
            .into_inner()
            .and_then(|w| w.into_inner().map_err(|e| e.into_error()))
            .map_err(|e| Error::io(&self.tmp, e))?;
        Ok(Finish {
            file,
            written: ShardWritten {
                shard: self.shard,
                samples,
                bytes: 0,
            },
            tmp: std::mem::take(&mut self.tmp),
            path: std::mem::take(&mut self.path),
        })
    }
}

impl Drop for OpenShard {
    fn drop(&mut self) {
        if !self.tmp.as_os_str().is_empty() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// A complete shard in its temporary file: synced, then renamed into place.
struct Finish {
    file: std::fs::File,
    written: ShardWritten,
    tmp: PathBuf,
    path: PathBuf,
}

impl Finish {
    fn complete(self) -> Result<ShardWritten> {
        let result = (|| {
            self.file.sync_all().map_err(|e| Error::io(&self.tmp, e))?;
            let bytes = self
                .file
                .metadata()
                .map_err(|e| Error::io(&self.tmp, e))?
                .len();
            std::fs::rename(&self.tmp, &self.path).map_err(|e| Error::io(&self.path, e))?;
            Ok(ShardWritten {
                bytes,
                ..self.written
            })
        })();
        if result.is_err() {
            let _ = std::fs::remove_file(&self.tmp);
        }
        result
    }
}

/// A mask box of a region grown by `pad` samples on every side, in the samples of the
/// `w × h` region itself (clipped); `None` where it lies in the margin only.
fn in_sample(b: [usize; 4], pad: usize, w: usize, h: usize) -> Option<[usize; 4]> {
    let inside = b[2] >= pad && b[3] >= pad && b[0] < pad + w && b[1] < pad + h;
    inside.then(|| {
        [
            b[0].saturating_sub(pad),
            b[1].saturating_sub(pad),
            (b[2] - pad).min(w - 1),
            (b[3] - pad).min(h - 1),
        ]
    })
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
