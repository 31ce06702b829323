//! Four lanes per instruction for the ring arithmetic, where the CPU has AVX2
//! (checked at run time: the crate's baseline is x86-64-v2): four points of a row
//! under one ring ([`SpanRing::fold`]), or one point under four rings ([`Group`],
//! the point path of `MillingSurface::eval_mm_cached`).
//!
//! Each step is that of the scalar [`SpanRing::parts`], in the same order, with IEEE
//! operations that round alike in every lane (add, subtract, multiply, divide, square
//! root, floor, comparisons; no fused multiply-add), and the selects and clamps spelt
//! out as the scalar code defines them, so every lane gives the scalar path's bits
//! (`row_folds_equal_point_values_in_f64_bits` and
//! `groups_equal_their_rings_in_f64_bits` check it). Table reads are gathers; a lane
//! whose point is off the ring computes with indices clamped into the tables and is
//! dropped.

use super::ring::{Group, Kind, Padded, SHAPE_LUT, SpanRing};

/// Folds the ring into the points of the row (`xs` and `row` alike long) and returns
/// how many it did: all of them, or 0 without AVX2, where the caller's scalar loop
/// does them.
#[inline(always)]
pub(super) fn span(
    k: &SpanRing,
    xs: &[f64],
    row: &mut [f64],
    lut: &[f32; SHAPE_LUT],
    noise: &Padded,
) -> usize {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        assert!(
            x86::noise_row_fits(k.noise_row as i64),
            "a ring's noise profile lies in the padded profiles"
        );
        // SAFETY: the CPU has AVX2, and the ring's noise profile lies in `noise`.
        return unsafe { x86::span(k, xs, row, lut, noise) };
    }
    let _ = (k, xs, row, lut, noise);
    0
}

/// How the point path evaluates the four rings of a [`Group`] at a point (x, y)
/// (mm), a ring to a lane: for each, whether it covers the point (bit q of the mask
/// for lane q), its R_k and its A_k, as [`SpanRing::parts`] gives them on the row y,
/// bit for bit. [`Scalar`] works everywhere; [`Avx2`] exists only where the CPU has
/// AVX2, and code generic over the two is meant to be inlined into a function
/// compiled for AVX2 (`MillingSurface::eval_mm_cached`), where all of it then uses
/// the wide registers.
pub(super) trait PointLanes: Copy {
    fn group_at(
        self,
        g: &Group,
        kind: Kind,
        point: (f64, f64),
        lut: &[f32; SHAPE_LUT],
        noise: &Padded,
    ) -> (u32, [f64; 4], [f64; 4]);
}

/// One lane after another, [`SpanRing::parts`] itself.
#[derive(Clone, Copy)]
pub(super) struct Scalar;

impl PointLanes for Scalar {
    #[inline(always)]
    fn group_at(
        self,
        g: &Group,
        kind: Kind,
        (x, y): (f64, f64),
        lut: &[f32; SHAPE_LUT],
        noise: &Padded,
    ) -> (u32, [f64; 4], [f64; 4]) {
        let (mut mask, mut v, mut a) = (0, [0.0; 4], [0.0; 4]);
        for q in 0..4 {
            let mut k = g.ring(q, kind);
            k.set_row(y);
            let (c, vq, aq) = k.parts(x, lut, noise);
            (mask, v[q], a[q]) = (mask | (c as u32) << q, vq, aq);
        }
        (mask, v, a)
    }
}

/// Four lanes per instruction: a witness that the CPU has AVX2 ([`Avx2::detect`]).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) struct Avx2(());

#[cfg(target_arch = "x86_64")]
impl Avx2 {
    /// The witness, where the CPU has AVX2.
    #[inline(always)]
    pub(super) fn detect() -> Option<Avx2> {
        std::arch::is_x86_feature_detected!("avx2").then_some(Avx2(()))
    }
}

