//! Quality figures (DESIGN.md, "Quality figures"): what tests, benches and
//! `surftile stats` use to call a texture good, never the eye alone.
//!
//! The height figures take single-channel rasters; the [`structure`] figures take every
//! channel.

use rustfft::num_complex::Complex64;
use serde::Serialize;

use crate::fft::{RealFft2, half_spectrum_copies};
use crate::raster::Raster;

pub mod structure;

pub use structure::{PhaseSeams, SeamNoise, StructureFigures, seam_any_phase, seam_noise};

/// The ACF threshold of ISO 25178's Sal and Str.
const ACF_THRESHOLD: f64 = 0.2;
/// Radial PSD bins are merged from low frequency up until each holds this many samples.
const PSD_MIN_BIN_SAMPLES: usize = 32;
/// The foundation issue's fidelity bar on the standardised height-histogram W1.
pub const W1_BAR: f64 = 0.05;
/// The foundation issue's fidelity bar on the PSD error.
pub const PSD_ERROR_BAR: f64 = 0.15;

/// Areal roughness parameters (ISO 25178) of one height map, in its height unit;
/// lengths in pixels.
#[derive(Clone, Debug, Serialize)]
pub struct HeightStats {
    /// Mean height.
    pub mean: f64,
    /// Root-mean-square height about the mean.
    pub sq: f64,
    /// Arithmetic mean absolute height about the mean.
    pub sa: f64,
    /// Skewness.
    pub ssk: f64,
    /// Kurtosis (3 for a Gaussian).
    pub sku: f64,
    /// Maximum height: highest peak minus lowest valley.
    pub sz: f64,
    /// Autocorrelation length: shortest lag at which the normalised ACF falls to 0.2 (px).
    pub sal: f64,
    /// Texture aspect ratio: Sal over the longest such lag (1 = isotropic).
    pub str: f64,
    /// Repetition score, [`Acf::repetition`]: highest normalised ACF at lags beyond twice
    /// the decay length of their direction (≈ 1 for a periodic texture, near 0 for one
    /// that does not repeat).
    pub repetition: f64,
    /// Stationarity check, [`windowed_variance_ratio`]: 1 when the height variance is
    /// spread evenly; far from 1 when it sits in the middle or at the borders.
    pub windowed_variance_ratio: f64,
}

/// Everything `surftile stats A B` reports.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// Figures of A (the exemplar).
    pub a: HeightStats,
    /// Figures of B (the synthesis).
    pub b: HeightStats,
    /// 1-Wasserstein distance between the height histograms, both standardised by A's
    /// mean and standard deviation.
    pub w1: f64,
    /// RMS over radial bins of log10 P_B − log10 P_A (0 = same spectrum).
    pub psd_error: f64,
    /// What the PSD error reads for A's own content shown evenly ([`psd_error_even`]):
    /// where B misses a PSD bar by no more, the miss is A's. With the patch figures.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub psd_error_even: Option<f64>,
    /// Seam score of B on square cells of `cell` px (1.0 = invisible seams), if asked.
    pub seam_score: Option<f64>,
    /// The cell size the seam score used.
    pub cell: Option<usize>,
    /// Patch figures over every channel ([`structure::structure`]), when computed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub structure: Option<StructureFigures>,
    /// The regions of A and B the patch figures were measured on, when computed
    /// ([`STRUCTURE_SIDE_A`], [`STRUCTURE_SIDE_B`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub structure_regions: Option<StructureRegions>,
}

/// The largest side of A that [`compare_maps`] measures the patch figures on: a larger
/// A gives its central square of this side. Their nearest-neighbour searches grow faster
/// than the product of both maps' pixels (two 512² fractal maps took 7 s on 2 cores, two
/// 1024² maps 84 s, two 4096² maps more than 9 minutes); 512² of A against 1024² of B
/// took 25 s. [`structure::structure`] itself takes whole maps.
pub const STRUCTURE_SIDE_A: usize = 512;
/// The largest side of B that [`compare_maps`] measures the patch figures on: a larger
/// B gives its top-left square of this side, so the seams' offsets keep B's phase.
pub const STRUCTURE_SIDE_B: usize = 1024;

/// Where the patch figures were measured: `[x, y, width, height]` in A and in B.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct StructureRegions {
    /// The region of A.
    pub a: [usize; 4],
    /// The region of B.
    pub b: [usize; 4],
}

impl StructureRegions {
    /// The regions [`compare_maps`] takes in maps of these sizes.
    pub fn of(a: (usize, usize), b: (usize, usize)) -> StructureRegions {
        let (wa, ha) = (a.0.min(STRUCTURE_SIDE_A), a.1.min(STRUCTURE_SIDE_A));
        StructureRegions {
            a: [(a.0 - wa) / 2, (a.1 - ha) / 2, wa, ha],
            b: [0, 0, b.0.min(STRUCTURE_SIDE_B), b.1.min(STRUCTURE_SIDE_B)],
        }
    }

    /// Whether either map is measured on less than its whole.
    pub fn cropped(&self, a: (usize, usize), b: (usize, usize)) -> bool {
        (self.a[2], self.a[3]) != a || (self.b[2], self.b[3]) != b
    }
}

/// The operators that made a scale-limited surface (ISO 25178-3), as `surftile stats`
/// names them in its JSON.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Operators {
    /// The F-operator: `poly:N`, `plane` or `none`.
    pub f: String,
    /// The L-filter: the Gaussian's cut-off in µm, or `None`.
    pub l: Option<String>,
}

impl Operators {
    /// The operators of form removal `level` (`auto` is the plane on a height map) and
    /// an L-filter at `lfilter_um`.
    pub fn new(level: crate::prep::Leveling, lfilter_um: Option<f64>) -> Operators {
        Operators {
            f: level.for_heights().to_string(),
            l: lfilter_um.map(|l| {
                format!("gaussian λc = {l} µm (ISO 16610-61, zeroth-order regression at edges)")
            }),
        }
    }
}

/// Smallest side `compare_maps` takes: the PSD error's smallest window.
pub const MIN_STATS_SIDE: usize = 8;

/// Options of [`compare_maps`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompareOptions {
    /// Cell size in pixels of B's seam score (and the phase seams of the structure
    /// figures); `None`: their defaults.
    pub cell: Option<usize>,
    /// Form removal (the F-operator) of the height figures' channel 0: `auto` and
    /// `plane` subtract the least-squares plane, `poly:N` a polynomial, `none` nothing.
    /// The patch figures see height maps so, and colour as it is.
    pub leveling: crate::prep::Leveling,
    /// Fill missing points smoothly instead of refusing a map with any.
    pub fill_missing: bool,
    /// Gaussian L-filter cut-offs of the height figures in pixels, (x, y) for A then
    /// for B (each map's own spacing), or `None`: no filter.
    pub lfilter_px: Option<[(f64, f64); 2]>,
    /// Compute the structure (patch) figures too.
    pub structure: bool,
}

