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
//!   (`heal_seams`), except within m px of an edge, which stays the strip's.
//! - **Even lines.** Every cell of a render shows the same vertex patch, one of K strips
//!   per edge and one of K⁴ interiors at the same offsets, so a line of theirs that is
//!   smoother or rougher than the exemplar's typical step shows at that offset of every
//!   cell (issue 31's seam score at any phase). The vertex patch, the strips and the
//!   tile set's mean over each line are brought to the exemplar's mean squared step by
//!   per-line gains on the steps, solved in least squares (`even_lines`).
//!
//! Mip levels are each tile's 2 × 2 box means; edges stay exact down to the level whose
//! texels span m pixels.

use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

use crate::analysis::cut::min_cut_vertical;
use crate::error::{Error, Result};
use crate::raster::Raster;

/// Random crops tried per edge strip: the K strips of a direction are chosen together
/// from K times as many.
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

/// Gradient-domain healing of the cuts in a `w × h × c` image ([`crate::analysis::heal`],
/// seed 003's addition, here on a rectangle with fixed texels). A minimum-error cut
/// through stochastic content still steps where the two crops disagree: on the di-6 AFM
/// map the columns of the cuts, 8–24 px off the cell grid, had 1.3–1.4× the median
/// gradient energy (the 3×3 mean the seams had before blurred them without removing the
/// step). `labels[q]` says which image texel q shows and `source(label, x, y)` that
/// image's texel, where it reaches. Across every pair of neighbours with different
/// labels, the target gradient is one side's own continuation (its image's gradient
/// there; the sides alternating from pixel to pixel, as `heal` does), and the
/// least-squares correction that gives it is solved on the `free` texels with the others
/// held fixed: a tile's m px along its edges (so tiles still meet exactly); in a strip,
/// everything outside the two bands its vertex cuts lie in. Every free region must touch
/// a fixed texel, and
/// no free texel may lie on the image's border (the solve's lattice is a torus).
fn heal_seams<'a>(
    img: &mut [f32],
    (w, h, c): (usize, usize, usize),
    labels: &[u8],
    free: &[bool],
    source: &dyn Fn(u8, usize, usize) -> Option<&'a [f32]>,
) -> Result<()> {
    let lattice = crate::lattice::Lattice::rectangular(w as i64, h as i64)?;
    for k in 0..c {
        let mut b = vec![0.0f64; w * h];
        let mut any = false;
        for Link { q, n, at, next, .. } in free_links(w, h, free) {
            let (lq, ln) = (labels[q], labels[n]);
            if lq == ln {
                continue;
            }
            let step = |l: u8| match (source(l, at.0, at.1), source(l, next.0, next.1)) {
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
            let r = target - (img[n * c + k] as f64 - img[q * c + k] as f64);
            b[n] += r;
            b[q] -= r;
            any = true;
        }
        if any {
            add_correction(img, (c, k), &lattice, free, &b);
        }
    }
    Ok(())
}

/// A link between 4-neighbours q (at `at`) and n (at `next`, one step right or down) of
/// a `w × h` image; `axis` 0 for a step across columns, 1 across rows, and `line` the
/// column (row) it leaves.
struct Link {
    q: usize,
    n: usize,
    at: (usize, usize),
    next: (usize, usize),
    axis: usize,
    line: usize,
}

/// The links of a `w × h` image that touch a free texel, row by row.
fn free_links(w: usize, h: usize, free: &[bool]) -> impl Iterator<Item = Link> + '_ {
    (0..h).flat_map(move |y| {
        (0..w).flat_map(move |x| {
            [(x + 1, y, 0, x), (x, y + 1, 1, y)]
                .into_iter()
                .filter(move |&(nx, ny, _, _)| {
                    nx < w && ny < h && (free[y * w + x] || free[ny * w + nx])
                })
                .map(move |(nx, ny, axis, line)| Link {
                    q: y * w + x,
                    n: ny * w + nx,
                    at: (x, y),
                    next: (nx, ny),
                    axis,
                    line,
                })
        })
    })
}

