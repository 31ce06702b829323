//! Generalized normalized cross-correlation (seed 002, eqs. 3–8): two images of any
//! sizes, every shift at which they overlap at all, multi-channel.
//!
//! γ(x′) compares f with g placed at x′, over their overlap only, with the means of that
//! overlap (eq. 3). Eq. (4) rewrites it as
//!
//!   γ = (N·S_fg − S_f·S_g) / (√(N·S_f² − S_f²) · √(N·S_g² − S_g²)),
//!
//! where S_fg is the plain cross-correlation, here by FFT on grids zero-padded to at
//! least N_f + N_g − 1 in each dimension (no wrap-around), and S_f, S_f², S_g, S_g² and N
//! are rectangle sums of integral images (ALGORITHMS.md §4).
//!
//! Channels combine by eqs. (6)–(8): γ = Σᵢ γⁱσ_fⁱσ_gⁱ / Σᵢ σ_fⁱσ_gⁱ, and since
//! γⁱσ_fⁱσ_gⁱ·N = N·S_fgⁱ − S_fⁱ·S_gⁱ and σ_fⁱσ_gⁱ·N = √(N·S_f²ⁱ − S_fⁱ²)·√(N·S_g²ⁱ − S_gⁱ²),
//! numerators and denominators simply add over channels.
//!
//! **Flat overlaps.** A channel whose overlap in f (or g) varies by less than
//! [`FLAT`] of the image's own variance (Σ(f − f̄)² ≤ FLAT·N·var f) carries no structure
//! and contributes nothing; where no channel is left, γ = 0 — never NaN (a one-pixel
//! overlap, a constant image).
//!
//! Each channel has its image-wide mean removed first: γ does not change (eq. 3
//! subtracts the overlap's own means), and the sums that eq. (4) subtracts stay small.

use rustfft::num_complex::Complex64;

use crate::error::{Error, Result};
use crate::fft::Fft2;
use crate::raster::Raster;

/// Relative variance below which an overlap counts as flat (see the module notes).
pub const FLAT: f64 = 1e-6;

/// Most samples an NCC map may have (each of f64 per channel during the computation):
/// 2²⁶, e.g. two 4096² images.
pub const MAX_MAP: usize = 1 << 26;

/// The generalized NCC of f and g at every shift x′ at which they overlap.
#[derive(Clone, Debug, PartialEq)]
pub struct NccMap {
    /// Map width, N_f + N_g − 1.
    pub width: usize,
    /// Map height, M_f + M_g − 1.
    pub height: usize,
    /// Width and height of g: map index (i, j) is the shift x′ = (i − (N_g − 1), j − (M_g − 1)).
    g_size: (usize, usize),
    /// Width and height of f.
    f_size: (usize, usize),
    /// γ, row-major, in [−1, 1].
    pub gamma: Vec<f64>,
}

impl NccMap {
    /// γ at shift (dx, dy) (g's origin placed at (dx, dy) in f's pixels); 0 where the
    /// images do not overlap.
    pub fn at(&self, dx: i64, dy: i64) -> f64 {
        let i = dx + self.g_size.0 as i64 - 1;
        let j = dy + self.g_size.1 as i64 - 1;
        if i < 0 || j < 0 || i >= self.width as i64 || j >= self.height as i64 {
            return 0.0;
        }
        self.gamma[j as usize * self.width + i as usize]
    }

    /// Number of overlapping pixels N at shift (dx, dy).
    pub fn overlap(&self, dx: i64, dy: i64) -> usize {
        let span = |d: i64, nf: usize, ng: usize| {
            let lo = d.max(0);
            let hi = (d + ng as i64).min(nf as i64);
            (hi - lo).max(0) as usize
        };
        span(dx, self.f_size.0, self.g_size.0) * span(dy, self.f_size.1, self.g_size.1)
    }

