//! Wang tiles with hashed edges (DESIGN.md rule 2, ALGORITHMS.md §6; Cohen et al. 2003,
//! Wei 2004), quilted from crops of the exemplar with minimum-error seams
//! ([`crate::analysis::cut`]).
//!
//! With K colours per edge direction there are K⁴ tiles of T × T pixels; tile
//! `((W·K + E)·K + S)·K + N` has colour W on its column-0 edge, E on the edge after its
//! last column, S on its row-0 edge and N after its last row. A cell edge runs *between*
//! two pixel columns (or rows) and through the middle of a sample of its colour:
//!
//! - **Edge strips.** For each colour and direction one crop, 2e px across and T + 2e px
//!   along, centred on the edge. The m px on either side of the edge line are taken from
//!   it unchanged in every tile with that colour there, so two tiles whose shared edge has
//!   the same colour meet exactly: across the edge, pixels are neighbours in one crop.
//! - **Vertex patch.** Where four cells meet, the edge strips of four different edges
//!   would meet too: one vertex crop, 2e × 2e, is cut into both ends of every strip by
//!   minimum-error paths, so the m × m corner of every tile is the same piece of it and
//!   every strip end agrees with every other.
//! - **Interior.** Each tile has its own crop; it meets each of its four strips along an
//!   8-connected minimum-error path in the band m ≤ d < e from the edge; where two strips
//!   overlap in a corner, the strip of the nearer edge wins (the diagonal between them
//!   is a seam like the others). The cuts are then healed in the gradient domain
//!   (`heal_cuts`), except within m px of an edge, which stays the strip's.
//!
//! Mip levels are each tile's 2 × 2 box means; edges stay exact down to the level whose
//! texels span m pixels.

use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

use crate::analysis::cut::min_cut_vertical;
use crate::analysis::stitch::mean_filter_at as mean_filter;
use crate::error::{Error, Result};
use crate::raster::Raster;

/// Random crops tried for each edge strip (the most typical is kept).
const STRIP_CANDIDATES: usize = 64;

/// Random crops tried for each tile's interior.
const INTERIOR_CANDIDATES: usize = 16;

/// Largest K: 8⁴ = 4096 tiles, the most a bank holds.
pub const MAX_COLOURS: usize = 8;

/// The geometry of a Wang tile set, validated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WangLayout {
    /// Colours per edge direction, K.
    pub colours: usize,
    /// Tile side T in pixels (a power of two).
    pub side: usize,
    /// Half-width m of the band on each side of an edge copied unchanged from its strip.
    pub edge: usize,
    /// Width w of the cut band between a strip and the tile's interior (e = m + w).
    pub band: usize,
}

impl WangLayout {
    /// K colours, T × T tiles; `band` defaults to T/16 (≥ 2), m to T/32 (≥ 2).
    pub fn new(colours: usize, side: usize, band: Option<usize>) -> Result<WangLayout> {
        if !(1..=MAX_COLOURS).contains(&colours) {
            return Err(Error::param(
                "colours",
                colours,
                format!("1 to {MAX_COLOURS} colours per edge direction (K⁴ tiles)"),
            ));
        }
        if !side.is_power_of_two() || !(16..=4096).contains(&side) {
            return Err(Error::param(
                "patch",
                side,
                "a Wang tile side that is a power of two from 16 to 4096 pixels",
            ));
        }
        let edge = (side / 32).max(2);
        let band = band.unwrap_or((side / 16).max(2));
        if band == 0 || 2 * (edge + band) + 2 > side {
            return Err(Error::param(
                "overlap",
                band,
                format!(
                    "a cut band of 1 to {} px for {side} px tiles (twice the band plus the {edge} px edge strips must leave an interior)",
                    (side - 2) / 2 - edge
                ),
            ));
        }
        Ok(WangLayout {
            colours,
            side,
            edge,
            band,
        })
    }

    /// e = m + w: how far a strip reaches into a tile.
    pub fn reach(&self) -> usize {
        self.edge + self.band
    }

