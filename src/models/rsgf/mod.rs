//! Near-regular synthesis by random sampling and gap filling (RSGF, seed 002 §4), as a
//! lazy [`Surface`] (ALGORITHMS.md §4).
//!
//! The output plane is cut into square blocks of B pixels in a chessboard. A **random
//! block** (I + J even) shows an exemplar patch picked by hash(seed, I, J) among those
//! at lattice multiples of its own position (§4.1) — it depends on nothing else. A
//! **gap block** (I + J odd) shows the patch whose border, within ±tolerance of the
//! lattice multiples, best matches the border its four random neighbours compose (§4.2)
//! — it depends on those four only. Patches extend o pixels past their block; across
//! each block edge the two patches blend linearly.
//!
//! So every pixel is a function of a few blocks around it: any region, filled in any
//! order, on any number of threads, gives the pixels of one sequential whole-image run
//! ([`RsgfModel::synthesize`]) with the same seed, bit for bit. Solving a gap is the only
//! costly step (a border match over the exemplar); solved gaps are kept in an LRU
//! shared by all threads.

mod gap;
mod model;

use std::num::NonZeroUsize;
use std::ops::Range;
use std::sync::{Arc, Mutex};

use lru::LruCache;
use serde::{Deserialize, Serialize};

use model::Edge;
pub use model::{MAX_EXEMPLAR_PIXELS, RsgfModel, wrap_fits, wrapped_side};
pub(crate) use model::{mip_chain, wrap_extend, wrap_torus};

use crate::bank::{Bank, BankHeader, Record};
use crate::error::{Error, Result};
use crate::raster::Raster;
use crate::stream::{Region, Surface, fill_rows_by_sample, floor_split, in_range, mip_level};

/// How a gap's border is matched (§4.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Metric {
    /// Sum of squared differences over the border (eq. 10): also matches brightness.
    Ssd,
    /// Generalized NCC with the hole left out (eqs. 3–8): matches structure only.
    Ncc,
}

/// How neighbouring patches are joined across the 2·o pixels of their overlap.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Join {
    /// Linear blending across the overlap (the paper's): objects that differ in the
    /// overlap show through each other ("ghosts"), and the variance drops. Banks written
    /// before joins were recorded use it.
    #[default]
    Blend,
    /// A minimum-error cut through the overlap (Efros & Freeman 2001; seed 000 §3.2.1
    /// eq. (1)'s squared difference): every pixel is one patch's, so objects stay whole
    /// and the histogram is the exemplar's.
    Cut,
}

/// How a stochastic bank's patches meet the exemplar's edges (the bake's choice,
/// recorded as [`RsgfParams::reflect_edges`] or [`RsgfParams::wrap_edges`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Edges {
    /// Wrap where blocks at bounded positions would miss the exemplar's histogram
    /// (`bake::rsgf::coverage_bias`), the exemplar can wrap ([`wrap_fits`]) and, in a
    /// bake, trial fills say the wrapped layout misses fewer value bars
    /// (`bake::rsgf::EdgeTrial`); else reflect (with cuts; blended patches keep to
    /// bounded positions).
    #[default]
    Auto,
    /// Patches hang over the exemplar's edges, mirrored ([`RsgfParams::reflect_edges`]).
    Reflect,
    /// Patches wrap around the exemplar made periodic ([`RsgfParams::wrap_edges`]).
    Wrap,
}

