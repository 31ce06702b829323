//! The generalized roller (seed 003): double toroidal tiles cut from an exemplar on any
//! integer lattice, and several tiles with identical borders.
//!
//! The tile is carved from the lattice's reduced rhomboid R = o + [0,1)·u + [0,1)·v,
//! which holds exactly one pixel of every coset of ℤ²/Λ. Two minimum-error cuts make it
//! wrap (ALGORITHMS.md §2, generalised to oblique lattices):
//!
//! 1. across the v-edge (the u period): near s = 0 a pixel q may take Y(q + u) instead of
//!    Y(q); the switch follows the cheapest path through ψᵘ = |Y(q) − Y(q+u)|² (seed 003,
//!    eq. 1), giving V₁;
//! 2. across the u-edge (the v period): near t = 0 the pixel may take V₁(q + v); the path
//!    through ψᵛ = |V₁(q) − V₁(q+v)|² (eq. 2) is cyclic, since the tile already wraps in u.
//!
//! Pixels are grouped into bins along and across each seam — exactly the pixel rows and
//! columns for an axis-aligned lattice — and the recursion after eq. 2 runs over the bins
//! ([`crate::analysis::cut`]). The start vertex r* (the rhomboid's origin) is the one
//! whose two cuts cost least. The result is stored on the lattice's Hermite normal form
//! rectangle (ALGORITHMS.md §1), so the runtime never sees the obliqueness.

use crate::analysis::cut::min_cut_vertical;
use crate::analysis::heal::heal;
use crate::error::{Error, Result};
use crate::lattice::Lattice;
use crate::raster::Raster;

/// Roller tiles on a lattice, level 0, in HNF storage.
#[derive(Clone, Debug)]
pub struct RollerTiles {
    /// The tiling lattice (HNF: tiles are `a × c` texels, rows shift by `b`).
    pub lattice: Lattice,
    /// The reduced basis the rhomboids were cut along.
    pub basis: [(i64, i64); 2],
    /// Origin r* of the master rhomboid, then those of the other tiles, in exemplar pixels
    /// (before the phase: texel (0, 0) of the stored tiles is rhomboid offset `phase`).
    pub origins: Vec<(i64, i64)>,
    /// Phase p of the stored tiles: texel q holds what rhomboid offset q + p (reduced
    /// on the lattice) holds (the bake chooses it: see `choose_phase`).
    pub phase: (i64, i64),
    /// Per tile, `a × c × channels` texels, row-major.
    pub tiles: Vec<Vec<f32>>,
    /// Per tile, the exemplar pixel (x, y) each texel was taken from, before healing:
    /// neighbours whose sources are not neighbours in the exemplar lie on a seam.
    pub sources: Vec<Vec<(i64, i64)>>,
    /// Mean error per bin along each cut: the u cut, the v cut, then for every further
    /// tile its closed cut (mean of its four sides).
    pub seam_costs: Vec<f64>,
    /// Overlap (and border band) width in pixels.
    pub overlap: usize,
}

/// Exact lattice coordinates of a rhomboid: s·D and t·D of pixel q, with
/// q − o = s·u + t·v and D = det(u, v) > 0.
#[derive(Clone, Copy)]
struct Frame {
    u: (i64, i64),
    v: (i64, i64),
    d: i64,
    /// |u| and |v| in pixels.
    lu: f64,
    lv: f64,
}

impl Frame {
    fn new([u, v]: [(i64, i64); 2]) -> Frame {
        let d = u.0 * v.1 - u.1 * v.0;
        debug_assert!(d > 0);
        let len = |p: (i64, i64)| ((p.0 * p.0 + p.1 * p.1) as f64).sqrt();
        Frame {
            u,
            v,
            d,
            lu: len(u),
            lv: len(v),
        }
    }
    /// (s·D, t·D) of offset δ = q − o.
    fn st(&self, dx: i64, dy: i64) -> (i64, i64) {
        (dx * self.v.1 - dy * self.v.0, self.u.0 * dy - self.u.1 * dx)
    }
    /// The representative of offset δ's coset inside [0,1)² (offset from o).
    fn rep(&self, dx: i64, dy: i64) -> (i64, i64) {
        let (sd, td) = self.st(dx, dy);
        let (fs, ft) = (sd.div_euclid(self.d), td.div_euclid(self.d));
        (
            dx - fs * self.u.0 - ft * self.v.0,
            dy - fs * self.u.1 - ft * self.v.1,
        )
    }
    /// (s, t) of offset δ.
    fn st_unit(&self, d: (i64, i64)) -> (f64, f64) {
        let (sd, td) = self.st(d.0, d.1);
        (sd as f64 / self.d as f64, td as f64 / self.d as f64)
    }
    /// Pixel offsets δ with s ∈ [s0, s1), t ∈ [t0, t1), as (δ, s, t).
    fn pixels(&self, s: (f64, f64), t: (f64, f64)) -> Vec<((i64, i64), f64, f64)> {
        let (x0, x1, y0, y1) = self.bbox(s, t);
        let mut out = Vec::new();
        let df = self.d as f64;
        for dy in y0..=y1 {
            for dx in x0..=x1 {
                let (sd, td) = self.st(dx, dy);
                let (ss, tt) = (sd as f64 / df, td as f64 / df);
                // Exact at the rhomboid's own edges (0 and 1), where it matters.
                let in_s = if s.0 == 0.0 { sd >= 0 } else { ss >= s.0 } && ss < s.1;
                let in_t = if t.0 == 0.0 { td >= 0 } else { tt >= t.0 } && tt < t.1;
                if in_s && in_t {
                    out.push(((dx, dy), ss, tt));
                }
            }
        }
        out
    }
    /// Bounding box (x0, x1, y0, y1) of the parallelogram s ∈ [s0,s1], t ∈ [t0,t1].
    fn bbox(&self, s: (f64, f64), t: (f64, f64)) -> (i64, i64, i64, i64) {
        let corners = [(s.0, t.0), (s.1, t.0), (s.0, t.1), (s.1, t.1)].map(|(a, b)| {
            (
                a * self.u.0 as f64 + b * self.v.0 as f64,
                a * self.u.1 as f64 + b * self.v.1 as f64,
            )
        });
        let fold = |f: fn(f64, f64) -> f64, k: usize, init: f64| {
            corners
                .iter()
                .fold(init, |m, c| f(m, if k == 0 { c.0 } else { c.1 }))
        };
        (
            fold(f64::min, 0, f64::MAX).floor() as i64,
            fold(f64::max, 0, f64::MIN).ceil() as i64,
            fold(f64::min, 1, f64::MAX).floor() as i64,
            fold(f64::max, 1, f64::MIN).ceil() as i64,
        )
    }
}

