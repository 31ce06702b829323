//! `bake --method auto`: picks a method from the exemplar (issue 31, deliverable 4).
//!
//! 1. **A lattice** (seed 003's periodicity detection, [`super::periodicity::detect`]):
//!    a strong one (normalised autocorrelation ≥ [`STRONG_LATTICE`] at both vectors)
//!    goes to the roller, whose double-toroidal tiles repeat it exactly; a weaker,
//!    near-regular one to RSGF (seed 002), which samples and fills it. Stripes (a lay
//!    repeating across, not along) go to the roller, which pairs them with a stochastic
//!    side. Where the method picked cannot bake the lattice (a strong oblique lattice
//!    whose tile and overlap need more than the exemplar: (42, 42), (−42, 42) in
//!    100 × 100 pixels), `Baker::bake` says so and goes on with [`choose_stochastic`].
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
//!    minimum-error cuts; a small exemplar repeated, rule 4), or `synth` where the
//!    exemplar is over RSGF's size.
//! 3. **Photos under the bar.** The edge ratio does not see fine, sparse objects: the
//!    bright scratches of a photo of ice read 1.24, slate 0.98, wood and walnut photos
//!    1.14–1.24 (GIMP patterns outside the structure figures' seven), against 1.06–1.22
//!    for the sandblasted al3d-1 and AFM di-6 maps, so no bar on it separates them.
//!    What does is what the exemplar is: a **photo** ([`is_photo`]: colour, or grey
//!    in 8-bit levels) rather than a height map (floats, or 16-bit PNG). Under the bar,
//!    a height map gets rpn as above; a photo gets rpn only if one RPN realisation of a
//!    128² crop scores at least as well on coherence (the structure figures' patch
//!    measure) as a trial of the structured method of the same size, and otherwise that
//!    method. On the four photos above RPN scores 0.98–1.08 and RSGF 0.19–0.23 (paper,
//!    8-bit grey: 4.59 against 1.01; flat-fielded as bake prepares photos, re-measured
//!    2026-11-27), so none gets rpn. The trial runs on the centred
//!    256² crop, so it costs about a second on any photo (a 1024² one: 1.8 s for the
//!    whole bake, 0.55 s of it RSGF's own).
//!
//! 4. **Too small for RSGF's patch** (60 px with its defaults): the exemplar is repeated
//!    as a torus until a patch can start at every phase of it ([`torus_repeats`]), and
//!    RSGF bakes from that. Such exemplars are mostly patterns made to tile (GIMP's
//!    25–64-px patterns; a tiling pattern is one period of itself), and many do not
//!    pass [`crate::prep::level::tiles_along`]: a designed edge often runs along the
//!    wrap (GIMP's `bluegrid` jumps 20 times as much there as between any two
//!    neighbouring columns inside it). Synth, which such exemplars got until 2026-11-29,
//!    turned their motifs into a jumble: on the 15 GIMP patterns under 60 px, RSGF on
//!    the torus read coherence 0.27–0.53 where synth read 0.46–0.89 (but 0.69 against
//!    0.59 on `bluegrid`, whose synth output is noise by eye), completeness 0.00–0.11
//!    against 0.16–1.01 (512², `surftile stats`; docs/structure.md, "Small
//!    exemplars repeat as a torus"). Mirroring instead of repeating turned cubes and
//!    squares into mirror images, and 50-px photo crops into kaleidoscopes.
//!
//! **Why RSGF rather than synth for structured stochastic exemplars.** Both stream in
//! any split; both copy exemplar pieces. On the seven test photos at 1024² (same run,
//! same code, `examples/structure_figures.rs`), stochastic RSGF with cuts has the
//! lowest coherence of the three (0.20–0.33, against synth's 0.20–0.39 and
//! texture-synthesis' 0.32–0.44) and better completeness than texture-synthesis on
//! all seven (0.07–0.12 against 0.18–0.32), keeps the standard deviation (0.89–1.02;
//! synth 0.81–1.02), and fills 1024² in 0.18–0.37 s (`surftile render` far from the
//! origin, 2026-11-27). Synth, whose correction passes
//! smear small exemplars (the 127 × 80 rocks photo loses its dark joints: standard
//! deviation 0.81), stays available by name.
//!
//! The structure figures' coherence was tried first as the only test and cannot tell
//! photos from height maps (hence rule 3's use of it on photos alone): RPN of
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
    /// Copies of the exemplar along x and y that the method bakes from: `[1, 1]` but
    /// where the exemplar is too small for RSGF's patch ([`torus_repeats`]).
    pub repeat: [usize; 2],
}

