//! The sandblast pipeline of seed 000 §3.2: a synthetic height map of any size and any
//! (coarser) pixel spacing from one measurement.
//!
//! 1. **Pixel spacing.** Down-sample the measurement by ν_T/ν_I with nearest-neighbour
//!    interpolation (a finer target spacing is refused: the measurement does not hold
//!    that information).
//! 2. **Size.** If the down-sampled measurement covers the target, crop it (at a seeded
//!    random position) and apply RPN. Otherwise take RPN patches of crops at random
//!    positions and join them by Efros–Freeman stitching ([`crate::analysis::stitch`]).
//!    `padded` instead follows the variant seed 000 compares against (Fig. 8): the
//!    measurement, scaled by √(M_T N_T / M_I N_I) about its mean, is padded with its mean
//!    to the target size, its border blended into the padding by a sigmoid, and RPN is
//!    applied once to the whole.
//!
//! RPN makes any input Gaussian. By default the pipeline is the paper's, and keeps the
//! spectrum; [`SandblastBuilder::match_histogram`] matches each RPN output to the
//! measured height distribution while keeping its Fourier modulus as nearly as it can
//! (IAAFT, [`match_histogram_keeping_modulus`]), before stitching, which gives back the
//! skew and tails of strongly non-Gaussian maps (pits, forms). Crops are tapered with the
//! bake's Hann window, but at its Welch gain with a form's variance given back at the
//! longest wavelengths ([`Taper::MainLobe`]), so the fine roughness keeps its measured
//! power where a form holds most of a crop's variance.

use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

use crate::analysis::rpn::{IaaftEnd, match_histogram_keeping_modulus, random_phase_noise};
use crate::analysis::stitch::{StitchParams, stitch};
use crate::bake::{Baker, Taper};
use crate::error::{Error, Result};
use crate::hash::hash_cell;
use crate::io::ImageFile;
use crate::raster::Raster;
use crate::stats::windowed_variance_ratio;

/// Largest output accepted, in pixels: 2²⁶ (8192²). The pipeline holds its whole output
/// while stitching, with weights and patches besides, about 20 bytes a pixel: 16384²
/// peaked at 5.2 GB and 32768² passed 11.7 GB. For larger surfaces, bake a bank and
/// render it: renders stream.
pub const MAX_OUTPUT_PIXELS: usize = 1 << 26;
/// Largest padded-RPN output (2²⁴, 4096²): it transforms the whole plane at once, about
/// 40 bytes a pixel (8192² peaked at 2.6 GB).
pub const MAX_PADDED_PIXELS: usize = 1 << 24;
/// Most values the RPN patches may hold together before they are stitched: 2²⁸ (1 GiB
/// of f32), what an 8192² output's patches of 512 px at half overlap come to.
pub const MAX_PATCH_VALUES: usize = 1 << 28;
/// Default largest patch side, in pixels. Patches as large as the measurement keep its
/// longest wavelengths (an RPN patch holds none longer than itself): on the stationary
/// measured maps, 512 px patches give a PSD error about half that of seed 000's 256,
/// and on the 650² ones (matrix-2, x3p-2) whole-side patches take it from 0.21 and
/// 0.20 at 512 px to 0.15 and 0.14. The larger patches cost time: a 2048² output from
/// x3p-2 took 2.1 s with 650 px patches against 1.7 s with 512 px ones (before RPN
/// went through real FFTs).
pub const DEFAULT_PATCH: usize = 1024;
/// Histogram/modulus alternations per RPN output with `match_histogram`.
/// Sixteen converge further than eight: with the defaults, di-4's PSD error at 1024² goes
/// from 0.233 to 0.219 (its bar: 0.226), and the 27 maps passing go from 17 to 18
/// (ending on the histogram).
pub const IAAFT_ITERATIONS: usize = 16;

/// Validated pipeline parameters. Make one with [`Sandblast::builder`].
#[derive(Clone, Debug)]
pub struct Sandblast {
    width: usize,
    height: usize,
    spacing_um: Option<f64>,
    exemplar_spacing_um: Option<f64>,
    patch: Option<usize>,
    overlap: Option<usize>,
    seam_blend: Option<usize>,
    seed: u64,
    padded: bool,
    fill_missing: bool,
    taper: Taper,
    match_histogram: bool,
}