/// RSGF synthesis parameters (all lengths in exemplar pixels).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RsgfParams {
    /// Block side B. Default 40 (the paper's).
    pub block_px: usize,
    /// Border o that each patch extends past its block, for matching and blending.
    /// Default 10 (the paper's); below B/2.
    pub border_px: usize,
    /// Gap candidates lie within ± this many pixels (per axis) of a lattice multiple.
    /// Default 3 (the paper's).
    pub tolerance_px: usize,
    /// Border measure of the gap filling. Default SSD.
    pub metric: Metric,
    /// How patches join across block edges. Default: cuts (banks that do not record
    /// it blended).
    #[serde(default)]
    pub join: Join,
    /// With cuts: the patches ramp linearly over 2·feather pixels around the cut (0: a
    /// hard cut). Default 2; below the border.
    #[serde(default = "default_feather")]
    pub feather_px: usize,
    /// Per channel, a monotone map applied to every output value, as knots (from, to),
    /// `from` increasing: the bake's measure of the histogram a synthesis gives, mapped
    /// back onto the exemplar's (see `bake::rsgf::histogram_map`). None: values are
    /// the exemplar's (or blends of them) as they are.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub histogram: Option<Vec<Vec<[f32; 2]>>>,
    /// Patches may hang over the exemplar's edges by up to the border: the exemplar is
    /// extended by `border_px` on every side with its mirror image (reflected about
    /// its edge pixels), so that a block — the part of a patch the output shows away
    /// from cuts — can lie anywhere in the exemplar, edges included. Without it a
    /// block keeps o px from every edge, and the pixels near the edges are shown far
    /// less than the middle: on the 100² dried-mud photo (40-px blocks) the rows
    /// within 10 px of an edge were shown 0.01 times as often as the average and the
    /// middle 2.1 times, and the output kept 0.87 of the exemplar's standard
    /// deviation (1024²; 0.90 with reflected edges, W1 0.087 → 0.07). The mirrored
    /// pixels serve the gap matching; cuts pay for each pixel that would show one (a
    /// million times the largest squared difference of a pixel), so none shows
    /// where a cut can avoid it (`tests/rsgf.rs::reflected_edges_show_the_exemplars_border`).
    /// Default on in stochastic mode with cuts, unless the bank wraps
    /// ([`RsgfParams::wrap_edges`]); banks that do not record it: off. With
    /// [`Join::Blend`] the mirrored pixels would show across every overlap; zoomed-out
    /// samples, which blend patches read from the mip chain, may show them faintly.
    #[serde(default)]
    pub reflect_edges: bool,
    /// Patches wrap around the exemplar made periodic: a torus up to 2·`border_px`
    /// smaller per axis (or not at all), whose seams are minimum-error cuts through the
    /// columns and rows that its opposite edges share (`wrap_torus` in the model). Every torus position is
    /// a patch position, so every exemplar pixel is shown about equally often, and a
    /// block's phase no longer tells which exemplar rows it shows. With a block edge at
    /// a fixed place and its patch at a bounded position p, pixel u of a block shows
    /// exemplar row p + u, so the rows near the block's top come from the exemplar's
    /// upper part and those near its bottom from its lower part: the gradient energy
    /// per phase of the block grid follows the exemplar's rows, and the edges of a
    /// small exemplar are shown less than its middle (see docs/structure.md). On a
    /// torus p + u is uniform for every u. The bake turns it on in stochastic mode
    /// where blocks at bounded positions would miss the exemplar's histogram
    /// (`bake::rsgf::coverage_bias`), the exemplar can wrap ([`wrap_fits`]) and trial
    /// fills say wrapping misses fewer value bars (`bake::rsgf::EdgeTrial`), or
    /// where `--edges wrap` asks; banks that do not record it: off. Stochastic (unit
    /// lattice) only, not with `reflect_edges`, and with a ramp below the border (the
    /// torus's seams ramp as block edges do, whatever the join).
    #[serde(default)]
    pub wrap_edges: bool,
    /// Translation vectors v₁, v₂ in pixels ((1, 0), (0, 1) in stochastic mode).
    pub v1: (i64, i64),
    /// See `v1`.
    pub v2: (i64, i64),
}

/// Default cut feather ([`RsgfParams::feather_px`]).
pub const DEFAULT_FEATHER: usize = 2;

fn default_feather() -> usize {
    DEFAULT_FEATHER
}

/// Largest block side accepted.
pub const MAX_BLOCK: usize = 1024;

impl RsgfParams {
    /// The paper's settings (40 px blocks, 10 px borders, ±3 px, SSD) on lattice (v1, v2).
    pub fn new(v1: (i64, i64), v2: (i64, i64)) -> RsgfParams {
        RsgfParams {
            block_px: 40,
            border_px: 10,
            tolerance_px: 3,
            metric: Metric::Ssd,
            join: Join::Cut,
            feather_px: DEFAULT_FEATHER,
            histogram: None,
            reflect_edges: false,
            wrap_edges: false,
            v1,
            v2,
        }
    }