pub use crate::io::is_photo;

/// Picks the method for a preprocessed exemplar `ex` (finite values; see the module
/// notes). `seed` drives the RPN realisation. `photo` ([`is_photo`] of the exemplar as
/// read): a Gaussian-like photo gets rpn only where one RPN realisation scores at least
/// as well on coherence as a trial of the structured method (see the module notes).
pub fn choose_method(ex: &Raster, seed: u64, photo: bool) -> AutoChoice {
    match detect(ex) {
        Detection::Lattice(p) if p.strength >= STRONG_LATTICE => AutoChoice {
            method: Method::Roller,
            stochastic: false,
            repeat: [1, 1],
            reason: format!(
                "a lattice u = {:?}, v = {:?} repeats strongly (autocorrelation {:.2} ≥ {STRONG_LATTICE}): roller",
                p.u, p.v, p.strength
            ),
        },
        Detection::Lattice(p) => AutoChoice {
            method: Method::Rsgf,
            stochastic: false,
            repeat: [1, 1],
            reason: format!(
                "a near-regular lattice u = {:?}, v = {:?} (autocorrelation {:.2} < {STRONG_LATTICE}): rsgf",
                p.u, p.v, p.strength
            ),
        },
        Detection::Stripes { u, strength, .. } => AutoChoice {
            method: Method::Roller,
            stochastic: false,
            repeat: [1, 1],
            reason: format!(
                "stripes repeating every {u:?} (autocorrelation {strength:.2}): roller"
            ),
        },
        Detection::Stochastic => choose_stochastic(ex, seed, photo),
    }
}

