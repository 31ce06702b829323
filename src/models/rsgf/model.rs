//! The RSGF model: block geometry, the tables of similar patches, random picks, the
//! composition of blocks into pixels, and the sequential whole-image reference
//! (seed 002 §4; ALGORITHMS.md §4).
//!
//! **Blocks.** Output block (I, J) covers [I·B, (I+1)·B) × [J·B, (J+1)·B); its patch is
//! the exemplar square of side E = B + 2·o whose top-left corner is the block's
//! *position* q, laid on the output with its corner at the block's *origin*
//! (I·B − o, J·B − o). Neighbouring patches overlap by 2·o pixels across each block edge.
//!
//! **Similar patches** (§4.1). Positions whose offset from the origin is a lattice vector
//! a·v₁ + b·v₂ hold the "same" part of the regular structure. The lattice's Hermite
//! normal form (ALGORITHMS.md §1) turns "offset is a lattice vector" into "same residue",
//! so every position of the exemplar is filed once, under its residue, when the model is
//! built; a block then finds its candidates in O(1). A residue with no position in the
//! exemplar (a lattice cell larger than the room left for patches) borrows those of the
//! nearest residues, ring by ring in Chebyshev distance, so every block has candidates.

use crate::error::{Error, Result};
use crate::hash::hash_cell;
use crate::lattice::Lattice;
use crate::raster::Raster;

use super::gap::GapTables;
use super::{Join, RsgfParams};

/// An edge between two neighbouring blocks: `V` (i, j) between blocks (i − 1, j) and
/// (i, j), `H` (i, j) between (i, j − 1) and (i, j).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Edge {
    V,
    H,
}

/// Hash stream of the random picks (ASCII "RSGF").
const STREAM_RANDOM: u32 = 0x5253_4746;

/// Largest exemplar the model accepts, in pixels.
pub const MAX_EXEMPLAR_PIXELS: usize = 1 << 22;

/// Residue index ry·A + rx of the integer point p in the lattice's fundamental domain
/// [0, A) × [0, C) ([`Lattice::reduce`]'s local part), in modular arithmetic so that
/// no product overflows for any |p| < 2⁶² (A, C ≤ 2²²).
fn residue(l: Lattice, p: (i64, i64)) -> usize {
    let j = p.1.div_euclid(l.c);
    let ry = p.1 - j * l.c;
    let shift = (j.rem_euclid(l.a) * l.b).rem_euclid(l.a);
    let rx = (p.0.rem_euclid(l.a) - shift).rem_euclid(l.a);
    (ry * l.a + rx) as usize
}

/// Smallest mip level side kept.
const MIN_LEVEL_SIDE: usize = 4;

/// The exemplar at one mip level: `w × h × channels`, interleaved.
pub(crate) struct Level {
    pub w: usize,
    pub h: usize,
    pub data: Vec<f32>,
}

/// Farthest (Chebyshev, px) a residue without patch positions borrows those of its
/// neighbours; beyond it the exemplar does not show the lattice's period.
pub const MAX_NEAR_OFFSET: i64 = 8;

