//! Tool paths (seed 000 §4.3): where ring centres lie, in which order they were milled,
//! and which of them can reach a point — found from the geometry, in O(1).

use super::config::{LineDirection, LineOrder, MillingConfig, Orientation, PathKind, Travel};

/// A tool path with its derived numbers (mm).
#[derive(Clone, Debug)]
pub enum ToolPath {
    /// Parallel lines at angle β, ρ apart, with centres δ apart (§4.3.1).
    Parallel {
        /// cos β.
        cos_b: f64,
        /// sin β.
        sin_b: f64,
        /// ρ.
        rho: f64,
        /// δ.
        delta: f64,
        /// ρ·tan β: line j's centres sit at s = iδ + j·ρ·tan β along it (the paper's
        /// c̄(i, j) written in path coordinates; 0 for β = ±90°).
        shift: f64,
        /// Lines milled in ascending j.
        ascending: bool,
        /// Alternate directions.
        zigzag: bool,
        /// Line 0 milled against β.
        reverse: bool,
    },
    /// An Archimedean spiral r = aφ (§4.3.2).
    Spiral {
        /// a = ρ/2π.
        a: f64,
        /// δ.
        delta: f64,
        /// Origin u.
        origin: (f64, f64),
        /// o = ±1.
        o: f64,
        /// β.
        beta: f64,
        /// Outward (true) or inward.
        outward: bool,
        /// Last ring index of a finite spiral.
        k_end: Option<i64>,
        /// φ_k of the first rings, [`spiral_angle`] computed once (the rings around the
        /// origin, where every point has many candidates).
        phis: std::sync::Arc<[f64]>,
    },
}

/// Rings of a spiral whose angles are tabulated: 2¹⁶ (512 KiB), a disc of radius
/// √(2·2¹⁶·δ·a), 129 mm for the 4 mm presets.
pub const SPIRAL_TABLE: usize = 1 << 16;

/// Arc length of the spiral r = aφ from 0 to φ (seed 000 §4.3.2).
#[inline(always)]
pub fn arc_length(a: f64, phi: f64) -> f64 {
    0.5 * a * (phi * (1.0 + phi * phi).sqrt() + phi.asinh())
}

/// φ_k with L(φ_k) = kδ, solved directly by Newton's method from the asymptotic
/// inverse of L (one or two steps far out), or from √(2kδ/a) near the origin, which
/// lies above the root because L(φ) ≥ aφ²/2. A pure function of k, so every caller (the index, the brute-force twin, the
/// GPU later) places ring k at the same point.
///
/// The paper takes one Newton step from φ_(k−1) instead, which is O(k) to reach ring k
/// and drifts from the exact root for small k (`paper_spiral_angles`).
pub fn spiral_angle(a: f64, delta: f64, k: i64) -> f64 {
    let s = k as f64 * delta;
    if s <= 0.0 {
        return 0.0;
    }
    let q = 2.0 * s / a;
    // L(φ) = (a/2)(φ² + ln 2φ + ½ + O(φ⁻²)) inverted once for large φ; √q bounds the
    // root from above elsewhere.
    let mut phi = if q > 16.0 {
        (q - (2.0 * q.sqrt()).ln() - 0.5).sqrt()
    } else {
        q.sqrt()
    };
    for _ in 0..60 {
        let step = (arc_length(a, phi) - s) / (a * (1.0 + phi * phi).sqrt());
        phi -= step;
        if step.abs() <= 1e-13 * phi.max(1.0) {
            break;
        }
    }
    phi
}

/// The paper's recursion: φ_(0) = 0 and one Newton step per ring from the previous
/// angle, φ_(k+1) = φ_(k) − (L(φ_(k)) − (k+1)·δ)/L′(φ_(k)), for k = 0..n, for comparison
/// with [`spiral_angle`]. (The closing formula of §4.3.2 prints kδ where the iteration
/// above it, φ_(k,0) = φ_(k−1), solves for kδ at ring k: with kδ every angle would stay 0.)
pub fn paper_spiral_angles(a: f64, delta: f64, n: usize) -> Vec<f64> {
    let mut phis = vec![0.0f64];
    for k in 0..n {
        let p = phis[k];
        phis.push(p - (arc_length(a, p) - (k + 1) as f64 * delta) / (a * (1.0 + p * p).sqrt()));
    }
    phis
}

