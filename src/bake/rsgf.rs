//! Baking an RSGF bank (seed 002): the lattice (estimated by §3.3, given, or the
//! stochastic unit lattice), the synthesis parameters checked against the exemplar, and
//! the exemplar itself with its mip chain. The synthesis runs lazily at sampling time
//! ([`crate::models::rsgf::RsgfSurface`]).

use crate::analysis::ncc::autocorrelation;
use crate::analysis::translation::{
    BAKE_WITHOUT_LATTICE, MIN_MEAN_GAMMA, best_pair, no_lattice, ridge_notes,
};
use crate::bank::{Bank, BankHeader, ExemplarInfo, LevelInfo, Method, Record};
use crate::error::Result;
use crate::models::rsgf::{
    DEFAULT_FEATHER, Edges, Join, Metric, RsgfModel, RsgfParams, RsgfSurface, mip_chain, wrap_fits,
};
use crate::raster::Raster;
use crate::stream::{Region, Surface};

/// What the user asked for; the lattice is resolved by `bake`.
#[derive(Clone, Debug, PartialEq)]
pub struct RsgfOptions {
    /// Block side B in pixels. None: [`DEFAULT_BLOCK`] on a lattice; in stochastic
    /// mode, scaled to the exemplar's object scale ([`stochastic_block`]), with the
    /// border, unless one of the two is given.
    pub block_px: Option<usize>,
    /// Border o in pixels. None: [`DEFAULT_BORDER`], or scaled with the block.
    pub border_px: Option<usize>,
    /// Gap-candidate tolerance in pixels (default 3).
    pub tolerance_px: usize,
    /// Border measure; default NCC in stochastic mode, SSD on a lattice (the paper's):
    /// see [`RsgfParams::stochastic`].
    pub metric: Option<Metric>,
    /// How patches join (default: minimum-error cuts).
    pub join: Join,
    /// Ramp half-width around a cut in pixels. None: [`DEFAULT_FEATHER`] on a lattice;
    /// in stochastic mode, from the exemplar's roughness at the pixel scale
    /// ([`stochastic_feather`]).
    pub feather_px: Option<usize>,
    /// Stochastic mode: v₁ = (1, 0), v₂ = (0, 1), no estimation.
    pub stochastic: bool,
    /// In stochastic mode, map output values so that their histogram is the exemplar's
    /// ([`histogram_map`]; default off: it costs coherence).
    pub histogram: bool,
    /// In stochastic mode, how patches meet the exemplar's edges (default: reflected,
    /// or wrapped where the exemplar's [`coverage_bias`] says they may wrap and the
    /// bake's [`EdgeTrial`] agrees).
    pub edges: Edges,
    /// In stochastic mode with neither block nor border given: the window within which
    /// self-repetition should stay within [`REPEAT_BAR`]; the scaled block is capped
    /// at [`repeat_block`] for it. Default: issue 31's [`DEFAULT_REPEAT_WINDOW`]²
    /// (docs/structure.md, "Block size against self-repetition").
    pub repeat_window: RepeatWindow,
}

/// The window a stochastic bank's scaled block keeps its self-repetition within
/// ([`RsgfOptions::repeat_window`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RepeatWindow {
    /// [`DEFAULT_REPEAT_WINDOW`]², where the block is scaled (stochastic, neither
    /// block nor border given); nothing otherwise.
    #[default]
    Auto,
    /// No cap: the block follows the exemplar's objects alone, however often a window
    /// then shows them again.
    Off,
    /// An N² window, asked for: refused with a block or border given, without
    /// `stochastic` (unless the method is `auto`), or under the 32-px patch
    /// self-repetition compares.
    Side(usize),
}

impl RepeatWindow {
    /// The window's side, where it caps a scaled block.
    pub fn side(self) -> Option<usize> {
        match self {
            RepeatWindow::Auto => Some(DEFAULT_REPEAT_WINDOW),
            RepeatWindow::Off => None,
            RepeatWindow::Side(n) => Some(n),
        }
    }
}

impl std::fmt::Display for RepeatWindow {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RepeatWindow::Auto => f.write_str("auto"),
            RepeatWindow::Off => f.write_str("off"),
            RepeatWindow::Side(n) => write!(f, "{n}"),
        }
    }
}

impl std::str::FromStr for RepeatWindow {
    type Err = String;
    fn from_str(text: &str) -> std::result::Result<RepeatWindow, String> {
        match text.trim() {
            "auto" => Ok(RepeatWindow::Auto),
            "off" => Ok(RepeatWindow::Off),
            t => t.parse().map(RepeatWindow::Side).map_err(|_| {
                format!("'{text}' is not a repeat window; expected auto, off or a side N in pixels")
            }),
        }
    }
}

impl Default for RsgfOptions {
    fn default() -> Self {
        let p = RsgfParams::stochastic();
        RsgfOptions {
            block_px: None,
            border_px: None,
            tolerance_px: p.tolerance_px,
            metric: None,
            join: p.join,
            feather_px: None,
            stochastic: false,
            histogram: false,
            edges: Edges::Auto,
            repeat_window: RepeatWindow::Auto,
        }
    }
}