/// Lists of positions (indices qy·nx + qx), one per residue, packed (CSR).
struct Lists {
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Lists {
    fn get(&self, r: usize) -> &[u32] {
        &self.items[self.start[r] as usize..self.start[r + 1] as usize]
    }
}

/// Everything a pick and a pixel need, built once from the exemplar.
pub struct RsgfModel {
    pub(crate) params: RsgfParams,
    /// Channels.
    pub(crate) c: usize,
    /// Exemplar mip chain, level 0 first.
    pub(crate) levels: Vec<Level>,
    pub(crate) lattice: Lattice,
    /// Block side B and border o (a patch is E = B + 2·o pixels square).
    pub(crate) b: i64,
    pub(crate) o: i64,
    /// Patch positions per row: W − E + 1.
    pub(crate) nx: usize,
    /// Width of the mirrored frame around the exemplar in level 0 (o with
    /// [`RsgfParams::reflect_edges`], else 0).
    pad: usize,
    /// What a cut pays for each of its pixels that would show a mirrored one.
    mirror_cost: f64,
    /// Positions filed by residue, exactly.
    exact: Lists,
    /// As `exact`, with empty residues replaced by their nearest non-empty ones.
    near: Lists,
    pub(crate) gap: GapTables,
    /// The torus's side, where patches wrap.
    torus: Option<(usize, usize)>,
}

impl RsgfModel {
    /// Builds the model of `exemplar` (finite values, any channel count) with `params`.
    pub fn new(exemplar: &Raster, params: &RsgfParams) -> Result<RsgfModel> {
        params.validate()?;
        params.check_exemplar(exemplar.width, exemplar.height)?;
        if exemplar.data.iter().any(|v| !v.is_finite()) {
            return Err(Error::param(
                "RSGF exemplar",
                "(NaN or infinite samples)",
                "finite values: fill missing points first",
            ));
        }
        let (c, pad) = (exemplar.channels, params.reflect_edges);
        if !(1..=4).contains(&c) {
            return Err(Error::param("RSGF exemplar channels", c, "1 to 4 channels"));
        }
        let (w, h) = (exemplar.width, exemplar.height);
        if w * h > MAX_EXEMPLAR_PIXELS {
            return Err(Error::Limits(format!(
                "an RSGF exemplar of {w}×{h} pixels (at most 2^22, e.g. 2048²: the gap search keeps per-position tables and spectra of it)"
            )));
        }
        let (bp, op) = (params.block_px, params.border_px);
        if params.wrap_edges
            && wrapped_side(w, bp, op) * wrapped_side(h, bp, op) > MAX_EXEMPLAR_PIXELS
        {
            return Err(Error::Limits(format!(
                "an RSGF exemplar of {w}×{h} pixels wrapped with patches of {} px (the repeated torus, up to {}×{}, is searched like an exemplar: at most 2^22 pixels; use --edges reflect)",
                bp + 2 * op,
                wrapped_side(w, bp, op),
                wrapped_side(h, bp, op)
            )));
        }
        if let Some(maps) = &params.histogram {
            check_histogram(maps, c)?;
        }
        let lattice = Lattice::from_basis(params.v1, params.v2)?;
        let cells = lattice.a as u128 * lattice.c as u128;
        if cells > (w * h) as u128 {
            return Err(Error::param(
                "lattice",
                format!(
                    "({},{});({},{}) with a cell of {cells} px",
                    params.v1.0, params.v1.1, params.v2.0, params.v2.1
                ),
                format!(
                    "a cell no larger than the {w}×{h} exemplar (it must show at least one period)"
                ),
            ));
        }
        let (b, o) = (params.block_px as i64, params.border_px as i64);
        // Positions index the extended exemplar; a position's residue is that of its
        // block's corner in the exemplar's own coordinates.
        let extended;
        let mut torus_size = None;
        let (source, shift) = if pad {
            extended = reflect_pad(exemplar, params.border_px);
            (&extended, o)
        } else if params.wrap_edges {
            let torus = wrap_torus(exemplar, 2 * params.border_px, params.feather_px);
            torus_size = Some((torus.width, torus.height));
            extended = wrap_extend(&torus, (b + 2 * o - 1) as usize);
            (&extended, 0)
        } else {
            (exemplar, 0)
        };
        let (w, h) = (source.width, source.height);
        let ext = params.block_px + 2 * params.border_px;
        let (nx, ny) = (w + 1 - ext, h + 1 - ext);
        let residues = cells as usize;
        let residue_of = |qx: i64, qy: i64| residue(lattice, (qx - shift, qy - shift));
        // Exact lists: every position under its residue, in position order.
        let mut count = vec![0u32; residues + 1];
        for qy in 0..ny {
            for qx in 0..nx {
                count[residue_of(qx as i64, qy as i64) + 1] += 1;
            }
        }
        for r in 0..residues {
            count[r + 1] += count[r];
        }
        let mut items = vec![0u32; nx * ny];
        let mut fill = count.clone();
        for qy in 0..ny {
            for qx in 0..nx {
                let r = residue_of(qx as i64, qy as i64);
                items[fill[r] as usize] = (qy * nx + qx) as u32;
                fill[r] += 1;
            }
        }
        let exact = Lists {
            start: count,
            items,
        };
        // Near lists: an empty residue takes the positions of the residues at the
        // smallest Chebyshev offset d that has any.
        let mut near_start = Vec::with_capacity(residues + 1);
        let mut near_items = Vec::new();
        near_start.push(0u32);
        for r in 0..residues {
            let list = exact.get(r);
            if !list.is_empty() {
                near_items.extend_from_slice(list);
            } else {
                let (rx, ry) = ((r as i64) % lattice.a, (r as i64) / lattice.a);
                let mut found: Vec<u32> = Vec::new();
                let mut d = 1i64;
                while found.is_empty() {
                    // A residue with no position nearby: the exemplar does not show this
                    // part of the period (a cell taller or wider than the exemplar's
                    // patch positions). Refused, where an unbounded search would scan
                    // rings as wide as the cell for every such residue.
                    if d > MAX_NEAR_OFFSET {
                        return Err(Error::param(
                            "lattice",
                            format!(
                                "({},{});({},{})",
                                params.v1.0, params.v1.1, params.v2.0, params.v2.1
                            ),
                            format!(
                                "a period the {w}×{h} exemplar shows: residue ({rx}, {ry}) of its {}×{} cell has no patch position within {MAX_NEAR_OFFSET} px ({nx}×{ny} positions for patches of {ext} px)",
                                lattice.a, lattice.c
                            ),
                        ));
                    }
                    // The ring at Chebyshev offset d only.
                    for k in -d..=d {
                        for (dx, dy) in [(k, -d), (k, d)] {
                            found.extend_from_slice(exact.get(residue_of(rx + dx, ry + dy)));
                        }
                        if k.abs() < d {
                            for (dx, dy) in [(-d, k), (d, k)] {
                                found.extend_from_slice(exact.get(residue_of(rx + dx, ry + dy)));
                            }
                        }
                    }
                    d += 1;
                }
                found.sort_unstable();
                found.dedup();
                near_items.extend_from_slice(&found);
            }
            let end = u32::try_from(near_items.len())
                .map_err(|_| Error::Limits("RSGF similar-patch table over 2^32 entries".into()))?;
            near_start.push(end);
        }
        let near = Lists {
            start: near_start,
            items: near_items,
        };
        let levels = mip_chain(source);
        let gap = GapTables::new(source, params);
        // A cut through mirrored pixels costs more than any path through the exemplar's
        // own: a million times the largest squared difference of one pixel.
        let spread: f64 = (0..c)
            .map(|ch| {
                let (lo, hi) = exemplar
                    .data
                    .iter()
                    .skip(ch)
                    .step_by(c)
                    .fold((f64::MAX, f64::MIN), |(l, h), &v| {
                        (l.min(v as f64), h.max(v as f64))
                    });
                (hi - lo) * (hi - lo)
            })
            .sum();
        Ok(RsgfModel {
            params: params.clone(),
            c,
            levels,
            lattice,
            b,
            o,
            nx,
            pad: shift as usize,
            mirror_cost: 1e6 * spread.max(f64::MIN_POSITIVE),
            exact,
            near,
            gap,
            torus: torus_size,
        })
    }

    /// Width and height of the torus the patches wrap around
    /// ([`RsgfParams::wrap_edges`]), or None.
    pub fn torus(&self) -> Option<(usize, usize)> {
        self.torus
    }

    /// Residue index of the integer point p.
    pub(crate) fn residue(&self, p: (i64, i64)) -> usize {
        residue(self.lattice, p)
    }

    /// Positions of residue r (possibly none): those whose offset from a point of
    /// that residue is exactly a lattice vector.
    pub(crate) fn exact_list(&self, r: usize) -> &[u32] {
        self.exact.get(r)
    }

    /// Positions similar to p: the exact ones, or the nearest where there are none.
    pub(crate) fn near_candidates(&self, p: (i64, i64)) -> &[u32] {
        self.near.get(self.residue(p))
    }

    /// The origin (top-left of the patch) of block (i, j) in output pixels.
    #[inline]
    pub(crate) fn origin(&self, i: i64, j: i64) -> (i64, i64) {
        (i * self.b - self.o, j * self.b - self.o)
    }

    /// The first and last block whose patch reaches pixels s0 ..= s1 along one axis.
    #[inline]
    pub(crate) fn block_range(&self, s0: i64, s1: i64) -> (i64, i64) {
        (
            (s0 - self.o).div_euclid(self.b),
            (s1 + self.o).div_euclid(self.b),
        )
    }

    /// Whether block (i, j) is a random block (I + J even) rather than a gap.
    #[inline]
    pub fn is_random(i: i64, j: i64) -> bool {
        (i.wrapping_add(j)) & 1 == 0
    }

    /// The position of random block (i, j): one of its similar positions, chosen by
    /// hash(seed, i, j) (§4.1).
    pub fn random_pick(&self, seed: u32, i: i64, j: i64) -> u32 {
        let list = self.near_candidates(self.origin(i, j));
        let h = hash_cell(seed, i, j, STREAM_RANDOM)[0];
        list[((h as u64 * list.len() as u64) >> 32) as usize]
    }

    /// Position index → (qx, qy).
    #[inline]
    pub(crate) fn position(&self, q: u32) -> (usize, usize) {
        (q as usize % self.nx, q as usize / self.nx)
    }

