//! Baking: exemplar in, blend bank out (seed 000 §3.1–3.2 with Heitz & Neyret's
//! Gaussianisation).
//!
//! ```text
//! exemplar ─ missing points ─ plane levelling ─ down-sampling ─ T (Gaussianise)
//!    └─ K crops ─ Hann taper (or Moisan's periodic component) ─ RPN or ADSN
//!          └─ Gaussian patches
//!          └─ mip levels (2×2 box) ─ T⁻¹ table per level ─ bank
//! ```
//!
//! Validation happens in [`BakerBuilder::build`], so [`Baker::bake`] fails only on the
//! exemplar itself (missing points, too small).

use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

use crate::analysis::gauss::{gaussianize, inverse_lut, lut_eval, quantile};
use crate::analysis::level::level_plane;
use crate::analysis::missing::fill_missing;
use crate::analysis::periodic::periodic_smooth;
use crate::analysis::resample::{DownsampleFilter, downsample};
use crate::analysis::rpn::{asymptotic_spot_noise, random_phase_noise};
use crate::analysis::taper::hann_taper;
use crate::bank::{Bank, BankHeader, ExemplarInfo, LevelInfo, Method, Rule};
use crate::error::{Error, Result};
use crate::io::ImageFile;
use crate::raster::Raster;

/// Smallest exemplar side accepted, in pixels (after down-sampling).
pub const MIN_EXEMPLAR_SIDE: usize = 16;
/// Default largest tile side, in pixels.
pub const DEFAULT_MAX_PATCH: usize = 256;
/// Entries per T⁻¹ table.
pub const LUT_SIZE: usize = 1024;
/// T⁻¹ tables cover z ∈ [−LUT_Z_RANGE, LUT_Z_RANGE] standard deviations.
pub const LUT_Z_RANGE: f64 = 5.0;
/// Smallest mip level side, in texels.
const MIN_LEVEL_SIDE: usize = 4;

/// Plane levelling before analysis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Leveling {
    /// Subtract the least-squares plane from height maps (1 channel), leave colour as is.
    Auto,
    /// Always subtract the least-squares plane.
    Plane,
    /// Keep the data as is.
    None,
}

/// How a crop is made periodic before the FFT-based methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Taper {
    /// Taper to the mean with a Hann window, variance kept (the default). The RPN patch
    /// then has the Hann-windowed periodogram of the crop, whose leakage falls as f⁻⁶.
    Hann,
    /// Moisan's periodic component, as seed 000 §3.1.5 does. Its derivative still jumps
    /// at the wrap, which adds an f⁻⁴ tail to the spectrum: on smooth maps with a steep
    /// spectrum (al3d-1) that tail dominates mid frequencies (PSD error 0.43 against
    /// 0.27 with Hann), so it is not the default.
    Periodic,
}

/// Validated bake parameters. Make one with [`Baker::builder`].
#[derive(Clone, Debug)]
pub struct Baker {
    method: Method,
    patch: Option<usize>,
    bank_size: usize,
    seed: u64,
    leveling: Leveling,
    downsample: usize,
    filter: DownsampleFilter,
    fill_missing: bool,
    triangle_edge: Option<f64>,
    spacing_um: Option<f64>,
    taper: Taper,
}

/// Builder for [`Baker`]; every setter documents its default.
#[derive(Clone, Debug)]
pub struct BakerBuilder(Baker);

