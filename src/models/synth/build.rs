//! The bake of parallel controllable texture synthesis ([`crate::models::synth`]):
//! the exemplar's Gaussian stack, appearance vectors and k-coherence candidate sets
//! (Lefebvre & Hoppe 2005, §3; appearance space, Lefebvre & Hoppe 2006, §3).
//!
//! - **Gaussian stack** (2005, §3.1): level l (spacing h_l = 2^(n−1−l)) is the exemplar
//!   blurred to the scale of h_l, at full resolution: the level below convolved with the
//!   binomial kernel [1 4 6 4 1]/16 dilated by h_l/2 (à trous; borders clamped), so the
//!   blur's standard deviation is about 0.58·h_l.
//! - **Appearance vectors** (2006, §3): each pixel's 5×5 window of its stack level,
//!   samples h_l apart, every channel, projected on the window's leading principal
//!   components (fitted per level).
//! - **k-coherence** (2005, §3.3, after Tong et al. 2002): each pixel's candidates are
//!   itself and the k − 1 pixels of most similar appearance at least one spacing (and
//!   2 px) away, among those a synthesis may use (at most side − h_l).

use crate::error::{Error, Result};
use crate::models::synth::{SynthLevel, SynthModel, SynthParams};
use crate::nn::{KdTree, Pca, par_map};
use crate::raster::Raster;

/// Positions the appearance PCA is fitted on, at most.
const PCA_SAMPLES: usize = 16_384;

/// Builds the synthesis model of `ex` with `params` (levels 0 = the default).
pub fn synth_model(ex: &Raster, params: &SynthParams) -> Result<SynthModel> {
    let (w, h, c) = (ex.width, ex.height, ex.channels);
    let mut params = params.clone();
    if params.levels == 0 {
        params.levels = SynthParams::default_levels(w, h);
    }
    params.validate()?;
    params.check_exemplar(w, h, c)?;
    if let Some(i) = ex.data.iter().position(|v| !v.is_finite()) {
        return Err(Error::decode(
            "exemplar",
            format!(
                "pixel ({}, {}) holds {}; synthesis needs finite values in every channel",
                (i / c) % w,
                (i / c) / w,
                ex.data[i]
            ),
        ));
    }
    let n = params.levels;
    // Stack from fine to coarse.
    let mut stacks = vec![ex.data.clone()];
    for l in (0..n - 1).rev() {
        let spacing = 1usize << (n - 1 - l);
        let finer = stacks.last().map(|s| s.as_slice()).unwrap_or(&[]);
        stacks.push(binomial_blur(finer, w, h, c, spacing / 2));
    }
    stacks.reverse();
    let mut levels = Vec::with_capacity(n);
    for (l, stack) in stacks.into_iter().enumerate() {
        let spacing = 1i32 << (n - 1 - l);
        let appearance =
            appearance_vectors(&stack, w, h, c, spacing as usize, params.appearance_dims);
        let candidates =
            candidate_sets(&appearance, w, h, params.appearance_dims, spacing, params.k);
        levels.push(SynthLevel {
            spacing,
            stack,
            appearance,
            candidates,
        });
    }
    Ok(SynthModel {
        w,
        h,
        channels: c,
        params,
        levels,
    })
}

/// One à-trous binomial step: [1 4 6 4 1]/16 along x then y, taps `step` apart,
/// borders clamped.
fn binomial_blur(src: &[f32], w: usize, h: usize, c: usize, step: usize) -> Vec<f32> {
    const TAPS: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
    let step = step.max(1) as i64;
    let pass = |src: &[f32], horizontal: bool| {
        let mut out = vec![0.0f32; src.len()];
        for y in 0..h {
            for x in 0..w {
                for k in 0..c {
                    let mut s = 0.0f32;
                    for (t, &wt) in TAPS.iter().enumerate() {
                        let o = (t as i64 - 2) * step;
                        let (sx, sy) = if horizontal {
                            ((x as i64 + o).clamp(0, w as i64 - 1) as usize, y)
                        } else {
                            (x, (y as i64 + o).clamp(0, h as i64 - 1) as usize)
                        };
                        s += wt * src[(sy * w + sx) * c + k];
                    }
                    out[(y * w + x) * c + k] = s;
                }
            }
        }
        out
    };
    pass(&pass(src, true), false)
}

/// One stack level: values, width, height, channels.
struct Stack<'a> {
    values: &'a [f32],
    w: usize,
    h: usize,
    c: usize,
}