    /// The blocks that cover integer coordinate `s` along one axis, with their linear
    /// blending weights: one block of weight 1 inside, two across the 2·o pixels around
    /// an edge (weight (k + ½)/(2·o) for the block after it, k = 0 … 2·o − 1).
    #[inline]
    pub(crate) fn axis(&self, s: i64) -> [(i64, f32); 2] {
        let i = s.div_euclid(self.b);
        let u = s - i * self.b;
        let (edge_block, k) = if 2 * u < self.b {
            (i, u + self.o)
        } else {
            (i + 1, u - self.b + self.o)
        };
        if k < 0 {
            [(edge_block - 1, 1.0), (edge_block, 0.0)]
        } else if k >= 2 * self.o {
            [(edge_block, 1.0), (edge_block - 1, 0.0)]
        } else {
            let wr = (k as f32 + 0.5) / (2 * self.o) as f32;
            [(edge_block - 1, 1.0 - wr), (edge_block, wr)]
        }
    }

    /// As [`RsgfModel::axis`] for a real coordinate (prefiltered samples).
    pub(crate) fn axis_f(&self, s: f64) -> [(i64, f32); 2] {
        let bf = self.b as f64;
        let edge_block = (s / bf).round() as i64;
        let t = s - edge_block as f64 * bf + self.o as f64 + 0.5;
        let wr = (t / (2 * self.o) as f64).clamp(0.0, 1.0) as f32;
        [(edge_block - 1, 1.0 - wr), (edge_block, wr)]
    }

    /// Channel values of pixel (px, py), from the positions `pick(i, j)` of the blocks
    /// around it and, for [`Join::Cut`], the cuts `cut(edge, i, j, t)` of the edges
    /// between them ([`RsgfModel::edge_cut`]). The definition every fill must reproduce
    /// bit for bit.
    pub(crate) fn pixel(
        &self,
        px: i64,
        py: i64,
        pick: &mut dyn FnMut(i64, i64) -> u32,
        cut: &mut dyn FnMut(Edge, i64, i64, usize) -> u16,
        out: &mut [f32],
    ) {
        self.pixel_raw(px, py, pick, cut, out);
        self.remap(out);
    }

    /// Applies the histogram map of [`RsgfParams::histogram`], if any, to one sample.
    #[inline]
    pub(crate) fn remap(&self, out: &mut [f32]) {
        if let Some(maps) = &self.params.histogram {
            for (v, map) in out[..self.c].iter_mut().zip(maps) {
                *v = map_value(map, *v);
            }
        }
    }

    /// [`RsgfModel::pixel`] before the histogram map.
    fn pixel_raw(
        &self,
        px: i64,
        py: i64,
        pick: &mut dyn FnMut(i64, i64) -> u32,
        cut: &mut dyn FnMut(Edge, i64, i64, usize) -> u16,
        out: &mut [f32],
    ) {
        let c = self.c;
        let l0 = &self.levels[0];
        if self.params.join == Join::Cut {
            let rows = self.split(Edge::H, py, px.div_euclid(self.b), px, cut);
            if rows[1].1 == 0.0 {
                return self.row_pixel(rows[0].0, px, py, pick, cut, out);
            }
            let mut v = [0.0f32; 4];
            out[..c].fill(0.0);
            for (j, wy) in rows {
                if wy != 0.0 {
                    self.row_pixel(j, px, py, pick, cut, &mut v);
                    add_scaled(&mut out[..c], wy, &v[..c]);
                }
            }
            return;
        }
        out[..c].fill(0.0);
        self.taps(
            self.axis(px),
            self.axis(py),
            pick,
            |w, (qx, qy), (ox, oy)| {
                let ex = qx + (px - ox) as usize;
                let ey = qy + (py - oy) as usize;
                let at = (ey * l0.w + ex) * c;
                add_scaled(&mut out[..c], w, &l0.data[at..at + c]);
            },
        );
    }

    /// Pixel (px, py) of block row j alone: its patches joined along the cuts of the
    /// vertical edges of that row (`R_j` of [`RsgfModel::edge_cut`]).
    #[inline]
    fn row_pixel(
        &self,
        j: i64,
        px: i64,
        py: i64,
        pick: &mut dyn FnMut(i64, i64) -> u32,
        cut: &mut dyn FnMut(Edge, i64, i64, usize) -> u16,
        out: &mut [f32],
    ) {
        let c = self.c;
        let l0 = &self.levels[0];
        let mut at = |i: i64| {
            let (sx, sy) = self.source(i, j, px, py, pick);
            (sy * l0.w + sx) * c
        };
        let cols = self.split(Edge::V, px, j, py, cut);
        if cols[1].1 == 0.0 {
            let at = at(cols[0].0);
            out[..c].copy_from_slice(&l0.data[at..at + c]);
            return;
        }
        out[..c].fill(0.0);
        for (i, w) in cols {
            if w != 0.0 {
                let at = at(i);
                add_scaled(&mut out[..c], w, &l0.data[at..at + c]);
            }
        }
    }

    /// Whether pixel (px, py) of block row j alone (as [`RsgfModel::row_pixel`] composes
    /// it) reads a pixel of the mirrored frame, with any weight.
    fn row_mirrored(
        &self,
        j: i64,
        px: i64,
        py: i64,
        pick: &mut dyn FnMut(i64, i64) -> u32,
        cut: &mut dyn FnMut(Edge, i64, i64, usize) -> u16,
    ) -> bool {
        let (l0, pad) = (&self.levels[0], self.pad);
        self.split(Edge::V, px, j, py, cut)
            .into_iter()
            .filter(|&(_, w)| w != 0.0)
            .any(|(i, _)| {
                let (sx, sy) = self.source(i, j, px, py, pick);
                sx < pad || sy < pad || sx >= l0.w - pad || sy >= l0.h - pad
            })
    }

    /// The level-0 texel that block (i, j)'s patch lays on output pixel (px, py).
    #[inline]
    fn source(
        &self,
        i: i64,
        j: i64,
        px: i64,
        py: i64,
        pick: &mut dyn FnMut(i64, i64) -> u32,
    ) -> (usize, usize) {
        let (qx, qy) = self.position(pick(i, j));
        let (ox, oy) = self.origin(i, j);
        (qx + (px - ox) as usize, qy + (py - oy) as usize)
    }