#[cfg(target_arch = "x86_64")]
impl PointLanes for Avx2 {
    #[inline(always)]
    fn group_at(
        self,
        g: &Group,
        kind: Kind,
        (x, y): (f64, f64),
        lut: &[f32; SHAPE_LUT],
        noise: &Padded,
    ) -> (u32, [f64; 4], [f64; 4]) {
        assert!(
            g.noise_row.iter().all(|&r| x86::noise_row_fits(r as i64)),
            "every ring's noise profile lies in the padded profiles"
        );
        // SAFETY: `self` exists only where the CPU has AVX2, and every lane's noise
        // profile lies in `noise`.
        unsafe { x86::group_at(g, kind, x, y, lut, noise) }
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;
    use std::f64::consts::{FRAC_PI_2, PI, TAU};

    use super::super::config::InteractionKind;
    use super::super::ring::{
        ATAN_POLY, Group, Kind, NOISE_SAMPLES, PADDED_NOISE, Padded, SHAPE_LUT, SpanRing,
    };

    /// Whether a profile starting at entry `row` has its NOISE_SAMPLES + 1 entries in the
    /// padded profiles, as the gathers, which read 4 bytes at `row` + j for j <
    /// NOISE_SAMPLES, need (true for every ring `SpanRing::new` makes; checked so that no
    /// other value can reach them).
    #[inline(always)]
    pub(super) fn noise_row_fits(row: i64) -> bool {
        row >= 0 && row + (NOISE_SAMPLES as i64) < PADDED_NOISE as i64
    }

    /// `if m { a } else { b }` per lane.
    #[inline(always)]
    unsafe fn sel(m: __m256d, a: __m256d, b: __m256d) -> __m256d {
        // SAFETY: inlined into `span`, which runs only where the CPU has AVX2.
        unsafe { _mm256_blendv_pd(b, a, m) }
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
    /// The CPU must have AVX2, and the ring's noise profile must lie in `noise`
    /// (`noise_row_fits`).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn span(
        k: &SpanRing,
        xs: &[f64],
        row: &mut [f64],
        lut: &[f32; SHAPE_LUT],
        noise: &Padded,
    ) -> usize {
        let n = xs.len().min(row.len());
        // SAFETY: the CPU has AVX2 (this function's contract).
        let lanes = unsafe { Lanes::splat(k) };
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
            // SAFETY: the CPU has AVX2, the ring's profile lies in `noise` (this
            // function's contract).
            let g = unsafe { fold(k.kind, &lanes, x, f, lut, noise) };
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

    /// The AVX2 body of [`super::Avx2`]'s `group_at`: not compiled for AVX2 itself,
    /// so that it inlines into the function that calls it, which should be.
    ///
    /// # Safety
    /// The CPU must have AVX2, and every lane's noise profile must lie in `noise`
    /// (`noise_row_fits`).
    #[inline(always)]
    pub(super) unsafe fn group_at(
        g: &Group,
        kind: Kind,
        x: f64,
        y: f64,
        lut: &[f32; SHAPE_LUT],
        noise: &Padded,
    ) -> (u32, [f64; 4], [f64; 4]) {
        // SAFETY: the CPU has AVX2, the lanes' profiles lie in `noise` (this
        // function's contract); the loads read the group's 4-value fields.
        unsafe {
            // `SpanRing::set_row`'s operations, per lane.
            let dy = _mm256_sub_pd(_mm256_set1_pd(y), _mm256_load_pd(g.cy.as_ptr()));
            let dy2 = _mm256_mul_pd(dy, dy);
            let along_y = _mm256_mul_pd(_mm256_load_pd(g.sin_t.as_ptr()), dy);
            let lanes = Lanes::load(g, dy, dy2, along_y);
            let (covered, v, a) = parts(kind, &lanes, _mm256_set1_pd(x), lut, noise);
            let (mut vs, mut ws) = ([0.0; 4], [0.0; 4]);
            _mm256_storeu_pd(vs.as_mut_ptr(), v);
            _mm256_storeu_pd(ws.as_mut_ptr(), a);
            (_mm256_movemask_pd(covered) as u32, vs, ws)
        }
    }

    /// A [`Group`] in registers, with the row's terms dy, dy², sin θ·dy.
    #[derive(Clone, Copy)]
    struct Lanes {
        cx: __m256d,
        dy: __m256d,
        dy2: __m256d,
        edge: __m256d,
        r: __m256d,
        in_lo: __m256d,
        out_hi: __m256d,
        has: [__m256d; 3],
        centre: [__m256d; 3],
        scale: [__m256d; 3],
        slope: [__m256d; 3],
        mid: [__m256d; 3],
        cos_t: __m256d,
        along_y: __m256d,
        to_along: __m256d,
        w_slope: __m256d,
        w_mid: __m256d,
        amplitude: __m256d,
        rotation: __m256d,
        noise_row: __m128i,
    }

    impl Lanes {
        /// Ring `k` on the row it was set to, in every lane.
        #[inline(always)]
        unsafe fn splat(k: &SpanRing) -> Lanes {
            // SAFETY: inlined where the CPU has AVX2.
            unsafe {
                let v = |f: f64| _mm256_set1_pd(f);
                let p = |f: [f64; 3]| f.map(v);
                let m = |b: bool| _mm256_castsi256_pd(_mm256_set1_epi64x(-(b as i64)));
                Lanes {
                    cx: v(k.cx),
                    dy: v(k.dy),
                    dy2: v(k.dy2),
                    edge: v(k.edge),
                    r: v(k.r),
                    in_lo: v(k.in_lo),
                    out_hi: v(k.out_hi),
                    has: k.has.map(m),
                    centre: p(k.centre),
                    scale: p(k.scale),
                    slope: p(k.slope),
                    mid: p(k.mid),
                    cos_t: v(k.cos_t),
                    along_y: v(k.along_y),
                    to_along: v(k.to_along),
                    w_slope: v(k.w_slope),
                    w_mid: v(k.w_mid),
                    amplitude: v(k.amplitude),
                    rotation: v(k.rotation),
                    noise_row: _mm_set1_epi32(k.noise_row as i32),
                }
            }
        }

        /// Group `g` on the row whose terms are `dy`, `dy2`, `along_y`.
        #[inline(always)]
        unsafe fn load(g: &Group, dy: __m256d, dy2: __m256d, along_y: __m256d) -> Lanes {
            // SAFETY: inlined where the CPU has AVX2; each aligned load reads one
            // field of 4 f64 or u64 (`Group` is `repr(C, align(32))` and every such
            // field lies a multiple of 32 bytes from its start), and the unaligned
            // one the 16 bytes of `noise_row`.
            unsafe {
                let v = |f: &[f64; 4]| _mm256_load_pd(f.as_ptr());
                let p = |f: &[[f64; 4]; 3]| [v(&f[0]), v(&f[1]), v(&f[2])];
                let m = |f: &[u64; 4]| _mm256_load_pd(f.as_ptr() as *const f64);
                Lanes {
                    cx: v(&g.cx),
                    dy,
                    dy2,
                    edge: v(&g.edge),
                    r: v(&g.r),
                    in_lo: v(&g.in_lo),
                    out_hi: v(&g.out_hi),
                    has: [m(&g.has[0]), m(&g.has[1]), m(&g.has[2])],
                    centre: p(&g.centre),
                    scale: p(&g.scale),
                    slope: p(&g.slope),
                    mid: p(&g.mid),
                    cos_t: v(&g.cos_t),
                    along_y,
                    to_along: v(&g.to_along),
                    w_slope: v(&g.w_slope),
                    w_mid: v(&g.w_mid),
                    amplitude: v(&g.amplitude),
                    rotation: v(&g.rotation),
                    noise_row: _mm_loadu_si128(g.noise_row.as_ptr() as *const __m128i),
                }
            }
        }
    }

    /// The fold at four points `x` of the row, `f` the values so far.
    #[inline(always)]
    unsafe fn fold(
        kind: Kind,
        l: &Lanes,
        x: __m256d,
        f: __m256d,
        lut: &[f32; SHAPE_LUT],
        noise: &Padded,
    ) -> __m256d {
        // SAFETY: inlined into `span`, which runs only where the CPU has AVX2 and
        // the ring's profile lies in `noise`.
        unsafe {
            let (covered, v, a) = parts(kind, l, x, lut, noise);
            let folded = match kind.interaction {
                InteractionKind::Min => sel(_mm256_cmp_pd::<_CMP_LT_OQ>(v, f), v, f),
                InteractionKind::Latest => v,
                InteractionKind::Convex => _mm256_add_pd(
                    _mm256_mul_pd(a, v),
                    _mm256_mul_pd(_mm256_sub_pd(_mm256_set1_pd(1.0), a), f),
                ),
            };
            sel(covered, folded, f)
        }
    }

    /// [`SpanRing::parts`] per lane: the covered mask, R_k and A_k.
    #[inline(always)]
    unsafe fn parts(
        kind: Kind,
        l: &Lanes,
        x: __m256d,
        lut: &[f32; SHAPE_LUT],
        noise: &Padded,
    ) -> (__m256d, __m256d, __m256d) {
        // SAFETY: inlined into `span` or `group_at`, which run only where the CPU has
        // AVX2 and every lane's profile lies in `noise`.
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
                has: [has_ind, has_in, has_out],
                ..
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
            // by any part ([`SpanRing::parts`]).
            let covered = _mm256_or_pd(ind, _mm256_or_pd(inner, outer));
            let pick = |p: [__m256d; 3]| sel(ind, p[0], sel(inner, p[1], p[2]));
            let slope = pick(l.slope);
            let mid = pick(l.mid);
            let s = if kind.indicator {
                c(-1.0)
            } else {
                let centre = pick(l.centre);
                let scale = pick(l.scale);
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
                _mm256_add_pd(_mm256_mul_pd(l.cos_t, dx), l.along_y),
                l.to_along,
            );
            let mut v = _mm256_mul_pd(s, _mm256_add_pd(_mm256_mul_pd(slope, along), mid));
            if kind.with_noise {
                let turn = _mm256_add_pd(atan2_turns(dy, dx), l.rotation);
                let pos = _mm256_mul_pd(
                    _mm256_sub_pd(turn, _mm256_floor_pd(turn)),
                    c(NOISE_SAMPLES as f64),
                );
                let j = index(pos, NOISE_SAMPLES as i32 - 1);
                let t = _mm256_sub_pd(pos, _mm256_cvtepi32_pd(j));
                // SAFETY: 0 ≤ j ≤ NOISE_SAMPLES − 1 and each lane's padded profile (at
                // noise_row, `noise_row_fits`) has NOISE_SAMPLES + 1 entries: the 4
                // bytes at entry noise_row + j are entries j, j + 1 of the profile.
                let w = _mm_i32gather_epi32::<2>(
                    noise.as_ptr() as *const i32,
                    _mm_add_epi32(l.noise_row, j),
                );
                let a = _mm256_cvtepi32_pd(_mm_srai_epi32::<16>(_mm_slli_epi32::<16>(w)));
                let b = _mm256_cvtepi32_pd(_mm_srai_epi32::<16>(w));
                let nz = _mm256_add_pd(a, _mm256_mul_pd(_mm256_sub_pd(b, a), t));
                v = _mm256_add_pd(v, _mm256_mul_pd(l.amplitude, nz));
            }
            let a = match kind.interaction {
                InteractionKind::Convex => clamp(
                    _mm256_add_pd(_mm256_mul_pd(l.w_slope, along), l.w_mid),
                    0.0,
                    1.0,
                ),
                _ => c(1.0),
            };
            (covered, v, a)
        }
    }
}