/// The exemplar as a function of integer pixel position (all channels).
struct Image<'a> {
    r: &'a Raster,
}

impl Image<'_> {
    fn at(&self, x: i64, y: i64) -> &[f32] {
        let c = self.r.channels;
        let i = (y as usize * self.r.width + x as usize) * c;
        &self.r.data[i..i + c]
    }
}

fn sq_diff(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(&p, &q)| (p as f64 - q as f64).powi(2))
        .sum()
}

/// Cheapest 8-connected path through a `width × height` error matrix whose first and
/// last rows are at most one column apart (a closed loop). Returns the column per row.
fn min_cut_cyclic(err: &[f64], width: usize, height: usize) -> Vec<usize> {
    if width <= 1 || height <= 1 {
        return vec![0; height];
    }
    let mut best: Option<(f64, Vec<usize>)> = None;
    for start in 0..width {
        // Force row 0 to `start` and the last row to its neighbourhood.
        let mut e = err.to_vec();
        for c in 0..width {
            if c != start {
                e[c] = f64::INFINITY;
            }
            if c.abs_diff(start) > 1 {
                e[(height - 1) * width + c] = f64::INFINITY;
            }
        }
        let path = min_cut_vertical(&e, width, height);
        let cost: f64 = path
            .iter()
            .enumerate()
            .map(|(r, &c)| e[r * width + c])
            .sum();
        if cost.is_finite() && best.as_ref().is_none_or(|(b, _)| cost < *b) {
            best = Some((cost, path));
        }
    }
    best.map(|(_, p)| p).unwrap_or_else(|| vec![0; height])
}

/// Bins `(row, col, ψ)` into a `cols × rows` matrix; returns it and the mean error per
/// row of the cheapest path through it (the cut cost).
fn binned(items: &[(usize, usize, f64)], rows: usize, cols: usize) -> Vec<f64> {
    let mut m = vec![0.0; rows * cols];
    for &(r, c, e) in items {
        m[r.min(rows - 1) * cols + c.min(cols - 1)] += e;
    }
    m
}

fn path_cost(m: &[f64], cols: usize, path: &[usize]) -> f64 {
    path.iter()
        .enumerate()
        .map(|(r, &c)| m[r * cols + c])
        .sum::<f64>()
        / path.len().max(1) as f64
}

/// Bin index of a position measured in pixels: the floor, forgiving the rounding of
/// s = (s·D)/D (without it, x = 11 comes out as 10.999… on an axis-aligned lattice and
/// bin 11 stays empty, which the cut then follows for free).
fn bin(pixels: f64) -> usize {
    (pixels + 1e-7).max(0.0) as usize
}

/// (along-seam bin, distance-from-edge bin) of a pixel at lattice coordinates (s, t),
/// for one side of a tile's border band.
type SideBins<'a> = dyn Fn(f64, f64) -> (usize, usize) + 'a;

/// Geometry of one bake: frame, overlap, the ε of each seam and the bin counts.
struct Plan {
    f: Frame,
    ov: usize,
    eu: f64,
    ev: f64,
    /// Bins along t (u seam) and along s (v seam).
    nt: usize,
    ns: usize,
}

impl Plan {
    /// Across-seam bin of the u seam (pixels from the v-edge) and along-seam bin.
    fn bins_u(&self, s: f64, t: f64) -> (usize, usize) {
        let f = &self.f;
        (bin(t * f.lv), bin(s * f.d as f64 / f.lv))
    }
    fn bins_v(&self, s: f64, t: f64) -> (usize, usize) {
        let f = &self.f;
        (bin(s * f.lu), bin(t * f.d as f64 / f.lu))
    }
    /// True where the u cut makes the pixel at (s, t) take its value from δ + u.
    fn takes_u(&self, cut_u: &[usize], s: f64, t: f64) -> bool {
        let (r, c) = self.bins_u(s, t);
        (0.0..self.eu).contains(&s) && c < cut_u[r.min(self.nt - 1)]
    }
    /// True where the v cut makes the pixel at (s, t) take its value from δ + v.
    fn takes_v(&self, cut_v: &[usize], s: f64, t: f64) -> bool {
        let (r, c) = self.bins_v(s, t);
        (0.0..self.ev).contains(&t) && c < cut_v[r.min(self.ns - 1)]
    }
    /// Extent needed from the origin: s ∈ [0, 1+εu], t ∈ [0, 1+εv].
    fn extent(&self) -> (i64, i64, i64, i64) {
        self.f.bbox((0.0, 1.0 + self.eu), (0.0, 1.0 + self.ev))
    }
}