    /// The shift range: dx in `dx_range().0 ..= dx_range().1`.
    pub fn dx_range(&self) -> (i64, i64) {
        (-(self.g_size.0 as i64 - 1), self.f_size.0 as i64 - 1)
    }

    /// The shift range in y.
    pub fn dy_range(&self) -> (i64, i64) {
        (-(self.g_size.1 as i64 - 1), self.f_size.1 as i64 - 1)
    }
}

/// Checks that f and g can be correlated; returns the map size.
fn check(f: &Raster, g: &Raster) -> Result<(usize, usize)> {
    for (name, r) in [("f", f), ("g", g)] {
        if r.width == 0 || r.height == 0 || r.channels == 0 {
            return Err(Error::TooSmall {
                what: format!("NCC image {name}"),
                message: format!(
                    "{}×{}×{} is empty; expected at least one pixel",
                    r.width, r.height, r.channels
                ),
            });
        }
        if r.data.iter().any(|v| !v.is_finite()) {
            return Err(Error::param(
                format!("NCC image {name}"),
                "(NaN or infinite samples)",
                "finite values: fill missing points first",
            ));
        }
    }
    if f.channels != g.channels {
        return Err(Error::param(
            "NCC channels",
            format!("{} and {}", f.channels, g.channels),
            "two images with the same number of channels",
        ));
    }
    let (w, h) = (f.width + g.width - 1, f.height + g.height - 1);
    if w.saturating_mul(h) > MAX_MAP {
        return Err(Error::Limits(format!(
            "NCC map {w}×{h} over {MAX_MAP} samples"
        )));
    }
    Ok((w, h))
}

/// One channel with its mean removed, as f64, and its variance.
fn centred(r: &Raster, c: usize) -> (Vec<f64>, f64) {
    let n = (r.width * r.height) as f64;
    let v: Vec<f64> = (0..r.width * r.height)
        .map(|i| r.data[i * r.channels + c] as f64)
        .collect();
    let mean = v.iter().sum::<f64>() / n;
    let v: Vec<f64> = v.into_iter().map(|x| x - mean).collect();
    let var = v.iter().map(|x| x * x).sum::<f64>() / n;
    (v, var)
}

/// Summed-area table with a zero first row and column: `(w + 1) × (h + 1)`.
pub(crate) fn integral(v: &[f64], w: usize, h: usize, square: bool) -> Vec<f64> {
    let mut t = vec![0.0; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0.0;
        for x in 0..w {
            let a = v[y * w + x];
            row += if square { a * a } else { a };
            t[(y + 1) * (w + 1) + x + 1] = t[y * (w + 1) + x + 1] + row;
        }
    }
    t
}

/// Sum over [x0, x1) × [y0, y1) of the image behind summed-area table `t`.
#[inline]
fn rect(t: &[f64], w: usize, (x0, x1): (usize, usize), (y0, y1): (usize, usize)) -> f64 {
    let s = w + 1;
    t[y1 * s + x1] - t[y0 * s + x1] - t[y1 * s + x0] + t[y0 * s + x0]
}

/// The smallest 5-smooth number ≥ n (FFT-friendly sizes).
fn smooth_at_least(n: usize) -> usize {
    (n..)
        .find(|&m| {
            let mut k = m;
            for p in [2, 3, 5] {
                while k % p == 0 {
                    k /= p;
                }
            }
            k == 1
        })
        .unwrap_or(n)
}

