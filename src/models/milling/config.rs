//! The milling model's parameters (seed 000, Table 3) as a TOML file.
//!
//! Every key carries its unit in its name: lengths on the part in millimetres (`_mm`),
//! heights in micrometres (`_um`), angles in degrees (`_deg`); keys without a unit are
//! ratios or counts. Every key has a default, so an empty file is a valid configuration
//! (a 4 mm head, a_e = 0.5, bump rings, convex interaction, parallel path). Unknown keys
//! are refused, so a typo never silently falls back to a default.
//!
//! ```toml
//! [tool]
//! diameter_mm = 4.0          # d: the ring diameter, r = d/2
//!
//! [shape]                    # §4.1.1
//! kind = "bump"              # indicator | cosine | bump
//! width_mean_mm = 0.15       # μ_w⁻ ∈ (0, d/2): the cutting edge
//! width_std_mm = 0.01        # σ_w⁻
//! inner_width_mean_mm = 0.05 # μ_w⁺ⁱ ∈ [0, d/2 − μ_w⁻]
//! inner_width_std_mm = 0.005
//! outer_width_mean_mm = 0.08 # μ_w⁺ᵒ ≥ 0
//! outer_width_std_mm = 0.008
//!
//! [tilt]                     # §4.1.2
//! tilt_deg = 0.05            # φ; with depth_um gives μ_l⁻, μ_h⁻ = l ∓ r·sin φ
//! depth_um = 2.0             # l
//! # low_mean_um / high_mean_um set μ_l⁻ / μ_h⁻ directly instead
//!
//! [noise]                    # §4.1.3
//! amplitude_um = 0.15        # 0 switches the noise off
//! count_mean = 50            # λ: Poisson mean of the number of sines
//! frequency_mean = 50        # τ: Poisson mean of their angular frequencies
//!
//! [interaction]              # §4.2
//! kind = "convex"            # min | latest | convex
//!
//! [path]                     # §4.3
//! kind = "parallel"          # parallel | spiral
//! overlap = 0.5              # α ∈ (0, 1); ρ = (1 − α)·d, a_e = 1 − α
//! step_mm = 0.4              # δ > 0
//! ```
//!
//! [`MillingConfig::validate`] checks every range of Table 3 and names the key.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Ring shape (seed 000 §4.1.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ShapeKind {
    /// −1 on the indentation ring, 0 elsewhere.
    Indicator,
    /// −cos(π/2·D⁻) on the indentation ring.
    Cosine,
    /// The cosine indentation plus positive cosine accumulations inside and outside it.
    Bump,
}

/// Ring interaction (seed 000 §4.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InteractionKind {
    /// The deepest value wins; order does not matter.
    Min,
    /// The newest ring covering the point wins.
    Latest,
    /// Convex combination A_k·R_k + (1 − A_k)·f_{k−1}, newest last.
    Convex,
}

/// Tool path (seed 000 §4.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PathKind {
    /// Parallel lines (§4.3.1).
    Parallel,
    /// Archimedean spiral (§4.3.2).
    Spiral,
}

/// Order in which the parallel lines are milled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LineOrder {
    /// Line j after line j − 1 (towards +t, the left of the milling direction β).
    Ascending,
    /// Line j after line j + 1.
    Descending,
}

/// Milling direction along the parallel lines.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LineDirection {
    /// Every line in the same direction (the tool is lifted between lines).
    Oneway,
    /// Alternating: back and forth.
    Zigzag,
}

/// Turning sense of the spiral (o in seed 000 §4.3.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Orientation {
    /// Counter-clockwise, o = 1.
    Ccw,
    /// Clockwise, o = −1.
    Cw,
}

/// Direction of travel on the spiral.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Travel {
    /// From the origin outwards (the paper's default).
    Outward,
    /// From `radius_mm` inwards to the origin.
    Inward,
}