impl RsgfOptions {
    /// The parameters on lattice (v1, v2), before the exemplar is known: a ramp not
    /// given is [`DEFAULT_FEATHER`] (kept below the border).
    pub fn params(&self, v1: (i64, i64), v2: (i64, i64)) -> RsgfParams {
        self.params_with(None, v1, v2)
    }

    /// The parameters on lattice (v1, v2) for exemplar `ex`, which sets the ramp of a
    /// stochastic bank when none is given ([`stochastic_feather`]).
    pub fn params_for(&self, ex: &Raster, v1: (i64, i64), v2: (i64, i64)) -> RsgfParams {
        self.params_with(Some(ex), v1, v2)
    }

    fn params_with(&self, ex: Option<&Raster>, v1: (i64, i64), v2: (i64, i64)) -> RsgfParams {
        let (block_px, border_px) = match (self.block_px, self.border_px, ex) {
            (None, None, Some(ex)) if self.stochastic => {
                let scale = stochastic_block_within(ex, self.repeat_window.side());
                (scale.block_px, scale.border_px)
            }
            (b, o, _) => (b.unwrap_or(DEFAULT_BLOCK), o.unwrap_or(DEFAULT_BORDER)),
        };
        let wrap = self.stochastic
            && match self.edges {
                Edges::Wrap => true,
                Edges::Reflect => false,
                Edges::Auto => ex.is_some_and(|ex| {
                    wrap_fits(ex.width, ex.height, block_px, border_px)
                        && coverage_bias(ex, block_px).misses_a_bar()
                }),
            };
        let feather_px = self.feather_px.unwrap_or_else(|| {
            let chosen = match ex {
                Some(ex) if self.stochastic && self.join == Join::Cut => stochastic_feather(ex),
                _ => DEFAULT_FEATHER,
            };
            // Below the border, as validation asks of a ramp that is given.
            chosen.min(border_px.saturating_sub(1))
        });
        RsgfParams {
            block_px,
            border_px,
            tolerance_px: self.tolerance_px,
            metric: self.metric.unwrap_or(if self.stochastic {
                RsgfParams::stochastic().metric
            } else {
                RsgfParams::new(v1, v2).metric
            }),
            join: self.join,
            feather_px,
            histogram: None,
            // A stochastic exemplar wraps where `edges` says so (auto, here: where
            // bounded positions would miss its histogram and it can wrap; `bake`
            // resolves auto by its `EdgeTrial` before it gets here); otherwise its
            // patches hang over mirrored edges, which only cuts keep out of the
            // output (a linear blend would show them across every overlap).
            reflect_edges: self.stochastic && self.join == Join::Cut && !wrap,
            wrap_edges: wrap,
            v1,
            v2,
        }
    }
}

/// Block side of a lattice bank, and the least of a stochastic one (the paper's).
pub const DEFAULT_BLOCK: usize = 40;
/// Border of a lattice bank (the paper's); a stochastic bank's is a quarter of its
/// block.
pub const DEFAULT_BORDER: usize = 10;
/// A stochastic bank's block side per pixel of the exemplar's object scale.
pub const BLOCK_PER_SCALE: f64 = 2.5;
/// The autocorrelation level whose radius [`object_scale`] reports.
pub const SCALE_ACF: f64 = 0.05;
/// Side of the centred crop whose object scale [`stochastic_block`] measures, at most.
const SCALE_SIDE: usize = 512;

/// A stochastic bank's block and border, and the figure they come from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockScale {
    /// The exemplar's object scale ([`object_scale`]), px.
    pub scale_px: f64,
    /// Block side B.
    pub block_px: usize,
    /// Border o = B / 4.
    pub border_px: usize,
    /// The cap [`repeat_block`] set for the window given, px (None: no window).
    pub repeat_cap_px: Option<usize>,
    /// The block without that cap.
    pub uncapped_px: usize,
}

/// The object scale of an exemplar: the first radius at which its autocorrelation
/// (unbiased, channels averaged, on the centred crop of at most 512², averaged over
/// directions) falls below [`SCALE_ACF`]; half the crop's shorter side if it never
/// does. Where the autocorrelation has decayed that far, pixels no longer belong to the
/// same object: 12 px for the 156-px stone-wall photo of `tests/data`, 52 px for the
/// same photo enlarged 4×. The usual correlation length (ISO 25178's Sal, at 0.2) sees
/// the grain inside the stones instead: 2.4 and 9.9 px.
pub fn object_scale(ex: &Raster) -> f64 {
    let (w, h, c) = (
        ex.width.min(SCALE_SIDE),
        ex.height.min(SCALE_SIDE),
        ex.channels,
    );
    let (x0, y0) = ((ex.width - w) / 2, (ex.height - h) / 2);
    let grey: Vec<f32> = (0..w * h)
        .map(|i| {
            let at = ((y0 + i / w) * ex.width + x0 + i % w) * c;
            ex.data[at..at + c].iter().sum::<f32>() / c as f32
        })
        .collect();
    let r_max = w.min(h) / 2;
    let Ok(grey) = Raster::from_vec(w, h, 1, grey) else {
        return r_max as f64;
    };
    let acf = crate::stats::Acf::new(&grey);
    // Rings of whole radii over the half plane of lags (the ACF is symmetric).
    let (mut sum, mut count) = (vec![0.0f64; r_max + 1], vec![0usize; r_max + 1]);
    let r = r_max as i64;
    for dy in 0..=r {
        for dx in -r..=r {
            let d = ((dx * dx + dy * dy) as f64).sqrt().round() as usize;
            if d <= r_max && (dy > 0 || dx >= 0) {
                sum[d] += acf.unbiased(dx, dy);
                count[d] += 1;
            }
        }
    }
    (1..=r_max)
        .find(|&d| sum[d] / (count[d].max(1) as f64) < SCALE_ACF)
        .unwrap_or(r_max) as f64
}