impl BakerBuilder {
    /// Analysis method. Default: [`Method::Rpn`].
    pub fn method(mut self, method: Method) -> Self {
        self.0.method = method;
        self
    }
    /// Tile side in pixels, a power of two from 8 to 4096 and no larger than the
    /// exemplar. Default: per axis, the largest power of two that fits the exemplar,
    /// at most 256.
    pub fn patch(mut self, side: usize) -> Self {
        self.0.patch = Some(side);
        self
    }
    /// Number of tiles K (1 to 256). Default: 8.
    pub fn bank_size(mut self, k: usize) -> Self {
        self.0.bank_size = k;
        self
    }
    /// Seed of the random phases and crop positions. Default: 0.
    pub fn seed(mut self, seed: u64) -> Self {
        self.0.seed = seed;
        self
    }
    /// Plane levelling. Default: [`Leveling::Auto`].
    pub fn leveling(mut self, leveling: Leveling) -> Self {
        self.0.leveling = leveling;
        self
    }
    /// Integer down-sampling factor (1 to 64) and filter. Default: 1 (none), nearest.
    pub fn downsample(mut self, factor: usize, filter: DownsampleFilter) -> Self {
        self.0.downsample = factor;
        self.0.filter = filter;
        self
    }
    /// Fill missing (NaN) points harmonically instead of refusing them. Default: false.
    pub fn fill_missing(mut self, fill: bool) -> Self {
        self.0.fill_missing = fill;
        self
    }
    /// Triangle edge E of the blend grid, in pixels (≥ 2). Default: half the smaller
    /// tile side.
    pub fn triangle_edge(mut self, edge: f64) -> Self {
        self.0.triangle_edge = Some(edge);
        self
    }
    /// Pixel spacing of the exemplar in µm, overriding the file's. Default: the file's.
    pub fn spacing_um(mut self, spacing: f64) -> Self {
        self.0.spacing_um = Some(spacing);
        self
    }
    /// How crops are made periodic before RPN/ADSN. Default: [`Taper::Hann`].
    pub fn taper(mut self, taper: Taper) -> Self {
        self.0.taper = taper;
        self
    }
    /// Checks every parameter.
    pub fn build(self) -> Result<Baker> {
        let b = self.0;
        if let Some(p) = b.patch
            && (!p.is_power_of_two() || !(8..=4096).contains(&p))
        {
            return Err(Error::param(
                "patch",
                p,
                "a power of two from 8 to 4096 pixels",
            ));
        }
        if !(1..=256).contains(&b.bank_size) {
            return Err(Error::param("bank-size", b.bank_size, "1 to 256 tiles"));
        }
        if !(1..=64).contains(&b.downsample) {
            return Err(Error::param(
                "downsample",
                b.downsample,
                "an integer factor from 1 to 64",
            ));
        }
        if let Some(e) = b.triangle_edge
            && !(e.is_finite() && e >= 2.0)
        {
            return Err(Error::param(
                "triangle-edge",
                e,
                "a length of at least 2 pixels",
            ));
        }
        if let Some(s) = b.spacing_um
            && !(s.is_finite() && s > 0.0)
        {
            return Err(Error::param("spacing", s, "a positive pixel spacing in µm"));
        }
        Ok(b)
    }
}

impl Baker {
    /// A builder with the defaults.
    pub fn builder() -> BakerBuilder {
        BakerBuilder(Baker {
            method: Method::Rpn,
            patch: None,
            bank_size: 8,
            seed: 0,
            leveling: Leveling::Auto,
            downsample: 1,
            filter: DownsampleFilter::Nearest,
            fill_missing: false,
            triangle_edge: None,
            spacing_um: None,
            taper: Taper::Hann,
        })
    }

    /// The exemplar as analysis sees it: missing points filled (or refused), levelled,
    /// down-sampled. Returns the raster and its spacing in µm.
    pub fn preprocess(&self, image: &ImageFile, source: &str) -> Result<(Raster, Option<f64>)> {
        let mut raster = image.raster.clone();
        let missing = raster.count_nan();
        if missing > 0 {
            if !self.fill_missing {
                return Err(Error::MissingData {
                    what: source.to_string(),
                    count: missing,
                    total: raster.data.len(),
                });
            }
            fill_missing(&mut raster, source)?;
        }
        if raster.data.iter().any(|v| v.is_infinite()) {
            return Err(Error::decode(source, "the exemplar holds infinite values"));
        }
        let level = match self.leveling {
            Leveling::Plane => true,
            Leveling::None => false,
            Leveling::Auto => raster.channels == 1,
        };
        if level {
            level_plane(&mut raster);
        }
        let raster = downsample(&raster, self.downsample, self.filter)?;
        let spacing = self
            .spacing_um
            .or(image.spacing_um)
            .map(|s| s * self.downsample as f64);
        if raster.width < MIN_EXEMPLAR_SIDE || raster.height < MIN_EXEMPLAR_SIDE {
            return Err(Error::TooSmall {
                what: source.to_string(),
                message: format!(
                    "the exemplar is {}×{} pixels{}; baking needs at least {MIN_EXEMPLAR_SIDE}×{MIN_EXEMPLAR_SIDE}",
                    raster.width,
                    raster.height,
                    if self.downsample > 1 {
                        " after down-sampling"
                    } else {
                        ""
                    }
                ),
            });
        }
        Ok((raster, spacing))
    }