/// The figures of `b` (a synthesis, named `what_b`) against `a` (an exemplar), as
/// `surftile stats` prints them: both maps preprocessed alike ([`crate::prep::Prep`]),
/// the height figures on channel 0, the patch figures on all channels. Refuses a cell
/// of 0, maps under [`MIN_STATS_SIDE`], a flat A, and channel counts that differ when
/// the structure figures are asked for.
pub fn compare_maps(
    (a, what_a): (&Raster, &str),
    (b, what_b): (&Raster, &str),
    options: &CompareOptions,
) -> crate::Result<Comparison> {
    use crate::error::Error;
    use crate::prep::{Leveling, Prep};
    if options.cell == Some(0) {
        return Err(Error::param("cell", 0, "a cell size of at least 1 pixel"));
    }
    let levelled = options.leveling != Leveling::None;
    // The height figures read channel 0 as a scale-limited surface: form removed as
    // asked (any polynomial degree; `auto` is the plane) and the L-filter where asked,
    // over the defined points, then missing points filled or refused. The patch
    // figures read height maps so, and colour with its missing points filled.
    let height_channel = |full: &Raster, what: &str, k: usize| {
        crate::prep::scale_limited(
            &full.channel(0),
            what,
            options.leveling,
            options.lfilter_px.map(|l| l[k]),
            options.fill_missing,
        )
    };
    // Sizes first: scale-limiting keeps them, and filtering a map to refuse it is waste.
    check_side(a, what_a)?;
    check_side(b, what_b)?;
    let (ra, rb) = (height_channel(a, what_a, 0)?, height_channel(b, what_b, 1)?);
    let (full_a, full_b) = if a.channels == 1 && b.channels == 1 {
        (ra.clone(), rb.clone())
    } else {
        let prep = Prep {
            fill_missing: options.fill_missing,
            leveling: Leveling::None,
            ..Prep::default()
        };
        (prep.apply(a, what_a)?, prep.apply(b, what_b)?)
    };
    if ra.data.iter().all(|&v| v == ra.data[0]) {
        return Err(Error::Analysis {
            what: what_a.to_string(),
            message: format!(
                "A is flat (every height {}{}): W1 and the PSD error measure B against A's spread and spectrum, so A must vary",
                ra.data[0],
                if levelled { " after levelling" } else { "" }
            ),
        });
    }
    let mut figures = compare(&ra, &rb, options.cell);
    if options.structure {
        if full_a.channels != full_b.channels {
            return Err(Error::param(
                "B's channels",
                full_b.channels,
                format!(
                    "{} like A, for the patch figures (or skip them: `no_structure`)",
                    full_a.channels
                ),
            ));
        }
        let regions =
            StructureRegions::of((full_a.width, full_a.height), (full_b.width, full_b.height));
        let crop = |r: &Raster, [x, y, w, h]: [usize; 4]| r.crop(x, y, w, h);
        figures.structure = Some(structure::structure(
            &crop(&full_a, regions.a)?,
            &crop(&full_b, regions.b)?,
            options.cell,
        ));
        figures.structure_regions = Some(regions);
        figures.psd_error_even = Some(psd_error_even(&ra));
    }
    Ok(figures)
}

/// The ISO 25178 figures ([`HeightStats`]) of one height map on its scale-limited
/// surface ([`crate::prep::scale_limited`]: form removed by `form`, waviness by the
/// L-filter where `lfilter_px` gives cut-offs in pixels along x and y, then missing
/// points filled or refused). Refuses maps under [`MIN_STATS_SIDE`] and maps of more
/// than one channel.
pub fn describe_map(
    raster: &Raster,
    what: &str,
    form: crate::prep::Leveling,
    lfilter_px: Option<(f64, f64)>,
    fill_missing: bool,
) -> crate::Result<HeightStats> {
    use crate::error::Error;
    if raster.channels != 1 {
        return Err(Error::param(
            "map",
            format!("{} channels", raster.channels),
            "a height map (one channel) for its ISO 25178 parameters",
        ));
    }
    check_side(raster, what)?;
    let r = crate::prep::scale_limited(raster, what, form, lfilter_px, fill_missing)?;
    Ok(height_stats(&r))
}

/// Refuses a map under [`MIN_STATS_SIDE`] on a side.
fn check_side(r: &Raster, what: &str) -> crate::Result<()> {
    if r.width < MIN_STATS_SIDE || r.height < MIN_STATS_SIDE {
        return Err(crate::error::Error::TooSmall {
            what: what.to_string(),
            message: format!(
                "{}×{} pixels; stats needs at least {MIN_STATS_SIDE}×{MIN_STATS_SIDE} (the PSD error's smallest window)",
                r.width, r.height
            ),
        });
    }
    Ok(())
}

/// Compares exemplar `a` with synthesis `b`.
pub fn compare(a: &Raster, b: &Raster, cell: Option<usize>) -> Comparison {
    Comparison {
        a: height_stats(a),
        b: height_stats(b),
        w1: wasserstein1_standardised(a, b),
        psd_error: psd_error(a, b),
        psd_error_even: None,
        seam_score: cell.map(|n| seam_score(b, n)),
        cell,
        structure: None,
        structure_regions: None,
    }
}

fn moments(v: &[f32]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let mean = v.iter().map(|&x| x as f64).sum::<f64>() / n;
    let var = v.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / n;
    (mean, var.sqrt())
}

/// Roughness parameters of a height map.
pub fn height_stats(r: &Raster) -> HeightStats {
    let v = &r.data;
    let n = v.len().max(1) as f64;
    let (mean, sq) = moments(v);
    let sa = v.iter().map(|&x| (x as f64 - mean).abs()).sum::<f64>() / n;
    let m3 = v.iter().map(|&x| (x as f64 - mean).powi(3)).sum::<f64>() / n;
    let m4 = v.iter().map(|&x| (x as f64 - mean).powi(4)).sum::<f64>() / n;
    let (lo, hi) = v
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, u), &x| (l.min(x), u.max(x)));
    let acf = Acf::new(r);
    let profile = acf.decay_profile();
    let (sal, longest) = shortest_longest(&profile);
    let repetition = acf.repetition(&profile);
    let safe = |x: f64| if x.is_finite() { x } else { 0.0 };
    HeightStats {
        mean,
        sq,
        sa,
        ssk: safe(m3 / sq.powi(3)),
        sku: safe(m4 / sq.powi(4)),
        sz: (hi - lo) as f64,
        sal,
        str: if longest > 0.0 { sal / longest } else { 0.0 },
        repetition,
        windowed_variance_ratio: safe(windowed_variance_ratio(r)),
    }
}

/// The variance a map's Hann-windowed spectrum implies (Welch's estimate: the mean square
/// of the windowed deviations over the window's own mean square, 9/64 for the separable
/// Hann window) divided by its plain variance. A stationary map gives about 1, whatever
/// the window weights; a map whose variance sits in the middle (a crater, a dome) gives
/// more, one whose variance sits at the borders (a bowl, a part's edge) less.
///
/// It bounds what a stationary synthesis can do: the PSD error compares Hann-windowed
/// spectra, W1 plain height distributions, so an output with the map's variance is off
/// by about |log10 r| in PSD level, and one with its windowed spectrum off by the factor
/// √r in height spread. NaN for a flat map.
pub fn windowed_variance_ratio(r: &Raster) -> f64 {
    let (w, h) = (r.width, r.height);
    let (mean, sd) = moments(&r.data);
    let hann = |n: usize| -> Vec<f64> { (0..n).map(|i| crate::fft::hann(i, n)).collect() };
    let (wx, wy) = (hann(w), hann(h));
    let mean_sq = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>() / v.len().max(1) as f64;
    let norm = mean_sq(&wx) * mean_sq(&wy);
    let mut acc = 0.0;
    for (y, wy) in wy.iter().enumerate() {
        for (x, wx) in wx.iter().enumerate() {
            acc += ((r.get(x, y, 0) as f64 - mean) * wx * wy).powi(2);
        }
    }
    let welch = acc / (w * h).max(1) as f64 / norm;
    welch / (sd * sd)
}

/// Normalised autocorrelation of a height map, from a zero-padded FFT.
pub struct Acf {
    w: usize,
    h: usize,
    pw: usize,
    ph: usize,
    /// Raw lag sums, periodic index on the padded grid.
    raw: Vec<f64>,
    zero_lag: f64,
}

impl Acf {
    /// The ACF of `r` (mean removed).
    pub fn new(r: &Raster) -> Acf {
        let (w, h) = (r.width, r.height);
        let (pw, ph) = (2 * w, 2 * h);
        let (mean, _) = moments(&r.data);
        let mut padded = vec![0.0; pw * ph];
        for y in 0..h {
            for x in 0..w {
                padded[y * pw + x] = r.get(x, y, 0) as f64 - mean;
            }
        }
        // Half spectra: a real plane's power spectrum is its own mirror image.
        let mut plan = RealFft2::new(pw, ph);
        let mut spec = plan.forward(&padded);
        drop(padded);
        for s in &mut spec {
            *s = Complex64::new(s.norm_sqr(), 0.0);
        }
        let raw = plan.inverse(spec);
        let zero_lag = raw[0];
        Acf {
            w,
            h,
            pw,
            ph,
            raw,
            zero_lag,
        }
    }