/// ψ between value(δ) and value(δ + e); with `smooth`, summed over the 3×3
/// neighbourhood of δ (where `inside`).
fn psi_at<'a>(
    smooth: bool,
    inside: &dyn Fn((i64, i64), (i64, i64)) -> bool,
    d: (i64, i64),
    e: (i64, i64),
    value: &dyn Fn((i64, i64)) -> &'a [f32],
) -> f64 {
    if !smooth {
        return sq_diff(value(d), value((d.0 + e.0, d.1 + e.1)));
    }
    let mut sum = 0.0;
    for dy in -1..=1 {
        for dx in -1..=1 {
            let q = (d.0 + dx, d.1 + dy);
            if inside(q, e) {
                sum += sq_diff(value(q), value((q.0 + e.0, q.1 + e.1)));
            }
        }
    }
    sum
}

/// The two cuts at origin `o`: returns (cut_u, cut_v, cost_u, cost_v). With `exact` the
/// v cut compares V₁ (after the u cut) and is cyclic; otherwise it compares the raw
/// exemplar (a cheaper estimate for the r* search).
fn cuts<'a>(
    img: &'a Image,
    p: &Plan,
    o: (i64, i64),
    exact: bool,
) -> (Vec<usize>, Vec<usize>, f64, f64) {
    let f = &p.f;
    let (w, h) = (img.r.width as i64, img.r.height as i64);
    let at = |d: (i64, i64)| img.at(o.0 + d.0, o.1 + d.1);
    // In the exact pass ψ is summed over the 3×3 neighbourhood: a path through pixels
    // that merely happen to be equal (quantised data has many) costs nothing in the
    // seed's pointwise ψ, yet shows as a seam, since the gradients across it differ.
    let inside = |d: (i64, i64), e: (i64, i64)| {
        let (x, y) = (o.0 + d.0.min(d.0 + e.0), o.1 + d.1.min(d.1 + e.1));
        let (x1, y1) = (o.0 + d.0.max(d.0 + e.0), o.1 + d.1.max(d.1 + e.1));
        x >= 0 && y >= 0 && x1 < w && y1 < h
    };
    // ψ at pixel δ between value(δ) and value(δ + e). In the exact pass it is summed over
    // the 3×3 neighbourhood: a path through pixels that merely happen to be equal
    // (quantised data has many) costs nothing in the seed's pointwise ψ yet shows as a
    // seam, because the gradients across it do not match.
    let psi = |d, e, value: &dyn Fn((i64, i64)) -> &'a [f32]| psi_at(exact, &inside, d, e, value);
    // u seam: strip s ∈ [0, εu), t ∈ [0, 1 + εv).
    let items: Vec<(usize, usize, f64)> = f
        .pixels((0.0, p.eu), (0.0, 1.0 + p.ev))
        .into_iter()
        .map(|(d, s, t)| {
            let (r, c) = p.bins_u(s, t);
            (r, c, psi(d, f.u, &at))
        })
        .collect();
    let mu = binned(&items, p.nt, p.ov);
    let cut_u = min_cut_vertical(&mu, p.ov, p.nt);
    let cost_u = path_cost(&mu, p.ov, &cut_u);
    let v1 = |d: (i64, i64)| -> &[f32] {
        let (s, t) = f.st_unit(d);
        if exact && p.takes_u(&cut_u, s, t) {
            at((d.0 + f.u.0, d.1 + f.u.1))
        } else {
            at(d)
        }
    };
    // v seam: strip t ∈ [0, εv), s ∈ [0, 1).
    let items: Vec<(usize, usize, f64)> = f
        .pixels((0.0, 1.0), (0.0, p.ev))
        .into_iter()
        .map(|(d, s, t)| {
            let (r, c) = p.bins_v(s, t);
            (r, c, psi(d, f.v, &v1))
        })
        .collect();
    let mv = binned(&items, p.ns, p.ov);
    let cut_v = if exact {
        min_cut_cyclic(&mv, p.ov, p.ns)
    } else {
        min_cut_vertical(&mv, p.ov, p.ns)
    };
    let cost_v = path_cost(&mv, p.ov, &cut_v);
    (cut_u, cut_v, cost_u, cost_v)
}

/// Candidate origins in `[x0, x1] × [y0, y1]`, about `n` per axis.
fn grid(x: (i64, i64), y: (i64, i64), n: i64) -> Vec<(i64, i64)> {
    let step = |lo: i64, hi: i64| ((hi - lo) / n).max(1);
    let (sx, sy) = (step(x.0, x.1), step(y.0, y.1));
    let mut out = Vec::new();
    let mut yy = y.0;
    while yy <= y.1 {
        let mut xx = x.0;
        while xx <= x.1 {
            out.push((xx, yy));
            xx += sx;
        }
        yy += sy;
    }
    out
}

/// Range of origins o for which o + extent lies inside the exemplar, or an error that
/// says how big the exemplar must be.
fn origin_range(
    img: &Image,
    ext: (i64, i64, i64, i64),
    what: &str,
) -> Result<((i64, i64), (i64, i64))> {
    let (w, h) = (img.r.width as i64, img.r.height as i64);
    let x = (-ext.0, w - 1 - ext.1);
    let y = (-ext.2, h - 1 - ext.3);
    if x.0 > x.1 || y.0 > y.1 {
        return Err(Error::TooSmall {
            what: "exemplar".into(),
            message: format!(
                "{what} needs {}×{} pixels; the exemplar has {w}×{h} (give a smaller `tile` or `lattice`, or fewer `tiles`)",
                ext.1 - ext.0 + 1,
                ext.3 - ext.2 + 1
            ),
        });
    }
    Ok((x, y))
}

