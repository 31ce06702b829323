//! Defect layers (issue 35): the flaws visual inspection looks for, added to any
//! surface's heights in physical units, with a mask id per kind.
//!
//! - **scratch**: a groove along a straight or gently curved path (a circular arc of
//!   turning angle up to `bend`), V or U profile of width w and depth D, optional pile-up
//!   ridges of height `pile_up`·D on its flanks (from w/2 to w from the centre line), its
//!   depth ramped in over one width at each end;
//! - **dent**: a spherical-cap impression of diameter d and depth D (sphere radius
//!   R = (d²/4 + D²)/(2D)) with a raised rim of height `rim`·D out to 1.3·d/2;
//! - **pits**: a cluster of a few small spherical-cap craters within `spread` of its
//!   centre.
//!
//! **Placement** is seed 004's rule for every random choice: the plane is cut into cells
//! of `cell_um`; cell (i, j) of entry e holds one defect with probability `probability`,
//! and its position, orientation and parameters (uniform in their ranges) come from
//! hash(seed, i, j, stream e). A defect reaches at most one cell from its own, so a
//! sample depends on the 3×3 cells around it: O(1) per sample, and any region filled in
//! any split gives the same bits.
//!
//! **Units**: lengths in µm, converted with the source's spacing (µm per pixel); depths
//! in µm, added to heights in µm, or converted to pixels for surfaces whose heights are
//! in pixels (seed 001 models).
//!
//! **Mask**: a sample carries a defect's mask id where that defect changed it by more
//! than [`MASK_FRACTION`] of its depth (the deepest change wins where defects overlap);
//! elsewhere the inner surface's id (0 clean, seed 004's layer ids).

use std::ops::Range;
use std::path::Path;

use serde::Deserialize;

use crate::error::{Error, Result, finite_param, positive_param};
use crate::hash::hash_cell;
use crate::stream::{Region, Surface, default_threads, for_bands};

/// A sample is marked where a defect changed it by more than this fraction of the
/// defect's depth.
pub const MASK_FRACTION: f64 = 0.05;

/// Deepest defect accepted, in µm (a deep gouge in a machined part).
pub const MAX_DEPTH_UM: f64 = 1000.0;

/// Most pits in one cluster.
pub const MAX_PITS: u32 = 16;

/// Default mask ids (seed 004's layers use 1 to 15).
pub const SCRATCH_ID: u8 = 16;
/// See [`SCRATCH_ID`].
pub const DENT_ID: u8 = 17;
/// See [`SCRATCH_ID`].
pub const PITS_ID: u8 = 18;

/// Rim of a dent: from the cap's edge out to this factor of its radius.
const RIM_REACH: f64 = 1.3;

/// A range [lo, hi] a parameter is drawn from (lo = hi: fixed).
pub type Span = [f64; 2];

/// Cross profile of a scratch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// Depth falls linearly to the edges.
    V,
    /// Parabolic: depth·(1 − (2d/w)²).
    U,
}

/// One `[[defect]]` entry: its kind (`kind = "scratch" | "dent" | "pits"`), its
/// placement cells and probability, its mask id and its parameter ranges (µm unless
/// noted). Unknown keys are refused.
#[derive(Clone, Debug, PartialEq, Deserialize, serde::Serialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum DefectKind {
    /// A groove along an arc.
    Scratch {
        /// Side of the placement cells, µm; each holds at most one defect of this
        /// entry, which must fit within one cell of its centre.
        cell_um: f64,
        /// Probability that a cell holds one (0 to 1).
        probability: f64,
        /// The mask id of its samples (default: scratch 16, dent 17, pits 18).
        #[serde(default)]
        mask_id: Option<u8>,
        /// Length of the path.
        length_um: Span,
        /// Width of the groove at the surface.
        width_um: Span,
        /// Depth at its centre line.
        depth_um: Span,
        /// V or U.
        profile: Profile,
        /// Height of the pile-up ridges, as a fraction of the depth (0: none).
        #[serde(default)]
        pile_up: Span,
        /// Largest turning angle of the path over its length, radians (0: straight).
        #[serde(default)]
        bend: f64,
    },
    /// A spherical-cap impression with a raised rim.
    Dent {
        /// Side of the placement cells, µm; each holds at most one defect of this
        /// entry, which must fit within one cell of its centre.
        cell_um: f64,
        /// Probability that a cell holds one (0 to 1).
        probability: f64,
        /// The mask id of its samples (default: scratch 16, dent 17, pits 18).
        #[serde(default)]
        mask_id: Option<u8>,
        /// Diameter of the impression at the surface.
        diameter_um: Span,
        /// Depth at its centre.
        depth_um: Span,
        /// Rim height as a fraction of the depth.
        #[serde(default)]
        rim: Span,
    },
    /// A cluster of small craters.
    Pits {
        /// Side of the placement cells, µm; each holds at most one defect of this
        /// entry, which must fit within one cell of its centre.
        cell_um: f64,
        /// Probability that a cell holds one (0 to 1).
        probability: f64,
        /// The mask id of its samples (default: scratch 16, dent 17, pits 18).
        #[serde(default)]
        mask_id: Option<u8>,
        /// Number of craters (whole numbers, 1 to 16).
        count: [u32; 2],
        /// Diameter of each crater.
        diameter_um: Span,
        /// Depth of each crater.
        depth_um: Span,
        /// Radius of the disc their centres lie in.
        spread_um: f64,
    },
}

