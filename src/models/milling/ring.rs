//! One ring of the milling model (seed 000 §4.1): its random parameters, drawn from the
//! hash of its index, and its value R_k = S_k·T_k + N_k at a point.

use std::sync::OnceLock;

use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Poisson};
use rand_xoshiro::Xoshiro256PlusPlus;

use super::config::{InteractionKind, MillingConfig, ShapeKind};
use super::path::Nominal;
use crate::analysis::gauss::normal_quantile;
use crate::hash::hash_cell;

/// Angular noise profiles in a milling bank ("milling patch bank", ALGORITHMS.md §5).
pub const NOISE_PROFILES: usize = 64;
/// Samples per noise profile, over one turn.
pub const NOISE_SAMPLES: usize = 2048;
/// Entries of the radial shape table cos(π/2·D) for D ∈ [−1, 1].
pub const SHAPE_LUT: usize = 1025;

/// Truncation of every normal draw, in standard deviations: it bounds a ring's reach.
pub const TRUNCATE_SIGMA: f64 = 4.0;

/// Most pixels across a block of a region fill (one support annulus across, at most).
pub const SPAN: usize = 64;

/// Entries of the inverse normal CDF table, less one.
const INV_CDF: usize = 4096;

/// Φ⁻¹(i/4096) for i = 0..=4096, clamped to ±4 ([`normal_quantile`]).
/// Stored as f32 (16 KiB, half of L1) since every sample reads it at random.
fn inv_cdf_table() -> &'static [f32; INV_CDF + 1] {
    static TABLE: OnceLock<Box<[f32; INV_CDF + 1]>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut t = Box::new([0.0f32; INV_CDF + 1]);
        for (i, v) in t.iter_mut().enumerate() {
            *v = if i == 0 || i == INV_CDF {
                TRUNCATE_SIGMA * if i == 0 { -1.0 } else { 1.0 }
            } else {
                normal_quantile(i as f64 / INV_CDF as f64).clamp(-TRUNCATE_SIGMA, TRUNCATE_SIGMA)
            } as f32;
        }
        t
    })
}

/// A standard normal draw from 16 hash bits, truncated to ±4: Φ⁻¹ at the bits'
/// position in (0, 1), linear between the table's entries (the top 12 bits pick the
/// entry, the low 4 the point between it and the next).
#[inline(always)]
fn normal(table: &[f32; INV_CDF + 1], bits: u32) -> f64 {
    let i = ((bits >> 4) & 0xFFF) as usize;
    let f = ((bits & 15) as f64 + 0.5) * (1.0 / 16.0);
    let (a, b) = (table[i] as f64, table[i + 1] as f64);
    a + (b - a) * f
}

/// A uniform draw in (0, 1) from 16 hash bits.
#[inline(always)]
fn uniform16(bits: u32) -> f64 {
    ((bits & 0xFFFF) as f64 + 0.5) * (1.0 / 65536.0)
}

/// cos(π/2·D) at D = −1 + 2i/(SHAPE_LUT − 1): the radial profile of every shape part.
pub fn shape_table() -> Vec<f32> {
    (0..SHAPE_LUT)
        .map(|i| {
            let d = -1.0 + 2.0 * i as f64 / (SHAPE_LUT - 1) as f64;
            (std::f64::consts::FRAC_PI_2 * d).cos() as f32
        })
        .collect()
}

/// The angular noise profiles (seed 000 §4.1.3): profile p is
/// (1/λ_p)·Σ_j sin(τ_pj·φ + ξ_pj) with λ_p ~ Poisson(λ) (0 sines: a flat profile),
/// τ_pj ~ Poisson(τ) and ξ_pj ~ U(−π, π], at `NOISE_SAMPLES` angles of one turn.
///
/// A ring uses profile p rotated by a uniform angle ψ: sin(τ(φ + ψ) + ξ) = sin(τφ + ξ′)
/// with ξ′ = ξ + τψ again uniform, so each ring's noise is a draw of the paper's model
/// whose (λ, τ) come from a pool of `NOISE_PROFILES` draws instead of fresh ones.
///
/// We read τ as the sines' angular frequency, as the text says ("frequencies τ"); the
/// formula as printed multiplies the amplitude by τ instead, which sums to a single
/// sinusoid of the angle and leaves the [−1, 1] range the text gives N_k.
pub fn noise_profiles(count_mean: f64, frequency_mean: f64, seed: u64) -> Vec<f32> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x6E6F_6973_6570_726F);
    let count = Poisson::new(count_mean.max(1e-9)).ok();
    let freq = Poisson::new(frequency_mean.max(1e-9)).ok();
    let mut out = vec![0.0f32; NOISE_PROFILES * NOISE_SAMPLES];
    for profile in out.chunks_exact_mut(NOISE_SAMPLES) {
        let n = count.map_or(0.0, |p| p.sample(&mut rng)) as usize;
        let sines: Vec<(f64, f64)> = (0..n)
            .map(|_| {
                let tau = freq.map_or(0.0, |p| p.sample(&mut rng));
                let xi = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
                (tau, xi)
            })
            .collect();
        if sines.is_empty() {
            continue;
        }
        for (s, v) in profile.iter_mut().enumerate() {
            let phi = std::f64::consts::TAU * s as f64 / NOISE_SAMPLES as f64;
            let sum: f64 = sines.iter().map(|(t, x)| (t * phi + x).sin()).sum();
            *v = (sum / sines.len() as f64) as f32;
        }
    }
    out
}

/// Minimax coefficients for atan on [0, 1] (max error 1e-5 rad): atan z ≈
/// z·(c₀ + z²·(c₁ + z²·(c₂ + z²·(c₃ + z²·(c₄ − c₅·z²))))).
pub(crate) const ATAN_POLY: [f64; 6] = [
    0.999_977_26,
    -0.332_623_47,
    0.193_543_46,
    -0.116_432_87,
    0.052_653_32,
    0.011_721_2,
];

/// atan2(y, x) / 2π in [−½, ½], to about 2·10⁻⁶ turns: a polynomial instead of the libm
/// call, which would be a sixth of a sample's time. Used only to index the noise
/// profiles, whose samples are 5·10⁻⁴ turns apart.
#[inline(always)]
pub fn atan2_turns(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = if ax < ay { (ax, ay) } else { (ay, ax) };
    if hi == 0.0 {
        return 0.0;
    }
    let z = lo / hi;
    let z2 = z * z;
    let [c0, c1, c2, c3, c4, c5] = ATAN_POLY;
    let mut a = z * (c0 + z2 * (c1 + z2 * (c2 + z2 * (c3 + z2 * (c4 - c5 * z2)))));
    if ay > ax {
        a = std::f64::consts::FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = std::f64::consts::PI - a;
    }
    if y < 0.0 {
        a = -a;
    }
    a * (1.0 / std::f64::consts::TAU)
}