    /// Number of tiles, K⁴.
    pub fn tiles(&self) -> usize {
        self.colours.pow(4)
    }

    /// Colours (W, E, S, N) of tile `t`.
    pub fn colours_of(&self, t: usize) -> [usize; 4] {
        let k = self.colours;
        [t / (k * k * k), (t / (k * k)) % k, (t / k) % k, t % k]
    }

    /// Smallest exemplar side the layout needs: T + 2e (a strip is that long).
    pub fn min_exemplar(&self) -> usize {
        self.side + 2 * self.reach()
    }
}

/// A quilted Wang tile set, with the samples it was made of (for inspection and tests).
#[derive(Clone, Debug)]
#[cfg_attr(not(test), allow(dead_code))]
pub struct WangTiles {
    /// K⁴ tiles of T × T × channels, indexed `((W·K + E)·K + S)·K + N`.
    pub tiles: Vec<Vec<f32>>,
    /// Per colour, the vertical-edge strip: 2e wide, T + 2e tall; column e is the first
    /// one right of the edge, row e is tile row 0.
    pub vertical: Vec<Vec<f32>>,
    /// Per colour, the horizontal-edge strip: T + 2e wide, 2e tall; row e is the first
    /// one below the edge, column e is tile column 0.
    pub horizontal: Vec<Vec<f32>>,
    /// Mean squared error per seam pixel: vertex cuts over all strips, then the interior
    /// cuts over all tiles.
    pub seam_costs: Vec<f64>,
}

/// Squared difference of two pixels, summed over channels.
/// Gradient-domain healing of a tile's cuts ([`crate::analysis::heal`], seed 003's
/// addition, here on a square with fixed borders). A minimum-error cut through
/// stochastic content still steps where the two crops disagree: on the di-6 AFM map the
/// columns of the cuts, 8–24 px off the cell grid, had 1.3–1.4× the median gradient
/// energy (the 3×3 mean the seams had before blurred them without removing the step).
/// Across every pair of neighbours with different labels, the target gradient is one
/// side's own continuation (its image's gradient there; the sides alternating from
/// pixel to pixel, as `heal` does), and the least-squares correction that gives it is
/// solved with the m px along the edges held fixed, so tiles still meet exactly.
fn heal_cuts<'a>(
    tile: &mut [f32],
    labels: &[Label],
    t: usize,
    m: usize,
    c: usize,
    source: &dyn Fn(Label, usize, usize) -> Option<&'a [f32]>,
) -> Result<()> {
    let lattice = crate::lattice::Lattice::rectangular(t as i64, t as i64)?;
    let free: Vec<bool> = (0..t * t)
        .map(|i| {
            let (x, y) = (i % t, i / t);
            x >= m && y >= m && x + m < t && y + m < t
        })
        .collect();
    for k in 0..c {
        let mut b = vec![0.0f64; t * t];
        let mut any = false;
        for y in 0..t {
            for x in 0..t {
                let q = y * t + x;
                for (nx, ny) in [(x + 1, y), (x, y + 1)] {
                    if nx >= t || ny >= t {
                        continue;
                    }
                    let n = ny * t + nx;
                    let (lq, ln) = (labels[q], labels[n]);
                    if lq == ln || !(free[q] || free[n]) {
                        continue;
                    }
                    let step = |l: Label| match (source(l, x, y), source(l, nx, ny)) {
                        (Some(a), Some(b)) => Some(b[k] as f64 - a[k] as f64),
                        _ => None,
                    };
                    let target = match (step(lq), step(ln)) {
                        (Some(a), Some(b)) => {
                            if q.is_multiple_of(2) {
                                a
                            } else {
                                b
                            }
                        }
                        (Some(a), None) => a,
                        (None, Some(b)) => b,
                        (None, None) => continue,
                    };
                    let r = target - (tile[n * c + k] as f64 - tile[q * c + k] as f64);
                    b[n] += r;
                    b[q] -= r;
                    any = true;
                }
            }
        }
        if any {
            let correction = crate::analysis::heal::solve_masked(&lattice, &free, &b);
            for (q, &v) in correction.iter().enumerate() {
                if free[q] {
                    tile[q * c + k] = (tile[q * c + k] as f64 + v) as f32;
                }
            }
        }
    }
    Ok(())
}