    /// Stochastic mode: v₁ = (1, 0), v₂ = (0, 1), so every position is a candidate,
    /// matched by NCC. (SSD, the paper's, favours flat patches when every position
    /// competes: their borders differ least from anything, and the output's standard
    /// deviation drops — 0.94 of the exemplar's on the AFM map di-6, 0.99 with NCC.)
    pub fn stochastic() -> RsgfParams {
        RsgfParams {
            metric: Metric::Ncc,
            reflect_edges: true,
            ..RsgfParams::new((1, 0), (0, 1))
        }
    }

    /// Checks the parameters on their own.
    pub fn validate(&self) -> Result<()> {
        if !(2..=MAX_BLOCK).contains(&self.block_px) {
            return Err(Error::param(
                "block",
                self.block_px,
                format!("2 to {MAX_BLOCK} pixels"),
            ));
        }
        if self.border_px == 0 || self.border_px >= self.block_px.div_ceil(2) {
            return Err(Error::param(
                "border",
                self.border_px,
                format!(
                    "1 pixel to less than half the block ({} px): borders of neighbouring blocks must not meet",
                    self.block_px
                ),
            ));
        }
        if self.join == Join::Cut && self.feather_px >= self.border_px {
            return Err(Error::param(
                "feather",
                self.feather_px,
                format!(
                    "0 to less than the border ({} px): the ramp around a cut stays inside the overlap",
                    self.border_px
                ),
            ));
        }
        if self.reflect_edges && self.join != Join::Cut {
            return Err(Error::param(
                "reflect_edges",
                "with linear blending",
                "cuts (join = cut): only a cut keeps the mirrored pixels out of the output",
            ));
        }
        if self.wrap_edges && (self.v1, self.v2) != ((1, 0), (0, 1)) {
            return Err(Error::param(
                "wrap_edges",
                format!(
                    "on the lattice ({},{});({},{})",
                    self.v1.0, self.v1.1, self.v2.0, self.v2.1
                ),
                "stochastic mode (v1 = (1, 0), v2 = (0, 1)): the torus's seams do not keep a lattice's period",
            ));
        }
        if self.wrap_edges && self.feather_px >= self.border_px {
            return Err(Error::param(
                "feather",
                self.feather_px,
                format!(
                    "0 to less than the border ({} px) with wrapped edges: the torus's seams ramp as block edges do",
                    self.border_px
                ),
            ));
        }
        if self.reflect_edges && self.wrap_edges {
            return Err(Error::param(
                "edges",
                "reflected and wrapped",
                "one of reflect_edges and wrap_edges: a patch either hangs over mirrored edges or wraps around a torus",
            ));
        }
        if self.tolerance_px > 64 {
            return Err(Error::param(
                "tolerance",
                self.tolerance_px,
                "0 to 64 pixels",
            ));
        }
        crate::lattice::Lattice::from_basis(self.v1, self.v2)?;
        Ok(())
    }

    /// Checks that a `w × h` exemplar holds a block of B pixels, a patch of B + 2·o
    /// pixels unless its edges are reflected ([`RsgfParams::reflect_edges`]), and
    /// B + 4·o where patches wrap ([`RsgfParams::wrap_edges`]: the torus, up to 2·o
    /// smaller, holds a whole patch).
    pub fn check_exemplar(&self, w: usize, h: usize) -> Result<()> {
        let ext = self.block_px + 2 * self.border_px;
        if self.block_px > w.min(h) {
            return Err(Error::param(
                "block",
                self.block_px,
                format!("at most the exemplar's smaller side ({w}×{h})"),
            ));
        }
        if self.wrap_edges && ext + 2 * self.border_px > w.min(h) {
            return Err(Error::param(
                "block + 4 × border",
                ext + 2 * self.border_px,
                format!(
                    "at most the exemplar's smaller side ({w}×{h}) with wrapped edges: the torus, up to 2 × border smaller than the exemplar, holds a whole patch (or use --edges reflect)"
                ),
            ));
        }
        if !self.reflect_edges && ext > w.min(h) {
            return Err(Error::param(
                "block + 2 × border",
                ext,
                format!(
                    "at most the exemplar's smaller side ({w}×{h}): a patch is the block plus its border on each side"
                ),
            ));
        }
        Ok(())
    }
}