/// A `[[defect]]` entry (see [`DefectKind`]).
pub type DefectSpec = DefectKind;

impl DefectKind {
    /// Side of the placement cells, µm.
    pub fn cell_um(&self) -> f64 {
        match self {
            DefectKind::Scratch { cell_um, .. }
            | DefectKind::Dent { cell_um, .. }
            | DefectKind::Pits { cell_um, .. } => *cell_um,
        }
    }

    /// Probability that a cell holds one.
    pub fn probability(&self) -> f64 {
        match self {
            DefectKind::Scratch { probability, .. }
            | DefectKind::Dent { probability, .. }
            | DefectKind::Pits { probability, .. } => *probability,
        }
    }

    /// Its mask id.
    pub fn mask_id(&self) -> u8 {
        match self {
            DefectKind::Scratch { mask_id, .. }
            | DefectKind::Dent { mask_id, .. }
            | DefectKind::Pits { mask_id, .. } => mask_id.unwrap_or(self.default_id()),
        }
    }

    /// Its kind's name: scratch, dent or pits.
    pub fn name(&self) -> &'static str {
        match self {
            DefectKind::Scratch { .. } => "scratch",
            DefectKind::Dent { .. } => "dent",
            DefectKind::Pits { .. } => "pits",
        }
    }

    fn default_id(&self) -> u8 {
        match self {
            DefectKind::Scratch { .. } => SCRATCH_ID,
            DefectKind::Dent { .. } => DENT_ID,
            DefectKind::Pits { .. } => PITS_ID,
        }
    }

    /// Farthest a defect of the largest drawn parameters reaches from its centre, µm.
    fn reach_um(&self) -> f64 {
        match self {
            // Half the length, plus the pile-up's width beyond the centre line (arcs
            // are no longer than their chord's half length from the centre).
            DefectKind::Scratch {
                length_um,
                width_um,
                ..
            } => length_um[1] / 2.0 + width_um[1],
            DefectKind::Dent { diameter_um, .. } => RIM_REACH * diameter_um[1] / 2.0,
            DefectKind::Pits {
                diameter_um,
                spread_um,
                ..
            } => spread_um + diameter_um[1] / 2.0,
        }
    }
}

/// The `[[defect]]` entries of a configuration file.
#[derive(Clone, Debug, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct DefectConfig {
    /// The entries, each placed independently.
    #[serde(default)]
    pub defect: Vec<DefectSpec>,
}

/// Checks a range: both ends finite in `lo..=hi` bounds, lo ≤ hi.
fn span(key: &str, s: Span, lo: f64, hi: f64, what: &str) -> Result<()> {
    let ok = s.iter().all(|v| v.is_finite() && (lo..=hi).contains(v)) && s[0] <= s[1];
    if ok {
        Ok(())
    } else {
        Err(Error::param(
            key,
            format!(
                "[{}, {}]",
                crate::error::short(s[0]),
                crate::error::short(s[1])
            ),
            format!("[low, high] with low ≤ high, {what}"),
        ))
    }
}

impl DefectConfig {
    /// Parses and checks a configuration (`what` names it in errors).
    pub fn from_toml(text: &str, what: &str) -> Result<DefectConfig> {
        let config: DefectConfig =
            toml::from_str(text).map_err(|e| Error::decode(what, one_line(&e.to_string())))?;
        config.validate()?;
        Ok(config)
    }

    /// Reads a `.toml`, or a preset name (`tiles/defects/`: scratches, dents, pits).
    /// A bare name that is neither a file nor a preset is refused with the presets'
    /// names.
    pub fn load(path: &Path) -> Result<DefectConfig> {
        crate::models::preset_or_file(
            path,
            &PRESET_TEXTS,
            "defects",
            "a defects .toml file",
            DefectConfig::from_toml,
        )
        .map(|(config, _)| config)
    }

