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

pub mod auto;
pub mod quilting;
pub mod rsgf;
pub mod synth;

use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

use crate::analysis::gauss::{gaussianize, inverse_lut, lut_eval, quantile};
use crate::analysis::periodic::periodic_smooth;
use crate::analysis::periodicity::{Detection, detect};
use crate::analysis::roller::{mip_down, required_size, roller_tiles};
use crate::analysis::rpn::{asymptotic_spot_noise, random_phase_noise};
use crate::analysis::taper::{hann_taper, hann_taper_main_lobe};
use crate::bake::rsgf::RsgfOptions;
use crate::bank::{Bank, BankHeader, ExemplarInfo, LevelInfo, Method, Record};
use crate::error::{Error, Result};
use crate::io::ImageFile;
use crate::lattice::Lattice;
use crate::prep::resample::DownsampleFilter;
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

pub use crate::prep::Leveling;

/// How a crop is made periodic before the FFT-based methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
// The names the CLI takes (clap's kebab-case), for the Python package's keywords.
#[serde(rename_all = "kebab-case")]
pub enum Taper {
    /// Taper to the mean with a Hann window, variance kept by scaling every frequency
    /// alike (the bake's default). The RPN patch then has the Hann-windowed periodogram
    /// of the crop, whose leakage falls as f⁻⁶.
    Hann,
    /// The same Hann window at its Welch gain, so every frequency the window resolves
    /// keeps the crop's windowed power unscaled, with the variance the window took from
    /// a form given back in its main lobe (at most two cycles per crop). The sandblast
    /// pipeline's default: on maps whose variance lies in a form (a bowl, a tilted part),
    /// hann scales the fine roughness by the form's share of the variance. Not the
    /// bake's: on al3d-1's small tiles it takes the bank's PSD error from 0.277 to
    /// 0.368, over that map's bar of 0.354.
    MainLobe,
    /// Moisan's periodic component, as seed 000 §3.1.5 does. Its derivative still jumps
    /// at the wrap, which adds an f⁻⁴ tail to the spectrum: on smooth maps with a steep
    /// spectrum (al3d-1) that tail dominates mid frequencies (PSD error 0.43 against
    /// 0.27 with Hann), so it is not the default.
    Periodic,
}

impl Taper {
    /// The `pw × ph` crop at (x0, y0) of each row-major plane `w` wide, made periodic.
    pub(crate) fn crops(
        self,
        planes: &[Vec<f64>],
        w: usize,
        [x0, y0, pw, ph]: [usize; 4],
    ) -> Vec<Vec<f64>> {
        planes
            .iter()
            .map(|plane| {
                let crop: Vec<f64> = (0..ph)
                    .flat_map(|y| plane[(y0 + y) * w + x0..(y0 + y) * w + x0 + pw].to_vec())
                    .collect();
                match self {
                    Taper::Hann => hann_taper(&crop, pw, ph),
                    Taper::MainLobe => hann_taper_main_lobe(&crop, pw, ph),
                    Taper::Periodic => periodic_smooth(&crop, pw, ph).0,
                }
            })
            .collect()
    }
}

/// Roller tiles with identical borders a bake cuts when `tiles` is not given (fewer
/// where the exemplar does not hold them).
pub const DEFAULT_ROLLER_TILES: usize = 4;