/// What the output's histogram would show of an exemplar if blocks were copied from
/// bounded positions ([`RsgfParams::reflect_edges`]): the exemplar weighted by how
/// often each of its pixels lies in a block, against the exemplar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoverageBias {
    /// Worst channel's W1 between the weighted and the plain histogram, over the
    /// channel's standard deviation (as `stats::wasserstein1_standardised`).
    pub w1: f64,
    /// The channel's weighted standard deviation over its plain one, for the channel
    /// farthest from 1.
    pub sd_ratio: f64,
}

/// The W1 bar of the structure figures (issue 31), which [`CoverageBias`] is held to.
pub const COVERAGE_W1_BAR: f64 = 0.05;
/// The standard-deviation bar (within 5%).
pub const COVERAGE_SD_BAR: f64 = 0.05;

impl CoverageBias {
    /// Whether the coverage alone misses the W1 or the standard-deviation bar: blocks
    /// may then wrap around the exemplar made periodic ([`RsgfParams::wrap_edges`]),
    /// where every pixel is shown about equally, if the bake's [`EdgeTrial`] agrees.
    pub fn misses_a_bar(&self) -> bool {
        self.w1 >= COVERAGE_W1_BAR || (self.sd_ratio - 1.0).abs() >= COVERAGE_SD_BAR
    }
}

/// The [`CoverageBias`] of `ex` under blocks of `block` px at bounded positions: a
/// block shows exemplar columns [p, p + B) for p in [0, W − B] (edges reflected by the
/// border, so the patch's border may hang over), so column x is shown by
/// min(x + 1, B, W − x, W − B + 1) of them, and pixel (x, y) by the product of its
/// column's and its row's counts. On the 100² dried-mud photo: W1 0.06 and 0.91 of
/// the standard deviation, which the output shows too (0.064 and 0.902 at 512²,
/// `docs/structure.md`); on the 256² scikit-image photos 0.006–0.012 and 1.00–1.02.
pub fn coverage_bias(ex: &Raster, block: usize) -> CoverageBias {
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    let count = |n: usize| -> Vec<f64> {
        let b = block.min(n);
        (0..n)
            .map(|x| (x + 1).min(b).min(n - x).min(n - b + 1) as f64)
            .collect()
    };
    let (cx, cy) = (count(w), count(h));
    let weights: Vec<f64> = (0..w * h).map(|i| cx[i % w] * cy[i / w]).collect();
    let total: f64 = weights.iter().sum();
    let mut out = CoverageBias {
        w1: 0.0,
        sd_ratio: 1.0,
    };
    for ch in 0..c {
        let v: Vec<f64> = (0..w * h).map(|i| ex.data[i * c + ch] as f64).collect();
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
        let (lo, hi) = v
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, u), &x| (l.min(x), u.max(x)));
        if sd.is_nan() || sd <= 0.0 || hi <= lo {
            continue;
        }
        let wmean = v.iter().zip(&weights).map(|(x, k)| x * k).sum::<f64>() / total;
        let wsd = (v
            .iter()
            .zip(&weights)
            .map(|(x, k)| k * (x - wmean).powi(2))
            .sum::<f64>()
            / total)
            .sqrt();
        // W1 from the two cumulative histograms on COVERAGE_BINS bins: O(N), within
        // one bin's width of the exact figure.
        let step = (hi - lo) / COVERAGE_BINS as f64;
        let (mut plain, mut weighted) = (vec![0.0; COVERAGE_BINS], vec![0.0; COVERAGE_BINS]);
        for (x, k) in v.iter().zip(&weights) {
            let bin = (((x - lo) / step) as usize).min(COVERAGE_BINS - 1);
            plain[bin] += 1.0 / n;
            weighted[bin] += k / total;
        }
        let (mut f, mut fw, mut w1) = (0.0, 0.0, 0.0);
        for (p, q) in plain.iter().zip(&weighted) {
            f += p;
            fw += q;
            w1 += (f - fw).abs() * step;
        }
        out.w1 = out.w1.max(w1 / sd);
        let ratio = wsd / sd;
        if (ratio - 1.0).abs() > (out.sd_ratio - 1.0).abs() {
            out.sd_ratio = ratio;
        }
    }
    out
}

/// Bins of [`coverage_bias`]'s histograms.
const COVERAGE_BINS: usize = 4096;