/// Builder for [`Sandblast`]; every setter documents its default.
#[derive(Clone, Debug)]
pub struct SandblastBuilder(Sandblast);

impl SandblastBuilder {
    /// Target pixel spacing ν_T in µm, at least the measurement's. Default: the
    /// measurement's own spacing.
    pub fn spacing_um(mut self, um: f64) -> Self {
        self.0.spacing_um = Some(um);
        self
    }
    /// The measurement's pixel spacing ν_I in µm, overriding its file's. Default: the
    /// file's (needed only when a target spacing is given).
    pub fn exemplar_spacing_um(mut self, um: f64) -> Self {
        self.0.exemplar_spacing_um = Some(um);
        self
    }
    /// Patch side M_P in pixels for stitching. Default: the down-sampled measurement's
    /// smaller side, at most [`DEFAULT_PATCH`].
    pub fn patch(mut self, side: usize) -> Self {
        self.0.patch = Some(side);
        self
    }
    /// Overlap o of neighbouring patches in pixels, below the patch side. Default: half
    /// the patch (seed 000, Fig. 8: 256 and 128).
    pub fn overlap(mut self, px: usize) -> Self {
        self.0.overlap = Some(px);
        self
    }
    /// Radius in pixels of the multi-band seam blend; 0 keeps seed 000's hard cut (with
    /// its 3×3 mean). Default: o/8. The blend reaches up to 4× the radius from the seam
    /// ([`crate::analysis::stitch::blend_reach`]), and that reach must fit inside the
    /// overlap. The hard cut leaves a step where two RPN patches differ by a smooth
    /// offset, which on a smooth map (a steep spectrum) adds orders of magnitude of
    /// mid-frequency power: al3d-1 stitched to 1024² has a PSD error of 0.645 with it and
    /// 0.304 with the default blend (see [`StitchParams::with_blend`]).
    pub fn seam_blend(mut self, px: usize) -> Self {
        self.0.seam_blend = Some(px);
        self
    }
    /// Seed of crop positions and random phases. Default: 0.
    pub fn seed(mut self, seed: u64) -> Self {
        self.0.seed = seed;
        self
    }
    /// The padded-RPN variant with a sigmoid border instead of stitching. Default: false.
    pub fn padded(mut self, padded: bool) -> Self {
        self.0.padded = padded;
        self
    }
    /// Fill missing (NaN) points smoothly instead of refusing them. Default: false.
    pub fn fill_missing(mut self, fill: bool) -> Self {
        self.0.fill_missing = fill;
        self
    }
    /// How crops are made periodic before RPN. Default: [`Taper::MainLobe`].
    pub fn taper(mut self, taper: Taper) -> Self {
        self.0.taper = taper;
        self
    }
    /// Match each RPN output to the measured height distribution, keeping its Fourier
    /// modulus as nearly as it can ([`IAAFT_ITERATIONS`] alternations, ending on the
    /// histogram or the modulus, whichever leaves the other nearer its fidelity bar:
    /// [`IaaftEnd::Nearer`]), before stitching. Default: false (seed 000's pipeline: RPN
    /// output is Gaussian). On the 27 measured maps at 1024² (seed 0) it passes W1 and
    /// PSD error on 23 against 18 without it (di-6's W1: 0.011 against 0.090). With the
    /// variance-kept [`Taper::Hann`], 19 against 15, and always ending on the histogram
    /// 18 (nid-1, a smooth map with steps, failed: PSD error 1.33).
    pub fn match_histogram(mut self, on: bool) -> Self {
        self.0.match_histogram = on;
        self
    }
    /// Checks every parameter that does not depend on the measurement.
    pub fn build(self) -> Result<Sandblast> {
        let s = self.0;
        if s.width == 0 || s.height == 0 || s.width.saturating_mul(s.height) > MAX_OUTPUT_PIXELS {
            return Err(Error::param(
                "size",
                format!("{}x{}", s.width, s.height),
                format!(
                    "1 to {MAX_OUTPUT_PIXELS} pixels in all (2^26: the pipeline holds its whole output; for more, bake a bank and render it)"
                ),
            ));
        }
        for (name, v) in [
            ("spacing", s.spacing_um),
            ("exemplar-spacing", s.exemplar_spacing_um),
        ] {
            if let Some(v) = v
                && !(v.is_finite() && v > 0.0)
            {
                return Err(Error::param(name, v, "a positive pixel spacing in µm"));
            }
        }
        if let Some(p) = s.patch
            && !(8..=4096).contains(&p)
        {
            return Err(Error::param("patch", p, "a side of 8 to 4096 pixels"));
        }
        if let Some(p) = s.patch {
            let o = s.overlap.unwrap_or(p / 2).max(1);
            StitchParams::new(p, o)?.with_blend(s.seam_blend.unwrap_or(0))?;
        } else if s.overlap == Some(0) {
            return Err(Error::param("overlap", 0, "at least 1 pixel"));
        }
        Ok(s)
    }
}