/// What every bank header records of a preprocessed exemplar: its statistics, spacing
/// (µm), the bake seed and the preprocessing parameters as text.
pub type HeaderBase = (ExemplarInfo, Option<f64>, u64, String);

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
    tiles: Option<usize>,
    lattice: Option<[(i64, i64); 2]>,
    tile: Option<[usize; 2]>,
    overlap: Option<usize>,
    rsgf: RsgfOptions,
    colours: usize,
    synth: crate::models::synth::SynthParams,
    quilting: crate::bake::quilting::QuiltingOptions,
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
    /// Form removal. Default: [`Leveling::Auto`] (the plane off a height map, the flat
    /// field of a photo).
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
    /// Roller: number of tiles with identical borders (1 to 64). Default:
    /// [`DEFAULT_ROLLER_TILES`], or fewer where the exemplar does not hold them.
    pub fn tiles(mut self, n: usize) -> Self {
        self.0.tiles = Some(n);
        self
    }
    /// Roller: the periodicity vectors u, v in pixels, overriding detection.
    pub fn lattice(mut self, u: (i64, i64), v: (i64, i64)) -> Self {
        self.0.lattice = Some([u, v]);
        self
    }
    /// Roller: an axis-aligned tile of `w × h` pixels, overriding detection.
    pub fn tile(mut self, w: usize, h: usize) -> Self {
        self.0.tile = Some([w, h]);
        self
    }
    /// Roller: overlap (cut band) width in pixels. Default: a sixth of the tile, ≥ 8.
    pub fn overlap(mut self, px: usize) -> Self {
        self.0.overlap = Some(px);
        self
    }
    /// Quilt: colours per edge direction K (1 to 8; the bank holds K⁴ Wang tiles).
    /// Default: 2 (16 tiles).
    pub fn colours(mut self, k: usize) -> Self {
        self.0.colours = k;
        self
    }
    /// RSGF: block, border, tolerance, metric and stochastic mode. Default:
    /// [`RsgfOptions::default`] (the paper's 40 px blocks, 10 px borders, ±3 px, SSD).
    pub fn rsgf(mut self, options: RsgfOptions) -> Self {
        self.0.rsgf = options;
        self
    }
    /// Synth: levels (0 = the default for the exemplar), k, passes, jitter and
    /// appearance dimensions. Default: [`crate::models::synth::SynthParams::default`].
    pub fn synth(mut self, params: crate::models::synth::SynthParams) -> Self {
        self.0.synth = params;
        self
    }
    /// Quilting: the penalty λ (`None`: chosen by trial fills), block and overlap. Default:
    /// [`crate::bake::quilting::QuiltingOptions::default`].
    pub fn quilting(mut self, options: crate::bake::quilting::QuiltingOptions) -> Self {
        self.0.quilting = options;
        self
    }
    /// Checks every parameter, and that each option given belongs to the method (a
    /// roller's `tiles` on an rpn bake is refused, not ignored).
    pub fn build(self) -> Result<Baker> {
        let b = self.0;
        let m = b.method;
        let only = |fits: bool, options: &str, methods: &str| -> Result<()> {
            if fits {
                Ok(())
            } else {
                Err(Error::param(
                    "method",
                    m,
                    format!("{methods} when {options} is given"),
                ))
            }
        };
        use Method::{Quilt, Quilting, Roller, Rsgf, Synth};
        only(
            m == Quilting || b.quilting == Default::default(),
            "`penalty`, a quilting block, overlap, search or wrap",
            "quilting",
        )?;
        b.quilting.validate()?;
        only(
            m == Roller || (b.tiles.is_none() && b.tile.is_none()),
            "`tiles` or `tile`",
            "roller",
        )?;
        only(
            matches!(m, Roller | Quilt) || b.overlap.is_none(),
            "`overlap`",
            "roller or quilt",
        )?;
        only(m == Quilt || b.colours == 2, "`colours`", "quilt")?;
        only(
            matches!(m, Roller | Rsgf) || b.lattice.is_none(),
            "`lattice`",
            "roller or rsgf",
        )?;
        use crate::bake::rsgf::RepeatWindow;
        let rest = RsgfOptions {
            repeat_window: RepeatWindow::Auto,
            ..b.rsgf.clone()
        };
        only(
            m == Rsgf || rest == RsgfOptions::default(),
            "`block`, `border`, `tolerance`, `metric`, `join`, `feather`, `match_histogram`, `edges` or `stochastic`",
            "rsgf",
        )?;
        // `auto` passes the window on where it picks stochastic RSGF.
        only(
            matches!(m, Rsgf | Method::Auto) || b.rsgf.repeat_window == RepeatWindow::Auto,
            "`repeat_window`",
            "rsgf or auto",
        )?;
        only(
            m == Synth || b.synth == crate::models::synth::SynthParams::default(),
            "`levels`, `k`, `passes`, `fine_passes`, `jitter`, `appearance_dims`, `coherence`, `jitter_levels` or `ragged`",
            "synth",
        )?;
        if b.synth.levels != 0 {
            b.synth.validate()?;
        } else {
            crate::models::synth::SynthParams {
                levels: 1,
                ..b.synth.clone()
            }
            .validate()?;
        }
        if !b.rsgf.stochastic && b.rsgf.edges != crate::models::rsgf::Edges::Auto {
            return Err(Error::param(
                "`edges`",
                format!("{:?} without `stochastic`", b.rsgf.edges).to_lowercase(),
                "`stochastic` with it (a lattice bank's patches stay inside the exemplar), or `edges` = auto",
            ));
        }
        if b.rsgf.edges == crate::models::rsgf::Edges::Reflect
            && b.rsgf.join != crate::models::rsgf::Join::Cut
        {
            return Err(Error::param(
                "`edges`",
                "reflect with `join` = blend",
                "`join` = cut: only a cut keeps the mirrored pixels out of the output",
            ));
        }
        if let RepeatWindow::Side(n) = b.rsgf.repeat_window {
            let p = crate::stats::structure::COPY_PATCH;
            if !b.rsgf.stochastic && m != Method::Auto {
                return Err(Error::param(
                    "`repeat_window`",
                    format!("{n} without `stochastic`"),
                    "`stochastic` or `method` = auto with it: it caps the block a stochastic bank scales to its exemplar",
                ));
            }
            if b.rsgf.block_px.is_some() || b.rsgf.border_px.is_some() {
                return Err(Error::param(
                    "`repeat_window`",
                    format!("{n} with `block` or `border` given"),
                    "one of them: the window caps the block that is not given",
                ));
            }
            if n < p {
                return Err(Error::param(
                    "`repeat_window`",
                    n,
                    format!(
                        "a window of at least {p} px, the side of the patches self-repetition compares"
                    ),
                ));
            }
        }
        if b.rsgf.stochastic && b.lattice.is_some() {
            return Err(Error::param(
                "lattice",
                "given with `stochastic`",
                "one of them: stochastic mode uses v1 = (1, 0), v2 = (0, 1)",
            ));
        }
        b.rsgf.params((1, 0), (0, 1)).validate()?;
        if !(1..=crate::analysis::quilt::MAX_COLOURS).contains(&b.colours) {
            return Err(Error::param(
                "colours",
                b.colours,
                format!(
                    "1 to {} colours per edge direction (K⁴ Wang tiles)",
                    crate::analysis::quilt::MAX_COLOURS
                ),
            ));
        }
        if let Some(n) = b.tiles
            && !(1..=64).contains(&n)
        {
            return Err(Error::param("tiles", n, "1 to 64 tiles"));
        }
        if let Some([u, v]) = b.lattice {
            let l = Lattice::from_basis(u, v)?;
            if l.area() < 4 || l.area() > 1 << 24 {
                return Err(Error::param(
                    "lattice",
                    format!("({},{});({},{})", u.0, u.1, v.0, v.1),
                    "a cell of 4 to 2^24 pixels",
                ));
            }
        }
        if let Some([w, h]) = b.tile
            && !((2..=4096).contains(&w) && (2..=4096).contains(&h))
        {
            return Err(Error::param(
                "tile",
                format!("{w}x{h}"),
                "sides of 2 to 4096 pixels",
            ));
        }
        if b.overlap == Some(0) {
            return Err(Error::param("overlap", 0, "at least 1 pixel"));
        }
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
            && !(e >= 2.0 && crate::error::positive_param("triangle-edge", e, "").is_ok())
        {
            return Err(Error::param(
                "triangle-edge",
                crate::error::short(e),
                "a length of at least 2 pixels, at most 1e30",
            ));
        }
        if let Some(s) = b.spacing_um {
            crate::error::positive_param("spacing", s, "a positive pixel spacing in µm")?;
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
            tiles: None,
            lattice: None,
            tile: None,
            overlap: None,
            rsgf: RsgfOptions::default(),
            colours: 2,
            synth: crate::models::synth::SynthParams::default(),
            quilting: Default::default(),
        })
    }

    /// The exemplar as analysis sees it: resampled to square pixels where its file gives
    /// different x and y spacings (and no spacing was given instead), missing points
    /// filled (or refused), levelled, down-sampled. Returns the raster and its spacing in
    /// µm.
    pub fn preprocess(&self, image: &ImageFile, source: &str) -> Result<(Raster, Option<f64>)> {
        let (raster, spacing, _) = self.preprocess_repeated(image, source, [1, 1], &mut |_| {})?;
        Ok((raster, spacing))
    }

    /// [`Baker::preprocess`], the exemplar repeated `repeat` times along x and y as a
    /// torus ([`crate::bake::auto::repeat_torus`]) after its form removal and
    /// down-sampling and before a photo's flat field: a flat field fitted to one small
    /// period takes its motif for light (a 25-px cell's dark square is the first
    /// harmonic of its side), one fitted to the repeats leaves it, while a height map's
    /// plane is taken off the period itself, not off a sawtooth of its copies. Also
    /// returns the form removal as the bank records it: the `--level` given, and where
    /// the default meets a photo, what its flat field did, which `progress` also gets.
    fn preprocess_repeated(
        &self,
        image: &ImageFile,
        source: &str,
        repeat: [usize; 2],
        progress: &mut dyn FnMut(&str),
    ) -> Result<(Raster, Option<f64>, String)> {
        let mut exemplar = std::borrow::Cow::Borrowed(&image.raster);
        let mut file_spacing = image.spacing_um;
        if let (None, true, Some(dx), Some(dy)) = (
            self.spacing_um,
            image.non_square(),
            image.spacing_um,
            image.spacing_y(),
        ) {
            let (square, d) = crate::prep::resample::square_pixels(&image.raster, dx, dy)?;
            exemplar = std::borrow::Cow::Owned(square);
            file_spacing = Some(d);
        }
        // A photo under the default form removal is flat-fielded instead: its mean (its
        // colour) stays, the light falling across the frame goes.
        let flat_field = self.leveling == crate::prep::Leveling::Auto
            && crate::bake::auto::is_photo(&image.raster);
        let mut raster = crate::prep::Prep {
            fill_missing: self.fill_missing,
            leveling: if flat_field {
                crate::prep::Leveling::None
            } else {
                self.leveling
            },
            downsample: self.downsample,
            filter: self.filter,
        }
        .apply(&exemplar, source)?;
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
        if repeat != [1, 1] {
            raster = crate::bake::auto::repeat_torus(&raster, repeat);
        }
        let level = if flat_field {
            let done = crate::prep::level::flatten_illumination(
                &mut raster,
                crate::prep::level::ILLUMINATION_DEGREE,
            );
            let done = format!(
                "photo: flat field of degree {}: {done}",
                crate::prep::level::ILLUMINATION_DEGREE
            );
            progress(&done);
            format!("{:?} ({done})", self.leveling)
        } else {
            format!("{:?}", self.leveling)
        };
        let spacing = self
            .spacing_um
            .or(file_spacing)
            .map(|s| s * self.downsample as f64);
        if let Some(value) = constant_pixel(&raster) {
            let value: Vec<String> = value.iter().map(|v| format!("{v}")).collect();
            return Err(Error::Analysis {
                what: source.to_string(),
                message: format!(
                    "every pixel is the same ({}) as prepared (after `level`), so there is no texture to synthesise; expected an exemplar that varies (a plane levels to one value; a pattern drawn in the alpha channel, which is not read, reads as one colour)",
                    value.join(", ")
                ),
            });
        }
        Ok((raster, spacing, level))
    }

    /// The preprocessed exemplar, repeated `repeat` times as a torus
    /// ([`Baker::preprocess_repeated`]), and what every bank header records of it:
    /// exemplar statistics (of the repeats, with the size of one period), spacing, seed
    /// and the preprocessing parameters as text.
    fn preprocess_with_header(
        &self,
        image: &ImageFile,
        source: &str,
        repeat: [usize; 2],
        progress: &mut dyn FnMut(&str),
    ) -> Result<(Raster, HeaderBase)> {
        let (ex, spacing_um, level) = self.preprocess_repeated(image, source, repeat, progress)?;
        let mut info = exemplar_info(&ex, &image.raster, source);
        (info.width, info.height) = (ex.width / repeat[0], ex.height / repeat[1]);
        let repeated = if repeat == [1, 1] {
            String::new()
        } else {
            format!(" repeated={}x{}", repeat[0], repeat[1])
        };
        let base = (
            info,
            spacing_um,
            self.seed,
            format!(
                "level={level} downsample={} filter={:?} fill_missing={}{repeated}",
                self.downsample, self.filter, self.fill_missing
            ),
        );
        Ok((ex, base))
    }

    /// The method [`Method::Auto`] picks for `image` after this baker's preprocessing,
    /// with its one-line reason ([`crate::bake::auto`]).
    pub fn choose_method(
        &self,
        image: &ImageFile,
        source: &str,
    ) -> Result<crate::bake::auto::AutoChoice> {
        let (ex, _) = self.preprocess(image, source)?;
        let photo = crate::bake::auto::is_photo(&image.raster);
        Ok(crate::bake::auto::choose_method(&ex, self.seed, photo))
    }

    /// Bakes `image` with the method `auto` picked.
    fn bake_choice(
        &self,
        choice: &crate::bake::auto::AutoChoice,
        image: &ImageFile,
        source: &str,
        progress: &mut dyn FnMut(&str),
    ) -> Result<Bank> {
        let mut baker = Baker {
            method: choice.method,
            ..self.clone()
        };
        baker.rsgf.stochastic |= choice.stochastic;
        if choice.repeat != [1, 1] {
            // Only stochastic RSGF takes a repeated exemplar (`auto::choose_stochastic`,
            // which bounded the repeats' size).
            let (torus, base) =
                self.preprocess_with_header(image, source, choice.repeat, progress)?;
            return crate::bake::rsgf::bake(&torus, &baker.rsgf, None, source, base, progress);
        }
        baker.bake(image, source, progress)
    }

    /// Bakes a blend bank from `image`. `source` names it in errors and in the bank;
    /// `progress` receives one line per step.
    pub fn bake(
        &self,
        image: &ImageFile,
        source: &str,
        progress: &mut dyn FnMut(&str),
    ) -> Result<Bank> {
        match self.method {
            Method::Roller => return self.bake_roller(image, source, progress),
            Method::Quilt => return self.bake_quilt(image, source, progress),
            Method::Milling => {
                return Err(Error::param(
                    "method",
                    "milling",
                    "an image method (rpn, adsn, roller): milling banks are baked from a TOML configuration by MillingSurface::to_bank",
                ));
            }
            Method::Rsgf => {
                let (ex, base) = self.preprocess_with_header(image, source, [1, 1], progress)?;
                return crate::bake::rsgf::bake(
                    &ex,
                    &self.rsgf,
                    self.lattice,
                    source,
                    base,
                    progress,
                );
            }
            Method::Synth => {
                let (ex, base) = self.preprocess_with_header(image, source, [1, 1], progress)?;
                return crate::bake::synth::bake_synth(&ex, &self.synth, base, progress);
            }
            Method::Quilting => {
                let (ex, base) = self.preprocess_with_header(image, source, [1, 1], progress)?;
                return crate::bake::quilting::bake(&ex, &self.quilting, base, progress);
            }
            Method::Auto => {
                let choice = self.choose_method(image, source)?;
                progress(&format!("auto: {}", choice.reason));
                let on_lattice = choice.method == Method::Roller
                    || (choice.method == Method::Rsgf && !choice.stochastic);
                return match self.bake_choice(&choice, image, source, progress) {
                    // A lattice the picked method cannot bake (a strong oblique one whose
                    // tile and overlap need more than the exemplar, or whose cell the
                    // exemplar does not show whole) is not the user's fault: `auto`
                    // goes on as for an exemplar without one, and says so.
                    Err(e) if on_lattice => {
                        let (ex, _) = self.preprocess(image, source)?;
                        let photo = crate::bake::auto::is_photo(&image.raster);
                        let instead = crate::bake::auto::choose_stochastic(&ex, self.seed, photo);
                        progress(&format!(
                            "auto: {} cannot bake the lattice ({e}); taken as stochastic instead: {}",
                            choice.method, instead.reason
                        ));
                        self.bake_choice(&instead, image, source, progress)
                    }
                    baked => baked,
                };
            }
            Method::Rpn | Method::Adsn => {}
        }
        let (ex, spacing_um, level) = self.preprocess_repeated(image, source, [1, 1], progress)?;
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
            let crops = self.taper.crops(&gauss_planes, w, [x0, y0, pw, ph]);
            let patch = match self.method {
                Method::Adsn => asymptotic_spot_noise(&crops, pw, ph, &mut rng),
                // The roller returned at the top of `bake`.
                Method::Rpn
                | Method::Roller
                | Method::Milling
                | Method::Rsgf
                | Method::Quilt
                | Method::Synth
                | Method::Quilting
                | Method::Auto => random_phase_noise(&crops, pw, ph, &mut rng),
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
            shift: None,
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
                shift: None,
            });
        }

        let exemplar = exemplar_info(&ex, &image.raster, source);
        let sqrt3 = 3f64.sqrt();
        let header = BankHeader {
            method: self.method,
            channels: c,
            tiles: self.bank_size,
            tile_size: [pw, ph],
            lattice: [[edge, 0.0], [edge / 2.0, edge * sqrt3 / 2.0]],
            levels,
            spacing_um,
            height_unit: height_unit(c, spacing_um),
            seed: self.seed,
            exemplar,
            bake: format!(
                "method={} patch={pw}x{ph} bank_size={} seed={} level={} downsample={} filter={:?} fill_missing={} triangle_edge={edge} taper={:?}",
                self.method,
                self.bank_size,
                self.seed,
                level,
                self.downsample,
                self.filter,
                self.fill_missing,
                self.taper
            ),
            record: Record::Blend {
                triangle_edge: edge,
                lut_size: LUT_SIZE,
                lut_z_range: LUT_Z_RANGE,
            },
        };
        Bank::new(header, texels, luts, source)
    }
}

