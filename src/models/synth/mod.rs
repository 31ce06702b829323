//! Parallel controllable texture synthesis (Lefebvre & Hoppe, SIGGRAPH 2005) with
//! appearance-space neighbourhoods (Lefebvre & Hoppe, SIGGRAPH 2006), as a lazy,
//! split-invariant [`Surface`].
//!
//! The synthesis does not store pixels but **exemplar coordinates** S_l(q), level by level,
//! coarse to fine; level l's grid has spacing h_l = 2^(n−1−l) output pixels (the finest,
//! l = n − 1, is the output grid). Each step is a pure function of positions:
//!
//! 1. **coarsest level**: S_0(q) is a hashed random coordinate, uniform over the exemplar
//!    (not corrected: it has no patch to grow from);
//! 2. **upsampling**: S_l(2p + Δ) = S_(l−1)(p) + h_l·Δ, Δ ∈ {0, 1}², plus, on the
//!    levels below the coarsest down to spacing 16 px (`jitter_levels`), a hashed jitter
//!    of up to `jitter`·h_l pixels per axis (2005, §3.1–3.2). On levels of spacing ≥ 2
//!    px, each pixel continues, per axis with probability `ragged`, the patch of the
//!    parent on its other side instead of its own ("ragged upsampling", ours):
//!    S_l(q) = S_(l−1)(p′) + h_l·(q − 2p′) with p′ that neighbouring parent. So patch
//!    edges move by a level's spacing at every level instead of staying on the coarse
//!    levels' grid;
//! 3. **correction**, on levels of spacing ≤ 16 px (`CORRECT_MAX_SPACING`): `passes`
//!    times (`fine_passes` on the two finest), in four sub-passes over the 2×2 parities of q, each
//!    pixel takes the k-coherence candidate (2005, §3.3; the candidate sets are baked) whose
//!    exemplar neighbourhood best matches its own, candidates that continue a
//!    neighbour's patch favoured by the factor `coherence`. Neighbourhoods are the
//!    appearance vectors (PCA-reduced 5×5 Gaussian-stack windows; 2006, §3) of the 8
//!    neighbours.
//!
//! Where the 2005/2006 papers differ (one starting coordinate, 4 diagonal neighbours,
//! jitter at every level, no coherence bias), the structure figures
//! ([`crate::stats::structure`]) chose: those settings left pixel-scale seams and drifted
//! to the exemplar's blandest, most central pixels (coherence 0.69–0.75 against
//! texture-synthesis's 0.30 on the gravel photo, standard deviation −20%).
//!
//! A sub-pass reads only the eight neighbours of a pixel, so a region's pixels depend on
//! the previous level within a margin of 4·passes pixels (one more on a ragged level,
//! whose pixels read the parents beside their own), and so on up: a region filled
//! with its margins equals those pixels of the infinite texture bit for bit, in any split
//! and on any thread count. The output is the exemplar's value at the final coordinates,
//! so heights stay in their unit and colours stay exact. Zoomed-out regions (step ≥ 2)
//! stop at a coarser level and read its Gaussian-stack values.

mod build;

pub use build::synth_model;

use std::ops::Range;

use serde::{Deserialize, Serialize};

use crate::bank::{Bank, BankHeader, Record};
use crate::error::{Error, Result};
use crate::hash::hash_cell;
use crate::stream::{Region, Surface, check_buffer, default_threads, floor_split, in_range};

/// Synthesis parameters (stored in the bank header).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SynthParams {
    /// Synthesis levels n; the coarsest has spacing 2^(n−1) px. Default: the most the
    /// exemplar admits ([`SynthParams::max_levels`]).
    pub levels: usize,
    /// Candidates per exemplar pixel and level (k-coherence; the pixel itself first).
    /// Default 4; 1 to 16.
    pub k: usize,
    /// Correction passes per level, the coarsest and the [`FINE_LEVELS`] finest
    /// excepted. Default 4; 0 to 8.
    pub passes: usize,
    /// Correction passes on the [`FINE_LEVELS`] finest levels. Default 1; 0 to 8.
    #[serde(default = "default_fine_passes")]
    pub fine_passes: usize,
    /// Jitter added at upsampling, as a fraction of the level's spacing. Default 0.5;
    /// 0 to 1.
    pub jitter: f64,
    /// Dimensions of the appearance vectors. Default 8; 1 to 32, at most 25 × channels.
    pub appearance_dims: usize,
    /// Coherence bias κ (Ashikhmin 2001; Lefebvre & Hoppe 2005, §3.3): a candidate that
    /// continues a neighbour's patch has its neighbourhood distance multiplied by κ.
    /// Default 0.5; above 0, at most 1 (1: no bias).
    #[serde(default = "default_coherence")]
    pub coherence: f64,
    /// Levels below the coarsest whose upsampling adds jitter; 0 (the default): those
    /// of spacing ≥ [`JITTER_MIN_SPACING`], at least one ([`SynthParams::jittered`]).
    /// 0 to 12. (No jitter at all: `jitter` 0.)
    #[serde(default)]
    pub jitter_levels: usize,
    /// Ragged upsampling: the probability, per axis and pixel of a level of spacing ≥
    /// [`RAGGED_MIN_SPACING`], that the pixel continues the patch of its neighbouring
    /// parent instead of its own. Default 0.5; 0 to 0.5 (0: Lefebvre & Hoppe's
    /// upsampling, and what banks baked before it read as).
    #[serde(default)]
    pub ragged: f64,
}