    fn raw_at(&self, dx: i64, dy: i64) -> f64 {
        let x = dx.rem_euclid(self.pw as i64) as usize;
        let y = dy.rem_euclid(self.ph as i64) as usize;
        self.raw[y * self.pw + x]
    }

    /// Biased normalised ACF at an integer lag (1 at lag 0), as ISO 25178 defines it.
    pub fn at(&self, dx: i64, dy: i64) -> f64 {
        if self.zero_lag <= 0.0 {
            return 0.0;
        }
        self.raw_at(dx, dy) / self.zero_lag
    }

    /// Unbiased normalised ACF: each lag divided by its number of overlapping pairs.
    pub fn unbiased(&self, dx: i64, dy: i64) -> f64 {
        let overlap = (self.w as i64 - dx.abs()) * (self.h as i64 - dy.abs());
        if overlap <= 0 || self.zero_lag <= 0.0 {
            return 0.0;
        }
        let n = (self.w * self.h) as f64;
        self.raw_at(dx, dy) / overlap as f64 / (self.zero_lag / n)
    }

    fn bilinear(&self, x: f64, y: f64) -> f64 {
        let (x0, y0) = (x.floor(), y.floor());
        let (tx, ty) = (x - x0, y - y0);
        let (ix, iy) = (x0 as i64, y0 as i64);
        let a = self.at(ix, iy) * (1.0 - tx) + self.at(ix + 1, iy) * tx;
        let b = self.at(ix, iy + 1) * (1.0 - tx) + self.at(ix + 1, iy + 1) * tx;
        a * (1.0 - ty) + b * ty
    }

    /// Distance at which the ACF first falls to 0.2 in each whole degree of direction
    /// 0°–179° (x towards y), in pixels; a direction that never falls within half the
    /// map's smaller side counts as that half side.
    pub fn decay_profile(&self) -> [f64; 180] {
        let r_max = (self.w.min(self.h) / 2) as f64;
        std::array::from_fn(|deg| {
            let th = (deg as f64).to_radians();
            let (c, s) = (th.cos(), th.sin());
            let mut prev = (0.0, 1.0);
            let mut r = 0.5;
            while r <= r_max {
                let v = self.bilinear(r * c, r * s);
                if v <= ACF_THRESHOLD {
                    let (r0, v0) = prev;
                    return r0 + (r - r0) * (v0 - ACF_THRESHOLD) / (v0 - v).max(1e-12);
                }
                prev = (r, v);
                r += 0.5;
            }
            r_max
        })
    }

    /// (shortest, longest) of [`Acf::decay_profile`]: Sal and the longest decay length.
    pub fn decay_lengths(&self) -> (f64, f64) {
        shortest_longest(&self.decay_profile())
    }

    /// The repetition score: the highest unbiased normalised ACF at lags longer than
    /// twice the decay length of their own direction (`profile`, from
    /// [`Acf::decay_profile`]) and within half the map in each axis.
    ///
    /// DESIGN.md says "at lags beyond Sal". Just past a decay length the ACF is 0.2 by
    /// that length's definition, so that score cannot fall below about 0.2 for any
    /// texture, and a repetition weaker than 0.2 — a small measurement's structure
    /// coming back, seed 000 Fig. 8 — cannot be seen. At twice its decay length an
    /// exponential ACF, the slowest-decaying of the usual roughness models, is down to
    /// 0.2² = 0.04 (a Gaussian one to 0.2⁴), so a texture that does not repeat scores
    /// the estimator's noise and one that does scores the height of its returning peak.
    /// Measuring in each lag's own direction keeps a lay (a direction in which the ACF
    /// never decays) from hiding a repetition across it. The estimator's noise sets the
    /// floor, higher on smaller maps: about 0.06 for 512² of noise with a 7 px decay
    /// length, 0.18 for 256².
    pub fn repetition(&self, profile: &[f64; 180]) -> f64 {
        self.max_where(|dx, dy| {
            let r = ((dx * dx + dy * dy) as f64).sqrt();
            let deg = (dy as f64).atan2(dx as f64).to_degrees().round() as usize % 180;
            r > 2.0 * profile[deg]
        })
    }

    fn max_where(&self, keep: impl Fn(i64, i64) -> bool) -> f64 {
        let (hx, hy) = ((self.w / 2) as i64, (self.h / 2) as i64);
        let mut best = f64::MIN;
        for dy in 0..=hy {
            for dx in -hx..=hx {
                if keep(dx, dy) {
                    best = best.max(self.unbiased(dx, dy));
                }
            }
        }
        if best == f64::MIN { 0.0 } else { best }
    }
}

/// FFT index `k` of an `n`-point transform as a signed frequency: k up to n/2, k − n
/// above.
fn signed_frequency(k: usize, n: usize) -> f64 {
    if k <= n / 2 {
        k as f64
    } else {
        k as f64 - n as f64
    }
}

fn shortest_longest(profile: &[f64; 180]) -> (f64, f64) {
    profile
        .iter()
        .fold((f64::MAX, 0.0f64), |(lo, hi), &l| (lo.min(l), hi.max(l)))
}

/// The value figures of issue 31 for synthesis `out` against `exemplar`, over their
/// shared channels: the worst channel's [`wasserstein1_standardised`] and the standard
/// deviation ratio (out over exemplar) of the channel farthest from 1. The bars are
/// W1 < 0.05 and a ratio within 5% (docs/structure.md).
pub fn value_figures(exemplar: &Raster, out: &Raster) -> (f64, f64) {
    let (mut w1, mut ratio) = (0.0f64, 1.0f64);
    for k in 0..exemplar.channels.min(out.channels) {
        let (a, b) = (exemplar.channel(k), out.channel(k));
        w1 = w1.max(wasserstein1_standardised(&a, &b));
        let r = moments(&b.data).1 / moments(&a.data).1;
        if (r - 1.0).abs() > (ratio - 1.0).abs() {
            ratio = r;
        }
    }
    (w1, ratio)
}

/// 1-Wasserstein distance between the empirical height distributions of `a` and `b`,
/// both standardised by a's mean and standard deviation (exact, by merging the sorted
/// samples).
pub fn wasserstein1_standardised(a: &Raster, b: &Raster) -> f64 {
    let (mean, sd) = moments(&a.data);
    let sd = if sd > 0.0 { sd } else { 1.0 };
    // Sorted as the f32 they are (a radix sort of 4-byte keys), then standardised: the
    // map is increasing, so the order is the same.
    let prep = |r: &Raster| {
        let mut v = r.data.clone();
        radsort::sort(&mut v);
        v.iter()
            .map(|&x| (x as f64 - mean) / sd)
            .collect::<Vec<f64>>()
    };
    wasserstein1_sorted(&prep(a), &prep(b))
}

/// W1 = ∫ |F_a(t) − F_b(t)| dt for two ascending samples.
pub fn wasserstein1_sorted(a: &[f64], b: &[f64]) -> f64 {
    if a.is_empty() || b.is_empty() {
        return 0.0;
    }
    let (na, nb) = (a.len() as f64, b.len() as f64);
    let (mut i, mut j) = (0usize, 0usize);
    let mut prev = a[0].min(b[0]);
    let mut acc = 0.0;
    while i < a.len() || j < b.len() {
        let next = a
            .get(i)
            .copied()
            .unwrap_or(f64::INFINITY)
            .min(b.get(j).copied().unwrap_or(f64::INFINITY));
        acc += (i as f64 / na - j as f64 / nb).abs() * (next - prev);
        prev = next;
        while i < a.len() && a[i] == next {
            i += 1;
        }
        while j < b.len() && b[j] == next {
            j += 1;
        }
    }
    acc
}

