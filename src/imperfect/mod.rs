//! Imperfection layers over any surface (seed 004): a *tendency* field from abstract
//! sources (eqs. 1–2) and the surface's own geometry (exposure and curvature, eqs.
//! 3–10), guiding a stochastic blemish pattern (dust, eq. 11; patina; peeling, eq. 12).
//! The result is the weathered height, a layer id per point (the ground-truth mask of
//! a defect dataset) and the tendency.
//!
//! [`Imperfect`] wraps any [`Surface`] and is one itself. A region is computed from the
//! inner surface's heights on the region grown by a margin (the exposure rays' length
//! plus the curvature stencil), so every point depends only on heights at fixed
//! offsets around it: fills in pieces equal the whole, bit for bit.
//!
//! Units: positions in surface pixels. Heights enter the geometry scaled by `z_scale`
//! (surface pixels per height unit; by default chosen so that the rms slope is 0.5,
//! as shading does, which makes presets work on nanometre and millimetre maps alike).
//! Layer depths are in σ, the inner surface's height standard deviation.

pub mod geometry;
pub mod noise;
pub mod sources;

use std::ops::Range;
use std::path::Path;

use glam::DVec3;

use crate::error::{Error, Result, finite_param, non_negative_param, positive_param};
use crate::stream::{OriginSample, Region, Surface, default_threads, fill_parallel, for_bands};
use geometry::{Exposure, Window, local_shape, ray_pattern};
use noise::NoiseParams;
use sources::{Source, SourceConfig, total_flux};

/// Which blemish pattern.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Pattern {
    /// Dust (eq. 11): T″ = T·noise; the dust adds T″·depth to the height; layer 1
    /// where T″ ≥ λ₀.
    Dust,
    /// Patina: T″ = T·noise; layer 1 where T″ ≥ λ₀; the height is unchanged.
    Patina,
    /// Peeling (eq. 12): T″ = T·fBm; layer i where λᵢ₋₁ ≤ T″ < λᵢ; the height loses the
    /// depths of the layers peeled.
    Peeling,
}

/// The geometric factors (`[geometry]`): exposure (eqs. 4–6) and curvature (eqs.
/// 8–9), combined by α = 1 + r₀G_ξ + r₁|κ_a| + r₂|κ_g| (eq. 10).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GeometryConfig {
    /// d_h of ω(d) = d/(d_h + d) (eq. 4), in surface pixels (> 0).
    pub half_exposure_px: f64,
    /// n₀, the exposure rays (eq. 6), 1 to 1024.
    pub rays: usize,
    /// Longest ray, in surface pixels: bounds the cost and the fill margin.
    pub ray_length_px: f64,
    /// r₀, the weight of exposure G_ξ ∈ [0, 1] (negative: sheltered points gather more).
    pub exposure_weight: f64,
    /// r₁, the weight of |κ_a| (mean curvature).
    pub mean_curvature_weight: f64,
    /// r₂, the weight of |κ_g| (Gaussian curvature).
    pub gaussian_curvature_weight: f64,
    /// The scale of the curvatures and normals, in surface pixels (≥ 1): central
    /// differences over ± this distance. 1 is eq. (9) at the finest scale; a rough
    /// surface's pixel-scale curvature is mostly noise, so the presets use a few pixels.
    pub curvature_scale_px: f64,
    /// Curvatures in units of their rms over a 256² sample of the surface at the origin
    /// (default), so that a weight means the same on any surface; `false`: in 1/px and
    /// 1/px², as eq. (10) writes them.
    pub curvature_relative: bool,
}

impl Default for GeometryConfig {
    fn default() -> Self {
        GeometryConfig {
            half_exposure_px: 8.0,
            rays: 16,
            ray_length_px: 32.0,
            exposure_weight: 0.0,
            mean_curvature_weight: 0.0,
            gaussian_curvature_weight: 0.0,
            curvature_scale_px: 1.0,
            curvature_relative: true,
        }
    }
}

/// Layer thresholds and depths (`[layers]`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LayersConfig {
    /// λ₀ < λ₁ < … in (0, 1] (eq. 12); dust and patina use λ₀ only.
    pub thresholds: Vec<f64>,
    /// Peeling: the thickness of each layer lost, in σ of the surface heights (one per
    /// threshold). Dust: one value, the thickness of full dust (T″ = 1).
    pub depths_sigma: Vec<f64>,
    /// Colours (linear RGB in [0, 1]) for the colour image: the object's, then one per
    /// threshold (dust and patina: the full layer's, blended by T″ as eq. 11 does;
    /// peeling: the colour of each layer laid bare, eq. 12). Empty: a palette per
    /// pattern.
    pub colours: Vec<[f32; 3]>,
}