/// The block of a stochastic bank, scaled to the exemplar's objects: B =
/// [`BLOCK_PER_SCALE`] × [`object_scale`], at least [`DEFAULT_BLOCK`] and at most a
/// third of the exemplar's shorter side (so that a patch of 1.5 B has room to move),
/// even; border B / 4. Blocks smaller than the objects cut them into shards: the
/// stone-wall photo enlarged 4× (624², stones of 100–200 px) came out in 40-px pieces
/// of stones, and a 1024² photo of craters in 40-px blotches. The photos of 80–256 px
/// in `tests/data` read 3–12 px and keep the paper's 40 and 10 px. This is the block
/// without a repeat window (`--repeat-window off`); a bank's default caps it
/// ([`stochastic_block_within`]).
pub fn stochastic_block(ex: &Raster) -> BlockScale {
    stochastic_block_within(ex, None)
}

/// [`stochastic_block`], capped at [`repeat_block`] for a `window`² output and the
/// exemplar's area where a window is given (a stochastic bank's default gives
/// [`DEFAULT_REPEAT_WINDOW`]). Objects larger than the cap are cut: the trade is
/// measured in docs/structure.md, "Block size against self-repetition".
pub fn stochastic_block_within(ex: &Raster, window: Option<usize>) -> BlockScale {
    let scale_px = object_scale(ex);
    let want = (BLOCK_PER_SCALE * scale_px).round();
    let room = (ex.width.min(ex.height) / 3) as f64;
    let repeat_cap_px = window.map(|n| repeat_block(n, ex.width * ex.height));
    let even = |cap: f64| (want.min(cap).max(DEFAULT_BLOCK as f64) as usize) & !1;
    let block_px = even(repeat_cap_px.map_or(room, |b| room.min(b as f64)));
    BlockScale {
        scale_px,
        block_px,
        border_px: block_px / 4,
        repeat_cap_px,
        uncapped_px: even(room),
    }
}

/// The self-repetition bar of issue 31 that [`repeat_block`] keeps within.
pub const REPEAT_BAR: f64 = 0.15;

/// The self-repetition that stochastic blocks of `block` px predict within a
/// `window`² output of an exemplar of `area` pixels (docs/structure.md, "Why, in
/// numbers"). A block copies its patch verbatim, so a 32-px grid patch of the output
/// ([`crate::stats::structure::COPY_PATCH`]) lying inside one block, a share
/// ((B − 31) / B)² of them, has a near-copy wherever another block covers the same
/// exemplar patch: about λ = (N / B)²·(B − 31)² / A times. The prediction is that share
/// times 1 − e^−λ. Measured on ETR's `ice01` (1024², A = 256²): 0.004, 0.148 and 0.357
/// for B = 40, 56 and 84, where this reads 0.03, 0.19 and 0.40.
pub fn predicted_self_repetition(block: usize, window: usize, area: usize) -> f64 {
    let p = crate::stats::structure::COPY_PATCH;
    if block < p || area == 0 {
        return 0.0;
    }
    let (b, inside) = (block as f64, (block + 1 - p) as f64);
    let lambda = (window as f64 / b).powi(2) * inside * inside / area as f64;
    (inside / b).powi(2) * (1.0 - (-lambda).exp())
}

/// The largest even block of at least [`DEFAULT_BLOCK`] px whose
/// [`predicted_self_repetition`] within a `window`² output of an exemplar of `area`
/// pixels is at most [`REPEAT_BAR`]; [`DEFAULT_BLOCK`] where none is. The prediction
/// grows with the block, so the search stops at the first block over the bar.
pub fn repeat_block(window: usize, area: usize) -> usize {
    let mut b = DEFAULT_BLOCK;
    while b < crate::models::rsgf::MAX_BLOCK
        && predicted_self_repetition(b + 2, window, area) <= REPEAT_BAR
    {
        b += 2;
    }
    b
}

/// Issue 31's window for its self-repetition bar: the side of the window a stochastic
/// bank's scaled block keeps its self-repetition within by default
/// ([`RepeatWindow::Auto`]), and within which [`repetition_advice`] predicts it.
pub const DEFAULT_REPEAT_WINDOW: usize = 1024;

/// One line for the bake log where stochastic blocks of `block` px from an exemplar of
/// `area` pixels are predicted to repeat over [`REPEAT_BAR`] within
/// [`DEFAULT_REPEAT_WINDOW`]² ([`predicted_self_repetition`]) and a smaller block
/// would not: the prediction, and the default cap ([`repeat_block`]) with its cost. The
/// bake logs it where `--repeat-window off` lifted the cap. `None` where the blocks stay within the
/// bar (every photo of `tests/data`, with 40-px blocks, predicts at most 0.051:
/// ((40 − 31)/40)²).
pub fn repetition_advice(block: usize, area: usize) -> Option<String> {
    let n = DEFAULT_REPEAT_WINDOW;
    let predicted = predicted_self_repetition(block, n, area);
    let cap = repeat_block(n, area);
    (predicted > REPEAT_BAR && cap < block).then(|| {
        format!(
            "self-repetition within {n}² is predicted at {predicted:.2} with {block}-px blocks (bar {REPEAT_BAR}): --repeat-window auto ({n}) caps them at {cap} px (predicted {:.2}), which cuts objects larger than that",
            predicted_self_repetition(cap, n, area)
        )
    })
}

