//! 2-D FFTs on top of rustfft, with plans built once per size and reused.
//!
//! [`Fft2`]: row-major `height × width` complex f64, unnormalised in both directions
//! (rustfft's convention): `inverse(forward(x)) = width · height · x`. [`RealFft2`]: real
//! planes through their half spectra, about twice as fast, its inverse normalised.

use std::sync::Arc;

use rustfft::num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

/// A 2-D FFT plan for one size; reuse it for every transform of that size.
pub struct Fft2 {
    width: usize,
    height: usize,
    row_fwd: Arc<dyn Fft<f64>>,
    row_inv: Arc<dyn Fft<f64>>,
    col_fwd: Arc<dyn Fft<f64>>,
    col_inv: Arc<dyn Fft<f64>>,
    scratch: Vec<Complex64>,
    transposed: Vec<Complex64>,
}

impl Fft2 {
    /// Plans transforms for a `width × height` grid (both ≥ 1).
    pub fn new(width: usize, height: usize) -> Self {
        let mut planner = FftPlanner::new();
        let row_fwd = planner.plan_fft_forward(width);
        let row_inv = planner.plan_fft_inverse(width);
        let col_fwd = planner.plan_fft_forward(height);
        let col_inv = planner.plan_fft_inverse(height);
        let scratch_len = [&row_fwd, &row_inv, &col_fwd, &col_inv]
            .iter()
            .map(|f| f.get_inplace_scratch_len())
            .max()
            .unwrap_or(0);
        Fft2 {
            width,
            height,
            row_fwd,
            row_inv,
            col_fwd,
            col_inv,
            scratch: vec![Complex64::default(); scratch_len],
            transposed: vec![Complex64::default(); width * height],
        }
    }

    /// Grid width.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Grid height.
    pub fn height(&self) -> usize {
        self.height
    }

    /// In-place forward transform of a row-major `height × width` grid.
    pub fn forward(&mut self, data: &mut [Complex64]) {
        let (r, c) = (self.row_fwd.clone(), self.col_fwd.clone());
        self.process(data, &*r, &*c);
    }

    /// In-place inverse transform (unnormalised: divide by `width · height` yourself).
    pub fn inverse(&mut self, data: &mut [Complex64]) {
        let (r, c) = (self.row_inv.clone(), self.col_inv.clone());
        self.process(data, &*r, &*c);
    }

    fn process(&mut self, data: &mut [Complex64], rows: &dyn Fft<f64>, cols: &dyn Fft<f64>) {
        assert_eq!(
            data.len(),
            self.width * self.height,
            "Fft2: wrong buffer size"
        );
        rows.process_with_scratch(data, &mut self.scratch);
        transpose::transpose(data, &mut self.transposed, self.width, self.height);
        cols.process_with_scratch(&mut self.transposed, &mut self.scratch);
        transpose::transpose(&self.transposed, data, self.height, self.width);
    }
}

/// 2-D transforms of real `width × height` planes through their half spectrum: the
/// `width / 2 + 1` columns kx = 0 … width/2 of the full spectrum, row-major with that
/// width (the other columns are their conjugates mirrored). Rows go through a real FFT
/// (`realfft`), columns through complex ones, so a transform costs about half of
/// [`Fft2`]'s on the same plane.
pub struct RealFft2 {
    width: usize,
    height: usize,
    row_fwd: Arc<dyn realfft::RealToComplex<f64>>,
    row_inv: Arc<dyn realfft::ComplexToReal<f64>>,
    col_fwd: Arc<dyn Fft<f64>>,
    col_inv: Arc<dyn Fft<f64>>,
    real_row: Vec<f64>,
    real_scratch: Vec<Complex64>,
    scratch: Vec<Complex64>,
    transposed: Vec<Complex64>,
}

impl RealFft2 {
    /// Plans transforms for a `width × height` plane (both ≥ 1).
    pub fn new(width: usize, height: usize) -> Self {
        let mut real = realfft::RealFftPlanner::<f64>::new();
        let row_fwd = real.plan_fft_forward(width);
        let row_inv = real.plan_fft_inverse(width);
        let mut planner = FftPlanner::new();
        let col_fwd = planner.plan_fft_forward(height);
        let col_inv = planner.plan_fft_inverse(height);
        let scratch_len = col_fwd
            .get_inplace_scratch_len()
            .max(col_inv.get_inplace_scratch_len());
        let real_scratch_len = row_fwd.get_scratch_len().max(row_inv.get_scratch_len());
        RealFft2 {
            width,
            height,
            row_fwd,
            row_inv,
            col_fwd,
            col_inv,
            real_row: vec![0.0; width],
            real_scratch: vec![Complex64::default(); real_scratch_len],
            scratch: vec![Complex64::default(); scratch_len],
            transposed: vec![Complex64::default(); (width / 2 + 1) * height],
        }
    }