impl Default for LayersConfig {
    fn default() -> Self {
        LayersConfig {
            thresholds: vec![0.3],
            depths_sigma: vec![0.2],
            colours: Vec::new(),
        }
    }
}

fn one() -> f64 {
    1.0
}

/// An imperfection layer's configuration (a `.toml`; presets `dust`, `patina`,
/// `peeling` in `tiles/imperfect/`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImperfectConfig {
    /// The blemish pattern.
    pub pattern: Pattern,
    /// Growth: every γ is multiplied by it (seed 004 §4.1). Default 1.
    #[serde(default = "one")]
    pub age: f64,
    /// Surface pixels per height unit; default: the one that makes the rms slope 0.5.
    #[serde(default)]
    pub z_scale: Option<f64>,
    /// The sources (`[[source]]`), at least one.
    #[serde(default)]
    pub source: Vec<SourceConfig>,
    /// Exposure and curvature.
    #[serde(default)]
    pub geometry: GeometryConfig,
    /// The noise of the pattern.
    #[serde(default)]
    pub noise: NoiseParams,
    /// Layer thresholds and depths.
    #[serde(default)]
    pub layers: LayersConfig,
}

macro_rules! preset {
    ($name:literal) => {
        (
            $name,
            include_str!(concat!("../../tiles/imperfect/", $name, ".toml")),
        )
    };
}

/// The presets, by name, with their TOML text.
pub const PRESETS: [(&str, &str); 3] = [preset!("dust"), preset!("patina"), preset!("peeling")];

impl ImperfectConfig {
    /// Parses and validates a TOML text; `what` names it in errors.
    pub fn from_toml(text: &str, what: &str) -> Result<ImperfectConfig> {
        let c: ImperfectConfig =
            toml::from_str(text).map_err(|e| crate::models::toml_error(text, what, e))?;
        c.validate()?;
        Ok(c)
    }

    /// A file, or a preset name (`dust`, `patina`, `peeling`) where no such file
    /// exists. Returns the configuration and the folder its relative paths are in.
    pub fn load(path: &Path) -> Result<(ImperfectConfig, Option<std::path::PathBuf>)> {
        crate::models::preset_or_file(
            path,
            &PRESETS,
            "imperfect",
            "an imperfection .toml file",
            ImperfectConfig::from_toml,
        )
    }