/// The generalized NCC of `f` and `g` (same channel count, any sizes), eqs. (3)–(8):
/// FFT cross term, integral-image sums. See [`ncc_direct`] for the slow twin.
pub fn ncc(f: &Raster, g: &Raster) -> Result<NccMap> {
    let (mw, mh) = check(f, g)?;
    let (fw, fh, gw, gh) = (f.width, f.height, g.width, g.height);
    let (pw, ph) = (smooth_at_least(mw), smooth_at_least(mh));
    let mut plan = Fft2::new(pw, ph);
    let same = std::ptr::eq(f, g);
    let mut num = vec![0.0f64; mw * mh];
    let mut den = vec![0.0f64; mw * mh];
    for c in 0..f.channels {
        let (fv, fvar) = centred(f, c);
        let (gv, gvar) = if same {
            (fv.clone(), fvar)
        } else {
            centred(g, c)
        };
        // S_fg(s) = Σ_x f(x)·g(x − s) = IFFT(F(f)·conj(F(g)))[s mod P].
        let pad = |v: &[f64], w: usize, h: usize| {
            let mut p = vec![Complex64::default(); pw * ph];
            for y in 0..h {
                for x in 0..w {
                    p[y * pw + x].re = v[y * w + x];
                }
            }
            p
        };
        let mut ff = pad(&fv, fw, fh);
        plan.forward(&mut ff);
        if same {
            for a in ff.iter_mut() {
                *a = Complex64::new(a.norm_sqr(), 0.0);
            }
        } else {
            let mut gg = pad(&gv, gw, gh);
            plan.forward(&mut gg);
            for (a, b) in ff.iter_mut().zip(&gg) {
                *a *= b.conj();
            }
        }
        plan.inverse(&mut ff);
        let scale = 1.0 / (pw * ph) as f64;
        let (tf, tf2) = (integral(&fv, fw, fh, false), integral(&fv, fw, fh, true));
        let (tg, tg2) = (integral(&gv, gw, gh, false), integral(&gv, gw, gh, true));
        for j in 0..mh {
            let dy = j as i64 - (gh as i64 - 1);
            // Overlap rows in f: [max(0, dy), min(fh, dy + gh)); in g: those minus dy.
            let fy = (dy.max(0) as usize, (dy + gh as i64).min(fh as i64) as usize);
            let gy = ((fy.0 as i64 - dy) as usize, (fy.1 as i64 - dy) as usize);
            let sy = dy.rem_euclid(ph as i64) as usize;
            for i in 0..mw {
                let dx = i as i64 - (gw as i64 - 1);
                let fx = (dx.max(0) as usize, (dx + gw as i64).min(fw as i64) as usize);
                let gx = ((fx.0 as i64 - dx) as usize, (fx.1 as i64 - dx) as usize);
                let n = ((fx.1 - fx.0) * (fy.1 - fy.0)) as f64;
                let sx = dx.rem_euclid(pw as i64) as usize;
                let sfg = ff[sy * pw + sx].re * scale;
                let (sf, sf2) = (rect(&tf, fw, fx, fy), rect(&tf2, fw, fx, fy));
                let (sg, sg2) = (rect(&tg, gw, gx, gy), rect(&tg2, gw, gx, gy));
                let df = n * sf2 - sf * sf;
                let dg = n * sg2 - sg * sg;
                // Df/N = Σ(f − f̄)² over the overlap: flat below FLAT·N·var.
                if df <= FLAT * n * n * fvar || dg <= FLAT * n * n * gvar {
                    continue;
                }
                let k = j * mw + i;
                num[k] += n * sfg - sf * sg;
                den[k] += df.sqrt() * dg.sqrt();
            }
        }
    }
    Ok(finish(num, den, (mw, mh), (fw, fh), (gw, gh)))
}

fn finish(
    num: Vec<f64>,
    den: Vec<f64>,
    (mw, mh): (usize, usize),
    f_size: (usize, usize),
    g_size: (usize, usize),
) -> NccMap {
    let gamma = num
        .iter()
        .zip(&den)
        .map(|(&a, &b)| {
            if b > 0.0 {
                (a / b).clamp(-1.0, 1.0)
            } else {
                0.0
            }
        })
        .collect();
    NccMap {
        width: mw,
        height: mh,
        g_size,
        f_size,
        gamma,
    }
}