impl Baker {
    /// Wang tiles (quilt): K⁴ tiles of T × T px quilted from crops
    /// ([`crate::analysis::quilt`]), each with its own 2 × 2 box mip chain, into a Wang
    /// bank. T is `--patch`, or the largest power of two (at most 256) whose tile plus
    /// strip ends fits the exemplar; `--overlap` is the cut band. Heights are kept as
    /// measured.
    fn bake_quilt(
        &self,
        image: &ImageFile,
        source: &str,
        progress: &mut dyn FnMut(&str),
    ) -> Result<Bank> {
        use crate::analysis::quilt::{WangLayout, wang_tiles};
        let (ex, spacing_um, level) = self.preprocess_repeated(image, source, [1, 1], progress)?;
        let (w, h, c) = (ex.width, ex.height, ex.channels);
        let side = match self.patch {
            Some(p) => p,
            None => {
                let mut t = 256usize;
                while t > 16
                    && WangLayout::new(self.colours, t, self.overlap)
                        .map_or(true, |l| l.min_exemplar() > w.min(h))
                {
                    t /= 2;
                }
                t
            }
        };
        let layout = WangLayout::new(self.colours, side, self.overlap)?;
        progress(&format!(
            "exemplar {w}×{h}×{c}; {} Wang tiles ({} colours) of {side}×{side} px, edge strips {} px, cut band {} px",
            layout.tiles(),
            layout.colours,
            2 * layout.edge,
            layout.band
        ));
        let wt = wang_tiles(&ex, layout, self.seed, source, progress)?;
        let k = layout.tiles();
        let mut flat: Vec<f32> = wt.tiles.concat();
        let mut texels = Vec::new();
        let mut levels = Vec::new();
        let mut s = side;
        loop {
            let (mean, sigma) = channel_stats(&flat, c);
            levels.push(LevelInfo {
                size: [s, s],
                mean,
                sigma,
                shift: Some(0),
            });
            if s / 2 < MIN_LEVEL_SIDE || levels.len() == 14 {
                texels.push(flat);
                break;
            }
            let next = box_half(&flat, k, s, s, c);
            texels.push(std::mem::replace(&mut flat, next));
            s /= 2;
        }
        progress(&format!("{} mip levels", levels.len()));
        let t = side as f64;
        let header = BankHeader {
            method: Method::Quilt,
            channels: c,
            tiles: k,
            tile_size: [side, side],
            lattice: [[t, 0.0], [0.0, t]],
            levels,
            spacing_um,
            height_unit: height_unit(c, spacing_um),
            seed: self.seed,
            exemplar: exemplar_info(&ex, &image.raster, source),
            bake: format!(
                "method=quilt colours={} patch={side} edge={} band={} seed={} level={} downsample={} filter={:?} fill_missing={}",
                layout.colours,
                layout.edge,
                layout.band,
                self.seed,
                level,
                self.downsample,
                self.filter,
                self.fill_missing
            ),
            record: Record::Wang {
                colours: layout.colours,
                seam_costs: wt.seam_costs,
            },
        };
        let luts = vec![Vec::new(); texels.len()];
        Bank::new(header, texels, luts, "just baked")
    }