    /// Checks every entry key by key.
    pub fn validate(&self) -> Result<()> {
        if self.defect.is_empty() {
            return Err(Error::param(
                "defect",
                "no entries",
                "at least one [[defect]] entry",
            ));
        }
        for (n, d) in self.defect.iter().enumerate() {
            let key = |k: &str| format!("defect {} ({}): {k}", n + 1, d.name());
            positive_param(&key("cell_um"), d.cell_um(), "a cell side in µm > 0")?;
            if !(0.0..=1.0).contains(&d.probability()) {
                return Err(Error::param(
                    key("probability"),
                    crate::error::short(d.probability()),
                    "a probability from 0 to 1",
                ));
            }
            let lengths =
                |k: &str, s: Span| span(&key(k), s, 1e-6, 1e6, "in µm, above 0 and at most 1e6");
            let depths = |k: &str, s: Span| {
                span(
                    &key(k),
                    s,
                    1e-6,
                    MAX_DEPTH_UM,
                    &format!("in µm, above 0 and at most {MAX_DEPTH_UM}"),
                )
            };
            let fractions =
                |k: &str, s: Span| span(&key(k), s, 0.0, 1.0, "fractions of the depth from 0 to 1");
            // A cap (dent, pit) is at most half a sphere: its depth at most its radius.
            let caps = |depth_um: Span, diameter_um: Span| {
                depths("depth_um", depth_um)?;
                lengths("diameter_um", diameter_um)?;
                if depth_um[1] > diameter_um[0] / 2.0 {
                    return Err(Error::param(
                        key("depth_um"),
                        crate::error::short(depth_um[1]),
                        format!(
                            "at most the smallest radius ({} µm): a cap is at most half a sphere",
                            crate::error::short(diameter_um[0] / 2.0)
                        ),
                    ));
                }
                Ok(())
            };
            match d {
                DefectKind::Scratch {
                    length_um,
                    width_um,
                    depth_um,
                    pile_up,
                    bend,
                    ..
                } => {
                    lengths("length_um", *length_um)?;
                    lengths("width_um", *width_um)?;
                    depths("depth_um", *depth_um)?;
                    fractions("pile_up", *pile_up)?;
                    if !(0.0..=std::f64::consts::FRAC_PI_2).contains(bend) {
                        return Err(Error::param(
                            key("bend"),
                            crate::error::short(*bend),
                            "a turning angle from 0 to π/2 radians (a gently curved path)",
                        ));
                    }
                }
                DefectKind::Dent {
                    diameter_um,
                    depth_um,
                    rim,
                    ..
                } => {
                    caps(*depth_um, *diameter_um)?;
                    fractions("rim", *rim)?;
                }
                DefectKind::Pits {
                    count,
                    diameter_um,
                    depth_um,
                    spread_um,
                    ..
                } => {
                    if !(count[0] >= 1 && count[0] <= count[1] && count[1] <= MAX_PITS) {
                        return Err(Error::param(
                            key("count"),
                            format!("[{}, {}]", count[0], count[1]),
                            format!("[low, high] with 1 ≤ low ≤ high ≤ {MAX_PITS}"),
                        ));
                    }
                    caps(*depth_um, *diameter_um)?;
                    finite_param(&key("spread_um"), *spread_um, "a radius in µm ≥ 0")?;
                    if *spread_um < 0.0 {
                        return Err(Error::param(
                            key("spread_um"),
                            crate::error::short(*spread_um),
                            "a radius in µm ≥ 0",
                        ));
                    }
                }
            }
            let reach = d.reach_um();
            if reach > d.cell_um() {
                return Err(Error::param(
                    key("cell_um"),
                    crate::error::short(d.cell_um()),
                    format!(
                        "at least the defect's reach from its centre ({} µm): a defect may cross only into the cells next to its own",
                        crate::error::short(reach)
                    ),
                ));
            }
            if d.mask_id() == 0 {
                return Err(Error::param(
                    key("mask_id"),
                    0,
                    "1 to 255 (0 marks clean samples)",
                ));
            }
        }
        Ok(())
    }
}

/// The first line of a TOML error (they span several).
fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The shipped presets, by name.
const PRESET_TEXTS: [(&str, &str); 3] = [
    (
        "scratches",
        include_str!("../../tiles/defects/scratches.toml"),
    ),
    ("dents", include_str!("../../tiles/defects/dents.toml")),
    ("pits", include_str!("../../tiles/defects/pits.toml")),
];

/// Names of the presets.
pub const PRESETS: [&str; 3] = ["scratches", "dents", "pits"];

/// One placed defect, in pixels and height units.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// Centre line through (cx, cy) with tangent angle θ there, curvature κ (1/px,
    /// signed), length, half width a, depth, pile-up height, profile.
    Scratch {
        c: [f64; 2],
        theta: f64,
        kappa: f64,
        length: f64,
        half_width: f64,
        depth: f64,
        pile_up: f64,
        profile: Profile,
    },
    /// Cap of radius r0 at c, depth, sphere radius, rim height.
    Dent {
        c: [f64; 2],
        r0: f64,
        depth: f64,
        sphere: f64,
        rim: f64,
    },
    /// Craters: (centre, radius, depth, sphere radius).
    Pits {
        pits: Vec<([f64; 2], f64, f64, f64)>,
    },
}

/// A placed defect: its shape (in pixels, depths too), the box it changes, its mask id.
#[derive(Clone, Debug, PartialEq)]
pub struct Placed {
    /// The shape, lengths and depths in pixels.
    pub shape: Shape,
    /// x0, y0, x1, y1 (pixels): nothing changes outside.
    pub bbox: [f64; 4],
    /// Mask id.
    pub id: u8,
    /// The configuration entry it comes from (0-based).
    pub entry: usize,
    /// A scratch's (cos θ, sin θ), computed once ((1, 0) for other shapes).
    pub axis: [f64; 2],
    /// Depth in pixels, the scale of [`MASK_FRACTION`].
    pub depth_px: f64,
    /// Height units per pixel of depth.
    pub z_scale: f64,
}

/// Uniform in [0, 1) from a hash word.
fn unit(h: u32) -> f64 {
    h as f64 / 4294967296.0
}