/// Which part of a ring a point lies in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Part {
    Indentation = 0,
    Inner = 1,
    Outer = 2,
}

/// A ring's first stage at a point: its id and hash (stream 0), the point's offset from
/// the jittered centre and the squared distance (mm, mm²).
#[derive(Clone, Copy, Debug)]
pub struct Near {
    /// The ring's id.
    pub id: (i64, i64),
    h: [u32; 4],
    dx: f64,
    dy: f64,
    dist2: f64,
}

/// A ring's value at a point it covers: R_k, the convex weight A_k, and the hash word
/// that decides its ε reordering ([`RingModel::key_of`]).
#[derive(Clone, Copy, Debug)]
pub struct Value {
    /// R_k(x, y) (µm).
    pub r: f64,
    /// A_k(x, y) ∈ [0, 1] (1 unless the interaction is convex).
    pub a: f64,
    pub(super) order: u32,
}
pub type Key = (i64, i64, u32, i64, i64);

/// The numbers of the ring sub-model, derived once from a configuration (mm, µm).
#[derive(Clone, Debug)]
pub struct RingModel {
    pub(crate) shape: ShapeKind,
    pub(crate) interaction: InteractionKind,
    /// r = d/2.
    pub(crate) r: f64,
    /// (mean, std) of w⁻, w⁺ⁱ, w⁺ᵒ in mm.
    widths: [(f64, f64); 3],
    /// Per part: (μ_l, σ_l, μ_h, σ_h) in µm.
    tilt: [(f64, f64, f64, f64); 3],
    pub(crate) noise_amplitude: f64,
    front: (f64, f64),
    rear: (f64, f64),
    /// Cholesky factor (l00, l10, l11) of Σ_c.
    chol: (f64, f64, f64),
    /// No ring reaches a point farther than this from its nominal centre (mm).
    pub(crate) reach_out: f64,
    /// No ring reaches a point nearer than this to its nominal centre (mm).
    pub(crate) reach_in: f64,
    /// ε.
    pub(crate) reorder: f64,
    /// How far a reordered ring moves, in rings.
    pub(crate) reorder_reach: i64,
    /// The inverse normal CDF table of the hashed draws.
    inv_cdf: &'static [f32; INV_CDF + 1],
    /// Squared distances from a jittered centre outside which no ring has support (mm²).
    pub(crate) support2: (f64, f64),
    seed: u32,
}

impl RingModel {
    /// Derives the ring model of a validated configuration; `seed` is the placement seed.
    pub fn new(c: &MillingConfig, seed: u32) -> RingModel {
        let r = c.tool.diameter_mm / 2.0;
        let s = &c.shape;
        let t = &c.tilt;
        let sin_phi = t.tilt_deg.to_radians().sin();
        let low = t.low_mean_um.unwrap_or(t.depth_um - r * 1000.0 * sin_phi);
        let high = t.high_mean_um.unwrap_or(t.depth_um + r * 1000.0 * sin_phi);
        let [[a, b], [_, cc]] = c.path.jitter_cov_mm2;
        let l00 = a.max(0.0).sqrt();
        let l10 = if l00 > 0.0 { b / l00 } else { 0.0 };
        let l11 = (cc - l10 * l10).max(0.0).sqrt();
        let jitter_bound = TRUNCATE_SIGMA * (l00 * l00 + (l10.abs() + l11).powi(2)).sqrt();
        let bump = s.kind == ShapeKind::Bump;
        let max = |(m, sd): (f64, f64)| (m + TRUNCATE_SIGMA * sd).max(0.0);
        let w_minus_max = max((s.width_mean_mm, s.width_std_mm)).min(r);
        let w_inner_max = if bump {
            max((s.inner_width_mean_mm, s.inner_width_std_mm))
        } else {
            0.0
        };
        let w_outer_max = if bump {
            max((s.outer_width_mean_mm, s.outer_width_std_mm))
        } else {
            0.0
        };
        // A margin of 1e-9 relative keeps rounding in the search windows on the safe side.
        let margin = 1e-9 * (1.0 + r);
        let reach_out = r + w_outer_max + jitter_bound + margin;
        let reach_in = (r - (w_minus_max + w_inner_max).min(r) - jitter_bound - margin).max(0.0);
        let reorder_reach = match c.path.reorder_reach_rings {
            0 => (2.0 * reach_out / c.path.step_mm).ceil().max(1.0) as i64,
            m => m as i64,
        };
        RingModel {
            shape: s.kind,
            interaction: c.interaction.kind,
            r,
            widths: [
                (s.width_mean_mm, s.width_std_mm),
                (s.inner_width_mean_mm, s.inner_width_std_mm),
                (s.outer_width_mean_mm, s.outer_width_std_mm),
            ],
            tilt: [
                (low, t.low_std_um, high, t.high_std_um),
                (
                    t.inner_low_mean_um,
                    t.inner_low_std_um,
                    t.inner_high_mean_um,
                    t.inner_high_std_um,
                ),
                (
                    t.outer_low_mean_um,
                    t.outer_low_std_um,
                    t.outer_high_mean_um,
                    t.outer_high_std_um,
                ),
            ],
            noise_amplitude: c.noise.amplitude_um,
            front: (
                c.interaction.front_weight_min,
                c.interaction.front_weight_max,
            ),
            rear: (c.interaction.rear_weight_min, c.interaction.rear_weight_max),
            chol: (l00, l10, l11),
            reach_out,
            reach_in,
            reorder: c.path.reorder,
            reorder_reach,
            inv_cdf: inv_cdf_table(),
            support2: (
                ((r - (w_minus_max + w_inner_max).min(r)) * (1.0 - 1e-12)).powi(2),
                ((r + w_outer_max) * (1.0 + 1e-12)).powi(2),
            ),
            seed,
        }
    }

    /// The ring's place in the milling order after the ε reordering: with probability
    /// ε (16 bits of its hash, stream 1, word 3) the ring moves by a hashed 1 to m rings
    /// forwards or backwards along its line (parallel: position) or spiral (rank), and
    /// comes after the ring it lands on.
    #[inline(always)]
    pub fn key(&self, ring: &Nominal, spiral: bool) -> Key {
        let order = hash_cell(self.seed, ring.0.0, ring.0.1, 1)[3];
        self.key_of(ring, order, spiral)
    }

