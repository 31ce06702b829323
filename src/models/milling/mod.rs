//! Face-milled surfaces (seed 000 §4) as an infinite [`Surface`] with O(1) lookup.
//!
//! The model: rings R_k = S_k·T_k + N_k (shape, tilting plane, angular noise; §4.1)
//! combined by an interaction f_k (minimum, latest or convex combination; §4.2) in the
//! order a tool path (parallel lines or an Archimedean spiral; §4.3) mills them. The
//! paper evaluates every ring of the image for every pixel and names the open problem:
//! "a fast searching algorithm to find all rings affecting one surface point". Here:
//!
//! - every ring's random parameters come from the hash of its index, so nothing is
//!   stored per ring and the path is endless;
//! - the rings that can reach a point are found from the path geometry
//!   ([`ToolPath::candidates`]): on parallel paths, the lines within reach and on each
//!   the two short runs of centres whose annulus can contain the point; on spirals, the
//!   turns within reach and on each the arc-length window, converted to ring indices;
//! - the few rings found are folded in their milling order (a sort of about five keys);
//! - `height()` keeps each thread's last-drawn rings in a small direct-mapped cache
//!   ([`MillingSurface::eval_mm_cached`]), so scattered queries over one field draw a
//!   ring's parameters once, not once per point.
//!
//! [`BruteForce`] is the slow twin: every ring of a finite path, the paper's way.
//!
//! **ε, the ring-order changes.** The paper permutes a random ⌈εn⌉ of the n rings of
//! the image globally. A global permutation needs the whole image's ring list, so here
//! each ring is reordered with probability ε (its own hash) and moves by a hashed 1 to
//! m rings forwards or backwards along its line (parallel) or spiral, m =
//! `path.reorder_reach_rings` (default ⌈2R/δ⌉, enough to pass every ring of the same
//! line that overlaps it). As in the paper, an ε share of the rings appears out of
//! order with its overlapping neighbours, above or below them with equal chance; unlike
//! it, a reordered ring never jumps ahead of or behind rings of another line (which
//! overlap it only at its sides), and the result does not depend on the image's extent.
//!
//! **Interactions outside a ring.** Latest and convex change f only on the ring's
//! support P_k (latest as the paper states; for convex, applying (1 − A_k) to the
//! whole plane would shrink every earlier ring's mark at each new ring anywhere, which
//! on an endless path leaves nothing). Minimum follows the paper: R_k = 0 off P_k, so
//! f = min(0, rings covering the point).
//!
//! Units: surface coordinates are pixels of `spacing_um`; the model works in mm and
//! gives heights in µm.

pub mod config;
pub mod path;
pub mod ring;
mod simd;

use std::ops::Range;

use smallvec::SmallVec;

use crate::bank::{Bank, BankHeader, ExemplarInfo, LevelInfo, Method, Record};
use crate::error::{Error, Result};
use crate::stream::{Region, Surface, fill_rows_by_sample, in_range};
use config::InteractionKind;
pub use config::MillingConfig;
use path::Nominal;
pub use path::ToolPath;
use ring::{Key, NOISE_PROFILES, NOISE_SAMPLES, RingModel, SHAPE_LUT};

/// The height adaptation of seed 000 §4.4: heights are mapped by
/// h′ = (h − model_mean)·target_std/model_std + target_mean.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Adaptation {
    /// Mean of the model's heights (µm), estimated once from a large sample.
    pub model_mean_um: f64,
    /// Standard deviation of the model's heights (µm).
    pub model_std_um: f64,
    /// Target mean (µm).
    pub target_mean_um: f64,
    /// Target standard deviation (µm).
    pub target_std_um: f64,
}

/// What a milling bank stores beside its tables (`BankHeader::milling`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MillingBankInfo {
    /// The configuration, every key included.
    pub config: MillingConfig,
    /// The height adaptation, when the configuration asks for one.
    pub adaptation: Option<Adaptation>,
}

/// An endless face-milled surface (seed 000 §4), sampled in O(1).
#[derive(Clone, Debug)]
pub struct MillingSurface {
    config: MillingConfig,
    rings: RingModel,
    path: ToolPath,
    lut: Vec<f32>,
    /// The noise profiles as stored in a bank (f32).
    noise: Vec<f32>,
    /// The same, quantised for the sampler ([`ring::quantise_noise`]).
    noise_q: Vec<i16>,
    /// `noise_q` padded for the row fills ([`ring::pad_noise`]).
    noise_pad: ring::Padded,
    mm_per_px: f64,
    adaptation: Option<Adaptation>,
    /// The side of the point cache's cells (mm; `cell_mm`).
    cell_side: f64,
    /// Identity of this surface's rings in the per-thread ring cache (clones share it:
    /// their rings are the same).
    uid: u64,
}

/// Slots of the per-thread cache of drawn rings (direct-mapped; a power of two). A
/// slot holds one ring's constants ([`ring::SpanRing`]) and key, about 300 bytes:
/// 300 KiB per thread, of which a field of points touches only its own rings.
const RING_CACHE_SLOTS: usize = 1024;

/// Cells of the per-thread cell cache along each axis (a power of two): cell (i, j)
/// goes to slot (i mod 64, j mod 64), so the cells of any field up to 64 cells wide
/// (13 mm at d = 4 mm) have slots of their own. A cell holds its rings' constants
/// ([`ring::Group`], 0.9 KiB per four rings; about 8 rings at d = 4 mm), so a thread
/// that fills every slot keeps about 10 MiB (at most 30 MiB, [`MAX_CELL_RINGS`]); one
/// that queries a smaller field, only that field's cells.
const CELL_CACHE_SIDE: usize = 64;

/// One cached ring: the surface it belongs to (uid 0: an empty slot), its id, its
/// constants and its milling-order key.
#[derive(Clone, Copy)]
struct CachedRing {
    uid: u64,
    id: (i64, i64),
    ring: ring::SpanRing,
    key: Key,
}