/// `[tool]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ToolConfig {
    /// d, the milling head diameter; the rings have radius r = d/2. Default 4 mm.
    pub diameter_mm: f64,
}

impl Default for ToolConfig {
    fn default() -> Self {
        ToolConfig { diameter_mm: 4.0 }
    }
}

/// `[shape]`: ring shape and the normal distributions of its widths.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShapeConfig {
    /// Shape function. Default bump.
    pub kind: ShapeKind,
    /// μ_w⁻, mean width of the indentation (the cutting edge), in (0, d/2). Default 0.15 mm.
    pub width_mean_mm: f64,
    /// σ_w⁻. Default 0.01 mm.
    pub width_std_mm: f64,
    /// μ_w⁺ⁱ, mean width of the inner accumulation (bump only), in [0, d/2 − μ_w⁻].
    /// Default 0.05 mm.
    pub inner_width_mean_mm: f64,
    /// σ_w⁺ⁱ. Default 0.005 mm.
    pub inner_width_std_mm: f64,
    /// μ_w⁺ᵒ, mean width of the outer accumulation (bump only), ≥ 0. Default 0.08 mm.
    pub outer_width_mean_mm: f64,
    /// σ_w⁺ᵒ. Default 0.008 mm.
    pub outer_width_std_mm: f64,
}

impl Default for ShapeConfig {
    fn default() -> Self {
        ShapeConfig {
            kind: ShapeKind::Bump,
            width_mean_mm: 0.15,
            width_std_mm: 0.01,
            inner_width_mean_mm: 0.05,
            inner_width_std_mm: 0.005,
            outer_width_mean_mm: 0.08,
            outer_width_std_mm: 0.008,
        }
    }
}

/// `[tilt]`: the tilting planes of eq. (1), as scaling factors of the shape (µm).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TiltConfig {
    /// φ, the tilt of the head towards the feed direction. With `depth_um` it gives
    /// μ_l⁻ = l − r·sin φ and μ_h⁻ = l + r·sin φ. Default 0.05°.
    pub tilt_deg: f64,
    /// l, the indentation depth at the tool centre. Default 2 µm.
    pub depth_um: f64,
    /// μ_l⁻ (rear of the indentation), overriding the value from tilt and depth.
    pub low_mean_um: Option<f64>,
    /// μ_h⁻ (front of the indentation), overriding the value from tilt and depth.
    pub high_mean_um: Option<f64>,
    /// σ_l⁻. Default 0.2 µm.
    pub low_std_um: f64,
    /// σ_h⁻. Default 0.2 µm.
    pub high_std_um: f64,
    /// μ_l⁺ⁱ. Default 0.3 µm.
    pub inner_low_mean_um: f64,
    /// μ_h⁺ⁱ. Default 0.3 µm.
    pub inner_high_mean_um: f64,
    /// σ_l⁺ⁱ. Default 0.05 µm.
    pub inner_low_std_um: f64,
    /// σ_h⁺ⁱ. Default 0.05 µm.
    pub inner_high_std_um: f64,
    /// μ_l⁺ᵒ (the outer accumulation is higher than the inner one: the tool keeps
    /// material from settling inside). Default 0.6 µm.
    pub outer_low_mean_um: f64,
    /// μ_h⁺ᵒ. Default 0.6 µm.
    pub outer_high_mean_um: f64,
    /// σ_l⁺ᵒ. Default 0.1 µm.
    pub outer_low_std_um: f64,
    /// σ_h⁺ᵒ. Default 0.1 µm.
    pub outer_high_std_um: f64,
}

impl Default for TiltConfig {
    fn default() -> Self {
        TiltConfig {
            tilt_deg: 0.05,
            depth_um: 2.0,
            low_mean_um: None,
            high_mean_um: None,
            low_std_um: 0.2,
            high_std_um: 0.2,
            inner_low_mean_um: 0.3,
            inner_high_mean_um: 0.3,
            inner_low_std_um: 0.05,
            inner_high_std_um: 0.05,
            outer_low_mean_um: 0.6,
            outer_high_mean_um: 0.6,
            outer_low_std_um: 0.1,
            outer_high_std_um: 0.1,
        }
    }
}