/// The intervals of a line at distance² between r_in² and r_out² from a point of it at
/// `c`, where `in2` = r_in² − (distance of the line)² and `out2` = r_out² − (the same)
/// ≥ 0: one interval through c when the line misses the inner disc, two otherwise.
#[inline(always)]
pub(super) fn annulus_runs(c: f64, in2: f64, out2: f64, mut run: impl FnMut(f64, f64)) {
    let half_out = out2.sqrt();
    if in2 > 0.0 {
        let half_in = in2.sqrt();
        run(c - half_out, c - half_in);
        run(c + half_in, c + half_out);
    } else {
        run(c - half_out, c + half_out);
    }
}

/// A ring's nominal placement: id, centre, motion direction, (rank, position).
pub type Nominal = ((i64, i64), f64, f64, (f64, f64), (i64, i64));

impl ToolPath {
    /// The path of a validated configuration.
    pub fn new(c: &MillingConfig) -> ToolPath {
        let p = &c.path;
        let rho = (1.0 - p.overlap) * c.tool.diameter_mm;
        let beta = p.angle_deg.to_radians();
        match p.kind {
            PathKind::Parallel => {
                let (sin_b, cos_b) = beta.sin_cos();
                let shift = if cos_b.abs() < 1e-12 {
                    0.0
                } else {
                    rho * sin_b / cos_b
                };
                ToolPath::Parallel {
                    cos_b,
                    sin_b,
                    rho,
                    delta: p.step_mm,
                    shift,
                    ascending: p.line_order != Some(LineOrder::Descending),
                    zigzag: p.direction == Some(LineDirection::Zigzag),
                    reverse: p.reverse == Some(true),
                }
            }
            PathKind::Spiral => {
                let a = rho / std::f64::consts::TAU;
                let k_end = p
                    .radius_mm
                    .map(|r| (arc_length(a, r / a) / p.step_mm).floor() as i64);
                let n = k_end.map_or(SPIRAL_TABLE, |k| (k as usize + 1).min(SPIRAL_TABLE));
                let phis = (0..n)
                    .map(|k| spiral_angle(a, p.step_mm, k as i64))
                    .collect();
                ToolPath::Spiral {
                    phis,
                    a,
                    delta: p.step_mm,
                    origin: p.origin_mm.map_or((0.0, 0.0), |o| (o[0], o[1])),
                    o: if p.orientation == Some(Orientation::Cw) {
                        -1.0
                    } else {
                        1.0
                    },
                    beta,
                    outward: p.travel != Some(Travel::Inward),
                    k_end,
                }
            }
        }
    }

    /// True for the spiral.
    pub fn is_spiral(&self) -> bool {
        matches!(self, ToolPath::Spiral { .. })
    }

    /// Nominal centre of ring `id` (mm): the first part of [`Self::nominal`], all the
    /// index needs for the rings that turn out not to cover a point.
    #[inline(always)]
    pub fn centre(&self, id: (i64, i64)) -> (f64, f64) {
        match *self {
            ToolPath::Parallel {
                cos_b,
                sin_b,
                rho,
                delta,
                shift,
                ..
            } => {
                let (i, j) = id;
                let s = i as f64 * delta + j as f64 * shift;
                let t = j as f64 * rho;
                (s * cos_b - t * sin_b, s * sin_b + t * cos_b)
            }
            ToolPath::Spiral { .. } => {
                let n = self.nominal(id);
                (n.1, n.2)
            }
        }
    }