/// Overlap used for `lattice` when none is given: a sixth of the rhomboid's smaller
/// width, at least 8 pixels, at most a third of it.
fn overlap_for(f: &Frame, overlap: Option<usize>) -> usize {
    let narrow = (f.d as f64 / f.lv).min(f.d as f64 / f.lu);
    overlap
        .unwrap_or(((narrow / 6.0).round() as usize).max(8))
        .min((narrow / 3.0).floor() as usize)
        .max(1)
}

/// Exemplar size (width, height) the master tile on `lattice` needs with its overlap.
pub fn required_size(lattice: Lattice, overlap: Option<usize>) -> (usize, usize) {
    let f = Frame::new(lattice.reduced_basis());
    let ov = overlap_for(&f, overlap) as f64;
    let (x0, x1, y0, y1) = f.bbox(
        (0.0, 1.0 + ov * f.lv / f.d as f64),
        (0.0, 1.0 + ov * f.lu / f.d as f64),
    );
    ((x1 - x0 + 1) as usize, (y1 - y0 + 1) as usize)
}

/// `g` of the rhomboid representative of each texel (x, y) of the HNF `A × C`
/// rectangle, row-major: a tile's sources, or any per-texel property.
fn map_hnf<T>(f: &Frame, lattice: Lattice, g: &dyn Fn((i64, i64)) -> T) -> Vec<T> {
    (0..lattice.c)
        .flat_map(|y| (0..lattice.a).map(move |x| (x, y)))
        .map(|(x, y)| g(f.rep(x, y)))
        .collect()
}

/// The texels at `sources`, all channels, row-major.
fn gather(img: &Image, sources: &[(i64, i64)]) -> Vec<f32> {
    sources
        .iter()
        .flat_map(|&(x, y)| img.at(x, y).iter().copied())
        .collect()
}