fn draw(s: Span, u: f64) -> f64 {
    s[0] + (s[1] - s[0]) * u
}

/// A spherical cap of radius r0, depth d, sphere radius R, at distance r: ≤ 0 inside.
fn cap(r: f64, r0: f64, depth: f64, sphere: f64) -> f64 {
    if r >= r0 {
        0.0
    } else {
        -depth + sphere - (sphere * sphere - r * r).max(0.0).sqrt()
    }
}

fn sphere_radius(r0: f64, depth: f64) -> f64 {
    (r0 * r0 + depth * depth) / (2.0 * depth)
}

impl Placed {
    /// The height change at (x, y), in height units.
    pub fn displacement(&self, x: f64, y: f64) -> f64 {
        self.displacement_px(x, y) * self.z_scale
    }

    /// The x intervals (pixels, at most two) of row y outside which this defect changes
    /// nothing: within its box, narrowed to the groove and ridges of a scratch (|d| < 2a
    /// from its centre line, widened by a pixel for rounding) and to the rim's circle of
    /// a dent. Used to visit only the samples a defect may change.
    fn row_spans(&self, y: f64) -> [Option<(f64, f64)>; 2] {
        let b = &self.bbox;
        if y < b[1] || y > b[3] {
            return [None, None];
        }
        let full = Some((b[0], b[2]));
        let clip = |lo: f64, hi: f64| {
            let (lo, hi) = (lo.max(b[0]), hi.min(b[2]));
            (lo <= hi).then_some((lo, hi))
        };
        const MARGIN: f64 = 1.0;
        match &self.shape {
            Shape::Scratch {
                c,
                kappa,
                half_width: a,
                ..
            } => {
                let [ct, st] = self.axis;
                let n = [-st, ct];
                let reach = 2.0 * a + MARGIN;
                if kappa.abs() < 1e-12 {
                    // d = (x − cx)·n0 + (y − cy)·n1, linear in x.
                    let dy = (y - c[1]) * n[1];
                    if n[0].abs() < 1e-9 {
                        return if dy.abs() < reach {
                            [full, None]
                        } else {
                            [None, None]
                        };
                    }
                    let (p, q) = ((-reach - dy) / n[0] + c[0], (reach - dy) / n[0] + c[0]);
                    return [clip(p.min(q), p.max(q)), None];
                }
                let r = 1.0 / kappa;
                if r.abs() > 1e5 {
                    // A nearly straight arc: the circle's arithmetic would lose its
                    // precision; the box is exact enough.
                    return [full, None];
                }
                // The annulus |r| − reach ≤ |p − centre| ≤ |r| + reach.
                let centre = [c[0] + r * n[0], c[1] + r * n[1]];
                let dy = y - centre[1];
                let outer = r.abs() + reach;
                if dy.abs() > outer {
                    return [None, None];
                }
                let wo = (outer * outer - dy * dy).sqrt();
                let inner = r.abs() - reach;
                if inner > 0.0 && dy.abs() < inner {
                    let wi = (inner * inner - dy * dy).sqrt();
                    [
                        clip(centre[0] - wo, centre[0] - wi),
                        clip(centre[0] + wi, centre[0] + wo),
                    ]
                } else {
                    [clip(centre[0] - wo, centre[0] + wo), None]
                }
            }
            Shape::Dent { c, r0, .. } => {
                let reach = RIM_REACH * r0 + MARGIN;
                let dy = y - c[1];
                if dy.abs() > reach {
                    return [None, None];
                }
                let w = (reach * reach - dy * dy).sqrt();
                [clip(c[0] - w, c[0] + w), None]
            }
            Shape::Pits { .. } => [full, None],
        }
    }

