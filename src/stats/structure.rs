//! Figures that see structure, not only statistics (issue 31): W1 and the PSD error
//! ignore phase, so random-phase noise scores as well as a faithful copy of gravel. These
//! compare patches of the output with patches of the exemplar, on every channel:
//!
//! - **coherence**: each 8×8 output patch (on a grid) to its nearest exemplar patch, over
//!   the exemplar's own figure (each half of the exemplar to the other half). About 1:
//!   locally like the exemplar; random-phase noise scores far above.
//! - **completeness**: each 8×8 exemplar patch to its nearest output patch, over the same
//!   reference: a method that repeats a few pieces scores high.
//! - **self-repetition**: the share of 32×32 output patches with a near-copy (relative L2
//!   below 0.05 after removing each channel's mean) elsewhere in the output, at least a
//!   patch side away.
//! - **copy score**: the share of 32×32 output patches with such a near-copy anywhere in
//!   the exemplar.
//! - **seams at any phase**: per axis and per offset modulo a cell, the gradient energy
//!   across those columns (rows) over the median offset's; the worst is reported, so
//!   seams off the claimed grid are found.
//!
//! Distances are root mean squares per value (the raster's unit). Nearest neighbours go
//! through principal components and a k-d tree ([`crate::nn`]): coherence and
//! completeness take the 8 nearest in the projected space and re-rank them exactly
//! (an upper bound on the exact figure; the tests hold it within a few percent of a
//! brute-force twin), the near-copy searches are exact (a range search in a contraction
//! of the full space, then a check of each hit).

use serde::Serialize;

use crate::nn::{KdTree, Pca, par_map, sq_dist};
use crate::raster::Raster;

/// Side of the patches of coherence and completeness, in pixels.
pub const COHERENCE_PATCH: usize = 8;
/// Side of the patches of self-repetition and the copy score, in pixels.
pub const COPY_PATCH: usize = 32;
/// A near-copy differs by less than this fraction of the patch's own norm (after mean
/// removal).
pub const COPY_RELATIVE_L2: f64 = 0.05;
/// Projected dimensions of the nearest-neighbour searches.
const PROJECTED: usize = 16;
/// Candidates re-ranked exactly per coherence or completeness query.
const RERANK: usize = 8;
/// Patches the principal components are fitted on, at most.
const PCA_SAMPLES: usize = 20_000;

/// The structure figures of an output against its exemplar.
#[derive(Clone, Debug, Serialize)]
pub struct StructureFigures {
    /// Output-to-exemplar 8×8 patch distance over the exemplar's half-to-half one
    /// (1: as coherent as the exemplar itself).
    pub coherence: f64,
    /// Exemplar-to-output 8×8 patch distance over the same reference (low: every part
    /// of the exemplar appears in the output).
    pub completeness: f64,
    /// The exemplar's half-to-half 8×8 patch distance both ratios divide by, in the
    /// raster's unit (rms per value).
    pub reference_distance: f64,
    /// Share of 32×32 output patches with a near-copy elsewhere in the output.
    pub self_repetition: f64,
    /// Share of 32×32 output patches with a near-copy in the exemplar.
    pub copy_score: f64,
    /// Seams searched at every phase of a cell, if the output is large enough.
    pub seams: Option<PhaseSeams>,
    /// What the seam figure reads on the output's own content with no grid behind it
    /// ([`seam_noise`] at the same cell, [`SEAM_NOISE_DRAWS`] draws, bar [`SEAM_BAR`]).
    pub seam_noise: Option<SeamNoise>,
}

/// The band the seam score at any phase should fall in (docs/structure.md).
pub const SEAM_BAR: (f64, f64) = (0.9, 1.15);
/// Draws of [`seam_noise`] in [`structure`].
pub const SEAM_NOISE_DRAWS: usize = 400;

/// Seams searched at every offset modulo a cell ([`seam_any_phase`]).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PhaseSeams {
    /// The cell the offsets are taken modulo, in pixels.
    pub cell: usize,
    /// The ratio farthest from 1 (in log terms) over both axes and every offset.
    pub worst: f64,
    /// Its axis: "x" (a vertical seam between columns) or "y" (between rows).
    pub axis: String,
    /// Its offset: the seam lies between pixels offset and offset + 1 modulo the cell.
    pub offset: usize,
    /// Largest ratio over both axes.
    pub max: f64,
    /// Smallest ratio over both axes.
    pub min: f64,
}