/// Solved gaps kept by default.
pub const DEFAULT_CACHE_BLOCKS: usize = 1 << 14;

/// Cut paths by edge, shared by all threads.
type CutCache = LruCache<(Edge, i64, i64), Arc<[u16]>>;

/// The lazy RSGF surface: an [`RsgfModel`], a seed, and the LRU of solved gaps.
pub struct RsgfSurface {
    model: RsgfModel,
    seed: u32,
    cache: Mutex<LruCache<(i64, i64), u32>>,
    /// Cuts of edges met by single samples.
    cut_cache: Mutex<CutCache>,
}

impl RsgfSurface {
    /// The RSGF surface of `exemplar` with `params`, placed with `seed`.
    pub fn new(exemplar: &Raster, params: &RsgfParams, seed: u32) -> Result<RsgfSurface> {
        Ok(RsgfSurface::from_model(
            RsgfModel::new(exemplar, params)?,
            seed,
        ))
    }

    /// The surface of a model.
    pub fn from_model(model: RsgfModel, seed: u32) -> RsgfSurface {
        let cap = NonZeroUsize::new(DEFAULT_CACHE_BLOCKS).unwrap_or(NonZeroUsize::MIN);
        RsgfSurface {
            model,
            seed,
            cache: Mutex::new(LruCache::new(cap)),
            cut_cache: Mutex::new(LruCache::new(cap)),
        }
    }

    /// The surface an RSGF bank describes (rule `rsgf`), checked by [`check_bank`].
    pub fn from_bank(bank: &Bank, seed: u32) -> Result<RsgfSurface> {
        let params = check_bank(bank, "RSGF bank")?;
        let h = &bank.header;
        let [w, ht] = h.tile_size;
        let ex = Raster::from_vec(w, ht, h.channels, bank.texels[0].clone())?;
        RsgfSurface::new(&ex, &params, seed)
    }

    /// Keeps at most `blocks` solved gaps and as many cuts (≥ 1).
    pub fn with_cache_capacity(self, blocks: usize) -> RsgfSurface {
        let cap = NonZeroUsize::new(blocks).unwrap_or(NonZeroUsize::MIN);
        RsgfSurface {
            cache: Mutex::new(LruCache::new(cap)),
            cut_cache: Mutex::new(LruCache::new(cap)),
            ..self
        }
    }

    /// The model behind the surface.
    pub fn model(&self) -> &RsgfModel {
        &self.model
    }

    /// The sequential whole-image RSGF of `width × height` pixels from the origin, with
    /// this surface's seed: the reference every fill equals.
    pub fn reference(&self, width: usize, height: usize) -> Raster {
        self.model.synthesize(self.seed, width, height)
    }

    /// Position of block (i, j): hashed for a random block, solved (or remembered) for
    /// a gap.
    pub fn pick(&self, i: i64, j: i64) -> u32 {
        if RsgfModel::is_random(i, j) {
            return self.model.random_pick(self.seed, i, j);
        }
        if let Some(&q) = self.lock().get(&(i, j)) {
            return q;
        }
        let q = self.model.solve_gap(self.seed, i, j);
        self.lock().put((i, j), q);
        q
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, LruCache<(i64, i64), u32>> {
        self.cache.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The picks of blocks [i0, i1] × [j0, j1], row-major, gaps solved on `threads`
    /// threads (each once; remembered ones taken from the cache).
    fn picks(&self, (i0, i1): (i64, i64), (j0, j1): (i64, i64), threads: usize) -> Blocks {
        let gw = (i1 - i0 + 1) as usize;
        let gh = (j1 - j0 + 1) as usize;
        let mut grid = vec![0u32; gw * gh];
        let mut todo = Vec::new();
        {
            let mut cache = self.lock();
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let at = (j - j0) as usize * gw + (i - i0) as usize;
                    if RsgfModel::is_random(i, j) {
                        grid[at] = self.model.random_pick(self.seed, i, j);
                    } else if let Some(&q) = cache.get(&(i, j)) {
                        grid[at] = q;
                    } else {
                        todo.push((at, i, j));
                    }
                }
            }
        }
        let solved = par_map(&todo, threads, |&(at, i, j)| {
            (at, self.model.solve_gap(self.seed, i, j))
        });
        let mut cache = self.lock();
        for &(at, q) in &solved {
            grid[at] = q;
            let i = i0 + (at % gw) as i64;
            let j = j0 + (at / gw) as i64;
            cache.put((i, j), q);
        }
        Blocks { i0, j0, gw, grid }
    }