/// Pixel-scale roughness at and above which a stochastic bank's cuts ramp over
/// [`ROUGH_FEATHER`] ([`stochastic_feather`]).
pub const ROUGH_AT: f64 = 0.1;
/// Ramp half-width of a stochastic bank on an exemplar rough at the pixel scale.
pub const ROUGH_FEATHER: usize = 1;
/// Ramp half-width of a stochastic bank on an exemplar smooth at the pixel scale.
pub const SMOOTH_FEATHER: usize = 3;

/// Roughness at the pixel scale: the mean squared difference of neighbouring pixels
/// (both axes, every channel) over twice the variance (summed over channels). 1 for
/// white noise, sin²(π/P) for a sine of period P px, 0 for a flat map.
pub fn pixel_roughness(ex: &Raster) -> f64 {
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    let mut var = 0.0;
    for k in 0..c {
        let n = (w * h) as f64;
        let mean = ex
            .data
            .iter()
            .skip(k)
            .step_by(c)
            .map(|&v| v as f64)
            .sum::<f64>()
            / n;
        var += ex
            .data
            .iter()
            .skip(k)
            .step_by(c)
            .map(|&v| (v as f64 - mean).powi(2))
            .sum::<f64>()
            / n;
    }
    let (mut dx, mut nx, mut dy, mut ny) = (0.0, 0usize, 0.0, 0usize);
    for y in 0..h {
        for x in 0..w {
            let at = (y * w + x) * c;
            for k in 0..c {
                let v = ex.data[at + k] as f64;
                if x + 1 < w {
                    dx += (ex.data[at + c + k] as f64 - v).powi(2);
                }
                if y + 1 < h {
                    dy += (ex.data[at + w * c + k] as f64 - v).powi(2);
                }
            }
            nx += usize::from(x + 1 < w);
            ny += usize::from(y + 1 < h);
        }
    }
    let mean_sq = 0.5 * (dx / nx.max(1) as f64 + dy / ny.max(1) as f64);
    if var > 0.0 {
        mean_sq / (2.0 * var)
    } else {
        0.0
    }
}

/// The cut ramp of a stochastic bank. A ramp averages the two patches across a cut.
/// On a surface rough at the pixel scale, that averaging takes out the roughness it
/// blends, so the block edges carry less gradient energy than the rest; on a smooth
/// one, a short ramp leaves the step between the patches. Either shows as a seam at the
/// block's own period. [`pixel_roughness`] ≥ [`ROUGH_AT`]: [`ROUGH_FEATHER`] (a 2-px
/// ramp), else [`SMOOTH_FEATHER`] (6 px). The seven photos of `tests/data` read 0.18–0.41
/// and the 27 measured height maps 0–0.06, except one noisy map (0.56). 1024², seeds 0
/// and 1, worst seam at the 40-px block (docs/structure.md): grass 0.89 / 0.90 with a
/// 4-px ramp, 0.95 / 0.94 with 2 px; di-6 (an AFM map) 1.21 / 1.19 with 4 px, 1.13 /
/// 1.13 with 6 px.
pub fn stochastic_feather(ex: &Raster) -> usize {
    stochastic_feather_of(pixel_roughness(ex))
}

/// [`stochastic_feather`] for a measured [`pixel_roughness`] `g`.
fn stochastic_feather_of(g: f64) -> usize {
    if g >= ROUGH_AT {
        ROUGH_FEATHER
    } else {
        SMOOTH_FEATHER
    }
}

/// Side of the trial synthesis [`histogram_map`] measures.
pub const TRIAL_SIDE: usize = 384;
/// Quantile steps of a histogram map (knots: one more, fewer where values repeat).
const MAP_STEPS: usize = 64;

/// The histogram map of a stochastic RSGF model (seed 000 §3.1.2's histogram
/// matching, T⁻¹, applied to the output): per channel, knots from the quantiles of a
/// trial synthesis (seed 0, TRIAL_SIDE² at the origin) to the exemplar's at the same
/// levels. Blocks copied from an exemplar cover its border less than its middle: a
/// 40-px block sits at 61 positions per axis of a 100-px exemplar (edges reflected,
/// [`RsgfParams::reflect_edges`]), so an edge pixel is in 1 where a central one is in
/// 40, and the output's histogram leans to the middle's. On the 100² dried-mud photo
/// that is a W1 of 0.06–0.07 and a standard deviation of 0.90–0.91 of the exemplar's
/// (512²). Such an exemplar now wraps ([`coverage_bias`], [`RsgfParams::wrap_edges`]:
/// 0.024–0.029 and 0.958–0.967); the map takes the wrapped synthesis to 0.006–0.007
/// and 0.995–0.996
/// (`tests/rsgf.rs::small_exemplars_wrap_and_keep_their_histogram`). It is off by default:
/// mapped values are no longer the exemplar's, and the patch figures pay for it
/// (measured before reflected edges, 1024²: coherence 0.238 → 0.367, PSD error
/// 0.042 → 0.133 on that photo). None for a flat channel.
pub fn histogram_map(model: RsgfModel, ex: &Raster) -> Result<Option<Vec<Vec<[f32; 2]>>>> {
    let c = ex.channels;
    let surface = RsgfSurface::from_model(model, 0);
    let mut trial = vec![0.0f32; TRIAL_SIDE * TRIAL_SIDE * c];
    surface.fill(&Region::new(0.0, 0.0, TRIAL_SIDE, TRIAL_SIDE), &mut trial)?;
    let mut maps = Vec::with_capacity(c);
    for k in 0..c {
        let sorted = |data: &[f32]| {
            let mut v: Vec<f32> = data.iter().skip(k).step_by(c).copied().collect();
            v.sort_by(f32::total_cmp);
            v
        };
        let (from, to) = (sorted(&trial), sorted(&ex.data));
        let at = |v: &[f32], q: usize| v[(q * (v.len() - 1) + MAP_STEPS / 2) / MAP_STEPS];
        let mut map: Vec<[f32; 2]> = Vec::with_capacity(MAP_STEPS + 1);
        for q in 0..=MAP_STEPS {
            let knot = [at(&from, q), at(&to, q)];
            if map.last().is_none_or(|l| knot[0] > l[0]) {
                map.push(knot);
            }
        }
        if map.len() < 2 {
            return Ok(None);
        }
        maps.push(map);
    }
    Ok(Some(maps))
}