/// Most rings a cell keeps ([`MAX_CELL_RINGS`] / 4 groups of 0.9 KiB): a model whose
/// cells meet more (a step δ far below the ring width) answers through the ring cache
/// alone, so a thread's cells never hold more than 4096 × 7.3 KiB ≈ 30 MiB.
const MAX_CELL_RINGS: usize = 32;

/// One cached cell: the surface (uid 0: an empty slot) and the cell it is about, and
/// the rings that can cover a point of the cell, in milling order, four to a
/// [`ring::Group`] (empty until the cell is asked for a second time, and for good if
/// the cell meets more than [`MAX_CELL_RINGS`], which `too_many` then says).
struct CachedCell {
    uid: u64,
    cell: (i64, i64),
    groups: Vec<ring::Group>,
    too_many: bool,
}

/// A thread's caches for [`MillingSurface::eval_mm_cached`].
#[derive(Default)]
struct PointCache {
    rings: Vec<CachedRing>,
    cells: Vec<CachedCell>,
    /// Scratch for building a cell.
    scratch: Vec<(Key, ring::SpanRing)>,
}

thread_local! {
    /// The rings and cells `height()` used last on this thread, by slot.
    static POINT_CACHE: std::cell::RefCell<PointCache> =
        std::cell::RefCell::new(PointCache::default());
}

/// Next surface uid (0 is never handed out).
static NEXT_UID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

/// Fewest pixels across a block of [`MillingSurface::fill_rows`] worth drawing its rings
/// once for.
const MIN_BLOCK: usize = 4;
/// Most pixels across a block.
const MAX_BLOCK: usize = ring::SPAN;
/// Pixel coordinates beyond which a block is folded point by point instead of ring by
/// ring: up to here, a column's coordinate is exact to far better than the spans'
/// one-column margin.
const SPAN_LIMIT: f64 = (1u64 << 40) as f64;

/// Samples of the statistics estimate: 2¹⁸ points.
const STAT_SAMPLES: usize = 1 << 18;

impl MillingSurface {
    /// The surface of `config` (validated here) sampled at `spacing_um` µm per pixel,
    /// with placement seed `seed` (ring parameters and noise profiles).
    pub fn new(config: &MillingConfig, spacing_um: f64, seed: u32) -> Result<MillingSurface> {
        config.validate()?;
        let noise = ring::noise_profiles(
            config.noise.count_mean,
            config.noise.frequency_mean,
            seed as u64,
        );
        Self::from_parts(config, spacing_um, seed, ring::shape_table(), noise, None)
    }

