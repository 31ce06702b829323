//! Rugged surfaces by stochastic midpoint displacement (seed 001, [Procedure 1]): broken
//! rock and unglazed china (eq. 5) and metallic casting (eq. 7), as an endless, lazy
//! [`Surface`].
//!
//! The paper fills one square patch: heights at its four corners, then level by level
//! every edge midpoint is the mean of the edge's two ends plus a displacement, and every
//! square's centre the mean of its four corners plus one, until the squares are one
//! pixel wide. Here (ALGORITHMS.md §7):
//!
//! - level 0 is an endless lattice of spacing 2^L pixels whose corners have hashed heights
//!   g·S⁽⁰⁾;
//! - level n (1 ≤ n ≤ L) halves the spacing: edge midpoints and square centres get
//!   g·S⁽ⁿ⁾ with S⁽ⁿ⁾ = S⁽ⁿ⁻¹⁾·(½)ʰ (eq. 6) and g uniform in [−½, ½], drawn from the
//!   hash of (seed, level, point), not from a generator's sequence;
//! - a new point depends only on the corners of its square at the level before, so a
//!   height needs the four corners of one square per level: O(L) per sample, the same
//!   at x = 10¹² as at 0. A region fill computes each level once over the region (plus
//!   the enclosing squares) and shares every parent among its children.
//!
//! With `smooth` (the `rock` and `china` presets), eq. (5) takes new points from the
//! 4-point interpolating rule (Dyn, Levin & Gregory 1987) instead of two-point means:
//! the paper's rule leaves the surface piecewise linear between coarse lattice lines,
//! whose slope jumps shading shows as square blocks; the 4-point rule's limit is C¹.
//! A point then reads parents 1.5 spacings around, so `height()` computes small
//! windows per level instead of one square (about 20× slower); fills barely change.
//!
//! [`FractalSurface::eager_grid`] is the slow twin: the whole-grid recursion over a
//! block of patches, level by level over a dense grid. Between lattice points the surface is
//! bilinear (the finest squares are one pixel); heights are in the units of the
//! amplitude S⁽⁰⁾ (`amplitude`, default 1).

use std::ops::Range;

use crate::error::{Error, MAX_PARAMETER, Result, positive_param, short};
use crate::hash::{hash_tile_keyed, pcg4d};
use crate::stream::{Region, Surface, fill_rows_by_sample, in_range};

/// How a midpoint is displaced.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FractalKind {
    /// Eq. (5): f_M = (f_R + f_L)/2 + g·S⁽ⁿ⁾ (broken rock, unglazed china).
    Rock,
    /// Eq. (7): f_M = (f_R + f_L)/2 + |f_R − f_L|·g·S⁽ⁿ⁾: the midpoint stays between its
    /// ends, so equal ends stay flat (the flat patches and coast-line curves of cast
    /// aluminium). A square's centre is scaled by (max − min) of its four corners, the
    /// natural extension the paper leaves unstated.
    Casting,
}

impl std::fmt::Display for FractalKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            FractalKind::Rock => "rock",
            FractalKind::Casting => "casting",
        })
    }
}

/// Parameters of a midpoint-displacement surface (in a model `.toml`, the `[fractal]`
/// table; keys left out keep their defaults).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FractalParams {
    /// Self-similarity h ∈ (0, 1] (eq. 6): each level's displacements are (½)ʰ of the
    /// level before. Small h: rough; h = 1: smoothest.
    pub h: f64,
    /// L: the coarsest lattice has a spacing of 2^L pixels (1 ≤ L ≤ 24); beyond that
    /// scale corners are independent.
    pub levels: u32,
    /// Eq. (5) or eq. (7).
    pub kind: FractalKind,
    /// S⁽⁰⁾, the displacement scale of the coarsest lattice, in height units (> 0).
    pub amplitude: f64,
    /// Eq. (5) with the 4-point rule instead of the paper's two-point means: no creases
    /// along the lattice lines (see `rule_edge`), at about 20× the cost of a single
    /// `height()` (region fills barely change). Default false (the paper's rule); the
    /// `rock` and `china` presets set it. Ignored by eq. (7).
    pub smooth: bool,
}