    /// The height change at (x, y), in pixels.
    fn displacement_px(&self, x: f64, y: f64) -> f64 {
        let b = &self.bbox;
        if x < b[0] || x > b[2] || y < b[1] || y > b[3] {
            return 0.0;
        }
        match &self.shape {
            Shape::Scratch {
                c,
                theta,
                kappa,
                length,
                half_width: a,
                depth,
                pile_up,
                profile,
            } => {
                let [ct, st] = self.axis;
                debug_assert_eq!([ct, st], [theta.cos(), theta.sin()]);
                let (t, n) = ([ct, st], [-st, ct]);
                let (dx, dy) = (x - c[0], y - c[1]);
                // Signed distance d from the centre line first: most of the box is
                // beyond the groove and its ridges (q ≥ 2), where nothing changes and the
                // along-path coordinate s (an atan2 on an arc) is not needed.
                let (s, q) = if kappa.abs() < 1e-12 {
                    let q = (dx * n[0] + dy * n[1]).abs() / a;
                    if q >= 2.0 {
                        return 0.0;
                    }
                    (dx * t[0] + dy * t[1], q)
                } else {
                    let r = 1.0 / kappa; // signed radius: the centre is at c + r·n
                    let (vx, vy) = (dx - r * n[0], dy - r * n[1]);
                    let d = (r.abs() - (vx * vx + vy * vy).sqrt()) * r.signum();
                    let q = d.abs() / a;
                    if q >= 2.0 {
                        return 0.0;
                    }
                    // Angle from the vector centre → c (−r·n) to centre → point.
                    let (ux, uy) = (-r * n[0], -r * n[1]);
                    let ang = (ux * vy - uy * vx).atan2(ux * vx + uy * vy);
                    (ang * r, q)
                };
                let half = length / 2.0;
                if s.abs() > half {
                    return 0.0;
                }
                // Depth ramps in over one width at each end (smoothstep).
                let e = ((half - s.abs()) / (2.0 * a)).clamp(0.0, 1.0);
                let e = e * e * (3.0 - 2.0 * e);
                let z = if q < 1.0 {
                    -depth
                        * match profile {
                            Profile::V => 1.0 - q,
                            Profile::U => 1.0 - q * q,
                        }
                } else {
                    let w = (std::f64::consts::PI * (q - 1.0)).sin();
                    pile_up * w * w
                };
                z * e
            }
            Shape::Dent {
                c,
                r0,
                depth,
                sphere,
                rim,
            } => {
                let r = ((x - c[0]).powi(2) + (y - c[1]).powi(2)).sqrt();
                if r < *r0 {
                    cap(r, *r0, *depth, *sphere)
                } else {
                    let u = (r - r0) / ((RIM_REACH - 1.0) * r0);
                    if u < 1.0 {
                        let w = (std::f64::consts::PI * u).sin();
                        rim * w * w
                    } else {
                        0.0
                    }
                }
            }
            Shape::Pits { pits } => pits
                .iter()
                .map(|(p, r0, depth, sphere)| {
                    let r = ((x - p[0]).powi(2) + (y - p[1]).powi(2)).sqrt();
                    cap(r, *r0, *depth, *sphere)
                })
                .fold(0.0, f64::min),
        }
    }
}

/// A defect configuration placed over surfaces of a given spacing and height unit.
#[derive(Clone, Debug)]
pub struct Defects {
    config: DefectConfig,
    seed: u32,
    /// µm per pixel.
    spacing_um: f64,
    /// Height units per µm of depth (1 for heights in µm, 1/spacing for pixels).
    z_per_um: f64,
}

/// Hash streams: one per entry, above seed 004's.
const STREAM_BASE: u32 = 0x4446_0000; // "DF"

impl Defects {
    /// `config` over a surface of `spacing_um` µm per pixel whose heights are in
    /// `height_unit` ("um", or "" for pixels), placed with `seed`.
    pub fn new(
        config: &DefectConfig,
        spacing_um: f64,
        height_unit: &str,
        seed: u32,
    ) -> Result<Defects> {
        config.validate()?;
        positive_param(
            "spacing_um",
            spacing_um,
            "the surface's spacing in µm per pixel > 0",
        )?;
        let z_per_um = match height_unit {
            "um" => 1.0,
            "" => 1.0 / spacing_um,
            other => {
                return Err(Error::param(
                    "height unit",
                    other,
                    "um or none (pixels): defect depths are in µm",
                ));
            }
        };
        // Cells under a pixel would place sub-pixel defects, millions to a row, and a
        // fill would list them all.
        for (n, d) in config.defect.iter().enumerate() {
            if d.cell_um() < spacing_um {
                return Err(Error::param(
                    format!("defect {} ({}): cell_um", n + 1, d.name()),
                    crate::error::short(d.cell_um()),
                    format!(
                        "at least the surface's pixel spacing ({} µm): a cell under a pixel places sub-pixel defects",
                        crate::error::short(spacing_um)
                    ),
                ));
            }
        }
        Ok(Defects {
            config: config.clone(),
            seed,
            spacing_um,
            z_per_um,
        })
    }