    /// The roller (seed 003): lattice from `--lattice`, `--tile`, detection, or the
    /// largest axis-aligned tile that leaves the overlap; then double toroidal tiles and
    /// toroidal mips, into a toroidal bank. Heights are kept as measured (no T).
    fn bake_roller(
        &self,
        image: &ImageFile,
        source: &str,
        report: &mut dyn FnMut(&str),
    ) -> Result<Bank> {
        // The analysis takes a second or two; its lines are held back until it succeeds,
        // so a refused exemplar gets one error line, not a half-told story. Without
        // `tiles`, several are tried first (a single tile repeats on the lattice, seed
        // 003 allows several with identical borders), then fewer.
        let counts: Vec<usize> = match self.tiles {
            Some(n) => vec![n],
            None => (1..=DEFAULT_ROLLER_TILES).rev().collect(),
        };
        let mut last = None;
        for &n in &counts {
            let mut lines: Vec<String> = Vec::new();
            match self.bake_roller_quiet(image, source, n, &mut |l| lines.push(l.to_string())) {
                Ok(bank) => {
                    if self.tiles.is_none() && n < DEFAULT_ROLLER_TILES {
                        report(&format!(
                            "the exemplar does not hold {DEFAULT_ROLLER_TILES} tiles with identical borders: {n}"
                        ));
                    }
                    for l in &lines {
                        report(l);
                    }
                    return Ok(bank);
                }
                Err(e) => last = Some(e),
            }
        }
        Err(last.expect("at least one tile count"))
    }