fn sq(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x as f64 - *y as f64).powi(2))
        .sum()
}

/// Transposes a `w × h × c` image.
fn transpose(img: &[f32], w: usize, h: usize, c: usize) -> Vec<f32> {
    let mut out = vec![0.0; img.len()];
    for y in 0..h {
        for x in 0..w {
            out[(x * h + y) * c..(x * h + y + 1) * c]
                .copy_from_slice(&img[(y * w + x) * c..(y * w + x + 1) * c]);
        }
    }
    out
}

/// Cuts the vertex patch `v` (2e × 2e) into both ends of a vertical strip (2e × (T + 2e))
/// along horizontal minimum-error paths in the bands of tile rows [m, e) and [T − e, T − m);
/// returns the summed path error and the number of path pixels.
fn cut_vertex_into(strip: &mut [f32], v: &[f32], lay: &WangLayout, c: usize) -> (f64, usize) {
    let (t, m, w, e) = (lay.side, lay.edge, lay.band, lay.reach());
    let sw = 2 * e;
    // Strip and vertex patch are both 2e wide.
    let px = |x: usize, y: usize| (y * sw + x) * c;
    // Strip row → vertex row, for the top (tile row 0 is strip row e) and bottom ends.
    let (mut cost, mut n) = (0.0, 0);
    for top in [true, false] {
        let vrow = |sy: usize| if top { sy } else { sy - t };
        // Band rows, and whether rows on the vertex side of the path are above it.
        let band0 = if top { e + m } else { t };
        // Pure vertex rows.
        let pure = if top { 0..e + m } else { t + w..t + sw };
        for sy in pure {
            for sx in 0..sw {
                let (a, b) = (px(sx, sy), px(sx, vrow(sy)));
                strip[a..a + c].copy_from_slice(&v[b..b + c]);
            }
        }
        let mut err = vec![0.0; sw * w];
        for sx in 0..sw {
            for r in 0..w {
                let sy = band0 + r;
                let (a, b) = (px(sx, sy), px(sx, vrow(sy)));
                err[sx * w + r] = sq(&strip[a..a + c], &v[b..b + c]);
            }
        }
        let path = min_cut_vertical(&err, w, sw);
        let on_vertex = |sx: usize, r: usize| if top { r < path[sx] } else { r > path[sx] };
        for sx in 0..sw {
            cost += err[sx * w + path[sx]];
            n += 1;
            for r in 0..w {
                if on_vertex(sx, r) {
                    let sy = band0 + r;
                    let (a, b) = (px(sx, sy), px(sx, vrow(sy)));
                    strip[a..a + c].copy_from_slice(&v[b..b + c]);
                }
            }
        }
        // Seam smoothing inside the band only: pixels whose side differs from a
        // 4-neighbour's within the band.
        let mut seam = Vec::new();
        for sx in 0..sw {
            for r in 0..w {
                let s = on_vertex(sx, r);
                let differs = (sx > 0 && on_vertex(sx - 1, r) != s)
                    || (sx + 1 < sw && on_vertex(sx + 1, r) != s)
                    || (r > 0 && on_vertex(sx, r - 1) != s)
                    || (r + 1 < w && on_vertex(sx, r + 1) != s);
                if differs && sx > 0 && sx + 1 < sw {
                    seam.push((sx, band0 + r));
                }
            }
        }
        mean_filter(strip, sw, t + sw, c, &seam);
    }
    (cost, n)
}

/// Which sample a tile pixel shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Label {
    Interior,
    West,
    East,
    South,
    North,
}