impl Default for FractalParams {
    fn default() -> Self {
        FractalParams {
            h: 0.7,
            levels: 8,
            kind: FractalKind::Rock,
            amplitude: 1.0,
            smooth: false,
        }
    }
}

impl FractalParams {
    /// Checks every parameter, naming the first one out of range.
    pub fn validate(&self) -> Result<()> {
        if !(self.h > 0.0 && self.h <= 1.0) {
            return Err(Error::param(
                "h",
                self.h,
                "a self-similarity in (0, 1]: at h ≤ 0 the displacements never shrink, so \
                 the recursion does not converge to a surface, and above 1 it is no longer \
                 a fractal (its dimension 3 − h would fall below 2)",
            ));
        }
        if !(1..=24).contains(&self.levels) {
            return Err(Error::param(
                "levels",
                self.levels,
                "1 to 24 levels (a coarsest lattice of 2 to 2²⁴ pixels)",
            ));
        }
        positive_param(
            "amplitude",
            self.amplitude,
            "a positive, finite displacement scale S⁽⁰⁾",
        )?;
        if self.kind == FractalKind::Casting {
            let bound = self.casting_bound();
            if !bound.is_finite() || bound > MAX_PARAMETER {
                return Err(Error::param(
                    "amplitude",
                    short(self.amplitude),
                    format!(
                        "for casting, an S⁽⁰⁾ whose heights stay within 1e30: eq. (7) scales each level's displacement by the range of its parents, so heights can grow to S⁽⁰⁾·(½ + Π(1 + S⁽ⁿ⁾)) = {} here (h = {}, levels = {})",
                        short(bound),
                        self.h,
                        self.levels
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The largest |height| eq. (7) can reach: corners within ±S⁽⁰⁾/2, and each level n
    /// widens the range of its parents by at most the factor 1 + S⁽ⁿ⁾ (|g| < ½ on
    /// either side), so heights stay within S⁽⁰⁾·(½ + Π_{n=1..L}(1 + S⁽ⁿ⁾)).
    fn casting_bound(&self) -> f64 {
        let q = 0.5f64.powf(self.h);
        let (mut s, mut product) = (self.amplitude, 1.0f64);
        for _ in 1..=self.levels {
            s *= q;
            product *= 1.0 + s;
        }
        self.amplitude * (0.5 + product)
    }
}

/// Eq. (5) or (7) for an edge midpoint between `a` and `b`, with uniform `g` and scale `s`.
#[inline(always)]
fn edge(kind: FractalKind, a: f64, b: f64, g: f64, s: f64) -> f64 {
    let mean = (a + b) * 0.5;
    match kind {
        FractalKind::Rock => mean + g * s,
        FractalKind::Casting => mean + (a - b).abs() * g * s,
    }
}

/// [Procedure 1] step (4) for a square's centre from its corners [c00, c10, c01, c11]
/// (x first): the mean plus g·S⁽ⁿ⁾, scaled for casting by (max − min) of the corners.
#[inline(always)]
fn centre(kind: FractalKind, c: [f64; 4], g: f64, s: f64) -> f64 {
    let mean = ((c[0] + c[1]) + (c[2] + c[3])) * 0.25;
    match kind {
        FractalKind::Rock => mean + g * s,
        FractalKind::Casting => {
            let range = c[0].max(c[1]).max(c[2]).max(c[3]) - c[0].min(c[1]).min(c[2]).min(c[3]);
            mean + range * g * s
        }
    }
}

/// The 4-point interpolating subdivision (Dyn, Levin & Gregory 1987): weights of the
/// parents 3, 1, 1 and 3 half-spacings away from a new point.
const SMOOTH: [f64; 4] = [-1.0 / 16.0, 9.0 / 16.0, 9.0 / 16.0, -1.0 / 16.0];

/// Level-0 squares the slow twin grows its block by on every side.
const TWIN_MARGIN: usize = 3;

/// A new point on a lattice line from its parents along that line, `taps` 3, 1, 1 and 3
/// half-spacings away. Eq. (5) (rock, china): the 4-point mean plus g·S⁽ⁿ⁾. The paper
/// takes the mean of the two nearest: the surface is then piecewise linear between the
/// coarse lattice lines at every scale, its slope jumps across them, and shading shows
/// the squares as creases (the `china` preset: second differences on lattice columns
/// 1.8–2.0× the median). The 4-point rule's limit is C¹, so nothing marks the lines
/// (`lattice_lines_carry_no_creases`). Eq. (7) (casting) keeps the paper's two-point
/// mean: its midpoint must stay between its ends.
#[inline(always)]
fn rule_edge(kind: FractalKind, smooth: bool, taps: [f64; 4], g: f64, s: f64) -> f64 {
    match kind {
        FractalKind::Rock if smooth => {
            (SMOOTH[0] * taps[0] + SMOOTH[1] * taps[1])
                + (SMOOTH[2] * taps[2] + SMOOTH[3] * taps[3])
                + g * s
        }
        _ => edge(kind, taps[1], taps[2], g, s),
    }
}

/// A square's centre from the 4 × 4 parents around it (`taps[b][a]`, x = a): the
/// tensor 4-point rule for eq. (5), the paper's four corners for eq. (7).
#[inline(always)]
fn rule_centre(kind: FractalKind, smooth: bool, taps: [[f64; 4]; 4], g: f64, s: f64) -> f64 {
    match kind {
        FractalKind::Rock if smooth => {
            let rows = taps.map(|r| {
                (SMOOTH[0] * r[0] + SMOOTH[1] * r[1]) + (SMOOTH[2] * r[2] + SMOOTH[3] * r[3])
            });
            (SMOOTH[0] * rows[0] + SMOOTH[1] * rows[1])
                + (SMOOTH[2] * rows[2] + SMOOTH[3] * rows[3])
                + g * s
        }
        _ => centre(kind, [taps[1][1], taps[1][2], taps[2][1], taps[2][2]], g, s),
    }
}

/// ⌊a / 2^k⌋ and ⌈a / 2^k⌉ for any sign.
#[inline(always)]
fn floor_shr(a: i64, k: u32) -> i64 {
    a >> k
}

#[inline(always)]
fn ceil_shr(a: i64, k: u32) -> i64 {
    -((-a) >> k)
}

/// An endless midpoint-displacement surface (seed 001, [Procedure 1] and eq. 7).
#[derive(Clone, Debug)]
pub struct FractalSurface {
    params: FractalParams,
    seed: u32,
    /// S⁽ⁿ⁾ for n = 0..=L.
    scale: Vec<f64>,
    /// The hash key of each level.
    keys: Vec<u32>,
}

impl FractalSurface {
    /// The surface of `params` (validated here) with placement seed `seed`.
    pub fn new(params: FractalParams, seed: u32) -> Result<FractalSurface> {
        params.validate()?;
        let l = params.levels as usize;
        let q = 0.5f64.powf(params.h);
        let mut scale = vec![params.amplitude; l + 1];
        for n in 1..=l {
            scale[n] = scale[n - 1] * q;
        }
        let keys = (0..=l as u32)
            .map(|n| pcg4d([seed, n, 0x5EED_F4AC, 0x001])[0])
            .collect();
        Ok(FractalSurface {
            params,
            seed,
            scale,
            keys,
        })
    }

    /// The parameters.
    pub fn params(&self) -> FractalParams {
        self.params
    }

    /// The placement seed.
    pub fn seed(&self) -> u32 {
        self.seed
    }

    /// g ∈ (−½, ½) of the point created at level `n` at pixel (x, y): 24 hashed bits.
    #[inline(always)]
    fn g(&self, n: usize, x: i64, y: i64) -> f64 {
        let h = hash_tile_keyed(self.keys[n], x, y);
        ((h >> 8) as f64 + 0.5) * (1.0 / (1u64 << 24) as f64) - 0.5
    }

    /// The height of lattice point (x, y) of level 0 (a corner of the coarsest lattice,
    /// x and y multiples of 2^L).
    #[inline(always)]
    fn corner(&self, x: i64, y: i64) -> f64 {
        self.g(0, x, y) * self.scale[0]
    }

    /// The lazy evaluation: the corners [c00, c10, c01, c11] of the level-`m` square
    /// (side 2^(L−m)) that contains pixel (x, y), and that square's origin. The paper's
    /// rule descends one square per level; the smooth rule computes the windows of
    /// parents its stencil reads (up to 7 × 7 per level: about 20× the cost).
    #[inline]
    fn square(&self, x: i64, y: i64, m: usize) -> ([f64; 4], i64, i64) {
        if !self.smooth() {
            return self.square_paper(x, y, m);
        }
        let k = self.params.levels - m as u32;
        let (i, j) = (floor_shr(x, k), floor_shr(y, k));
        let c = self.lattice(m as u32, i, i + 1, j, j + 1);
        ([c[0], c[1], c[2], c[3]], i << k, j << k)
    }

    /// [`FractalSurface::square`] for the paper's two-point rule: the corners of the
    /// level-`m` square that contains pixel (x, y), and its origin. Descends
    /// from the level-0 square: at each level only the three new points of the quadrant
    /// holding (x, y) are made (an edge midpoint on each of its two inner sides, and the
    /// centre); its fourth corner is the parent's.
    #[inline]
    fn square_paper(&self, x: i64, y: i64, m: usize) -> ([f64; 4], i64, i64) {
        let l = self.params.levels;
        let kind = self.params.kind;
        let (mut ox, mut oy) = (floor_shr(x, l) << l, floor_shr(y, l) << l);
        let side0 = 1i64 << l;
        let mut c = [
            self.corner(ox, oy),
            self.corner(ox + side0, oy),
            self.corner(ox, oy + side0),
            self.corner(ox + side0, oy + side0),
        ];
        for n in 1..=m {
            let half = 1i64 << (l - n as u32);
            let s = self.scale[n];
            let qx = (x >= ox + half) as usize;
            let qy = (y >= oy + half) as usize;
            // The midpoint of the horizontal edge on row qy, of the vertical edge on
            // column qx, and the centre.
            let hm = edge(
                kind,
                c[2 * qy],
                c[2 * qy + 1],
                self.g(n, ox + half, oy + 2 * half * qy as i64),
                s,
            );
            let vm = edge(
                kind,
                c[qx],
                c[qx + 2],
                self.g(n, ox + 2 * half * qx as i64, oy + half),
                s,
            );
            let ce = centre(kind, c, self.g(n, ox + half, oy + half), s);
            // Corner (a, b) of the quadrant lies at (qx + a, qy + b) half-steps from
            // the parent's origin: even/even is a parent corner, odd x an edge of a
            // row, odd y an edge of a column, odd/odd the centre.
            let pc = c[qx + 2 * qy];
            let vals = [pc, hm, vm, ce];
            let pick = |a: usize, b: usize| vals[((qx + a) & 1) | (((qy + b) & 1) << 1)];
            c = [pick(0, 0), pick(1, 0), pick(0, 1), pick(1, 1)];
            ox += half * qx as i64;
            oy += half * qy as i64;
        }
        (c, ox, oy)
    }

    /// Whether eq. (5) takes the 4-point rule (see [`FractalParams::smooth`]).
    #[inline(always)]
    fn smooth(&self) -> bool {
        self.params.smooth && self.params.kind == FractalKind::Rock
    }

    /// The surface at (x, y) with the recursion stopped at level `m`: bilinear in the
    /// level-m square that holds the point.
    #[inline]
    fn at_level(&self, x: f64, y: f64, m: usize) -> f64 {
        let (xf, yf) = (x.floor(), y.floor());
        let (c, ox, oy) = self.square(xf as i64, yf as i64, m);
        let (fx, fy) = if m == self.params.levels as usize {
            (x - xf, y - yf)
        } else {
            let side = (1i64 << (self.params.levels - m as u32)) as f64;
            ((x - ox as f64) / side, (y - oy as f64) / side)
        };
        bilinear(c, fx, fy)
    }

    /// The slow twin: the whole-grid recursion over `cells_w × cells_h` level-0 squares
    /// starting at square (cell_x, cell_y), level by level over a dense grid of pixels
    /// (every point of a level from the whole previous level). The smooth rule reads
    /// parents up to 1.5 of their spacings away, so the recursion runs over the block
    /// grown by [`TWIN_MARGIN`] squares on every side (the values it cannot complete
    /// stay NaN and never reach the block: the gap they leave is below 3·2^L pixels)
    /// and returns the block. Returns the (cells_w·2^L + 1) × (cells_h·2^L + 1) lattice
    /// heights, row-major, x first.
    pub fn eager_grid(&self, cell_x: i64, cell_y: i64, cells_w: usize, cells_h: usize) -> Vec<f64> {
        let l = self.params.levels;
        let kind = self.params.kind;
        let smooth = self.smooth();
        let side0 = 1usize << l;
        let mg = TWIN_MARGIN;
        let (bw, bh) = (
            (cells_w + 2 * mg) * side0 + 1,
            (cells_h + 2 * mg) * side0 + 1,
        );
        let (x0, y0) = ((cell_x - mg as i64) << l, (cell_y - mg as i64) << l);
        let mut f = vec![f64::NAN; bw * bh];
        for j in (0..bh).step_by(side0) {
            for i in (0..bw).step_by(side0) {
                f[j * bw + i] = self.corner(x0 + i as i64, y0 + j as i64);
            }
        }
        for n in 1..=l as usize {
            let half = side0 >> n;
            let s = self.scale[n];
            let prev = f.clone();
            // The previous level's value `d` parent spacings from pixel (i, j) along
            // each axis, NaN off the grid.
            let at = |i: usize, j: usize, dx: i64, dy: i64| {
                let (pi, pj) = (i as i64 + dx * half as i64, j as i64 + dy * half as i64);
                if pi < 0 || pj < 0 || pi >= bw as i64 || pj >= bh as i64 {
                    f64::NAN
                } else {
                    prev[pj as usize * bw + pi as usize]
                }
            };
            for j in (0..bh).step_by(half) {
                for i in (0..bw).step_by(half) {
                    let (oi, oj) = ((i / half) % 2 == 1, (j / half) % 2 == 1);
                    let g = self.g(n, x0 + i as i64, y0 + j as i64);
                    let v = match (oi, oj) {
                        (false, false) => continue,
                        (true, false) => {
                            let taps = [-3, -1, 1, 3].map(|d| at(i, j, d, 0));
                            rule_edge(kind, smooth, taps, g, s)
                        }
                        (false, true) => {
                            let taps = [-3, -1, 1, 3].map(|d| at(i, j, 0, d));
                            rule_edge(kind, smooth, taps, g, s)
                        }
                        (true, true) => {
                            let mut taps = [[0.0; 4]; 4];
                            for (b, row) in taps.iter_mut().enumerate() {
                                for (a, t) in row.iter_mut().enumerate() {
                                    *t = at(i, j, 2 * a as i64 - 3, 2 * b as i64 - 3);
                                }
                            }
                            rule_centre(kind, smooth, taps, g, s)
                        }
                    };
                    f[j * bw + i] = v;
                }
            }
        }
        let (w, h) = (cells_w * side0 + 1, cells_h * side0 + 1);
        let (ox, oy) = (mg * side0, mg * side0);
        (0..h)
            .flat_map(|j| (0..w).map(move |i| (i, j)))
            .map(|(i, j)| f[(oy + j) * bw + ox + i])
            .collect()
    }

    /// The finest lattice heights over pixels [x0, x0 + w) × [y0, y0 + h).
    fn window(&self, x0: i64, y0: i64, w: usize, h: usize) -> Vec<f64> {
        self.lattice(
            self.params.levels,
            x0,
            x0 + w as i64 - 1,
            y0,
            y0 + h as i64 - 1,
        )
    }

    /// The level-`n` lattice heights over indices [i0, i1] × [j0, j1] (spacing
    /// 2^(L−n) px), row-major: from the level before over the indices its rule reads
    /// (1.5 parent spacings around), each point made once and shared by its children.
    fn lattice(&self, n: u32, i0: i64, i1: i64, j0: i64, j1: i64) -> Vec<f64> {
        let l = self.params.levels;
        if n == 0 {
            return (j0..=j1)
                .flat_map(|j| (i0..=i1).map(move |i| (i, j)))
                .map(|(i, j)| self.corner(i << l, j << l))
                .collect();
        }
        let kind = self.params.kind;
        let smooth = self.smooth();
        let k = l - n;
        let s = self.scale[n as usize];
        let reach = if self.smooth() { 3 } else { 1 };
        let (pi0, pi1, pj0, pj1) = (
            floor_shr(i0 - reach, 1),
            ceil_shr(i1 + reach, 1),
            floor_shr(j0 - reach, 1),
            ceil_shr(j1 + reach, 1),
        );
        let parents = self.lattice(n - 1, pi0, pi1, pj0, pj1);
        let pw = (pi1 - pi0 + 1) as usize;
        // Parent at level-n indices (i, j), both even.
        let parent =
            |i: i64, j: i64| parents[((j / 2 - pj0) as usize) * pw + (i / 2 - pi0) as usize];
        let mut out = Vec::with_capacity(((i1 - i0 + 1) * (j1 - j0 + 1)) as usize);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let g = || self.g(n as usize, i << k, j << k);
                let v = match (i & 1, j & 1) {
                    (0, 0) => parent(i, j),
                    (1, 0) if !smooth => edge(kind, parent(i - 1, j), parent(i + 1, j), g(), s),
                    (0, 1) if !smooth => edge(kind, parent(i, j - 1), parent(i, j + 1), g(), s),
                    (1, 1) if !smooth => centre(
                        kind,
                        [
                            parent(i - 1, j - 1),
                            parent(i + 1, j - 1),
                            parent(i - 1, j + 1),
                            parent(i + 1, j + 1),
                        ],
                        g(),
                        s,
                    ),
                    (1, 0) => {
                        rule_edge(kind, true, [-3, -1, 1, 3].map(|d| parent(i + d, j)), g(), s)
                    }
                    (0, _) => {
                        rule_edge(kind, true, [-3, -1, 1, 3].map(|d| parent(i, j + d)), g(), s)
                    }
                    _ => {
                        let mut taps = [[0.0; 4]; 4];
                        for (b, row) in taps.iter_mut().enumerate() {
                            for (a, t) in row.iter_mut().enumerate() {
                                *t = parent(i + 2 * a as i64 - 3, j + 2 * b as i64 - 3);
                            }
                        }
                        rule_centre(kind, true, taps, g(), s)
                    }
                };
                out.push(v);
            }
        }
        out
    }
}

/// Bilinear interpolation of corners [c00, c10, c01, c11] at (fx, fy) ∈ [0, 1]²: exact
/// at the corners.
#[inline(always)]
fn bilinear(c: [f64; 4], fx: f64, fy: f64) -> f64 {
    let bottom = c[0] + (c[1] - c[0]) * fx;
    let top = c[2] + (c[3] - c[2]) * fx;
    bottom + (top - bottom) * fy
}

impl Surface for FractalSurface {
    fn channels(&self) -> usize {
        1
    }

    /// Footprints above 1 pixel stop the recursion at the level whose squares are about
    /// the footprint's size (the finer displacements, which a wide footprint would
    /// average away, are left out).
    fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
        if !in_range(x, y) {
            out[0] = f32::NAN;
            return;
        }
        let l = self.params.levels as usize;
        let m = if footprint.is_nan() || footprint <= 1.0 {
            l
        } else {
            l - (footprint.log2().floor() as usize).min(l)
        };
        out[0] = self.at_level(x, y, m) as f32;
    }

    #[inline]
    fn height(&self, x: f64, y: f64) -> f32 {
        if !in_range(x, y) {
            return f32::NAN;
        }
        self.at_level(x, y, self.params.levels as usize) as f32
    }

    /// Step-1 rows from one `Self::window` over the band (plus one column and row for
    /// the bilinear), each sample with the point path's arithmetic, so the bits equal
    /// `height()`'s; other steps sample point by point.
    fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
        if region.step != 1.0 || rows.is_empty() {
            return fill_rows_by_sample(self, region, rows, out);
        }
        let (xa, ya) = (region.x_at(0), region.y_at(rows.start));
        let (xb, yb) = (region.x_at(region.width - 1), region.y_at(rows.end - 1));
        if !(in_range(xa, ya) && in_range(xb, yb)) {
            return fill_rows_by_sample(self, region, rows, out);
        }
        let (x0, y0) = (xa.floor() as i64, ya.floor() as i64);
        let (w, h) = (
            (xb.floor() as i64 - x0 + 2) as usize,
            (yb.floor() as i64 - y0 + 2) as usize,
        );
        let grid = self.window(x0, y0, w, h);
        for (r, row) in rows.enumerate() {
            let y = region.y_at(row);
            let yf = y.floor();
            let (gy, fy) = ((yf as i64 - y0) as usize, y - yf);
            let line = &mut out[r * region.width..(r + 1) * region.width];
            for (col, o) in line.iter_mut().enumerate() {
                let x = region.x_at(col);
                let xf = x.floor();
                let (gx, fx) = ((xf as i64 - x0) as usize, x - xf);
                let p = gy * w + gx;
                let c = [grid[p], grid[p + 1], grid[p + w], grid[p + w + 1]];
                *o = bilinear(c, fx, fy) as f32;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn surface(kind: FractalKind, h: f64, levels: u32, seed: u32) -> FractalSurface {
        smooth_surface(kind, false, h, levels, seed)
    }

    fn smooth_surface(
        kind: FractalKind,
        smooth: bool,
        h: f64,
        levels: u32,
        seed: u32,
    ) -> FractalSurface {
        FractalSurface::new(
            FractalParams {
                h,
                levels,
                kind,
                amplitude: 1.0,
                smooth,
            },
            seed,
        )
        .unwrap()
    }

    /// Lazy equals eager: every lattice point of a 3 × 2 block of level-0 squares at
    /// negative coordinates, from `height()` and from a region fill, is the whole-grid
    /// recursion's value bit for bit, for rock (the paper's rule and the smooth one)
    /// and casting.
    #[test]
    fn lazy_heights_equal_the_whole_grid_recursion() {
        for (kind, smooth) in [
            (FractalKind::Rock, false),
            (FractalKind::Rock, true),
            (FractalKind::Casting, false),
        ] {
            let s = smooth_surface(kind, smooth, 0.6, 5, 9);
            let (cx, cy, cw, ch) = (-2i64, -7i64, 3usize, 2usize);
            let grid = s.eager_grid(cx, cy, cw, ch);
            let (w, h) = (cw * 32 + 1, ch * 32 + 1);
            assert!(grid.iter().all(|v| v.is_finite()), "eager grid incomplete");
            let (x0, y0) = ((cx * 32) as f64, (cy * 32) as f64);
            let mut fill = vec![0.0f32; w * h];
            crate::stream::fill_parallel(&s, &Region::new(x0, y0, w, h), &mut fill, 2).unwrap();
            for j in 0..h {
                for i in 0..w {
                    let want = grid[j * w + i] as f32;
                    let lazy = s.height(x0 + i as f64, y0 + j as f64);
                    assert_eq!(
                        lazy.to_bits(),
                        want.to_bits(),
                        "{kind} height at ({i}, {j})"
                    );
                    assert_eq!(
                        fill[j * w + i].to_bits(),
                        want.to_bits(),
                        "{kind} fill at ({i}, {j})"
                    );
                }
            }
        }
    }

    /// Fills at fractional offsets, split into pieces, equal `height()` bit for bit.
    #[test]
    fn fills_equal_point_samples_at_fractional_offsets() {
        let s = surface(FractalKind::Casting, 0.8, 7, 3);
        let region = Region::new(-1000.25, 377.5, 300, 90);
        let mut out = vec![0.0f32; 300 * 90];
        crate::stream::fill_parallel(&s, &region, &mut out, 2).unwrap();
        for r in 0..90 {
            for c in 0..300 {
                let want = s.height(region.x_at(c), region.y_at(r));
                assert_eq!(out[r * 300 + c].to_bits(), want.to_bits(), "({c}, {r})");
            }
        }
    }

    #[test]
    fn bad_parameters_are_refused_with_the_reason() {
        for h in [0.0, -0.5, 1.5, f64::NAN] {
            let p = FractalParams {
                h,
                ..Default::default()
            };
            let e = FractalSurface::new(p, 0).unwrap_err().to_string();
            assert!(
                e.contains("h") && e.contains("(0, 1]") && e.contains("converge"),
                "{e}"
            );
        }
        let e = FractalSurface::new(
            FractalParams {
                levels: 0,
                ..Default::default()
            },
            0,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("levels"), "{e}");
        let e = FractalSurface::new(
            FractalParams {
                amplitude: f64::INFINITY,
                ..Default::default()
            },
            0,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("amplitude"), "{e}");
    }

    /// Eq. (7) multiplies each level's displacement by its parents' range, so a large
    /// S⁽⁰⁾ overflows to ±inf (the fuzzer's `[fractal] kind = "casting", h = 1,
    /// amplitude = 42949672961` sampled −inf at (0.5, 0.25)). Such amplitudes are
    /// refused by their growth bound, and the bound holds on rendered heights.
    #[test]
    fn casting_amplitudes_that_overflow_are_refused_and_the_bound_holds() {
        let casting = |amplitude: f64, h: f64, levels: u32| FractalParams {
            kind: FractalKind::Casting,
            amplitude,
            h,
            levels,
            ..Default::default()
        };
        let e = FractalSurface::new(casting(42949672961.0, 1.0, 8), 0)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("invalid amplitude = 42949672961: expected for casting"),
            "{e}"
        );
        assert!(FractalSurface::new(casting(1e6, 0.7, 8), 0).is_err());
        for (a, h, levels) in [(1.0, 0.7, 8), (6.0, 0.3, 10), (100.0, 1.0, 8)] {
            let p = casting(a, h, levels);
            let bound = p.casting_bound();
            assert!(bound.is_finite() && bound <= MAX_PARAMETER);
            let s = FractalSurface::new(p, 3).unwrap();
            let mut v = vec![0.0f32; 256 * 256];
            s.fill(&Region::new(-1e6, 7.5, 256, 256), &mut v).unwrap();
            let top = v.iter().fold(0.0f32, |m, x| m.max(x.abs())) as f64;
            assert!(
                top.is_finite() && top <= bound,
                "S0 {a}: |h| {top} > bound {bound}"
            );
            assert!(top > 0.0);
        }
    }
}