    fn from_parts(
        config: &MillingConfig,
        spacing_um: f64,
        seed: u32,
        lut: Vec<f32>,
        noise: Vec<f32>,
        adaptation: Option<Adaptation>,
    ) -> Result<MillingSurface> {
        if !(spacing_um.is_finite() && spacing_um > 0.0 && spacing_um < 1e9) {
            return Err(Error::param(
                "spacing",
                spacing_um,
                "a positive pixel spacing in µm",
            ));
        }
        let noise_q = ring::quantise_noise(&noise);
        let rings = RingModel::new(config, seed);
        Ok(MillingSurface {
            config: config.clone(),
            cell_side: Self::cell_mm(&rings),
            rings,
            path: ToolPath::new(config),
            lut,
            noise_pad: ring::pad_noise(&noise_q),
            noise_q,
            noise,
            mm_per_px: spacing_um / 1000.0,
            adaptation,
            uid: NEXT_UID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &MillingConfig {
        &self.config
    }

    /// Pixel spacing in µm.
    pub fn spacing_um(&self) -> f64 {
        self.mm_per_px * 1000.0
    }

    /// The height adaptation in use.
    pub fn adaptation(&self) -> Option<Adaptation> {
        self.adaptation
    }

    /// Mean and standard deviation (µm) of the unadapted model, from 2¹⁸ points spread
    /// by the R2 low-discrepancy sequence over a square of 40 ring diameters around the
    /// origin (around the spiral's origin for spirals).
    pub fn model_stats(&self) -> (f64, f64) {
        let side = 20.0 * self.config.tool.diameter_mm;
        let centre = match &self.path {
            ToolPath::Spiral { origin, .. } => *origin,
            _ => (0.0, 0.0),
        };
        // R2 sequence (Roberts 2018): fractional parts of n·(1/g, 1/g²), g the plastic number.
        let g = 1.324_717_957_244_746f64;
        let (a1, a2) = (1.0 / g, 1.0 / (g * g));
        let mut sum = 0.0;
        let mut sum2 = 0.0;
        for n in 0..STAT_SAMPLES {
            let (u, v) = ((0.5 + a1 * n as f64).fract(), (0.5 + a2 * n as f64).fract());
            let h = self.eval_mm(centre.0 + (u - 0.5) * side, centre.1 + (v - 0.5) * side);
            sum += h;
            sum2 += h * h;
        }
        let mean = sum / STAT_SAMPLES as f64;
        (
            mean,
            (sum2 / STAT_SAMPLES as f64 - mean * mean).max(0.0).sqrt(),
        )
    }

    /// The same surface with heights matched to `target` (mean, std) in µm (§4.4),
    /// the model's own statistics estimated once by [`Self::model_stats`].
    pub fn adapted_to(mut self, target_mean_um: f64, target_std_um: f64) -> Result<Self> {
        if !target_mean_um.is_finite() {
            return Err(Error::param(
                "adapt.mean_um",
                target_mean_um,
                "a finite mean height in µm",
            ));
        }
        if !(target_std_um.is_finite() && target_std_um > 0.0) {
            return Err(Error::param(
                "adapt.std_um",
                target_std_um,
                "a positive standard deviation in µm",
            ));
        }
        let (mean, std) = self.model_stats();
        if std <= 0.0 {
            return Err(Error::param(
                "adapt",
                "(flat model)",
                "a configuration whose heights vary, to scale them to a standard deviation",
            ));
        }
        self.adaptation = Some(Adaptation {
            model_mean_um: mean,
            model_std_um: std,
            target_mean_um,
            target_std_um,
        });
        Ok(self)
    }

    /// Applies the configuration's `[adapt]` section, reading a measurement relative
    /// to `base` (the configuration's folder).
    pub fn adapt_from_config(self, base: Option<&std::path::Path>) -> Result<Self> {
        let Some(adapt) = self.config.adapt.clone() else {
            return Ok(self);
        };
        let (mean, std) = match &adapt.measurement {
            Some(file) => {
                let path = base.map_or_else(|| file.into(), |b| b.join(file));
                let image = crate::io::read_image(&path, &Default::default())?;
                let r = crate::prep::Prep {
                    fill_missing: true,
                    leveling: crate::prep::Leveling::Plane,
                    ..Default::default()
                }
                .apply(&image.raster.channel(0), &path.display().to_string())?;
                let s = crate::stats::height_stats(&r);
                (s.mean, s.sq)
            }
            None => {
                let (m, s) = self.model_stats();
                (adapt.mean_um.unwrap_or(m), adapt.std_um.unwrap_or(s))
            }
        };
        self.adapted_to(mean, std)
    }

    /// f(x, y) in µm at a point in mm, before adaptation: the indexed evaluation.
    #[inline]
    pub fn eval_mm(&self, x: f64, y: f64) -> f64 {
        let m = &self.rings;
        let path = &self.path;
        let spiral = path.is_spiral();
        // Stage 1 for every candidate: the hash, the jittered centre and the distance;
        // stage 2 only for the few whose support can contain the point.
        let mut near: SmallVec<[ring::Near; 16]> = SmallVec::new();
        path.candidates(x, y, m.reach_in, m.reach_out, |id| {
            let n = m.near(id, path.centre(id), x, y);
            if m.may_cover(&n) {
                near.push(n);
            }
        });
        let mut found: SmallVec<[(Key, f64, f64); 12]> = near
            .iter()
            .filter_map(|n| {
                let ring = path.nominal(n.id);
                let v = m.finish(&ring, n, &self.lut, &self.noise_q)?;
                Some((m.key_of(&ring, v.order, spiral), v.r, v.a))
            })
            .collect();
        fold_keyed(m.interaction, &mut found)
    }

    /// [`Self::eval_mm`] through this thread's caches.
    ///
    /// The plane is cut into square cells half as wide as the annulus in which a ring
    /// can have support (0.2 mm at d = 4 mm). The second time a point falls in a cell,
    /// the cell keeps the rings that can cover any of its points, in milling order, as
    /// the constants of their arithmetic, four rings to a group. From then on a point
    /// of the cell costs a slot lookup, its groups evaluated four rings per
    /// instruction with the row fills' straight-line code (AVX2 where the CPU has it;
    /// one by one otherwise), and a branch-free fold in milling order.
    ///
    /// A point in a cell seen once goes through the ring cache instead: each candidate
    /// ring's point-independent draws ([`ring::RingModel::drawn`]: two hashes, a dozen
    /// normal deviates, its milling key) are made once and kept in a direct-mapped
    /// slot (cells are built from it too), and the candidates covering the point are
    /// folded in milling order.
    ///
    /// The values, the order of the fold and so the bits are those of
    /// [`Self::eval_mm`] (`cached_heights_equal_uncached_ones`); only the time
    /// differs. Points near each other share their cells and rings, so scattered
    /// queries over a field, as a renderer or an inspection rig makes them, mostly hit;
    /// far-apart points miss and pay the draws as [`Self::eval_mm`] does, plus the
    /// slot writes.
    #[inline]
    pub fn eval_mm_cached(&self, x: f64, y: f64) -> f64 {
        POINT_CACHE.with(|cache| {
            let Ok(mut cache) = cache.try_borrow_mut() else {
                // Only if a ring's evaluation re-entered height() on this thread.
                return self.eval_mm(x, y);
            };
            self.ready(&mut cache);
            #[cfg(target_arch = "x86_64")]
            if let Some(avx2) = simd::Avx2::detect() {
                // SAFETY: the witness says the CPU has AVX2.
                return unsafe { self.cached_avx2(avx2, &mut cache, x, y) };
            }
            self.cached(simd::Scalar, &mut cache, x, y)
        })
    }

    /// Gives a thread's point cache its slots, all empty, unless it has them.
    fn ready(&self, cache: &mut PointCache) {
        if cache.rings.is_empty() {
            // Empty slots: uid 0 is never a surface's.
            let placeholder = self.cache_entry((0, 0), 0);
            cache.rings.resize(RING_CACHE_SLOTS, placeholder);
            cache.cells = (0..CELL_CACHE_SIDE * CELL_CACHE_SIDE)
                .map(|_| CachedCell {
                    uid: 0,
                    cell: (0, 0),
                    groups: Vec::new(),
                    too_many: false,
                })
                .collect();
        }
    }

    /// The side of the point cache's cells (mm): half the width of the annulus in
    /// which a ring can have support, so that a cell meets few rings' supports
    /// (smaller cells meet fewer, but more of them must be built and kept: at d = 4 mm,
    /// 0.2 mm cells and 0.1 mm ones differ by a tenth of a sample's time).
    fn cell_mm(rings: &RingModel) -> f64 {
        let (in2, out2) = rings.support2;
        ((out2.sqrt() - in2.sqrt()) * 0.5).max(1e-6)
    }

    /// Ring `id` as the ring cache keeps it, for the surface `uid`.
    fn cache_entry(&self, id: (i64, i64), uid: u64) -> CachedRing {
        let d = self
            .rings
            .drawn(&self.path.nominal(id), self.path.is_spiral());
        CachedRing {
            uid,
            id,
            ring: self.rings.span_ring(&d),
            key: d.key,
        }
    }

    /// The ring cache's slot for ring `id`.
    #[inline(always)]
    fn ring_slot(id: (i64, i64)) -> usize {
        (crate::hash::hash_tile(0, id.0, id.1) as usize) & (RING_CACHE_SLOTS - 1)
    }

    /// Ring `id` in its slot `slot` of the ring cache, drawn into it unless it is there.
    #[inline(always)]
    fn ring_in<'c>(
        &self,
        rings: &'c mut [CachedRing],
        slot: usize,
        id: (i64, i64),
    ) -> &'c CachedRing {
        let e = &mut rings[slot];
        if !(e.uid == self.uid && e.id == id) {
            *e = self.cache_entry(id, self.uid);
        }
        e
    }

    /// [`Self::cached`] compiled for AVX2, with all of it inlined (the evaluation
    /// is no closure, which would not inherit the target feature).
    ///
    /// # Safety
    /// The CPU must have AVX2 (which `avx2` witnesses).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn cached_avx2(&self, avx2: simd::Avx2, cache: &mut PointCache, x: f64, y: f64) -> f64 {
        self.cached(avx2, cache, x, y)
    }