/// All structure figures of `output` against `exemplar` (same channel count, each at
/// least 16 px a side; copy figures need 32 px). `cell` is the seam search's period
/// (default [`DEFAULT_SEAM_CELL`]).
pub fn structure(exemplar: &Raster, output: &Raster, cell: Option<usize>) -> StructureFigures {
    let (coherence, completeness, reference_distance) = coherence_completeness(exemplar, output);
    let (self_repetition, copy_score) = repetition_and_copies(exemplar, output);
    let cell = cell.unwrap_or(DEFAULT_SEAM_CELL);
    StructureFigures {
        coherence,
        completeness,
        reference_distance,
        self_repetition,
        copy_score,
        seams: (output.width >= 2 * cell && output.height >= 2 * cell && cell >= 2)
            .then(|| seam_any_phase(output, cell)),
        seam_noise: (output.width >= 2 * cell && output.height >= 2 * cell && cell >= 2)
            .then(|| seam_noise(output, &[cell], SEAM_NOISE_DRAWS, 1, SEAM_BAR)),
    }
}

/// The seam search's cell when none is claimed: every grid whose period divides it
/// shows up at some offset.
pub const DEFAULT_SEAM_CELL: usize = 32;

/// A patch's values, row by row, channels interleaved, into `dst`.
fn patch_into(r: &Raster, x: usize, y: usize, side: usize, dst: &mut Vec<f32>) {
    dst.clear();
    let c = r.channels;
    for row in y..y + side {
        let start = (row * r.width + x) * c;
        dst.extend_from_slice(&r.data[start..start + side * c]);
    }
}

/// Top-left corners of every `side`-patch inside the rectangle [x0, x1) × [y0, y1),
/// every `stride` pixels.
fn corners(
    (x0, x1): (usize, usize),
    (y0, y1): (usize, usize),
    side: usize,
    stride: usize,
) -> Vec<(usize, usize)> {
    if x1 < x0 + side || y1 < y0 + side {
        return Vec::new();
    }
    let mut v = Vec::new();
    for y in (y0..=y1 - side).step_by(stride) {
        for x in (x0..=x1 - side).step_by(stride) {
            v.push((x, y));
        }
    }
    v
}

/// A searchable set of 8×8 patches of one raster: every position in a rectangle.
struct PatchIndex<'a> {
    raster: &'a Raster,
    corners: Vec<(usize, usize)>,
    tree: KdTree,
}