/// What [`Sandblast::run`] made and how.
#[derive(Clone, Debug)]
pub struct SandblastOutput {
    /// The synthetic height map, `width × height`, in the measurement's height unit.
    pub raster: Raster,
    /// Its pixel spacing in µm, if known.
    pub spacing_um: Option<f64>,
    /// The measurement as synthesis saw it: levelled, down-sampled.
    pub exemplar: Raster,
    /// How the size was reached.
    pub how: Route,
}

/// How the target size was reached (seed 000 §3.2, step 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Route {
    /// The measurement covers the target: one crop, RPN.
    Crop,
    /// RPN patches of random crops, EF-stitched: `nx × ny` patches of `patch` px
    /// overlapping by `overlap` px.
    Stitched {
        /// Patches per row.
        nx: usize,
        /// Patch rows.
        ny: usize,
        /// Patch side.
        patch: usize,
        /// Overlap.
        overlap: usize,
    },
    /// Padded RPN with a sigmoid border.
    Padded,
}

impl Sandblast {
    /// A builder for a `width × height` output with the defaults.
    pub fn builder(width: usize, height: usize) -> SandblastBuilder {
        SandblastBuilder(Sandblast {
            width,
            height,
            spacing_um: None,
            exemplar_spacing_um: None,
            patch: None,
            overlap: None,
            seam_blend: None,
            seed: 0,
            padded: false,
            fill_missing: false,
            taper: Taper::MainLobe,
            match_histogram: false,
        })
    }