/// Adds to channel `k` of an image with `c` channels, on its free texels, the masked
/// Poisson correction whose divergence is `rhs` ([`crate::analysis::heal::solve_masked`]).
fn add_correction(
    img: &mut [f32],
    (c, k): (usize, usize),
    lattice: &crate::lattice::Lattice,
    free: &[bool],
    rhs: &[f64],
) {
    let correction = crate::analysis::heal::solve_masked(lattice, free, rhs);
    for (q, &v) in correction.iter().enumerate() {
        if free[q] {
            img[q * c + k] = (img[q * c + k] as f64 + v) as f32;
        }
    }
}

/// Most rounds of [`even_lines`]: each scales every line's steps by the square root of
/// its remaining ratio and re-solves, until they are all within 2% of their target.
const EVEN_ROUNDS: usize = 3;

/// Evens out the steps of every line of a piece that many tiles share, in place: for
/// each line between neighbouring columns (rows) of the `w × h × c` image, the mean
/// squared step across it over the links that touch a `free` texel is brought towards
/// `target.0` (`target.1`; 0 leaves that direction as it is) by scaling those steps by
/// √(target / mean), at most 2× either way in one round, and solving for the image whose
/// steps are closest to the scaled ones in least squares, the texels that are not free
/// held fixed (a masked Poisson solve, as [`heal_seams`]; the same rules on `free`
/// apply). Rounds repeat up to [`EVEN_ROUNDS`] times, so a line's steps can change by
/// more than 2× in all. A vertex patch is in every tile and
/// a strip in 1/K of them, always at the same offsets, so any line of theirs that is
/// rougher or smoother than typical shows in the render at that offset of every cell,
/// whatever is chosen around it: on di-6 (256 px tiles, K = 4), the vertex patch's rows
/// read 2.3–2.4× the median step in the tiles' W and E bands at tile row 3, and the
/// strips that best made up for it along the whole row left 0.62–0.89 in the cell's
/// middle, 0.72 over all four. The solve is a least-squares compromise between
/// neighbouring lines' gains, so no single step is guaranteed its line's factor.
fn even_lines(
    img: &mut [f32],
    dims: (usize, usize, usize),
    free: &[bool],
    target: (f64, f64),
) -> Result<()> {
    for _ in 0..EVEN_ROUNDS {
        let gains = line_gains(&[line_steps(img, dims, free)], target);
        if even(&gains) {
            break;
        }
        scale_lines(img, dims, free, &gains)?;
    }
    Ok(())
}

/// Whether every gain is within 1% of 1 (each line's mean squared step within 2% of its
/// target): nothing left worth a solve.
fn even(gains: &[Vec<f64>; 2]) -> bool {
    gains.iter().flatten().all(|g| (g - 1.0).abs() <= 0.01)
}

/// Sum of squared steps and count per line of a `w × h × c` image over the links that
/// touch a free texel: `[0][x]` between columns x and x + 1, `[1][y]` between rows y and
/// y + 1.
type LineSteps = [Vec<(f64, usize)>; 2];

fn line_steps(img: &[f32], (w, h, c): (usize, usize, usize), free: &[bool]) -> LineSteps {
    let mut lines = [vec![(0.0f64, 0usize); w], vec![(0.0f64, 0usize); h]];
    for Link {
        q, n, axis, line, ..
    } in free_links(w, h, free)
    {
        let l = &mut lines[axis][line];
        l.0 += sq(&img[q * c..][..c], &img[n * c..][..c]);
        l.1 += 1;
    }
    lines
}

/// Per line, √(target / mean squared step) over the summed `steps` of several images of
/// one shape, within [1/2, 2]; 1 where a line has no links.
fn line_gains(steps: &[LineSteps], target: (f64, f64)) -> [Vec<f64>; 2] {
    [0, 1].map(|axis| {
        let t = if axis == 0 { target.0 } else { target.1 };
        (0..steps[0][axis].len())
            .map(|i| {
                let (s, n) = steps
                    .iter()
                    .fold((0.0, 0), |(s, n), l| (s + l[axis][i].0, n + l[axis][i].1));
                if n == 0 || s <= 0.0 || t <= 0.0 {
                    1.0
                } else {
                    (t * n as f64 / s).sqrt().clamp(0.5, 2.0)
                }
            })
            .collect()
    })
}