/// Cuts `n_tiles` double toroidal tiles from `exemplar` on `lattice`, with an overlap
/// (and border band) of `overlap` pixels (default: a sixth of the rhomboid's smaller
/// width, at least 8 and at most a third of it).
pub fn roller_tiles(
    exemplar: &Raster,
    lattice: Lattice,
    n_tiles: usize,
    overlap: Option<usize>,
    progress: &mut dyn FnMut(&str),
) -> Result<RollerTiles> {
    if n_tiles == 0 {
        return Err(Error::param("tiles", 0, "at least 1 tile"));
    }
    let img = Image { r: exemplar };
    let basis = lattice.reduced_basis();
    let f = Frame::new(basis);
    // Widths of the rhomboid across its v-edges and across its u-edges, in pixels.
    let (wu, wv) = (f.d as f64 / f.lv, f.d as f64 / f.lu);
    let ov = overlap_for(&f, overlap);
    let plan = Plan {
        f,
        ov,
        eu: ov as f64 / wu,
        ev: ov as f64 / wv,
        nt: ((1.0 + ov as f64 / wv) * f.lv).ceil() as usize + 1,
        ns: f.lu.ceil() as usize + 1,
    };
    let (u, v) = (basis[0], basis[1]);
    let what = format!(
        "a tile on u = ({}, {}), v = ({}, {}) with a {ov} px overlap",
        u.0, u.1, v.0, v.1
    );
    let (rx, ry) = origin_range(&img, plan.extent(), &what)?;

    // r*: the origin whose two cuts cost least (coarse grid, raw ψᵛ).
    let candidates = grid(rx, ry, 16);
    progress(&format!(
        "roller: lattice u = ({}, {}), v = ({}, {}); HNF tile {}×{} (row shift {}); overlap {ov} px; searching r* over {} origins",
        u.0,
        u.1,
        v.0,
        v.1,
        lattice.a,
        lattice.c,
        lattice.b,
        candidates.len()
    ));
    let o = candidates
        .iter()
        .map(|&o| {
            let (_, _, cu, cv) = cuts(&img, &plan, o, false);
            (o, cu + cv)
        })
        .fold(None, |best: Option<((i64, i64), f64)>, (o, c)| match best {
            Some((_, b)) if b <= c => best,
            _ => Some((o, c)),
        })
        .map(|(o, _)| o)
        .expect("the origin range is not empty");
    let (cut_u, cut_v, cost_u, cost_v) = cuts(&img, &plan, o, true);
    progress(&format!(
        "roller: r* = ({}, {}); cut costs {cost_u:.4e} (u), {cost_v:.4e} (v) per bin",
        o.0, o.1
    ));

    // The master tile T₀: the exemplar pixel each offset δ ∈ R takes.
    let shift = |o: (i64, i64), d: (i64, i64)| (o.0 + d.0, o.1 + d.1);
    let v1 = |d: (i64, i64), s: f64, t: f64| -> (i64, i64) {
        if plan.takes_u(&cut_u, s, t) {
            shift(o, shift(d, u))
        } else {
            shift(o, d)
        }
    };
    let master_src = |d: (i64, i64)| -> (i64, i64) {
        let (s, t) = f.st_unit(d);
        if plan.takes_v(&cut_v, s, t) {
            v1(shift(d, v), s, t + 1.0)
        } else {
            v1(d, s, t)
        }
    };
    let master = |d: (i64, i64)| -> &[f32] {
        let p = master_src(d);
        img.at(p.0, p.1)
    };
    let at = |o: (i64, i64), d: (i64, i64)| img.at(o.0 + d.0, o.1 + d.1);
    let src0 = map_hnf(&f, lattice, &master_src);
    let mut tile0 = gather(&img, &src0);
    let c0 = heal(&lattice, exemplar, &src0, &mut tile0, None);
    let mut tiles = vec![tile0];
    let mut sources = vec![src0];
    let mut origins = vec![o];
    let mut seam_costs = vec![cost_u, cost_v];

    if n_tiles > 1 {
        // Further tiles: rhomboids elsewhere whose border band best matches T₀'s, each
        // joined to T₀'s band by a closed cut (four side paths), so every tile shares
        // T₀'s outer border and any arrangement stays seamless.
        let band = ov;
        let keep = phase_margin(band) + 2;
        // A tile's own interior meets T₀'s kept band along a cut inside the band; a band
        // no wider than what is kept leaves no room for one, and the interior would meet
        // T₀ wherever the rhomboid happens to end (healing then overshoots: 20-px warning
        // stripes on a 2 px overlap gave −121 to 314 on a 0–255 photo).
        if band <= keep {
            return Err(Error::TooSmall {
                what: "lattice".into(),
                message: format!(
                    "{n_tiles} tiles need an overlap wider than the {keep} px of the first tile's border every tile keeps, for the cut around each interior; {what} leaves no room (ask for 1 tile, or a larger `tile` or `lattice`)"
                ),
            });
        }
        let (bu, bv) = (band as f64 / wu, band as f64 / wv);
        let (kx, ky) = origin_range(&img, f.bbox((0.0, 1.0), (0.0, 1.0)), &what)?;
        let ring: Vec<((i64, i64), f64, f64)> = f
            .pixels((0.0, 1.0), (0.0, 1.0))
            .into_iter()
            .filter(|&(_, s, t)| s < bu || s >= 1.0 - bu || t < bv || t >= 1.0 - bv)
            .collect();
        let min_sep = (f.lu.min(f.lv) / 2.0).max(1.0);
        let mut scored: Vec<((i64, i64), f64)> = grid(kx, ky, 24)
            .into_iter()
            .map(|ok| {
                let e: f64 = ring
                    .iter()
                    .map(|&(d, _, _)| sq_diff(master(d), at(ok, d)))
                    .sum();
                (ok, e)
            })
            .collect();
        scored.sort_by(|p, q| p.1.total_cmp(&q.1).then(p.0.cmp(&q.0)));
        // Best-matching first, greedily, at least `sep` apart; where the greedy choice
        // packs badly, the separation is relaxed (to three quarters) before giving up.
        for sep in [min_sep, 0.75 * min_sep] {
            origins.truncate(1);
            for &(ok, _) in &scored {
                if origins.len() == n_tiles {
                    break;
                }
                let far = origins
                    .iter()
                    .all(|p| (((p.0 - ok.0).pow(2) + (p.1 - ok.1).pow(2)) as f64).sqrt() >= sep);
                if far {
                    origins.push(ok);
                }
            }
            if origins.len() == n_tiles {
                break;
            }
        }
        if origins.len() < n_tiles {
            return Err(Error::TooSmall {
                what: "exemplar".into(),
                message: format!(
                    "{n_tiles} tiles need {n_tiles} rhomboids at least {:.0} px apart; the exemplar holds {} (ask for fewer `tiles` or a smaller `tile`)",
                    0.75 * min_sep,
                    origins.len()
                ),
            });
        }
        let mut pending = Vec::new();
        for (k, &ok) in origins.iter().enumerate().skip(1) {
            progress(&format!(
                "roller: tile {} of {n_tiles} from ({}, {})",
                k + 1,
                ok.0,
                ok.1
            ));
            // Side cuts: (distance-from-edge bin, along bin) per side; interior where
            // every side's distance bin reaches its cut (≥ `keep`: the outermost `keep`
            // bins are T₀ in every tile, room for the phase).
            let sides: [Box<SideBins>; 4] = [
                Box::new(|s, t| (bin(t * f.lv), bin(s * wu))),
                Box::new(|s, t| (bin(t * f.lv), bin((1.0 - s) * wu))),
                Box::new(|s, t| (bin(s * f.lu), bin(t * wv))),
                Box::new(|s, t| (bin(s * f.lu), bin((1.0 - t) * wv))),
            ];
            let along = [plan.nt, plan.nt, plan.ns, plan.ns];
            let mut side_cuts = Vec::new();
            let mut cost = 0.0;
            for (side, &n) in sides.iter().zip(&along) {
                let items: Vec<(usize, usize, f64)> = ring
                    .iter()
                    .filter_map(|&(d, s, t)| {
                        let (r, c) = side(s, t);
                        (c >= keep && c < band)
                            .then(|| (r, c - keep, sq_diff(master(d), at(ok, d))))
                    })
                    .collect();
                let cols = band.saturating_sub(keep).max(1);
                let m = binned(&items, n, cols);
                let path = min_cut_vertical(&m, cols, n);
                cost += path_cost(&m, cols, &path) / 4.0;
                side_cuts.push(path.into_iter().map(|p| p + keep).collect::<Vec<usize>>());
            }
            seam_costs.push(cost);
            let interior = |s: f64, t: f64| {
                sides
                    .iter()
                    .zip(&side_cuts)
                    .zip(&along)
                    .all(|((side, cut), &n)| {
                        let (r, c) = side(s, t);
                        c >= cut[r.min(n - 1)]
                    })
            };
            let src = map_hnf(&f, lattice, &|d| {
                let (s, t) = f.st_unit(d);
                if interior(s, t) {
                    shift(ok, d)
                } else {
                    master_src(d)
                }
            });
            let free = map_hnf(&f, lattice, &|d| {
                let (s, t) = f.st_unit(d);
                interior(s, t)
            });
            // T₀'s healed band everywhere outside the closed cut; the inside is healed
            // with the band held fixed, so every tile keeps T₀'s border exactly.
            let mut tile = gather(&img, &src);
            tile.iter_mut()
                .zip(&c0)
                .for_each(|(t, c)| *t = (*t as f64 + c) as f32);
            pending.push((src, free, tile));
        }
        // The interiors are healed independently: in parallel, each result its own.
        std::thread::scope(|scope| {
            let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
            let chunk = pending.len().div_ceil(workers).max(1);
            for group in pending.chunks_mut(chunk) {
                scope.spawn(move || {
                    for (src, free, tile) in group {
                        heal(&lattice, exemplar, src, tile, Some(free));
                    }
                });
            }
        });
        for (src, _, tile) in pending {
            tiles.push(tile);
            sources.push(src);
        }
    }
    let ch = exemplar.channels;
    let phase = choose_phase(lattice, basis, &tiles, ch, n_tiles, ov);
    if phase != (0, 0) {
        progress(&format!(
            "roller: phase ({}, {}): the cell borders cross typical rows and columns",
            phase.0, phase.1
        ));
        for tile in &mut tiles {
            *tile = rotate(lattice, tile, ch, phase);
        }
        for src in &mut sources {
            *src = rotate(lattice, src, 1, phase);
        }
    }
    Ok(RollerTiles {
        lattice,
        basis,
        origins,
        phase,
        tiles,
        sources,
        seam_costs,
        overlap: ov,
    })
}