    fn bake_roller_quiet(
        &self,
        image: &ImageFile,
        source: &str,
        n_tiles: usize,
        progress: &mut dyn FnMut(&str),
    ) -> Result<Bank> {
        let (ex, spacing_um, level) = self.preprocess_repeated(image, source, [1, 1], progress)?;
        let (w, h, c) = (ex.width, ex.height, ex.channels);
        progress(&format!(
            "exemplar {w}×{h}×{c}; roller with {n_tiles} tile(s)"
        ));
        let lattice = if let Some([u, v]) = self.lattice {
            progress(&format!(
                "lattice given: u = ({}, {}), v = ({}, {})",
                u.0, u.1, v.0, v.1
            ));
            Lattice::from_basis(u, v)?
        } else if let Some([tw, th]) = self.tile {
            Lattice::rectangular(tw as i64, th as i64)?
        } else {
            // A stochastic side: the largest that leaves the overlap (a sixth of the tile,
            // at least 8 px) and, for several tiles, room for their rhomboids.
            let per_axis = (n_tiles as f64).sqrt().ceil();
            let side = |n: usize| {
                let room = 1.0 + (per_axis - 1.0) / 2.0;
                let t = ((n as f64 * 6.0 / 7.0).min(n as f64 - 8.0) / room).floor();
                (t.max(2.0)) as i64
            };
            let fits = |l: Lattice| {
                let (nw, nh) = required_size(l, self.overlap);
                (nw <= w, nh <= h)
            };
            match detect(&ex) {
                Detection::Lattice(p) => {
                    progress(&format!(
                        "periodicity detected: u = ({}, {}), v = ({}, {}), autocorrelation {:.2}",
                        p.u.0, p.u.1, p.v.0, p.v.1, p.strength
                    ));
                    Lattice::from_basis(p.u, p.v)?
                }
                Detection::Stripes { u, lay, strength } => {
                    // Repeats across the lay only: u, and a stochastic side along the
                    // lay, shortened until tile and overlap fit.
                    let along = |t: i64| {
                        (
                            (t as f64 * lay.0).round() as i64,
                            (t as f64 * lay.1).round() as i64,
                        )
                    };
                    let free = if lay.0.abs() > lay.1.abs() { w } else { h };
                    let mut t = side(free);
                    while t > 2 && fits(Lattice::from_basis(u, along(t))?) != (true, true) {
                        t -= 1;
                    }
                    let mut v = along(t);
                    // Where u lies on an axis, the lay may be the other axis measured a
                    // little askew (the central peak of rows of blocks leans with their
                    // shapes: Extreme Tux Racer's pave02 read 1.6°, and its courses
                    // stepped 4 px at every cut). Of the measured lay and the axis, the
                    // side along which the exemplar continues itself better is taken;
                    // grooves that truly lean keep their lean.
                    let axis = match u {
                        (0, _) => Some((v.0, 0)),
                        (_, 0) => Some((0, v.1)),
                        _ => None,
                    };
                    if let Some(a) = axis.filter(|&a| a != v && a != (0, 0)) {
                        let fit = |l: Lattice| fits(l) == (true, true);
                        if Lattice::from_basis(u, a).is_ok_and(fit)
                            && shift_mismatch(&ex, a) < shift_mismatch(&ex, v)
                        {
                            v = a;
                        }
                    }
                    progress(&format!(
                        "stripes detected: u = ({}, {}) (autocorrelation {strength:.2}), no \
                         repeat along the lay: v = ({}, {}), stochastic",
                        u.0, u.1, v.0, v.1
                    ));
                    Lattice::from_basis(u, v)?
                }
                Detection::Stochastic => {
                    let (mut tw, mut th) = (side(w), side(h));
                    // Shrink until the tile plus its overlap fits (the estimate rounds).
                    while tw > 2 && th > 2 {
                        let (fw, fh) = fits(Lattice::rectangular(tw, th)?);
                        if fw && fh {
                            break;
                        }
                        tw -= !fw as i64;
                        th -= !fh as i64;
                    }
                    progress(&format!(
                        "no periodicity found: axis-aligned {tw}×{th} tiles"
                    ));
                    Lattice::rectangular(tw, th)?
                }
            }
        };
        let rt = roller_tiles(&ex, lattice, n_tiles, self.overlap, progress)?;
        let mut levels = Vec::new();
        let mut texels = Vec::new();
        let mut tiles = rt.tiles.clone();
        let [u, v] = rt.basis;
        let longest = ((u.0 * u.0 + u.1 * u.1).max(v.0 * v.0 + v.1 * v.1) as f64).sqrt();
        let mut l = 0u32;
        loop {
            let lat = lattice.at_level(l);
            let flat: Vec<f32> = tiles.concat();
            let (mean, sigma) = channel_stats(&flat, c);
            levels.push(LevelInfo {
                size: [lat.a as usize, lat.c as usize],
                mean,
                sigma,
                shift: Some(lat.b as usize),
            });
            texels.push(flat);
            l += 1;
            if l >= 14 || (1u64 << l) as f64 > longest / 2.0 {
                break;
            }
            tiles = mip_down(&tiles, lat, lattice.at_level(l), c);
        }
        progress(&format!(
            "{} tile(s) of {}×{} texels (row shift {}), {} mip levels",
            rt.tiles.len(),
            lattice.a,
            lattice.c,
            lattice.b,
            levels.len()
        ));
        let header = BankHeader {
            method: Method::Roller,
            channels: c,
            tiles: rt.tiles.len(),
            tile_size: [lattice.a as usize, lattice.c as usize],
            lattice: [[u.0 as f64, u.1 as f64], [v.0 as f64, v.1 as f64]],
            levels,
            spacing_um,
            height_unit: height_unit(c, spacing_um),
            seed: self.seed,
            exemplar: exemplar_info(&ex, &image.raster, source),
            bake: format!(
                "method=roller lattice=({},{});({},{}) tiles={} overlap={} origins={:?} phase={:?} level={} downsample={} filter={:?} fill_missing={}",
                u.0,
                u.1,
                v.0,
                v.1,
                n_tiles,
                rt.overlap,
                rt.origins,
                rt.phase,
                level,
                self.downsample,
                self.filter,
                self.fill_missing
            ),
            record: Record::Toroidal {
                seam_costs: rt.seam_costs,
            },
        };
        let luts = vec![Vec::new(); texels.len()];
        Bank::new(header, texels, luts, "just baked")
    }
}