/// The finest spacing ragged upsampling reaches. Ragged at spacing 1 too, the
/// one-pixel steps it leaves along patch edges survive the finest level's single
/// correction pass: coherence 0.257 against 0.254 on gravel, 0.398 against 0.391 on
/// brick (1024², seed 0).
pub const RAGGED_MIN_SPACING: i32 = 2;

/// The finest spacing the default jitter reaches. Patches then stay below about twice
/// that, so 32 × 32 windows of the output rarely copy an exemplar window whole, while
/// the correction still has whole objects to join: on gravel at 1024², jitter down to
/// spacing 32 left coherent patches that repeat (self-repetition 0.164); down to 8, a
/// small exemplar's objects break (rocks, 80 px: coherence 0.56 against 0.42).
pub const JITTER_MIN_SPACING: i32 = 16;

fn default_coherence() -> f64 {
    0.5
}

fn default_fine_passes() -> usize {
    1
}

impl Default for SynthParams {
    fn default() -> Self {
        SynthParams {
            levels: 0,
            k: 4,
            passes: 4,
            fine_passes: default_fine_passes(),
            jitter: 0.5,
            appearance_dims: 8,
            coherence: default_coherence(),
            jitter_levels: 0,
            ragged: 0.5,
        }
    }
}

/// The coarsest spacing that is corrected. Above it, the levels only place random
/// exemplar pieces (jittered); from it down, the corrections join them. At coarser
/// spacings the neighbourhoods see only the blurred stack's low frequencies, which on a
/// stationary texture are noise: matching them pulls every patch to a few regions of
/// the exemplar (gravel at 1024²: the 32 px blocks of the exemplar used under a quarter
/// of the mean went from 17 to 29 of 64, completeness 0.253 → 0.312, when spacing 32
/// was corrected too).
pub const CORRECT_MAX_SPACING: i32 = 16;

/// The finest levels, which get `fine_passes` correction passes.
pub const FINE_LEVELS: usize = 2;

/// Exemplar sides below this are refused.
pub const MIN_EXEMPLAR_SIDE: usize = 16;

impl SynthParams {
    /// The default number of levels for a `w × h` exemplar: the most it admits
    /// ([`SynthParams::max_levels`]); the coarser the start, the larger the features
    /// the synthesis can keep whole.
    pub fn default_levels(w: usize, h: usize) -> usize {
        Self::max_levels(w, h)
    }

    /// Pixels the neighbourhood of the coarsest corrected level spans at coarsest
    /// spacing h₀: that level's spacing is h₀/2, and a 5×5 appearance window around each
    /// of the 3×3 neighbours covers 7 samples h₀/2 apart, 3·h₀ + 1 pixels.
    fn span(h0: usize) -> usize {
        3 * h0 + 1
    }

    /// How many levels below the coarsest get jitter in an `n`-level synthesis.
    pub fn jittered(&self, n: usize) -> usize {
        if self.jitter_levels > 0 {
            return self.jitter_levels;
        }
        let by_spacing = (1..n)
            .take_while(|&l| (1i32 << (n - 1 - l)) >= JITTER_MIN_SPACING)
            .count();
        by_spacing.max(1)
    }

    /// One line for bake progress and `info`: levels, candidates, passes, jitter,
    /// coherence and appearance dimensions.
    pub fn describe(&self) -> String {
        format!(
            "{} levels (coarsest spacing {} px), k = {}, {} passes ({} on the finest), jitter {} on {} levels, ragged {}, coherence {}, {}-d appearance",
            self.levels,
            1usize << self.levels.saturating_sub(1),
            self.k,
            self.passes,
            self.fine_passes,
            self.jitter,
            self.jittered(self.levels),
            self.ragged,
            self.coherence,
            self.appearance_dims
        )
    }

    /// Checks the ranges (not the exemplar).
    pub fn validate(&self) -> Result<()> {
        if !(1..=12).contains(&self.levels) {
            return Err(Error::param(
                "levels",
                self.levels,
                "1 to 12 synthesis levels",
            ));
        }
        if !(1..=16).contains(&self.k) {
            return Err(Error::param("k", self.k, "1 to 16 candidates per pixel"));
        }
        if self.passes > 8 {
            return Err(Error::param(
                "passes",
                self.passes,
                "0 to 8 correction passes per level",
            ));
        }
        if self.fine_passes > 8 {
            return Err(Error::param(
                "fine passes",
                self.fine_passes,
                "0 to 8 correction passes on the finest levels",
            ));
        }
        if !(self.jitter.is_finite() && (0.0..=1.0).contains(&self.jitter)) {
            return Err(Error::param(
                "jitter",
                self.jitter,
                "a fraction from 0 to 1 of a level's spacing",
            ));
        }
        if !(self.coherence.is_finite() && self.coherence > 0.0 && self.coherence <= 1.0) {
            return Err(Error::param(
                "coherence",
                self.coherence,
                "a distance factor above 0 and at most 1",
            ));
        }
        if !(self.ragged.is_finite() && (0.0..=0.5).contains(&self.ragged)) {
            return Err(Error::param(
                "ragged",
                self.ragged,
                "a probability from 0 to 0.5 of continuing the neighbouring parent's patch",
            ));
        }
        if self.jitter_levels > 12 {
            return Err(Error::param(
                "jitter levels",
                self.jitter_levels,
                "0 to 12 levels (those beyond the finest are ignored)",
            ));
        }
        if !(1..=32).contains(&self.appearance_dims) {
            return Err(Error::param(
                "appearance dimensions",
                self.appearance_dims,
                "1 to 32",
            ));
        }
        Ok(())
    }