/// Where the windows of side `n` start along an axis of `len` pixels (Welch's method):
/// the first flush with one edge, the last flush with the other, evenly spaced at most
/// n/2 apart (50% overlap), and at most `per_axis` of them. Every pixel of a map whose
/// side is not a multiple of `n` counts (a 127 × 80 exemplar was measured on its left
/// 80 × 80 square alone), and a large map is sampled across its whole extent.
fn window_starts(len: usize, n: usize, per_axis: usize) -> Vec<usize> {
    if n == 0 || len < n || per_axis == 0 {
        return Vec::new();
    }
    let k = ((len - n).div_ceil((n / 2).max(1)) + 1).min(per_axis);
    if k == 1 {
        return vec![(len - n) / 2];
    }
    (0..k).map(|i| i * (len - n) / (k - 1)).collect()
}

/// Radially averaged power spectrum of square `n × n` windows of `r` (mean removed, Hann
/// window), averaged over the windows of [`window_starts`] (up to `per_axis` per axis).
/// Returns the mean power per integer radius 0..=n/2 and the number of frequencies per
/// radius in one window.
fn radial_psd(r: &Raster, n: usize, per_axis: usize) -> (Vec<f64>, Vec<usize>) {
    let xs = window_starts(r.width, n, per_axis);
    let corners: Vec<(usize, usize)> = window_starts(r.height, n, per_axis)
        .into_iter()
        .flat_map(|wy| xs.iter().map(move |&wx| (wx, wy)))
        .collect();
    radial_psd_at(n, &corners, |x, y| r.get(x, y, 0) as f64)
}

/// [`radial_psd`] over the `n × n` windows whose top-left corners are `corners`, of the
/// plane whose value at (x, y) is `value(x, y)`.
fn radial_psd_at(
    n: usize,
    corners: &[(usize, usize)],
    value: impl Fn(usize, usize) -> f64,
) -> (Vec<f64>, Vec<usize>) {
    let hann: Vec<f64> = (0..n).map(|i| crate::fft::hann(i, n)).collect();
    // Half spectra (real FFTs): each column that stands for its mirror image too counts
    // twice. Each frequency's radius bin and weight, once for every window.
    let mut plan = RealFft2::new(n, n);
    let hw = plan.half_width();
    let bins = n / 2 + 1;
    let mut power = vec![0.0; bins];
    let mut count = vec![0usize; bins];
    let copies = |kx: usize| half_spectrum_copies(kx, n);
    // u32::MAX: outside the bins.
    let bin_of: Vec<u32> = (0..n * hw)
        .map(|i| {
            let rad = ((i % hw) as f64).hypot(signed_frequency(i / hw, n));
            if rad >= 1.0 && rad <= (n / 2) as f64 {
                rad as u32
            } else {
                u32::MAX
            }
        })
        .collect();
    for (i, &bin) in bin_of.iter().enumerate() {
        if bin != u32::MAX {
            count[bin as usize] += copies(i % hw);
        }
    }
    for &corner in corners {
        let spec = plan.forward(&tapered_window(&value, corner, &hann));
        for (row, bins) in spec.chunks_exact(hw).zip(bin_of.chunks_exact(hw)) {
            for (kx, (s, &bin)) in row.iter().zip(bins).enumerate() {
                if bin != u32::MAX {
                    power[bin as usize] += copies(kx) as f64 * s.norm_sqr();
                }
            }
        }
    }
    for (p, &c) in power.iter_mut().zip(&count) {
        if c > 0 {
            *p /= (c * corners.len().max(1)) as f64;
        }
    }
    (power, count)
}

/// The `n × n` window (n = `hann.len()`) at `(x0, y0)` of the plane `value`, its mean
/// removed and tapered by the separable window `hann`.
fn tapered_window(
    value: impl Fn(usize, usize) -> f64,
    (x0, y0): (usize, usize),
    hann: &[f64],
) -> Vec<f64> {
    let n = hann.len();
    let mut win: Vec<f64> = (0..n * n).map(|i| value(x0 + i % n, y0 + i / n)).collect();
    let m = win.iter().sum::<f64>() / (n * n) as f64;
    for (i, v) in win.iter_mut().enumerate() {
        *v = (*v - m) * hann[i % n] * hann[i / n];
    }
    win
}

/// Log–log slope of the radially averaged power spectrum of `r` (mean over up to 8 × 8
/// square `window × window` windows, Hann-tapered, [`window_starts`]), fitted by least squares over the
/// integer radii in [k_lo, k_hi] (cycles per window), each radius weighted equally in
/// log k by binning into 24 log-spaced bins. A surface whose spectrum falls as k^−β
/// gives −β.
pub fn psd_slope(r: &Raster, window: usize, (k_lo, k_hi): (f64, f64)) -> f64 {
    let (power, _) = radial_psd(r, window, 8);
    let (lo, hi) = (k_lo.max(1.0).ln(), k_hi.min((window / 2) as f64).ln());
    let nb = 24;
    let mut bins = vec![(0.0f64, 0.0f64, 0usize); nb];
    for (k, &p) in power.iter().enumerate().skip(1) {
        let lk = (k as f64).ln();
        if lk < lo || lk > hi || p <= 0.0 {
            continue;
        }
        let b = (((lk - lo) / (hi - lo)) * nb as f64).min(nb as f64 - 1.0) as usize;
        bins[b].0 += lk;
        bins[b].1 += p.ln();
        bins[b].2 += 1;
    }
    let pts: Vec<(f64, f64)> = bins
        .iter()
        .filter(|b| b.2 > 0)
        .map(|b| (b.0 / b.2 as f64, b.1 / b.2 as f64))
        .collect();
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx
}

/// The foundation issue's fidelity bars for a synthesis of `exemplar`: a small or uneven
/// map can differ from itself by more than [`W1_BAR`] and [`PSD_ERROR_BAR`], so its two
/// halves are compared by the same figures, and where that self-difference is larger the
/// bar is 1.2× it.
///
/// The halves are taken both ways, top against bottom and left against right, and each
/// figure keeps the larger of its two differences. Halves cut along a lay are not two
/// samples of the surface: plu-1's grooves run from top to bottom, so its top and bottom
/// halves hold the same grooves and differ by a PSD error of about 0.06, while its left
/// and right halves, different grooves, differ by 0.27. With the top and bottom alone
/// the bar depended on how the map was turned: the same map turned by 90° got 0.32
/// instead of 0.15.
#[derive(Clone, Copy, Debug)]
pub struct FidelityBars {
    /// W1 between the exemplar's halves: the larger of top against bottom and left
    /// against right (NaN under 2 × 2).
    pub w1_self: f64,
    /// PSD error between the exemplar's halves, the larger of the two cuts where both
    /// can be measured (NaN where no half is 8 px a side).
    pub psd_self: f64,
    /// The bar on the standardised height-histogram W1.
    pub w1: f64,
    /// The bar on the PSD error.
    pub psd: f64,
}

/// [`FidelityBars`] of one exemplar.
pub fn fidelity_bars(exemplar: &Raster) -> FidelityBars {
    let (w, h) = (exemplar.width, exemplar.height);
    let cuts = [
        (
            exemplar.crop(0, 0, w, h / 2),
            exemplar.crop(0, h / 2, w, h - h / 2),
        ),
        (
            exemplar.crop(0, 0, w / 2, h),
            exemplar.crop(w / 2, 0, w - w / 2, h),
        ),
    ];
    let differences: Vec<(f64, f64)> = cuts
        .into_iter()
        .map(|halves| match halves {
            (Ok(a), Ok(b)) if w >= 2 && h >= 2 => {
                (wasserstein1_standardised(&a, &b), psd_error(&a, &b))
            }
            _ => (f64::NAN, f64::NAN),
        })
        .collect();
    // f64::max keeps the cut that could be measured where the other could not (a half
    // under 8 px a side has no PSD error).
    let w1_self = differences[0].0.max(differences[1].0);
    let psd_self = differences[0].1.max(differences[1].1);
    FidelityBars {
        w1_self,
        psd_self,
        // f64::max takes the floor where the self-difference is NaN.
        w1: W1_BAR.max(1.2 * w1_self),
        psd: PSD_ERROR_BAR.max(1.2 * psd_self),
    }
}