    /// [`Self::key`] from the hash word already drawn by [`Self::finish`].
    #[inline(always)]
    pub fn key_of(&self, ring: &Nominal, order: u32, spiral: bool) -> Key {
        let (id, _, _, _, (mut rank, mut pos)) = *ring;
        let mut tie = 0;
        if self.reorder > 0.0 && uniform16(order) < self.reorder {
            let m = self.reorder_reach as u64;
            // Multiply-shift range reduction of 16 bits to 0..2m.
            let step = (((order >> 16) as u64 * 2 * m) >> 16) as i64 - m as i64;
            let step = if step >= 0 { step + 1 } else { step };
            if spiral {
                rank = rank.saturating_add(step);
            } else {
                pos = pos.saturating_add(step);
            }
            tie = 1;
        }
        (rank, pos, tie, id.0, id.1)
    }

    /// R_k(x, y) = S_k·T_k + N_k and the convex weight A_k of the ring with nominal
    /// placement `ring`, or None outside its support P_k (seed 000 §4.1, eq. 1, §4.2).
    ///
    /// The ring's random numbers come from its hash, drawn only as far as the point
    /// needs them. Stream 0 gives 8 draws of 16 bits: the jitter (z₁, z₂), the widths
    /// w⁻, w⁺ⁱ, w⁺ᵒ, the noise profile and rotation, and the convex weights a_k, b_k;
    /// stream 1 gives the tilting plane (l, h) of each part (words 0–2) and the ε
    /// reordering (word 3).
    #[inline(always)]
    pub fn value(
        &self,
        ring: &Nominal,
        x: f64,
        y: f64,
        lut: &[f32],
        noise: &[i16],
    ) -> Option<Value> {
        let near = self.near(ring.0, (ring.1, ring.2), x, y);
        if !self.may_cover(&near) {
            return None;
        }
        self.finish(ring, &near, lut, noise)
    }

    /// First stage of [`Self::value`], free of branches: the ring's hash, the offset of
    /// the point from its jittered centre (the nominal centre is `centre`), and the
    /// squared distance.
    #[inline(always)]
    pub fn near(&self, id: (i64, i64), centre: (f64, f64), x: f64, y: f64) -> Near {
        let t = self.inv_cdf;
        let h = hash_cell(self.seed, id.0, id.1, 0);
        let (z1, z2) = (normal(t, h[0]), normal(t, h[0] >> 16));
        let (l00, l10, l11) = self.chol;
        let (dx, dy) = (
            x - (centre.0 + l00 * z1),
            y - (centre.1 + l10 * z1 + l11 * z2),
        );
        Near {
            id,
            h,
            dx,
            dy,
            dist2: dx * dx + dy * dy,
        }
    }

    /// False when the point is outside every support the ring can have.
    #[inline(always)]
    pub fn may_cover(&self, near: &Near) -> bool {
        near.dist2 >= self.support2.0 && near.dist2 <= self.support2.1
    }

    /// Second stage of [`Self::value`], for a point that [`Self::may_cover`] passed;
    /// `ring` is the nominal placement of `near.id`. Draws only what the point needs.
    #[inline(always)]
    pub fn finish(&self, ring: &Nominal, near: &Near, lut: &[f32], noise: &[i16]) -> Option<Value> {
        let (id, _, _, dir, _) = *ring;
        let Near {
            h, dx, dy, dist2, ..
        } = *near;
        let dist = dist2.sqrt();
        let w_minus = self.w_minus(h);
        let (part, centre, width) = self.part_of(
            dist,
            w_minus,
            || self.w_inner(h, w_minus),
            || self.w_outer(h),
        )?;
        let h1 = hash_cell(self.seed, id.0, id.1, 1);
        let along = self.along(dir, dx, dy);
        Some(Value {
            r: self.ring_value(
                (part, centre, width),
                dist,
                along,
                self.plane(h1, part),
                h[2] >> 16,
                dx,
                dy,
                lut,
                noise,
            ),
            a: self.weight(self.weights(h), along),
            order: h1[3],
        })
    }

    /// w⁻ (mm) from stream 0, word 1, low half.
    #[inline(always)]
    fn w_minus(&self, h: [u32; 4]) -> f64 {
        self.draw(0, h[1]).min(self.r)
    }

    /// w⁺ⁱ (mm) from stream 0, word 1, high half; at most the r − w⁻ left inside.
    #[inline(always)]
    fn w_inner(&self, h: [u32; 4], w_minus: f64) -> f64 {
        self.draw(1, h[1] >> 16).min(self.r - w_minus)
    }

    /// w⁺ᵒ (mm) from stream 0, word 2, low half.
    #[inline(always)]
    fn w_outer(&self, h: [u32; 4]) -> f64 {
        self.draw(2, h[2])
    }

    #[inline(always)]
    fn draw(&self, k: usize, bits: u32) -> f64 {
        (self.widths[k].0 + self.widths[k].1 * normal(self.inv_cdf, bits)).max(0.0)
    }

    /// The part of the ring at distance `dist` from its centre, with the centre and
    /// width of that part's profile, or None off the support. Closed parts, tried in
    /// the order indentation, inner, outer (their common borders have S = 0 in every
    /// part but the indicator's indentation). The bump's widths are asked for only when
    /// needed.
    #[inline(always)]
    fn part_of(
        &self,
        dist: f64,
        w_minus: f64,
        w_inner: impl FnOnce() -> f64,
        w_outer: impl FnOnce() -> f64,
    ) -> Option<(Part, f64, f64)> {
        let r = self.r;
        let edge = r - w_minus;
        if dist >= edge && dist <= r && w_minus > 0.0 {
            Some((Part::Indentation, r - 0.5 * w_minus, w_minus))
        } else if self.shape != ShapeKind::Bump {
            None
        } else if dist < edge {
            let w = w_inner();
            (w > 0.0 && dist >= edge - w).then_some((Part::Inner, edge - 0.5 * w, w))
        } else {
            let w = w_outer();
            (w > 0.0 && dist > r && dist <= r + w).then_some((Part::Outer, r + 0.5 * w, w))
        }
    }

    /// Position along the direction of motion, −½ at the rear to ½ at the front.
    #[inline(always)]
    fn along(&self, (cos_t, sin_t): (f64, f64), dx: f64, dy: f64) -> f64 {
        (cos_t * dx + sin_t * dy) * (0.5 / self.r)
    }

    /// The tilting plane's (l, h) of `part` (µm), from stream 1, word `part`.
    #[inline(always)]
    fn plane(&self, h1: [u32; 4], part: Part) -> (f64, f64) {
        let hp = h1[part as usize];
        let (ml, sl, mh, sh) = self.tilt[part as usize];
        let t = self.inv_cdf;
        (ml + sl * normal(t, hp), mh + sh * normal(t, hp >> 16))
    }

    /// The convex weights (a_k at the front, b_k at the rear) from stream 0, word 3.
    #[inline(always)]
    fn weights(&self, h: [u32; 4]) -> (f64, f64) {
        (
            self.front.0 + (self.front.1 - self.front.0) * uniform16(h[3]),
            self.rear.0 + (self.rear.1 - self.rear.0) * uniform16(h[3] >> 16),
        )
    }