    /// Checks that a `w × h × c` exemplar holds the coarsest neighbourhood
    /// (3·h₀ + 1 ≤ min(w, h); see `span`).
    pub fn check_exemplar(&self, w: usize, h: usize, c: usize) -> Result<()> {
        if w < MIN_EXEMPLAR_SIDE || h < MIN_EXEMPLAR_SIDE {
            return Err(Error::param(
                "exemplar size",
                format!("{w}×{h}"),
                format!("at least {MIN_EXEMPLAR_SIDE}×{MIN_EXEMPLAR_SIDE} pixels for synthesis"),
            ));
        }
        let h0 = 1usize << (self.levels - 1);
        if Self::span(h0) > w.min(h) {
            return Err(Error::param(
                "levels",
                self.levels,
                format!(
                    "at most {} for a {w}×{h} exemplar: the coarsest neighbourhood spans 3·{h0} + 1 = {} px",
                    Self::max_levels(w, h),
                    Self::span(h0)
                ),
            ));
        }
        if self.appearance_dims > 25 * c {
            return Err(Error::param(
                "appearance dimensions",
                self.appearance_dims,
                format!("at most 25 × {c} channels = {}", 25 * c),
            ));
        }
        Ok(())
    }

    /// The most levels a `w × h` exemplar admits (3·h₀ + 1 ≤ min side), at most 12.
    pub fn max_levels(w: usize, h: usize) -> usize {
        let side = w.min(h);
        let mut levels = 1;
        while Self::span(1 << levels) <= side && levels < 12 {
            levels += 1;
        }
        levels
    }

    /// f32 values the bank stores per exemplar pixel and level: the stack's channels,
    /// the appearance vector and the candidates.
    pub fn values_per_pixel(&self, channels: usize) -> usize {
        channels + self.appearance_dims + self.k
    }
}

/// One synthesis level's tables over the exemplar's pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthLevel {
    /// Spacing h_l in pixels.
    pub spacing: i32,
    /// The Gaussian stack at this level, `w × h × channels`.
    pub stack: Vec<f32>,
    /// Appearance vectors, `w × h × dims`.
    pub appearance: Vec<f32>,
    /// k-coherence candidates per pixel (linear indices y·w + x), `w × h × k`; the
    /// pixel itself first.
    pub candidates: Vec<u32>,
}

/// The baked synthesis: exemplar size, parameters and per-level tables.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthModel {
    /// Exemplar width.
    pub w: usize,
    /// Exemplar height.
    pub h: usize,
    /// Channels.
    pub channels: usize,
    /// Parameters.
    pub params: SynthParams,
    /// Levels, coarsest first.
    pub levels: Vec<SynthLevel>,
}

/// A rectangle of a level's grid, [x0, x0 + w) × [y0, y0 + h).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Rect {
    x0: i64,
    y0: i64,
    w: usize,
    h: usize,
}

impl Rect {
    fn grow(self, m: usize) -> Rect {
        Rect {
            x0: self.x0 - m as i64,
            y0: self.y0 - m as i64,
            w: self.w + 2 * m,
            h: self.h + 2 * m,
        }
    }

    /// The parent level's rectangle that holds every parent of this one's pixels.
    fn parent(self) -> Rect {
        let x0 = self.x0.div_euclid(2);
        let y0 = self.y0.div_euclid(2);
        let x1 = (self.x0 + self.w as i64 - 1).div_euclid(2);
        let y1 = (self.y0 + self.h as i64 - 1).div_euclid(2);
        Rect {
            x0,
            y0,
            w: (x1 - x0 + 1) as usize,
            h: (y1 - y0 + 1) as usize,
        }
    }
}

/// Exemplar coordinates over a rectangle of one level.
struct Grid {
    rect: Rect,
    coords: Vec<[i32; 2]>,
}

impl Grid {
    #[inline]
    fn at(&self, x: i64, y: i64) -> [i32; 2] {
        let i = (y - self.rect.y0) as usize * self.rect.w + (x - self.rect.x0) as usize;
        self.coords[i]
    }
}

/// The four sub-pass parities, in the order of Lefebvre & Hoppe 2005 (§3.3).
const SUBPASSES: [(i64, i64); 4] = [(0, 0), (1, 1), (0, 1), (1, 0)];
/// The neighbours whose appearance vectors form a pixel's neighbourhood: the 8 around
/// it (the 2006 paper's 4 diagonals, §5, left seams visible in our figures).
const NEIGHBOURS: [(i32, i32); 8] = [
    (-1, -1),
    (1, -1),
    (-1, 1),
    (1, 1),
    (0, -1),
    (-1, 0),
    (1, 0),
    (0, 1),
];
/// The order candidate sets are gathered in: the pixel's upper-left neighbour first
/// (its own coordinate continues that patch), then the rest of the 3 × 3 block.
const SCAN: [(i32, i32); 9] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (0, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];
/// Hash streams: one per level for the coarsest coordinates, the jitter and the ragged
/// upsampling's choice of parent.
const STREAM_COARSE: u32 = 0x5359_0000;
const STREAM_JITTER: u32 = 0x5359_1000;
const STREAM_RAGGED: u32 = 0x5359_2000;

impl SynthModel {
    /// The valid coordinate range of level `l`: [0, side − h_l], so that the h_l × h_l
    /// block of finest coordinates a level-l coordinate becomes stays inside the
    /// exemplar (neighbourhood reads beyond the border are clamped).
    #[inline]
    fn valid(&self, l: usize) -> ([i32; 2], [i32; 2]) {
        let m = self.levels[l].spacing;
        ([0, 0], [self.w as i32 - m, self.h as i32 - m])
    }