/// `[noise]` (§4.1.3): per ring, a Poisson(λ) number of sines of the polar angle with
/// Poisson(τ) frequencies and uniform shifts, averaged and scaled by `amplitude_um`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseConfig {
    /// Scale of N_k; 0 switches the noise off. Default 0.15 µm.
    pub amplitude_um: f64,
    /// λ, the mean number of sines (1 to 1000). Default 50.
    pub count_mean: f64,
    /// τ, the mean angular frequency (0 to 500). Default 50.
    pub frequency_mean: f64,
}

impl Default for NoiseConfig {
    fn default() -> Self {
        NoiseConfig {
            amplitude_um: 0.15,
            count_mean: 50.0,
            frequency_mean: 50.0,
        }
    }
}

/// `[interaction]` (§4.2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InteractionConfig {
    /// Interaction function. Default convex.
    pub kind: InteractionKind,
    /// a_min of a_k ~ U[a_min, a_max], the weight A_k at the front of a ring (convex).
    /// Default 0.5.
    pub front_weight_min: f64,
    /// a_max. Default 0.9.
    pub front_weight_max: f64,
    /// b_min of b_k ~ U[b_min, b_max], the weight A_k at the rear of a ring. Default 0.2.
    pub rear_weight_min: f64,
    /// b_max. Default 0.5.
    pub rear_weight_max: f64,
}

impl Default for InteractionConfig {
    fn default() -> Self {
        InteractionConfig {
            kind: InteractionKind::Convex,
            front_weight_min: 0.5,
            front_weight_max: 0.9,
            rear_weight_min: 0.2,
            rear_weight_max: 0.5,
        }
    }
}

/// `[path]` (§4.3): the tool path and the randomisation of centres and order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PathConfig {
    /// Parallel lines or a spiral. Default parallel.
    pub kind: PathKind,
    /// α ∈ (0, 1), the ring overlap of neighbouring lines or turns: ρ = (1 − α)·d.
    /// The radial width of cut is a_e = 1 − α. Default 0.5.
    pub overlap: f64,
    /// δ > 0, the distance between successive ring centres (feed per revolution).
    /// Default 0.4 mm.
    pub step_mm: f64,
    /// β: the lines' angle to the x axis (parallel) or the spiral's start angle.
    /// Default 0°.
    pub angle_deg: f64,
    /// Σ_c, the covariance of the centre jitter c_k ~ N(c̄_k, Σ_c), symmetric and
    /// positive semi-definite. Draws are truncated at 4σ so a ring's reach is bounded.
    /// Default [[4e-4, 0], [0, 4e-4]] mm² (σ = 20 µm).
    pub jitter_cov_mm2: [[f64; 2]; 2],
    /// ε ∈ [0, 1], the share of rings whose temporal order is changed. Default 0.
    pub reorder: f64,
    /// How far, in rings along their line or spiral, a reordered ring moves (0 =
    /// automatic: far enough to pass every ring of the path that overlaps it, ⌈2R/δ⌉).
    pub reorder_reach_rings: u32,
    /// Parallel: the order of the lines. Default ascending.
    pub line_order: Option<LineOrder>,
    /// Parallel: one way or zigzag. Default oneway.
    pub direction: Option<LineDirection>,
    /// Parallel: mill the reference line (j = 0) against β. Default false.
    pub reverse: Option<bool>,
    /// Spiral: its origin u. Default [0, 0] mm.
    pub origin_mm: Option<[f64; 2]>,
    /// Spiral: ccw (o = 1) or cw (o = −1). Default ccw.
    pub orientation: Option<Orientation>,
    /// Spiral: outward from the origin or inward to it. Default outward.
    pub travel: Option<Travel>,
    /// Spiral: the outer radius where the path ends (outward) or starts (inward;
    /// required there). Default: none, an endless outward spiral.
    pub radius_mm: Option<f64>,
}