    /// Columns of the half spectrum: `width / 2 + 1`.
    pub fn half_width(&self) -> usize {
        self.width / 2 + 1
    }

    /// Half spectrum of a real row-major plane.
    pub fn forward(&mut self, plane: &[f64]) -> Vec<Complex64> {
        assert_eq!(
            plane.len(),
            self.width * self.height,
            "RealFft2: wrong plane size"
        );
        let mut half = vec![Complex64::default(); self.half_width() * self.height];
        self.forward_top(plane, self.height, &mut half);
        half
    }

    /// [`RealFft2::forward`] into `half` (half_width × height) of a plane whose rows from
    /// `rows` on are zero: only its first `rows` rows are read (`plane` may hold just
    /// those), and the row transforms of the others, zero, are not computed.
    pub fn forward_top(&mut self, plane: &[f64], rows: usize, half: &mut [Complex64]) {
        let (w, h, hw) = (self.width, self.height, self.half_width());
        let rows = rows.min(h);
        assert!(plane.len() >= w * rows, "RealFft2: plane too small");
        assert_eq!(half.len(), hw * h, "RealFft2: wrong spectrum size");
        for (row, out) in plane
            .chunks_exact(w)
            .take(rows)
            .zip(half.chunks_exact_mut(hw))
        {
            self.real_row.copy_from_slice(row);
            // Lengths match the plan, the only error realfft reports for a forward
            // transform.
            let _ =
                self.row_fwd
                    .process_with_scratch(&mut self.real_row, out, &mut self.real_scratch);
        }
        half[rows * hw..].fill(Complex64::default());
        self.columns(half, true);
    }

    /// Real plane of a half spectrum, normalised (divided by `width · height`). The
    /// imaginary parts of columns 0 and, for an even width, width/2 are dropped: the
    /// real part of the full inverse, as [`inverse_real`] takes it.
    pub fn inverse(&mut self, mut half: Vec<Complex64>) -> Vec<f64> {
        let mut plane = vec![0.0; self.width * self.height];
        self.inverse_top(&mut half, self.height, &mut plane);
        plane
    }

    /// [`RealFft2::inverse`] of `half` (overwritten) into the first `rows` rows of the
    /// plane, `plane` (at least width × rows): the other rows are not computed.
    pub fn inverse_top(&mut self, half: &mut [Complex64], rows: usize, plane: &mut [f64]) {
        let (w, h, hw) = (self.width, self.height, self.half_width());
        let rows = rows.min(h);
        assert_eq!(half.len(), hw * h, "RealFft2: wrong spectrum size");
        assert!(plane.len() >= w * rows, "RealFft2: plane too small");
        self.columns(half, false);
        let scale = 1.0 / (w * h) as f64;
        for (row, out) in half
            .chunks_exact_mut(hw)
            .zip(plane.chunks_exact_mut(w))
            .take(rows)
        {
            row[0].im = 0.0;
            if w % 2 == 0 {
                row[hw - 1].im = 0.0;
            }
            // Lengths match the plan and the imaginary parts realfft checks are zero.
            let _ = self
                .row_inv
                .process_with_scratch(row, out, &mut self.real_scratch);
            for v in out.iter_mut() {
                *v *= scale;
            }
        }
    }

    fn columns(&mut self, half: &mut [Complex64], forward: bool) {
        let (h, hw) = (self.height, self.half_width());
        let cols = if forward {
            &self.col_fwd
        } else {
            &self.col_inv
        };
        transpose::transpose(half, &mut self.transposed, hw, h);
        cols.process_with_scratch(&mut self.transposed, &mut self.scratch);
        transpose::transpose(&self.transposed, half, h, hw);
    }
}

/// Periodic Hann window value for sample i of n (the sample centres, so both ends are
/// small and equal): the window of spectra (taper, PSD estimates).
pub(crate) fn hann(i: usize, n: usize) -> f64 {
    let t = (i as f64 + 0.5) / n as f64;
    0.5 - 0.5 * (2.0 * std::f64::consts::PI * t).cos()
}

/// How many frequencies of the full spectrum column `kx` of a [`RealFft2`] half
/// spectrum stands for: 1 for column 0 and, for an even `width`, column width/2 (their
/// own mirrors), 2 for the others (themselves and their mirror images). Sums of power
/// over a half spectrum weighted by it are the full spectrum's.
pub fn half_spectrum_copies(kx: usize, width: usize) -> usize {
    if kx == 0 || 2 * kx == width { 1 } else { 2 }
}