/// The choice for an exemplar without a lattice (rules 2 and 3 of the module notes):
/// also where the method picked for a detected lattice cannot bake it (a strong oblique
/// lattice whose tile and overlap need more than the exemplar; see
/// [`crate::bake::Baker::bake`]).
pub fn choose_stochastic(ex: &Raster, seed: u64, photo: bool) -> AutoChoice {
    let ratio = edge_ratio(ex, seed);
    let rsgf = RsgfParams::stochastic();
    let patch = rsgf.block_px + 2 * rsgf.border_px;
    let (w, h) = (ex.width, ex.height);
    // A whole patch must fit, although reflected edges would let a block alone do:
    // fewer than 2·o + 1 positions per axis repeat too often. An exemplar too small for
    // one is repeated as a torus (rule 4 of the module notes).
    let repeat = torus_repeats(w, h, patch, rsgf.block_px + 4 * rsgf.border_px);
    let (rw, rh) = (w * repeat[0], h * repeat[1]);
    let rsgf_fits = rw * rh <= MAX_EXEMPLAR_PIXELS;
    let structured = |why: String| {
        if !rsgf_fits {
            let size = if repeat == [1, 1] {
                format!("{w}×{h}")
            } else {
                format!("{w}×{h}, repeated to hold an rsgf patch, {rw}×{rh}")
            };
            AutoChoice {
                method: Method::Synth,
                stochastic: false,
                repeat: [1, 1],
                reason: format!(
                    "{why}, and {size} is over rsgf's {MAX_EXEMPLAR_PIXELS} pixels: synth"
                ),
            }
        } else {
            let copied = "patches copied whole, joined along minimum-error cuts";
            let reason = if repeat == [1, 1] {
                format!("{why}: rsgf `stochastic` ({copied})")
            } else {
                format!(
                    "{why}, and {w}×{h} holds no {patch}-px patch of rsgf: rsgf `stochastic` on it repeated {} × {} as a torus ({copied}; a tiling pattern is one period of itself)",
                    repeat[0], repeat[1]
                )
            };
            AutoChoice {
                method: Method::Rsgf,
                stochastic: true,
                repeat,
                reason,
            }
        }
    };
    if ratio > EDGE_RATIO {
        return structured(format!(
            "stochastic with objects whose edges random phases destroy (edge ratio {ratio:.2} > {EDGE_RATIO})"
        ));
    }
    let gaussian = format!(
        "stochastic and Gaussian-like: random phases keep its edges (edge ratio {ratio:.2} ≤ {EDGE_RATIO})"
    );
    if !photo {
        return AutoChoice {
            method: Method::Rpn,
            stochastic: false,
            repeat: [1, 1],
            reason: format!("{gaussian}: rpn"),
        };
    }
    let name = if rsgf_fits { "rsgf" } else { "synth" };
    // The trial's RSGF runs on the repeats of the prepared exemplar (the bake flat-fields
    // the repeats instead: close enough to choose between rpn and RSGF).
    let torus = (rsgf_fits && repeat != [1, 1]).then(|| repeat_torus(ex, repeat));
    let from = rsgf_fits.then(|| torus.as_ref().unwrap_or(ex));
    match trial_coherence(ex, seed, from) {
        Some((rpn, other)) if rpn <= other => AutoChoice {
            method: Method::Rpn,
            stochastic: false,
            repeat: [1, 1],
            reason: format!(
                "{gaussian}, a photo, and random phases as coherent as {name} in a trial (coherence {rpn:.2} ≤ {other:.2}): rpn"
            ),
        },
        Some((rpn, other)) => structured(format!(
            "{gaussian}, but a photo whose objects random phases lose: coherence of a trial {other:.2} with {name} against {rpn:.2} with rpn"
        )),
        None => structured(format!(
            "{gaussian}, but a photo, and the coherence trial could not run"
        )),
    }
}

/// Copies of a `w × h` exemplar along x and y for RSGF's stochastic patches of `patch`
/// px, which can wrap around an exemplar of `wrap` px a side (block + 4 borders,
/// [`crate::models::rsgf::wrap_fits`]): `[1, 1]` where both sides hold a patch; else,
/// along each side under `wrap`, the fewest k with k·side ≥ `wrap` and
/// k·side − `patch` + 1 ≥ side, so that the repeats can wrap where the bake asks it
/// and a patch can start at every phase of the exemplar (rule 4 of the module notes).
pub fn torus_repeats(w: usize, h: usize, patch: usize, wrap: usize) -> [usize; 2] {
    if w.min(h) >= patch || w.min(h) == 0 {
        return [1, 1];
    }
    let copies = |side: usize| {
        if side >= wrap {
            1
        } else {
            wrap.div_ceil(side).max((patch - 1).div_ceil(side) + 1)
        }
    };
    [copies(w), copies(h)]
}

/// `ex` repeated `repeat[0]` times along x and `repeat[1]` times along y: its torus
/// unrolled (`ex` itself where a count is 0).
pub fn repeat_torus(ex: &Raster, repeat: [usize; 2]) -> Raster {
    if repeat.contains(&0) {
        return ex.clone();
    }
    ex.torus(ex.width * repeat[0], ex.height * repeat[1])
}

/// Side of the trials of [`trial_coherence`], at most.
const TRIAL_SIDE: usize = 128;

