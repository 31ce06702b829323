//! Integer lattices in Hermite normal form (ALGORITHMS.md §1), for the roller (seed 003)
//! and RSGF (seed 002) tilings.
//!
//! Any integer lattice spanned by u, v (det ≠ 0) has the basis a = (A, 0), b = (B, C) with
//! A > 0, C > 0, 0 ≤ B < A. The rectangle [0, A) × [0, C) is then a fundamental domain, so
//! a tile on an oblique lattice is stored as an A × C image and moving one cell row up
//! shifts x by B: sampling costs two floor divisions whatever the lattice.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// A lattice basis in Hermite normal form: a = (A, 0), b = (B, C), in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Lattice {
    /// A > 0: the horizontal period, and the stored tile's width.
    pub a: i64,
    /// 0 ≤ B < A: the x shift from one cell row to the next.
    pub b: i64,
    /// C > 0: the row height, and the stored tile's height.
    pub c: i64,
}

/// Extended Euclid: (g, m, n) with m·p + n·q = g = gcd(p, q) ≥ 0.
fn extended_gcd(p: i64, q: i64) -> (i64, i64, i64) {
    let (mut r0, mut r1) = (p, q);
    let (mut m0, mut m1) = (1i64, 0i64);
    let (mut n0, mut n1) = (0i64, 1i64);
    while r1 != 0 {
        let k = r0.div_euclid(r1);
        (r0, r1) = (r1, r0 - k * r1);
        (m0, m1) = (m1, m0 - k * m1);
        (n0, n1) = (n1, n0 - k * n1);
    }
    if r0 < 0 {
        (-r0, -m0, -n0)
    } else {
        (r0, m0, n0)
    }
}

/// Largest magnitude of a lattice vector's components, in pixels (2³⁰): far beyond any
/// tile, and small enough that the Hermite normal form's products cannot overflow.
pub const MAX_COMPONENT: i64 = 1 << 30;

impl Lattice {
    /// The Hermite normal form of the lattice spanned by u and v (ALGORITHMS.md §1):
    /// C = gcd(u₂, v₂); with m·u₂ + n·v₂ = C, w = m·u + n·v has w₂ = C;
    /// A = |det(u, v)| / C; B = w₁ mod A. Collinear vectors, and components beyond
    /// ±[`MAX_COMPONENT`], are refused.
    pub fn from_basis(u: (i64, i64), v: (i64, i64)) -> Result<Lattice> {
        if [u.0, u.1, v.0, v.1]
            .iter()
            .any(|c| c.unsigned_abs() > MAX_COMPONENT as u64)
        {
            return Err(Error::param(
                "lattice",
                format!("({},{});({},{})", u.0, u.1, v.0, v.1),
                "vector components within ±2^30 pixels",
            ));
        }
        let det = u.0 as i128 * v.1 as i128 - u.1 as i128 * v.0 as i128;
        if det == 0 {
            return Err(Error::param(
                "lattice",
                format!("({},{});({},{})", u.0, u.1, v.0, v.1),
                "two vectors that are not collinear (non-zero determinant)",
            ));
        }
        let (c, m, n) = extended_gcd(u.1, v.1);
        let a = i64::try_from(det.abs() / c as i128)
            .map_err(|_| Error::param("lattice", det, "a cell area below 2^63 pixels"))?;
        let w1 = m as i128 * u.0 as i128 + n as i128 * v.0 as i128;
        let b = w1.rem_euclid(a as i128) as i64;
        Ok(Lattice { a, b, c })
    }

    /// An axis-aligned lattice of `w × h` cells.
    pub fn rectangular(w: i64, h: i64) -> Result<Lattice> {
        Lattice::from_basis((w, 0), (0, h))
    }

    /// The HNF basis vectors ((A, 0), (B, C)).
    pub fn basis(&self) -> [(i64, i64); 2] {
        [(self.a, 0), (self.b, self.c)]
    }

    /// Cell area in pixels: |det| = A·C.
    pub fn area(&self) -> i64 {
        self.a * self.c
    }

    /// True when the integer point p is a lattice vector.
    pub fn contains(&self, p: (i64, i64)) -> bool {
        p.1.rem_euclid(self.c) == 0 && (p.0 - (p.1 / self.c) * self.b).rem_euclid(self.a) == 0
    }