    /// Runs the pipeline on `image`; `source` names it in errors; `progress` gets one
    /// line per step.
    pub fn run(
        &self,
        image: &ImageFile,
        source: &str,
        progress: &mut dyn FnMut(&str),
    ) -> Result<SandblastOutput> {
        let mut pre = Baker::builder().fill_missing(self.fill_missing);
        if let Some(s) = self.exemplar_spacing_um {
            pre = pre.spacing_um(s);
        }
        let (measured, nu_i) = pre.build()?.preprocess(image, source)?;
        let (exemplar, spacing_um) = match (self.spacing_um, nu_i) {
            (None, _) => (measured, nu_i),
            (Some(t), None) => {
                return Err(Error::param(
                    "spacing",
                    t,
                    format!(
                        "a known exemplar spacing to down-sample from: {source} does not record one; pass `exemplar_spacing` UM"
                    ),
                ));
            }
            (Some(t), Some(i)) => {
                // A relative tolerance for spacings written with fewer digits.
                if t < i * (1.0 - 1e-9) {
                    return Err(Error::param(
                        "spacing",
                        t,
                        format!(
                            "at least the exemplar's {i} µm: seed 000 §3.2 synthesises coarser spacings only (a measurement holds nothing finer)"
                        ),
                    ));
                }
                let factor = t / i;
                let ds = downsample_nearest(&measured, factor, source)?;
                if factor > 1.0 + 1e-9 {
                    progress(&format!(
                        "down-sampled {}×{} at {i} µm by {factor:.4} to {}×{} at {t} µm",
                        measured.width, measured.height, ds.width, ds.height
                    ));
                }
                (ds, Some(t))
            }
        };
        if let Some(note) = stationarity_note(&exemplar.channel(0), source, self.taper) {
            progress(&note);
        }
        let (ew, eh, c) = (exemplar.width, exemplar.height, exemplar.channels);
        let (w, h) = (self.width, self.height);
        let planes_in: Vec<Vec<f64>> = (0..c).map(|ch| exemplar.channel_f64(ch)).collect();
        // With `match_histogram`, each RPN output is matched to the measured height
        // distribution keeping its Fourier modulus (IAAFT), before it is stitched.
        let sorted: Vec<Vec<f64>> = if self.match_histogram {
            planes_in
                .iter()
                .map(|p| {
                    let mut v = p.clone();
                    v.sort_unstable_by(f64::total_cmp);
                    v
                })
                .collect()
        } else {
            Vec::new()
        };
        let finish = |planes: Vec<Vec<f64>>, pw: usize, ph: usize| -> Vec<Vec<f64>> {
            if sorted.is_empty() {
                return planes;
            }
            planes
                .iter()
                .zip(&sorted)
                .map(|(p, s)| {
                    match_histogram_keeping_modulus(
                        p,
                        pw,
                        ph,
                        s,
                        IAAFT_ITERATIONS,
                        IaaftEnd::Nearer,
                    )
                })
                .collect()
        };
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(self.seed);
        let crop_of = |x0: usize, y0: usize, pw: usize, ph: usize| {
            self.taper.crops(&planes_in, ew, [x0, y0, pw, ph])
        };
        // Settings only stitching reads, named where the route does not stitch.
        let unused = [
            ("patch", self.patch.is_some()),
            ("overlap", self.overlap.is_some()),
            ("seam-blend", self.seam_blend.is_some()),
        ]
        .iter()
        .filter(|(_, set)| *set)
        .map(|(name, _)| *name)
        .collect::<Vec<_>>()
        .join(", ");
        let note_unused = |progress: &mut dyn FnMut(&str), route: &str| {
            if !unused.is_empty() {
                progress(&format!("note: {unused} unused: {route} does not stitch"));
            }
        };
        let (planes, how) = if ew >= w && eh >= h {
            let (x0, y0) = (rng.random_range(0..=ew - w), rng.random_range(0..=eh - h));
            progress(&format!(
                "the exemplar ({ew}×{eh}) covers {w}×{h}: crop at ({x0}, {y0}), RPN"
            ));
            note_unused(progress, "a crop of the measurement");
            let planes = finish(
                random_phase_noise(&crop_of(x0, y0, w, h), w, h, &mut rng),
                w,
                h,
            );
            (interleave(&planes, w, h)?, Route::Crop)
        } else if self.padded {
            if w * h > MAX_PADDED_PIXELS {
                return Err(Error::Limits(format!(
                    "a {w}×{h} padded RPN is over its limit of {MAX_PADDED_PIXELS} pixels (one FFT of the whole plane, about 40 bytes a pixel); stitch it instead (leave out `padded`)"
                )));
            }
            progress(&format!(
                "padded RPN: {ew}×{eh} scaled and padded to {w}×{h} with a sigmoid border"
            ));
            note_unused(progress, "padded RPN");
            let padded: Vec<Vec<f64>> = planes_in.iter().map(|p| pad(p, ew, eh, w, h)).collect();
            let planes = finish(random_phase_noise(&padded, w, h, &mut rng), w, h);
            (interleave(&planes, w, h)?, Route::Padded)
        } else {
            let side = ew.min(eh);
            let p = self.patch.unwrap_or(side.min(DEFAULT_PATCH));
            if p > side {
                return Err(Error::param(
                    "patch",
                    p,
                    format!("at most the exemplar's smaller side ({ew}×{eh} after down-sampling)"),
                ));
            }
            let params = StitchParams::new(p, self.overlap.unwrap_or(p / 2).max(1))?;
            let params = params.with_blend(self.seam_blend.unwrap_or(params.overlap() / 8))?;
            let (nx, ny) = (params.count(w), params.count(h));
            // Every patch is made before stitching: bound what they hold, whatever the
            // output's shape (a 2^26 × 1 output asked for 262,144 patches of 512², and
            // took the machine's 24 GB).
            let held = nx
                .checked_mul(ny)
                .and_then(|n| n.checked_mul(p * p))
                .and_then(|n| n.checked_mul(c));
            if held.is_none_or(|n| n > MAX_PATCH_VALUES) {
                return Err(Error::Limits(format!(
                    "a {w}×{h} output needs {nx}×{ny} patches of {p}×{p} px, over the budget of {MAX_PATCH_VALUES} patch values held for stitching; ask for a squarer size or a smaller `patch`"
                )));
            }
            progress(&format!(
                "stitching {nx}×{ny} RPN patches of {p}×{p} px, overlap {} px, {}",
                params.overlap(),
                match params.blend() {
                    0 => "hard-cut seams".to_string(),
                    r => format!("seams blended in bands up to {r} px"),
                }
            ));
            let patches = rpn_patches(
                (nx, ny),
                p,
                self.seed,
                |x, y| crop_of(x, y, p, p),
                |planes| finish(planes, p, p),
                (ew, eh),
                progress,
            )?;
            let mut patches: Vec<Option<Vec<f32>>> = patches.into_iter().map(Some).collect();
            let raster = stitch(w, h, c, params, |i, j, _| {
                patches[j * nx + i]
                    .take()
                    .ok_or_else(|| Error::Limits(format!("patch ({i}, {j}) asked twice")))
            })?;
            let overlap = params.overlap();
            (
                raster,
                Route::Stitched {
                    nx,
                    ny,
                    patch: p,
                    overlap,
                },
            )
        };
        Ok(SandblastOutput {
            raster: planes,
            spacing_um,
            exemplar,
            how,
        })
    }
}