    /// A_k: eq. (1) with a_k at the front and b_k at the rear (Table 3's names); 1
    /// unless the interaction is convex.
    #[inline(always)]
    fn weight(&self, (a, b): (f64, f64), along: f64) -> f64 {
        if self.interaction == InteractionKind::Convex {
            ((a - b) * along + 0.5 * (a + b)).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }

    /// R_k = S_k·T_k + N_k at a point of the ring's `part` (eq. 1): the shape from the
    /// table, the plane through the lowest (rear) and highest (front) scaling, and the
    /// noise profile picked and rotated by the 16 bits `noise_word`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn ring_value(
        &self,
        (part, centre, width): (Part, f64, f64),
        dist: f64,
        along: f64,
        (low, high): (f64, f64),
        noise_word: u32,
        dx: f64,
        dy: f64,
        lut: &[f32],
        noise: &[i16],
    ) -> f64 {
        let v = self.shape_plane((part, centre, width), dist, along, (low, high), lut);
        if self.noise_amplitude > 0.0 {
            v + self.noise_at(noise_word, dx, dy, noise)
        } else {
            v
        }
    }

    /// S_k·T_k: the shape from the table times the tilting plane.
    #[inline(always)]
    fn shape_plane(
        &self,
        (part, centre, width): (Part, f64, f64),
        dist: f64,
        along: f64,
        (low, high): (f64, f64),
        lut: &[f32],
    ) -> f64 {
        let s = match self.shape {
            ShapeKind::Indicator => -1.0,
            _ => {
                // D = (dist − centre)·2/w ∈ [−1, 1]; cos(π/2·D) from the table.
                let d = ((dist - centre) * (2.0 / width)).clamp(-1.0, 1.0);
                let pos = (d + 1.0) * (0.5 * (SHAPE_LUT - 1) as f64);
                let i = (pos as usize).min(SHAPE_LUT - 2);
                let f = pos - i as f64;
                let c = lut[i] as f64 + (lut[i + 1] as f64 - lut[i] as f64) * f;
                if part == Part::Indentation { -c } else { c }
            }
        };
        let plane = (high - low) * along + 0.5 * (high + low);
        s * plane
    }

    /// N_k: the noise profile picked and rotated by the 16 bits `noise_word`, at the
    /// angle of (dx, dy), times the amplitude.
    #[inline(always)]
    fn noise_at(&self, noise_word: u32, dx: f64, dy: f64, noise: &[i16]) -> f64 {
        let profile = (noise_word as usize >> 10) % NOISE_PROFILES;
        let turn = atan2_turns(dy, dx) + (noise_word & 0x3FF) as f64 * (1.0 / 1024.0);
        let pos = (turn - turn.floor()) * NOISE_SAMPLES as f64;
        let i = (pos as usize).min(NOISE_SAMPLES - 1);
        let f = pos - i as f64;
        let row = &noise[profile * NOISE_SAMPLES..(profile + 1) * NOISE_SAMPLES];
        let (a, b) = (row[i] as f64, row[(i + 1) % NOISE_SAMPLES] as f64);
        self.noise_amplitude * NOISE_UNIT * (a + (b - a) * f)
    }

    /// Ring `d` ready to be folded into rows ([`SpanRing::fold`]) or evaluated at
    /// points ([`SpanRing::parts`], or four rings at once as a [`Group`]).
    #[inline(always)]
    pub(crate) fn span_ring(&self, d: &Drawn) -> SpanRing {
        SpanRing::new(self, d)
    }

    /// The radii (mm) between which ring `d` can cover a point, or None if it covers
    /// none: the union of its parts as `part_of` bounds them (indentation [r − w⁻, r],
    /// inner [r − w⁻ − w⁺ⁱ, r − w⁻), outer (r, r + w⁺ᵒ]), within the model's support.
    pub fn support_radii(&self, d: &Drawn) -> Option<(f64, f64)> {
        self.support_of(&self.span_ring(d))
    }

    /// [`Self::support_radii`] of a ring already worked into its constants.
    #[inline(always)]
    pub(crate) fn support_of(&self, k: &SpanRing) -> Option<(f64, f64)> {
        let (lo, hi) = k.support()?;
        Some((
            lo.max(self.support2.0.sqrt()),
            hi.min(self.support2.1.sqrt()),
        ))
    }

    /// What the ring arithmetic branches on: the same for every ring of the model.
    #[inline(always)]
    pub(crate) fn kind(&self) -> Kind {
        Kind {
            indicator: self.shape == ShapeKind::Indicator,
            with_noise: self.noise_amplitude > 0.0,
            interaction: self.interaction,
        }
    }

    /// Everything about ring `ring` that does not depend on the point, drawn at once:
    /// what a region fill computes once per ring and block ([`Drawn::value`]).
    pub fn drawn(&self, ring: &Nominal, spiral: bool) -> Drawn {
        let (id, cx, cy, dir, _) = *ring;
        let near = self.near(id, (cx, cy), 0.0, 0.0);
        let h = near.h;
        let h1 = hash_cell(self.seed, id.0, id.1, 1);
        let w_minus = self.w_minus(h);
        Drawn {
            // near() at the origin gives dx = 0 − (cx + jitter): the jittered centre
            // negated, and x − c below is the same sum near() forms at x.
            centre: (-near.dx, -near.dy),
            dir,
            w_minus,
            w_inner: self.w_inner(h, w_minus),
            w_outer: self.w_outer(h),
            planes: [
                self.plane(h1, Part::Indentation),
                self.plane(h1, Part::Inner),
                self.plane(h1, Part::Outer),
            ],
            noise_word: h[2] >> 16,
            weights: self.weights(h),
            key: self.key_of(ring, h1[3], spiral),
        }
    }
}

/// What every ring of a model shares and the ring arithmetic branches on (once per
/// ring or group, never per point).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Kind {
    pub(crate) indicator: bool,
    pub(crate) with_noise: bool,
    pub(crate) interaction: InteractionKind,
}