impl Stack<'_> {
    /// The 5×5 window at (x, y), samples `spacing` apart (clamped), every channel.
    fn window(&self, spacing: usize, x: usize, y: usize, dst: &mut Vec<f32>) {
        dst.clear();
        let (w, h, c) = (self.w, self.h, self.c);
        let s = spacing as i64;
        for j in -2..=2i64 {
            let sy = (y as i64 + j * s).clamp(0, h as i64 - 1) as usize;
            for i in -2..=2i64 {
                let sx = (x as i64 + i * s).clamp(0, w as i64 - 1) as usize;
                dst.extend_from_slice(&self.values[(sy * w + sx) * c..(sy * w + sx + 1) * c]);
            }
        }
    }
}

/// Appearance vectors (`w × h × dims`) of one stack level.
fn appearance_vectors(
    stack: &[f32],
    w: usize,
    h: usize,
    c: usize,
    spacing: usize,
    dims: usize,
) -> Vec<f32> {
    let level = Stack {
        values: stack,
        w,
        h,
        c,
    };
    let step = (w * h).div_ceil(PCA_SAMPLES).max(1);
    let mut data = Vec::new();
    let mut v = Vec::new();
    for i in (0..w * h).step_by(step) {
        level.window(spacing, i % w, i / w, &mut v);
        data.extend_from_slice(&v);
    }
    let pca = Pca::fit(&data, 25 * c, dims);
    let rows: Vec<usize> = (0..h).collect();
    par_map(&rows, |&y| {
        let mut v = Vec::new();
        let mut out = vec![0.0f32; w * dims];
        for x in 0..w {
            level.window(spacing, x, y, &mut v);
            pca.project(&v, &mut out[x * dims..(x + 1) * dims]);
        }
        out
    })
    .concat()
}

/// k-coherence candidates (`w × h × k`, linear indices) of one level.
///
/// The search runs on the pixels of a sub-grid of stride max(2, h_l/2) (the tree holds
/// them, and they are the queries); every other pixel takes its sub-grid corner's
/// candidates shifted by its offset, clamped to the usable range (a coherent shift,
/// as k-coherence itself assumes). Half a spacing is below the jitter a level adds,
/// and the search, slow at coarse levels where the smooth stack makes many near
/// neighbours fall inside the exclusion, costs stride² less: the bake of a 256²
/// exemplar fell from 9.3 s to 0.6 s with the structure figures unchanged (gravel:
/// coherence 0.281 → 0.280, completeness 0.361 → 0.368).
fn candidate_sets(
    appearance: &[f32],
    w: usize,
    h: usize,
    dims: usize,
    spacing: i32,
    k: usize,
) -> Vec<u32> {
    let m = spacing as usize;
    let stride = (m / 2).max(2);
    let on_grid = |i: usize| (i % w).is_multiple_of(stride) && (i / w).is_multiple_of(stride);
    let usable: Vec<u32> = (0..w * h)
        .filter(|&i| {
            let (x, y) = (i % w, i / w);
            x + m <= w && y + m <= h && on_grid(i)
        })
        .map(|i| i as u32)
        .collect();
    let points: Vec<f32> = usable
        .iter()
        .flat_map(|&i| {
            appearance[i as usize * dims..(i as usize + 1) * dims]
                .iter()
                .copied()
        })
        .collect();
    let tree = KdTree::new(&points, dims);
    let away = spacing.max(2);
    let corners: Vec<u32> = (0..(w * h) as u32)
        .filter(|&i| on_grid(i as usize))
        .collect();
    let found = par_map(&corners, |&i| {
        let (x, y) = ((i as usize % w) as i32, (i as usize / w) as i32);
        let q = &appearance[i as usize * dims..(i as usize + 1) * dims];
        tree.nearest(q, k - 1, |t| {
            let u = usable[t as usize] as usize;
            let (ux, uy) = ((u % w) as i32, (u / w) as i32);
            (ux - x).abs() >= away || (uy - y).abs() >= away
        })
        .into_iter()
        .map(|(_, t)| usable[t as usize])
        .collect::<Vec<u32>>()
    });
    let columns = w.div_ceil(stride);
    let (xmax, ymax) = ((w - m) as i32, (h - m) as i32);
    let mut sets = vec![0u32; w * h * k];
    for i in 0..w * h {
        let (x, y) = (i % w, i / w);
        let corner = &found[(y / stride) * columns + x / stride];
        let (ox, oy) = ((x % stride) as i32, (y % stride) as i32);
        let set = &mut sets[i * k..(i + 1) * k];
        set.fill(i as u32);
        for (slot, &c) in set[1..].iter_mut().zip(corner) {
            let cx = ((c as usize % w) as i32 + ox).min(xmax);
            let cy = ((c as usize / w) as i32 + oy).min(ymax);
            *slot = (cy as usize * w + cx as usize) as u32;
        }
    }
    sets
}