    /// The cuts of every edge between the blocks of `blocks` (none when patches blend),
    /// on `threads` threads: the vertical edges, then the horizontal ones, which cut
    /// between rows that the vertical ones compose. Horizontal edges need the vertical
    /// ones on both sides of their block column: none in the first and last columns
    /// (see [`RsgfSurface::block_range_x`]).
    fn cuts(&self, blocks: &Blocks, threads: usize) -> Cuts {
        let gh = blocks.grid.len() / blocks.gw;
        let mut cuts = Cuts {
            i0: blocks.i0,
            j0: blocks.j0,
            gw: blocks.gw,
            v: vec![Vec::new(); blocks.grid.len()],
            h: vec![Vec::new(); blocks.grid.len()],
        };
        if self.model.params.join != Join::Cut {
            return cuts;
        }
        for edge in [Edge::V, Edge::H] {
            let todo: Vec<(usize, usize)> = (0..gh)
                .flat_map(|dj| (0..blocks.gw).map(move |di| (di, dj)))
                .filter(|&(di, dj)| match edge {
                    Edge::V => di > 0,
                    Edge::H => dj > 0 && di > 0 && di + 1 < blocks.gw,
                })
                .collect();
            let paths = par_map(&todo, threads, |&(di, dj)| {
                let (i, j) = (blocks.i0 + di as i64, blocks.j0 + dj as i64);
                self.model.edge_cut(
                    edge,
                    i,
                    j,
                    &mut |i, j| blocks.get(i, j),
                    &mut |e, i, j, t| cuts.get(e, i, j)[t],
                )
            });
            let list = match edge {
                Edge::V => &mut cuts.v,
                Edge::H => &mut cuts.h,
            };
            for (&(di, dj), path) in todo.iter().zip(paths) {
                list[dj * blocks.gw + di] = path;
            }
        }
        cuts
    }

    /// The cut of one edge at t, computed or remembered (the single-sample path).
    fn cut_at(&self, edge: Edge, i: i64, j: i64, t: usize) -> u16 {
        let key = (edge, i, j);
        let known = self
            .cut_cache
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(&key)
            .cloned();
        let path = known.unwrap_or_else(|| {
            let path: Arc<[u16]> = self
                .model
                .edge_cut(
                    edge,
                    i,
                    j,
                    &mut |i, j| self.pick(i, j),
                    &mut |e, i, j, t| self.cut_at(e, i, j, t),
                )
                .into();
            self.cut_cache
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .put(key, path.clone());
            path
        });
        path[t]
    }

    /// The block columns a fill of pixels x0 ..= x1 needs: those whose patches reach
    /// them, and with cuts one more on each side, for the horizontal cuts of the
    /// outer ones.
    fn block_range_x(&self, x0: i64, x1: i64) -> (i64, i64) {
        let (i0, i1) = self.model.block_range(x0, x1);
        match self.model.params.join {
            Join::Cut => (i0 - 1, i1 + 1),
            Join::Blend => (i0, i1),
        }
    }

    /// Whether `region` samples integer pixels at step 1 (the block-wise fast path).
    fn pixel_aligned(region: &Region) -> Option<(i64, i64)> {
        let (x, y) = (region.x_at(0), region.y_at(0));
        (region.step == 1.0 && x.fract() == 0.0 && y.fract() == 0.0).then_some((x as i64, y as i64))
    }