/// Statistics of the preprocessed exemplar `ex`, kept in the bank, and the full scale of
/// `raw`, as read, where it was a photo ([`crate::io::photo_full_scale`]).
pub(crate) fn exemplar_info(ex: &Raster, raw: &Raster, source: &str) -> ExemplarInfo {
    let c = ex.channels;
    let sorted: Vec<Vec<f64>> = (0..c)
        .map(|ch| {
            let mut v = ex.channel_f64(ch);
            v.sort_by(f64::total_cmp);
            v
        })
        .collect();
    let quantile_levels = vec![0.0, 0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 0.99, 1.0];
    ExemplarInfo {
        source: source.to_string(),
        width: ex.width,
        height: ex.height,
        mean: sorted.iter().map(|s| mean_of(s)).collect(),
        std: sorted.iter().map(|s| std_of(s)).collect(),
        quantiles: sorted
            .iter()
            .map(|s| quantile_levels.iter().map(|&p| quantile(s, p)).collect())
            .collect(),
        quantile_levels,
        // Only where the preparation kept the photo's scale (the flat field, or none):
        // a plane-levelled photo lies about 0.
        levels: crate::io::photo_full_scale(raw)
            .filter(|&full| ex.data.iter().all(|&v| (0.0..=full).contains(&v))),
    }
}