    /// The defect of entry `e` in cell (i, j), if it holds one.
    pub fn in_cell(&self, e: usize, i: i64, j: i64) -> Option<Placed> {
        let d = &self.config.defect[e];
        let stream = STREAM_BASE + e as u32;
        let h = hash_cell(self.seed, i, j, stream);
        if unit(h[0]) >= d.probability() {
            return None;
        }
        let px = 1.0 / self.spacing_um;
        let cell = d.cell_um() * px;
        let c = [
            (i as f64 + unit(h[1])) * cell,
            (j as f64 + unit(h[2])) * cell,
        ];
        // Further draws from a second hash of the same cell.
        let g = hash_cell(self.seed ^ 0x9E37_79B9, i, j, stream);
        let (shape, reach, depth_px) = match d {
            DefectKind::Scratch {
                length_um,
                width_um,
                depth_um,
                profile,
                pile_up,
                bend,
                ..
            } => {
                let length = draw(*length_um, unit(g[0])) * px;
                let a = draw(*width_um, unit(g[1])) * px / 2.0;
                let depth = draw(*depth_um, unit(g[2])) * px;
                let turn = bend * (2.0 * unit(g[3]) - 1.0);
                let shape = Shape::Scratch {
                    c,
                    theta: std::f64::consts::PI * unit(h[3]),
                    kappa: turn / length,
                    length,
                    half_width: a,
                    depth,
                    pile_up: draw(*pile_up, unit(h[3].rotate_left(16))) * depth,
                    profile: *profile,
                };
                (shape, length / 2.0 + 2.0 * a, depth)
            }
            DefectKind::Dent {
                diameter_um,
                depth_um,
                rim,
                ..
            } => {
                let r0 = draw(*diameter_um, unit(g[0])) * px / 2.0;
                let depth = draw(*depth_um, unit(g[1])) * px;
                let shape = Shape::Dent {
                    c,
                    r0,
                    depth,
                    sphere: sphere_radius(r0, depth),
                    rim: draw(*rim, unit(g[2])) * depth,
                };
                (shape, RIM_REACH * r0, depth)
            }
            DefectKind::Pits {
                count,
                diameter_um,
                depth_um,
                spread_um,
                ..
            } => {
                let extra = count[1] - count[0];
                let n = count[0] + ((unit(g[0]) * (extra + 1) as f64) as u32).min(extra);
                let mut pits = Vec::with_capacity(n as usize);
                let (mut deepest, mut widest) = (0.0f64, 0.0f64);
                for k in 0..n {
                    let p = hash_cell(self.seed, i, j, stream ^ ((0x100 + k) << 8));
                    let rad = spread_um * px * unit(p[0]).sqrt();
                    let ang = std::f64::consts::TAU * unit(p[1]);
                    let r0 = draw(*diameter_um, unit(p[2])) * px / 2.0;
                    let depth = draw(*depth_um, unit(p[3])) * px;
                    pits.push((
                        [c[0] + rad * ang.cos(), c[1] + rad * ang.sin()],
                        r0,
                        depth,
                        sphere_radius(r0, depth),
                    ));
                    deepest = deepest.max(depth);
                    widest = widest.max(r0);
                }
                (Shape::Pits { pits }, spread_um * px + widest, deepest)
            }
        };
        let r = reach + 1.0;
        let axis = match &shape {
            Shape::Scratch { theta, .. } => [theta.cos(), theta.sin()],
            _ => [1.0, 0.0],
        };
        Some(Placed {
            shape,
            bbox: [c[0] - r, c[1] - r, c[0] + r, c[1] + r],
            id: d.mask_id(),
            entry: e,
            axis,
            depth_px,
            z_scale: self.z_per_um * self.spacing_um,
        })
    }