    /// Nominal placement of ring (i, j) (parallel) or (k, _) (spiral).
    #[inline(always)]
    pub fn nominal(&self, id: (i64, i64)) -> Nominal {
        match *self {
            ToolPath::Parallel {
                cos_b,
                sin_b,
                ascending,
                zigzag,
                reverse,
                ..
            } => {
                let (i, j) = id;
                let (cx, cy) = self.centre(id);
                let forward = (zigzag && j.rem_euclid(2) == 1) == reverse;
                let dir = if forward { 1i64 } else { -1 };
                let rank = if ascending { j } else { -j };
                (
                    id,
                    cx,
                    cy,
                    (dir as f64 * cos_b, dir as f64 * sin_b),
                    (rank, dir * i),
                )
            }
            ToolPath::Spiral {
                a,
                delta,
                origin,
                o,
                beta,
                outward,
                k_end,
                ref phis,
            } => {
                let k = id.0;
                let phi = match phis.get(k as usize) {
                    Some(&p) => p,
                    None => spiral_angle(a, delta, k),
                };
                let (sn, cs) = (phi + beta).sin_cos();
                let rad = a * phi;
                // d/dφ of (o·aφ·cos(φ+β), aφ·sin(φ+β)), reversed when travelling inwards.
                let (tx, ty) = (o * (cs - phi * sn), sn + phi * cs);
                let len = (tx * tx + ty * ty).sqrt();
                let sign = if outward { 1.0 } else { -1.0 } / len;
                let rank = if outward { k } else { k_end.unwrap_or(0) - k };
                (
                    id,
                    origin.0 + o * rad * cs,
                    origin.1 + rad * sn,
                    (tx * sign, ty * sign),
                    (rank, 0),
                )
            }
        }
    }

    /// Calls `visit` with every ring whose nominal centre lies in the annulus
    /// [reach_in, reach_out] around (x, y) (mm), and possibly a few more: the rings that
    /// can touch the point, found from the path's geometry (ALGORITHMS.md §5).
    #[inline(always)]
    pub fn candidates(
        &self,
        x: f64,
        y: f64,
        reach_in: f64,
        reach_out: f64,
        mut visit: impl FnMut((i64, i64)),
    ) {
        match *self {
            ToolPath::Parallel {
                cos_b,
                sin_b,
                rho,
                delta,
                shift,
                ..
            } => {
                let s = x * cos_b + y * sin_b;
                let t = -x * sin_b + y * cos_b;
                let j0 = ((t - reach_out) / rho).ceil() as i64;
                let j1 = ((t + reach_out) / rho).floor() as i64;
                for j in j0..=j1 {
                    let dt = t - j as f64 * rho;
                    let out2 = reach_out * reach_out - dt * dt;
                    if out2 < 0.0 {
                        continue;
                    }
                    let base = s - j as f64 * shift;
                    let in2 = reach_in * reach_in - dt * dt;
                    annulus_runs(base, in2, out2, |lo, hi| {
                        let i0 = (lo / delta).ceil() as i64;
                        let i1 = (hi / delta).floor() as i64;
                        for i in i0..=i1 {
                            visit((i, j));
                        }
                    });
                }
            }
            ToolPath::Spiral {
                a,
                delta,
                origin,
                o,
                beta,
                k_end,
                ..
            } => {
                let (qx, qy) = (o * (x - origin.0), y - origin.1);
                let rp = (qx * qx + qy * qy).sqrt();
                let phi_lo = ((rp - reach_out) / a).max(0.0);
                let phi_hi = (rp + reach_out) / a;
                let k_max = k_end.unwrap_or(i64::MAX);
                let mut run = |pa: f64, pb: f64| {
                    if pb < pa {
                        return;
                    }
                    let k0 = (arc_length(a, pa) / delta).ceil() as i64;
                    let k1 = ((arc_length(a, pb) / delta).floor() as i64).min(k_max);
                    for k in k0.max(0)..=k1 {
                        visit((k, 0));
                    }
                };
                if rp <= reach_out * 1.000_001 {
                    run(phi_lo, phi_hi);
                    return;
                }
                // Centres within reach_out of the point are within asin(R/ρ_p) of its
                // polar angle, on each turn.
                let half = (reach_out / rp).asin() + 1e-12;
                let psi = qy.atan2(qx) - beta;
                let tau = std::f64::consts::TAU;
                let n0 = ((phi_lo - psi - half) / tau).ceil() as i64;
                let n1 = ((phi_hi - psi + half) / tau).floor() as i64;
                for n in n0..=n1 {
                    let mid = psi + n as f64 * tau;
                    run((mid - half).max(phi_lo), (mid + half).min(phi_hi));
                }
            }
        }
    }