/// What a row fill or a point needs of one ring: the constants of [`Drawn::value`]'s
/// arithmetic, worked out once (a region fill makes them per ring and block, the
/// point path per ring it caches), and the terms of the current row. Shared by the
/// scalar path ([`SpanRing::parts`]) and the AVX2 one ([`super::simd`]: the ring in
/// every lane on a row, or four rings as a [`Group`] at a point), which do the same
/// operations in the same order. The parts are indexed
/// [`Part`]-wise: indentation, inner, outer.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SpanRing {
    pub(crate) cx: f64,
    pub(crate) cy: f64,
    pub(crate) dy: f64,
    pub(crate) dy2: f64,
    pub(crate) r: f64,
    /// r − w⁻: where the indentation starts.
    pub(crate) edge: f64,
    /// Whether each part has a positive width.
    pub(crate) has: [bool; 3],
    /// Profile centres of the parts.
    pub(crate) centre: [f64; 3],
    /// 2 / the profile widths of the parts (w⁻, w⁺ⁱ, w⁺ᵒ).
    pub(crate) scale: [f64; 3],
    /// The inner part's lower and the outer part's upper bound.
    pub(crate) in_lo: f64,
    pub(crate) out_hi: f64,
    /// Each part's plane as h − l and ½(h + l): `shape_plane`'s two terms.
    pub(crate) slope: [f64; 3],
    pub(crate) mid: [f64; 3],
    pub(crate) kind: Kind,
    pub(crate) cos_t: f64,
    pub(crate) sin_t: f64,
    /// sin θ·dy, the row's share of the position along the motion.
    pub(crate) along_y: f64,
    pub(crate) to_along: f64,
    /// The convex weight as (a − b, ½(a + b)).
    pub(crate) w_slope: f64,
    pub(crate) w_mid: f64,
    pub(crate) amplitude: f64,
    pub(crate) rotation: f64,
    /// Where the ring's noise profile starts in the padded profiles ([`pad_noise`]):
    /// a multiple of NOISE_SAMPLES + 1 below [`PADDED_NOISE`].
    pub(crate) noise_row: usize,
}

/// Entries of the padded noise profiles ([`pad_noise`]).
pub(crate) const PADDED_NOISE: usize = NOISE_PROFILES * (NOISE_SAMPLES + 1);

impl SpanRing {
    #[inline(always)]
    fn new(m: &RingModel, d: &Drawn) -> SpanRing {
        let r = m.r;
        let bump = m.shape == ShapeKind::Bump;
        let edge = r - d.w_minus;
        let (wa, wb) = d.weights;
        let profile = (d.noise_word as usize >> 10) % NOISE_PROFILES;
        SpanRing {
            cx: d.centre.0,
            cy: d.centre.1,
            dy: 0.0,
            dy2: 0.0,
            r,
            edge,
            has: [
                d.w_minus > 0.0,
                bump && d.w_inner > 0.0,
                bump && d.w_outer > 0.0,
            ],
            centre: [
                r - 0.5 * d.w_minus,
                edge - 0.5 * d.w_inner,
                r + 0.5 * d.w_outer,
            ],
            scale: [2.0 / d.w_minus, 2.0 / d.w_inner, 2.0 / d.w_outer],
            in_lo: edge - d.w_inner,
            out_hi: r + d.w_outer,
            slope: d.planes.map(|(low, high)| high - low),
            mid: d.planes.map(|(low, high)| 0.5 * (high + low)),
            kind: m.kind(),
            cos_t: d.dir.0,
            sin_t: d.dir.1,
            along_y: 0.0,
            to_along: 0.5 / m.r,
            w_slope: wa - wb,
            w_mid: 0.5 * (wa + wb),
            amplitude: m.noise_amplitude * NOISE_UNIT,
            rotation: (d.noise_word & 0x3FF) as f64 * (1.0 / 1024.0),
            noise_row: profile * (NOISE_SAMPLES + 1),
        }
    }

    /// The radii (mm) between which the ring can cover a point: its parts' union as
    /// [`Self::parts`] bounds them, or None if it has none.
    #[inline(always)]
    pub(crate) fn support(&self) -> Option<(f64, f64)> {
        let [ind, inner, outer] = self.has;
        let lo = if inner {
            self.in_lo
        } else if ind {
            self.edge
        } else {
            self.r
        };
        let hi = if outer { self.out_hi } else { self.r };
        (ind || inner || outer).then_some((lo.max(0.0), hi))
    }

    /// The same ring with no parts: it covers no point (the padding of a [`Group`]).
    #[inline(always)]
    pub(crate) fn covering_nothing(&self) -> SpanRing {
        SpanRing {
            has: [false; 3],
            ..*self
        }
    }

    /// Moves to the row at y (mm).
    #[inline(always)]
    pub(crate) fn set_row(&mut self, y: f64) {
        self.dy = y - self.cy;
        self.dy2 = self.dy * self.dy;
        self.along_y = self.sin_t * self.dy;
    }

    /// The ring folded into `row` at the points `xs` (mm) of the row [`Self::set_row`]
    /// chose: each point it covers becomes min(f, R), R or A·R + (1 − A)·f by the
    /// interaction, the others keep f. The values are those of [`Drawn::value`] and
    /// the fold that of `fold_keyed`, bit for bit: the same operations on the same
    /// numbers. Every point goes through the same straight-line code (the part of the
    /// ring, the shape, plane and noise chosen by selects, not branches; a point off
    /// the support computes a value and drops it): four points per instruction where
    /// the CPU has AVX2 ([`super::simd`]), one by one otherwise. `noise` holds the
    /// profiles as [`pad_noise`] lays them out.
    #[inline(always)]
    pub(crate) fn fold(&self, xs: &[f64], row: &mut [f64], lut: &[f32; SHAPE_LUT], noise: &Padded) {
        let n = xs.len().min(row.len());
        let done = super::simd::span(self, &xs[..n], &mut row[..n], lut, noise);
        for (f, &x) in row[done..n].iter_mut().zip(&xs[done..n]) {
            *f = self.point(x, *f, lut, noise);
        }
    }

    /// The fold at one point x of the row, f the value so far: [`Self::parts`] and
    /// `fold_keyed`'s step, without branches on the point.
    #[inline(always)]
    pub(crate) fn point(&self, x: f64, f: f64, lut: &[f32; SHAPE_LUT], noise: &Padded) -> f64 {
        let (covered, v, a) = self.parts(x, lut, noise);
        fold_step(self.kind.interaction, covered, f, v, a)
    }