/// Coherence ([`crate::stats::structure::coherence_completeness`]), against the
/// exemplar's centred crop of at most [`TEST_SIDE`]² (so that the trial costs the same
/// on any photo: 0.3 s, where the whole of a 1024² photo took 16 s), of one RPN
/// realisation of the crop's centre (at most [`TRIAL_SIDE`]², every channel under the
/// same random phases, each matched back to its histogram) and of a synthesis of the
/// same size from the crop by the structured method: stochastic RSGF with the
/// parameters `bake` gives it from `rsgf_from`, but edges by the coverage alone,
/// without the bake's trial fills (`rsgf_from`: the exemplar, or its torus repeated
/// where it is small: the crop is taken of it as of the exemplar), else synth with its
/// defaults. `None` if the structured trial cannot run.
fn trial_coherence(ex: &Raster, seed: u64, rsgf_from: Option<&Raster>) -> Option<(f64, f64)> {
    use crate::stats::structure::coherence_completeness;
    let centred = |r: &Raster| {
        let (cw, ch) = (r.width.min(TEST_SIDE), r.height.min(TEST_SIDE));
        r.crop((r.width - cw) / 2, (r.height - ch) / 2, cw, ch).ok()
    };
    let ex = &centred(ex)?;
    let (w, h, c) = (
        ex.width.min(TRIAL_SIDE),
        ex.height.min(TRIAL_SIDE),
        ex.channels,
    );
    let (x0, y0) = ((ex.width - w) / 2, (ex.height - h) / 2);
    let planes: Vec<Vec<f64>> = (0..c)
        .map(|ch| {
            (0..w * h)
                .map(|i| ex.data[((y0 + i / w) * ex.width + x0 + i % w) * c + ch] as f64)
                .collect()
        })
        .collect();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let noise = random_phase_noise(&planes, w, h, &mut rng);
    let mut rpn = vec![0.0f32; w * h * c];
    for (ch, (plane, n)) in planes.iter().zip(&noise).enumerate() {
        for (i, v) in histogram_matched(plane, n).into_iter().enumerate() {
            rpn[i * c + ch] = v as f32;
        }
    }
    let rpn = Raster::from_vec(w, h, c, rpn).ok()?;
    let other = if let Some(from) = rsgf_from {
        let from = &centred(from)?;
        let options = crate::bake::rsgf::RsgfOptions {
            stochastic: true,
            ..Default::default()
        };
        // The coverage's choice of edges, without the bake's trial fills
        // (`bake::rsgf::EdgeTrial`): the layouts differ by 0.07–0.10 in coherence
        // (docs/structure.md, "Trial fills decide"), where rpn's trial reads four
        // to eight times RSGF's (1.02–2.24 against 0.18–0.28 on gimp-ice and the
        // classic set's stone wall, text and sponge).
        let params = options.params_for(from, (1, 0), (0, 1));
        crate::models::rsgf::RsgfModel::new(from, &params)
            .ok()?
            .synthesize(seed as u32, w, h)
    } else {
        use crate::stream::Surface;
        let model = crate::models::synth::synth_model(ex, &Default::default()).ok()?;
        let surface = crate::models::synth::SynthSurface::new(model, seed as u32);
        let mut v = vec![0.0f32; w * h * c];
        surface
            .fill(&crate::stream::Region::new(0.0, 0.0, w, h), &mut v)
            .ok()?;
        Raster::from_vec(w, h, c, v).ok()?
    };
    Some((
        coherence_completeness(ex, &rpn).0,
        coherence_completeness(ex, &other).0,
    ))
}

/// `noise` with the values of `plane` in its rank order (histogram matching, as the
/// bank's T⁻¹ maps RPN back to the exemplar's histogram).
fn histogram_matched(plane: &[f64], noise: &[f64]) -> Vec<f64> {
    let mut sorted = plane.to_vec();
    sorted.sort_by(f64::total_cmp);
    let mut order: Vec<usize> = (0..noise.len()).collect();
    order.sort_by(|&a, &b| noise[a].total_cmp(&noise[b]));
    let mut matched = vec![0.0; noise.len()];
    for (rank, &i) in order.iter().enumerate() {
        matched[i] = quantile(&sorted, (rank as f64 + 0.5) / noise.len() as f64);
    }
    matched
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
    let matched = histogram_matched(&grey, &noise);
    difference_kurtosis(&grey, w, h) / difference_kurtosis(&matched, w, h)
}