/// Forward FFT of a real row-major plane.
pub fn forward_real(plan: &mut Fft2, plane: &[f64]) -> Vec<Complex64> {
    let mut data: Vec<Complex64> = plane.iter().map(|&v| Complex64::new(v, 0.0)).collect();
    plan.forward(&mut data);
    data
}

/// Inverse FFT, normalised, keeping the real part.
pub fn inverse_real(plan: &mut Fft2, mut spectrum: Vec<Complex64>) -> Vec<f64> {
    plan.inverse(&mut spectrum);
    let scale = 1.0 / (plan.width() * plan.height()) as f64;
    spectrum.iter().map(|c| c.re * scale).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// forward_top and inverse_top against the full transforms: a plane whose rows from
    /// r on are zero has the same half spectrum, and the first rows of the inverse are
    /// the same, bit for bit, on even and odd sizes.
    #[test]
    fn top_transforms_are_the_full_ones_cut_short() {
        for (w, h, r) in [(12usize, 10usize, 4usize), (9, 7, 3), (16, 9, 9)] {
            let plane: Vec<f64> = (0..w * h)
                .map(|i| {
                    if i / w < r {
                        ((i * 7919) % 101) as f64 / 17.0 - 2.0
                    } else {
                        0.0
                    }
                })
                .collect();
            let mut plan = RealFft2::new(w, h);
            let full = plan.forward(&plane);
            let mut top = vec![Complex64::new(9.0, 9.0); full.len()];
            plan.forward_top(&plane[..w * r], r, &mut top);
            assert_eq!(top, full, "{w}×{h}, {r} rows: forward");
            let back = plan.inverse(full.clone());
            let mut rows = vec![7.0; w * r];
            plan.inverse_top(&mut top, r, &mut rows);
            assert_eq!(rows[..], back[..w * r], "{w}×{h}, {r} rows: inverse");
        }
    }

    /// The slow twin: a direct O(n²) 2-D DFT.
    fn naive_dft(plane: &[Complex64], w: usize, h: usize) -> Vec<Complex64> {
        let mut out = vec![Complex64::default(); w * h];
        for ky in 0..h {
            for kx in 0..w {
                let mut acc = Complex64::default();
                for y in 0..h {
                    for x in 0..w {
                        let ang = -2.0
                            * std::f64::consts::PI
                            * ((kx * x) as f64 / w as f64 + (ky * y) as f64 / h as f64);
                        acc += plane[y * w + x] * Complex64::from_polar(1.0, ang);
                    }
                }
                out[ky * w + kx] = acc;
            }
        }
        out
    }

    /// The half spectrum is the full one's first width/2 + 1 columns, and back again
    /// gives the plane, on odd and even sizes.
    #[test]
    fn real_transform_is_the_full_ones_half() {
        for &(w, h) in &[(8usize, 8usize), (7, 5), (12, 9), (1, 6), (6, 1)] {
            let plane: Vec<f64> = (0..w * h).map(|i| (i as f64 * 0.37).sin() + 0.2).collect();
            let full = naive_dft(
                &plane
                    .iter()
                    .map(|&v| Complex64::new(v, 0.0))
                    .collect::<Vec<_>>(),
                w,
                h,
            );
            let mut plan = RealFft2::new(w, h);
            let hw = plan.half_width();
            let half = plan.forward(&plane);
            for ky in 0..h {
                for kx in 0..hw {
                    let (a, b) = (half[ky * hw + kx], full[ky * w + kx]);
                    assert!((a - b).norm() < 1e-9, "{w}×{h} ({kx}, {ky}): {a} vs {b}");
                }
            }
            let back = plan.inverse(half);
            for (a, b) in back.iter().zip(&plane) {
                assert!((a - b).abs() < 1e-12, "{w}×{h}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn matches_naive_dft_on_odd_and_even_sizes() {
        for &(w, h) in &[(8usize, 8usize), (7, 5), (12, 9), (1, 6)] {
            let plane: Vec<Complex64> = (0..w * h)
                .map(|i| Complex64::new((i as f64 * 0.37).sin(), (i as f64 * 0.11).cos()))
                .collect();
            let expected = naive_dft(&plane, w, h);
            let mut plan = Fft2::new(w, h);
            let mut got = plane.clone();
            plan.forward(&mut got);
            for (a, b) in got.iter().zip(&expected) {
                assert!((a - b).norm() < 1e-9, "{w}×{h}: {a} vs {b}");
            }
            plan.inverse(&mut got);
            for (a, b) in got.iter().zip(&plane) {
                assert!((a / (w * h) as f64 - b).norm() < 1e-12);
            }
        }
    }
}