/// Mean squared difference between `ex` and itself shifted by `d` (all channels, over
/// the pixels both cover): how well the exemplar continues itself along `d`.
fn shift_mismatch(ex: &Raster, d: (i64, i64)) -> f64 {
    let (w, h, c) = (ex.width as i64, ex.height as i64, ex.channels);
    let (mut sum, mut n) = (0.0, 0usize);
    for y in 0.max(-d.1)..h.min(h - d.1) {
        for x in 0.max(-d.0)..w.min(w - d.0) {
            for ch in 0..c {
                let a = ex.get(x as usize, y as usize, ch) as f64;
                let b = ex.get((x + d.0) as usize, (y + d.1) as usize, ch) as f64;
                sum += (a - b).powi(2);
            }
            n += c;
        }
    }
    if n == 0 {
        f64::INFINITY
    } else {
        sum / n as f64
    }
}

/// The one pixel value of a raster whose pixels are all equal, bit for bit (none
/// otherwise, or for an empty raster).
fn constant_pixel(r: &Raster) -> Option<&[f32]> {
    let mut px = r.data.chunks_exact(r.channels.max(1));
    let first = px.next()?;
    px.all(|p| p.iter().zip(first).all(|(a, b)| a.to_bits() == b.to_bits()))
        .then_some(first)
}

fn mean_of(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn std_of(v: &[f64]) -> f64 {
    let m = mean_of(v);
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// The height unit a bank of `c` channels records: µm for a height map with a known
/// spacing, none otherwise.
pub(crate) fn height_unit(c: usize, spacing_um: Option<f64>) -> String {
    if c == 1 && spacing_um.is_some() {
        "um".into()
    } else {
        String::new()
    }
}

/// Mean and standard deviation per channel of interleaved samples.
pub(crate) fn channel_stats(data: &[f32], c: usize) -> (Vec<f64>, Vec<f64>) {
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