/// A windowed-variance ratio ([`windowed_variance_ratio`]) further than this from 1, in
/// log10, marks a measurement as not stationary: an output with its variance then has a
/// PSD level off by more than the foundation's PSD-error threshold of 0.15.
pub const NONSTATIONARY_LOG10: f64 = crate::stats::PSD_ERROR_BAR;

/// A note for the progress lines when `heights` (one channel) is too far from
/// stationary for a stationary synthesis to match both its height distribution and its
/// spectrum within the foundation's thresholds, or None. What it costs depends on where
/// the variance sits and on the `taper`: variance in the middle (a crater, a dome) puts
/// the spectrum's level off by about |log10 r| at every frequency; variance at the
/// borders (a form) does too with [`Taper::Hann`], while [`Taper::MainLobe`] gives it back
/// at the longest wavelengths and keeps the fine spectrum and the height spread, though
/// not the form's shape.
pub fn stationarity_note(heights: &Raster, source: &str, taper: Taper) -> Option<String> {
    let r = windowed_variance_ratio(heights);
    (r.is_finite() && r.log10().abs() > NONSTATIONARY_LOG10).then(|| {
        let head = format!(
            "note: {source} is not stationary: its Hann-windowed spectrum implies {r:.2}× its height variance"
        );
        let level_off = format!(
            "a stationary synthesis matches its heights or its spectrum, not both (with its variance, a PSD error of about {:.2})",
            r.log10().abs()
        );
        if r > 1.0 {
            format!(
                "{head} (the variance sits in the middle: a crater, a dome, a central feature); {level_off}"
            )
        } else if taper == Taper::MainLobe {
            format!(
                "{head} (the variance sits at the borders: a bowl, a part's edge, form left after levelling); the main-lobe taper gives it back at the longest wavelengths, keeping the fine spectrum and the height spread but not the form's shape"
            )
        } else {
            format!(
                "{head} (the variance sits at the borders: a bowl, a part's edge, form left after levelling); {level_off}"
            )
        }
    })
}