    /// Bakes a blend bank from `image`. `source` names it in errors and in the bank;
    /// `progress` receives one line per step.
    pub fn bake(
        &self,
        image: &ImageFile,
        source: &str,
        progress: &mut dyn FnMut(&str),
    ) -> Result<Bank> {
        let (ex, spacing_um) = self.preprocess(image, source)?;
        let (w, h, c) = (ex.width, ex.height, ex.channels);
        let side = |n: usize| (1usize << n.ilog2()).min(DEFAULT_MAX_PATCH);
        let [pw, ph] = match self.patch {
            Some(p) if p > w || p > h => {
                return Err(Error::param(
                    "patch",
                    p,
                    format!("at most the exemplar's smaller side ({w}×{h} after preprocessing)"),
                ));
            }
            Some(p) => [p, p],
            None => [side(w), side(h)],
        };
        let edge = self.triangle_edge.unwrap_or((pw.min(ph) / 2) as f64);
        progress(&format!(
            "exemplar {w}×{h}×{c}; {} tiles of {pw}×{ph} by {}, triangle edge {edge} px",
            self.bank_size, self.method
        ));

        // T: Gaussianise each channel; keep the sorted heights for T⁻¹.
        let mut gauss_planes = Vec::with_capacity(c);
        let mut sorted = Vec::with_capacity(c);
        for ch in 0..c {
            let (g, s) = gaussianize(&ex.channel_f64(ch));
            gauss_planes.push(g);
            sorted.push(s);
        }

        // K Gaussian patches: random crops, periodic component, RPN or ADSN.
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(self.seed);
        let mut level0 = vec![0.0f32; self.bank_size * pw * ph * c];
        for k in 0..self.bank_size {
            let (x0, y0) = (rng.random_range(0..=w - pw), rng.random_range(0..=h - ph));
            let crops: Vec<Vec<f64>> = gauss_planes
                .iter()
                .map(|plane| {
                    let crop: Vec<f64> = (0..ph)
                        .flat_map(|y| plane[(y0 + y) * w + x0..(y0 + y) * w + x0 + pw].to_vec())
                        .collect();
                    match self.taper {
                        Taper::Hann => hann_taper(&crop, pw, ph),
                        Taper::Periodic => periodic_smooth(&crop, pw, ph).0,
                    }
                })
                .collect();
            let patch = match self.method {
                Method::Rpn => random_phase_noise(&crops, pw, ph, &mut rng),
                Method::Adsn => asymptotic_spot_noise(&crops, pw, ph, &mut rng),
            };
            let tile = &mut level0[k * pw * ph * c..(k + 1) * pw * ph * c];
            for (ch, plane) in patch.iter().enumerate() {
                for (i, &v) in plane.iter().enumerate() {
                    tile[i * c + ch] = v as f32;
                }
            }
            progress(&format!(
                "tile {}/{} from crop at ({x0}, {y0})",
                k + 1,
                self.bank_size
            ));
        }

        // Level 0: T⁻¹ maps the patches' standardised values to the exemplar quantiles.
        let (mean0, sigma0) = channel_stats(&level0, c);
        let lut0: Vec<f32> = sorted
            .iter()
            .flat_map(|s| inverse_lut(s, LUT_SIZE, LUT_Z_RANGE))
            .collect();
        // Heights the level-0 patches stand for, to prefilter the coarser tables.
        let mut heights: Vec<f32> = level0
            .iter()
            .enumerate()
            .map(|(i, &g)| {
                let ch = i % c;
                let z = ((g as f64 - mean0[ch]) / sigma0[ch].max(1e-30)) as f32;
                lut_eval(
                    &lut0[ch * LUT_SIZE..(ch + 1) * LUT_SIZE],
                    z,
                    LUT_Z_RANGE as f32,
                )
            })
            .collect();
        let mut texels = vec![level0];
        let mut luts = vec![lut0];
        let mut levels = vec![LevelInfo {
            size: [pw, ph],
            mean: mean0,
            sigma: sigma0,
        }];
        // Coarser levels: 2×2 box filter of the Gaussian patches and of the heights; each
        // level's table maps its Gaussian values to the distribution of averaged heights
        // (Deliot & Heitz prefilter T⁻¹ per level for the same reason).
        let (mut lw, mut lh) = (pw, ph);
        while lw / 2 >= MIN_LEVEL_SIDE && lh / 2 >= MIN_LEVEL_SIDE {
            let prev = texels
                .last()
                .map(|t| box_half(t, self.bank_size, lw, lh, c))
                .unwrap_or_default();
            heights = box_half(&heights, self.bank_size, lw, lh, c);
            lw /= 2;
            lh /= 2;
            let (mean, sigma) = channel_stats(&prev, c);
            let lut: Vec<f32> = (0..c)
                .flat_map(|ch| {
                    let mut s: Vec<f64> = heights
                        .iter()
                        .skip(ch)
                        .step_by(c)
                        .map(|&v| v as f64)
                        .collect();
                    s.sort_by(f64::total_cmp);
                    inverse_lut(&s, LUT_SIZE, LUT_Z_RANGE)
                })
                .collect();
            texels.push(prev);
            luts.push(lut);
            levels.push(LevelInfo {
                size: [lw, lh],
                mean,
                sigma,
            });
        }

        let quantile_levels = vec![0.0, 0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 0.99, 1.0];
        let exemplar = ExemplarInfo {
            source: source.to_string(),
            width: w,
            height: h,
            mean: (0..c).map(|ch| mean_of(&sorted[ch])).collect(),
            std: (0..c).map(|ch| std_of(&sorted[ch])).collect(),
            quantiles: sorted
                .iter()
                .map(|s| quantile_levels.iter().map(|&p| quantile(s, p)).collect())
                .collect(),
            quantile_levels,
        };
        let sqrt3 = 3f64.sqrt();
        let header = BankHeader {
            rule: Rule::Blend,
            method: self.method,
            channels: c,
            tiles: self.bank_size,
            tile_size: [pw, ph],
            lattice: [[edge, 0.0], [edge / 2.0, edge * sqrt3 / 2.0]],
            triangle_edge: edge,
            levels,
            spacing_um,
            height_unit: if c == 1 && spacing_um.is_some() {
                "um".into()
            } else {
                String::new()
            },
            seed: self.seed,
            lut_size: LUT_SIZE,
            lut_z_range: LUT_Z_RANGE,
            exemplar,
            bake: format!(
                "method={} patch={pw}x{ph} bank_size={} seed={} level={:?} downsample={} filter={:?} fill_missing={} triangle_edge={edge} taper={:?}",
                self.method,
                self.bank_size,
                self.seed,
                self.leveling,
                self.downsample,
                self.filter,
                self.fill_missing,
                self.taper
            ),
        };
        let bank = Bank {
            header,
            texels,
            luts,
        };
        bank.validate(source)?;
        Ok(bank)
    }
}