/// PSD error (DESIGN.md): on equal-size square windows of a and b (side = the smallest
/// side of either; Welch's 50%-overlapping windows, [`window_starts`]), radially average the power spectra, merge low-frequency bins until
/// each holds ≥ 32 samples, and take the RMS over bins of log10 P_b − log10 P_a.
pub fn psd_error(a: &Raster, b: &Raster) -> f64 {
    let n = a.width.min(a.height).min(b.width).min(b.height);
    if n < 8 {
        return f64::NAN;
    }
    let (pa, counts) = radial_psd(a, n, 8);
    let (pb, _) = radial_psd(b, n, 8);
    log_rms_of_mean_spectra(&pa, &pb, &counts)
}

/// Placements per axis of the windows [`psd_error_even`] lays over an exemplar's period
/// whose shorter side is at most [`EVEN_FULL_SIDE`]: as many as [`psd_error`] takes at
/// most (16 read the same to 0.001 on the photos of docs/structure.md).
const EVEN_PLACEMENTS: usize = 8;
/// Above this shorter side, [`psd_error_even`] takes 4 × 4 placements, so that a 4096²
/// map costs it 16 FFTs of 4096² (13 s on 2 cores; 8 × 8 took 44 s). On the photos of
/// docs/structure.md 4 × 4 reads within 0.014 of 8 × 8, and mostly within 0.004.
const EVEN_FULL_SIDE: usize = 512;

/// The PSD error ([`psd_error`], channel 0) that the exemplar's own content reads
/// against the exemplar when every part of it is shown equally often: what an exact,
/// even reproduction of `exemplar` would read.
///
/// [`psd_error`] estimates the exemplar's spectrum on its own windows, of its shorter
/// side (the synthesis's side where that is shorter). An exemplar no larger than one
/// window has one, and the Hann taper weighs its middle: where the middle is smoother or
/// rougher than the edges, a synthesis that shows the edges as often as the middle
/// differs from that estimate however faithful it is. Here windows of the exemplar's
/// shorter side lie at 8 × 8 evenly spaced offsets (4 × 4 over [`EVEN_FULL_SIDE`] px)
/// over the exemplar's period: its torus along an axis where it tiles
/// ([`crate::prep::level::tiles_along`]), the exemplar and its mirror image along the
/// others, so that no window crosses a jump. Their mean spectrum is compared with the
/// exemplar's estimate. Where a synthesis misses the PSD bar by no more than this
/// figure reads, the miss is the exemplar's. It is not a lower bound: a synthesis that
/// shows the exemplar's middle more often than its edges reads less. NaN under 8 px a
/// side.
pub fn psd_error_even(exemplar: &Raster) -> f64 {
    let (w, h) = (exemplar.width, exemplar.height);
    let n = w.min(h);
    if n < 8 {
        return f64::NAN;
    }
    let (pa, counts) = radial_psd(exemplar, n, EVEN_PLACEMENTS);
    let tiles = |axis: usize| crate::prep::level::tiles_along(exemplar, axis);
    // The period along an axis: the side where it tiles, else the side and its mirror.
    let (px, py) = (
        if tiles(0) { w } else { 2 * w },
        if tiles(1) { h } else { 2 * h },
    );
    // Sample i of a period p over a side of len: wrapped, then mirrored past the side.
    let at = |i: usize, len: usize, p: usize| {
        let m = i % p;
        if m < len { m } else { p - 1 - m }
    };
    let per_axis = if n <= EVEN_FULL_SIDE {
        EVEN_PLACEMENTS
    } else {
        EVEN_PLACEMENTS / 2
    };
    let offsets = |p: usize| -> Vec<usize> {
        let k = per_axis.min(p);
        (0..k).map(|i| i * p / k).collect()
    };
    let xs = offsets(px);
    let corners: Vec<(usize, usize)> = offsets(py)
        .into_iter()
        .flat_map(|y| xs.iter().map(move |&x| (x, y)))
        .collect();
    let (pb, _) = radial_psd_at(n, &corners, |x, y| {
        exemplar.get(at(x, w, px), at(y, h, py), 0) as f64
    });
    log_rms_of_mean_spectra(&pa, &pb, &counts)
}

/// The PSD error's comparison of a periodic spectrum `b` with a target modulus `a`, both
/// half spectra of real `w × h` planes ([`crate::fft::RealFft2`]: columns kx = 0 … w/2,
/// no window): power summed over integer radial bins, each column that stands for its
/// mirror image too counted twice, radii scaled so the smaller side's frequencies are
/// whole numbers, bins merged as [`psd_error`] does. What IAAFT uses to judge how far a
/// projection left the modulus it had to keep.
pub fn spectrum_log_error(a: &[f64], b: &[Complex64], w: usize, h: usize) -> f64 {
    let hw = w / 2 + 1;
    let side = w.min(h) as f64;
    let bins = w.min(h) / 2 + 1;
    let (mut sa, mut sb, mut counts) = (vec![0.0; bins], vec![0.0; bins], vec![0usize; bins]);
    for ky in 0..h {
        let fy = signed_frequency(ky, h) * side / h as f64;
        for kx in 0..hw {
            let fx = kx as f64 * side / w as f64;
            let rad = (fx * fx + fy * fy).sqrt();
            if rad >= 1.0 && (rad as usize) < bins {
                let copies = half_spectrum_copies(kx, w);
                let i = ky * hw + kx;
                sa[rad as usize] += (copies as f64) * a[i] * a[i];
                sb[rad as usize] += (copies as f64) * b[i].norm_sqr();
                counts[rad as usize] += copies;
            }
        }
    }
    log_rms_over_merged_bins(&sa, &sb, &counts)
}

/// [`log_rms_over_merged_bins`] from per-bin mean powers (as [`radial_psd`] gives them)
/// and the bins' sample counts.
fn log_rms_of_mean_spectra(mean_a: &[f64], mean_b: &[f64], counts: &[usize]) -> f64 {
    let sum =
        |p: &[f64]| -> Vec<f64> { p.iter().zip(counts).map(|(p, &c)| p * c as f64).collect() };
    log_rms_over_merged_bins(&sum(mean_a), &sum(mean_b), counts)
}

/// RMS over radial bins of log10 B − log10 A, from per-bin power sums, low-frequency
/// bins merged until each holds ≥ 32 samples; bin 0 (the mean) is left out. NaN when
/// no bin has power on both sides.
fn log_rms_over_merged_bins(sum_a: &[f64], sum_b: &[f64], counts: &[usize]) -> f64 {
    let (mut sq, mut bins) = (0.0, 0usize);
    let (mut acc_a, mut acc_b, mut acc_n) = (0.0, 0.0, 0usize);
    for k in 1..sum_a.len() {
        acc_a += sum_a[k];
        acc_b += sum_b[k];
        acc_n += counts[k];
        if acc_n >= PSD_MIN_BIN_SAMPLES {
            if acc_a > 0.0 && acc_b > 0.0 {
                sq += (acc_b.log10() - acc_a.log10()).powi(2);
                bins += 1;
            }
            (acc_a, acc_b, acc_n) = (0.0, 0.0, 0);
        }
    }
    if bins == 0 {
        f64::NAN
    } else {
        (sq / bins as f64).sqrt()
    }
}

/// Seam score on square cells of `cell` px: mean squared gradient across cell borders
/// divided by that inside cells (1.0 = seams invisible).
pub fn seam_score(r: &Raster, cell: usize) -> f64 {
    let cell = cell.max(1) as i64;
    seam_score_by(r, |x, y| {
        (
            (x as i64).div_euclid(cell),
            (y as i64).div_euclid(cell),
            false,
        )
    })
}

