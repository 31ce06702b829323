//! `bake --method auto`: picks a method from the exemplar (issue 31, deliverable 4).
//!
//! 1. **A lattice** (seed 003's periodicity detection, [`super::periodicity::detect`]):
//!    a strong one (normalised autocorrelation ≥ [`STRONG_LATTICE`] at both vectors)
//!    goes to the roller, whose double-toroidal tiles repeat it exactly; a weaker,
//!    near-regular one to RSGF (seed 002), which samples and fills it. Stripes (a lay
//!    repeating across, not along) go to the roller, which pairs them with a stochastic
//!    side.
//! 2. **Stochastic**: how much structure random phases destroy. Objects with edges
//!    (stones, blades, cracks, bricks) make the height or grey-level differences of
//!    neighbouring pixels heavy-tailed: most are small, a few at the edges are large.
//!    Random phases (seed 000 §3.1.2) keep the spectrum and spread those edges into
//!    Gaussian differences. So `auto` takes one RPN realisation of a crop of the
//!    exemplar, histogram-matched back as the bank's T⁻¹ does, and compares the
//!    kurtosis of the differences (x and y, averaged; 3 for a Gaussian field): the
//!    **edge ratio** exemplar ÷ RPN. A Gaussian-like map (sandblasted, most AFM and
//!    interferometer roughness) has nothing RPN loses: ratio near 1 (0.63–1.17 on the
//!    four measured maps of the fidelity test), and RPN keeps histogram and spectrum
//!    best of all methods. Photos of objects lose their edges: 1.42–2.72 on the seven
//!    test photos. Above [`EDGE_RATIO`], RSGF in stochastic mode is taken (every
//!    exemplar position a candidate, gaps matched by NCC, blocks joined along
//!    minimum-error cuts), or `synth` where the exemplar cannot hold an RSGF patch.
//!
//! **Why RSGF rather than synth for structured stochastic exemplars.** Both stream in
//! any split; both copy exemplar pieces. On the seven test photos at 1024² (same run,
//! same code, `examples/structure_figures.rs`), stochastic RSGF with cuts has the
//! lowest coherence of the three (0.20–0.33, against synth's 0.20–0.39 and
//! texture-synthesis' 0.32–0.44) and better completeness than texture-synthesis on
//! all seven (0.07–0.12 against 0.18–0.32), keeps the standard deviation (0.89–1.02;
//! synth 0.81–1.02), and fills 1024² in 0.17–0.74 s. Synth, whose correction passes
//! smear small exemplars (the 127 × 80 rocks photo loses its dark joints: standard
//! deviation 0.81), stays available by name.
//!
//! The structure figures' coherence was tried first and cannot tell them apart: RPN of
//! the gravel photo scores 1.01 (its 8×8 patches are as far from the exemplar as the
//! exemplar's halves are from each other: gravel is busy), the al3d-1 map 1.87.
//! (Figures from `cargo test --release --test auto -- --nocapture`.) Nor can
//! "synth's coherence is lower" decide: synth copies exemplar pieces, so its coherence is
//! below 1 on any input.

use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

use crate::analysis::gauss::quantile;
use crate::analysis::periodicity::{Detection, detect};
use crate::analysis::rpn::random_phase_noise;
use crate::bank::Method;
use crate::models::rsgf::MAX_EXEMPLAR_PIXELS;
use crate::models::rsgf::RsgfParams;
use crate::raster::Raster;

/// Normalised autocorrelation at both lattice vectors from which the roller, rather
/// than RSGF, takes a lattice.
pub const STRONG_LATTICE: f64 = 0.8;
/// Edge ratio (difference kurtosis, exemplar ÷ RPN) above which the exemplar counts as
/// structured: between the measured maps' largest (1.17, al3d-1) and the photos'
/// smallest (1.42, grass).
pub const EDGE_RATIO: f64 = 1.3;
/// Side of the centred crop the RPN test runs on, at most (keeps `auto` within about
/// a second on a large map).
const TEST_SIDE: usize = 256;

/// The method `auto` picks and why, in one line with the figures it used.
#[derive(Clone, Debug, PartialEq)]
pub struct AutoChoice {
    /// The method.
    pub method: Method,
    /// With [`Method::Rsgf`]: stochastic mode (no lattice).
    pub stochastic: bool,
    /// One line: the reason and its figures.
    pub reason: String,
}