/// The trial fills that choose a stochastic bank's edges where its [`coverage_bias`]
/// says the blocks may wrap: the value figures ([`crate::stats::value_figures`]: W1
/// and standard-deviation ratio) of an unwrapped synthesis (reflected edges with cuts;
/// bounded positions with a blend) and a wrapped one, seed 0, [`EDGE_TRIAL_SIDE`]² at
/// the origin. The fills are not histogram-mapped (`--match-histogram` maps either
/// layout's values afterwards).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeTrial {
    /// (W1, standard-deviation ratio) of the unwrapped layout.
    pub reflected: (f64, f64),
    /// The same of the wrapped layout.
    pub wrapped: (f64, f64),
}

/// Side of [`EdgeTrial`]'s fills: the larger of issue 31's two outputs. Near a bar the
/// figures of a small fill are noisy: the 128-px berries of the classic texture set,
/// reflected, read W1 0.058 on a 384² fill, 0.044 at 512² and 0.047 at 1024².
pub const EDGE_TRIAL_SIDE: usize = 1024;

/// How many of the two value bars ([`COVERAGE_W1_BAR`], [`COVERAGE_SD_BAR`]) the
/// figures (W1, standard-deviation ratio) miss.
pub fn value_bars_missed((w1, sd_ratio): (f64, f64)) -> usize {
    usize::from(w1.is_nan() || w1 >= COVERAGE_W1_BAR)
        + usize::from(sd_ratio.is_nan() || (sd_ratio - 1.0).abs() >= COVERAGE_SD_BAR)
}

impl EdgeTrial {
    /// Whether the bank wraps: only where the wrapped trial misses fewer of the two value
    /// bars than the unwrapped one (where the layouts trade one bar for the other, it
    /// does not). Wrapping is for the values, and it costs coherence: a patch across the
    /// torus's seam is in no exemplar, and the cut that closes the torus keeps features
    /// from both of its sides. On the 128-px berries of the classic
    /// texture set, whose coverage predicted W1 0.066, wrapping read coherence 0.352
    /// against 0.254 reflected (1024²), where reflected already met both value bars
    /// (W1 0.047, standard deviation 0.985; docs/structure.md, "The classic texture
    /// set").
    pub fn wrap(&self) -> bool {
        value_bars_missed(self.wrapped) < value_bars_missed(self.reflected)
    }

    /// One line for the bake's progress.
    pub fn text(&self) -> String {
        let (r, w) = (self.reflected, self.wrapped);
        format!(
            "edges by trial fills ({EDGE_TRIAL_SIDE}², seed 0), as the coverage says blocks may wrap: unwrapped W1 {:.3}, standard deviation {:.3}; wrapped {:.3}, {:.3} (bars {COVERAGE_W1_BAR} and ±{COVERAGE_SD_BAR}): {}",
            r.0,
            r.1,
            w.0,
            w.1,
            if self.wrap() {
                "wrapped, which misses fewer bars"
            } else {
                "not wrapped, as wrapping misses no fewer bars and costs coherence (pass --edges wrap to wrap)"
            }
        )
    }
}

/// The [`EdgeTrial`] of `options` (stochastic, block and border resolved) on `ex`.
pub fn edges_by_trial(ex: &Raster, options: &RsgfOptions) -> Result<EdgeTrial> {
    let figures = |edges: Edges| -> Result<(f64, f64)> {
        let options = RsgfOptions {
            edges,
            ..options.clone()
        };
        let params = options.params_for(ex, (1, 0), (0, 1));
        let surface = RsgfSurface::from_model(RsgfModel::new(ex, &params)?, 0);
        let c = ex.channels;
        let n = EDGE_TRIAL_SIDE;
        let mut out = vec![0.0f32; n * n * c];
        surface.fill(&Region::new(0.0, 0.0, n, n), &mut out)?;
        let out = Raster::from_vec(n, n, c, out)?;
        Ok(crate::stats::value_figures(ex, &out))
    };
    Ok(EdgeTrial {
        reflected: figures(Edges::Reflect)?,
        wrapped: figures(Edges::Wrap)?,
    })
}