    /// The body of [`Self::eval_mm_cached`] over this thread's `cache`, four rings at
    /// a time by `lanes`.
    #[inline(always)]
    fn cached(&self, lanes: impl simd::PointLanes, cache: &mut PointCache, x: f64, y: f64) -> f64 {
        let side = self.cell_side;
        let cell = ((x / side).floor() as i64, (y / side).floor() as i64);
        let mask = CELL_CACHE_SIDE as i64 - 1;
        let slot = ((cell.0 & mask) + (cell.1 & mask) * CELL_CACHE_SIDE as i64) as usize;
        let PointCache {
            rings,
            cells,
            scratch,
        } = cache;
        let c = &mut cells[slot];
        let lut = self.lut_array();
        let known = c.uid == self.uid && c.cell == cell;
        if known && c.groups.is_empty() && !c.too_many {
            c.too_many = !self.build_cell(rings, scratch, cell, side, &mut c.groups);
        }
        if known && !c.too_many {
            let kind = self.rings.kind();
            let mut f = 0.0;
            for g in &c.groups {
                let (mask, v, a) = lanes.group_at(g, kind, (x, y), lut, &self.noise_pad);
                for q in 0..4 {
                    f = ring::fold_step(kind.interaction, mask >> q & 1 != 0, f, v[q], a[q]);
                }
            }
            return f;
        }
        if !known {
            // First time in this cell: remember it, and go through the ring cache.
            c.uid = self.uid;
            c.cell = cell;
            c.groups.clear();
            c.too_many = false;
        }
        self.through_rings(lanes, rings, (x, y), lut)
    }

    /// The cell `cell` (side `side` mm): the rings that can cover any of its points, in
    /// milling order, four to a group (the last padded with rings that cover nothing).
    /// At least one group, so that a built cell is never empty; or false, with no
    /// group, if the cell meets more than [`MAX_CELL_RINGS`] rings.
    fn build_cell(
        &self,
        rings: &mut [CachedRing],
        scratch: &mut Vec<(Key, ring::SpanRing)>,
        cell: (i64, i64),
        side: f64,
        groups: &mut Vec<ring::Group>,
    ) -> bool {
        let (x0, y0) = (cell.0 as f64 * side, cell.1 as f64 * side);
        // The cell a hair larger than its side: a point's floor(x / side) may round
        // across the border.
        let margin = 1e-9 * side + 1e-12 * x0.abs().max(y0.abs());
        let rect = (
            x0 - margin,
            y0 - margin,
            x0 + side + margin,
            y0 + side + margin,
        );
        scratch.clear();
        self.rect_candidates(rect, |id| {
            let e = self.ring_in(rings, Self::ring_slot(id), id);
            if let Some((lo, hi)) = e.ring.support()
                && rect_meets_annulus(rect, (e.ring.cx, e.ring.cy), lo, hi)
            {
                scratch.push((e.key, e.ring));
            }
        });
        groups.clear();
        if scratch.len() > MAX_CELL_RINGS {
            return false;
        }
        scratch.sort_unstable_by_key(|e| e.0);
        let none = match scratch.first() {
            Some(e) => e.1,
            None => self.cache_entry((0, 0), 0).ring,
        }
        .covering_nothing();
        for chunk in scratch.chunks(4) {
            let at = |q: usize| chunk.get(q).map_or(&none, |e| &e.1);
            groups.push(ring::Group::from_rings([at(0), at(1), at(2), at(3)]));
        }
        if groups.is_empty() {
            groups.push(ring::Group::from_rings([&none; 4]));
        }
        true
    }

    /// The point (x, y) (mm) through the ring cache: its candidate rings four at a
    /// time, those covering it folded in milling order.
    #[inline(always)]
    fn through_rings(
        &self,
        lanes: impl simd::PointLanes,
        rings: &mut [CachedRing],
        (x, y): (f64, f64),
        lut: &[f32; SHAPE_LUT],
    ) -> f64 {
        let m = &self.rings;
        let mut ids: SmallVec<[(i64, i64); 16]> = SmallVec::new();
        self.path
            .candidates(x, y, m.reach_in, m.reach_out, |id| ids.push(id));
        let mut found: SmallVec<[(Key, f64, f64); 16]> = SmallVec::new();
        // Slots of the candidates not yet evaluated: at most 4, all distinct.
        let mut pending = [0usize; 4];
        let mut n = 0;
        for &id in &ids {
            let slot = Self::ring_slot(id);
            if pending[..n].contains(&slot) {
                // The slot may be about to change: evaluate what waits on it first.
                self.covering(lanes, rings, &pending[..n], (x, y), lut, &mut found);
                n = 0;
            }
            self.ring_in(rings, slot, id);
            pending[n] = slot;
            n += 1;
            if n == 4 {
                self.covering(lanes, rings, &pending, (x, y), lut, &mut found);
                n = 0;
            }
        }
        self.covering(lanes, rings, &pending[..n], (x, y), lut, &mut found);
        fold_keyed(m.interaction, &mut found)
    }