    /// Rows `rows` of an aligned region whose first pixel is (x0, y0), from `blocks`.
    fn compose_rows(
        &self,
        blocks: &Blocks,
        cuts: &Cuts,
        (x0, y0): (i64, i64),
        width: usize,
        rows: Range<usize>,
        out: &mut [f32],
    ) {
        let c = self.model.c;
        let mut lookup = |i: i64, j: i64| blocks.get(i, j);
        let mut cut = |edge: Edge, i: i64, j: i64, t: usize| cuts.get(edge, i, j)[t];
        for (r, row) in rows.enumerate() {
            let py = y0 + row as i64;
            for col in 0..width {
                let at = (r * width + col) * c;
                self.model.pixel(
                    x0 + col as i64,
                    py,
                    &mut lookup,
                    &mut cut,
                    &mut out[at..at + c],
                );
            }
        }
    }
}

/// Block positions over a rectangle of blocks.
struct Blocks {
    i0: i64,
    j0: i64,
    gw: usize,
    grid: Vec<u32>,
}

impl Blocks {
    #[inline]
    fn get(&self, i: i64, j: i64) -> u32 {
        self.grid[(j - self.j0) as usize * self.gw + (i - self.i0) as usize]
    }
}

/// Cut paths of the edges over a rectangle of blocks ([`RsgfSurface::cuts`]).
struct Cuts {
    i0: i64,
    j0: i64,
    gw: usize,
    /// Per block: the path of its left edge (V) and of its top edge (H).
    v: Vec<Vec<u16>>,
    h: Vec<Vec<u16>>,
}

impl Cuts {
    #[inline]
    fn get(&self, edge: Edge, i: i64, j: i64) -> &[u16] {
        let at = (j - self.j0) as usize * self.gw + (i - self.i0) as usize;
        match edge {
            Edge::V => &self.v[at],
            Edge::H => &self.h[at],
        }
    }
}