    /// Checks every parameter, naming the first one out of range (a projector's mask
    /// file is read when the layer is built, where its folder is known).
    pub fn validate(&self) -> Result<()> {
        let g = &self.geometry;
        positive_param(
            "geometry.half_exposure_px",
            g.half_exposure_px,
            "d_h > 0 pixels: the half-exposure distance of ω(d) = d/(d_h + d) (eq. 4)",
        )?;
        if !(1..=1024).contains(&g.rays) {
            return Err(Error::param("geometry.rays", g.rays, "1 to 1024 rays"));
        }
        if !(g.ray_length_px.is_finite() && g.ray_length_px >= 1.0 && g.ray_length_px <= 1024.0) {
            return Err(Error::param(
                "geometry.ray_length_px",
                g.ray_length_px,
                "1 to 1024 pixels",
            ));
        }
        for (name, v) in [
            ("geometry.exposure_weight", g.exposure_weight),
            ("geometry.mean_curvature_weight", g.mean_curvature_weight),
            (
                "geometry.gaussian_curvature_weight",
                g.gaussian_curvature_weight,
            ),
        ] {
            finite_param(name, v, "a finite weight")?;
        }
        if !(g.curvature_scale_px.is_finite() && (1.0..=64.0).contains(&g.curvature_scale_px)) {
            return Err(Error::param(
                "geometry.curvature_scale_px",
                g.curvature_scale_px,
                "1 to 64 pixels",
            ));
        }
        non_negative_param("age", self.age, "a finite age ≥ 0 (it scales every γ)")?;
        if let Some(z) = self.z_scale {
            positive_param("z_scale", z, "positive surface pixels per height unit")?;
        }
        if self.source.is_empty() {
            return Err(Error::param(
                "source",
                "none",
                "at least one [[source]] (ambient, point, directional, spotlight or projector)",
            ));
        }
        for (i, c) in self.source.iter().enumerate() {
            Source::check(c, i + 1)?;
        }
        self.noise.validate()?;
        let l = &self.layers;
        if l.thresholds.is_empty() {
            return Err(Error::param(
                "layers.thresholds",
                "[]",
                "at least one threshold λ₀ in (0, 1]",
            ));
        }
        let mut last = 0.0;
        for (i, &t) in l.thresholds.iter().enumerate() {
            if !(t > last && t <= 1.0) {
                return Err(Error::param(
                    "layers.thresholds",
                    format!("{:?}", l.thresholds),
                    format!(
                        "thresholds in increasing order within (0, 1]: λ{i} = {t} must exceed {last}"
                    ),
                ));
            }
            last = t;
        }
        let depths_wanted = match self.pattern {
            Pattern::Dust => 1,
            Pattern::Patina => 0,
            Pattern::Peeling => l.thresholds.len(),
        };
        if self.pattern != Pattern::Patina && l.depths_sigma.len() != depths_wanted {
            return Err(Error::param(
                "layers.depths_sigma",
                format!("{:?}", l.depths_sigma),
                format!("{depths_wanted} depth(s) for {:?}", self.pattern).to_lowercase(),
            ));
        }
        for &d in &l.depths_sigma {
            non_negative_param(
                "layers.depths_sigma",
                d,
                "finite depths ≥ 0, in σ of the surface heights",
            )?;
        }
        if !l.colours.is_empty() {
            // Peeling shows the colour of each layer laid bare (the object's and one per
            // threshold); dust and patina blend the object's with the layer's.
            let wanted = match self.pattern {
                Pattern::Peeling => l.thresholds.len() + 1,
                Pattern::Dust | Pattern::Patina => 2,
            };
            if l.colours.len() < wanted {
                return Err(Error::param(
                    "layers.colours",
                    l.colours.len(),
                    format!(
                        "at least {wanted} RGB colours for {:?} (the object's, then one per layer)",
                        self.pattern
                    )
                    .to_lowercase(),
                ));
            }
            if let Some(c) = l
                .colours
                .iter()
                .find(|c| c.iter().any(|v| !(0.0..=1.0).contains(v)))
            {
                return Err(Error::param(
                    "layers.colours",
                    format!("{c:?}"),
                    "RGB components within [0, 1]",
                ));
            }
        }
        Ok(())
    }
}

impl ImperfectConfig {
    /// The colours of the colour image: `layers.colours`, or the pattern's palette
    /// (bare grey object; dust a light beige; patina verdigris; peeling: an ochre coat
    /// over a red primer, a grey undercoat and the metal).
    pub fn colours(&self) -> Vec<[f32; 3]> {
        if !self.layers.colours.is_empty() {
            return self.layers.colours.clone();
        }
        let mut c = match self.pattern {
            Pattern::Dust => vec![[0.50, 0.52, 0.56], [0.97, 0.92, 0.80]],
            Pattern::Patina => vec![[0.72, 0.52, 0.30], [0.35, 0.66, 0.56]],
            Pattern::Peeling => vec![
                [0.80, 0.62, 0.25],
                [0.66, 0.22, 0.16],
                [0.55, 0.55, 0.55],
                [0.80, 0.80, 0.84],
            ],
        };
        // Peeling with other than three layers: repeat the last.
        while c.len() < self.layers.thresholds.len() + 1 {
            c.push(*c.last().expect("non-empty"));
        }
        c.truncate(self.layers.thresholds.len() + 1);
        c
    }

    /// The colour image (8-bit RGB) of points with layer ids `layers` and patterns T″
    /// `pattern` (a [`LayerFill`]'s), lit by `shading` (8-bit grey, one per point): dust
    /// and patina blend S = T″·S_layer + (1 − T″)·S_object (eq. 11) where the layer
    /// shows; peeling shows the colour of the layer laid bare (eq. 12).
    pub fn colour_image(&self, layers: &[u8], pattern: &[f32], shading: &[u8]) -> Vec<u8> {
        let c = self.colours();
        let mut out = Vec::with_capacity(shading.len() * 3);
        for ((&id, &t2), &light) in layers.iter().zip(pattern).zip(shading) {
            let s = match self.pattern {
                Pattern::Peeling => c[id as usize],
                _ => {
                    let t = if id > 0 && t2.is_finite() { t2 } else { 0.0 };
                    let (a, b) = (c[0], c[1]);
                    [
                        t * b[0] + (1.0 - t) * a[0],
                        t * b[1] + (1.0 - t) * a[1],
                        t * b[2] + (1.0 - t) * a[2],
                    ]
                }
            };
            let l = light as f32 / 255.0;
            out.extend(
                s.iter()
                    .map(|v| (v * l * 255.0).round().clamp(0.0, 255.0) as u8),
            );
        }
        out
    }
}