    /// The lattice seen at mip level `l` (ALGORITHMS.md §1): Λ_L = (Λ ∩ 2ᴸℤ²)/2ᴸ, on which
    /// a Λ-periodic image box-filtered and sampled every 2ᴸ pixels is periodic.
    pub fn at_level(&self, l: u32) -> Lattice {
        let s = 1i64 << l;
        // Λ ∩ sℤ²: points i·(A,0) + j·(B,C) with both coordinates ≡ 0 (mod s). The
        // smallest positive row j·C ≡ 0 (mod s) for which some i solves i·A + j·B ≡ 0,
        // then the smallest positive multiple of A ≡ 0 (mod s); i, j < s suffice.
        let row = (1..=s)
            .find_map(|j| {
                ((j * self.c) % s == 0)
                    .then(|| (0..s).find(|&i| (i * self.a + j * self.b) % s == 0))
                    .flatten()
                    .map(|i| (i * self.a + j * self.b, j * self.c))
            })
            .expect("j = s always works: s·(B, C) ∈ sℤ²");
        let a = (1..=s)
            .map(|k| k * self.a)
            .find(|&v| v % s == 0)
            .expect("s·A ≡ 0 (mod s)");
        let (a, bx, c) = (a / s, row.0 / s, row.1 / s);
        Lattice {
            a,
            b: bx.rem_euclid(a),
            c,
        }
    }

    /// A Lagrange–Gauss reduced basis (u, v): the two shortest independent lattice
    /// vectors, |u| ≤ |v|, with det(u, v) > 0. Its parallelogram is the most compact
    /// fundamental domain, the one a roller tile is carved from.
    pub fn reduced_basis(&self) -> [(i64, i64); 2] {
        let norm = |p: (i64, i64)| p.0 as i128 * p.0 as i128 + p.1 as i128 * p.1 as i128;
        let dot =
            |p: (i64, i64), q: (i64, i64)| p.0 as i128 * q.0 as i128 + p.1 as i128 * q.1 as i128;
        let (mut u, mut v) = ((self.a, 0), (self.b, self.c));
        if norm(v) < norm(u) {
            std::mem::swap(&mut u, &mut v);
        }
        loop {
            // v ← v − round(⟨u,v⟩/|u|²)·u, then swap while v is shorter.
            let k = (dot(u, v) as f64 / norm(u) as f64).round() as i64;
            v = (v.0 - k * u.0, v.1 - k * u.1);
            if norm(v) >= norm(u) {
                break;
            }
            std::mem::swap(&mut u, &mut v);
        }
        if (u.0 as i128 * v.1 as i128 - u.1 as i128 * v.0 as i128) < 0 {
            v = (-v.0, -v.1);
        }
        [u, v]
    }

    /// Cell (i, j) of the integer point p and its position inside the fundamental
    /// domain [0, A) × [0, C): p = i·(A, 0) + j·(B, C) + local.
    pub fn reduce(&self, p: (i64, i64)) -> ((i64, i64), (i64, i64)) {
        let j = p.1.div_euclid(self.c);
        let x = p.0 - j * self.b;
        let i = x.div_euclid(self.a);
        ((i, j), (x - i * self.a, p.1 - j * self.c))
    }
}

/// A `w × h` one-channel pattern that repeats exactly on the lattice spanned by u and v
/// (pixels, not collinear): cos 2πp + 0.6·sin 2πq + 0.3·cos 2π(p + 2q), with (p, q) the
/// coordinates of the pixel in the basis (u, v). The synthetic exemplar of the lattice
/// tests (roller, RSGF) and benches.
pub fn periodic_pattern(w: usize, h: usize, u: (i64, i64), v: (i64, i64)) -> crate::Raster {
    let d = (u.0 * v.1 - u.1 * v.0) as f64;
    // Reciprocal vectors: ⟨u*, u⟩ = 1, ⟨u*, v⟩ = 0.
    let us = (v.1 as f64 / d, -v.0 as f64 / d);
    let vs = (-u.1 as f64 / d, u.0 as f64 / d);
    let tau = std::f64::consts::TAU;
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let p = x * us.0 + y * us.1;
            let q = x * vs.0 + y * vs.1;
            ((tau * p).cos() + 0.6 * (tau * q).sin() + 0.3 * (tau * (p + 2.0 * q)).cos()) as f32
        })
        .collect();
    crate::Raster {
        width: w,
        height: h,
        channels: 1,
        data,
    }
}