/// Nearest-neighbour down-sampling by a real factor ≥ 1 (seed 000 §3.2): output pixel x
/// takes input pixel ⌊x·factor⌋ (for an integer factor, every factor-th sample).
pub fn downsample_nearest(r: &Raster, factor: f64, source: &str) -> Result<Raster> {
    if !(factor.is_finite() && factor >= 1.0) {
        return Err(Error::param(
            "down-sampling factor",
            factor,
            "a factor of at least 1",
        ));
    }
    let out = |n: usize| ((n as f64 / factor) + 1e-9).floor() as usize;
    let (w, h, c) = (out(r.width), out(r.height), r.channels);
    if w < crate::bake::MIN_EXEMPLAR_SIDE || h < crate::bake::MIN_EXEMPLAR_SIDE {
        return Err(Error::TooSmall {
            what: source.to_string(),
            message: format!(
                "down-sampling {}×{} by {factor:.4} leaves {w}×{h} pixels; synthesis needs at least {m}×{m} (ask for a finer spacing or a larger measurement)",
                r.width,
                r.height,
                m = crate::bake::MIN_EXEMPLAR_SIDE
            ),
        });
    }
    let at = |k: usize, n: usize| ((k as f64 * factor + 1e-9).floor() as usize).min(n - 1);
    let mut data = Vec::with_capacity(w * h * c);
    for y in 0..h {
        let sy = at(y, r.height);
        for x in 0..w {
            let sx = at(x, r.width);
            data.extend_from_slice(&r.data[(sy * r.width + sx) * c..(sy * r.width + sx + 1) * c]);
        }
    }
    Raster::from_vec(w, h, c, data)
}

/// Seed 000 §3.2's padding for RPN at a size larger than the input: the deviations from
/// the mean scaled by √(M_T N_T / M_I N_I), centred in a field of the mean, and faded
/// into it by a logistic sigmoid over the outer eighth of the smaller input side.
pub fn pad(plane: &[f64], iw: usize, ih: usize, w: usize, h: usize) -> Vec<f64> {
    let n = plane.len().max(1) as f64;
    let mean = plane.iter().sum::<f64>() / n;
    let gain = ((w * h) as f64 / (iw * ih) as f64).sqrt();
    let ramp = (iw.min(ih) as f64 / 8.0).max(1.0);
    let sigmoid = |d: f64| 1.0 / (1.0 + (-(d / ramp - 0.5) * 10.0).exp());
    let (x0, y0) = ((w.saturating_sub(iw)) / 2, (h.saturating_sub(ih)) / 2);
    let mut out = vec![mean; w * h];
    for y in 0..ih.min(h) {
        for x in 0..iw.min(w) {
            // Distance (in pixels) to the nearest border of the input, from its centre.
            let d = (x.min(iw - 1 - x).min(y).min(ih - 1 - y)) as f64 + 0.5;
            out[(y0 + y) * w + x0 + x] = mean + gain * sigmoid(d) * (plane[y * iw + x] - mean);
        }
    }
    out
}