    #[inline]
    fn clamp(&self, l: usize, c: [i32; 2]) -> [i32; 2] {
        let (lo, hi) = self.valid(l);
        [c[0].clamp(lo[0], hi[0]), c[1].clamp(lo[1], hi[1])]
    }

    /// Correction passes at level `l`: none at the coarsest, whose random coordinates
    /// have no coherent patch to grow from, nor at spacings above
    /// [`CORRECT_MAX_SPACING`]; `fine_passes` on the [`FINE_LEVELS`] finest, `passes`
    /// between. The patches and their seams are settled on the coarser levels; the
    /// finest only align edges, and cost the most (on gravel at 1024², 4 passes there
    /// instead of 1 changed coherence by 0.002 and took 70% longer).
    fn passes_at(&self, l: usize) -> usize {
        if l == 0 || self.levels[l].spacing > CORRECT_MAX_SPACING {
            0
        } else if l + FINE_LEVELS >= self.levels.len() {
            self.params.fine_passes
        } else {
            self.params.passes
        }
    }

    /// The coordinates of level `l` over `rect`.
    fn level(&self, seed: u32, l: usize, rect: Rect) -> Grid {
        let need = rect.grow(self.passes_at(l) * SUBPASSES.len());
        let mut grid = if l == 0 {
            self.coarsest(seed, need)
        } else {
            // Ragged upsampling reads the parents one pixel beyond.
            let reach = if self.ragged_at(l) { 1 } else { 0 };
            let parent = self.level(seed, l - 1, need.grow(reach).parent());
            self.upsample(seed, l, &parent, need)
        };
        for _ in 0..self.passes_at(l) {
            for &parity in &SUBPASSES {
                let v = grid.rect;
                let inner = Rect {
                    x0: v.x0 + 1,
                    y0: v.y0 + 1,
                    w: v.w - 2,
                    h: v.h - 2,
                };
                grid = self.correct(l, &grid, inner, parity, true);
            }
        }
        debug_assert_eq!(grid.rect, rect);
        grid
    }

    /// The coarsest level: a hashed exemplar coordinate per pixel, uniform over the
    /// valid range, so every exemplar pixel is as likely to be used (Lefebvre & Hoppe
    /// start from one coordinate everywhere, which a non-periodic exemplar cannot
    /// continue; the first corrected level grows coherent patches from these seeds).
    fn coarsest(&self, seed: u32, rect: Rect) -> Grid {
        let (lo, hi) = self.valid(0);
        let room = [(hi[0] - lo[0] + 1) as u64, (hi[1] - lo[1] + 1) as u64];
        let mut coords = Vec::with_capacity(rect.w * rect.h);
        for y in rect.y0..rect.y0 + rect.h as i64 {
            for x in rect.x0..rect.x0 + rect.w as i64 {
                let r = hash_cell(seed, x, y, STREAM_COARSE);
                coords.push([
                    lo[0] + ((r[0] as u64 * room[0]) >> 32) as i32,
                    lo[1] + ((r[1] as u64 * room[1]) >> 32) as i32,
                ]);
            }
        }
        Grid { rect, coords }
    }

    /// Whether level `l` is upsampled raggedly (spacing ≥ [`RAGGED_MIN_SPACING`]).
    fn ragged_at(&self, l: usize) -> bool {
        l > 0 && self.params.ragged > 0.0 && self.levels[l].spacing >= RAGGED_MIN_SPACING
    }

    /// Level `l` from its parent grid (Lefebvre & Hoppe 2005, §3.1–3.2): each pixel
    /// q continues its parent p's patch, S(p) + h·(q − 2p), or with ragged upsampling,
    /// per axis with probability `ragged`, the patch of the parent on q's other side.
    /// A neighbouring patch whose continuation would leave the valid range is not
    /// taken: clamped, it would repeat the exemplar's edge column in streaks. Then the
    /// jitter, on the jittered levels.
    fn upsample(&self, seed: u32, l: usize, parent: &Grid, rect: Rect) -> Grid {
        let h = self.levels[l].spacing;
        // The probability as a 32-bit threshold (0.5 → 2^31).
        let ragged = if self.ragged_at(l) {
            (self.params.ragged * 4_294_967_296.0) as u64
        } else {
            0
        };
        let amplitude = if l <= self.params.jittered(self.levels.len()) {
            self.params.jitter * h as f64
        } else {
            0.0
        };
        let mut coords = Vec::with_capacity(rect.w * rect.h);
        for y in rect.y0..rect.y0 + rect.h as i64 {
            for x in rect.x0..rect.x0 + rect.w as i64 {
                let own = (x.div_euclid(2), y.div_euclid(2));
                let continued = |(px, py): (i64, i64)| {
                    let p = parent.at(px, py);
                    [
                        p[0] + h * (x - 2 * px) as i32,
                        p[1] + h * (y - 2 * py) as i32,
                    ]
                };
                let mut c = continued(own);
                if ragged > 0 {
                    let r = hash_cell(seed, x, y, STREAM_RAGGED + l as u32);
                    // The other parent is on the side of q's parity: left of an even q.
                    let other = |o: i64, q: i64, r: u32| match (r as u64) < ragged {
                        false => o,
                        true if q == 2 * o => o - 1,
                        true => o + 1,
                    };
                    let p = (other(own.0, x, r[0]), other(own.1, y, r[1]));
                    if p != own {
                        let e = continued(p);
                        if self.clamp(l, e) == e {
                            c = e;
                        }
                    }
                }
                if amplitude > 0.0 {
                    let r = hash_cell(seed, x, y, STREAM_JITTER + l as u32);
                    for a in 0..2 {
                        let u = r[a] as f64 / 4_294_967_296.0 * 2.0 - 1.0;
                        c[a] += (amplitude * u + 0.5).floor() as i32;
                    }
                }
                coords.push(self.clamp(l, c));
            }
        }
        Grid { rect, coords }
    }