impl Default for PathConfig {
    fn default() -> Self {
        PathConfig {
            kind: PathKind::Parallel,
            overlap: 0.5,
            step_mm: 0.4,
            angle_deg: 0.0,
            jitter_cov_mm2: [[4e-4, 0.0], [0.0, 4e-4]],
            reorder: 0.0,
            reorder_reach_rings: 0,
            line_order: None,
            direction: None,
            reverse: None,
            origin_mm: None,
            orientation: None,
            travel: None,
            radius_mm: None,
        }
    }
}

/// `[adapt]` (§4.4): match the mean and standard deviation of the heights to a
/// measurement, given as numbers or as a height map file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AdaptConfig {
    /// Target mean height.
    pub mean_um: Option<f64>,
    /// Target standard deviation (> 0).
    pub std_um: Option<f64>,
    /// A measured height map (.npy, .tif, .png, …), relative to the configuration file;
    /// its mean and standard deviation after plane levelling are the targets.
    pub measurement: Option<String>,
}

/// A whole milling configuration (seed 000, Table 3).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MillingConfig {
    /// `[tool]`.
    pub tool: ToolConfig,
    /// `[shape]`.
    pub shape: ShapeConfig,
    /// `[tilt]`.
    pub tilt: TiltConfig,
    /// `[noise]`.
    pub noise: NoiseConfig,
    /// `[interaction]`.
    pub interaction: InteractionConfig,
    /// `[path]`.
    pub path: PathConfig,
    /// `[adapt]`, if the heights are to be matched to a measurement.
    pub adapt: Option<AdaptConfig>,
}

macro_rules! preset {
    ($name:literal) => {
        (
            $name,
            include_str!(concat!("../../../tiles/milling/", $name, ".toml")),
        )
    };
}
/// The presets of seed 000, Table 1: parallel and spiral paths, 4 and 8 mm heads,
/// a_e = 0.2, 0.5 and 0.8, as `(name, TOML)`. The files live in `tiles/milling/`.
pub const PRESETS: [(&str, &str); 12] = [
    preset!("parallel-d4-ae02"),
    preset!("parallel-d4-ae05"),
    preset!("parallel-d4-ae08"),
    preset!("parallel-d8-ae02"),
    preset!("parallel-d8-ae05"),
    preset!("parallel-d8-ae08"),
    preset!("spiral-d4-ae02"),
    preset!("spiral-d4-ae05"),
    preset!("spiral-d4-ae08"),
    preset!("spiral-d8-ae02"),
    preset!("spiral-d8-ae05"),
    preset!("spiral-d8-ae08"),
];

impl MillingConfig {
    /// Parses a configuration (`what` names it in errors) and validates it.
    pub fn from_toml(text: &str, what: &str) -> Result<MillingConfig> {
        let config: MillingConfig =
            toml::from_str(text).map_err(|e| crate::models::toml_error(text, what, e))?;
        config.validate()?;
        Ok(config)
    }

    /// Reads a configuration file, or a preset by name (`parallel-d4-ae05`, with or
    /// without `.toml`) when no such file exists. Returns the configuration and the
    /// folder that relative paths in it (`adapt.measurement`) are relative to.
    pub fn load(path: &Path) -> Result<(MillingConfig, Option<std::path::PathBuf>)> {
        crate::models::preset_or_file(
            path,
            &PRESETS,
            "config",
            "a milling TOML file",
            MillingConfig::from_toml,
        )
    }