/// `f` over `todo` on up to `threads` threads, results in `todo`'s order.
fn par_map<T: Sync, R: Send>(todo: &[T], threads: usize, f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    if threads <= 1 || todo.len() < 2 {
        return todo.iter().map(&f).collect();
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let parts = crossbeam::scope(|s| {
        let handles: Vec<_> = (0..threads.min(todo.len()))
            .map(|_| {
                s.spawn(|_| {
                    let mut mine = Vec::new();
                    loop {
                        let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(job) = todo.get(k) else {
                            break;
                        };
                        mine.push((k, f(job)));
                    }
                    mine
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_default())
            .collect::<Vec<_>>()
    });
    let mut slots: Vec<Option<R>> = (0..todo.len()).map(|_| None).collect();
    for (k, r) in parts.unwrap_or_default() {
        slots[k] = Some(r);
    }
    // A worker that died (it cannot, short of a bug) leaves its jobs undone here: do
    // them on this thread rather than return wrong results.
    slots
        .into_iter()
        .zip(todo)
        .map(|(r, job)| r.unwrap_or_else(|| f(job)))
        .collect()
}

impl Surface for RsgfSurface {
    fn channels(&self) -> usize {
        self.model.c
    }

    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        let c = self.model.c;
        if !in_range(x, y) {
            out[..c].fill(f32::NAN);
            return;
        }
        let mut pick = |i: i64, j: i64| self.pick(i, j);
        let mut cut = |edge: Edge, i: i64, j: i64, t: usize| self.cut_at(edge, i, j, t);
        let (level, t) = mip_level(footprint, self.model.levels.len());
        if footprint > 1.0 && (level > 0 || t > 0.0) {
            let mut a = [0.0f32; 4];
            self.model.sample_level(x, y, level, &mut pick, &mut a);
            if t > 0.0 {
                let mut b = [0.0f32; 4];
                self.model.sample_level(x, y, level + 1, &mut pick, &mut b);
                for k in 0..c {
                    a[k] += t * (b[k] - a[k]);
                }
            }
            out[..c].copy_from_slice(&a[..c]);
            return;
        }
        // SAFETY: in_range bounds both coordinates by 2⁵².
        let ((ix, fx), (iy, fy)) = unsafe { (floor_split(x), floor_split(y)) };
        if fx == 0.0 && fy == 0.0 {
            self.model.pixel(ix, iy, &mut pick, &mut cut, out);
            return;
        }
        let mut v = [[0.0f32; 4]; 4];
        for (k, (dx, dy)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
            self.model
                .pixel(ix + dx, iy + dy, &mut pick, &mut cut, &mut v[k]);
        }
        let (fx, fy) = (fx as f32, fy as f32);
        for k in 0..c {
            let top = v[0][k] + fx * (v[1][k] - v[0][k]);
            let bottom = v[2][k] + fx * (v[3][k] - v[2][k]);
            out[k] = top + fy * (bottom - top);
        }
    }

    fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        let Some((x0, y0)) = Self::pixel_aligned(region) else {
            return fill_rows_by_sample(self, region, rows, out);
        };
        if rows.is_empty() {
            return;
        }
        let m = &self.model;
        let xr = self.block_range_x(x0, x0 + region.width as i64 - 1);
        let yr = m.block_range(y0 + rows.start as i64, y0 + rows.end as i64 - 1);
        let blocks = self.picks(xr, yr, 1);
        let cuts = self.cuts(&blocks, 1);
        self.compose_rows(&blocks, &cuts, (x0, y0), region.width, rows, out);
    }

    fn fill(&self, region: &Region, out: &mut [f32]) -> Result<()> {
        let threads = crate::stream::default_threads();
        let Some((x0, y0)) = Self::pixel_aligned(region) else {
            return crate::stream::fill_parallel(self, region, out, threads);
        };
        region.validate()?;
        let c = self.model.c;
        crate::stream::check_buffer(region, c, out)?;
        let m = &self.model;
        let xr = self.block_range_x(x0, x0 + region.width as i64 - 1);
        let yr = m.block_range(y0, y0 + region.height as i64 - 1);
        let blocks_n = (xr.1 - xr.0 + 1) as u128 * (yr.1 - yr.0 + 1) as u128;
        if blocks_n > 1 << 26 {
            return Err(Error::Limits(format!(
                "an RSGF fill over {blocks_n} blocks (at most 2^26)"
            )));
        }
        let blocks = self.picks(xr, yr, threads);
        let cuts = self.cuts(&blocks, threads);
        // Compose in bands of rows, on all threads.
        crate::stream::for_bands(region, c, out, threads, 16, |rows, chunk| {
            self.compose_rows(&blocks, &cuts, (x0, y0), region.width, rows, chunk)
        })
    }
}

/// The parameters of an RSGF bank, checked: one tile (the exemplar) with its halvings,
/// valid parameters that fit it, finite texels. `what` names the bank in errors.
pub fn check_bank(bank: &Bank, what: &str) -> Result<RsgfParams> {
    let h = &bank.header;
    let bad = |m: String| Err(Error::bank(what, m));
    let Record::Rsgf(section) = &h.record else {
        return bad(format!("a {} bank; expected the rsgf rule", h.rule()));
    };
    bank.validate(what)?;
    let params: RsgfParams = BankHeader::decode(section, "rsgf", what)?;
    // One tile, the exemplar, of 1 to 2^22 pixels: checked by `Bank::validate`.
    let [w, ht] = h.tile_size;
    params
        .validate()
        .and_then(|_| params.check_exemplar(w, ht))
        .map_err(|e| Error::bank(what, format!("parameters: {e}")))?;
    check_halvings(bank, what)?;
    Ok(params)
}

/// Checks that a bank holding its exemplar as one tile has 1 to 14 levels, each the
/// halving of the one before ([`mip_chain`]'s sizes), and no table (RSGF and quilting
/// banks). `what` names the bank in errors.
pub(crate) fn check_halvings(bank: &Bank, what: &str) -> Result<()> {
    let h = &bank.header;
    let bad = |m: String| Err(Error::bank(what, m));
    let [w, ht] = h.tile_size;
    if h.levels.is_empty() || h.levels.len() > 14 || h.lut_size() != 0 {
        return bad(format!(
            "{} levels and a table of {}; expected 1 to 14 levels and none",
            h.levels.len(),
            h.lut_size()
        ));
    }
    for (l, info) in h.levels.iter().enumerate() {
        let expected = [w >> l, ht >> l];
        if info.size != expected {
            return bad(format!(
                "level {l} is {:?}; expected {expected:?}",
                info.size
            ));
        }
    }
    Ok(())
}