    /// The rings in the cache slots `slots` (at most 4) at the point (x, y) (mm): each
    /// that covers it is pushed to `found` as (key, R_k, A_k).
    #[inline(always)]
    fn covering(
        &self,
        lanes: impl simd::PointLanes,
        cache: &[CachedRing],
        slots: &[usize],
        (x, y): (f64, f64),
        lut: &[f32; SHAPE_LUT],
        found: &mut SmallVec<[(Key, f64, f64); 16]>,
    ) {
        let Some(&last) = slots.last() else {
            return;
        };
        let at = |q: usize| &cache[slots.get(q).copied().unwrap_or(last)];
        let g = ring::Group::from_rings([&at(0).ring, &at(1).ring, &at(2).ring, &at(3).ring]);
        let (mask, v, a) = lanes.group_at(&g, self.rings.kind(), (x, y), lut, &self.noise_pad);
        for q in 0..slots.len() {
            if mask >> q & 1 != 0 {
                found.push((at(q).key, v[q], a[q]));
            }
        }
    }

    /// The shape table as the row and point paths read it.
    #[inline(always)]
    fn lut_array(&self) -> &[f32; SHAPE_LUT] {
        self.lut[..]
            .try_into()
            .expect("the shape table has SHAPE_LUT entries (checked when loaded)")
    }

    /// Rows `rows` of `region` in blocks: the rings that can reach a block are found
    /// and drawn once ([`ring::RingModel::drawn`]) and sorted into milling order once,
    /// then folded ring by ring over the block ([`Self::block_ring_major`]; point by
    /// point beyond [`SPAN_LIMIT`]). A ring's numbers and the fold's order of operations
    /// are those of [`Self::eval_mm`], so each value is the bits `height()` gives at that
    /// point. Blocks are about one support annulus wide (and at most the band's rows
    /// tall); where that is under [`MIN_BLOCK`] pixels, or the step is above 1 pixel
    /// (footprint averaging), points are sampled one by one.
    fn fill_blocks(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        let m = &self.rings;
        let px_mm = region.step * self.mm_per_px;
        let side = ((m.support2.1.sqrt() - m.support2.0.sqrt()) / px_mm).floor();
        if !(region.step <= 1.0 && side >= MIN_BLOCK as f64) {
            return fill_rows_by_sample(self, region, rows, out);
        }
        let side = (side as usize).min(MAX_BLOCK);
        let spiral = self.path.is_spiral();
        let mut list: Vec<ring::Drawn> = Vec::with_capacity(64);
        let mut acc: Vec<f64> = Vec::with_capacity(side * side);
        let w = region.width;
        let mut r0 = rows.start;
        while r0 < rows.end {
            let r1 = (r0 + side).min(rows.end);
            let mut c0 = 0;
            while c0 < w {
                let c1 = (c0 + side).min(w);
                let (x0, y0) = (region.x_at(c0), region.y_at(r0));
                let (x1, y1) = (region.x_at(c1 - 1), region.y_at(r1 - 1));
                let at = |r: usize, c: usize| (r - rows.start) * w + c;
                if !(in_range(x0, y0) && in_range(x1, y1)) {
                    for r in r0..r1 {
                        for c in c0..c1 {
                            out[at(r, c)] = self.height(region.x_at(c), region.y_at(r));
                        }
                    }
                    c0 = c1;
                    continue;
                }
                let s = self.mm_per_px;
                let rect = (x0 * s, y0 * s, x1 * s, y1 * s);
                self.block_rings(rect, spiral, &mut list);
                if x0.abs().max(x1.abs()).max(y0.abs()).max(y1.abs()) > SPAN_LIMIT {
                    for r in r0..r1 {
                        let y = region.y_at(r) * s;
                        for c in c0..c1 {
                            let x = region.x_at(c) * s;
                            out[at(r, c)] = self.adapt(self.fold_drawn(&list, x, y));
                        }
                    }
                } else {
                    self.block_ring_major(region, (r0, r1, c0, c1), &list, &mut acc);
                    let bw = c1 - c0;
                    for (r, src) in (r0..r1).zip(acc.chunks_exact(bw)) {
                        let dst = &mut out[at(r, c0)..at(r, c1)];
                        for (o, &h) in dst.iter_mut().zip(src) {
                            *o = self.adapt(h);
                        }
                    }
                }
                c0 = c1;
            }
            r0 = r1;
        }
    }

    /// The rings that can reach the rectangle `rect` (mm), drawn, in milling order.
    fn block_rings(&self, rect: (f64, f64, f64, f64), spiral: bool, list: &mut Vec<ring::Drawn>) {
        list.clear();
        self.rings_reaching_rect(rect, spiral, |_, d| list.push(d));
        if self.rings.interaction != InteractionKind::Min {
            list.sort_unstable_by_key(|d| d.key);
        }
    }

    /// Calls `push(id, drawn)` for every ring that can reach the rectangle `rect` (mm),
    /// in the order the path visits them (sort by [`ring::Drawn::key`] for milling
    /// order). The GPU fill builds its per-block ring lists with it.
    pub(crate) fn rings_reaching_rect(
        &self,
        rect: (f64, f64, f64, f64),
        spiral: bool,
        mut push: impl FnMut((i64, i64), ring::Drawn),
    ) {
        let m = &self.rings;
        let (s_in, s_out) = (m.support2.0.sqrt(), m.support2.1.sqrt());
        self.rect_candidates(rect, |id| {
            let d = m.drawn(&self.path.nominal(id), spiral);
            if rect_meets_annulus(rect, d.centre, s_in, s_out) {
                push(id, d);
            }
        });
    }