    /// The blocks (with weights) that show coordinate `s` along one axis when patches
    /// join along cuts: a vertical edge's (`Edge::V`, s = x) in block row `fixed`, a
    /// horizontal edge's (`Edge::H`, s = y) in block column `fixed`; `cross` is the
    /// other coordinate. Away from a cut one block has weight 1 (the second entry 0);
    /// within `feather_px` of it the two ramp linearly over 2·feather pixels.
    #[inline]
    fn split(
        &self,
        edge: Edge,
        s: i64,
        fixed: i64,
        cross: i64,
        cut: &mut dyn FnMut(Edge, i64, i64, usize) -> u16,
    ) -> [(i64, f32); 2] {
        let (b, o) = (self.b, self.o);
        let bs = s.div_euclid(b);
        let u = s - bs * b;
        let (e, k) = if u < o {
            (bs, u + o)
        } else if u >= b - o {
            (bs + 1, u - (b - o))
        } else {
            return [(bs, 1.0), (bs, 0.0)];
        };
        let (i, j) = match edge {
            Edge::V => (e, fixed),
            Edge::H => (fixed, e),
        };
        let along = (cross - (fixed * b - o)) as usize;
        let w = ramp(
            k - i64::from(cut(edge, i, j, along)),
            self.params.feather_px,
        );
        if w == 0.0 {
            [(e - 1, 1.0), (e, 0.0)]
        } else if w == 1.0 {
            [(e, 1.0), (e - 1, 0.0)]
        } else {
            [(e - 1, 1.0 - w), (e, w)]
        }
    }

    /// The minimum-error cut of `edge` (i, j) (Efros & Freeman 2001; the error is seed
    /// 000 §3.2.1 eq. (1)'s squared difference, summed over channels), through the
    /// 2·o pixels of overlap across the edge, as an 8-connected path found by dynamic
    /// programming. Returns, for each t along the edge, the first pixel k across it that
    /// shows the block after the edge; those before show the block before. The path
    /// keeps `feather_px` pixels from the overlap's sides, so that the ramp around it
    /// stays inside. Ties go to the smaller k.
    ///
    /// - `Edge::V` (i, j), between blocks (i − 1, j) and (i, j): along the whole height
    ///   E = B + 2·o of block row j's patches, from those two patches (`pick`).
    /// - `Edge::H` (i, j), between block rows j − 1 and j, within block column i: along
    ///   x in [i·B, (i + 1)·B), from the two rows R_{j−1} and R_j as their own vertical
    ///   cuts (`cut`) compose them, so every pixel of a corner belongs to one row. The
    ///   path starts at the middle of the overlap at x = i·B and ends beside it at
    ///   (i + 1)·B, so the paths of neighbouring block columns join. Entries outside
    ///   that span hold the middle.
    pub(crate) fn edge_cut(
        &self,
        edge: Edge,
        i: i64,
        j: i64,
        pick: &mut dyn FnMut(i64, i64) -> u32,
        cut: &mut dyn FnMut(Edge, i64, i64, usize) -> u16,
    ) -> Vec<u16> {
        let c = self.c;
        let f = self.params.feather_px;
        let (b, o) = (self.b as usize, self.o as usize);
        let m = 2 * o - 2 * f;
        match edge {
            Edge::V => {
                let l0 = &self.levels[0];
                let (ax, ay) = self.position(pick(i - 1, j));
                let (bx, by) = self.position(pick(i, j));
                let pad = self.pad;
                let path = min_cut(b + 2 * o, m, None, |t, k| {
                    let (pa, pb) = (
                        ((ay + t) * l0.w + ax + b + f + k) * c,
                        ((by + t) * l0.w + bx + f + k) * c,
                    );
                    // With the cut at k + f, the block before shows the overlap's
                    // columns up to k + 2f − 1 and the block after from k on (the ramp
                    // included): neither may reach into the mirrored frame.
                    let mirrored =
                        (k + 2 * f >= 1 && ax + b + k + 2 * f > l0.w - pad) || bx + k < pad;
                    (0..c)
                        .map(|ch| (l0.data[pa + ch] as f64 - l0.data[pb + ch] as f64).powi(2))
                        .sum::<f64>()
                        + if mirrored { self.mirror_cost } else { 0.0 }
                });
                path.into_iter().map(|k| (k + f) as u16).collect()
            }
            Edge::H => {
                let (x0, y0) = (i * self.b, j * self.b - self.o);
                let (mut va, mut vb) = ([0.0f32; 4], [0.0f32; 4]);
                let pin = o - f;
                // The six blocks and four vertical cuts the two rows use here, fetched
                // once (a single sample's `pick` and `cut` go through shared caches).
                let picks: Vec<u32> = (j - 1..=j)
                    .flat_map(|jj| (i - 1..=i + 1).map(move |ii| (ii, jj)))
                    .map(|(ii, jj)| pick(ii, jj))
                    .collect();
                let vcuts: Vec<Vec<u16>> = (j - 1..=j)
                    .flat_map(|jj| (i..=i + 1).map(move |ii| (ii, jj)))
                    .map(|(ii, jj)| (0..b + 2 * o).map(|t| cut(Edge::V, ii, jj, t)).collect())
                    .collect();
                let mut pick = |ii: i64, jj: i64| picks[((jj - j + 1) * 3 + ii - i + 1) as usize];
                let mut cut = |_: Edge, ii: i64, jj: i64, t: usize| {
                    vcuts[((jj - j + 1) * 2 + ii - i) as usize][t]
                };
                let path = min_cut(b, m, Some(pin), |t, k| {
                    let (x, y) = (x0 + t as i64, y0 + (f + k) as i64);
                    self.row_pixel(j - 1, x, y, &mut pick, &mut cut, &mut va);
                    self.row_pixel(j, x, y, &mut pick, &mut cut, &mut vb);
                    // As for vertical cuts: the row above shows up to y + f − 1, the
                    // row below from y − f on.
                    let mirrored = self.pad > 0
                        && ((k + 2 * f >= 1
                            && self.row_mirrored(j - 1, x, y + f as i64 - 1, &mut pick, &mut cut))
                            || self.row_mirrored(j, x, y - f as i64, &mut pick, &mut cut));
                    (0..c)
                        .map(|ch| (va[ch] as f64 - vb[ch] as f64).powi(2))
                        .sum::<f64>()
                        + if mirrored { self.mirror_cost } else { 0.0 }
                });
                let mut full = vec![o as u16; b + 2 * o];
                for (t, k) in path.into_iter().enumerate() {
                    full[o + t] = (k + f) as u16;
                }
                full
            }
        }
    }

    /// Calls `f(weight, position, origin)` for each block with a non-zero weight,
    /// rows of blocks outer, in the fixed order of `ax` and `ay`.
    #[inline]
    fn taps(
        &self,
        ax: [(i64, f32); 2],
        ay: [(i64, f32); 2],
        pick: &mut dyn FnMut(i64, i64) -> u32,
        mut f: impl FnMut(f32, (usize, usize), (i64, i64)),
    ) {
        for (j, wy) in ay {
            if wy == 0.0 {
                continue;
            }
            for (i, wx) in ax {
                if wx != 0.0 {
                    f(wy * wx, self.position(pick(i, j)), self.origin(i, j));
                }
            }
        }
    }