    /// One sub-pass: the pixels of `parity` in `inner` take the candidate whose
    /// neighbourhood (the appearance vectors of the 8 neighbours) best matches theirs;
    /// the others keep their coordinates. Reads `grid` within one pixel of `inner`.
    ///
    /// Candidates are the k-coherence sets of the 8 neighbours and of the pixel itself,
    /// shifted back by the neighbour's offset (2005, §3.3); those continuing a
    /// neighbour's own patch have their distance scaled by κ. Duplicates are scored
    /// once, and a score stops as soon as it cannot win. With `skip_coherent`, a pixel
    /// whose 8 neighbours all continue its patch keeps its coordinate unscored: its
    /// own coordinate is the first candidate scored and matches exactly (distance 0),
    /// so the full search would keep it too (`coherent_pixels_are_skipped_exactly`).
    fn correct(
        &self,
        l: usize,
        grid: &Grid,
        inner: Rect,
        parity: (i64, i64),
        skip_coherent: bool,
    ) -> Grid {
        let level = &self.levels[l];
        let dims = self.params.appearance_dims;
        let k = self.params.k;
        let hs = level.spacing;
        let (w, eh) = (self.w as i32, self.h as i32);
        let (lo, hi) = self.valid(l);
        let kappa = self.params.coherence as f32;
        let appearance = |c: [i32; 2]| {
            let i = (c[1] * w + c[0]) as usize * dims;
            &level.appearance[i..i + dims]
        };
        let mut own = vec![0.0f32; NEIGHBOURS.len() * dims];
        let mut seen: Vec<([i32; 2], bool)> = Vec::with_capacity(9 * k);
        let mut coords = Vec::with_capacity(inner.w * inner.h);
        for y in inner.y0..inner.y0 + inner.h as i64 {
            for x in inner.x0..inner.x0 + inner.w as i64 {
                let here = grid.at(x, y);
                if (x.rem_euclid(2), y.rem_euclid(2)) != parity {
                    coords.push(here);
                    continue;
                }
                let coherent = NEIGHBOURS.iter().all(|&(dx, dy)| {
                    grid.at(x + dx as i64, y + dy as i64) == [here[0] + hs * dx, here[1] + hs * dy]
                });
                if coherent && skip_coherent {
                    coords.push(here);
                    continue;
                }
                for (n, &(dx, dy)) in NEIGHBOURS.iter().enumerate() {
                    let c = grid.at(x + dx as i64, y + dy as i64);
                    own[n * dims..(n + 1) * dims].copy_from_slice(appearance(c));
                }
                // Squared distance of candidate u's neighbourhood, or None once it
                // reaches `bound`.
                let score = |u: [i32; 2], bound: f32| {
                    let mut d = 0.0f32;
                    for (n, &(ex, ey)) in NEIGHBOURS.iter().enumerate() {
                        let a = appearance([
                            (u[0] + hs * ex).clamp(0, w - 1),
                            (u[1] + hs * ey).clamp(0, eh - 1),
                        ]);
                        d = add_squared_differences(d, &own[n * dims..(n + 1) * dims], a);
                        if d >= bound {
                            return None;
                        }
                    }
                    Some(d)
                };
                let mut best = (f32::INFINITY, here);
                seen.clear();
                for &(dx, dy) in &SCAN {
                    let v = grid.at(x + dx as i64, y + dy as i64);
                    let vi = (v[1] * w + v[0]) as usize;
                    for (j, &cand) in level.candidates[vi * k..(vi + 1) * k].iter().enumerate() {
                        let u = [
                            (cand % self.w as u32) as i32 - hs * dx,
                            (cand / self.w as u32) as i32 - hs * dy,
                        ];
                        if u[0] < lo[0] || u[1] < lo[1] || u[0] > hi[0] || u[1] > hi[1] {
                            continue;
                        }
                        // The first candidate is the neighbour itself: u continues
                        // its patch.
                        let continues = j == 0;
                        if seen.iter().any(|&(s, c)| s == u && (c || !continues)) {
                            continue;
                        }
                        seen.push((u, continues));
                        let factor = if continues { kappa } else { 1.0 };
                        if let Some(d) = score(u, best.0 / factor) {
                            best = (d * factor, u);
                        }
                    }
                }
                coords.push(best.1);
            }
        }
        Grid {
            rect: inner,
            coords,
        }
    }

    /// Values of level `l` over `rect` (its grid), `channels` per pixel, into `out`.
    fn values(&self, seed: u32, l: usize, rect: Rect, out: &mut [f32]) {
        let grid = self.level(seed, l, rect);
        let c = self.channels;
        let stack = &self.levels[l].stack;
        for (dst, s) in out.chunks_exact_mut(c).zip(&grid.coords) {
            let i = (s[1] as usize * self.w + s[0] as usize) * c;
            dst.copy_from_slice(&stack[i..i + c]);
        }
    }

    /// The level a footprint of `step` pixels reads: finest for step < 2, one coarser
    /// per doubling.
    fn level_for(&self, step: f64) -> usize {
        let top = self.levels.len() - 1;
        if step.is_nan() || step < 2.0 {
            return top;
        }
        let up = (step.log2().floor() as usize).min(top);
        top - up
    }
}