/// Seam score for any partition of the pixels into cells: `cell_of(x, y)` names the
/// cell of pixel (x, y); pixel pairs in different cells are border pairs.
pub fn seam_score_by(r: &Raster, cell_of: impl Fn(usize, usize) -> (i64, i64, bool)) -> f64 {
    let (mut border, mut nb, mut inside, mut ni) = (0.0, 0usize, 0.0, 0usize);
    let ids: Vec<(i64, i64, bool)> = (0..r.pixels())
        .map(|i| cell_of(i % r.width, i / r.width))
        .collect();
    for y in 0..r.height {
        for x in 0..r.width {
            let here = r.get(x, y, 0) as f64;
            let id = ids[y * r.width + x];
            for (nx, ny) in [(x + 1, y), (x, y + 1)] {
                if nx >= r.width || ny >= r.height {
                    continue;
                }
                let g = (r.get(nx, ny, 0) as f64 - here).powi(2);
                if ids[ny * r.width + nx] != id {
                    border += g;
                    nb += 1;
                } else {
                    inside += g;
                    ni += 1;
                }
            }
        }
    }
    if nb == 0 || ni == 0 || inside == 0.0 {
        return f64::NAN;
    }
    (border / nb as f64) / (inside / ni as f64)
}

/// Seam score at known seam pairs: the mean squared height difference over the pairs
/// `seam(x, y, d)` marks (d = 0: (x, y)–(x+1, y); d = 1: (x, y)–(x, y+1)) ÷ what the other
/// pairs of the same direction give, weighted by the seam pairs of each direction (so an
/// anisotropic map compares like with like). 1.0: the seams are as rough as anywhere
/// else; below 1, smoother than the map (a blurred seam); above, a visible step. NaN when
/// there are no seam pairs or nothing else to compare with.
pub fn seam_score_at(r: &Raster, seam: impl Fn(usize, usize, usize) -> bool) -> f64 {
    let (mut on, mut n_on, mut off, mut n_off) =
        ([0.0f64; 2], [0usize; 2], [0.0f64; 2], [0usize; 2]);
    for y in 0..r.height {
        for x in 0..r.width {
            let here = r.get(x, y, 0) as f64;
            for (d, (nx, ny)) in [(x + 1, y), (x, y + 1)].into_iter().enumerate() {
                if nx >= r.width || ny >= r.height {
                    continue;
                }
                let g = (r.get(nx, ny, 0) as f64 - here).powi(2);
                if seam(x, y, d) {
                    on[d] += g;
                    n_on[d] += 1;
                } else {
                    off[d] += g;
                    n_off[d] += 1;
                }
            }
        }
    }
    let mut expected = 0.0;
    for d in 0..2 {
        if n_on[d] > 0 {
            if n_off[d] == 0 || off[d] == 0.0 {
                return f64::NAN;
            }
            expected += n_on[d] as f64 * off[d] / n_off[d] as f64;
        }
    }
    if expected == 0.0 {
        return f64::NAN;
    }
    (on[0] + on[1]) / expected
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raster(w: usize, h: usize, f: impl Fn(usize, usize) -> f64) -> Raster {
        Raster::from_vec(
            w,
            h,
            1,
            (0..w * h).map(|i| f(i % w, i / w) as f32).collect(),
        )
        .unwrap()
    }

    #[test]
    fn w1_of_a_shift_is_the_shift() {
        let a: Vec<f64> = (0..100).map(|i| i as f64).collect();
        let b: Vec<f64> = a.iter().map(|v| v + 2.5).collect();
        assert!((wasserstein1_sorted(&a, &b) - 2.5).abs() < 1e-12);
        // Different sizes, same distribution: uniform on 0..1 at two resolutions.
        let c: Vec<f64> = (0..1000).map(|i| (i as f64 + 0.5) / 1000.0).collect();
        let d: Vec<f64> = (0..10).map(|i| (i as f64 + 0.5) / 10.0).collect();
        assert!(wasserstein1_sorted(&c, &d) < 0.03);
    }

    #[test]
    fn moments_of_a_symmetric_two_level_map() {
        let r = raster(10, 10, |x, _| if x % 2 == 0 { 1.0 } else { -1.0 });
        let s = height_stats(&r);
        assert!(s.mean.abs() < 1e-12 && (s.sq - 1.0).abs() < 1e-12 && (s.sa - 1.0).abs() < 1e-12);
        assert!(s.ssk.abs() < 1e-12 && (s.sku - 1.0).abs() < 1e-12 && (s.sz - 2.0).abs() < 1e-12);
    }

    /// A sinusoid along x: ACF = cos(2π dx / period), which first reaches 0.2 at
    /// dx = period·acos(0.2)/(2π); along y it never decays.
    #[test]
    fn sal_and_repetition_of_a_sinusoid() {
        let period = 16.0;
        let r = raster(128, 128, |x, _| {
            (2.0 * std::f64::consts::PI * x as f64 / period).sin()
        });
        let s = height_stats(&r);
        let expected = period * 0.2f64.acos() / (2.0 * std::f64::consts::PI);
        // The biased estimator shrinks the ACF by (1 − |dx|/w): allow 10%.
        assert!(
            (s.sal - expected).abs() < 0.1 * expected,
            "Sal {} vs {expected}",
            s.sal
        );
        assert!(s.str < 0.2, "Str {}", s.str);
        assert!(s.repetition > 0.95, "repetition {}", s.repetition);
    }

    /// The half-spectrum binning against a slow twin that bins every frequency of the
    /// full spectra, on odd and even sizes: the same sums, so the same error to 1e-12.
    #[test]
    fn spectrum_log_error_of_half_spectra_is_the_full_spectra_binning() {
        use crate::fft::{Fft2, RealFft2, forward_real};
        let full_binning = |a: &[Complex64], b: &[Complex64], w: usize, h: usize| {
            let side = w.min(h) as f64;
            let bins = w.min(h) / 2 + 1;
            let (mut sa, mut sb, mut counts) =
                (vec![0.0; bins], vec![0.0; bins], vec![0usize; bins]);
            let signed = signed_frequency;
            for ky in 0..h {
                for kx in 0..w {
                    let (fx, fy) = (
                        signed(kx, w) * side / w as f64,
                        signed(ky, h) * side / h as f64,
                    );
                    let rad = (fx * fx + fy * fy).sqrt();
                    if rad >= 1.0 && (rad as usize) < bins {
                        sa[rad as usize] += a[ky * w + kx].norm_sqr();
                        sb[rad as usize] += b[ky * w + kx].norm_sqr();
                        counts[rad as usize] += 1;
                    }
                }
            }
            log_rms_over_merged_bins(&sa, &sb, &counts)
        };
        for (w, h) in [(64usize, 48usize), (63, 50), (40, 77)] {
            let a: Vec<f64> = (0..w * h).map(|i| ((i * 7919) % 101) as f64).collect();
            let b: Vec<f64> = (0..w * h)
                .map(|i| (i as f64 * 0.3).sin() + ((i * 31) % 7) as f64)
                .collect();
            let mut full = Fft2::new(w, h);
            let expected = full_binning(
                &forward_real(&mut full, &a),
                &forward_real(&mut full, &b),
                w,
                h,
            );
            let mut half = RealFft2::new(w, h);
            let modulus: Vec<f64> = half.forward(&a).iter().map(|c| c.norm()).collect();
            let got = spectrum_log_error(&modulus, &half.forward(&b), w, h);
            assert!(
                expected > 0.1,
                "{w}×{h}: the spectra should differ ({expected})"
            );
            assert!(
                (got - expected).abs() < 1e-12,
                "{w}×{h}: {got} vs {expected}"
            );
        }
    }

    /// Fidelity bars: a map whose halves are alike keeps the foundation's floors; one
    /// whose halves differ gets 1.2× the difference; a one-row map (no halves) the floors.
    #[test]
    fn fidelity_bars_are_the_floor_or_the_maps_own_difference() {
        // Periodic over 32 px both ways: its left and right halves are the same, and so
        // are its top and bottom ones.
        let texture = |x: usize, y: usize| (((x % 32) * 7919 + (y % 32) * 104_729) % 101) as f64;
        let alike = fidelity_bars(&raster(64, 64, texture));
        assert_eq!((alike.w1_self, alike.psd_self), (0.0, 0.0));
        assert_eq!((alike.w1, alike.psd), (W1_BAR, PSD_ERROR_BAR));
        // The bottom half ten times as smooth in its fine detail, and shifted in height.
        let uneven = fidelity_bars(&raster(64, 64, |x, y| {
            if y < 32 {
                texture(x, y)
            } else {
                0.1 * texture(x, y) + 0.05 * x as f64
            }
        }));
        assert!(uneven.w1_self > W1_BAR && uneven.psd_self > PSD_ERROR_BAR);
        assert_eq!(
            (uneven.w1, uneven.psd),
            (1.2 * uneven.w1_self, 1.2 * uneven.psd_self)
        );
        let row = fidelity_bars(&raster(64, 1, texture));
        assert!(row.w1_self.is_nan() && row.psd_self.is_nan());
        assert_eq!((row.w1, row.psd), (W1_BAR, PSD_ERROR_BAR));
    }

    /// A lay whose grooves run from top to bottom (plu-1's kind): its top and bottom
    /// halves hold the same grooves and differ by nothing, its left and right halves
    /// differ, and the bars are those of the left and right, the same as for the map
    /// turned by 90°. The twin: the two cuts measured by hand.
    #[test]
    fn fidelity_bars_cut_across_a_lay_and_do_not_depend_on_the_maps_turn() {
        // Grooves along y: a column profile whose left half is smooth and whose right
        // half is rough.
        let groove = |x: usize| {
            let v = ((x * 7919) % 101) as f64;
            if x < 32 { 0.05 * v + 0.1 * x as f64 } else { v }
        };
        let lay = raster(64, 64, |x, _| groove(x));
        let turned = raster(64, 64, |_, y| groove(y));
        let (top, bottom) = (
            lay.crop(0, 0, 64, 32).unwrap(),
            lay.crop(0, 32, 64, 32).unwrap(),
        );
        let (left, right) = (
            lay.crop(0, 0, 32, 64).unwrap(),
            lay.crop(32, 0, 32, 64).unwrap(),
        );
        assert_eq!(wasserstein1_standardised(&top, &bottom), 0.0);
        let (w1_lr, psd_lr) = (
            wasserstein1_standardised(&left, &right),
            psd_error(&left, &right),
        );
        assert!(w1_lr > W1_BAR && psd_lr > PSD_ERROR_BAR);
        let bars = fidelity_bars(&lay);
        assert_eq!((bars.w1_self, bars.psd_self), (w1_lr, psd_lr));
        assert_eq!((bars.w1, bars.psd), (1.2 * w1_lr, 1.2 * psd_lr));
        // Turned, the same figures up to the order of their sums.
        let turned = fidelity_bars(&turned);
        assert!((turned.w1_self - w1_lr).abs() < 1e-9 * w1_lr);
        assert!((turned.psd_self - psd_lr).abs() < 1e-9 * psd_lr);
    }

    #[test]
    fn psd_windows_cover_the_map_half_a_window_apart() {
        // Known answers: flush with both edges, evenly spaced, at most n/2 apart.
        assert_eq!(window_starts(70, 24, 8), vec![0, 11, 23, 34, 46]);
        assert_eq!(window_starts(127, 80, 8), vec![0, 23, 47]);
        assert_eq!(window_starts(80, 80, 8), vec![0]);
        assert_eq!(window_starts(100, 50, 8), vec![0, 25, 50]);
        // Capped, still spanning the map: 1024 with n = 80 would want 25.
        assert_eq!(
            window_starts(1024, 80, 8),
            vec![0, 134, 269, 404, 539, 674, 809, 944]
        );
        assert!(window_starts(79, 80, 8).is_empty());
    }

    /// Uniform noise in [−1, 1] at each pixel (pcg4d), times `gain(x, y)`.
    fn noise(w: usize, h: usize, gain: impl Fn(usize, usize) -> f64) -> Raster {
        raster(w, h, |x, y| {
            let u = crate::hash::pcg4d([x as u32, y as u32, 7, 11])[0];
            gain(x, y) * (u as f64 / u32::MAX as f64 * 2.0 - 1.0)
        })
    }

    /// A 128² exemplar of white noise 3 times as strong outside its middle square as in
    /// it. The one Hann window psd_error takes on it weighs the middle; shown evenly, the
    /// exemplar holds its mean power, in every radial bin alike (white noise), so
    /// psd_error_even reads log10 of the mean power over the taper-weighted power,
    /// predicted here from the taper alone (0.510; it reads 0.524). The exemplar tiled to
    /// 512², an exact and even reproduction, reads about as much in psd_error (0.480); the
    /// same noise at one strength reads under 0.08 in both (0.058, 0.043).
    #[test]
    fn psd_error_even_reads_an_exemplars_uneven_middle() {
        let n = 128;
        let middle = |i: usize| (n / 4..3 * n / 4).contains(&i);
        let power = |x: usize, y: usize| if middle(x) && middle(y) { 1.0f64 } else { 9.0 };
        let uneven = noise(n, n, |x, y| power(x, y).sqrt());
        let hann: Vec<f64> = (0..n).map(|i| crate::fft::hann(i, n).powi(2)).collect();
        let (mut weighted, mut weights, mut mean) = (0.0, 0.0, 0.0);
        for y in 0..n {
            for x in 0..n {
                weighted += hann[x] * hann[y] * power(x, y);
                weights += hann[x] * hann[y];
                mean += power(x, y) / (n * n) as f64;
            }
        }
        let predicted = (mean / (weighted / weights)).log10();
        assert!(
            predicted > 0.25,
            "the test's exemplar should be uneven: {predicted}"
        );
        let even = psd_error_even(&uneven);
        assert!(
            (even - predicted).abs() < 0.05,
            "{even} against {predicted}"
        );
        let tiled = |r: &Raster| raster(512, 512, |x, y| r.get(x % n, y % n, 0) as f64);
        let exact = psd_error(&uneven, &tiled(&uneven));
        // psd_error takes its 8 × 8 windows at offsets that do not spread as evenly.
        assert!((exact - even).abs() < 0.08, "tiled {exact}, even {even}");
        let uniform = noise(n, n, |_, _| 1.0);
        let (even, exact) = (
            psd_error_even(&uniform),
            psd_error(&uniform, &tiled(&uniform)),
        );
        assert!(even < 0.08 && exact < 0.08, "{even}, {exact}");
        assert!(psd_error_even(&raster(7, 40, |x, y| (x * y) as f64)).is_nan());
    }

    /// psd_error_even against a slow twin that builds the period as a raster (the
    /// exemplar and its mirror images side by side along an axis that does not tile),
    /// repeats it 2 × 2 and crops every window, for an exemplar that tiles both ways, one
    /// that tiles along x alone, and one that tiles along neither.
    #[test]
    fn psd_error_even_is_its_windows_over_the_built_period() {
        use crate::prep::level::tiles_along;
        let tau = std::f64::consts::TAU;
        let periodic = |x: usize, y: usize, w: usize, h: usize| {
            (tau * 3.0 * x as f64 / w as f64).sin() * (tau * 2.0 * y as f64 / h as f64).cos()
                + 0.5 * (tau * (5.0 * x as f64 / w as f64 + 4.0 * y as f64 / h as f64)).cos()
        };
        let cases = [
            (raster(48, 40, |x, y| periodic(x, y, 48, 40)), [true, true]),
            (
                raster(48, 40, |x, y| periodic(x, y, 48, 40) + 0.05 * y as f64),
                [true, false],
            ),
            (
                raster(48, 40, |x, y| {
                    periodic(x, y, 48, 40) + 0.04 * x as f64 - 0.05 * y as f64
                }),
                [false, false],
            ),
        ];
        for (ex, tiles) in cases {
            assert_eq!([tiles_along(&ex, 0), tiles_along(&ex, 1)], tiles);
            let (w, h) = (ex.width, ex.height);
            let pw = if tiles[0] { w } else { 2 * w };
            let ph = if tiles[1] { h } else { 2 * h };
            let mut period = vec![0.0f64; pw * ph];
            for y in 0..ph {
                for x in 0..pw {
                    let sx = if x < w { x } else { 2 * w - 1 - x };
                    let sy = if y < h { y } else { 2 * h - 1 - y };
                    period[y * pw + x] = ex.get(sx, sy, 0) as f64;
                }
            }
            let repeated = raster(2 * pw, 2 * ph, |x, y| period[(y % ph) * pw + x % pw]);
            let n = w.min(h);
            let (pa, counts) = radial_psd(&ex, n, 8);
            let mut pb = vec![0.0; pa.len()];
            for i in 0..8 {
                for j in 0..8 {
                    let window = repeated.crop(j * pw / 8, i * ph / 8, n, n).unwrap();
                    for (b, p) in pb.iter_mut().zip(radial_psd(&window, n, 1).0) {
                        *b += p / 64.0;
                    }
                }
            }
            let twin = log_rms_of_mean_spectra(&pa, &pb, &counts);
            let fast = psd_error_even(&ex);
            assert!(
                (fast - twin).abs() < 1e-9 && twin > 0.0,
                "{tiles:?}: {fast} against {twin}"
            );
        }
    }

    /// radial_psd through half spectra against a slow twin that bins every frequency of
    /// a full complex spectrum, for even and odd window sides and several windows.
    #[test]
    fn radial_psd_of_half_spectra_is_the_full_spectra_binning() {
        use crate::fft::{Fft2, forward_real};
        let r = raster(70, 50, |x, y| {
            (0.3 * x as f64).sin()
                + 0.5 * (0.17 * y as f64 + 0.05 * x as f64).cos()
                + ((x * 7919 + y * 31) % 17) as f64 * 0.03
        });
        for n in [24usize, 21] {
            let (power, count) = radial_psd(&r, n, 8);
            let hann: Vec<f64> = (0..n).map(|i| crate::fft::hann(i, n)).collect();
            let mut plan = Fft2::new(n, n);
            let bins = n / 2 + 1;
            let (mut p_full, mut c_full) = (vec![0.0; bins], vec![0usize; bins]);
            let mut windows = 0;
            for &wy in &window_starts(r.height, n, 8) {
                for &wx in &window_starts(r.width, n, 8) {
                    windows += 1;
                    let spec = forward_real(
                        &mut plan,
                        &tapered_window(|x, y| r.get(x, y, 0) as f64, (wx, wy), &hann),
                    );
                    for ky in 0..n {
                        for kx in 0..n {
                            let rad = signed_frequency(kx, n).hypot(signed_frequency(ky, n));
                            if rad >= 1.0 && rad <= (n / 2) as f64 {
                                p_full[rad as usize] += spec[ky * n + kx].norm_sqr();
                                if windows == 1 {
                                    c_full[rad as usize] += 1;
                                }
                            }
                        }
                    }
                }
            }
            assert!(windows > 1, "the test should average several windows");
            assert_eq!(count, c_full, "n = {n}");
            for (k, (&a, &b)) in power.iter().zip(&p_full).enumerate() {
                let b = if c_full[k] > 0 {
                    b / (c_full[k] * windows) as f64
                } else {
                    b
                };
                assert!(
                    (a - b).abs() <= 1e-9 * b.abs().max(1e-12),
                    "n = {n}, bin {k}: {a} vs {b}"
                );
            }
        }
    }

    /// 512² box-filtered noise (9×9, periodic) does not repeat: its score is the
    /// estimator's noise, under 0.1, where any texture's ACF just past its decay length —
    /// DESIGN.md's "beyond Sal" — is 0.2. Its own 128² corner tiled 4×4 repeats exactly
    /// at 128 px: over 0.95.
    #[test]
    fn repetition_tells_noise_from_a_tiled_copy() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(5);
        let n = 512;
        let white: Vec<f64> = (0..n * n).map(|_| rng.random::<f64>() - 0.5).collect();
        let smooth = |x: usize, y: usize| -> f64 {
            (0..81)
                .map(|k| white[((y + k / 9) % n) * n + (x + k % 9) % n])
                .sum()
        };
        let noise = height_stats(&raster(n, n, smooth));
        let tiled = height_stats(&raster(n, n, |x, y| smooth(x % 128, y % 128)));
        println!(
            "repetition: noise {}, tiled {}",
            noise.repetition, tiled.repetition
        );
        assert!(
            noise.repetition < 0.1,
            "noise repetition {}",
            noise.repetition
        );
        assert!(
            tiled.repetition > 0.95,
            "tiled repetition {}",
            tiled.repetition
        );
    }

    /// Stationary noise: ratio 1 within 10%. The same noise only inside a central disc
    /// of radius a quarter of the side (a crater on a flat map), or only outside it: the
    /// expected ratio is the window's mean square over that region divided by its mean
    /// square over the map, 3.98 inside and 0.27 outside (computed from the window
    /// alone); the thresholds 3 and 0.5 leave room for the noise.
    #[test]
    fn windowed_variance_ratio_tells_stationary_from_centred_or_bordered() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(11);
        let n = 128;
        let field: Vec<f64> = (0..n * n).map(|_| rng.random::<f64>() - 0.5).collect();
        let inside = |x: usize, y: usize| {
            let (dx, dy) = (x as f64 - 63.5, y as f64 - 63.5);
            dx.hypot(dy) < 32.0
        };
        let all = raster(n, n, |x, y| field[y * n + x]);
        let centre = raster(
            n,
            n,
            |x, y| if inside(x, y) { field[y * n + x] } else { 0.0 },
        );
        let border = raster(
            n,
            n,
            |x, y| if inside(x, y) { 0.0 } else { field[y * n + x] },
        );
        let (a, c, b) = (
            windowed_variance_ratio(&all),
            windowed_variance_ratio(&centre),
            windowed_variance_ratio(&border),
        );
        assert!((a - 1.0).abs() < 0.1, "stationary {a}");
        assert!(c > 3.0, "centred {c}");
        assert!(b < 0.5, "bordered {b}");
        assert!(windowed_variance_ratio(&raster(16, 16, |_, _| 2.0)).is_nan());
    }

    #[test]
    fn psd_error_is_zero_for_the_same_map_and_grows_with_a_gain() {
        let r = raster(64, 64, |x, y| {
            ((x * 7 + y * 13) % 17) as f64 + (x as f64 * 0.3).sin()
        });
        assert!(psd_error(&r, &r) < 1e-12);
        let mut louder = r.clone();
        for v in &mut louder.data {
            *v *= 10.0;
        }
        // Power ×100 is +2 in log10 in every bin.
        assert!((psd_error(&r, &louder) - 2.0).abs() < 1e-6);
    }

    #[test]
    fn seam_score_sees_a_step_at_cell_borders() {
        let smooth = raster(64, 64, |x, y| {
            (x as f64 * 0.5).sin() + (y as f64 * 0.3).cos()
        });
        assert!((seam_score(&smooth, 16) - 1.0).abs() < 0.3);
        let seamed = raster(64, 64, |x, y| {
            (x as f64 * 0.5).sin() + (y as f64 * 0.3).cos() + ((x / 16) % 2) as f64 * 3.0
        });
        assert!(seam_score(&seamed, 16) > 5.0);
    }

    /// At marked pairs: a step on the marked column is seen; marking plain pairs of an
    /// anisotropic map gives 1 (each direction compared with itself), where pooling the
    /// directions would not.
    #[test]
    fn seam_score_at_compares_each_direction_with_itself() {
        // x gradients 4× the y gradients in energy.
        let aniso = raster(64, 64, |x, y| {
            ((x * 7 + y * 3) % 11) as f64 * 2.0 + (y % 3) as f64
        });
        let on_column = |x: usize, _: usize, d: usize| d == 0 && x == 20;
        let plain = seam_score_at(&aniso, on_column);
        assert!((plain - 1.0).abs() < 0.2, "plain column {plain}");
        let stepped = raster(64, 64, |x, y| {
            ((x * 7 + y * 3) % 11) as f64 * 2.0 + (y % 3) as f64 + if x > 20 { 40.0 } else { 0.0 }
        });
        assert!(seam_score_at(&stepped, on_column) > 5.0);
        assert!(seam_score_at(&aniso, |_, _, _| false).is_nan());
    }
}