/// RPN patches of random crops, one per patch of an `nx × ny` stitching grid, made in
/// parallel. Patch (i, j) draws its crop and phases from its own generator, seeded by
/// the hash of (seed, i, j), so the result does not depend on the thread count; crops
/// lie inside the `ew × eh` exemplar, and `finish` gets each patch's planes after RPN.
/// `progress` gets a line at each quarter of the patches done.
fn rpn_patches(
    (nx, ny): (usize, usize),
    p: usize,
    seed: u64,
    crop: impl Fn(usize, usize) -> Vec<Vec<f64>> + Sync,
    finish: impl Fn(Vec<Vec<f64>>) -> Vec<Vec<f64>> + Sync,
    (ew, eh): (usize, usize),
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<Vec<f32>>> {
    let n = nx * ny;
    let threads = crate::stream::default_threads().clamp(1, n);
    let next = std::sync::atomic::AtomicUsize::new(0);
    let make = |k: usize| {
        let (i, j) = (k % nx, k / nx);
        let hsh = hash_cell(
            seed as u32 ^ (seed >> 32) as u32,
            i as i64,
            j as i64,
            0x5B1A,
        );
        let mut rng =
            Xoshiro256PlusPlus::seed_from_u64(((hsh[0] as u64) << 32 | hsh[1] as u64) ^ seed);
        let (x0, y0) = (rng.random_range(0..=ew - p), rng.random_range(0..=eh - p));
        let planes = finish(random_phase_noise(&crop(x0, y0), p, p, &mut rng));
        interleave(&planes, p, p).map(|r| r.data)
    };
    let mut out: Vec<Option<Result<Vec<f32>>>> = (0..n).map(|_| None).collect();
    let slots = std::sync::Mutex::new(&mut out);
    let (made, done) = crossbeam::channel::unbounded::<()>();
    crossbeam::scope(|s| {
        let (make, next, slots) = (&make, &next, &slots);
        for _ in 0..threads {
            let made = made.clone();
            s.spawn(move |_| {
                loop {
                    let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    if k >= n {
                        break;
                    }
                    let patch = make(k);
                    if let Ok(mut slots) = slots.lock() {
                        slots[k] = Some(patch);
                    }
                    let _ = made.send(());
                }
            });
        }
        // This thread reports; the channel closes when the last worker ends, panicked
        // or not.
        drop(made);
        let mut quarter = 0;
        for (k, ()) in done.iter().enumerate() {
            if (k + 1) * 4 / n > quarter {
                quarter = (k + 1) * 4 / n;
                progress(&format!(
                    "RPN patches: {}/{n} ({}%)",
                    k + 1,
                    (k + 1) * 100 / n
                ));
            }
        }
    })
    .map_err(|_| Error::Limits("an RPN patch worker stopped".into()))?;
    out.into_iter()
        .map(|p| p.unwrap_or_else(|| Err(Error::Limits("an RPN patch was not made".into()))))
        .collect()
}

/// Planes (one per channel) into an interleaved raster.
fn interleave(planes: &[Vec<f64>], w: usize, h: usize) -> Result<Raster> {
    let mut r = Raster::zeros(w, h, planes.len());
    for (ch, plane) in planes.iter().enumerate() {
        r.set_channel_f64(ch, plane);
    }
    Ok(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_down_sampling_by_an_integer_keeps_every_kth_sample() {
        let r = Raster::from_vec(40, 36, 1, (0..40 * 36).map(|i| i as f32).collect()).unwrap();
        let d = downsample_nearest(&r, 2.0, "t").unwrap();
        assert_eq!((d.width, d.height), (20, 18));
        assert_eq!(d.get(3, 5, 0), r.get(6, 10, 0));
        let d = downsample_nearest(&r, 1.5, "t").unwrap();
        assert_eq!((d.width, d.height), (26, 24));
        assert_eq!(d.get(3, 5, 0), r.get(4, 7, 0));
        let e = downsample_nearest(&r, 3.0, "t").unwrap_err().to_string();
        assert!(e.contains("leaves 13×12 pixels"), "{e}");
    }

    /// The padding keeps the mean everywhere outside the input, scales the deviations by
    /// √(area ratio) in the middle of the input, and fades them towards its border.
    #[test]
    fn padding_scales_the_middle_and_fades_the_border() {
        let (iw, ih, w, h) = (32, 32, 128, 64);
        let plane: Vec<f64> = (0..iw * ih)
            .map(|i| 5.0 + ((i * 7) % 5) as f64 - 2.0)
            .collect();
        let mean = plane.iter().sum::<f64>() / plane.len() as f64;
        let out = pad(&plane, iw, ih, w, h);
        let gain = (128.0f64 * 64.0 / (32.0 * 32.0)).sqrt();
        assert_eq!(out[0], mean);
        assert_eq!(out[(h - 1) * w + w - 1], mean);
        let (x0, y0) = (48, 16);
        let mid = (y0 + 16) * w + x0 + 16;
        let dev = plane[16 * iw + 16] - mean;
        assert!((out[mid] - mean - gain * dev).abs() < 1e-3 * gain * dev.abs().max(1.0));
        let edge = y0 * w + x0 + 16;
        let dev_edge = plane[16] - mean;
        assert!((out[edge] - mean).abs() < 0.1 * gain * dev_edge.abs().max(1e-9));
    }
}