/// Quilts the K⁴ tiles of `layout` from crops of `ex` drawn with `seed`.
pub fn wang_tiles(
    ex: &Raster,
    layout: WangLayout,
    seed: u64,
    source: &str,
    progress: &mut dyn FnMut(&str),
) -> Result<WangTiles> {
    let lay = layout;
    let (t, m, w, e) = (lay.side, lay.edge, lay.band, lay.reach());
    let c = ex.channels;
    let need = lay.min_exemplar();
    if ex.width < need || ex.height < need {
        return Err(Error::TooSmall {
            what: source.to_string(),
            message: format!(
                "{}×{} pixels; Wang tiles of {t} px need an exemplar of at least {need}×{need} (the tile plus two {e} px strip ends): pass a smaller `patch`",
                ex.width, ex.height
            ),
        });
    }
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut pick = |cw: usize, ch: usize| {
        (
            rng.random_range(0..=ex.width - cw),
            rng.random_range(0..=ex.height - ch),
        )
    };
    let sw = 2 * e;
    // Mean squared step between horizontal (vertical) neighbours over the exemplar.
    let step = |dx: usize, dy: usize| {
        let (mut s, mut n) = (0.0, 0usize);
        for y in 0..ex.height - dy {
            for x in 0..ex.width - dx {
                let (a, b) = ((y * ex.width + x) * c, ((y + dy) * ex.width + x + dx) * c);
                s += sq(&ex.data[a..a + c], &ex.data[b..b + c]);
                n += 1;
            }
        }
        s / n.max(1) as f64
    };
    let (along_x, along_y) = (step(1, 0), step(0, 1));
    // How far a strip-shaped image (2e wide, in the vertical frame) is from typical
    // across its edge, over `rows`: for every line between neighbouring columns within
    // m + 1 px of the edge line (between columns e − 1 and e), the mean squared step
    // across it relative to `target`, as |ln ratio|, summed. The strip's columns within
    // m px of the edge go unchanged into every tile with that colour there, at the same
    // offsets, so a strip that is smoother or rougher a few pixels beside the edge shows
    // as a seam at that offset of every cell. Judged on the edge line alone, di-6's
    // quilt (16 tiles of 256 px, 4096² render) read up to 1.84 at the tile period; now
    // up to 1.51. (Every line of the strip, cut band included, read 0.75–1.40 there but
    // left 1.55 on the cut band's first row of the raw map's tiles:
    // `cut_bands_carry_no_seam_energy`.)
    let off_across = |img: &[f32], rows: std::ops::Range<usize>, target: f64| {
        let n = rows.len();
        (e - m - 1..e + m)
            .map(|x| {
                let s: f64 = rows
                    .clone()
                    .map(|k| {
                        let (a, b) = ((k * sw + x) * c, (k * sw + x + 1) * c);
                        sq(&img[a..a + c], &img[b..b + c])
                    })
                    .sum();
                ((s / n.max(1) as f64).max(1e-300) / target.max(1e-300))
                    .ln()
                    .abs()
            })
            .sum::<f64>()
    };
    // The vertex patch ends every strip, so it too is the most typical of a few crops,
    // by its steps across both centre lines.
    let mut vertex = Vec::new();
    let mut best = f64::INFINITY;
    for _ in 0..STRIP_CANDIDATES {
        let (vx, vy) = pick(sw, sw);
        let v = ex.crop(vx, vy, sw, sw)?.data;
        let off =
            off_across(&v, 0..sw, along_x) + off_across(&transpose(&v, sw, sw, c), 0..sw, along_y);
        if off < best {
            (best, vertex) = (off, v);
        }
    }
    let vertex_t = transpose(&vertex, sw, sw, c);
    let (mut vcost, mut vn) = (0.0, 0);
    let mut vertical = Vec::with_capacity(lay.colours);
    let mut horizontal = Vec::with_capacity(lay.colours);
    // An edge line is a seam of every tile with that colour, so each strip is the most
    // typical of a few random crops, with the vertex patch cut into its ends, by the mean
    // squared step across the edge line along the tile's T px (a strip from a rougher or
    // smoother spot would make every cell border of its colour show). Horizontal strips
    // are vertical ones in the transposed frame, with the transposed vertex.
    let mut typical = |vertical: bool| {
        let (target, v) = if vertical {
            (along_x, &vertex)
        } else {
            (along_y, &vertex_t)
        };
        let mut best: Option<(f64, Vec<f32>, (f64, usize))> = None;
        for _ in 0..STRIP_CANDIDATES {
            let mut img = if vertical {
                let (x0, y0) = pick(sw, t + sw);
                ex.crop(x0, y0, sw, t + sw)?.data
            } else {
                let (x0, y0) = pick(t + sw, sw);
                transpose(&ex.crop(x0, y0, t + sw, sw)?.data, t + sw, sw, c)
            };
            let cost = cut_vertex_into(&mut img, v, &lay, c);
            let off = off_across(&img, e..e + t, target);
            if best.as_ref().is_none_or(|(o, _, _)| off < *o) {
                best = Some((off, img, cost));
            }
        }
        Ok::<_, Error>(best.map(|b| (b.1, b.2)).unwrap_or_default())
    };
    for _ in 0..lay.colours {
        let (s, (a, b)) = typical(true)?;
        vertical.push(s);
        (vcost, vn) = (vcost + a, vn + b);
        let (s, (a, b)) = typical(false)?;
        horizontal.push(transpose(&s, sw, t + sw, c));
        (vcost, vn) = (vcost + a, vn + b);
    }
    progress(&format!(
        "{} edge strips of {sw}×{} px and a {sw}×{sw} vertex patch, cut in (seam error {:.3e} per pixel)",
        2 * lay.colours,
        t + sw,
        vcost / vn.max(1) as f64
    ));

    let (mut icost, mut in_) = (0.0, 0);
    let mut tiles = Vec::with_capacity(lay.tiles());
    for k in 0..lay.tiles() {
        let [cw_, ce, cs, cn] = lay.colours_of(k);
        let (sv_w, sv_e, sh_s, sh_n) = (
            &vertical[cw_],
            &vertical[ce],
            &horizontal[cs],
            &horizontal[cn],
        );
        let hw = t + sw;
        // Each strip at tile pixel (x, y), where it reaches.
        let west = |x: usize, y: usize| &sv_w[((e + y) * sw + e + x) * c..][..c];
        let east = |x: usize, y: usize| &sv_e[((e + y) * sw + x + e - t) * c..][..c];
        let south = |x: usize, y: usize| &sh_s[((e + y) * hw + e + x) * c..][..c];
        let north = |x: usize, y: usize| &sh_n[((y + e - t) * hw + e + x) * c..][..c];
        // A cut: for each row (column), the path's offset into the band, and its error.
        let cut = |err: &dyn Fn(usize, usize) -> f64| -> (Vec<usize>, f64) {
            let mut m_ = vec![0.0; t * w];
            for along in 0..t {
                for r in 0..w {
                    m_[along * w + r] = err(along, r);
                }
            }
            let path = min_cut_vertical(&m_, w, t);
            let cost = path.iter().enumerate().map(|(a, &r)| m_[a * w + r]).sum();
            (path, cost)
        };
        // The interior is the crop, of a few, whose four cuts into the strips cost least
        // (as image quilting picks its patches): seams inside the cells then show as
        // little as the cell borders, which are the strips' own texture.
        let mut best: Option<(f64, Vec<f32>, [Vec<usize>; 4])> = None;
        for _ in 0..INTERIOR_CANDIDATES {
            let (x0, y0) = pick(t, t);
            let img = ex.crop(x0, y0, t, t)?.data;
            let inside = |x: usize, y: usize| &img[(y * t + x) * c..][..c];
            let (cl, a) = cut(&|y, r| sq(west(m + r, y), inside(m + r, y)));
            let (cr, b) = cut(&|y, r| sq(east(t - e + r, y), inside(t - e + r, y)));
            let (ct, d) = cut(&|x, r| sq(south(x, m + r), inside(x, m + r)));
            let (cb, f) = cut(&|x, r| sq(north(x, t - e + r), inside(x, t - e + r)));
            let cost = a + b + d + f;
            if best.as_ref().is_none_or(|(o, _, _)| cost < *o) {
                best = Some((cost, img, [cl, cr, ct, cb]));
            }
        }
        let Some((cost, inner, [cl, cr, ct, cb])) = best else {
            unreachable!("INTERIOR_CANDIDATES > 0")
        };
        let inside = |x: usize, y: usize| &inner[(y * t + x) * c..][..c];
        icost += cost;
        in_ += 4 * t;
        let label = |x: usize, y: usize| -> Label {
            let in_w = x < m + cl[y];
            let in_e = x >= t - e + cr[y];
            let in_s = y < m + ct[x];
            let in_n = y >= t - e + cb[x];
            let vert = in_w || in_e;
            let horiz = in_s || in_n;
            let v = if in_w { Label::West } else { Label::East };
            let h = if in_s { Label::South } else { Label::North };
            match (vert, horiz) {
                (false, false) => Label::Interior,
                (true, false) => v,
                (false, true) => h,
                (true, true) => {
                    let dx = if in_w { x } else { t - 1 - x };
                    let dy = if in_s { y } else { t - 1 - y };
                    if dx < m || (dy >= m && dx <= dy) {
                        v
                    } else {
                        h
                    }
                }
            }
        };
        let mut tile = vec![0.0f32; t * t * c];
        let mut labels = vec![Label::Interior; t * t];
        for y in 0..t {
            for x in 0..t {
                let l = label(x, y);
                labels[y * t + x] = l;
                let src = match l {
                    Label::Interior => inside(x, y),
                    Label::West => west(x, y),
                    Label::East => east(x, y),
                    Label::South => south(x, y),
                    Label::North => north(x, y),
                };
                tile[(y * t + x) * c..(y * t + x + 1) * c].copy_from_slice(src);
            }
        }
        // Each label's own image at tile pixel (x, y), where it reaches.
        let source = |l: Label, x: usize, y: usize| -> Option<&[f32]> {
            match l {
                Label::Interior => Some(inside(x, y)),
                Label::West => (x < e).then(|| west(x, y)),
                Label::East => (x >= t - e).then(|| east(x, y)),
                Label::South => (y < e).then(|| south(x, y)),
                Label::North => (y >= t - e).then(|| north(x, y)),
            }
        };
        heal_cuts(&mut tile, &labels, t, m, c, &source)?;
        tiles.push(tile);
    }
    progress(&format!(
        "{} tiles of {t}×{t} px quilted (interior seam error {:.3e} per pixel)",
        lay.tiles(),
        icost / in_.max(1) as f64
    ));
    Ok(WangTiles {
        tiles,
        vertical,
        horizontal,
        seam_costs: vec![vcost / vn.max(1) as f64, icost / in_.max(1) as f64],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(w: usize, h: usize, seed: u64) -> Raster {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        // Smoothed white noise: correlated like a rough surface.
        let white: Vec<f32> = (0..w * h).map(|_| rng.random::<f32>()).collect();
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let mut s = 0.0;
                for dy in 0..3 {
                    for dx in 0..3 {
                        s += white[((y + dy) % h) * w + (x + dx) % w];
                    }
                }
                s / 9.0
            })
            .collect();
        Raster::from_vec(w, h, 1, data).unwrap()
    }

    /// Acceptance (issue 7): every pair of tiles whose shared edge has the same colour
    /// meets exactly — the m columns (rows) on each side of the edge are the strip of
    /// that colour, unchanged, so across the edge the pixels are neighbours in one crop.
    /// Corners are the vertex patch in every tile.
    #[test]
    fn tiles_sharing_an_edge_colour_meet_exactly() {
        let lay = WangLayout::new(2, 64, None).unwrap();
        let ex = noise(100, 90, 4);
        let wt = wang_tiles(&ex, lay, 9, "noise", &mut |_| {}).unwrap();
        let (t, m, e) = (lay.side, lay.edge, lay.reach());
        let sw = 2 * e;
        assert_eq!(wt.tiles.len(), 16);
        let px = |tile: &[f32], x: usize, y: usize| tile[y * t + x];
        let mut pairs = 0;
        for (ia, a) in wt.tiles.iter().enumerate() {
            for (ib, b) in wt.tiles.iter().enumerate() {
                let (ca, cb) = (lay.colours_of(ia), lay.colours_of(ib));
                // a's east edge against b's west edge.
                if ca[1] == cb[0] {
                    pairs += 1;
                    let s = &wt.vertical[ca[1]];
                    for y in 0..t {
                        for d in 0..m {
                            assert_eq!(px(a, t - 1 - d, y), s[(e + y) * sw + e - 1 - d]);
                            assert_eq!(px(b, d, y), s[(e + y) * sw + e + d]);
                        }
                    }
                }
                // a's north edge against b's south edge.
                if ca[3] == cb[2] {
                    let s = &wt.horizontal[ca[3]];
                    for x in 0..t {
                        for d in 0..m {
                            assert_eq!(px(a, x, t - 1 - d), s[(e - 1 - d) * (t + sw) + e + x]);
                            assert_eq!(px(b, x, d), s[(e + d) * (t + sw) + e + x]);
                        }
                    }
                }
            }
        }
        assert_eq!(pairs, 16 * 8);
        // The strips' ends agree with each other where they overlap: every corner.
        let first = &wt.tiles[0];
        for tile in &wt.tiles {
            for y in 0..m {
                for x in 0..m {
                    assert_eq!(px(tile, x, y), px(first, x, y));
                    assert_eq!(
                        px(tile, t - 1 - x, t - 1 - y),
                        px(first, t - 1 - x, t - 1 - y)
                    );
                }
            }
        }
    }

    #[test]
    fn bad_layouts_name_what_is_wrong() {
        let e = WangLayout::new(0, 64, None).unwrap_err().to_string();
        assert_eq!(
            e,
            "invalid colours = 0: expected 1 to 8 colours per edge direction (K⁴ tiles)"
        );
        assert!(WangLayout::new(2, 48, None).is_err());
        assert!(WangLayout::new(2, 64, Some(40)).is_err());
        let lay = WangLayout::new(2, 64, None).unwrap();
        let e = wang_tiles(&noise(70, 70, 1), lay, 0, "small", &mut |_| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("at least 76×76"), "{e}");
    }

    /// The cuts between a tile's interior and its strips are healed: on the di-6 AFM
    /// map (256 px tiles, K = 2), no row or column of the cut bands (m to e px from an
    /// edge) has more than 1.5× the median gradient energy of the tiles' rows and
    /// columns. The 3×3 mean the seams had before left 1.79 (row 7), 1.69 (column 7) and
    /// 1.56 (column 245); healed, the worst is column 7 at 1.45, the rest ≤ 1.28.
    #[test]
    fn cut_bands_carry_no_seam_energy() {
        let ex = crate::io::read_image("tiles/di-6.npy".as_ref(), &Default::default())
            .unwrap()
            .raster;
        let lay = WangLayout::new(2, 256, None).unwrap();
        let w = wang_tiles(&ex, lay, 0, "di-6", &mut |_| {}).unwrap();
        let (t, m, e) = (lay.side, lay.edge, lay.reach());
        let (mut rows, mut cols) = (vec![0.0f64; t - 1], vec![0.0f64; t - 1]);
        for tile in &w.tiles {
            for y in 0..t {
                for x in 0..t {
                    let v = tile[y * t + x];
                    if y + 1 < t {
                        rows[y] += ((tile[(y + 1) * t + x] - v) as f64).powi(2);
                    }
                    if x + 1 < t {
                        cols[x] += ((tile[y * t + x + 1] - v) as f64).powi(2);
                    }
                }
            }
        }
        for (name, energy) in [("row", &rows), ("column", &cols)] {
            let mut sorted = energy.clone();
            sorted.sort_by(f64::total_cmp);
            let median = sorted[sorted.len() / 2];
            for i in (m - 1..e).chain(t - e - 1..t - m) {
                let ratio = energy[i] / median;
                assert!(ratio <= 1.5, "{name} {i}: {ratio:.2} × the median");
            }
        }
    }
}