/// How the patches of `params` join, in words.
pub fn join_text(params: &RsgfParams) -> String {
    match params.join {
        Join::Cut => format!(
            "minimum-error cuts ramped over {} px",
            2 * params.feather_px
        ),
        Join::Blend => "linear blending".into(),
    }
}

/// Bakes the RSGF bank of a preprocessed exemplar. `lattice` overrides estimation;
/// `info` and `bake_text` describe the exemplar and the bake for the header.
pub(crate) fn bake(
    ex: &Raster,
    options: &RsgfOptions,
    lattice: Option<[(i64, i64); 2]>,
    source: &str,
    header_base: (ExemplarInfo, Option<f64>, u64, String),
    progress: &mut dyn FnMut(&str),
) -> Result<Bank> {
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    // The defaults that depend on the exemplar (a stochastic bank's block and ramp) are
    // measured once, said, and fixed in the options every later step uses.
    let mut resolved = options.clone();
    if options.stochastic && options.block_px.is_none() && options.border_px.is_none() {
        let scale = stochastic_block_within(ex, options.repeat_window.side());
        let repeat = match (options.repeat_window.side(), scale.repeat_cap_px) {
            (Some(n), Some(cap)) => {
                let off = if scale.uncapped_px > scale.block_px {
                    format!("; --repeat-window off keeps {} px", scale.uncapped_px)
                } else {
                    String::new()
                };
                format!(
                    ", and at most {cap} px, where self-repetition within {n}² is predicted to stay within {REPEAT_BAR} (predicted {:.3}{off})",
                    predicted_self_repetition(scale.block_px, n, w * h)
                )
            }
            _ => String::new(),
        };
        progress(&format!(
            "blocks of {} px, border {} px: {BLOCK_PER_SCALE} × the object scale {:.0} px (autocorrelation below {SCALE_ACF}), kept within [{DEFAULT_BLOCK} px, a third of the shorter side]{repeat} (pass --block to choose)",
            scale.block_px, scale.border_px, scale.scale_px
        ));
        if options.repeat_window == RepeatWindow::Off
            && let Some(line) = repetition_advice(scale.block_px, w * h)
        {
            progress(&line);
        }
        resolved.block_px = Some(scale.block_px);
        resolved.border_px = Some(scale.border_px);
    }
    if options.feather_px.is_none() && options.stochastic && options.join == Join::Cut {
        let g = pixel_roughness(ex);
        // Below the border, as `params_with` keeps it.
        let border = resolved.border_px.unwrap_or(DEFAULT_BORDER);
        let feather = stochastic_feather_of(g).min(border.saturating_sub(1));
        progress(&format!(
            "cut ramp of {} px: roughness at the pixel scale {g:.3} ({} {ROUGH_AT}; pass --feather to choose)",
            2 * feather,
            if g >= ROUGH_AT { "≥" } else { "<" }
        ));
        resolved.feather_px = Some(feather);
    }
    // Where the coverage says the blocks may wrap, trial fills of both layouts decide:
    // wrapping costs coherence, so it is kept only where the wrapped fill misses fewer
    // of the two value bars.
    if options.stochastic
        && options.edges == Edges::Auto
        && resolved.params_for(ex, (1, 0), (0, 1)).wrap_edges
    {
        let trial = edges_by_trial(ex, &resolved)?;
        progress(&trial.text());
        resolved.edges = if trial.wrap() {
            Edges::Wrap
        } else {
            Edges::Reflect
        };
    }
    let options = &resolved;
    // Parameters that do not depend on the lattice fail before any analysis.
    let probe = options.params_for(ex, (1, 0), (0, 1));
    probe.validate()?;
    probe.check_exemplar(w, h)?;
    let (v1, v2) = if options.stochastic {
        progress("stochastic mode: v1 = (1, 0), v2 = (0, 1)");
        ((1, 0), (0, 1))
    } else if let Some([u, v]) = lattice {
        progress(&format!(
            "lattice given: v1 = ({}, {}), v2 = ({}, {})",
            u.0, u.1, v.0, v.1
        ));
        (u, v)
    } else {
        let map = autocorrelation(ex)?;
        match best_pair(&map) {
            Some(t) if t.mean_gamma >= MIN_MEAN_GAMMA => {
                progress(&format!(
                    "lattice estimated: v1 = ({}, {}), v2 = ({}, {}), goodness {:.3}, mean γ {:.3}",
                    t.v1.0, t.v1.1, t.v2.0, t.v2.1, t.goodness, t.mean_gamma
                ));
                for note in ridge_notes(&map, &t) {
                    progress(&note);
                }
                (t.v1, t.v2)
            }
            other => return Err(no_lattice(source, other, BAKE_WITHOUT_LATTICE)),
        }
    };
    // In stochastic mode the probe already is the bank's parameters (the same unit
    // lattice): its block, ramp and edges need not be measured again.
    let params = if options.stochastic {
        probe
    } else {
        options.params_for(ex, v1, v2)
    };
    // Building the model checks the lattice against the exemplar, as loading will.
    let model = RsgfModel::new(ex, &params)?;
    if options.stochastic {
        let bias = coverage_bias(ex, params.block_px);
        let torus = model
            .torus()
            .map(|(tw, th)| format!(" (torus {tw}×{th})"))
            .unwrap_or_default();
        progress(&format!(
            "edges {}: blocks at bounded positions would show the exemplar with W1 {:.3} and {:.3} of its standard deviation (bars {COVERAGE_W1_BAR} and ±{COVERAGE_SD_BAR})",
            if params.wrap_edges {
                format!("wrapped around the exemplar made periodic{torus}")
            } else if params.reflect_edges {
                "reflected".into()
            } else {
                "bounded (blended patches keep inside the exemplar)".into()
            },
            bias.w1,
            bias.sd_ratio
        ));
    }
    let torus_text = model
        .torus()
        .map(|(tw, th)| format!(" torus={tw}x{th}"))
        .unwrap_or_default();
    // The bank keeps the exemplar's own chain (the model's may be extended by its
    // reflected edges, or be the repeated torus: loading rebuilds either).
    let (levels, texels) = exemplar_levels(ex);
    let mut params = params;
    if options.stochastic && options.histogram {
        params.histogram = histogram_map(model, ex)?;
        if let Some(maps) = &params.histogram {
            progress(&format!(
                "histogram map of {} knots per channel from a {TRIAL_SIDE}² trial synthesis",
                maps.iter().map(|m| m.len()).min().unwrap_or(0)
            ));
        }
    }
    progress(&format!(
        "exemplar {w}×{h}×{c}, {} mip levels; blocks of {} px, border {} px, tolerance ±{} px, {:?}, {}",
        levels.len(),
        params.block_px,
        params.border_px,
        params.tolerance_px,
        params.metric,
        join_text(&params)
    ));
    let (exemplar, spacing_um, seed, bake_text) = header_base;
    let header = BankHeader {
        method: Method::Rsgf,
        channels: c,
        tiles: 1,
        tile_size: [w, h],
        lattice: [[v1.0 as f64, v1.1 as f64], [v2.0 as f64, v2.1 as f64]],
        levels,
        spacing_um,
        height_unit: crate::bake::height_unit(c, spacing_um),
        seed,
        exemplar,
        bake: format!(
            "method=rsgf v1=({},{}) v2=({},{}) block={} border={} tolerance={} metric={:?} join={:?} feather={} stochastic={} reflect_edges={} wrap_edges={}{} {bake_text}",
            v1.0,
            v1.1,
            v2.0,
            v2.1,
            params.block_px,
            params.border_px,
            params.tolerance_px,
            params.metric,
            params.join,
            params.feather_px,
            options.stochastic,
            params.reflect_edges,
            params.wrap_edges,
            torus_text
        ),
        record: Record::Rsgf(
            serde_json::to_value(&params)
                .map_err(|e| crate::error::Error::bank(source, format!("rsgf section: {e}")))?,
        ),
    };
    let luts = vec![Vec::new(); texels.len()];
    Bank::new(header, texels, luts, "just baked")
}