    /// Channel values at real (x, y) from mip `level` (bilinear in the level, blocks
    /// blended with real-valued weights): the prefiltered view of zoomed-out samples.
    pub(crate) fn sample_level(
        &self,
        x: f64,
        y: f64,
        level: usize,
        pick: &mut dyn FnMut(i64, i64) -> u32,
        out: &mut [f32],
    ) {
        let c = self.c;
        let lv = &self.levels[level];
        let scale = 1.0 / (1u64 << level) as f64;
        let centre = ((1u64 << level) as f64 - 1.0) / 2.0;
        out[..c].fill(0.0);
        self.taps(
            self.axis_f(x),
            self.axis_f(y),
            pick,
            |w, (qx, qy), (ox, oy)| {
                let ex = (qx as f64 + (x - ox as f64) - centre) * scale;
                let ey = (qy as f64 + (y - oy as f64) - centre) * scale;
                bilinear_add(lv, c, ex, ey, w, out);
            },
        );
        self.remap(out);
    }

    /// The sequential whole-image RSGF (§4) of `width × height` pixels from the origin:
    /// every random block, then every gap in raster order, then every pixel by
    /// `RsgfModel::pixel`. The slow reference that streamed fills are tested against.
    pub fn synthesize(&self, seed: u32, width: usize, height: usize) -> Raster {
        let (i0, i1) = self.block_range(0, width as i64 - 1);
        // Cuts: one more block column each side, for the horizontal cuts of the outer
        // ones (they cut between rows composed across both of their vertical edges).
        let cut = i64::from(self.params.join == Join::Cut);
        let (i0, i1) = (i0 - cut, i1 + cut);
        let (j0, j1) = self.block_range(0, height as i64 - 1);
        let gw = (i1 - i0 + 1) as usize;
        let gh = (j1 - j0 + 1) as usize;
        let mut grid = vec![u32::MAX; gw * gh];
        for j in j0..=j1 {
            for i in i0..=i1 {
                if Self::is_random(i, j) {
                    grid[(j - j0) as usize * gw + (i - i0) as usize] = self.random_pick(seed, i, j);
                }
            }
        }
        for j in j0..=j1 {
            for i in i0..=i1 {
                if !Self::is_random(i, j) {
                    grid[(j - j0) as usize * gw + (i - i0) as usize] = self.solve_gap(seed, i, j);
                }
            }
        }
        let mut out = Raster::zeros(width, height, self.c);
        let c = self.c;
        let lookup = |i: i64, j: i64| grid[(j - j0) as usize * gw + (i - i0) as usize];
        // Vertical cuts first: the horizontal ones are cut between rows they compose.
        let mut cuts: std::collections::HashMap<(Edge, i64, i64), Vec<u16>> =
            std::collections::HashMap::new();
        if self.params.join == Join::Cut {
            for edge in [Edge::V, Edge::H] {
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        if (edge == Edge::V && i > i0)
                            || (edge == Edge::H && j > j0 && i > i0 && i < i1)
                        {
                            let path =
                                self.edge_cut(edge, i, j, &mut { lookup }, &mut |e, i, j, t| {
                                    cuts[&(e, i, j)][t]
                                });
                            cuts.insert((edge, i, j), path);
                        }
                    }
                }
            }
        }
        let mut cut = |e: Edge, i: i64, j: i64, t: usize| cuts[&(e, i, j)][t];
        for y in 0..height {
            for x in 0..width {
                let at = (y * width + x) * c;
                self.pixel(
                    x as i64,
                    y as i64,
                    &mut { lookup },
                    &mut cut,
                    &mut out.data[at..at + c],
                );
            }
        }
        out
    }
}

/// The minimum-cost 8-connected path through an n × m cost grid `err(t, k)`, one k
/// per t (t along, k across), by dynamic programming; ties go to the smaller k. With
/// `pin`, the path starts at k = pin and ends within one of it (so that it can go on
/// at pin).
fn min_cut(
    n: usize,
    m: usize,
    pin: Option<usize>,
    mut err: impl FnMut(usize, usize) -> f64,
) -> Vec<usize> {
    let mut cost = vec![0.0f64; n * m];
    for t in 0..n {
        for k in 0..m {
            let before = if t == 0 {
                match pin {
                    Some(p) if p != k => f64::INFINITY,
                    _ => 0.0,
                }
            } else {
                cost[(t - 1) * m + k.saturating_sub(1)..(t - 1) * m + (k + 2).min(m)]
                    .iter()
                    .fold(f64::INFINITY, |x, &y| x.min(y))
            };
            // Unreachable cells need no error.
            cost[t * m + k] = if before.is_finite() {
                before + err(t, k)
            } else {
                f64::INFINITY
            };
        }
    }
    let argmin = |row: &[f64], lo: usize| {
        let mut best = lo;
        for (k, &v) in row.iter().enumerate() {
            if v < row[best - lo] {
                best = lo + k;
            }
        }
        best
    };
    let (lo, hi) = match pin {
        Some(p) => (p.saturating_sub(1), (p + 2).min(m)),
        None => (0, m),
    };
    let mut path = vec![0usize; n];
    let mut k = argmin(&cost[(n - 1) * m + lo..(n - 1) * m + hi], lo);
    path[n - 1] = k;
    for t in (0..n - 1).rev() {
        let lo = k.saturating_sub(1);
        k = argmin(&cost[t * m + lo..t * m + (k + 2).min(m)], lo);
        path[t] = k;
    }
    path
}

/// out += w · src, element by element.
#[inline]
fn add_scaled(out: &mut [f32], w: f32, src: &[f32]) {
    for (o, v) in out.iter_mut().zip(src) {
        *o += w * v;
    }
}

/// A histogram map at v: linear between the knots (from, to) around it, the end
/// knots' values beyond them.
#[inline]
fn map_value(map: &[[f32; 2]], v: f32) -> f32 {
    let i = map.partition_point(|k| k[0] <= v);
    if i == 0 {
        return map[0][1];
    }
    if i == map.len() {
        return map[i - 1][1];
    }
    let (a, b) = (map[i - 1], map[i]);
    // In f64: knot gaps near ±f32::MAX would overflow to infinity in f32.
    let t = (v as f64 - a[0] as f64) / (b[0] as f64 - a[0] as f64);
    (a[1] as f64 + t * (b[1] as f64 - a[1] as f64)) as f32
}

/// Checks a histogram map from a bank: one per channel, at least two knots each,
/// finite, `from` strictly increasing and `to` non-decreasing.
fn check_histogram(maps: &[Vec<[f32; 2]>], c: usize) -> Result<()> {
    let ok = maps.len() == c
        && maps.iter().all(|m| {
            m.len() >= 2
                && m.iter().all(|k| k[0].is_finite() && k[1].is_finite())
                && m.windows(2)
                    .all(|w| w[0][0] < w[1][0] && w[0][1] <= w[1][1])
        });
    if ok {
        Ok(())
    } else {
        Err(Error::param(
            "RSGF histogram map",
            format!("({} maps)", maps.len()),
            format!("one map per channel ({c}), each of at least two finite knots, increasing"),
        ))
    }
}