    /// At the point x of the row: whether the ring covers it, and its R_k and A_k
    /// there (A_k only for the convex interaction), as [`Drawn::value`] gives them,
    /// without branches on the point (a point off the ring gets a value to drop).
    #[inline(always)]
    pub(crate) fn parts(&self, x: f64, lut: &[f32; SHAPE_LUT], noise: &Padded) -> (bool, f64, f64) {
        let dx = x - self.cx;
        let d2 = dx * dx + self.dy2;
        let dist = d2.sqrt();
        let [has_ind, has_in, has_out] = self.has;
        let ind = has_ind & (dist >= self.edge) & (dist <= self.r);
        let below = dist < self.edge;
        let inner = !ind & has_in & below & (dist >= self.in_lo);
        let outer = !ind & has_out & !below & (dist > self.r) & (dist <= self.out_hi);
        // `Drawn::value` first asks for d² within the model's support annulus
        // `support2`; every part lies inside it with a margin of 10⁻¹² of the radius
        // (the widths' truncation at 4σ bounds them), far above the rounding of d² and
        // √d², so a point in a part passes that test and it is left out here.
        let covered = ind | inner | outer;
        let pick = |p: [f64; 3]| select(ind, p[0], select(inner, p[1], p[2]));
        let (slope, mid) = (pick(self.slope), pick(self.mid));
        let s = if self.kind.indicator {
            -1.0
        } else {
            let dd = ((dist - pick(self.centre)) * pick(self.scale)).clamp(-1.0, 1.0);
            let pos = (dd + 1.0) * (0.5 * (SHAPE_LUT - 1) as f64);
            let i = (pos as usize).min(SHAPE_LUT - 2);
            let t = pos - i as f64;
            let c = lut[i] as f64 + (lut[i + 1] as f64 - lut[i] as f64) * t;
            select(ind, -c, c)
        };
        let along = (self.cos_t * dx + self.along_y) * self.to_along;
        let mut v = s * (slope * along + mid);
        if self.kind.with_noise {
            let turn = atan2_turns(self.dy, dx) + self.rotation;
            let pos = (turn - turn.floor()) * NOISE_SAMPLES as f64;
            let i = (pos as usize).min(NOISE_SAMPLES - 1);
            let t = pos - i as f64;
            let profile = &noise.0[self.noise_row..self.noise_row + NOISE_SAMPLES + 1];
            let (a, b) = (profile[i] as f64, profile[i + 1] as f64);
            v += self.amplitude * (a + (b - a) * t);
        }
        let a = match self.kind.interaction {
            InteractionKind::Convex => (self.w_slope * along + self.w_mid).clamp(0.0, 1.0),
            _ => 1.0,
        };
        (covered, v, a)
    }
}

/// Four rings' [`SpanRing`] constants, a ring to a lane, as the AVX2 path loads them
/// (one aligned vector per field); what the point path keeps per cell. The row terms
/// are not kept: a point computes them for its own y.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct Group {
    pub(crate) cx: [f64; 4],
    pub(crate) cy: [f64; 4],
    pub(crate) r: [f64; 4],
    pub(crate) edge: [f64; 4],
    pub(crate) in_lo: [f64; 4],
    pub(crate) out_hi: [f64; 4],
    pub(crate) centre: [[f64; 4]; 3],
    pub(crate) scale: [[f64; 4]; 3],
    pub(crate) slope: [[f64; 4]; 3],
    pub(crate) mid: [[f64; 4]; 3],
    pub(crate) cos_t: [f64; 4],
    pub(crate) sin_t: [f64; 4],
    pub(crate) to_along: [f64; 4],
    pub(crate) w_slope: [f64; 4],
    pub(crate) w_mid: [f64; 4],
    pub(crate) amplitude: [f64; 4],
    pub(crate) rotation: [f64; 4],
    /// Lane masks (all ones or all zeros) of [`SpanRing::has`].
    pub(crate) has: [[u64; 4]; 3],
    pub(crate) noise_row: [i32; 4],
}

impl Group {
    /// Ring `ks[q]` in lane q.
    #[inline(always)]
    pub(crate) fn from_rings(ks: [&SpanRing; 4]) -> Group {
        #[inline(always)]
        fn lanes<T, const N: usize>(
            ks: [&SpanRing; 4],
            f: impl Fn(&SpanRing) -> [T; N],
        ) -> [[T; 4]; N]
        where
            T: Copy + Default,
        {
            let mut out = [[T::default(); 4]; N];
            for (q, k) in ks.iter().enumerate() {
                for (p, v) in f(k).into_iter().enumerate() {
                    out[p][q] = v;
                }
            }
            out
        }
        let lane = |f: fn(&SpanRing) -> f64| lanes(ks, |k| [f(k)])[0];
        let parts = |f: fn(&SpanRing) -> [f64; 3]| lanes(ks, f);
        Group {
            cx: lane(|k| k.cx),
            cy: lane(|k| k.cy),
            r: lane(|k| k.r),
            edge: lane(|k| k.edge),
            in_lo: lane(|k| k.in_lo),
            out_hi: lane(|k| k.out_hi),
            centre: parts(|k| k.centre),
            scale: parts(|k| k.scale),
            slope: parts(|k| k.slope),
            mid: parts(|k| k.mid),
            cos_t: lane(|k| k.cos_t),
            sin_t: lane(|k| k.sin_t),
            to_along: lane(|k| k.to_along),
            w_slope: lane(|k| k.w_slope),
            w_mid: lane(|k| k.w_mid),
            amplitude: lane(|k| k.amplitude),
            rotation: lane(|k| k.rotation),
            has: lanes(ks, |k| k.has.map(|h| (h as u64).wrapping_neg())),
            noise_row: lanes(ks, |k| [k.noise_row as i32])[0],
        }
    }

    /// The ring of lane q (of a model of kind `kind`), on row 0: the scalar twin's
    /// view of the group.
    #[inline(always)]
    pub(crate) fn ring(&self, q: usize, kind: Kind) -> SpanRing {
        let part = |f: &[[f64; 4]; 3]| [f[0][q], f[1][q], f[2][q]];
        SpanRing {
            cx: self.cx[q],
            cy: self.cy[q],
            dy: 0.0,
            dy2: 0.0,
            r: self.r[q],
            edge: self.edge[q],
            has: [0, 1, 2].map(|p| self.has[p][q] != 0),
            centre: part(&self.centre),
            scale: part(&self.scale),
            in_lo: self.in_lo[q],
            out_hi: self.out_hi[q],
            slope: part(&self.slope),
            mid: part(&self.mid),
            kind,
            cos_t: self.cos_t[q],
            sin_t: self.sin_t[q],
            along_y: 0.0,
            to_along: self.to_along[q],
            w_slope: self.w_slope[q],
            w_mid: self.w_mid[q],
            amplitude: self.amplitude[q],
            rotation: self.rotation[q],
            noise_row: self.noise_row[q] as usize,
        }
    }
}

/// The noise profiles laid out for the row fills and the point path ([`pad_noise`]):
/// exactly [`PADDED_NOISE`] entries, which the AVX2 gathers rely on.
#[derive(Clone, Debug)]
pub(crate) struct Padded(Box<[i16; PADDED_NOISE]>);

impl Padded {
    /// The entries, for the gathers.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(crate) fn as_ptr(&self) -> *const i16 {
        self.0.as_ptr()
    }
}

/// The minimum interaction's step: v where it is below f, else f (one definition, so
/// that the point, row and brute-force folds agree on ties of ±0).
#[inline(always)]
pub(crate) fn fold_min(f: f64, v: f64) -> f64 {
    if v < f { v } else { f }
}