/// The image whose steps are closest in least squares to its own steps scaled by
/// `gains` (per line, as [`line_steps`] numbers them), the texels that are not free held
/// fixed: one masked Poisson solve per channel.
fn scale_lines(
    img: &mut [f32],
    (w, h, c): (usize, usize, usize),
    free: &[bool],
    gains: &[Vec<f64>; 2],
) -> Result<()> {
    let lattice = crate::lattice::Lattice::rectangular(w as i64, h as i64)?;
    for k in 0..c {
        let mut b = vec![0.0f64; w * h];
        for Link {
            q, n, axis, line, ..
        } in free_links(w, h, free)
        {
            let d = img[n * c + k] as f64 - img[q * c + k] as f64;
            let r = d * (gains[axis][line] - 1.0);
            b[n] += r;
            b[q] -= r;
        }
        add_correction(img, (c, k), &lattice, free, &b);
    }
    Ok(())
}

/// Squared difference of two pixels, summed over channels.
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
/// returns the summed path error and the number of path pixels. With `heal`, the cuts are
/// then healed in the gradient domain ([`heal_seams`]) inside the two bands: the 3×3 mean
/// that smoothed them before left a step that every tile with the strip's colour showed at
/// the same rows of its W or E columns (di-6, 256 px tiles: 3.7× and 6.5× the median
/// gradient energy on tile rows 232 and 233 there, 1.5× over the whole row).
fn cut_vertex_into(
    strip: &mut [f32],
    v: &[f32],
    lay: &WangLayout,
    c: usize,
    heal: bool,
) -> Result<(f64, usize)> {
    let (t, m, w, e) = (lay.side, lay.edge, lay.band, lay.reach());
    let (sw, sh) = (2 * e, t + 2 * e);
    let crop = heal.then(|| strip.to_vec());
    // Strip and vertex patch are both 2e wide.
    let px = |x: usize, y: usize| (y * sw + x) * c;
    // Strip row → vertex row: the top end's (tile row 0 is strip row e) and the bottom's.
    let vrow = |sy: usize| if sy < sw { Some(sy) } else { sy.checked_sub(t) };
    let mut labels = vec![0u8; sw * sh];
    let (mut cost, mut n) = (0.0, 0);
    for top in [true, false] {
        // Band rows, and the pure vertex rows beyond them.
        let band0 = if top { e + m } else { t };
        let pure = if top { 0..e + m } else { t + w..sh };
        for sy in pure {
            labels[sy * sw..(sy + 1) * sw].fill(1);
        }
        let mut err = vec![0.0; sw * w];
        for sx in 0..sw {
            for r in 0..w {
                let sy = band0 + r;
                let (a, b) = (px(sx, sy), px(sx, vrow(sy).unwrap_or(0)));
                err[sx * w + r] = sq(&strip[a..a + c], &v[b..b + c]);
            }
        }
        let path = min_cut_vertical(&err, w, sw);
        for sx in 0..sw {
            cost += err[sx * w + path[sx]];
            n += 1;
            for r in 0..w {
                if (top && r < path[sx]) || (!top && r > path[sx]) {
                    labels[(band0 + r) * sw + sx] = 1;
                }
            }
        }
    }
    for sy in 0..sh {
        for sx in 0..sw {
            if labels[sy * sw + sx] == 1 {
                let (a, b) = (px(sx, sy), px(sx, vrow(sy).unwrap_or(0)));
                strip[a..a + c].copy_from_slice(&v[b..b + c]);
            }
        }
    }
    if let Some(crop) = crop {
        let free: Vec<bool> = (0..sw * sh)
            .map(|q| {
                let (x, y) = (q % sw, q / sw);
                let band = (e + m..e + m + w).contains(&y) || (t..t + w).contains(&y);
                band && x > 0 && x + 1 < sw
            })
            .collect();
        let source = |l: u8, x: usize, y: usize| -> Option<&[f32]> {
            if l == 0 {
                Some(&crop[px(x, y)..][..c])
            } else {
                vrow(y).map(|vy| &v[px(x, vy)..][..c])
            }
        };
        heal_seams(strip, (sw, sh, c), &labels, &free, &source)?;
    }
    Ok((cost, n))
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

/// The labels in the order of their codes (`Label as u8`).
const LABELS: [Label; 5] = [
    Label::Interior,
    Label::West,
    Label::East,
    Label::South,
    Label::North,
];

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
    // How a strip-shaped image (2e wide, in the vertical frame) compares with typical
    // across its edge, over `rows`: for every line between neighbouring columns within
    // m + 1 px of the edge line (between columns e − 1 and e), the mean squared step
    // across it over `target`. The strip's columns within m px of the edge go unchanged
    // into every tile with that colour there, at the same offsets, so a strip that is
    // smoother or rougher a few pixels beside the edge shows as a seam at that offset of
    // every cell.
    let across = |img: &[f32], rows: std::ops::Range<usize>, target: f64| -> Vec<f64> {
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
                (s / n.max(1) as f64).max(1e-300) / target.max(1e-300)
            })
            .collect()
    };
    let off = |ratios: &[f64]| ratios.iter().map(|r| r.ln().abs()).sum::<f64>();
    // The vertex patch ends every strip, so it too is the most typical of a few crops,
    // by its steps across both centre lines.
    let mut best = (f64::INFINITY, (0, 0));
    for _ in 0..STRIP_CANDIDATES {
        let at = pick(sw + 2, sw + 2);
        let v = ex.crop(at.0 + 1, at.1 + 1, sw, sw)?.data;
        let o = off(&across(&v, 0..sw, along_x))
            + off(&across(&transpose(&v, sw, sw, c), 0..sw, along_y));
        if o < best.0 {
            best = (o, at);
        }
    }
    // Its lines evened out, with the exemplar's ring around it held fixed.
    let vertex = {
        let p = sw + 2;
        let mut v = ex.crop(best.1.0, best.1.1, p, p)?.data;
        let free: Vec<bool> = (0..p * p)
            .map(|q| (1..=sw).contains(&(q % p)) && (1..=sw).contains(&(q / p)))
            .collect();
        even_lines(&mut v, (p, p, c), &free, (along_x, along_y))?;
        let mut inner = Vec::with_capacity(sw * sw * c);
        for y in 1..=sw {
            inner.extend_from_slice(&v[(y * p + 1) * c..(y * p + 1 + sw) * c]);
        }
        inner
    };
    let vertex_t = transpose(&vertex, sw, sw, c);
    let (mut vcost, mut vn) = (0.0, 0);
    // The K strips of a direction are chosen together from K · STRIP_CANDIDATES random
    // crops, each with the vertex patch cut into its ends: hashed colours put every strip
    // in 1/K of the cells, so the figure a render shows at each line within m + 1 px of
    // the edge is the mean over the K strips of that line's step. Each strip in turn is
    // the candidate that brings the running mean closest to typical on its worst line
    // (then on the sum), not the one most typical alone. Judged alone on the sum of
    // |ln ratio|, di-6's two horizontal strips both came out smooth on tile rows 247–248
    // (0.52 and 0.89 of the typical step), and a 4096² render read 0.60 of the median
    // there. Horizontal strips are vertical ones in the transposed frame, with the
    // transposed vertex.
    let mut strips = |vertical: bool| -> Result<Vec<Vec<f32>>> {
        let (target, v) = if vertical {
            (along_x, &vertex)
        } else {
            (along_y, &vertex_t)
        };
        let crop = |(x0, y0): (usize, usize)| -> Result<Vec<f32>> {
            Ok(if vertical {
                ex.crop(x0, y0, sw, t + sw)?.data
            } else {
                transpose(&ex.crop(x0, y0, t + sw, sw)?.data, t + sw, sw, c)
            })
        };
        let mut pool = Vec::with_capacity(lay.colours * STRIP_CANDIDATES);
        for _ in 0..lay.colours * STRIP_CANDIDATES {
            let at = if vertical {
                pick(sw, t + sw)
            } else {
                pick(t + sw, sw)
            };
            let mut img = crop(at)?;
            cut_vertex_into(&mut img, v, &lay, c, false)?;
            pool.push((at, across(&img, e..e + t, target)));
        }
        let lines = 2 * m + 1;
        let mut sum = vec![0.0; lines];
        let mut taken = vec![false; pool.len()];
        let mut out = Vec::with_capacity(lay.colours);
        for k in 0..lay.colours {
            let score = |r: &[f64]| {
                let devs = (0..lines).map(|j| ((sum[j] + r[j]) / (k + 1) as f64).ln().abs());
                devs.fold((0.0f64, 0.0), |(mx, s), d| (mx.max(d), s + d))
            };
            // Ordered by total_cmp, so a score that overflows or is NaN (a flat strip
            // line against a huge target) still ranks, last.
            let Some((i, _)) = pool
                .iter()
                .enumerate()
                .filter(|(i, _)| !taken[*i])
                .map(|(i, (_, r))| (i, score(r)))
                .min_by(|(_, a), (_, b)| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)))
            else {
                unreachable!("the pool holds K · STRIP_CANDIDATES > K crops")
            };
            taken[i] = true;
            sum.iter_mut().zip(&pool[i].1).for_each(|(s, r)| *s += r);
            let mut img = crop(pool[i].0)?;
            let (a, b) = cut_vertex_into(&mut img, v, &lay, c, true)?;
            // Its lines evened out too ([`even_lines`]), the pure vertex rows at its ends
            // and its outer columns held fixed: the lines across the edge over the strip's
            // length between the pure vertex rows (tile rows m to T − m), then the lines
            // along it over the 2m columns that tiles keep unchanged (the rest of a tile
            // is evened with the tile set, below).
            let free: Vec<bool> = (0..sw * (t + sw))
                .map(|q| {
                    let (x, y) = (q % sw, q / sw);
                    x > 0 && x + 1 < sw && (e + m..t + w).contains(&y)
                })
                .collect();
            let (target, along) = if vertical {
                (along_x, along_y)
            } else {
                (along_y, along_x)
            };
            let kept: Vec<bool> = (0..sw * (t + sw))
                .map(|q| free[q] && (e - m..e + m).contains(&(q % sw)))
                .collect();
            for _ in 0..EVEN_ROUNDS {
                even_lines(&mut img, (sw, t + sw, c), &free, (target, 0.0))?;
                even_lines(&mut img, (sw, t + sw, c), &kept, (0.0, along))?;
            }
            (vcost, vn) = (vcost + a, vn + b);
            out.push(img);
        }
        Ok(out)
    };
    let vertical = strips(true)?;
    let horizontal: Vec<Vec<f32>> = strips(false)?
        .iter()
        .map(|s| transpose(s, sw, t + sw, c))
        .collect();
    progress(&format!(
        "{} edge strips of {sw}×{} px and a {sw}×{sw} vertex patch, cut in (seam error {:.3e} per pixel)",
        2 * lay.colours,
        t + sw,
        vcost / vn.max(1) as f64
    ));

    let (mut icost, mut in_) = (0.0, 0);
    // Tiles are healed everywhere but within m px of an edge, which stays the strip's.
    let free: Vec<bool> = (0..t * t)
        .map(|q| {
            let (x, y) = (q % t, q / t);
            x >= m && y >= m && x + m < t && y + m < t
        })
        .collect();
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
        let mut labels = vec![Label::Interior as u8; t * t];
        for y in 0..t {
            for x in 0..t {
                let l = label(x, y);
                labels[y * t + x] = l as u8;
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
        let source = |l: u8, x: usize, y: usize| -> Option<&[f32]> {
            match LABELS[l as usize] {
                Label::Interior => Some(inside(x, y)),
                Label::West => (x < e).then(|| west(x, y)),
                Label::East => (x >= t - e).then(|| east(x, y)),
                Label::South => (y < e).then(|| south(x, y)),
                Label::North => (y >= t - e).then(|| north(x, y)),
            }
        };
        heal_seams(&mut tile, (t, t, c), &labels, &free, &source)?;
        tiles.push(tile);
    }
    // The tile set's lines evened out: hashed colours make every tile equally likely in
    // a cell, so what a render reads at each offset of the cell is the mean over the
    // tiles of that line's steps. With 16 tiles, their interiors alone left 0.77–1.29 of
    // the median on di-6's rows (4096² render); each line gets one gain for all tiles,
    // so the tiles keep their own line-to-line differences.
    for _ in 0..EVEN_ROUNDS {
        let steps: Vec<LineSteps> = tiles
            .iter()
            .map(|tile| line_steps(tile, (t, t, c), &free))
            .collect();
        let gains = line_gains(&steps, (along_x, along_y));
        if even(&gains) {
            break;
        }
        // Each tile is solved on its own: in parallel, each result its own.
        let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
        let chunk = tiles.len().div_ceil(workers).max(1);
        std::thread::scope(|scope| {
            let runs: Vec<_> = tiles
                .chunks_mut(chunk)
                .map(|group| {
                    let (free, gains) = (&free, &gains);
                    scope.spawn(move || {
                        group
                            .iter_mut()
                            .try_for_each(|tile| scale_lines(tile, (t, t, c), free, gains))
                    })
                })
                .collect();
            runs.into_iter()
                .try_for_each(|r| r.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
        })?;
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

    /// Issue 31: every line of a cell reads like every other. On the di-6 AFM map (256 px
    /// tiles, K = 2), the mean squared step across each of the T lines between columns
    /// (rows) of a cell — the T − 1 inside a tile, averaged over the 16 tiles as hashed
    /// colours weight them, and the cell border, averaged over every pair of tiles that
    /// can meet there — lies within [0.9, 1.15] of those lines' median, the bar of the
    /// seam score at any phase. Before the lines were evened, rows 247–248 read 0.79
    /// (both N strips smooth there), row 234 1.29 and column 7 1.45 (in cut bands); now
    /// 0.96–1.09 (docs/structure.md, "Quilt on di-6").
    #[test]
    fn every_line_of_a_cell_carries_the_typical_step() {
        let ex = crate::io::read_image("tiles/di-6.npy".as_ref(), &Default::default())
            .unwrap()
            .raster;
        let lay = WangLayout::new(2, 256, None).unwrap();
        let w = wang_tiles(&ex, lay, 0, "di-6", &mut |_| {}).unwrap();
        let t = lay.side;
        let px = |tile: &[f32], x: usize, y: usize| tile[y * t + x] as f64;
        // [0][x]: between columns x and x + 1 (x = T − 1: across the cell border).
        let mut lines = [vec![0.0f64; t], vec![0.0f64; t]];
        for tile in &w.tiles {
            for y in 0..t {
                let [cols, rows] = &mut lines;
                for (i, (across, down)) in cols.iter_mut().zip(rows).enumerate() {
                    if i + 1 < t {
                        *across += (px(tile, i + 1, y) - px(tile, i, y)).powi(2) / t as f64;
                        *down += (px(tile, y, i + 1) - px(tile, y, i)).powi(2) / t as f64;
                    }
                }
            }
        }
        let n = w.tiles.len() as f64;
        lines
            .iter_mut()
            .for_each(|l| l.iter_mut().for_each(|v| *v /= n));
        let (mut border, mut pairs) = ([0.0f64; 2], [0usize; 2]);
        for (ia, a) in w.tiles.iter().enumerate() {
            for (ib, b) in w.tiles.iter().enumerate() {
                let (ca, cb) = (lay.colours_of(ia), lay.colours_of(ib));
                let meet = [ca[1] == cb[0], ca[3] == cb[2]];
                for axis in 0..2 {
                    if !meet[axis] {
                        continue;
                    }
                    pairs[axis] += 1;
                    border[axis] += (0..t)
                        .map(|i| {
                            let (p, q) = if axis == 0 {
                                (px(a, t - 1, i), px(b, 0, i))
                            } else {
                                (px(a, i, t - 1), px(b, i, 0))
                            };
                            (q - p).powi(2) / t as f64
                        })
                        .sum::<f64>();
                }
            }
        }
        for axis in 0..2 {
            lines[axis][t - 1] = border[axis] / pairs[axis] as f64;
            let mut sorted = lines[axis].clone();
            sorted.sort_by(f64::total_cmp);
            let median = sorted[t / 2];
            for (i, e) in lines[axis].iter().enumerate() {
                let ratio = e / median;
                let name = ["column", "row"][axis];
                assert!(
                    (0.9..=1.15).contains(&ratio),
                    "{name} line {i}: {ratio:.3} × the median"
                );
            }
        }
    }
}