/// `d` plus the squared differences of `p` and `q`, added in order (the same bits for
/// every length); the default 8 dimensions unrolled, without bounds checks.
#[inline(always)]
fn add_squared_differences(mut d: f32, p: &[f32], q: &[f32]) -> f32 {
    if let (Ok(p), Ok(q)) = (<&[f32; 8]>::try_from(p), <&[f32; 8]>::try_from(q)) {
        for i in 0..8 {
            d += (p[i] - q[i]) * (p[i] - q[i]);
        }
        return d;
    }
    for (&a, &b) in p.iter().zip(q) {
        d += (a - b) * (a - b);
    }
    d
}

/// A surface synthesised from a synth bank ([`Rule::Synth`]) with a placement seed.
pub struct SynthSurface {
    model: SynthModel,
    seed: u32,
}

/// Side of the blocks a fill is cut into (level-grid pixels): large enough that the
/// margins cost little, small enough to spread over the cores.
const FILL_BLOCK: usize = 256;

impl SynthSurface {
    /// The surface of `bank` placed with `seed`.
    pub fn from_bank(bank: &Bank, seed: u32) -> Result<SynthSurface> {
        let params = check_bank(bank, "synth bank")?;
        let h = &bank.header;
        let [w, ht] = h.tile_size;
        let c = h.channels;
        let mut levels = Vec::with_capacity(params.levels);
        for (l, block) in bank.extra.iter().enumerate() {
            let n = w * ht;
            let (stack, rest) = block.split_at(n * c);
            let (appearance, candidates) = rest.split_at(n * params.appearance_dims);
            levels.push(SynthLevel {
                spacing: 1 << (params.levels - 1 - l),
                stack: stack.to_vec(),
                appearance: appearance.to_vec(),
                candidates: candidates.iter().map(|&v| v as u32).collect(),
            });
        }
        Ok(SynthSurface {
            model: SynthModel {
                w,
                h: ht,
                channels: c,
                params,
                levels,
            },
            seed,
        })
    }

    /// A surface straight from a model.
    pub fn new(model: SynthModel, seed: u32) -> SynthSurface {
        SynthSurface { model, seed }
    }

    /// The model.
    pub fn model(&self) -> &SynthModel {
        &self.model
    }

    /// Fills the level-grid rectangle `rect` of level `l` into `out`, in blocks on
    /// `threads` threads.
    fn fill_grid(&self, l: usize, rect: Rect, out: &mut [f32], threads: usize) {
        let c = self.model.channels;
        let bands: Vec<(usize, &mut [f32])> = out
            .chunks_mut(FILL_BLOCK * rect.w * c)
            .enumerate()
            .collect();
        let work = |(b, chunk): (usize, &mut [f32])| {
            let rows = chunk.len() / (rect.w * c);
            let mut buf = Vec::new();
            for bx in (0..rect.w).step_by(FILL_BLOCK) {
                let bw = FILL_BLOCK.min(rect.w - bx);
                let sub = Rect {
                    x0: rect.x0 + bx as i64,
                    y0: rect.y0 + (b * FILL_BLOCK) as i64,
                    w: bw,
                    h: rows,
                };
                buf.resize(bw * rows * c, 0.0);
                self.model.values(self.seed, l, sub, &mut buf);
                for r in 0..rows {
                    chunk[(r * rect.w + bx) * c..(r * rect.w + bx + bw) * c]
                        .copy_from_slice(&buf[r * bw * c..(r + 1) * bw * c]);
                }
            }
        };
        let threads = threads.clamp(1, bands.len().max(1));
        if threads == 1 {
            bands.into_iter().for_each(work);
            return;
        }
        let queue = crossbeam::queue::ArrayQueue::new(bands.len());
        for band in bands {
            let _ = queue.push(band);
        }
        let _ = crossbeam::scope(|s| {
            for _ in 0..threads {
                s.spawn(|_| {
                    while let Some(band) = queue.pop() {
                        work(band);
                    }
                });
            }
        });
    }

    /// Fills `region` on `threads` threads: integer-aligned step-1 regions straight
    /// from the finest level's grid; others bilinearly from the grid of the level their
    /// step reads, over the rectangle that covers them.
    pub fn fill_threads(&self, region: &Region, out: &mut [f32], threads: usize) -> Result<()> {
        region.validate()?;
        let c = self.model.channels;
        check_buffer(region, c, out)?;
        let (x0, y0) = (region.x_at(0), region.y_at(0));
        if region.step == 1.0 && x0.fract() == 0.0 && y0.fract() == 0.0 {
            let top = self.model.levels.len() - 1;
            let rect = Rect {
                x0: x0 as i64,
                y0: y0 as i64,
                w: region.width,
                h: region.height,
            };
            self.fill_grid(top, rect, out, threads);
            return Ok(());
        }
        let l = self.model.level_for(region.step);
        let spacing = self.model.levels[l].spacing as f64;
        let (x1, y1) = (
            region.x_at(region.width - 1),
            region.y_at(region.height - 1),
        );
        let gx0 = (x0.min(x1) / spacing).floor() as i64;
        let gy0 = (y0.min(y1) / spacing).floor() as i64;
        let gx1 = (x0.max(x1) / spacing).floor() as i64 + 1;
        let gy1 = (y0.max(y1) / spacing).floor() as i64 + 1;
        let (gw, gh) = ((gx1 - gx0 + 1) as usize, (gy1 - gy0 + 1) as usize);
        if gw.saturating_mul(gh) > 1 << 28 {
            return Err(Error::Limits(format!(
                "a synth region covering {gw}×{gh} grid pixels at level {l}"
            )));
        }
        let rect = Rect {
            x0: gx0,
            y0: gy0,
            w: gw,
            h: gh,
        };
        let mut grid = vec![0.0f32; gw * gh * c];
        self.fill_grid(l, rect, &mut grid, threads);
        for row in 0..region.height {
            let gy = region.y_at(row) / spacing;
            for col in 0..region.width {
                let gx = region.x_at(col) / spacing;
                let at = (row * region.width + col) * c;
                bilinear(&grid, rect, c, gx, gy, &mut out[at..at + c]);
            }
        }
        Ok(())
    }
}