/// The slow twin of [`ncc`]: eq. (3) per channel as written (overlap means, then the
/// sums of products), combined by eqs. (6)–(8), with the same flatness rule.
/// O(N_f·M_f·N_g·M_g): for tests on small images.
pub fn ncc_direct(f: &Raster, g: &Raster) -> Result<NccMap> {
    let (mw, mh) = check(f, g)?;
    let (fw, fh, gw, gh) = (f.width, f.height, g.width, g.height);
    let mut num = vec![0.0f64; mw * mh];
    let mut den = vec![0.0f64; mw * mh];
    for c in 0..f.channels {
        let (fv, fvar) = centred(f, c);
        let (gv, gvar) = centred(g, c);
        for j in 0..mh {
            let dy = j as i64 - (gh as i64 - 1);
            for i in 0..mw {
                let dx = i as i64 - (gw as i64 - 1);
                let mut pts = Vec::new();
                for y in 0..fh as i64 {
                    for x in 0..fw as i64 {
                        let (gx, gy) = (x - dx, y - dy);
                        if gx >= 0 && gy >= 0 && gx < gw as i64 && gy < gh as i64 {
                            pts.push((
                                fv[y as usize * fw + x as usize],
                                gv[gy as usize * gw + gx as usize],
                            ));
                        }
                    }
                }
                let n = pts.len() as f64;
                let fm = pts.iter().map(|p| p.0).sum::<f64>() / n;
                let gm = pts.iter().map(|p| p.1).sum::<f64>() / n;
                let cross: f64 = pts.iter().map(|p| (p.0 - fm) * (p.1 - gm)).sum();
                let sf: f64 = pts.iter().map(|p| (p.0 - fm).powi(2)).sum();
                let sg: f64 = pts.iter().map(|p| (p.1 - gm).powi(2)).sum();
                if sf <= FLAT * n * fvar || sg <= FLAT * n * gvar {
                    continue;
                }
                // γⁱ·σ_f·σ_g = cross, σ_f·σ_g = √sf·√sg (eqs. 6–8).
                num[j * mw + i] += cross;
                den[j * mw + i] += sf.sqrt() * sg.sqrt();
            }
        }
    }
    Ok(finish(num, den, (mw, mh), (fw, fh), (gw, gh)))
}