/// The exemplar and its 2 × 2 halvings ([`mip_chain`]) as a bank's levels and texels:
/// what RSGF and quilting banks hold.
pub(crate) fn exemplar_levels(ex: &Raster) -> (Vec<LevelInfo>, Vec<Vec<f32>>) {
    let chain = mip_chain(ex);
    let levels = chain
        .iter()
        .map(|l| {
            let (mean, sigma) = crate::bake::channel_stats(&l.data, ex.channels);
            LevelInfo {
                size: [l.w, l.h],
                mean,
                sigma,
                shift: None,
            }
        })
        .collect();
    (levels, chain.into_iter().map(|l| l.data).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Known answers of the edge rule: a bank wraps only where the wrapped trial misses
    /// fewer of the two value bars than the unwrapped one.
    #[test]
    fn edges_wrap_only_where_wrapping_misses_fewer_value_bars() {
        assert_eq!(value_bars_missed((0.049, 0.951)), 0);
        assert_eq!(value_bars_missed((0.05, 1.0)), 1);
        assert_eq!(value_bars_missed((0.01, 1.05)), 1);
        assert_eq!(value_bars_missed((0.2, 0.9)), 2);
        assert_eq!(value_bars_missed((f64::NAN, 1.0)), 1);
        let trial = |reflected, wrapped| EdgeTrial { reflected, wrapped }.wrap();
        // The dried mud (512²): reflected misses both, wrapped meets both.
        assert!(trial((0.064, 0.902), (0.029, 0.958)));
        // One bar bought.
        assert!(trial((0.064, 0.99), (0.03, 0.99)));
        // Berries: reflected meets both already.
        assert!(!trial((0.044, 0.983), (0.016, 0.991)));
        // Peppers: both miss W1, wrapping nearer the bar is not enough.
        assert!(!trial((0.130, 0.968), (0.073, 0.966)));
        // Wrapping misses more.
        assert!(!trial((0.03, 0.99), (0.06, 0.99)));
        // The layouts trade one bar for the other.
        assert!(!trial((0.06, 0.99), (0.03, 0.93)));
    }
}