/// Adds `w ·` the bilinear sample of level `lv` at texel coordinates (x, y) (clamped
/// to the level) to `out`.
fn bilinear_add(lv: &Level, c: usize, x: f64, y: f64, w: f32, out: &mut [f32]) {
    let xm = (lv.w - 1) as f64;
    let ym = (lv.h - 1) as f64;
    let (x, y) = (x.clamp(0.0, xm), y.clamp(0.0, ym));
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(lv.w - 1), (y0 + 1).min(lv.h - 1));
    let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
    let at = |xx: usize, yy: usize, ch: usize| lv.data[(yy * lv.w + xx) * c + ch];
    for (ch, o) in out[..c].iter_mut().enumerate() {
        let top = at(x0, y0, ch) + fx * (at(x1, y0, ch) - at(x0, y0, ch));
        let bottom = at(x0, y1, ch) + fx * (at(x1, y1, ch) - at(x0, y1, ch));
        *o += w * (top + fy * (bottom - top));
    }
}

/// `ex` extended by `p` pixels on every side with its mirror image about its edge
/// pixels (x = −k shows x = k; `p` < both sides).
pub(crate) fn reflect_pad(ex: &Raster, p: usize) -> Raster {
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    let (pw, ph) = (w + 2 * p, h + 2 * p);
    let reflect = |s: usize, n: usize| {
        let s = s as i64 - p as i64;
        let n = n as i64;
        (if s < 0 {
            -s
        } else if s >= n {
            2 * (n - 1) - s
        } else {
            s
        }) as usize
    };
    let mut data = Vec::with_capacity(pw * ph * c);
    for y in 0..ph {
        let row = reflect(y, h) * w;
        for x in 0..pw {
            let at = (row + reflect(x, w)) * c;
            data.extend_from_slice(&ex.data[at..at + c]);
        }
    }
    Raster {
        width: pw,
        height: ph,
        channels: c,
        data,
    }
}

/// Weight of the side after a cut for a pixel `d` pixels past it (negative: before it),
/// with a linear ramp over 2·`f` pixels around the cut (a hard cut for `f` = 0): how
/// [`RsgfModel::split`] weighs the block after an edge, and the torus's seams ramp.
#[inline]
fn ramp(d: i64, f: usize) -> f32 {
    if f == 0 {
        f32::from(u8::from(d >= 0))
    } else {
        ((d as f32 + 0.5) / (2 * f) as f32 + 0.5).clamp(0.0, 1.0)
    }
}

/// Mean over rows of the squared jump across the seam of a torus `period` wide whose
/// row y shows column `cut[y]` right of the seam and column cut[y] − 1 + `period`
/// (mod the width) left of it, summed over channels.
fn seam_jump(ex: &Raster, period: usize, cut: &[usize]) -> f64 {
    let (w, c) = (ex.width, ex.channels);
    let mut acc = 0.0;
    for (y, &kk) in cut.iter().enumerate() {
        let before = (kk + period - 1) % w;
        for ch in 0..c {
            let d =
                ex.data[(y * w + kk) * c + ch] as f64 - ex.data[(y * w + before) * c + ch] as f64;
            acc += d * d;
        }
    }
    acc / cut.len() as f64
}

/// One axis of [`wrap_torus`]: `ex` made periodic across x with the period whose seam
/// jumps least ([`seam_jump`]): W (no cut), or W − ov for ov in (2·f, `max_ov`]
/// through the minimum-error cut of that overlap (seed 003, eq. (1)). With `closed`
/// the chosen overlap's cut is then searched again as a closed path along y (it ends
/// within one pixel of where it starts: the other axis already wraps), the cheapest of
/// the paths pinned at each start; the choice itself uses open paths, so that it costs
/// O(H · Σ m) rather than O(H · Σ m²). Returns the torus's columns (all rows kept).
/// A period one pixel longer than an exemplar's own repeats a column, which jumps not
/// at all: on an exemplar that tiles exactly, the torus may be that one pixel longer.
fn wrap_x(ex: &Raster, max_ov: usize, f: usize, closed: bool) -> Raster {
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    let sq = |a: &[f32], b: &[f32]| -> f64 {
        a.iter()
            .zip(b)
            .map(|(&p, &q)| (p as f64 - q as f64).powi(2))
            .sum()
    };
    let px = |x: usize, y: usize| &ex.data[(y * w + x) * c..(y * w + x + 1) * c];
    let errors = |ov: usize| -> Vec<f64> {
        let (tw, m) = (w - ov, ov - 2 * f);
        (0..h)
            .flat_map(|y| (0..m).map(move |k| (y, k)))
            .map(|(y, k)| sq(px(k + f, y), px(k + f + tw, y)))
            .collect()
    };
    let shifted = |path: Vec<usize>| -> Vec<usize> { path.into_iter().map(|k| k + f).collect() };
    let mut best = (seam_jump(ex, w, &vec![0; h]), 0usize, vec![0usize; h]);
    for ov in 2 * f + 1..=max_ov.min(w / 2) {
        let m = ov - 2 * f;
        let err = errors(ov);
        let cut = shifted(min_cut(h, m, None, |y, k| err[y * m + k]));
        let jump = seam_jump(ex, w - ov, &cut);
        if jump < best.0 {
            best = (jump, ov, cut);
        }
    }
    if closed && best.1 > 0 {
        let (ov, m) = (best.1, best.1 - 2 * f);
        let err = errors(ov);
        let mut cheapest: Option<(f64, Vec<usize>)> = None;
        for pin in 0..m {
            let path = min_cut(h, m, Some(pin), |y, k| err[y * m + k]);
            let cost: f64 = path.iter().enumerate().map(|(y, &k)| err[y * m + k]).sum();
            if cheapest.as_ref().is_none_or(|b| cost < b.0) {
                cheapest = Some((cost, path));
            }
        }
        if let Some((_, path)) = cheapest {
            best.2 = shifted(path);
        }
    }
    let (_, ov, cut) = best;
    let tw = w - ov;
    let mut data = vec![0.0f32; tw * h * c];
    for (y, &kk) in cut.iter().enumerate() {
        for x in 0..tw {
            let at = (y * tw + x) * c;
            if x >= ov {
                data[at..at + c].copy_from_slice(px(x, y));
            } else {
                let a = ramp(x as i64 - kk as i64, f);
                for ch in 0..c {
                    data[at + ch] = a * px(x, y)[ch] + (1.0 - a) * px(x + tw, y)[ch];
                }
            }
        }
    }
    Raster {
        width: tw,
        height: h,
        channels: c,
        data,
    }
}

