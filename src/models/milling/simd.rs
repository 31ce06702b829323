//! Four points of a row per instruction for [`SpanRing::fold`], where the CPU has
//! AVX2 (checked at run time: the crate's baseline is x86-64-v2).
//!
//! Each step is the scalar [`SpanRing::point`]'s, in the same order, with IEEE
//! operations that round alike in every lane (add, subtract, multiply, divide, square
//! root, floor, comparisons; no fused multiply-add), and the selects and clamps spelt
//! out as the scalar code defines them, so every lane gives the scalar path's bits
//! (`block_fills_equal_point_samples_bit_for_bit` checks the row fill against
//! `height()`, which is scalar). Table reads are gathers; a lane whose point is off
//! the ring computes with indices clamped into the tables and is dropped.
//!

use super::ring::{SHAPE_LUT, SpanRing};

/// Folds the ring into the points of the row (`xs` and `row` alike long) and returns
/// how many it did: all of them, or 0 without AVX2, where the caller's scalar loop
/// does them.
#[inline(always)]
pub(super) fn span(k: &SpanRing, xs: &[f64], row: &mut [f64], lut: &[f32; SHAPE_LUT]) -> usize {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2.
        return unsafe { x86::span(k, xs, row, lut) };
    }
    let _ = (k, xs, row, lut);
    0
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;
    use std::f64::consts::{FRAC_PI_2, PI, TAU};

    use super::super::config::InteractionKind;
    use super::super::ring::{ATAN_POLY, NOISE_SAMPLES, SHAPE_LUT, SpanRing};

    /// `if m { a } else { b }` per lane.
    #[inline(always)]
    unsafe fn sel(m: __m256d, a: __m256d, b: __m256d) -> __m256d {
        // SAFETY: inlined into `span`, which runs only where the CPU has AVX2.
        unsafe { _mm256_blendv_pd(b, a, m) }
    }

    /// A lane mask of `b` (all ones or all zeros).
    #[inline(always)]
    unsafe fn mask(b: bool) -> __m256d {
        // SAFETY: inlined into `span`, which runs only where the CPU has AVX2.
        unsafe { _mm256_castsi256_pd(_mm256_set1_epi64x(-(b as i64))) }
    }

    /// `f64::clamp(x, lo, hi)`: below lo gives lo, above hi gives hi, else x itself
    /// (−0.0 stays −0.0, which `max`/`min` instructions would not promise).
    #[inline(always)]
    unsafe fn clamp(x: __m256d, lo: f64, hi: f64) -> __m256d {
        // SAFETY: inlined into `span`, which runs only where the CPU has AVX2.
        unsafe {
            let (lo, hi) = (_mm256_set1_pd(lo), _mm256_set1_pd(hi));
            let x = sel(_mm256_cmp_pd::<_CMP_LT_OQ>(x, lo), lo, x);
            sel(_mm256_cmp_pd::<_CMP_GT_OQ>(x, hi), hi, x)
        }
    }

    /// `(pos as usize).min(max)` for pos ≥ 0, as 32-bit lanes; lanes that are
    /// negative or NaN (dropped points) give 0.
    #[inline(always)]
    unsafe fn index(pos: __m256d, max: i32) -> __m128i {
        // SAFETY: inlined into `span`, which runs only where the CPU has AVX2.
        unsafe {
            let i = _mm256_cvttpd_epi32(pos);
            _mm_min_epi32(_mm_max_epi32(i, _mm_setzero_si128()), _mm_set1_epi32(max))
        }
    }

    /// [`super::super::ring::atan2_turns`] per lane.
    #[inline(always)]
    unsafe fn atan2_turns(y: __m256d, x: __m256d) -> __m256d {
        // SAFETY: inlined into `span`, which runs only where the CPU has AVX2.
        unsafe {
            let sign = _mm256_set1_pd(-0.0);
            let (ax, ay) = (_mm256_andnot_pd(sign, x), _mm256_andnot_pd(sign, y));
            let x_lt_y = _mm256_cmp_pd::<_CMP_LT_OQ>(ax, ay);
            let (lo, hi) = (sel(x_lt_y, ax, ay), sel(x_lt_y, ay, ax));
            let z = _mm256_div_pd(lo, hi);
            let z2 = _mm256_mul_pd(z, z);
            let c = |v: f64| _mm256_set1_pd(v);
            let [c0, c1, c2, c3, c4, c5] = ATAN_POLY;
            let p = _mm256_sub_pd(c(c4), _mm256_mul_pd(c(c5), z2));
            let p = _mm256_add_pd(c(c3), _mm256_mul_pd(z2, p));
            let p = _mm256_add_pd(c(c2), _mm256_mul_pd(z2, p));
            let p = _mm256_add_pd(c(c1), _mm256_mul_pd(z2, p));
            let mut a = _mm256_mul_pd(z, _mm256_add_pd(c(c0), _mm256_mul_pd(z2, p)));
            a = sel(
                _mm256_cmp_pd::<_CMP_GT_OQ>(ay, ax),
                _mm256_sub_pd(c(FRAC_PI_2), a),
                a,
            );
            let zero = _mm256_setzero_pd();
            a = sel(
                _mm256_cmp_pd::<_CMP_LT_OQ>(x, zero),
                _mm256_sub_pd(c(PI), a),
                a,
            );
            a = sel(
                _mm256_cmp_pd::<_CMP_LT_OQ>(y, zero),
                _mm256_xor_pd(a, sign),
                a,
            );
            let turns = _mm256_mul_pd(a, c(1.0 / TAU));
            sel(_mm256_cmp_pd::<_CMP_EQ_OQ>(hi, zero), zero, turns)
        }
    }

    /// The AVX2 body of [`super::span`]: every point of the row, the last (n mod 4)
    /// through a padded group of four whose extra lanes are dropped.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn span(
        k: &SpanRing,
        xs: &[f64],
        row: &mut [f64],
        lut: &[f32; SHAPE_LUT],
    ) -> usize {
        let n = xs.len().min(row.len());
        let c = |v: f64| _mm256_set1_pd(v);
        let lanes = Lanes {
            cx: c(k.cx),
            dy: c(k.dy),
            dy2: c(k.dy2),
            edge: c(k.edge),
            r: c(k.r),
            in_lo: c(k.in_lo),
            out_hi: c(k.out_hi),
            // SAFETY: the CPU has AVX2 (this function's contract).
            has_ind: unsafe { mask(k.has_ind) },
            has_in: unsafe { mask(k.has_in) },
            has_out: unsafe { mask(k.has_out) },
        };
        for i in (0..n).step_by(4) {
            let m = (n - i).min(4);
            // The last group of a row not a multiple of 4 long goes through arrays
            // padded with its last point.
            let (x, f) = if m == 4 {
                // SAFETY: i + 4 ≤ n ≤ the lengths of both slices.
                unsafe {
                    (
                        _mm256_loadu_pd(xs.as_ptr().add(i)),
                        _mm256_loadu_pd(row.as_ptr().add(i)),
                    )
                }
            } else {
                let (mut xp, mut fp) = ([xs[n - 1]; 4], [row[n - 1]; 4]);
                for q in 0..m {
                    (xp[q], fp[q]) = (xs[i + q], row[i + q]);
                }
                // SAFETY: the arrays hold 4 values each.
                unsafe { (_mm256_loadu_pd(xp.as_ptr()), _mm256_loadu_pd(fp.as_ptr())) }
            };
            // SAFETY: the CPU has AVX2 (this function's contract).
            let g = unsafe { group(k, &lanes, x, f, lut) };
            if m == 4 {
                // SAFETY: as for the loads.
                unsafe { _mm256_storeu_pd(row.as_mut_ptr().add(i), g) };
            } else {
                let mut out = [0.0f64; 4];
                // SAFETY: the array holds 4 values.
                unsafe { _mm256_storeu_pd(out.as_mut_ptr(), g) };
                for (r, &v) in row[i..n].iter_mut().zip(&out) {
                    *r = v;
                }
            }
        }
        n
    }

    /// Lane constants of one ring on one row ([`SpanRing`] broadcast).
    #[derive(Clone, Copy)]
    struct Lanes {
        cx: __m256d,
        dy: __m256d,
        dy2: __m256d,
        edge: __m256d,
        r: __m256d,
        in_lo: __m256d,
        out_hi: __m256d,
        has_ind: __m256d,
        has_in: __m256d,
        has_out: __m256d,
    }

    /// The fold at four points `x` of the row, `f` the values so far.
    #[inline(always)]
    unsafe fn group(
        k: &SpanRing,
        l: &Lanes,
        x: __m256d,
        f: __m256d,
        lut: &[f32; SHAPE_LUT],
    ) -> __m256d {
        // SAFETY: inlined into `span`, which runs only where the CPU has AVX2.
        unsafe {
            let c = |v: f64| _mm256_set1_pd(v);
            let Lanes {
                cx,
                dy,
                dy2,
                edge,
                r,
                in_lo,
                out_hi,
                has_ind,
                has_in,
                has_out,
            } = *l;
            let sign = c(-0.0);
            let dx = _mm256_sub_pd(x, cx);
            let d2 = _mm256_add_pd(_mm256_mul_pd(dx, dx), dy2);
            let dist = _mm256_sqrt_pd(d2);
            let ind = _mm256_and_pd(
                has_ind,
                _mm256_and_pd(
                    _mm256_cmp_pd::<_CMP_GE_OQ>(dist, edge),
                    _mm256_cmp_pd::<_CMP_LE_OQ>(dist, r),
                ),
            );
            let below = _mm256_cmp_pd::<_CMP_LT_OQ>(dist, edge);
            let inner = _mm256_andnot_pd(
                ind,
                _mm256_and_pd(
                    _mm256_and_pd(has_in, below),
                    _mm256_cmp_pd::<_CMP_GE_OQ>(dist, in_lo),
                ),
            );
            let outer = _mm256_andnot_pd(
                ind,
                _mm256_andnot_pd(
                    below,
                    _mm256_and_pd(
                        has_out,
                        _mm256_and_pd(
                            _mm256_cmp_pd::<_CMP_GT_OQ>(dist, r),
                            _mm256_cmp_pd::<_CMP_LE_OQ>(dist, out_hi),
                        ),
                    ),
                ),
            );
            // Within the model's support annulus, as `Drawn::value` first asks: implied
            // by any part ([`SpanRing::point`]).
            let covered = _mm256_or_pd(ind, _mm256_or_pd(inner, outer));
            let pick = |a: f64, b: f64, o: f64| sel(ind, c(a), sel(inner, c(b), c(o)));
            let slope = pick(k.p_ind.0, k.p_in.0, k.p_out.0);
            let mid = pick(k.p_ind.1, k.p_in.1, k.p_out.1);
            let s = if k.indicator {
                c(-1.0)
            } else {
                let centre = pick(k.c_ind, k.c_in, k.c_out);
                let scale = pick(k.k_ind, k.k_in, k.k_out);
                let dd = _mm256_mul_pd(_mm256_sub_pd(dist, centre), scale);
                let dd = clamp(dd, -1.0, 1.0);
                let pos = _mm256_mul_pd(_mm256_add_pd(dd, c(1.0)), c(0.5 * (SHAPE_LUT - 1) as f64));
                let j = index(pos, SHAPE_LUT as i32 - 2);
                let t = _mm256_sub_pd(pos, _mm256_cvtepi32_pd(j));
                // Entries j and j + 1 in one 8-byte read per lane, then the four j-th
                // entries to the low half and the (j + 1)-th to the high one.
                // SAFETY: 0 ≤ j ≤ SHAPE_LUT − 2, so the 8 bytes at entry j lie in the table.
                let pairs = _mm256_i32gather_epi64::<4>(lut.as_ptr() as *const i64, j);
                let split = _mm256_permutevar8x32_ps(
                    _mm256_castsi256_ps(pairs),
                    _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7),
                );
                let (g0, g1) = (
                    _mm256_castps256_ps128(split),
                    _mm256_extractf128_ps::<1>(split),
                );
                let (g0, g1) = (_mm256_cvtps_pd(g0), _mm256_cvtps_pd(g1));
                let cs = _mm256_add_pd(g0, _mm256_mul_pd(_mm256_sub_pd(g1, g0), t));
                sel(ind, _mm256_xor_pd(cs, sign), cs)
            };
            let along = _mm256_mul_pd(
                _mm256_add_pd(_mm256_mul_pd(c(k.cos_t), dx), c(k.along_y)),
                c(k.to_along),
            );
            let mut v = _mm256_mul_pd(s, _mm256_add_pd(_mm256_mul_pd(slope, along), mid));
            if k.with_noise {
                let turn = _mm256_add_pd(atan2_turns(dy, dx), c(k.rotation));
                let pos = _mm256_mul_pd(
                    _mm256_sub_pd(turn, _mm256_floor_pd(turn)),
                    c(NOISE_SAMPLES as f64),
                );
                let j = index(pos, NOISE_SAMPLES as i32 - 1);
                let t = _mm256_sub_pd(pos, _mm256_cvtepi32_pd(j));
                // SAFETY: 0 ≤ j ≤ NOISE_SAMPLES − 1 and the padded profile has
                // NOISE_SAMPLES + 1 entries: the 4 bytes at entry j are entries j, j + 1.
                let w = _mm_i32gather_epi32::<2>(k.noise.as_ptr() as *const i32, j);
                let a = _mm256_cvtepi32_pd(_mm_srai_epi32::<16>(_mm_slli_epi32::<16>(w)));
                let b = _mm256_cvtepi32_pd(_mm_srai_epi32::<16>(w));
                let nz = _mm256_add_pd(a, _mm256_mul_pd(_mm256_sub_pd(b, a), t));
                v = _mm256_add_pd(v, _mm256_mul_pd(c(k.amplitude), nz));
            }
            let folded = match k.interaction {
                InteractionKind::Min => sel(_mm256_cmp_pd::<_CMP_LT_OQ>(v, f), v, f),
                InteractionKind::Latest => v,
                InteractionKind::Convex => {
                    let a = clamp(
                        _mm256_add_pd(_mm256_mul_pd(c(k.w_slope), along), c(k.w_mid)),
                        0.0,
                        1.0,
                    );
                    _mm256_add_pd(
                        _mm256_mul_pd(a, v),
                        _mm256_mul_pd(_mm256_sub_pd(c(1.0), a), f),
                    )
                }
            };
            sel(covered, folded, f)
        }
    }
}