/// True when the bases (u, v) and (u', v') span the same lattice: M = [u v]⁻¹[u' v'] is
/// an integer matrix with det ±1 (the test ALGORITHMS.md §1 asks detection tests to use,
/// independent of the Hermite normal form).
pub fn same_lattice(u: (i64, i64), v: (i64, i64), u2: (i64, i64), v2: (i64, i64)) -> bool {
    let d = u.0 as i128 * v.1 as i128 - v.0 as i128 * u.1 as i128;
    if d == 0 {
        return false;
    }
    // [u v]⁻¹ = (1/d)·[[v₂, −v₁], [−u₂, u₁]]; each entry of d·M must be divisible by d.
    let col = |q: (i64, i64)| {
        let (x, y) = (q.0 as i128, q.1 as i128);
        (
            v.1 as i128 * x - v.0 as i128 * y,
            -(u.1 as i128) * x + u.0 as i128 * y,
        )
    };
    let (m11, m21) = col(u2);
    let (m12, m22) = col(v2);
    if [m11, m21, m12, m22].iter().any(|e| e % d != 0) {
        return false;
    }
    let (m11, m21, m12, m22) = (m11 / d, m21 / d, m12 / d, m22 / d);
    (m11 * m22 - m12 * m21).abs() == 1
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Known answers: the lattices, and ALGORITHMS.md's long thin example
    /// (−17,31)/(29,11) → A = 1086, B = 595, C = 1.
    #[test]
    fn hermite_normal_form_known_answers() {
        assert_eq!(
            Lattice::from_basis((32, 0), (0, 24)).unwrap(),
            Lattice { a: 32, b: 0, c: 24 }
        );
        assert_eq!(
            Lattice::from_basis((40, 0), (13, 29)).unwrap(),
            Lattice {
                a: 40,
                b: 13,
                c: 29
            }
        );
        assert_eq!(
            Lattice::from_basis((-17, 31), (29, 11)).unwrap(),
            Lattice {
                a: 1086,
                b: 595,
                c: 1
            }
        );
        // Order and sign of the basis do not matter.
        assert_eq!(
            Lattice::from_basis((29, 11), (17, -31)).unwrap(),
            Lattice {
                a: 1086,
                b: 595,
                c: 1
            }
        );
    }

    #[test]
    fn collinear_vectors_are_refused() {
        let e = Lattice::from_basis((4, 6), (-2, -3))
            .unwrap_err()
            .to_string();
        assert!(e.contains("not collinear"), "{e}");
        assert!(Lattice::from_basis((0, 0), (1, 5)).is_err());
    }

    #[test]
    fn unimodular_test_on_hand_made_bases() {
        // Same lattice: v' = v + 2u, u' = −u.
        assert!(same_lattice((40, 0), (13, 29), (-40, 0), (93, 29)));
        // A sublattice (index 2) is not the same lattice.
        assert!(!same_lattice((40, 0), (13, 29), (80, 0), (13, 29)));
        // Different lattice of the same area.
        assert!(!same_lattice((32, 0), (0, 24), (24, 0), (0, 32)));
    }

    /// Λ_L by brute force: the points of Λ inside a window that are multiples of 2ᴸ,
    /// divided by 2ᴸ, must be exactly the points of `at_level(l)` there.
    #[test]
    fn mip_lattices_match_brute_force() {
        for (u, v) in [
            ((32, 0), (0, 24)),
            ((40, 0), (13, 29)),
            ((-17, 31), (29, 11)),
            ((7, 3), (2, 5)),
        ] {
            let l0 = Lattice::from_basis(u, v).unwrap();
            for l in 0..5u32 {
                let s = 1i64 << l;
                let ll = l0.at_level(l);
                assert!(ll.a > 0 && ll.c > 0 && (0..ll.a).contains(&ll.b), "{ll:?}");
                for y in -40..40i64 {
                    for x in -80..80i64 {
                        assert_eq!(
                            l0.contains((x * s, y * s)),
                            ll.contains((x, y)),
                            "{u:?} {v:?} level {l} at ({x}, {y})"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn reduced_bases_are_short_and_span_the_lattice() {
        let l = Lattice::from_basis((-17, 31), (29, 11)).unwrap();
        let [u, v] = l.reduced_basis();
        assert!(same_lattice(u, v, (-17, 31), (29, 11)));
        let n = |p: (i64, i64)| p.0 * p.0 + p.1 * p.1;
        // u must be as short as the shortest non-zero lattice vector, found by brute
        // force over a window.
        let shortest = (-100..100i64)
            .flat_map(|x| (-100..100i64).map(move |y| (x, y)))
            .filter(|&p| p != (0, 0) && l.contains(p))
            .map(n)
            .min()
            .unwrap();
        assert_eq!(n(u), shortest);
        assert!(u.0 * v.1 - u.1 * v.0 > 0);
    }

    proptest! {
        /// For any non-degenerate basis the HNF spans the same lattice, is normalised,
        /// and reduction lands in the fundamental domain with a lattice-vector remainder.
        #[test]
        fn hnf_spans_the_same_lattice(u0 in -60i64..60, u1 in -60i64..60, v0 in -60i64..60, v1 in -60i64..60,
                                      px in -5000i64..5000, py in -5000i64..5000) {
            prop_assume!(u0 * v1 - u1 * v0 != 0);
            let l = Lattice::from_basis((u0, u1), (v0, v1)).unwrap();
            prop_assert!(l.a > 0 && l.c > 0 && (0..l.a).contains(&l.b));
            prop_assert_eq!(l.area(), (u0 * v1 - u1 * v0).abs());
            let [a, b] = l.basis();
            prop_assert!(same_lattice((u0, u1), (v0, v1), a, b));
            prop_assert!(l.contains((u0, u1)) && l.contains((v0, v1)));
            let ((i, j), (lx, ly)) = l.reduce((px, py));
            prop_assert!((0..l.a).contains(&lx) && (0..l.c).contains(&ly));
            prop_assert_eq!((i * l.a + j * l.b + lx, j * l.c + ly), (px, py));
        }
    }
}