/// A region's layers: the weathered heights, the layer id (0: intact outermost layer;
/// dust and patina: 1 where present; peeling: the layer showing) and the tendency T.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerFill {
    /// Weathered heights (channel 0 of the inner surface, in its units).
    pub heights: Vec<f32>,
    /// Layer id per point.
    pub layers: Vec<u8>,
    /// Tendency T ∈ [0, 1] (eq. 3), before the noise.
    pub tendency: Vec<f32>,
    /// T″ = T·noise(P) ∈ [0, 1], the pattern the layers are cut from (eqs. 11–12).
    pub pattern: Vec<f32>,
}

/// The finest sampling step a layer is computed at, in surface pixels: its rays and
/// stencils are measured in samples, so finer steps would need margins of
/// ray_length / step samples (at 1/8, 8 × the ray length).
pub const MIN_STEP: f64 = 0.125;

/// Values per point of a computed band: height, layer id, T, T″.
const OUT: usize = 4;

/// Rows per band of a parallel fill: each band reads its margin again, so bands are
/// taller than the streaming default.
const IMPERFECT_BAND_ROWS: usize = 64;

/// Columns computed together within a band (see `Imperfect::compute`).
const COLUMN_BLOCK: usize = 128;

/// An imperfection layer over `S` (seed 004), itself a [`Surface`] of weathered
/// heights.
pub struct Imperfect<S> {
    inner: S,
    config: ImperfectConfig,
    sources: Vec<Source>,
    pattern: Vec<[f64; 3]>,
    z_scale: f64,
    sigma: f64,
    /// The units |κ_a| and |κ_g| are divided by (1 unless `curvature_relative`).
    curvature_units: [f64; 2],
    seed: u32,
}