impl<'a> PatchIndex<'a> {
    fn new(raster: &'a Raster, pca: &Pca, corners: Vec<(usize, usize)>) -> PatchIndex<'a> {
        let out = pca.out();
        let projected: Vec<Vec<f32>> = par_map(&corners, |&(x, y)| {
            let mut v = Vec::new();
            patch_into(raster, x, y, COHERENCE_PATCH, &mut v);
            let mut p = vec![0.0f32; out];
            pca.project(&v, &mut p);
            p
        });
        let flat: Vec<f32> = projected.into_iter().flatten().collect();
        PatchIndex {
            raster,
            tree: KdTree::new(&flat, out),
            corners,
        }
    }

    /// RMS-per-value distance from the patch of `q` at (x, y) to its nearest patch
    /// here (the best of the `RERANK` nearest in projection, re-ranked exactly).
    fn nearest_distance(&self, pca: &Pca, q: &Raster, (x, y): (usize, usize)) -> f64 {
        let mut v = Vec::new();
        patch_into(q, x, y, COHERENCE_PATCH, &mut v);
        let mut p = vec![0.0f32; pca.out()];
        pca.project(&v, &mut p);
        let mut w = Vec::new();
        let mut best = f64::INFINITY;
        for (_, id) in self.tree.nearest(&p, RERANK, |_| true) {
            let (cx, cy) = self.corners[id as usize];
            patch_into(self.raster, cx, cy, COHERENCE_PATCH, &mut w);
            best = best.min(sq_dist(&v, &w) as f64);
        }
        (best / v.len().max(1) as f64).sqrt()
    }
}

/// Principal components of 8×8 patches of `r`, fitted on up to [`PCA_SAMPLES`]
/// positions spread evenly.
fn fit_patch_pca(r: &Raster) -> Pca {
    let all = corners((0, r.width), (0, r.height), COHERENCE_PATCH, 1);
    let step = all.len().div_ceil(PCA_SAMPLES).max(1);
    let mut data = Vec::new();
    let mut v = Vec::new();
    for &(x, y) in all.iter().step_by(step) {
        patch_into(r, x, y, COHERENCE_PATCH, &mut v);
        data.extend_from_slice(&v);
    }
    let dim = COHERENCE_PATCH * COHERENCE_PATCH * r.channels;
    Pca::fit(&data, dim, PROJECTED)
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// (coherence, completeness, reference distance).
pub fn coherence_completeness(exemplar: &Raster, output: &Raster) -> (f64, f64, f64) {
    let p = COHERENCE_PATCH;
    let pca = fit_patch_pca(exemplar);
    let (w, h) = (exemplar.width, exemplar.height);
    // The halves split the longer side.
    let (first, second) = if w >= h {
        (((0, w / 2), (0, h)), ((w / 2, w), (0, h)))
    } else {
        (((0, w), (0, h / 2)), ((0, w), (h / 2, h)))
    };
    let mut reference = Vec::new();
    for (from, to) in [(first, second), (second, first)] {
        let index = PatchIndex::new(exemplar, &pca, corners(to.0, to.1, p, 1));
        let queries = corners(from.0, from.1, p, p);
        reference.extend(par_map(&queries, |&c| {
            index.nearest_distance(&pca, exemplar, c)
        }));
    }
    let reference = mean(&reference);
    let whole = PatchIndex::new(exemplar, &pca, corners((0, w), (0, h), p, 1));
    let queries = corners((0, output.width), (0, output.height), p, p);
    let coherence = mean(&par_map(&queries, |&c| {
        whole.nearest_distance(&pca, output, c)
    }));
    let index = PatchIndex::new(
        output,
        &pca,
        corners((0, output.width), (0, output.height), p, 1),
    );
    let queries = corners((0, w), (0, h), p, p);
    let completeness = mean(&par_map(&queries, |&c| {
        index.nearest_distance(&pca, exemplar, c)
    }));
    (coherence / reference, completeness / reference, reference)
}

/// Per channel, an integral image of the values (f64), (w+1) × (h+1).
fn integral(r: &Raster, c: usize) -> Vec<f64> {
    let (w, h) = (r.width, r.height);
    let mut s = vec![0.0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0.0;
        for x in 0..w {
            row += r.get(x, y, c) as f64;
            s[(y + 1) * (w + 1) + x + 1] = s[y * (w + 1) + x + 1] + row;
        }
    }
    s
}

/// Blocks per side of the contraction a 32×32 patch is searched in.
const BLOCKS: usize = 8;

/// The contraction of mean-removed 32×32 patches that near-copy searches run in: per
/// channel, the 8×8 block sums over 4 (so its norm never exceeds the patch's, by
/// Cauchy–Schwarz), less the patch mean's share.
struct BlockFeatures {
    sums: Vec<Vec<f64>>,
    width: usize,
    channels: usize,
}

impl BlockFeatures {
    fn new(r: &Raster) -> BlockFeatures {
        BlockFeatures {
            sums: (0..r.channels).map(|c| integral(r, c)).collect(),
            width: r.width,
            channels: r.channels,
        }
    }

    fn rect(&self, c: usize, x: usize, y: usize, side: usize) -> f64 {
        let s = &self.sums[c];
        let w = self.width + 1;
        s[(y + side) * w + x + side] - s[y * w + x + side] - s[(y + side) * w + x] + s[y * w + x]
    }

    fn features(&self, x: usize, y: usize, dst: &mut Vec<f32>) {
        dst.clear();
        let b = COPY_PATCH / BLOCKS;
        let scale = 1.0 / b as f64;
        for c in 0..self.channels {
            let patch_mean = self.rect(c, x, y, COPY_PATCH) / (COPY_PATCH * COPY_PATCH) as f64;
            for by in 0..BLOCKS {
                for bx in 0..BLOCKS {
                    let sum = self.rect(c, x + bx * b, y + by * b, b);
                    dst.push(((sum - patch_mean * (b * b) as f64) * scale) as f32);
                }
            }
        }
    }
}

/// A mean-removed 32×32 patch (each channel's own mean), as f64.
fn centred_patch(r: &Raster, x: usize, y: usize) -> Vec<f64> {
    let c = r.channels;
    let mut means = vec![0.0f64; c];
    for row in y..y + COPY_PATCH {
        for col in x..x + COPY_PATCH {
            for (k, m) in means.iter_mut().enumerate() {
                *m += r.get(col, row, k) as f64;
            }
        }
    }
    for m in &mut means {
        *m /= (COPY_PATCH * COPY_PATCH) as f64;
    }
    let mut v = Vec::with_capacity(COPY_PATCH * COPY_PATCH * c);
    for row in y..y + COPY_PATCH {
        for col in x..x + COPY_PATCH {
            for (k, m) in means.iter().enumerate() {
                v.push(r.get(col, row, k) as f64 - m);
            }
        }
    }
    v
}

fn sq_dist64(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// A searchable set of every 32×32 patch position of a raster, in the block
/// contraction projected on its principal components.
struct CopyIndex<'a> {
    raster: &'a Raster,
    corners: Vec<(usize, usize)>,
    tree: KdTree,
}

impl<'a> CopyIndex<'a> {
    fn new(raster: &'a Raster, pca: &Pca) -> CopyIndex<'a> {
        let features = BlockFeatures::new(raster);
        let corners = corners((0, raster.width), (0, raster.height), COPY_PATCH, 1);
        let out = pca.out();
        let projected: Vec<Vec<f32>> = par_map(&corners, |&(x, y)| {
            let mut v = Vec::new();
            features.features(x, y, &mut v);
            let mut p = vec![0.0f32; out];
            pca.project(&v, &mut p);
            p
        });
        let flat: Vec<f32> = projected.into_iter().flatten().collect();
        CopyIndex {
            raster,
            tree: KdTree::new(&flat, out),
            corners,
        }
    }

    /// Whether the mean-removed patch `p` (whose projection is `proj`) has a near-copy
    /// here at a corner `allowed` accepts.
    fn has_near_copy(
        &self,
        p: &[f64],
        proj: &[f32],
        allowed: impl Fn(usize, usize) -> bool,
    ) -> bool {
        let norm2 = p.iter().map(|v| v * v).sum::<f64>();
        let bound = COPY_RELATIVE_L2 * COPY_RELATIVE_L2 * norm2;
        if bound <= 0.0 {
            return false;
        }
        // The f32 projection may round a true hit just past the bound: widen it by a
        // relative 1e-3 and decide on the exact f64 distance.
        let radius2 = (bound * 1.001) as f32;
        self.tree.any_within(proj, radius2, &mut |id, _| {
            let (x, y) = self.corners[id as usize];
            allowed(x, y) && sq_dist64(p, &centred_patch(self.raster, x, y)) < bound
        })
    }
}

/// (self-repetition, copy score) of `output` against `exemplar`.
pub fn repetition_and_copies(exemplar: &Raster, output: &Raster) -> (f64, f64) {
    let queries = corners(
        (0, output.width),
        (0, output.height),
        COPY_PATCH,
        COPY_PATCH,
    );
    if queries.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    // Fitted on the output's own block features; any orthonormal basis keeps the
    // search exact, a good one keeps it fast.
    let sample_features = BlockFeatures::new(output);
    let all = corners((0, output.width), (0, output.height), COPY_PATCH, 1);
    let step = all.len().div_ceil(PCA_SAMPLES).max(1);
    let mut data = Vec::new();
    let mut v = Vec::new();
    for &(x, y) in all.iter().step_by(step) {
        sample_features.features(x, y, &mut v);
        data.extend_from_slice(&v);
    }
    let pca = Pca::fit(&data, BLOCKS * BLOCKS * output.channels, PROJECTED);
    let project = |r: &Raster, feats: &BlockFeatures, (x, y): (usize, usize)| {
        let mut v = Vec::new();
        feats.features(x, y, &mut v);
        let mut p = vec![0.0f32; pca.out()];
        pca.project(&v, &mut p);
        (centred_patch(r, x, y), p)
    };
    let own = CopyIndex::new(output, &pca);
    let repeated = par_map(&queries, |&(x, y)| {
        let (p, proj) = project(output, &sample_features, (x, y));
        own.has_near_copy(&p, &proj, |cx, cy| {
            cx.abs_diff(x) >= COPY_PATCH || cy.abs_diff(y) >= COPY_PATCH
        })
    });
    let self_repetition = share(&repeated);
    let copy_score = if exemplar.width >= COPY_PATCH
        && exemplar.height >= COPY_PATCH
        && exemplar.channels == output.channels
    {
        let source = CopyIndex::new(exemplar, &pca);
        share(&par_map(&queries, |&(x, y)| {
            let (p, proj) = project(output, &sample_features, (x, y));
            source.has_near_copy(&p, &proj, |_, _| true)
        }))
    } else {
        f64::NAN
    };
    (self_repetition, copy_score)
}

fn share(flags: &[bool]) -> f64 {
    flags.iter().filter(|&&f| f).count() as f64 / flags.len().max(1) as f64
}

/// Seams at any phase of `cell`: for each axis and offset o in 0..cell, the mean
/// squared difference (summed over channels) across the pairs between pixel o and o + 1
/// modulo the cell, over the median of the offsets' means. Seams off a claimed grid
/// (a bank whose tiles are placed a few pixels off) show at their own offset.
pub fn seam_any_phase(r: &Raster, cell: usize) -> PhaseSeams {
    let cell = cell.max(2);
    let c = r.channels;
    let mut energy = [vec![0.0f64; cell], vec![0.0f64; cell]];
    let mut count = [vec![0usize; cell], vec![0usize; cell]];
    for y in 0..r.height {
        for x in 0..r.width {
            let here = (y * r.width + x) * c;
            if x + 1 < r.width {
                let next = here + c;
                let g: f64 = (0..c)
                    .map(|k| (r.data[next + k] as f64 - r.data[here + k] as f64).powi(2))
                    .sum();
                energy[0][x % cell] += g;
                count[0][x % cell] += 1;
            }
            if y + 1 < r.height {
                let next = here + r.width * c;
                let g: f64 = (0..c)
                    .map(|k| (r.data[next + k] as f64 - r.data[here + k] as f64).powi(2))
                    .sum();
                energy[1][y % cell] += g;
                count[1][y % cell] += 1;
            }
        }
    }
    let mut best = PhaseSeams {
        cell,
        worst: 1.0,
        axis: "x".into(),
        offset: 0,
        max: f64::MIN,
        min: f64::MAX,
    };
    for axis in 0..2 {
        let means: Vec<f64> = energy[axis]
            .iter()
            .zip(&count[axis])
            .map(|(e, &n)| e / n.max(1) as f64)
            .collect();
        for (o, ratio) in over_median(&means).into_iter().enumerate() {
            best.max = best.max.max(ratio);
            best.min = best.min.min(ratio);
            if ratio.ln().abs() > best.worst.ln().abs() {
                best.worst = ratio;
                best.axis = if axis == 0 { "x" } else { "y" }.into();
                best.offset = o;
            }
        }
    }
    best
}

/// Each offset's mean over the median of the offsets' means (1 where the median is 0).
fn over_median(means: &[f64]) -> Vec<f64> {
    let mut sorted = means.to_vec();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    let median = if n % 2 == 1 {
        sorted[n / 2]
    } else {
        0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
    };
    means
        .iter()
        .map(|m| if median > 0.0 { m / median } else { 1.0 })
        .collect()
}

/// Gradient energy across each pair of neighbouring columns (x, x + 1), summed over
/// rows and channels, and across each pair of neighbouring rows: the lines whose means
/// per offset [`seam_any_phase`] compares.
fn line_energies(r: &Raster) -> [Vec<f64>; 2] {
    let (w, c) = (r.width, r.channels);
    if w * c == 0 {
        return [Vec::new(), Vec::new()];
    }
    let sq = |a: &[f32], b: &[f32]| -> f64 {
        a.iter()
            .zip(b)
            .map(|(&p, &q)| (q as f64 - p as f64).powi(2))
            .sum()
    };
    let lines: Vec<&[f32]> = r.data.chunks_exact(w * c).collect();
    let mut cols = vec![0.0f64; w.saturating_sub(1)];
    for line in &lines {
        for (x, e) in cols.iter_mut().enumerate() {
            *e += sq(&line[x * c..(x + 1) * c], &line[(x + 1) * c..(x + 2) * c]);
        }
    }
    let rows = lines.windows(2).map(|p| sq(p[0], p[1])).collect();
    [cols, rows]
}

/// The worst ratio of [`seam_any_phase`] over both axes and every cell of `cells`,
/// from line energies (each line holds the same number of pixel pairs).
fn worst_phase(lines: [&[f64]; 2], cells: &[usize]) -> f64 {
    let mut worst = 1.0f64;
    for &cell in cells {
        let cell = cell.max(2);
        for line in lines {
            let means: Vec<f64> = (0..cell)
                .map(|o| {
                    let (sum, n) = line
                        .iter()
                        .skip(o)
                        .step_by(cell)
                        .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
                    sum / n.max(1) as f64
                })
                .collect();
            for ratio in over_median(&means) {
                if ratio.ln().abs() > worst.ln().abs() {
                    worst = ratio;
                }
            }
        }
    }
    worst
}

/// What the seam score at any phase reads on an output's own content with no grid
/// behind it ([`seam_noise`]).
#[derive(Clone, Debug, Serialize)]
pub struct SeamNoise {
    /// The worst ratio over `cells` as the output reads it.
    pub observed: f64,
    /// Median of the worst ratio over the draws.
    pub median: f64,
    /// Share of the draws whose worst ratio lies within the bar.
    pub in_bar: f64,
    /// Share of the draws at least as far from 1 (in log terms) as the observed ratio:
    /// small where a grid lines up with some offset.
    pub p_value: f64,
    /// Draws.
    pub draws: usize,
}

/// The seam score's noise floor: the worst ratio of [`seam_any_phase`] over `cells`
/// when the output's column and row gradient energies ([`line_energies`]) are put in a
/// random order, `draws` times (seeded), so that no grid lines up with any offset.
/// Strong, sparse edges (cracks, mortar) make a few lines carry much of the energy, and
/// the means per offset then swing however the texture was made: where the draws fall
/// outside `bar` (lo, hi) most of the time, a texture without any grid would miss it
/// as often. A permutation test of the offset means; a figure that reads far outside
/// its draws shows a grid.
pub fn seam_noise(
    r: &Raster,
    cells: &[usize],
    draws: usize,
    seed: u64,
    (lo, hi): (f64, f64),
) -> SeamNoise {
    use rand::SeedableRng;
    use rand::seq::SliceRandom;
    let [mut cols, mut rows] = line_energies(r);
    let observed = worst_phase([&cols, &rows], cells);
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut worst: Vec<f64> = (0..draws)
        .map(|_| {
            cols.shuffle(&mut rng);
            rows.shuffle(&mut rng);
            worst_phase([&cols, &rows], cells)
        })
        .collect();
    let share = |keep: &dyn Fn(f64) -> bool| {
        worst.iter().filter(|&&w| keep(w)).count() as f64 / draws.max(1) as f64
    };
    let in_bar = share(&|w| (lo..=hi).contains(&w));
    let p_value = share(&|w| w.ln().abs() >= observed.ln().abs());
    worst.sort_by(f64::total_cmp);
    let median = worst.get(worst.len() / 2).copied().unwrap_or(f64::NAN);
    SeamNoise {
        observed,
        median,
        in_bar,
        p_value,
        draws,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(w: usize, h: usize, c: usize, seed: u64) -> Raster {
        let mut s = seed;
        let data = (0..w * h * c)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 40) as f32 / (1u64 << 24) as f32
            })
            .collect();
        Raster::from_vec(w, h, c, data).unwrap()
    }

    /// The line energies give [`seam_any_phase`]'s own worst ratio (the slow twin: the
    /// pixel loop over offsets), and the noise floor sees a planted grid far outside its
    /// draws while white noise stays within the bar.
    #[test]
    fn seam_noise_reads_the_figure_and_its_floor() {
        let mut r = noise(512, 384, 1, 9);
        for cell in [7, 32, 40] {
            let [cols, rows] = line_energies(&r);
            let fast = worst_phase([&cols, &rows], &[cell]);
            let slow = seam_any_phase(&r, cell).worst;
            assert!(
                (fast / slow - 1.0).abs() < 1e-9,
                "cell {cell}: {fast} vs {slow}"
            );
        }
        let white = seam_noise(&r, &[32, 40], 200, 3, (0.9, 1.15));
        assert!(white.in_bar > 0.95, "white noise: {white:?}");
        // A faint ridge every 20 columns: its two columns of pairs carry 1.24 times the
        // energy of the others (uniform noise: 1/6 per pair, 1/6 + 0.04 beside a
        // ridge). At their offsets the figure reads outside the bar; the same column
        // energies in a random order do not.
        for y in 0..r.height {
            for x in (0..r.width).filter(|x| x % 20 == 0) {
                r.data[y * r.width + x] += 0.2;
            }
        }
        let grid = seam_noise(&r, &[40], 200, 3, (0.9, 1.15));
        assert!(grid.observed > 1.18, "{grid:?}");
        assert!(grid.median < 1.12 && grid.in_bar > 0.9, "{grid:?}");
        assert!(
            grid.p_value < 0.01 && white.p_value > 0.01,
            "{grid:?} {white:?}"
        );
        // Seeded: the same draws twice.
        let again = seam_noise(&r, &[40], 200, 3, (0.9, 1.15));
        assert_eq!(again.median.to_bits(), grid.median.to_bits());
    }

    /// A smooth, structured test image: sums of a few sines, plus a little noise.
    fn smooth(w: usize, h: usize, seed: u64) -> Raster {
        let n = noise(w, h, 1, seed);
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                (x * 0.31 + (y * 0.07).sin() * 3.0).sin()
                    + (y * 0.23 + x * 0.05).cos() * 0.7
                    + 0.05 * n.data[i]
            })
            .collect();
        Raster::from_vec(w, h, 1, data).unwrap()
    }

    /// The slow twin: the mean over grid patches of `q` of the exact nearest distance
    /// to any patch of `db` inside `rect`.
    fn brute_mean_nearest(
        q: &Raster,
        qrect: ((usize, usize), (usize, usize)),
        db: &Raster,
        rect: ((usize, usize), (usize, usize)),
    ) -> f64 {
        let p = COHERENCE_PATCH;
        let mut total = Vec::new();
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for (qx, qy) in corners(qrect.0, qrect.1, p, p) {
            patch_into(q, qx, qy, p, &mut a);
            let mut best = f64::INFINITY;
            for (x, y) in corners(rect.0, rect.1, p, 1) {
                patch_into(db, x, y, p, &mut b);
                let d: f64 = a
                    .iter()
                    .zip(&b)
                    .map(|(u, v)| (*u as f64 - *v as f64).powi(2))
                    .sum();
                best = best.min(d);
            }
            total.push((best / a.len() as f64).sqrt());
        }
        mean(&total)
    }

    #[test]
    fn coherence_and_completeness_match_their_brute_force_twins() {
        let ex = smooth(48, 40, 1);
        let out = smooth(64, 56, 2);
        let (coh, comp, reference) = coherence_completeness(&ex, &out);
        let r1 = brute_mean_nearest(&ex, ((0, 24), (0, 40)), &ex, ((24, 48), (0, 40)));
        let r2 = brute_mean_nearest(&ex, ((24, 48), (0, 40)), &ex, ((0, 24), (0, 40)));
        let want_ref = {
            // Means over both halves' queries together (equal counts here).
            0.5 * (r1 + r2)
        };
        let want_coh = brute_mean_nearest(&out, ((0, 64), (0, 56)), &ex, ((0, 48), (0, 40)));
        let want_comp = brute_mean_nearest(&ex, ((0, 48), (0, 40)), &out, ((0, 64), (0, 56)));
        // The fast search re-ranks 8 candidates: never below the exact figure, and
        // within 5% of it on structured data.
        for (fast, slow, what) in [
            (reference, want_ref, "reference"),
            (coh * reference, want_coh, "coherence"),
            (comp * reference, want_comp, "completeness"),
        ] {
            assert!(
                fast >= slow * (1.0 - 1e-5) && fast <= slow * 1.05,
                "{what}: fast {fast} vs brute force {slow}"
            );
        }
    }

    /// Slow twin of the near-copy searches: every pair of positions, compared exactly.
    fn brute_repetition(ex: &Raster, out: &Raster) -> (f64, f64) {
        let queries = corners((0, out.width), (0, out.height), COPY_PATCH, COPY_PATCH);
        let bound = COPY_RELATIVE_L2 * COPY_RELATIVE_L2;
        let (mut rep, mut copy) = (0, 0);
        for &(x, y) in &queries {
            let p = centred_patch(out, x, y);
            let n2 = p.iter().map(|v| v * v).sum::<f64>();
            let hit = |r: &Raster, skip_near: bool| {
                corners((0, r.width), (0, r.height), COPY_PATCH, 1)
                    .into_iter()
                    .filter(|&(cx, cy)| {
                        !skip_near || cx.abs_diff(x) >= COPY_PATCH || cy.abs_diff(y) >= COPY_PATCH
                    })
                    .any(|(cx, cy)| sq_dist64(&p, &centred_patch(r, cx, cy)) < bound * n2)
            };
            rep += hit(out, true) as usize;
            copy += hit(ex, false) as usize;
        }
        (
            rep as f64 / queries.len() as f64,
            copy as f64 / queries.len() as f64,
        )
    }

    #[test]
    fn near_copy_searches_match_their_brute_force_twin() {
        // An output made of exemplar pieces, one of them twice, over fresh noise.
        let ex = noise(70, 60, 2, 5);
        let mut out = noise(128, 96, 2, 9);
        let paste = |out: &mut Raster, (sx, sy): (usize, usize), (dx, dy): (usize, usize)| {
            for y in 0..34 {
                for x in 0..34 {
                    for c in 0..2 {
                        out.set(dx + x, dy + y, c, ex.get(sx + x, sy + y, c) * 1.001);
                    }
                }
            }
        };
        paste(&mut out, (3, 4), (0, 0));
        paste(&mut out, (3, 4), (64, 0));
        paste(&mut out, (30, 20), (32, 62));
        let fast = repetition_and_copies(&ex, &out);
        let slow = brute_repetition(&ex, &out);
        assert_eq!(fast, slow);
        // Queries on the 32-px grid: (0,0) and (64,0) repeat each other; those two and
        // (32,64) are copies; 12 patches in all.
        assert_eq!(slow, (2.0 / 12.0, 3.0 / 12.0));
    }

    /// Twin of the phase search: each column pair's energy by a direct loop, grouped
    /// by offset afterwards.
    #[test]
    fn seams_are_found_off_the_grid() {
        let mut r = noise(256, 192, 1, 3);
        // A step between columns 36 and 37 of every 64-px cell: offset 36 mod 64.
        for y in 0..192 {
            for x in 0..256 {
                if x % 64 > 36 {
                    let v = r.get(x, y, 0);
                    r.set(x, y, 0, v + 0.5 * ((x / 64) % 2) as f32 + 0.3);
                }
            }
        }
        let s = seam_any_phase(&r, 64);
        assert_eq!((s.axis.as_str(), s.offset), ("x", 36));
        let col = |x: usize| {
            (0..192)
                .map(|y| (r.get(x + 1, y, 0) as f64 - r.get(x, y, 0) as f64).powi(2))
                .sum::<f64>()
        };
        let mut by_offset = vec![(0.0, 0usize); 64];
        for x in 0..255 {
            by_offset[x % 64].0 += col(x);
            by_offset[x % 64].1 += 192;
        }
        let means: Vec<f64> = by_offset.iter().map(|(e, n)| e / *n as f64).collect();
        let mut sorted = means.clone();
        sorted.sort_by(f64::total_cmp);
        let median = 0.5 * (sorted[31] + sorted[32]);
        assert!((s.worst - means[36] / median).abs() < 1e-9, "{s:?}");
        // Plain noise: every offset within 15% of the median.
        let clean = seam_any_phase(&noise(512, 512, 1, 4), 32);
        assert!(clean.max < 1.15 && clean.min > 0.85, "{clean:?}");
    }

    /// Noise against a structured exemplar scores far above 1 in coherence; a crop of
    /// the exemplar itself about 1 or below, and is all copies.
    #[test]
    fn noise_is_incoherent_and_a_crop_is_a_copy() {
        let ex = smooth(128, 128, 11);
        let crop = Raster::from_vec(
            64,
            64,
            1,
            (0..64 * 64)
                .map(|i| ex.get(10 + i % 64, 20 + i / 64, 0))
                .collect(),
        )
        .unwrap();
        let figures = structure(&ex, &crop, None);
        assert!(figures.coherence < 0.5, "{figures:?}");
        assert_eq!(figures.copy_score, 1.0);
        let mut n = noise(64, 64, 1, 2);
        for v in &mut n.data {
            *v = (*v - 0.5) * 3.0;
        }
        let figures = structure(&ex, &n, None);
        assert!(figures.coherence > 3.0, "{figures:?}");
        assert_eq!(figures.copy_score, 0.0);
    }
}