/// One step of the interaction's fold, f_k = f(f_{k−1}, R_k) with weight A_k, where
/// the ring covers the point (`covered`), else f itself; without branches.
#[inline(always)]
pub(crate) fn fold_step(
    interaction: InteractionKind,
    covered: bool,
    f: f64,
    v: f64,
    a: f64,
) -> f64 {
    let folded = match interaction {
        InteractionKind::Min => fold_min(f, v),
        InteractionKind::Latest => v,
        InteractionKind::Convex => a * v + (1.0 - a) * f,
    };
    select(covered, folded, f)
}

/// `if c { a } else { b }`, written so that it compiles to a select, not a branch.
#[inline(always)]
fn select(c: bool, a: f64, b: f64) -> f64 {
    let m = (c as u64).wrapping_neg();
    f64::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}

/// The noise profiles laid out for the row fills and the point path: each followed by
/// a copy of its first sample, so the interpolation's next sample is always the next
/// entry (and the AVX2 path reads both in one 32-bit load).
pub(crate) fn pad_noise(noise: &[i16]) -> Padded {
    assert_eq!(
        noise.len(),
        NOISE_PROFILES * NOISE_SAMPLES,
        "the quantised noise holds NOISE_PROFILES profiles of NOISE_SAMPLES"
    );
    let padded: Vec<i16> = noise
        .chunks_exact(NOISE_SAMPLES)
        .flat_map(|p| p.iter().chain(&p[..1]).copied())
        .collect();
    Padded(
        padded
            .into_boxed_slice()
            .try_into()
            .expect("NOISE_PROFILES padded profiles"),
    )
}

/// The point-independent draws of one ring ([`RingModel::drawn`]).
#[derive(Clone, Copy, Debug)]
pub struct Drawn {
    /// The jittered centre (mm).
    pub centre: (f64, f64),
    pub(crate) dir: (f64, f64),
    pub(crate) w_minus: f64,
    pub(crate) w_inner: f64,
    pub(crate) w_outer: f64,
    pub(crate) planes: [(f64, f64); 3],
    pub(crate) noise_word: u32,
    pub(crate) weights: (f64, f64),
    /// The ring's place in the milling order.
    pub key: Key,
}

impl Drawn {
    /// The ring's value at (x, y) (mm), or None off its support: the same numbers, in
    /// the same order of operations, as [`RingModel::value`].
    #[inline(always)]
    pub fn value(
        &self,
        m: &RingModel,
        x: f64,
        y: f64,
        lut: &[f32],
        noise: &[i16],
    ) -> Option<Value> {
        let (dx, dy) = (x - self.centre.0, y - self.centre.1);
        let dist2 = dx * dx + dy * dy;
        if !(dist2 >= m.support2.0 && dist2 <= m.support2.1) {
            return None;
        }
        let dist = dist2.sqrt();
        let (part, centre, width) =
            m.part_of(dist, self.w_minus, || self.w_inner, || self.w_outer)?;
        let along = m.along(self.dir, dx, dy);
        Some(Value {
            r: m.ring_value(
                (part, centre, width),
                dist,
                along,
                self.planes[part as usize],
                self.noise_word,
                dx,
                dy,
                lut,
                noise,
            ),
            a: m.weight(self.weights, along),
            order: 0,
        })
    }
}

/// The value of one step of a quantised noise profile ([`quantise_noise`]).
pub const NOISE_UNIT: f64 = 1.0 / 32767.0;