/// Bilinear interpolation of a level grid at level coordinates (gx, gy), which the
/// grid's rectangle covers with its right and bottom neighbours.
fn bilinear(grid: &[f32], rect: Rect, c: usize, gx: f64, gy: f64, out: &mut [f32]) {
    // SAFETY: gx, gy are finite and far inside the i64 range (checked coordinates over a
    // spacing of at least 1).
    let ((ix, fx), (iy, fy)) = unsafe { (floor_split(gx), floor_split(gy)) };
    let (fx, fy) = (fx as f32, fy as f32);
    let (cx, cy) = ((ix - rect.x0) as usize, (iy - rect.y0) as usize);
    let cx1 = (cx + 1).min(rect.w - 1);
    let cy1 = (cy + 1).min(rect.h - 1);
    for (k, o) in out.iter_mut().enumerate() {
        let v = |x: usize, y: usize| grid[(y * rect.w + x) * c + k];
        let top = v(cx, cy) + (v(cx1, cy) - v(cx, cy)) * fx;
        let bottom = v(cx, cy1) + (v(cx1, cy1) - v(cx, cy1)) * fx;
        *o = top + (bottom - top) * fy;
    }
}

impl Surface for SynthSurface {
    fn channels(&self) -> usize {
        self.model.channels
    }

    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        let c = self.model.channels;
        if !in_range(x, y) || out.len() < c {
            out.iter_mut().for_each(|v| *v = f32::NAN);
            return;
        }
        let l = self.model.level_for(footprint);
        let spacing = self.model.levels[l].spacing as f64;
        let (gx, gy) = (x / spacing, y / spacing);
        let rect = Rect {
            x0: gx.floor() as i64,
            y0: gy.floor() as i64,
            w: 2,
            h: 2,
        };
        let mut grid = [0.0f32; 16];
        self.model.values(self.seed, l, rect, &mut grid[..4 * c]);
        bilinear(&grid[..4 * c], rect, c, gx, gy, &mut out[..c]);
    }

    fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        let sub = Region {
            row0: region.row0 + rows.start as i64,
            height: rows.len(),
            ..*region
        };
        if self.fill_threads(&sub, out, 1).is_err() {
            out.iter_mut().for_each(|v| *v = f32::NAN);
        }
    }

    fn fill(&self, region: &Region, out: &mut [f32]) -> Result<()> {
        self.fill_threads(region, out, default_threads())
    }
}