    /// Checks every range of seed 000, Table 3; the error names the key.
    pub fn validate(&self) -> Result<()> {
        let d = self.tool.diameter_mm;
        positive("tool.diameter_mm", d, "a positive head diameter in mm")?;
        if d > 1e4 {
            return Err(Error::param("tool.diameter_mm", d, "at most 10000 mm"));
        }
        let r = d / 2.0;
        let s = &self.shape;
        if !(s.width_mean_mm > 0.0 && s.width_mean_mm < r) {
            return Err(Error::param(
                "shape.width_mean_mm",
                s.width_mean_mm,
                format!("μ_w⁻ in (0, d/2) = (0, {r}) mm"),
            ));
        }
        let inner_max = r - s.width_mean_mm;
        if !(s.inner_width_mean_mm >= 0.0 && s.inner_width_mean_mm <= inner_max) {
            return Err(Error::param(
                "shape.inner_width_mean_mm",
                s.inner_width_mean_mm,
                format!("μ_w⁺ⁱ in [0, d/2 − μ_w⁻] = [0, {inner_max}] mm"),
            ));
        }
        non_negative(
            "shape.outer_width_mean_mm",
            s.outer_width_mean_mm,
            "μ_w⁺ᵒ ≥ 0 mm",
        )?;
        if s.outer_width_mean_mm > d {
            return Err(Error::param(
                "shape.outer_width_mean_mm",
                s.outer_width_mean_mm,
                format!("μ_w⁺ᵒ at most d = {d} mm"),
            ));
        }
        for (key, v) in [
            ("shape.width_std_mm", s.width_std_mm),
            ("shape.inner_width_std_mm", s.inner_width_std_mm),
            ("shape.outer_width_std_mm", s.outer_width_std_mm),
        ] {
            non_negative(key, v, "a standard deviation ≥ 0 mm")?;
            if v > r / 4.0 {
                return Err(Error::param(
                    key,
                    v,
                    format!("a standard deviation at most d/8 = {} mm", r / 4.0),
                ));
            }
        }
        let t = &self.tilt;
        if !(t.tilt_deg.is_finite() && t.tilt_deg.abs() < 90.0) {
            return Err(Error::param(
                "tilt.tilt_deg",
                t.tilt_deg,
                "an angle in (−90, 90) degrees",
            ));
        }
        for (key, v) in [
            ("tilt.depth_um", Some(t.depth_um)),
            ("tilt.low_mean_um", t.low_mean_um),
            ("tilt.high_mean_um", t.high_mean_um),
            ("tilt.inner_low_mean_um", Some(t.inner_low_mean_um)),
            ("tilt.inner_high_mean_um", Some(t.inner_high_mean_um)),
            ("tilt.outer_low_mean_um", Some(t.outer_low_mean_um)),
            ("tilt.outer_high_mean_um", Some(t.outer_high_mean_um)),
        ] {
            if let Some(v) = v {
                finite(key, v, "a finite height in µm")?;
            }
        }
        for (key, v) in [
            ("tilt.low_std_um", t.low_std_um),
            ("tilt.high_std_um", t.high_std_um),
            ("tilt.inner_low_std_um", t.inner_low_std_um),
            ("tilt.inner_high_std_um", t.inner_high_std_um),
            ("tilt.outer_low_std_um", t.outer_low_std_um),
            ("tilt.outer_high_std_um", t.outer_high_std_um),
        ] {
            non_negative(key, v, "a standard deviation ≥ 0 µm")?;
        }
        let n = &self.noise;
        non_negative("noise.amplitude_um", n.amplitude_um, "an amplitude ≥ 0 µm")?;
        if !(n.count_mean >= 1.0 && n.count_mean <= 1000.0) {
            return Err(Error::param(
                "noise.count_mean",
                n.count_mean,
                "λ, a mean number of sines from 1 to 1000",
            ));
        }
        if !(n.frequency_mean >= 0.0 && n.frequency_mean <= 500.0) {
            return Err(Error::param(
                "noise.frequency_mean",
                n.frequency_mean,
                "τ, a mean frequency from 0 to 500 per turn",
            ));
        }
        let i = &self.interaction;
        unit_range(
            "interaction.front_weight_min",
            i.front_weight_min,
            0.0,
            "[0, 1]",
        )?;
        unit_range(
            "interaction.front_weight_max",
            i.front_weight_max,
            i.front_weight_min,
            "[front_weight_min, 1]",
        )?;
        unit_range(
            "interaction.rear_weight_min",
            i.rear_weight_min,
            0.0,
            "[0, 1]",
        )?;
        unit_range(
            "interaction.rear_weight_max",
            i.rear_weight_max,
            i.rear_weight_min,
            "[rear_weight_min, 1]",
        )?;
        let p = &self.path;
        if !(p.overlap > 0.0 && p.overlap < 1.0) {
            return Err(Error::param(
                "path.overlap",
                p.overlap,
                "α in (0, 1) (the line spacing is ρ = (1 − α)·d; a_e = 1 − α)",
            ));
        }
        positive("path.step_mm", p.step_mm, "δ > 0 mm between ring centres")?;
        // Rings per unit area are 1/(ρδ); bound the rings that can cover one point.
        let rho = (1.0 - p.overlap) * d;
        let reach = r + s.outer_width_mean_mm + 4.0 * s.outer_width_std_mm;
        let candidates = (2.0 * reach / p.step_mm + 2.0) * (2.0 * reach / rho + 2.0);
        if candidates > 20_000.0 {
            return Err(Error::param(
                "path.step_mm",
                p.step_mm,
                format!(
                    "δ of at least {:.3e} mm: with ρ = {rho} mm, smaller steps put more than 20000 rings within reach of a point",
                    p.step_mm * candidates / 20_000.0
                ),
            ));
        }
        if !(p.angle_deg.is_finite() && p.angle_deg.abs() <= 360.0) {
            return Err(Error::param(
                "path.angle_deg",
                p.angle_deg,
                "an angle β in [−360, 360] degrees",
            ));
        }
        let [[a, b], [b2, c]] = p.jitter_cov_mm2;
        if ![a, b, b2, c].iter().all(|v| v.is_finite())
            || b != b2
            || a < 0.0
            || c < 0.0
            || a * c - b * b < -1e-18
            || a.max(c).sqrt() > r
        {
            return Err(Error::param(
                "path.jitter_cov_mm2",
                format!("{:?}", p.jitter_cov_mm2),
                format!(
                    "Σ_c, a symmetric positive semi-definite 2×2 matrix in mm² with σ ≤ d/2 = {r} mm"
                ),
            ));
        }
        if !(0.0..=1.0).contains(&p.reorder) {
            return Err(Error::param(
                "path.reorder",
                p.reorder,
                "ε in [0, 1], the share of rings whose order changes",
            ));
        }
        if p.reorder_reach_rings > 1 << 20 {
            return Err(Error::param(
                "path.reorder_reach_rings",
                p.reorder_reach_rings,
                "0 (automatic) to 1048576 rings",
            ));
        }
        let only = |key: &str, set: bool, kind: &str| -> Result<()> {
            if set {
                Err(Error::param(
                    format!("path.{key}"),
                    "(set)",
                    format!("not set: it applies to {kind} paths only"),
                ))
            } else {
                Ok(())
            }
        };
        match p.kind {
            PathKind::Parallel => {
                only("origin_mm", p.origin_mm.is_some(), "spiral")?;
                only("orientation", p.orientation.is_some(), "spiral")?;
                only("travel", p.travel.is_some(), "spiral")?;
                only("radius_mm", p.radius_mm.is_some(), "spiral")?;
            }
            PathKind::Spiral => {
                only("line_order", p.line_order.is_some(), "parallel")?;
                only("direction", p.direction.is_some(), "parallel")?;
                only("reverse", p.reverse.is_some(), "parallel")?;
                if let Some(o) = p.origin_mm
                    && !o.iter().all(|v| v.is_finite() && v.abs() < 1e12)
                {
                    return Err(Error::param(
                        "path.origin_mm",
                        format!("{o:?}"),
                        "a finite point [x, y] in mm",
                    ));
                }
                if let Some(rad) = p.radius_mm {
                    positive("path.radius_mm", rad, "a positive spiral radius in mm")?;
                    if rad / rho > 1e7 {
                        return Err(Error::param(
                            "path.radius_mm",
                            rad,
                            format!("at most 10⁷ turns of ρ = {rho} mm"),
                        ));
                    }
                }
                if p.travel == Some(Travel::Inward) && p.radius_mm.is_none() {
                    return Err(Error::param(
                        "path.radius_mm",
                        "(not set)",
                        "a start radius in mm: an inward spiral starts at a finite radius",
                    ));
                }
            }
        }
        if let Some(adapt) = &self.adapt {
            if let Some(m) = adapt.mean_um {
                finite("adapt.mean_um", m, "a finite mean height in µm")?;
            }
            if let Some(s) = adapt.std_um {
                positive("adapt.std_um", s, "a positive standard deviation in µm")?;
            }
            if adapt.measurement.is_some() && (adapt.mean_um.is_some() || adapt.std_um.is_some()) {
                return Err(Error::param(
                    "adapt.measurement",
                    "(set)",
                    "either a measurement file or mean_um/std_um, not both",
                ));
            }
            if adapt.measurement.is_none() && adapt.mean_um.is_none() && adapt.std_um.is_none() {
                return Err(Error::param(
                    "adapt",
                    "(empty)",
                    "measurement, or mean_um and/or std_um",
                ));
            }
        }
        Ok(())
    }