impl<S: Surface> Imperfect<S> {
    /// The layer `config` over `inner`, with noise seed `seed`; a projector's mask path
    /// is relative to `base`. Measures σ and the rms slope on a 256² fill at the origin;
    /// refuses a source placed inside the surface.
    pub fn new(
        inner: S,
        config: &ImperfectConfig,
        base: Option<&Path>,
        seed: u32,
    ) -> Result<Imperfect<S>> {
        config.validate()?;
        let origin = OriginSample::of(&inner)?;
        let n = OriginSample::SIZE;
        let sd = origin.sd;
        let sigma = if sd > 0.0 && sd.is_finite() { sd } else { 1.0 };
        let z_scale = config.z_scale.unwrap_or(origin.half_slope_scale());
        let mut curvature_units = [1.0, 1.0];
        if config.geometry.curvature_relative {
            let scaled: Vec<f32> = origin
                .heights
                .iter()
                .map(|&v| (v as f64 * z_scale) as f32)
                .collect();
            let win = Window {
                data: &scaled,
                width: n,
                height: n,
            };
            let (mut sa, mut sg, mut k) = (0.0f64, 0.0f64, 0usize);
            let stride = (config.geometry.curvature_scale_px.round() as usize).max(1);
            for y in stride..n - stride {
                for x in stride..n - stride {
                    let (_, a, g) = local_shape(&win, y * n + x, stride);
                    if a.is_finite() && g.is_finite() {
                        sa += a * a;
                        sg += g * g;
                        k += 1;
                    }
                }
            }
            let k = k.max(1) as f64;
            for (u, s) in curvature_units.iter_mut().zip([sa, sg]) {
                let rms = (s / k).sqrt();
                if rms > 0.0 && rms.is_finite() {
                    *u = rms;
                }
            }
        }
        let mut sources = Vec::with_capacity(config.source.len());
        for (i, sc) in config.source.iter().enumerate() {
            let s = Source::new(sc, i + 1, base)?;
            if let Some(p) = s.position() {
                let below = inner.height(p.x, p.y) as f64 * z_scale;
                if p.z.is_nan() || below.is_nan() || p.z <= below {
                    return Err(Error::param(
                        format!("source {}: position", i + 1),
                        format!("[{}, {}, {}]", p.x, p.y, p.z),
                        format!(
                            "a point above the surface: the source is inside it (the surface there is at z = {below:.3} px)"
                        ),
                    ));
                }
            }
            sources.push(s.aged(config.age));
        }
        Ok(Imperfect {
            inner,
            config: config.clone(),
            sources,
            pattern: ray_pattern(config.geometry.rays),
            z_scale,
            sigma,
            curvature_units,
            seed,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &ImperfectConfig {
        &self.config
    }

    /// Surface pixels per height unit used by the geometry.
    pub fn z_scale(&self) -> f64 {
        self.z_scale
    }

    /// σ, the height standard deviation layer depths are measured in.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// The curvature stencil's half width in samples at `step`.
    fn stride(&self, step: f64) -> usize {
        ((self.config.geometry.curvature_scale_px / step).round() as usize).max(1)
    }

    /// Samples of margin a fill at `step` reads around its region: the rays' reach
    /// (plus one for the bilinear) or the curvature stencil, whichever is wider.
    fn margin(&self, step: f64) -> usize {
        ((self.config.geometry.ray_length_px / step).ceil() as usize + 2).max(self.stride(step) + 1)
    }

    /// Refuses steps finer than [`MIN_STEP`].
    fn check_step(region: &Region) -> Result<()> {
        if region.step < MIN_STEP {
            return Err(Error::param(
                "step",
                region.step,
                "at least 1/8 pixel for an imperfection layer (its rays and curvature stencils are measured in samples)",
            ));
        }
        Ok(())
    }

    /// Heights, layer ids and tendencies of `region`, on all cores.
    pub fn fill_layers(&self, region: &Region) -> Result<LayerFill> {
        region.validate()?;
        Self::check_step(region)?;
        let len = region.width * region.height;
        let mut out = vec![0.0f32; len * OUT];
        for_bands(
            region,
            OUT,
            &mut out,
            default_threads(),
            IMPERFECT_BAND_ROWS,
            |rows, chunk| self.compute(region, rows, chunk),
        )?;
        let mut f = LayerFill {
            heights: Vec::with_capacity(len),
            layers: Vec::with_capacity(len),
            tendency: Vec::with_capacity(len),
            pattern: Vec::with_capacity(len),
        };
        for p in out.chunks_exact(OUT) {
            f.heights.push(p[0]);
            f.layers.push(p[1] as u8);
            f.tendency.push(p[2]);
            f.pattern.push(p[3]);
        }
        Ok(f)
    }

    /// Rows `rows` of `region` as interleaved (height, layer id, T, T″) into `out`;
    /// NaN (layer 0) below [`MIN_STEP`].
    fn compute(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        let step = region.step;
        if step.is_nan() || step < MIN_STEP {
            for o in out.chunks_exact_mut(OUT) {
                o.copy_from_slice(&[f32::NAN, 0.0, f32::NAN, f32::NAN]);
            }
            return;
        }
        let m = self.margin(step);
        let stride = self.stride(step);
        let (w, h) = (region.width, rows.len());
        let grown = Region {
            col0: region.col0 - m as i64,
            row0: region.row0 + rows.start as i64 - m as i64,
            width: w + 2 * m,
            height: h + 2 * m,
            ..*region
        };
        let (gw, gh) = (grown.width, grown.height);
        let c = self.inner.channels();
        let mut raw = vec![0.0f32; gw * gh * c];
        if fill_parallel(&self.inner, &grown, &mut raw, 1).is_err() {
            out.fill(f32::NAN);
            return;
        }
        let heights: Vec<f32> = raw.iter().step_by(c).copied().collect();
        // Heights in sample units: x, y and z in one unit for the rays and curvatures.
        let k = (self.z_scale / step) as f32;
        let scaled: Vec<f32> = heights.iter().map(|&v| v * k).collect();
        let win = Window {
            data: &scaled,
            width: gw,
            height: gh,
        };
        let g = &self.config.geometry;
        let exposure = (g.exposure_weight != 0.0).then(|| {
            Exposure::new(
                &self.pattern,
                g.ray_length_px / step,
                g.half_exposure_px / step,
            )
        });
        let tops = exposure
            .as_ref()
            .map(|e| geometry::local_max(&win, e.margin()))
            .unwrap_or_default();
        let layers = &self.config.layers;
        // Column blocks keep the rays' reach (the block plus its margin, over the rows
        // within a ray length) in L2 cache.
        for block in (0..w).step_by(COLUMN_BLOCK) {
            for r in 0..h {
                let y = region.y_at(rows.start + r);
                for col in block..(block + COLUMN_BLOCK).min(w) {
                    let at = (r + m) * gw + col + m;
                    let o = &mut out[(r * w + col) * OUT..(r * w + col + 1) * OUT];
                    let hv = heights[at];
                    if !hv.is_finite() {
                        o.copy_from_slice(&[f32::NAN, 0.0, f32::NAN, f32::NAN]);
                        continue;
                    }
                    let x = region.x_at(col);
                    let ([hu, hvv], mean, gauss) = local_shape(&win, at, stride);
                    let normal = DVec3::new(-hu, -hvv, 1.0).normalize();
                    let p = DVec3::new(x, y, hv as f64 * self.z_scale);
                    let flux = total_flux(&self.sources, p, normal);
                    let exposed = exposure.as_ref().map_or(1.0, |e| {
                        e.at(&win, col + m, r + m, normal.to_array(), tops[at])
                    });
                    // Curvatures from sample units to 1/px and 1/px².
                    let alpha = 1.0
                        + g.exposure_weight * exposed
                        + g.mean_curvature_weight * (mean / step).abs() / self.curvature_units[0]
                        + g.gaussian_curvature_weight * (gauss / (step * step)).abs()
                            / self.curvature_units[1];
                    let t = (flux * alpha).clamp(0.0, 1.0);
                    let t2 = t * self.config.noise.at(self.seed, x, y);
                    let id = layers.thresholds.iter().take_while(|&&l| t2 >= l).count();
                    let height = match self.config.pattern {
                        Pattern::Dust => hv as f64 + t2 * layers.depths_sigma[0] * self.sigma,
                        Pattern::Patina => hv as f64,
                        Pattern::Peeling => {
                            hv as f64 - layers.depths_sigma[..id].iter().sum::<f64>() * self.sigma
                        }
                    };
                    o[0] = height as f32;
                    o[1] = id as f32;
                    o[2] = t as f32;
                    o[3] = t2 as f32;
                }
            }
        }
    }
}

impl<S: Surface> Imperfect<S> {
    /// Output `k` (0 height, 1 layer id, 2 T, 3 T″) of rows `rows` of `region`.
    fn rows_of(&self, k: usize, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        let mut o = vec![0.0f32; rows.len() * region.width * OUT];
        self.compute(region, rows, &mut o);
        for (d, s) in out.iter_mut().zip(o.chunks_exact(OUT)) {
            *d = s[k];
        }
    }

    /// Output `k` of one sample with its margin: bounded cost, (2·margin + 1)² inner
    /// heights.
    fn sample_of(&self, k: usize, x: f64, y: f64, footprint: f64) -> f32 {
        let step = if footprint.is_finite() && footprint > 0.0 {
            footprint
        } else {
            1.0
        };
        let region = Region::new(x, y, 1, 1).with_step(step);
        let mut o = [0.0f32; OUT];
        self.compute(&region, 0..1, &mut o);
        o[k]
    }

    /// Output `k` of `region`, in bands on all cores.
    fn fill_of(&self, k: usize, region: &Region, out: &mut [f32]) -> Result<()> {
        region.validate()?;
        Self::check_step(region)?;
        if out.len() != region.width * region.height {
            return Err(Error::param(
                "buffer",
                format!("{} values", out.len()),
                format!("{}×{} values", region.width, region.height),
            ));
        }
        for_bands(
            region,
            1,
            out,
            default_threads(),
            IMPERFECT_BAND_ROWS,
            |rows, chunk| self.rows_of(k, region, rows, chunk),
        )
    }
}

/// The layer ids of an imperfection layer as a one-channel surface (0.0, 1.0, …), for
/// page streamers and the viewer's mask view.
pub struct LayerIds<S>(pub std::sync::Arc<Imperfect<S>>);

impl<S: Surface> Surface for LayerIds<S> {
    fn channels(&self) -> usize {
        1
    }

    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        out[0] = self.0.sample_of(1, x, y, footprint);
    }

    fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        self.0.rows_of(1, region, rows, out)
    }

    fn fill(&self, region: &Region, out: &mut [f32]) -> Result<()> {
        self.0.fill_of(1, region, out)
    }
}

impl<S: Surface> Surface for Imperfect<S> {
    fn channels(&self) -> usize {
        1
    }

    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        out[0] = self.sample_of(0, x, y, footprint);
    }

    fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        self.rows_of(0, region, rows, out)
    }

    fn fill(&self, region: &Region, out: &mut [f32]) -> Result<()> {
        self.fill_of(0, region, out)
    }
}