/// How far (in pixels, perpendicular to a rhomboid edge) the phase of several tiles may
/// move their cell borders: the outermost `phase_margin + 2` bins of the border band are
/// kept T₀'s in every tile, so borders moved that far still meet T₀ on both sides.
fn phase_margin(band: usize) -> usize {
    (band.saturating_sub(3) / 3).min(8)
}

/// A Λ-periodic texel array `data` (`channels` values per texel, HNF row-major) read
/// from phase `p`: texel q of the result is texel q + p, reduced on the lattice.
fn rotate<T: Copy>(l: Lattice, data: &[T], channels: usize, p: (i64, i64)) -> Vec<T> {
    let mut out = Vec::with_capacity(data.len());
    for y in 0..l.c {
        for x in 0..l.a {
            let (_, (sx, sy)) = l.reduce((x + p.0, y + p.1));
            let i = (sy * l.a + sx) as usize * channels;
            out.extend_from_slice(&data[i..i + channels]);
        }
    }
    out
}

/// The phase p of the stored tiles: where the runtime's cell borders fall on the
/// tile. A toroidal tile may be stored from any phase, and with one tile the surface
/// only shifts; with several, the cell borders are where tiles meet, inside the border
/// band all tiles share, so the phase may move them only within the band's reserved
/// outer bins ([`phase_margin`]; the tiles then still meet T₀ on both sides).
///
/// Of the phases allowed (one tile: |pₓ|, |p_y| ≤ 16), the chosen one makes the pixel
/// pairs across cell borders as rough as all pairs of the same direction, on average
/// over the tiles (least Σ_d n_d·|r_d − 1|, r_d = mean squared difference of the
/// direction-d pairs crossing a border ÷ that of all direction-d pairs). Why: measured
/// exemplars have rows and columns of unequal roughness (scan lines; di-6's vertical
/// pair energy varies by ±40% from one row to the next), and the border band is the one
/// part every cell shows, so an atypical line there repeats on every cell of the
/// lattice. Ties go to the smallest |p|, then the lowest (y, x): deterministic.
fn choose_phase(
    l: Lattice,
    basis: [(i64, i64); 2],
    tiles: &[Vec<f32>],
    channels: usize,
    n_tiles: usize,
    band: usize,
) -> (i64, i64) {
    // The runtime's cells (`ToroidalSurface::cell_id`): rhomboids of the reduced basis
    // for several tiles on an oblique lattice, the HNF rectangles otherwise.
    let f = Frame::new(basis);
    let rhomboid = n_tiles > 1 && l.b != 0;
    let cell = |q: (i64, i64)| -> (i64, i64) {
        if rhomboid {
            let (sd, td) = f.st(q.0, q.1);
            (sd.div_euclid(f.d), td.div_euclid(f.d))
        } else {
            l.reduce(q).0
        }
    };
    let dirs = [(1, 0), (0, 1)];
    // Border pairs (q, direction), and the mean squared difference of all pairs of each
    // direction (the same at every phase), over every tile.
    let mut crossing = Vec::new();
    let mut mean = [0.0f64; 2];
    let texel = |q: (i64, i64)| -> std::ops::Range<usize> {
        let (_, (x, y)) = l.reduce(q);
        let i = (y * l.a + x) as usize * channels;
        i..i + channels
    };
    for y in 0..l.c {
        for x in 0..l.a {
            for (d, e) in dirs.iter().enumerate() {
                let (q, n) = ((x, y), (x + e.0, y + e.1));
                if cell(q) != cell(n) {
                    crossing.push((q, d));
                }
                for t in tiles {
                    mean[d] += sq_diff(&t[texel(q)], &t[texel(n)]);
                }
            }
        }
    }
    let pairs = (l.a * l.c) as f64 * tiles.len() as f64;
    mean.iter_mut().for_each(|m| *m /= pairs);
    if mean.contains(&0.0) {
        return (0, 0);
    }
    let r = if n_tiles == 1 {
        16
    } else {
        phase_margin(band) as i64
    };
    // Perpendicular displacement of the borders, |p × e| / |e| for each edge e.
    let perp = |p: (i64, i64), e: (i64, i64)| {
        (p.0 * e.1 - p.1 * e.0).abs() as f64 / ((e.0 * e.0 + e.1 * e.1) as f64).sqrt()
    };
    let mut best = ((0, 0), f64::INFINITY);
    let mut candidates: Vec<(i64, i64)> = (-r..=r)
        .flat_map(|y| (-r..=r).map(move |x| (x, y)))
        .filter(|&p| n_tiles == 1 || basis.iter().all(|&e| perp(p, e) <= r as f64))
        .collect();
    candidates.sort_by_key(|&(x, y)| (x * x + y * y, y, x));
    for p in candidates {
        let (mut sum, mut n) = ([0.0f64; 2], [0usize; 2]);
        for &(q, d) in &crossing {
            let e = dirs[d];
            let (a, b) = ((q.0 + p.0, q.1 + p.1), (q.0 + p.0 + e.0, q.1 + p.1 + e.1));
            for t in tiles {
                sum[d] += sq_diff(&t[texel(a)], &t[texel(b)]);
            }
            n[d] += tiles.len();
        }
        let score: f64 = (0..2)
            .filter(|&d| n[d] > 0)
            .map(|d| n[d] as f64 * (sum[d] / n[d] as f64 / mean[d] - 1.0).abs())
            .sum();
        if score < best.1 {
            best = (p, score);
        }
    }
    best.0
}