    /// Every defect whose box meets [x0, x1] × [y0, y1] (pixels), in a fixed order
    /// (entry, then cell row, then cell column).
    pub fn placed_in(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<Placed> {
        let mut out = Vec::new();
        for (e, d) in self.config.defect.iter().enumerate() {
            let cell = d.cell_um() / self.spacing_um;
            let (i0, i1) = (
                (x0 / cell).floor() as i64 - 1,
                (x1 / cell).floor() as i64 + 1,
            );
            let (j0, j1) = (
                (y0 / cell).floor() as i64 - 1,
                (y1 / cell).floor() as i64 + 1,
            );
            for j in j0..=j1 {
                for i in i0..=i1 {
                    if let Some(p) = self.in_cell(e, i, j) {
                        let b = p.bbox;
                        if b[0] <= x1 && b[2] >= x0 && b[1] <= y1 && b[3] >= y0 {
                            out.push(p);
                        }
                    }
                }
            }
        }
        out
    }

    /// The defects whose boxes meet `region`.
    pub fn placed_over(&self, region: &Region) -> Vec<Placed> {
        let (xa, xb) = (region.x_at(0), region.x_at(region.width.saturating_sub(1)));
        let (ya, yb) = (region.y_at(0), region.y_at(region.height.saturating_sub(1)));
        self.placed_in(xa.min(xb), ya.min(yb), xa.max(xb), ya.max(yb))
    }

    /// Whether listing the defects over `region` would visit more cells than sampling
    /// each of its samples does (3 × 3 cells of each entry a sample): a coarse step over
    /// small cells. Fills then sum sample by sample ([`Defects::at`], the same bits), so
    /// that their cost stays bounded by their samples.
    fn too_many_cells(&self, region: &Region) -> bool {
        let (w, h) = (
            region.width as f64 * region.step,
            region.height as f64 * region.step,
        );
        let cells: f64 = self
            .config
            .defect
            .iter()
            .map(|d| {
                let c = d.cell_um() / self.spacing_um;
                (w / c + 3.0) * (h / c + 3.0)
            })
            .sum();
        cells > 9.0 * self.config.defect.len() as f64 * (region.width * region.height) as f64
    }

    /// The change and mask id at each sample of rows `rows` of `region`, each from the
    /// defects of its own 3 × 3 cells (see [`Defects::too_many_cells`]).
    fn each_sample(
        &self,
        region: &Region,
        rows: Range<usize>,
        mut f: impl FnMut(usize, usize, f64, u8),
    ) {
        for r in rows {
            let y = region.y_at(r);
            for col in 0..region.width {
                let x = region.x_at(col);
                let (dz, id) = Defects::at(&self.placed_in(x, y, x, y), x, y);
                f(r, col, dz, id);
            }
        }
    }

    /// The mask ids over `region` (0 where no defect changed a sample by more than
    /// [`MASK_FRACTION`] of its depth), row-major.
    pub fn fill_ids(&self, region: &Region, ids: &mut [u8]) -> Result<()> {
        self.fill_ids_boxed(region, ids).map(|_| ())
    }

    /// [`Defects::fill_ids`], returning the defects placed over `region` with their
    /// mask boxes ([`Boxed`]).
    pub fn fill_ids_boxed(&self, region: &Region, ids: &mut [u8]) -> Result<Vec<Boxed>> {
        region.validate()?;
        if ids.len() != region.width * region.height {
            return Err(Error::param(
                "mask buffer",
                format!("{} values", ids.len()),
                format!(
                    "{} for a {}×{} region",
                    region.width * region.height,
                    region.width,
                    region.height
                ),
            ));
        }
        if self.too_many_cells(region) {
            let w = region.width;
            self.each_sample(region, 0..region.height, |r, c, _, id| ids[r * w + c] = id);
            return Ok(Vec::new());
        }
        let placed = self.placed_over(region);
        let mut row = RowChanges::new(region.width, placed.len());
        for (r, out) in ids.chunks_exact_mut(region.width).enumerate() {
            row.compute(&placed, region, r);
            out.copy_from_slice(&row.ids);
        }
        Ok(row.boxed(placed))
    }

    /// Adds the defects to `heights` (one channel, row-major over `region`) and writes
    /// their mask ids to `ids`, in one pass on the calling thread: the heights
    /// [`Defected`] gives over the same inner heights, and the ids of
    /// [`Defects::fill_ids`]. Returns the defects placed over `region` with their mask
    /// boxes.
    pub fn apply(
        &self,
        region: &Region,
        heights: &mut [f32],
        ids: &mut [u8],
    ) -> Result<Vec<Boxed>> {
        region.validate()?;
        let n = region.width * region.height;
        if heights.len() != n || ids.len() != n {
            return Err(Error::param(
                "defect buffers",
                format!("{} heights and {} ids", heights.len(), ids.len()),
                format!(
                    "{n} of each for a {}×{} region",
                    region.width, region.height
                ),
            ));
        }
        if self.too_many_cells(region) {
            let w = region.width;
            self.each_sample(region, 0..region.height, |r, c, dz, id| {
                add(&mut heights[r * w + c], dz);
                ids[r * w + c] = id;
            });
            return Ok(Vec::new());
        }
        let placed = self.placed_over(region);
        let mut row = RowChanges::new(region.width, placed.len());
        let rows = heights
            .chunks_exact_mut(region.width)
            .zip(ids.chunks_exact_mut(region.width));
        for (r, (hs, is)) in rows.enumerate() {
            row.compute(&placed, region, r);
            row.add_to(hs);
            is.copy_from_slice(&row.ids);
        }
        Ok(row.boxed(placed))
    }

    /// The height change at (x, y) and the mask id it sets (0: none), over `placed`.
    pub fn at(placed: &[Placed], x: f64, y: f64) -> (f64, u8) {
        let (mut sum, mut id, mut strongest) = (0.0, 0u8, 0.0);
        for p in placed {
            let v = p.displacement_px(x, y);
            if v != 0.0 {
                sum += v * p.z_scale;
                let rel = v.abs() / p.depth_px;
                if rel > MASK_FRACTION && rel > strongest {
                    strongest = rel;
                    id = p.id;
                }
            }
        }
        (sum, id)
    }
}

/// `inner` (one channel of heights) with defects added.
pub struct Defected<S> {
    inner: S,
    defects: Defects,
}

impl<S: Surface> Defected<S> {
    /// `defects` over `inner`, which must have one channel (heights).
    pub fn new(inner: S, defects: Defects) -> Result<Defected<S>> {
        if inner.channels() != 1 {
            return Err(Error::param(
                "defects",
                format!("over a surface of {} channels", inner.channels()),
                "a height surface (one channel): defects change heights",
            ));
        }
        Ok(Defected { inner, defects })
    }

    /// The defects.
    pub fn defects(&self) -> &Defects {
        &self.defects
    }

    /// The surface under the defects.
    pub fn inner(&self) -> &S {
        &self.inner
    }

    /// The defects placed over `region`.
    pub fn placed_over(&self, region: &Region) -> Vec<Placed> {
        self.defects.placed_over(region)
    }

    /// The defects' mask ids over `region` ([`Defects::fill_ids`]).
    pub fn fill_ids(&self, region: &Region, ids: &mut [u8]) -> Result<()> {
        self.defects.fill_ids(region, ids)
    }