fn mean_of(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn std_of(v: &[f64]) -> f64 {
    let m = mean_of(v);
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// Mean and standard deviation per channel of interleaved samples.
fn channel_stats(data: &[f32], c: usize) -> (Vec<f64>, Vec<f64>) {
    (0..c)
        .map(|ch| {
            let v: Vec<f64> = data.iter().skip(ch).step_by(c).map(|&x| x as f64).collect();
            (mean_of(&v), std_of(&v))
        })
        .unzip()
}

/// 2×2 box average of `tiles` periodic `w × h × c` tiles (w, h even).
fn box_half(data: &[f32], tiles: usize, w: usize, h: usize, c: usize) -> Vec<f32> {
    let (hw, hh) = (w / 2, h / 2);
    let mut out = vec![0.0f32; tiles * hw * hh * c];
    for t in 0..tiles {
        let src = &data[t * w * h * c..(t + 1) * w * h * c];
        let dst = &mut out[t * hw * hh * c..(t + 1) * hw * hh * c];
        for y in 0..hh {
            for x in 0..hw {
                for ch in 0..c {
                    let at = |xx: usize, yy: usize| src[(yy * w + xx) * c + ch];
                    dst[(y * hw + x) * c + ch] = 0.25
                        * (at(2 * x, 2 * y)
                            + at(2 * x + 1, 2 * y)
                            + at(2 * x, 2 * y + 1)
                            + at(2 * x + 1, 2 * y + 1));
                }
            }
        }
    }
    out
}