/// `r` with x and y swapped.
fn transpose(r: &Raster) -> Raster {
    let (w, h, c) = (r.width, r.height, r.channels);
    let mut data = vec![0.0f32; w * h * c];
    for y in 0..h {
        for x in 0..w {
            data[(x * h + y) * c..(x * h + y + 1) * c]
                .copy_from_slice(&r.data[(y * w + x) * c..(y * w + x + 1) * c]);
        }
    }
    Raster {
        width: h,
        height: w,
        channels: c,
        data,
    }
}

/// The exemplar made periodic: a torus whose two seams are minimum-error cuts through
/// the columns (then rows) that its opposite edges share, as the roller cuts its tile
/// (seed 003, eqs. (1) and (2), on the unit lattice) but without healing, so its
/// pixels are the exemplar's except within `f` of a cut, where they ramp as a block
/// edge does. Per axis the period is the one whose seam jumps least ([`wrap_x`]): the
/// exemplar's side, uncut (an exemplar that nearly tiles, as GIMP patterns do, may need
/// no cut), or the side less ov for ov in (2·f, `max_ov`]. The second seam is closed (it
/// ends beside where it starts), since the first axis already wraps. Both sides above
/// 2·`max_ov`.
pub(crate) fn wrap_torus(ex: &Raster, max_ov: usize, f: usize) -> Raster {
    let v1 = wrap_x(ex, max_ov, f, false);
    let t = wrap_x(&transpose(&v1), max_ov, f, true);
    transpose(&t)
}

/// Side of the repeated torus a wrapped model searches and samples, per exemplar side
/// (at most W − 1 + B + 2·o): [`MAX_EXEMPLAR_PIXELS`] bounds it as it bounds the
/// exemplar.
pub fn wrapped_side(side: usize, block_px: usize, border_px: usize) -> usize {
    side + block_px + 2 * border_px - 1
}

/// Whether a `w × h` exemplar can wrap patches of `block_px` + 2·`border_px`: its torus
/// (up to 2·border smaller per axis) holds a whole patch, and the repeated torus stays
/// within [`MAX_EXEMPLAR_PIXELS`].
pub fn wrap_fits(w: usize, h: usize, block_px: usize, border_px: usize) -> bool {
    block_px + 4 * border_px <= w.min(h)
        && wrapped_side(w, block_px, border_px) * wrapped_side(h, block_px, border_px)
            <= MAX_EXEMPLAR_PIXELS
}

/// The torus `t` repeated to `t.width + p` × `t.height + p` pixels, so that a patch of
/// p + 1 pixels at any of its `t.width × t.height` positions lies inside.
pub(crate) fn wrap_extend(t: &Raster, p: usize) -> Raster {
    t.torus(t.width + p, t.height + p)
}