    /// Adds the defects of `placed` to rows `rows` of `region` in `out`.
    fn add_rows(placed: &[Placed], region: &Region, rows: Range<usize>, out: &mut [f32]) {
        let mut changes = RowChanges::new(region.width, 0);
        for (r, row) in rows.zip(out.chunks_mut(region.width)) {
            changes.compute(placed, region, r);
            changes.add_to(row);
        }
    }
}

/// The defects' changes along one row of a region: per column, the height change (the
/// sum [`Defects::at`] forms, in the same order) and the mask id. Each defect visits
/// only the columns of its box (nothing changes outside it), so a row costs its
/// defects' widths, not their number times its width.
struct RowChanges {
    dz: Vec<f64>,
    strongest: Vec<f64>,
    ids: Vec<u8>,
    /// Per placed defect, the columns and rows (first, first, last, last) where it
    /// changed a sample by more than [`MASK_FRACTION`] of its depth, over the rows
    /// computed so far.
    boxes: Vec<[usize; 4]>,
}

/// A placed defect and its mask box: the first and last column and row (inclusive,
/// in samples of the region) where it changed a sample by more than [`MASK_FRACTION`]
/// of its depth, whether or not its id won there; `None` where it changed none.
pub type Boxed = (Placed, Option<[usize; 4]>);

impl RowChanges {
    fn new(width: usize, defects: usize) -> RowChanges {
        RowChanges {
            dz: vec![0.0; width],
            strongest: vec![0.0; width],
            ids: vec![0; width],
            boxes: vec![[usize::MAX, usize::MAX, 0, 0]; defects],
        }
    }

    /// The placed defects with their boxes.
    fn boxed(self, placed: Vec<Placed>) -> Vec<Boxed> {
        placed
            .into_iter()
            .zip(self.boxes)
            .map(|(p, b)| (p, (b[0] != usize::MAX).then_some(b)))
            .collect()
    }

    /// The changes of `placed` along row `row` of `region`.
    fn compute(&mut self, placed: &[Placed], region: &Region, row: usize) {
        self.dz.fill(0.0);
        self.strongest.fill(0.0);
        self.ids.fill(0);
        let y = region.y_at(row);
        let w = region.width;
        let x0 = region.x_at(0);
        // Columns whose x may lie in [lo, hi], one more each side for rounding: a column
        // outside adds nothing, as in `at`.
        let columns = |(lo, hi): (f64, f64)| {
            let (a, z) = ((lo - x0) / region.step, (hi - x0) / region.step);
            (z >= -1.0 && a <= w as f64).then(|| {
                let first = (a.floor() - 1.0).max(0.0) as usize;
                let last = ((z.ceil() + 1.0).min(w as f64 - 1.0)) as usize;
                (first, last)
            })
        };
        for (i, p) in placed.iter().enumerate() {
            let [one, two] = p.row_spans(y).map(|s| s.and_then(columns));
            // Two spans (a scratch's arc crossing the row twice) widened into each other
            // are visited once.
            let spans = match (one, two) {
                (Some(a), Some(b)) if b.0 <= a.1 + 1 => [Some((a.0, a.1.max(b.1))), None],
                other => [other.0, other.1],
            };
            for (first, last) in spans.into_iter().flatten() {
                for col in first..=last {
                    let v = p.displacement_px(region.x_at(col), y);
                    if v != 0.0 {
                        self.dz[col] += v * p.z_scale;
                        let rel = v.abs() / p.depth_px;
                        if rel > MASK_FRACTION {
                            if rel > self.strongest[col] {
                                self.strongest[col] = rel;
                                self.ids[col] = p.id;
                            }
                            if let Some(b) = self.boxes.get_mut(i) {
                                *b = [b[0].min(col), b[1].min(row), b[2].max(col), b[3].max(row)];
                            }
                        }
                    }
                }
            }
        }
    }

    /// Adds the changes to a row of heights.
    fn add_to(&self, row: &mut [f32]) {
        for (v, &dz) in row.iter_mut().zip(&self.dz) {
            add(v, dz);
        }
    }
}

/// Adds a defect change to a height (nothing where there is none), as every path does.
fn add(v: &mut f32, dz: f64) {
    if dz != 0.0 {
        *v = (*v as f64 + dz) as f32;
    }
}

impl<S: Surface> Surface for Defected<S> {
    fn channels(&self) -> usize {
        1
    }

    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        self.inner.sample_footprint(x, y, footprint, out);
        let placed = self.defects.placed_in(x, y, x, y);
        let (dz, _) = Defects::at(&placed, x, y);
        if dz != 0.0 {
            out[0] = (out[0] as f64 + dz) as f32;
        }
    }

    fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        self.inner.fill_rows(region, rows.clone(), out);
        let Ok(part) = region.sub(0, rows.start, region.width, rows.len()) else {
            return;
        };
        if self.defects.too_many_cells(&part) {
            let (w, first) = (region.width, rows.start);
            self.defects.each_sample(region, rows, |r, c, dz, _| {
                add(&mut out[(r - first) * w + c], dz)
            });
            return;
        }
        Self::add_rows(&self.placed_over(&part), region, rows, out);
    }

    fn fill(&self, region: &Region, out: &mut [f32]) -> Result<()> {
        self.inner.fill(region, out)?;
        if self.defects.too_many_cells(region) {
            // Bands of the fill, each sample from its own cells.
            return for_bands(region, 1, out, default_threads(), 16, |rows, chunk| {
                let (w, first) = (region.width, rows.start);
                self.defects.each_sample(region, rows, |r, c, dz, _| {
                    add(&mut chunk[(r - first) * w + c], dz)
                })
            });
        }
        let placed = self.placed_over(region);
        for_bands(region, 1, out, default_threads(), 16, |rows, chunk| {
            Self::add_rows(&placed, region, rows, chunk)
        })
    }
}