    /// Calls `visit(id)` for every ring whose nominal centre is close enough to the
    /// rectangle `rect` (mm) for the ring to reach it: the path's candidates of its
    /// middle, with the reach widened by half its diagonal.
    fn rect_candidates(&self, rect: (f64, f64, f64, f64), visit: impl FnMut((i64, i64))) {
        let m = &self.rings;
        let (x0, y0, x1, y1) = rect;
        let (mx, my) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
        // Half the diagonal, a hair larger so rounding cannot drop a ring.
        let half = 0.5 * (x1 - x0).hypot(y1 - y0) * (1.0 + 1e-9) + 1e-12;
        self.path.candidates(
            mx,
            my,
            (m.reach_in - half).max(0.0),
            m.reach_out + half,
            visit,
        );
    }

    /// The ring model (for the GPU path).
    #[cfg_attr(not(feature = "gpu"), allow(dead_code))]
    pub(crate) fn ring_model(&self) -> &RingModel {
        &self.rings
    }

    /// The tool path (for the GPU path).
    #[cfg_attr(not(feature = "gpu"), allow(dead_code))]
    pub(crate) fn tool_path(&self) -> &ToolPath {
        &self.path
    }

    /// Millimetres per surface pixel.
    #[cfg_attr(not(feature = "gpu"), allow(dead_code))]
    pub(crate) fn mm_per_px(&self) -> f64 {
        self.mm_per_px
    }

    /// The radial shape table and the quantised noise profiles (for the GPU path).
    #[cfg_attr(not(feature = "gpu"), allow(dead_code))]
    pub(crate) fn tables(&self) -> (&[f32], &[i16]) {
        (&self.lut, &self.noise_q)
    }

    /// The block rows r0..r1 × columns c0..c1 of `region`, ring by ring in milling
    /// order: each ring updates f only at the points of its own support (the annulus
    /// of its drawn widths, [`ring::RingModel::support_radii`]), found per row as one or
    /// two column spans, a hair wider than the rounding of a column's coordinate (the
    /// exact test being [`ring::Drawn::value`]'s). Per point, the rings covering it are
    /// folded in the same order and with the same operations as in
    /// [`Self::fold_drawn`], so the values are the same bits; a ring costs nothing at
    /// the points it misses.
    fn block_ring_major(
        &self,
        region: &Region,
        (r0, r1, c0, c1): (usize, usize, usize, usize),
        list: &[ring::Drawn],
        acc: &mut Vec<f64>,
    ) {
        let m = &self.rings;
        let s = self.mm_per_px;
        let bw = c1 - c0;
        acc.clear();
        acc.resize((r1 - r0) * bw, 0.0);
        let xs: SmallVec<[f64; MAX_BLOCK]> = (c0..c1).map(|c| region.x_at(c) * s).collect();
        let lut = self.lut_array();
        // Column of x (mm), before rounding, and how far its rounding can reach: a
        // millionth of a column, or 10⁻¹² of the coordinate (pixels) where that is more
        // (up to SPAN_LIMIT = 2⁴⁰ px, about one column).
        let col_of = |x: f64| (x / s - region.x) / region.step - region.col0 as f64;
        let far = region.x_at(c0).abs().max(region.x_at(c1 - 1).abs());
        let slack = 1e-6 + 1e-12 * far / region.step;
        for d in list {
            let mut k = m.span_ring(d);
            let Some((lo, hi)) = m.support_of(&k) else {
                continue;
            };
            let (in2, out2) = (lo * lo * (1.0 - 1e-9), hi * hi * (1.0 + 1e-9));
            let (cx, cy) = d.centre;
            for r in r0..r1 {
                let y = region.y_at(r) * s;
                let dy2 = (y - cy) * (y - cy);
                let out2 = out2 - dy2;
                if out2 < 0.0 {
                    continue;
                }
                let in2 = in2 - dy2;
                k.set_row(y);
                let row = &mut acc[(r - r0) * bw..(r - r0 + 1) * bw];
                path::annulus_runs(cx, in2, out2, |lo: f64, hi: f64| {
                    let a = (col_of(lo) - slack).ceil().max(c0 as f64);
                    let b = (col_of(hi) + slack).floor().min((c1 - 1) as f64);
                    if a.is_nan() || b.is_nan() || a > b {
                        return;
                    }
                    let (a, b) = (a as usize - c0, b as usize - c0);
                    k.fold(&xs[a..=b], &mut row[a..=b], lut, &self.noise_pad);
                });
            }
        }
    }

    /// [`Self::eval_mm`] over a block's ring list in milling order.
    #[inline(always)]
    fn fold_drawn(&self, list: &[ring::Drawn], x: f64, y: f64) -> f64 {
        let m = &self.rings;
        let mut covering = list
            .iter()
            .filter_map(|d| d.value(m, x, y, &self.lut, &self.noise_q));
        match m.interaction {
            InteractionKind::Min => covering.fold(0.0f64, |f, v| ring::fold_min(f, v.r)),
            InteractionKind::Latest => covering.next_back().map_or(0.0, |v| v.r),
            InteractionKind::Convex => covering.fold(0.0, |f, v| v.a * v.r + (1.0 - v.a) * f),
        }
    }

    #[inline(always)]
    fn adapt(&self, h: f64) -> f32 {
        match &self.adaptation {
            Some(a) => {
                ((h - a.model_mean_um) * (a.target_std_um / a.model_std_um) + a.target_mean_um)
                    as f32
            }
            None => h as f32,
        }
    }