/// Mip level `l` (≥ 1) of Λ-periodic tiles from level `l − 1`: each texel of the level-l
/// HNF rectangle is the mean of the 2×2 block of level-(l−1) texels it covers, each
/// found through the level-(l−1) lattice (a toroidal box filter).
pub fn mip_down(
    prev: &[Vec<f32>],
    lat_prev: Lattice,
    lat: Lattice,
    channels: usize,
) -> Vec<Vec<f32>> {
    let (a, c) = (lat.a as usize, lat.c as usize);
    prev.iter()
        .map(|tile| {
            let mut out = Vec::with_capacity(a * c * channels);
            for y in 0..c as i64 {
                for x in 0..a as i64 {
                    let mut acc = [0.0f64; 4];
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (_, (lx, ly)) = lat_prev.reduce((2 * x + dx, 2 * y + dy));
                        let i = (ly as usize * lat_prev.a as usize + lx as usize) * channels;
                        for ch in 0..channels {
                            acc[ch] += tile[i + ch] as f64;
                        }
                    }
                    out.extend(acc[..channels].iter().map(|&s| (s / 4.0) as f32));
                }
            }
            out
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub use crate::lattice::periodic_pattern as periodic;

    /// On an exactly periodic exemplar with its true lattice, ψ ≡ 0 and the tile is the
    /// period itself: every stored texel equals the exemplar at any congruent position.
    #[test]
    fn exact_period_is_extracted_exactly() {
        for (u, v) in [
            ((32, 0), (0, 24)),
            ((40, 0), (13, 29)),
            ((-17, 31), (29, 11)),
        ] {
            let ex = periodic(200, 180, u, v);
            let lat = Lattice::from_basis(u, v).unwrap();
            let t = roller_tiles(&ex, lat, 1, None, &mut |_| {}).unwrap();
            let f = Frame::new(t.basis);
            let o = (t.origins[0].0 + t.phase.0, t.origins[0].1 + t.phase.1);
            let anchor = (100, 90);
            for (k, &val) in t.tiles[0].iter().enumerate() {
                let (x, y) = ((k % lat.a as usize) as i64, (k / lat.a as usize) as i64);
                // Another representative of the coset of o + (x, y), in another rhomboid.
                let d = f.rep(o.0 + x - anchor.0, o.1 + y - anchor.1);
                let expect = ex.get((anchor.0 + d.0) as usize, (anchor.1 + d.1) as usize, 0);
                assert!(
                    (val - expect).abs() < 1e-5,
                    "{u:?} {v:?} texel {k}: {val} vs {expect}"
                );
            }
            assert!(
                t.seam_costs[0] < 1e-9 && t.seam_costs[1] < 1e-9,
                "{:?}",
                t.seam_costs
            );
        }
    }

    /// White noise in [−0.5, 0.5) from a xorshift: a stochastic exemplar.
    fn noise(w: usize, h: usize, seed: u64) -> Raster {
        let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let data = (0..w * h)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) as f32
            })
            .collect();
        Raster::from_vec(w, h, 1, data).unwrap()
    }

    /// Rotating by p reads texel q + p (reduced on the lattice), and by −p undoes it.
    #[test]
    fn rotation_reads_the_lattice_reduced_texel() {
        let l = Lattice::from_basis((40, 0), (13, 29)).unwrap();
        let data: Vec<u32> = (0..(l.a * l.c) as u32).collect();
        for p in [(3, -2), (-16, 16), (41, 30)] {
            let r = rotate(l, &data, 1, p);
            for (k, &v) in r.iter().enumerate() {
                let q = ((k as i64 % l.a) + p.0, (k as i64 / l.a) + p.1);
                let (_, (x, y)) = l.reduce(q);
                assert_eq!(v, data[(y * l.a + x) as usize]);
            }
            assert_eq!(rotate(l, &r, 1, (-p.0, -p.1)), data);
        }
    }

    /// Row 0 of a 32 × 24 noise tile raised by a scan-line offset, so the row pairs
    /// around it (one of them where phase (0, 0) puts the border) are rougher than the
    /// rest: the chosen phase moves the border off them, making the border pairs as rough
    /// as all pairs (ratio within 15% of 1 in each direction; over 1.5 at phase (0, 0)).
    #[test]
    fn the_phase_moves_cell_borders_off_atypical_lines() {
        let l = Lattice::rectangular(32, 24).unwrap();
        let n = noise(32, 24, 3);
        let tile: Vec<f32> = (0..32 * 24)
            .map(|k| n.data[k] + if k / 32 == 0 { 0.5 } else { 0.0 })
            .collect();
        let ratio = |t: &[f32], d: usize| {
            let at = |x: usize, y: usize| t[(y % 24) * 32 + x % 32] as f64;
            let (mut border, mut nb, mut all) = (0.0, 0, 0.0);
            for y in 0..24 {
                for x in 0..32 {
                    let g = if d == 0 {
                        (at(x + 1, y) - at(x, y)).powi(2)
                    } else {
                        (at(x, y + 1) - at(x, y)).powi(2)
                    };
                    all += g;
                    if (d == 0 && x == 31) || (d == 1 && y == 23) {
                        border += g;
                        nb += 1;
                    }
                }
            }
            (border / nb as f64) / (all / (32.0 * 24.0))
        };
        assert!(
            ratio(&tile, 1) > 1.5,
            "the test tile has no atypical border"
        );
        let p = choose_phase(l, l.reduced_basis(), std::slice::from_ref(&tile), 1, 1, 8);
        let rotated = rotate(l, &tile, 1, p);
        for d in 0..2 {
            let r = ratio(&rotated, d);
            assert!(
                (r - 1.0).abs() < 0.15,
                "phase {p:?}: direction {d} ratio {r}"
            );
        }
    }

    /// With several tiles the phase moves the cell borders only inside the band every
    /// tile shares: across each border of the runtime's cells (HNF rectangles, or
    /// rhomboids on an oblique lattice) all tiles hold T₀'s texels on both sides.
    #[test]
    fn phased_tiles_agree_across_cell_borders() {
        let ex = noise(300, 300, 9);
        for lat in [
            Lattice::rectangular(72, 64).unwrap(),
            Lattice::from_basis((80, 0), (26, 70)).unwrap(),
        ] {
            let t = roller_tiles(&ex, lat, 3, None, &mut |_| {}).unwrap();
            let f = Frame::new(t.basis);
            let cell = |q: (i64, i64)| {
                if lat.b != 0 {
                    let (sd, td) = f.st(q.0, q.1);
                    (sd.div_euclid(f.d), td.div_euclid(f.d))
                } else {
                    lat.reduce(q).0
                }
            };
            let idx = |q: (i64, i64)| {
                let (_, (x, y)) = lat.reduce(q);
                (y * lat.a + x) as usize
            };
            let mut borders = 0;
            for y in 0..lat.c {
                for x in 0..lat.a {
                    for e in [(1, 0), (0, 1)] {
                        let (q, n) = ((x, y), (x + e.0, y + e.1));
                        if cell(q) == cell(n) {
                            continue;
                        }
                        borders += 1;
                        for k in 1..3 {
                            for r in [q, n] {
                                assert_eq!(
                                    t.tiles[k][idx(r)],
                                    t.tiles[0][idx(r)],
                                    "{lat:?} phase {:?}: tile {k} at {r:?}",
                                    t.phase
                                );
                            }
                        }
                    }
                }
            }
            assert!(borders >= (lat.a + lat.c) as usize, "{lat:?}: {borders}");
        }
    }

    #[test]
    fn too_small_exemplar_says_what_it_needs() {
        let ex = periodic(40, 40, (32, 0), (0, 24));
        let e = roller_tiles(
            &ex,
            Lattice::rectangular(36, 36).unwrap(),
            1,
            None,
            &mut |_| {},
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("needs") && e.contains("40×40"), "{e}");
        let e = roller_tiles(
            &ex,
            Lattice::rectangular(8, 8).unwrap(),
            0,
            None,
            &mut |_| {},
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("at least 1 tile"), "{e}");
    }

    /// A rhomboid 5 px wide gets a 1 px overlap: no room, beyond the border band every
    /// tile keeps of T₀, for the cut around a further tile's interior. Several tiles are
    /// refused with a reason (a bake without `tiles` then makes one); one tile bakes.
    #[test]
    fn several_tiles_need_room_for_their_border_cut() {
        let ex = noise(64, 64, 5);
        let lattice = Lattice::rectangular(20, 5).unwrap();
        let Err(e) = roller_tiles(&ex, lattice, 2, None, &mut |_| {}) else {
            panic!("2 tiles on a 1 px overlap baked");
        };
        let e = e.to_string();
        assert!(
            e.contains("2 tiles need an overlap wider") && e.contains("1 tile"),
            "{e}"
        );
        let one = roller_tiles(&ex, lattice, 1, None, &mut |_| {}).unwrap();
        assert_eq!(one.tiles.len(), 1);
    }
}