    /// Every ring of the finite path that can reach the rectangle [x0, x1] × [y0, y1]
    /// (mm), in no particular order: the brute-force twin's ring list.
    pub fn rings_reaching(
        &self,
        (x0, y0, x1, y1): (f64, f64, f64, f64),
        reach: f64,
    ) -> Vec<(i64, i64)> {
        let mut out = Vec::new();
        match *self {
            ToolPath::Parallel {
                cos_b,
                sin_b,
                rho,
                delta,
                shift,
                ..
            } => {
                let corners = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)];
                let ss = corners.map(|(x, y)| x * cos_b + y * sin_b);
                let ts = corners.map(|(x, y)| -x * sin_b + y * cos_b);
                let (smin, smax) = (
                    ss.iter().cloned().fold(f64::MAX, f64::min),
                    ss.iter().cloned().fold(f64::MIN, f64::max),
                );
                let (tmin, tmax) = (
                    ts.iter().cloned().fold(f64::MAX, f64::min),
                    ts.iter().cloned().fold(f64::MIN, f64::max),
                );
                let j0 = ((tmin - reach) / rho).floor() as i64 - 1;
                let j1 = ((tmax + reach) / rho).ceil() as i64 + 1;
                for j in j0..=j1 {
                    let i0 = ((smin - reach - j as f64 * shift) / delta).floor() as i64 - 1;
                    let i1 = ((smax + reach - j as f64 * shift) / delta).ceil() as i64 + 1;
                    out.extend((i0..=i1).map(|i| (i, j)));
                }
            }
            ToolPath::Spiral {
                a,
                delta,
                origin,
                k_end,
                ..
            } => {
                let far = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)]
                    .iter()
                    .map(|(x, y)| ((x - origin.0).powi(2) + (y - origin.1).powi(2)).sqrt())
                    .fold(0.0, f64::max);
                let k_max = (arc_length(a, (far + reach) / a) / delta).ceil() as i64 + 1;
                let k_max = k_max.min(k_end.unwrap_or(i64::MAX));
                out.extend((0..=k_max).map(|k| (k, 0)));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spiral_angles_solve_the_arc_length() {
        let (a, delta) = (2.0 / std::f64::consts::TAU, 0.4);
        for k in [0i64, 1, 2, 5, 100, 10_000, 1 << 30, 1 << 40] {
            let phi = spiral_angle(a, delta, k);
            let want = k as f64 * delta;
            assert!(
                (arc_length(a, phi) - want).abs() <= 1e-9 * want.max(1.0),
                "k = {k}: L(φ) = {} for {want}",
                arc_length(a, phi)
            );
        }
    }

    /// The paper's one-step recursion against the exact angles: the "tiny difference"
    /// (ALGORITHMS.md §5) is largest for the first rings and fades out.
    #[test]
    fn paper_recursion_drifts_only_near_the_origin() {
        let (a, delta) = (2.0 / std::f64::consts::TAU, 0.4);
        let paper = paper_spiral_angles(a, delta, 2000);
        let diff = |k: usize| {
            let e = spiral_angle(a, delta, k as i64);
            a * (paper[k] - e).abs() * e.max(1.0)
        };
        // In mm along the path: visible near the origin, negligible far out.
        assert!(diff(1) > 1e-3, "first ring {}", diff(1));
        assert!(diff(2000) < 1e-4, "ring 2000 {}", diff(2000));
    }
}