    /// The TOML text of this configuration (every key, defaults included).
    pub fn to_toml(&self) -> Result<String> {
        toml::to_string(self).map_err(|e| {
            let e = e.to_string();
            Error::decode(
                "milling configuration",
                format!(
                    "cannot be written as TOML ({})",
                    e.lines().next().unwrap_or("")
                ),
            )
        })
    }
}

fn finite(key: &str, v: f64, expected: &str) -> Result<()> {
    crate::error::finite_param(key, v, expected).map(|_| ())
}

fn positive(key: &str, v: f64, expected: &str) -> Result<()> {
    crate::error::positive_param(key, v, expected).map(|_| ())
}

fn non_negative(key: &str, v: f64, expected: &str) -> Result<()> {
    crate::error::non_negative_param(key, v, expected).map(|_| ())
}

fn unit_range(key: &str, v: f64, lo: f64, range: &str) -> Result<()> {
    if v >= lo && v <= 1.0 {
        Ok(())
    } else {
        Err(Error::param(key, v, format!("a weight in {range}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_parses_and_matches_its_name() {
        for (name, text) in PRESETS {
            let c = MillingConfig::from_toml(text, name).unwrap();
            let d: f64 = if name.contains("-d4-") { 4.0 } else { 8.0 };
            let ae: f64 = name[name.len() - 2..].parse::<f64>().unwrap() / 10.0;
            assert_eq!(c.tool.diameter_mm, d, "{name}");
            assert!((1.0 - c.path.overlap - ae).abs() < 1e-12, "{name}");
            let kind = if name.starts_with("spiral") {
                PathKind::Spiral
            } else {
                PathKind::Parallel
            };
            assert_eq!(c.path.kind, kind, "{name}");
        }
    }

    #[test]
    fn an_empty_file_is_the_documented_default() {
        let c = MillingConfig::from_toml("", "empty").unwrap();
        assert_eq!(c, MillingConfig::default());
        // And a written configuration reads back as itself.
        let again = MillingConfig::from_toml(&c.to_toml().unwrap(), "again").unwrap();
        assert_eq!(again, c);
    }
}