/// The normalised autocorrelation of `f`: [`ncc`] of f with itself.
pub fn autocorrelation(f: &Raster) -> Result<NccMap> {
    ncc(f, f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    fn random(w: usize, h: usize, c: usize, seed: u64) -> Raster {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let data = (0..w * h * c)
            .map(|_| rng.random_range(-1.0f32..1.0) + 3.0)
            .collect();
        Raster::from_vec(w, h, c, data).unwrap()
    }

    /// The FFT + integral-image NCC equals the double loop of eq. (3) within 1e-4 at
    /// every shift, for unequal sizes (g wider, g taller, g larger, g = f) and 1 or 3
    /// channels.
    #[test]
    fn fast_ncc_matches_the_direct_double_loop() {
        let mut worst = 0.0f64;
        for (k, &((fw, fh), (gw, gh), c)) in [
            ((13, 9), (7, 11), 1),
            ((10, 12), (16, 5), 3),
            ((9, 8), (9, 8), 3),
            ((17, 6), (4, 4), 1),
        ]
        .iter()
        .enumerate()
        {
            let f = random(fw, fh, c, 2 * k as u64);
            let g = random(gw, gh, c, 2 * k as u64 + 1);
            let (fast, slow) = (ncc(&f, &g).unwrap(), ncc_direct(&f, &g).unwrap());
            assert_eq!((fast.width, fast.height), (fw + gw - 1, fh + gh - 1));
            for (a, b) in fast.gamma.iter().zip(&slow.gamma) {
                assert!(
                    (a - b).abs() <= 1e-4,
                    "{fw}×{fh} vs {gw}×{gh}×{c}: {a} vs {b}"
                );
                worst = worst.max((a - b).abs());
            }
            // Self-correlation: the autocorrelation path against the general one.
            let auto = autocorrelation(&f).unwrap();
            let twin = ncc_direct(&f, &f).unwrap();
            for (a, b) in auto.gamma.iter().zip(&twin.gamma) {
                assert!((a - b).abs() <= 1e-4, "autocorrelation {a} vs {b}");
            }
            assert!((auto.at(0, 0) - 1.0).abs() < 1e-9);
        }
        eprintln!("worst |fast − direct| = {worst:e}");
    }

    /// γ follows its definition at a hand-checked shift: g a crop of f is found at its
    /// offset with γ = 1, and a negated copy gives −1.
    #[test]
    fn crops_are_found_with_gamma_one() {
        let f = random(20, 16, 3, 9);
        let mut g = Raster::zeros(6, 5, 3);
        let mut neg = Raster::zeros(6, 5, 3);
        for y in 0..5 {
            for x in 0..6 {
                for c in 0..3 {
                    let v = f.get(x + 7, y + 4, c);
                    g.data[(y * 6 + x) * 3 + c] = v;
                    neg.data[(y * 6 + x) * 3 + c] = -v;
                }
            }
        }
        let m = ncc(&f, &g).unwrap();
        assert!((m.at(7, 4) - 1.0).abs() < 1e-9, "{}", m.at(7, 4));
        assert_eq!(m.overlap(7, 4), 30);
        assert_eq!(m.overlap(-5, -4), 1);
        let best = (0..m.gamma.len())
            .filter(|&k| {
                let (i, j) = ((k % m.width) as i64 - 5, (k / m.width) as i64 - 4);
                m.overlap(i, j) == 30
            })
            .max_by(|&a, &b| m.gamma[a].total_cmp(&m.gamma[b]))
            .unwrap();
        assert_eq!(
            ((best % m.width) as i64 - 5, (best / m.width) as i64 - 4),
            (7, 4)
        );
        assert!((ncc(&f, &neg).unwrap().at(7, 4) + 1.0).abs() < 1e-9);
    }

    /// Flat images, flat channels and one-pixel overlaps give γ = 0, never NaN.
    #[test]
    fn flat_inputs_give_zero_not_nan() {
        let flat = Raster::from_vec(8, 6, 1, vec![2.5; 48]).unwrap();
        let noisy = random(5, 7, 1, 4);
        for m in [
            ncc(&flat, &flat).unwrap(),
            ncc(&flat, &noisy).unwrap(),
            ncc(&noisy, &flat).unwrap(),
        ] {
            assert!(m.gamma.iter().all(|v| *v == 0.0));
        }
        let m = ncc(&noisy, &noisy).unwrap();
        assert!(m.gamma.iter().all(|v| v.is_finite()));
        assert_eq!(m.at(4, 6), 0.0, "one-pixel overlap");
        // A flat channel beside a structured one: only the structured one counts.
        let mut two = Raster::zeros(5, 7, 2);
        for k in 0..35 {
            two.data[2 * k] = noisy.data[k];
            two.data[2 * k + 1] = 1.0;
        }
        let (a, b) = (ncc(&two, &two).unwrap(), ncc(&noisy, &noisy).unwrap());
        for (x, y) in a.gamma.iter().zip(&b.gamma) {
            assert!((x - y).abs() < 1e-9);
        }
    }

    #[test]
    fn bad_inputs_are_refused() {
        let a = random(4, 4, 1, 1);
        let b = random(4, 4, 3, 1);
        assert!(ncc(&a, &b).unwrap_err().to_string().contains("channels"));
        let e = Raster::zeros(0, 4, 1);
        assert!(ncc(&a, &e).unwrap_err().to_string().contains("empty"));
        let mut n = random(4, 4, 1, 1);
        n.data[3] = f32::NAN;
        assert!(ncc(&n, &a).unwrap_err().to_string().contains("finite"));
    }
}