/// The parameters of a synth bank, checked: one tile (the exemplar), parameters that
/// fit it, one table block per level of the right length, finite values, candidate
/// indices that are whole numbers inside the exemplar. `what` names the bank in errors.
pub fn check_bank(bank: &Bank, what: &str) -> Result<SynthParams> {
    let h = &bank.header;
    let bad = |m: String| Err(Error::bank(what, m));
    let Record::Synth(section) = &h.record else {
        return bad(format!("a {} bank; expected a synth bank", h.rule()));
    };
    bank.validate(what)?;
    let params: SynthParams = BankHeader::decode(section, "synth", what)?;
    // One tile, the exemplar, of 1 to 2^22 pixels: checked by `Bank::validate`.
    let [w, ht] = h.tile_size;
    params
        .validate()
        .and_then(|_| params.check_exemplar(w, ht, h.channels))
        .map_err(|e| Error::bank(what, format!("parameters: {e}")))?;
    if h.levels.len() != 1 || h.levels[0].size != [w, ht] || h.lut_size() != 0 {
        return bad("synth layout: expected the exemplar as one level and no table".into());
    }
    if bank.extra.len() != params.levels {
        return bad(format!(
            "{} table blocks; expected one per synthesis level ({})",
            bank.extra.len(),
            params.levels
        ));
    }
    let per = params.values_per_pixel(h.channels);
    let values = (h.channels + params.appearance_dims) * w * ht;
    for (l, block) in bank.extra.iter().enumerate() {
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
    Ok(params)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::synth::synth_model;
    use crate::raster::Raster;

    /// A smooth two-tone exemplar with features at several scales.
    fn exemplar() -> Raster {
        let (w, h) = (64, 48);
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                (x * 0.37).sin() * (y * 0.23).cos() + (x * 0.05 + y * 0.11).sin()
            })
            .collect();
        Raster::from_vec(w, h, 1, data).unwrap()
    }

    /// A grid of level `l` over `rect` made of `patch` × `patch` blocks (from the
    /// rectangle's corner), each continuing one coordinate drawn below `room` per axis
    /// by a linear congruential generator seeded with `seed`; clamped to the valid range.
    fn patch_grid(
        model: &SynthModel,
        l: usize,
        rect: Rect,
        patch: i32,
        room: [i32; 2],
        seed: u64,
    ) -> Grid {
        let mut state = seed;
        let mut next = |n: i32| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) % n as u64) as i32
        };
        let across = (rect.w as i32 + patch - 1) / patch;
        let down = (rect.h as i32 + patch - 1) / patch;
        let origins: Vec<[i32; 2]> = (0..across * down)
            .map(|_| [next(room[0]), next(room[1])])
            .collect();
        let hs = model.levels[l].spacing;
        let coords = (0..rect.w * rect.h)
            .map(|i| {
                let (x, y) = ((i % rect.w) as i32, (i / rect.w) as i32);
                let o = origins[((y / patch) * across + x / patch) as usize];
                model.clamp(l, [o[0] + hs * (x % patch), o[1] + hs * (y % patch)])
            })
            .collect();
        Grid { rect, coords }
    }

    /// Ragged upsampling is the plain upsampling inside a parent patch, and at a patch
    /// edge each pixel continues one of its nearest parents (its own, or the one on its
    /// other side per axis), within the valid range. At probability 0.5 per axis, 25%
    /// and 30% of the pixels next to a patch edge take another patch here (asserted:
    /// 20–60%).
    #[test]
    fn ragged_upsampling_moves_only_patch_edges() {
        let params = SynthParams {
            jitter: 0.0,
            ..SynthParams::default()
        };
        let model = synth_model(&exemplar(), &params).unwrap();
        let plain = SynthModel {
            params: SynthParams {
                ragged: 0.0,
                ..params.clone()
            },
            ..model.clone()
        };
        const PATCH: i32 = 4;
        let mut tested = 0;
        for l in 1..model.levels.len() {
            if !model.ragged_at(l) {
                continue;
            }
            let (h, hp) = (model.levels[l].spacing, model.levels[l - 1].spacing);
            let (_, hi) = model.valid(l - 1);
            let prect = Rect {
                x0: -8,
                y0: 4,
                w: 24,
                h: 18,
            };
            // Whole patches inside the valid range, so none is clamped.
            let room = [hi[0] - hp * (PATCH - 1) + 1, hi[1] - hp * (PATCH - 1) + 1];
            let parent = patch_grid(&model, l - 1, prect, PATCH, room, 777 + l as u64);
            let patch = |px: i64, py: i64| {
                let (i, j) = ((px - prect.x0) as i32, (py - prect.y0) as i32);
                (j / PATCH, i / PATCH)
            };
            let rect = Rect {
                x0: -14,
                y0: 10,
                w: 40,
                h: 30,
            };
            let rag = model.upsample(3, l, &parent, rect);
            let flat = plain.upsample(3, l, &parent, rect);
            let (mut edge, mut moved) = (0, 0);
            for y in rect.y0..rect.y0 + rect.h as i64 {
                for x in rect.x0..rect.x0 + rect.w as i64 {
                    let (r, f) = (rag.at(x, y), flat.at(x, y));
                    let (ox, oy) = (x.div_euclid(2), y.div_euclid(2));
                    let near = [(ox - 1, ox + 1), (oy - 1, oy + 1)];
                    let inside = (near[1].0..=near[1].1)
                        .all(|py| (near[0].0..=near[0].1).all(|px| patch(px, py) == patch(ox, oy)));
                    if inside {
                        assert_eq!(r, f, "level {l} at ({x}, {y}), inside a patch");
                        continue;
                    }
                    edge += 1;
                    let other = |o: i64, q: i64| if q == 2 * o { o - 1 } else { o + 1 };
                    let mut allowed: Vec<[i32; 2]> = [ox, other(ox, x)]
                        .iter()
                        .flat_map(|&px| [oy, other(oy, y)].map(|py| (px, py)))
                        .map(|(px, py)| {
                            let p = parent.at(px, py);
                            [
                                p[0] + h * (x - 2 * px) as i32,
                                p[1] + h * (y - 2 * py) as i32,
                            ]
                        })
                        .filter(|&e| model.clamp(l, e) == e)
                        .collect();
                    // Its own patch, clamped.
                    allowed.push(f);
                    assert!(allowed.contains(&r), "level {l} at ({x}, {y}): {r:?}");
                    moved += usize::from(r != f);
                }
            }
            let share = moved as f64 / edge as f64;
            println!("level {l}: {moved} of {edge} edge pixels moved");
            assert!((0.2..0.6).contains(&share), "level {l}: {moved} of {edge}");
            tested += 1;
        }
        assert!(tested >= 2);
    }

    /// Skipping pixels whose 8 neighbours continue their patch changes nothing: on
    /// random grids with coherent islands, every sub-pass at every level gives the
    /// same coordinates as the full search.
    #[test]
    fn coherent_pixels_are_skipped_exactly() {
        let model = synth_model(&exemplar(), &SynthParams::default()).unwrap();
        let mut skipped = 0usize;
        for l in 1..model.levels.len() {
            let (lo, hi) = model.valid(l);
            let rect = Rect {
                x0: -5,
                y0: 7,
                w: 20,
                h: 16,
            };
            // Patches of 5×5 pixels, each continuing one random coordinate.
            let room = [hi[0] - lo[0] + 1, hi[1] - lo[1] + 1];
            let grid = patch_grid(&model, l, rect, 5, room, 12345 + l as u64);
            let inner = Rect {
                x0: -4,
                y0: 8,
                w: 18,
                h: 14,
            };
            for &parity in &SUBPASSES {
                let fast = model.correct(l, &grid, inner, parity, true);
                let full = model.correct(l, &grid, inner, parity, false);
                assert_eq!(fast.coords, full.coords, "level {l}, parity {parity:?}");
            }
            skipped += 1;
        }
        assert!(skipped >= 2);
    }
}