    /// A bank holding this surface's configuration, tables and adaptation
    /// (`surftile bake --method milling`).
    pub fn to_bank(&self, source: &str) -> Result<Bank> {
        let info = MillingBankInfo {
            config: self.config.clone(),
            adaptation: self.adaptation,
        };
        let info = serde_json::to_value(&info)
            .map_err(|e| Error::bank(source, format!("milling section: {e}")))?;
        let header = BankHeader {
            method: Method::Milling,
            channels: 1,
            tiles: NOISE_PROFILES,
            tile_size: [NOISE_SAMPLES, 1],
            lattice: [[0.0; 2]; 2],
            levels: vec![LevelInfo {
                size: [NOISE_SAMPLES, 1],
                mean: vec![0.0],
                sigma: vec![0.0],
                shift: None,
            }],
            spacing_um: Some(self.spacing_um()),
            height_unit: "um".into(),
            seed: 0,
            exemplar: ExemplarInfo {
                source: source.into(),
                width: 0,
                height: 0,
                mean: vec![0.0],
                std: vec![0.0],
                quantile_levels: Vec::new(),
                quantiles: vec![Vec::new()],
                levels: None,
            },
            bake: format!("method=milling config={source}"),
            record: Record::Milling {
                lut_size: SHAPE_LUT,
                info,
            },
        };
        Bank::new(
            header,
            vec![self.noise.clone()],
            vec![self.lut.clone()],
            source,
        )
    }

    /// The surface a milling bank describes, with placement seed `seed` for the rings
    /// (the noise profiles are the bank's).
    pub fn from_bank(bank: &Bank, seed: u32) -> Result<MillingSurface> {
        let info = check_bank(bank, "milling bank")?;
        let h = &bank.header;
        Self::from_parts(
            &info.config,
            h.spacing_um.unwrap_or(1.0),
            seed,
            bank.luts[0].clone(),
            bank.texels[0].clone(),
            info.adaptation,
        )
    }
}

impl Surface for MillingSurface {
    fn channels(&self) -> usize {
        1
    }

    /// Full resolution for footprints up to 1 pixel; wider footprints average an n×n
    /// grid of points inside it (n = ⌈footprint⌉, at most 4), so zoomed-out fills do not
    /// alias the rings as badly as point samples would.
    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        if footprint.is_nan() || footprint <= 1.0 {
            out[0] = self.height(x, y);
            return;
        }
        let n = footprint.ceil().min(4.0) as usize;
        let mut sum = 0.0f64;
        for a in 0..n {
            for b in 0..n {
                let ox = ((a as f64 + 0.5) / n as f64 - 0.5) * footprint;
                let oy = ((b as f64 + 0.5) / n as f64 - 0.5) * footprint;
                sum += self.height(x + ox, y + oy) as f64;
            }
        }
        out[0] = (sum / (n * n) as f64) as f32;
    }

    #[inline]
    fn height(&self, x: f64, y: f64) -> f32 {
        if !in_range(x, y) {
            return f32::NAN;
        }
        self.adapt(self.eval_mm_cached(x * self.mm_per_px, y * self.mm_per_px))
    }

    fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        self.fill_blocks(region, rows, out);
    }
}

/// Whether the annulus lo ≤ |p − centre| ≤ hi (mm) can meet the rectangle `rect`: its
/// nearest point no farther than hi and its farthest no nearer than lo, each with a
/// relative slack of 10⁻⁹ on the squares, far above their rounding.
#[inline(always)]
fn rect_meets_annulus(rect: (f64, f64, f64, f64), (cx, cy): (f64, f64), lo: f64, hi: f64) -> bool {
    let (x0, y0, x1, y1) = rect;
    let nx = (x0 - cx).max(cx - x1).max(0.0);
    let ny = (y0 - cy).max(cy - y1).max(0.0);
    let fx = (cx - x0).abs().max((x1 - cx).abs());
    let fy = (cy - y0).abs().max((y1 - cy).abs());
    nx * nx + ny * ny <= hi * hi * (1.0 + 1e-9) && fx * fx + fy * fy >= lo * lo * (1.0 - 1e-9)
}

/// f at a point from the rings covering it, each as (milling-order key, R_k, A_k), in
/// any order: min, the latest ring's value, or the convex fold in milling order (§4.2).
fn fold_keyed(interaction: InteractionKind, found: &mut [(Key, f64, f64)]) -> f64 {
    match interaction {
        InteractionKind::Min => found.iter().fold(0.0f64, |f, v| ring::fold_min(f, v.1)),
        InteractionKind::Latest => found
            .iter()
            .max_by(|a, b| a.0.cmp(&b.0))
            .map_or(0.0, |v| v.1),
        InteractionKind::Convex => {
            found.sort_unstable_by_key(|p| p.0);
            found
                .iter()
                .fold(0.0, |f, &(_, r, a)| a * r + (1.0 - a) * f)
        }
    }
}

/// The brute-force twin (seed 000 §4 as written): every ring of the finite path that
/// reaches a rectangle, sorted once into milling order, each evaluated at every point
/// and folded by the interaction, f_k = f(f_{k−1}, R_k). O(rings) per point.
pub struct BruteForce<'a> {
    surface: &'a MillingSurface,
    rings: Vec<(Key, Nominal)>,
}

impl<'a> BruteForce<'a> {
    /// The rings of `surface`'s path reaching the pixel rectangle [x0, x1] × [y0, y1].
    pub fn new(surface: &'a MillingSurface, x0: f64, y0: f64, x1: f64, y1: f64) -> Self {
        let s = surface.mm_per_px;
        let m = &surface.rings;
        let spiral = surface.path.is_spiral();
        let mut rings: Vec<(Key, Nominal)> = surface
            .path
            .rings_reaching((x0 * s, y0 * s, x1 * s, y1 * s), m.reach_out)
            .into_iter()
            .map(|id| {
                let ring = surface.path.nominal(id);
                (m.key(&ring, spiral), ring)
            })
            .collect();
        rings.sort_by_key(|a| a.0);
        BruteForce { surface, rings }
    }