/// The noise profiles as the sampler reads them: 16-bit steps of 1/32767 (an error of
/// 1.5·10⁻⁵ of the noise amplitude), so the 64 profiles take 256 KiB and stay in L2
/// under random access instead of 512 KiB as f32.
pub fn quantise_noise(profiles: &[f32]) -> Vec<i16> {
    profiles
        .iter()
        .map(|&v| (v.clamp(-1.0, 1.0) as f64 * 32767.0).round() as i16)
        .collect()
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// Uniform draws in [0, 1) from a xorshift64 stream started at `seed` (not 0).
    pub(in super::super) fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// The shape table and the quantised noise profiles, plain and padded, that the
    /// bit-for-bit tests read.
    fn tables() -> (Vec<f32>, Vec<i16>, Padded) {
        let noise_q = quantise_noise(&noise_profiles(50.0, 50.0, 4));
        let noise_pad = pad_noise(&noise_q);
        (shape_table(), noise_q, noise_pad)
    }

    /// Calls `f(shape, interaction, model, path)` for every shape × interaction, on a
    /// parallel path at 20°.
    fn each_shape_and_interaction(
        mut f: impl FnMut(&str, &str, RingModel, super::super::path::ToolPath),
    ) {
        for shape in ["indicator", "cosine", "bump"] {
            for interaction in ["min", "latest", "convex"] {
                let text = format!(
                    "[shape]\nkind = \"{shape}\"\n[interaction]\nkind = \"{interaction}\"\n[path]\nkind = \"parallel\"\nangle_deg = 20.0\n"
                );
                let c = super::super::config::MillingConfig::from_toml(&text, "test").unwrap();
                f(
                    shape,
                    interaction,
                    RingModel::new(&c, 5),
                    super::super::path::ToolPath::new(&c),
                );
            }
        }
    }

    #[test]
    fn hashed_normals_have_unit_variance_and_are_truncated() {
        let n = 200_000u32;
        let t = inv_cdf_table();
        let zs: Vec<f64> = (0..n)
            .map(|i| normal(t, hash_cell(3, i as i64, 0, 0)[0]))
            .collect();
        let mean = zs.iter().sum::<f64>() / n as f64;
        let var = zs.iter().map(|z| (z - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0).abs() < 0.02, "variance {var}");
        assert!(zs.iter().all(|z| z.abs() <= TRUNCATE_SIGMA));
    }

    /// The row fold (AVX2 where the CPU has it, see `super::super::simd`), its scalar
    /// twin [`SpanRing::point`] (the path of CPUs without AVX2) and the point path
    /// ([`Drawn::value`] and the interaction's step) give the same f64 bits, for every
    /// shape × interaction, rows of every length mod 4, across each ring, from values
    /// so far that include ±0. (The fill test compares f32 heights; this compares f64.)
    #[test]
    fn row_folds_equal_point_values_in_f64_bits() {
        let (lut, noise_q, noise_pad) = tables();
        let lut: &[f32; SHAPE_LUT] = lut[..].try_into().unwrap();
        let (mut covered, mut total) = (0usize, 0usize);
        each_shape_and_interaction(|shape, interaction, m, path| {
            for id in 0..12i64 {
                let d = m.drawn(&path.nominal((id % 3, id)), false);
                let (lo, hi) = m.support_radii(&d).unwrap();
                let mut k = m.span_ring(&d);
                let mut state = (id as u64 + 1) * 0x9E37_79B9_7F4A_7C15;
                for row in 0..40 {
                    let y = d.centre.1 - hi + 2.0 * hi * (row as f64 + 0.5) / 40.0;
                    k.set_row(y);
                    // 37 + row % 4 points over the right-hand run of the annulus on
                    // this row, a little beyond it at both ends.
                    let dy2 = (y - d.centre.1).powi(2);
                    let (a, b) = ((lo * lo - dy2).max(0.0).sqrt(), (hi * hi - dy2).sqrt());
                    let n = 37 + row % 4;
                    let xs: Vec<f64> = (0..n)
                        .map(|i| d.centre.0 + a - 0.02 + (b - a + 0.04) * i as f64 / n as f64)
                        .collect();
                    let f0: Vec<f64> = (0..n)
                        .map(|i| {
                            state ^= state << 13;
                            state ^= state >> 7;
                            state ^= state << 17;
                            match i % 5 {
                                0 => 0.0,
                                1 => -0.0,
                                _ => (state >> 11) as f64 / (1u64 << 53) as f64 * 10.0 - 5.0,
                            }
                        })
                        .collect();
                    let mut simd = f0.clone();
                    k.fold(&xs, &mut simd, lut, &noise_pad);
                    for i in 0..n {
                        let scalar = k.point(xs[i], f0[i], lut, &noise_pad);
                        let want = match d.value(&m, xs[i], y, lut, &noise_q) {
                            Some(v) => {
                                covered += 1;
                                match m.interaction {
                                    InteractionKind::Min => fold_min(f0[i], v.r),
                                    InteractionKind::Latest => v.r,
                                    InteractionKind::Convex => v.a * v.r + (1.0 - v.a) * f0[i],
                                }
                            }
                            None => f0[i],
                        };
                        total += 1;
                        assert_eq!(
                            (simd[i].to_bits(), scalar.to_bits()),
                            (want.to_bits(), want.to_bits()),
                            "{shape} {interaction} ring {id} row {row} point {i}: row fold {}, scalar {scalar}, point {want}",
                            simd[i]
                        );
                    }
                }
            }
        });
        assert!(
            covered > total / 4,
            "only {covered} of {total} points covered"
        );
    }

    /// A [`Group`] of four different rings evaluated at a point, four lanes per
    /// instruction where the CPU has AVX2 and lane by lane by the scalar twin, gives
    /// each ring's [`Drawn::value`] in f64 bits, for every shape × interaction, at
    /// points spread over the rings' supports (and off them); a padding lane
    /// ([`SpanRing::covering_nothing`]) covers nothing.
    #[test]
    fn groups_equal_their_rings_in_f64_bits() {
        use super::super::simd::{PointLanes, Scalar};
        let (lut, noise_q, noise_pad) = tables();
        let lut: &[f32; SHAPE_LUT] = lut[..].try_into().unwrap();
        let (mut covered, mut total) = (0usize, 0usize);
        let mut u = uniform(0x9E37_79B9_7F4A_7C15);
        each_shape_and_interaction(|shape, interaction, m, path| {
            for id in 0..8i64 {
                // Four neighbouring rings of two lines; the last lane padding in
                // every other group.
                let ds = [0, 1, 2, 3].map(|q| m.drawn(&path.nominal((id + q, q % 2)), false));
                let ks = ds.map(|d| m.span_ring(&d));
                let pad = ks[3].covering_nothing();
                let last = if id % 2 == 0 { &pad } else { &ks[3] };
                let g = Group::from_rings([&ks[0], &ks[1], &ks[2], last]);
                for _ in 0..300 {
                    // A point on or near the support of one of the rings.
                    let d = &ds[(u() * 4.0) as usize % 4];
                    let (lo, hi) = m.support_radii(d).unwrap();
                    let radius = lo - 0.05 + (hi - lo + 0.1) * u();
                    let angle = std::f64::consts::TAU * u();
                    let (x, y) = (
                        d.centre.0 + radius * angle.cos(),
                        d.centre.1 + radius * angle.sin(),
                    );
                    let scalar = Scalar.group_at(&g, m.kind(), (x, y), lut, &noise_pad);
                    #[cfg(target_arch = "x86_64")]
                    if let Some(avx2) = super::super::simd::Avx2::detect() {
                        let wide = avx2.group_at(&g, m.kind(), (x, y), lut, &noise_pad);
                        assert_eq!(
                            (wide.0, wide.1.map(f64::to_bits), wide.2.map(f64::to_bits)),
                            (
                                scalar.0,
                                scalar.1.map(f64::to_bits),
                                scalar.2.map(f64::to_bits)
                            ),
                            "{shape} {interaction} rings {id}.. at ({x}, {y})"
                        );
                    }
                    for (q, d) in ds.iter().enumerate() {
                        let want = if q == 3 && id % 2 == 0 {
                            None
                        } else {
                            d.value(&m, x, y, lut, &noise_q)
                        };
                        let got = (scalar.0 >> q & 1 != 0).then_some((scalar.1[q], scalar.2[q]));
                        total += 1;
                        covered += want.is_some() as usize;
                        assert_eq!(
                            got.map(|(v, a)| (v.to_bits(), a.to_bits())),
                            want.map(|w| (w.r.to_bits(), w.a.to_bits())),
                            "{shape} {interaction} ring {} lane {q} at ({x}, {y})",
                            id + q as i64
                        );
                    }
                }
            }
        });
        assert!(
            covered > total / 8,
            "only {covered} of {total} lane values covered"
        );
    }

    #[test]
    fn fast_atan2_agrees_with_libm() {
        for k in 0..10_000 {
            let a = k as f64 * 0.000_628_3 - std::f64::consts::PI;
            let (y, x) = (a.sin() * 3.7, a.cos() * 3.7);
            let want = y.atan2(x) / std::f64::consts::TAU;
            assert!((atan2_turns(y, x) - want).abs() < 3e-6, "angle {a}");
        }
        assert_eq!(atan2_turns(0.0, 0.0), 0.0);
    }

    /// The profiles are the sum of sines they claim to be, within the table's
    /// interpolation error.
    #[test]
    fn noise_profiles_are_bounded_and_not_flat() {
        let p = noise_profiles(50.0, 50.0, 1);
        assert!(p.iter().all(|v| v.abs() <= 1.0));
        let rms = (p.iter().map(|v| (*v as f64).powi(2)).sum::<f64>() / p.len() as f64).sqrt();
        // Mean of λ sines of random phase: rms ≈ 1/√(2λ) = 0.1.
        assert!((0.07..0.14).contains(&rms), "rms {rms}");
    }
}