/// The exemplar and its 2×2 box-filtered halvings down to [`MIN_LEVEL_SIDE`].
pub(crate) fn mip_chain(exemplar: &Raster) -> Vec<Level> {
    let c = exemplar.channels;
    let mut levels = vec![Level {
        w: exemplar.width,
        h: exemplar.height,
        data: exemplar.data.clone(),
    }];
    loop {
        let prev = &levels[levels.len() - 1];
        let (w, h) = (prev.w / 2, prev.h / 2);
        if w < MIN_LEVEL_SIDE || h < MIN_LEVEL_SIDE {
            break;
        }
        let mut data = vec![0.0f32; w * h * c];
        for y in 0..h {
            for x in 0..w {
                for ch in 0..c {
                    let at = |xx: usize, yy: usize| prev.data[(yy * prev.w + xx) * c + ch];
                    data[(y * w + x) * c + ch] = 0.25
                        * (at(2 * x, 2 * y)
                            + at(2 * x + 1, 2 * y)
                            + at(2 * x, 2 * y + 1)
                            + at(2 * x + 1, 2 * y + 1));
                }
            }
        }
        levels.push(Level { w, h, data });
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An exemplar that repeats every 88 × 84 px (waves and noise), cut 100 × 96:
    /// the torus, at most `max_ov` smaller per axis, differs between neighbours
    /// (wrap-around pairs and seams included) within 10% of what the exemplar's own
    /// neighbours do, per axis (0.94–1.00 measured; it is 89 × 85: a period one pixel
    /// longer repeats a column, which jumps not at all); with hard cuts it shows only
    /// the exemplar's values. A 64 × 62 crop wrapped without cuts reads 1.39–1.71: its
    /// one wrap-around pair per row differs as unrelated pixels do.
    #[test]
    fn the_torus_of_a_periodic_exemplar_wraps_smoothly() {
        let tau = std::f64::consts::TAU;
        let field = |x: usize, y: usize, ch: usize| -> f32 {
            let (ix, iy) = (x as i64 % 88, y as i64 % 84);
            let noise = crate::hash::hash_cell(7, ix, iy, ch as u32)[0] as f64 / u32::MAX as f64;
            let (x, y, k) = (x as f64, y as f64, ch as f64);
            (0.5 * noise
                + (tau * x / 88.0 + k).sin()
                + 0.5 * (tau * 3.0 * x / 88.0 + 1.0 + k).sin()
                + (tau * y / 84.0).cos()
                + 0.3 * (tau * (2.0 * x / 88.0 + y / 84.0) + 0.4 * k).sin()) as f32
        };
        // Mean squared difference of horizontal and vertical neighbours, summed over
        // channels, with the wrap-around pairs of a torus (`wrap`) or without.
        let roughness = |r: &Raster, wrap: bool| -> (f64, f64) {
            let (w, h, c) = (r.width, r.height, r.channels);
            let v = |x: usize, y: usize, ch: usize| r.data[(y * w + x) * c + ch] as f64;
            let (mut sx, mut nx, mut sy, mut ny) = (0.0, 0.0, 0.0, 0.0);
            for y in 0..h {
                for x in 0..w {
                    for ch in 0..c {
                        if x + 1 < w || wrap {
                            sx += (v((x + 1) % w, y, ch) - v(x, y, ch)).powi(2);
                            nx += 1.0 / c as f64;
                        }
                        if y + 1 < h || wrap {
                            sy += (v(x, (y + 1) % h, ch) - v(x, y, ch)).powi(2);
                            ny += 1.0 / c as f64;
                        }
                    }
                }
            }
            (sx / nx, sy / ny)
        };
        for c in [1usize, 3] {
            let (w, h) = (100usize, 96usize);
            let ex = Raster {
                width: w,
                height: h,
                channels: c,
                data: (0..w * h * c)
                    .map(|i| field((i / c) % w, i / c / w, i % c))
                    .collect(),
            };
            let (rx, ry) = roughness(&ex, false);
            let (cx, cy) = roughness(&ex.crop(0, 0, 64, 62).unwrap(), true);
            assert!(
                cx > 1.3 * rx && cy > 1.3 * ry,
                "channels {c}: the crop reads {:.3}, {:.3}",
                cx / rx,
                cy / ry
            );
            for f in [0usize, 1, 3] {
                let t = wrap_torus(&ex, 20, f);
                assert!(
                    (80..=100).contains(&t.width) && (76..=96).contains(&t.height),
                    "channels {c}, ramp {f}: {}×{}",
                    t.width,
                    t.height
                );
                let (tx, ty) = roughness(&t, true);
                assert!(
                    tx <= 1.1 * rx && ty <= 1.1 * ry,
                    "channels {c}, ramp {f}: {:.3}, {:.3} of the exemplar's",
                    tx / rx,
                    ty / ry
                );
                if f == 0 {
                    let mut values: Vec<u32> = ex.data.iter().map(|v| v.to_bits()).collect();
                    values.sort_unstable();
                    assert!(
                        t.data
                            .iter()
                            .all(|v| values.binary_search(&v.to_bits()).is_ok()),
                        "channels {c}: a hard cut wrote a value the exemplar does not hold"
                    );
                }
            }
        }
    }

    /// The extension repeats the torus.
    #[test]
    fn wrap_extend_repeats_the_torus() {
        let t = Raster {
            width: 3,
            height: 2,
            channels: 1,
            data: vec![0.0, 1.0, 2.0, 10.0, 11.0, 12.0],
        };
        let e = wrap_extend(&t, 2);
        assert_eq!((e.width, e.height), (5, 4));
        assert_eq!(
            e.data,
            vec![
                0.0, 1.0, 2.0, 0.0, 1.0, 10.0, 11.0, 12.0, 10.0, 11.0, 0.0, 1.0, 2.0, 0.0, 1.0,
                10.0, 11.0, 12.0, 10.0, 11.0
            ]
        );
    }

    /// Reflection about the edge pixels, by hand.
    #[test]
    fn reflect_pad_mirrors_about_the_edge_pixels() {
        // 3 × 2, one channel: 0 1 2 / 3 4 5; padded by 1: x = −1 shows x = 1.
        let ex = Raster::from_vec(3, 2, 1, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]).unwrap();
        let p = reflect_pad(&ex, 1);
        assert_eq!((p.width, p.height, p.channels), (5, 4, 1));
        #[rustfmt::skip]
        let want = [
            4.0, 3.0, 4.0, 5.0, 4.0,
            1.0, 0.0, 1.0, 2.0, 1.0,
            4.0, 3.0, 4.0, 5.0, 4.0,
            1.0, 0.0, 1.0, 2.0, 1.0,
        ];
        assert_eq!(p.data, want);
    }

    /// A histogram map interpolates between its knots and holds its ends, and stays
    /// finite with knots near ±f32::MAX.
    #[test]
    fn histogram_maps_interpolate_and_stay_finite() {
        let map = [[0.0f32, 10.0], [1.0, 12.0], [3.0, 13.0]];
        assert_eq!(map_value(&map, -5.0), 10.0);
        assert_eq!(map_value(&map, 0.5), 11.0);
        assert_eq!(map_value(&map, 2.0), 12.5);
        assert_eq!(map_value(&map, 9.0), 13.0);
        let wide = [[-3.0e38f32, -3.0e38], [3.0e38, 3.0e38]];
        assert_eq!(map_value(&wide, 0.0), 0.0);
        assert!(check_histogram(&[wide.to_vec()], 1).is_ok());
    }

    /// The cheapest 8-connected path by exhaustive search: every path, its cost.
    fn brute_cut(err: &[Vec<f64>], pin: Option<usize>) -> f64 {
        let mut best = f64::INFINITY;
        let mut path = vec![0usize; err.len()];
        fn walk(
            t: usize,
            err: &[Vec<f64>],
            pin: Option<usize>,
            path: &mut Vec<usize>,
            cost: f64,
            best: &mut f64,
        ) {
            let n = err.len();
            if t == n {
                let end_ok = pin.is_none_or(|p| path[n - 1].abs_diff(p) <= 1);
                if end_ok && cost < *best {
                    *best = cost;
                }
                return;
            }
            for k in 0..err[0].len() {
                let ok = if t == 0 {
                    pin.is_none_or(|p| p == k)
                } else {
                    k.abs_diff(path[t - 1]) <= 1
                };
                if ok {
                    path[t] = k;
                    walk(t + 1, err, pin, path, cost + err[t][k], best);
                }
            }
        }
        walk(0, err, pin, &mut path, 0.0, &mut best);
        best
    }

    /// The dynamic programme finds a path as cheap as the exhaustive search's, that is
    /// 8-connected, starts at the pin and ends beside it.
    #[test]
    fn cuts_are_the_cheapest_paths() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for trial in 0..40 {
            let (n, m) = (3 + trial % 5, 2 + trial % 4);
            let err: Vec<Vec<f64>> = (0..n)
                .map(|_| (0..m).map(|_| (rnd() * 4.0).floor()).collect())
                .collect();
            for pin in [None, Some(trial % m)] {
                let path = min_cut(n, m, pin, |t, k| err[t][k]);
                let cost: f64 = path.iter().enumerate().map(|(t, &k)| err[t][k]).sum();
                assert_eq!(cost, brute_cut(&err, pin), "trial {trial}, pin {pin:?}");
                assert!(path.windows(2).all(|w| w[0].abs_diff(w[1]) <= 1));
                if let Some(p) = pin {
                    assert_eq!(path[0], p);
                    assert!(path[n - 1].abs_diff(p) <= 1);
                }
            }
        }
    }

    /// The overflow-free residue equals [`Lattice::reduce`]'s wherever that one does not
    /// overflow, and stays in range at |p| ~ 2⁵² with a lattice whose C is 1.
    #[test]
    fn residues_match_the_lattice_reduction() {
        for (u, v) in [
            ((23, 0), (9, 19)),
            ((25, -2), (1, 30)),
            ((-17, 31), (29, 11)),
            ((1, 0), (0, 1)),
        ] {
            let l = Lattice::from_basis(u, v).unwrap();
            for p in [
                (0, 0),
                (-1, -1),
                (123_456, -98_765),
                (-7_000_000_001, 5_000_000_003),
            ] {
                let (_, (rx, ry)) = l.reduce(p);
                assert_eq!(
                    residue(l, p),
                    (ry * l.a + rx) as usize,
                    "{u:?}/{v:?} at {p:?}"
                );
            }
        }
        let l = Lattice::from_basis((4_000_000, 0), (3_999_999, 1)).unwrap();
        let r = residue(l, (1 << 52, -(1 << 52) + 3));
        assert!(r < (l.a * l.c) as usize);
    }
}