    /// Number of rings evaluated per point.
    pub fn rings(&self) -> usize {
        self.rings.len()
    }

    /// The height at pixel (x, y), which must lie in the rectangle.
    pub fn height(&self, x: f64, y: f64) -> f32 {
        let s = self.surface;
        let (x, y) = (x * s.mm_per_px, y * s.mm_per_px);
        let m = &s.rings;
        let mut f = 0.0f64;
        for (_, ring) in &self.rings {
            let value = m.value(ring, x, y, &s.lut, &s.noise_q);
            f = match (m.interaction, value) {
                (InteractionKind::Min, v) => ring::fold_min(f, v.map_or(0.0, |v| v.r)),
                (InteractionKind::Latest, Some(v)) => v.r,
                (InteractionKind::Convex, Some(v)) => v.a * v.r + (1.0 - v.a) * f,
                (_, None) => f,
            };
        }
        s.adapt(f)
    }
}

/// The configuration and adaptation of a milling bank, checked: one level of noise
/// profiles, one shape table, a configuration that passes its own checks, a positive
/// spacing, a finite adaptation, tables within [−1, 1]. `what` names the bank in errors.
pub fn check_bank(bank: &Bank, what: &str) -> Result<MillingBankInfo> {
    let h = &bank.header;
    let bad = |m: String| Err(Error::bank(what, m));
    let Record::Milling { info, .. } = &h.record else {
        return bad(format!("a {} bank; expected a milling bank", h.rule()));
    };
    bank.validate(what)?;
    let info: MillingBankInfo = BankHeader::decode(info, "milling", what)?;
    info.config
        .validate()
        .map_err(|e| Error::bank(what, format!("configuration: {e}")))?;
    if h.channels != 1
        || h.tiles != NOISE_PROFILES
        || h.tile_size != [NOISE_SAMPLES, 1]
        || h.levels.len() != 1
        || h.levels[0].size != [NOISE_SAMPLES, 1]
        || h.lut_size() != SHAPE_LUT
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
    if bank.texels[0]
        .iter()
        .chain(&bank.luts[0])
        .any(|v| v.is_nan() || v.abs() > 1.0)
    {
        return bad("milling tables hold values outside [−1, 1]".into());
    }
    Ok(info)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The point path as CPUs without AVX2 run it (`simd::Scalar`, which the AVX2
    /// machines of CI would otherwise never take) gives [`MillingSurface::eval_mm`]'s
    /// bits, through the ring cache (a cell's first point) and through built cells (its
    /// later ones), on a parallel and a spiral path, for every interaction.
    #[test]
    fn the_scalar_point_path_equals_the_uncached_one() {
        let mut u = ring::tests::uniform(0x2545_F491_4F6C_DD1D);
        let (mut points, mut nonzero) = (0usize, 0usize);
        for path in [
            "parallel\"\nangle_deg = 30.0",
            "spiral\"\norigin_mm = [0.7, -0.4]",
        ] {
            for interaction in ["min", "latest", "convex"] {
                let text = format!(
                    "[interaction]\nkind = \"{interaction}\"\n[path]\nkind = \"{path}\nreorder = 0.3\n"
                );
                let c = MillingConfig::from_toml(&text, "test").unwrap();
                let s = MillingSurface::new(&c, 6.1, 3).unwrap();
                let mut cache = PointCache::default();
                s.ready(&mut cache);
                for _ in 0..400 {
                    let (x, y) = (3.0 * (u() - 0.5), 3.0 * (u() - 0.5));
                    let want = s.eval_mm(x, y);
                    for ask in 0..2 {
                        let got = s.cached(simd::Scalar, &mut cache, x, y);
                        assert_eq!(
                            got.to_bits(),
                            want.to_bits(),
                            "{text}\nat ({x}, {y}) mm, ask {ask}: scalar {got}, uncached {want}"
                        );
                    }
                    points += 1;
                    nonzero += (want != 0.0) as usize;
                }
                assert!(
                    cache.cells.iter().any(|c| !c.groups.is_empty()),
                    "{text}: no cell was built"
                );
            }
        }
        assert!(
            nonzero > points / 2,
            "only {nonzero} of {points} points touched"
        );
    }

    /// A step far below the ring width (δ = 0.02 mm) puts more than [`MAX_CELL_RINGS`]
    /// rings on every cell: no cell is built, and every point, asked again and again,
    /// still gives the uncached bits (through the ring cache), on both point paths.
    #[test]
    fn cells_meeting_too_many_rings_stay_unbuilt() {
        let mut u = ring::tests::uniform(0x1234_5678_9ABC_DEF1);
        let text =
            "[interaction]\nkind = \"convex\"\n[path]\nkind = \"parallel\"\nstep_mm = 0.02\n";
        let c = MillingConfig::from_toml(text, "test").unwrap();
        let s = MillingSurface::new(&c, 6.1, 3).unwrap();
        let mut cache = PointCache::default();
        s.ready(&mut cache);
        for _ in 0..100 {
            let (x, y) = (u() - 0.5, u() - 0.5);
            let want = s.eval_mm(x, y);
            for _ in 0..3 {
                let got = s.cached(simd::Scalar, &mut cache, x, y);
                assert_eq!(got.to_bits(), want.to_bits(), "at ({x}, {y}) mm");
                let got = s.eval_mm_cached(x, y);
                assert_eq!(got.to_bits(), want.to_bits(), "at ({x}, {y}) mm");
            }
        }
        let seen = cache.cells.iter().filter(|c| c.uid == s.uid);
        assert!(
            seen.clone().all(|c| c.groups.is_empty()) && seen.filter(|c| c.too_many).count() > 10,
            "cells with too many rings were built, or none was found too full"
        );
    }
}