/// Picks the method for a preprocessed exemplar `ex` (finite values; see the module
/// notes). `seed` drives the RPN realisation.
pub fn choose_method(ex: &Raster, seed: u64) -> AutoChoice {
    match detect(ex) {
        Detection::Lattice(p) if p.strength >= STRONG_LATTICE => AutoChoice {
            method: Method::Roller,
            stochastic: false,
            reason: format!(
                "a lattice u = {:?}, v = {:?} repeats strongly (autocorrelation {:.2} ≥ {STRONG_LATTICE}): roller",
                p.u, p.v, p.strength
            ),
        },
        Detection::Lattice(p) => AutoChoice {
            method: Method::Rsgf,
            stochastic: false,
            reason: format!(
                "a near-regular lattice u = {:?}, v = {:?} (autocorrelation {:.2} < {STRONG_LATTICE}): rsgf",
                p.u, p.v, p.strength
            ),
        },
        Detection::Stripes { u, strength, .. } => AutoChoice {
            method: Method::Roller,
            stochastic: false,
            reason: format!(
                "stripes repeating every {u:?} (autocorrelation {strength:.2}): roller"
            ),
        },
        Detection::Stochastic => {
            let ratio = edge_ratio(ex, seed);
            if ratio <= EDGE_RATIO {
                AutoChoice {
                    method: Method::Rpn,
                    stochastic: false,
                    reason: format!(
                        "stochastic and Gaussian-like: random phases keep its edges (edge ratio {ratio:.2} ≤ {EDGE_RATIO}): rpn"
                    ),
                }
            } else {
                let objects = format!(
                    "stochastic with objects whose edges random phases destroy (edge ratio {ratio:.2} > {EDGE_RATIO})"
                );
                let rsgf = RsgfParams::stochastic();
                let patch = rsgf.block_px + 2 * rsgf.border_px;
                // A whole patch must fit, although reflected edges would let a block
                // alone do: fewer than 2·o + 1 positions per axis repeat too often.
                if patch <= ex.width.min(ex.height) && ex.width * ex.height <= MAX_EXEMPLAR_PIXELS {
                    AutoChoice {
                        method: Method::Rsgf,
                        stochastic: true,
                        reason: format!(
                            "{objects}: rsgf `stochastic` (patches copied whole, joined along minimum-error cuts)"
                        ),
                    }
                } else {
                    AutoChoice {
                        method: Method::Synth,
                        stochastic: false,
                        reason: format!(
                            "{objects}, and no room for rsgf's {patch}-px patches in {}×{}: synth",
                            ex.width, ex.height
                        ),
                    }
                }
            }
        }
    }
}

/// Kurtosis of the x and y differences of a row-major `w × h` plane, averaged.
fn difference_kurtosis(plane: &[f64], w: usize, h: usize) -> f64 {
    let kurtosis = |d: &[f64]| {
        let n = d.len().max(1) as f64;
        let mean = d.iter().sum::<f64>() / n;
        let (mut m2, mut m4) = (0.0, 0.0);
        for &v in d {
            let e = (v - mean) * (v - mean);
            m2 += e;
            m4 += e * e;
        }
        let (m2, m4) = (m2 / n, m4 / n);
        if m2 > 0.0 { m4 / (m2 * m2) } else { 3.0 }
    };
    let mut dx = Vec::with_capacity(w * h);
    let mut dy = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let v = plane[y * w + x];
            if x + 1 < w {
                dx.push(plane[y * w + x + 1] - v);
            }
            if y + 1 < h {
                dy.push(plane[(y + 1) * w + x] - v);
            }
        }
    }
    (kurtosis(&dx) + kurtosis(&dy)) / 2.0
}

/// The edge ratio of `ex` (see the module notes): the difference kurtosis of its
/// centred crop (at most [`TEST_SIDE`]², channels averaged) over that of one RPN
/// realisation of the crop, matched back to the crop's histogram.
pub fn edge_ratio(ex: &Raster, seed: u64) -> f64 {
    let (w, h) = (ex.width.min(TEST_SIDE), ex.height.min(TEST_SIDE));
    let (x0, y0) = ((ex.width - w) / 2, (ex.height - h) / 2);
    let c = ex.channels;
    let grey: Vec<f64> = (0..w * h)
        .map(|i| {
            let at = ((y0 + i / w) * ex.width + x0 + i % w) * c;
            ex.data[at..at + c].iter().map(|&v| v as f64).sum::<f64>() / c as f64
        })
        .collect();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let noise = random_phase_noise(std::slice::from_ref(&grey), w, h, &mut rng).remove(0);
    let mut sorted = grey.clone();
    sorted.sort_by(f64::total_cmp);
    let mut order: Vec<usize> = (0..noise.len()).collect();
    order.sort_by(|&a, &b| noise[a].total_cmp(&noise[b]));
    let mut matched = vec![0.0; noise.len()];
    for (rank, &i) in order.iter().enumerate() {
        matched[i] = quantile(&sorted, (rank as f64 + 0.5) / noise.len() as f64);
    }
    difference_kurtosis(&grey, w, h) / difference_kurtosis(&matched, w, h)
}
