//! The coordinate hashes of surftile, to be shared bit for bit with `shaders/`.
//!
//! All use only 32-bit wrapping multiply, add, xor and shift, so a WGSL twin gives
//! identical bits. `pcg4d` is the 4-D PCG-family hash of Jarzynski & Olano, "Hash
//! Functions for GPU Rendering" (JCGT 9(3), 2020), mapping (seed, cell i, cell j, stream)
//! to four words. The per-sample paths use shorter chains: [`hash_tile`] (the toroidal
//! rule's cell, Wellons' lowbias32 finish) and [`hash_vertex`] (the blend rule's vertex,
//! one more round for the offsets). Never `fract(sin(x) * 43758.5453)`: it bands and
//! repeats.

/// Folds a signed 64-bit cell index into 32 bits.
///
/// The low word is kept as is; the high word is mixed in with a Weyl constant, so cells
/// 2³² apart do not collide. For |i| < 2³¹ the high word is 0 or all ones, which keeps
/// the GPU twin (two i32 words) cheap.
#[inline(always)]
pub fn fold_cell(i: i64) -> u32 {
    let lo = i as u32;
    let hi = (i >> 32) as u32;
    lo ^ hi.wrapping_mul(0x9E37_79B9)
}

/// PCG 4-D hash (Jarzynski & Olano 2020, `pcg4d`): 4 words in, 4 words out.
#[inline(always)]
pub fn pcg4d(v: [u32; 4]) -> [u32; 4] {
    let mut x = v[0].wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
    let mut y = v[1].wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
    let mut z = v[2].wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
    let mut w = v[3].wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
    x = x.wrapping_add(y.wrapping_mul(w));
    y = y.wrapping_add(z.wrapping_mul(x));
    z = z.wrapping_add(x.wrapping_mul(y));
    w = w.wrapping_add(y.wrapping_mul(z));
    x ^= x >> 16;
    y ^= y >> 16;
    z ^= z >> 16;
    w ^= w >> 16;
    x = x.wrapping_add(y.wrapping_mul(w));
    y = y.wrapping_add(z.wrapping_mul(x));
    z = z.wrapping_add(x.wrapping_mul(y));
    w = w.wrapping_add(y.wrapping_mul(z));
    [x, y, z, w]
}

/// Hash of (seed, triangle-grid vertex (i, j)) for the blend rule: word 0 is
/// [`hash_tile`] and picks the tile ([`pick_tile`], its high half); word 1, one more
/// xor–multiply–xorshift round of word 0, gives the x offset (low 16 bits) and the y
/// offset (high 16 bits).
///
/// Word 1 is a bijection of word 0, so a vertex has 2³² possible choices, far more than
/// the (tile, x offset, y offset) combinations of a usual bank (8 tiles of 256²: 2¹⁹);
/// the extra round decorrelates the offsets from the tile's bits
/// (`hash_vertex_offsets_are_balanced_and_independent_of_the_tile`). It replaced the PCG hash `pcg3d` here, which spent a quarter
/// of a `height()` call's instructions on three hashes; see the README's deviations.
#[inline(always)]
pub fn hash_vertex(seed: u32, i: i64, j: i64) -> [u32; 2] {
    let a = hash_tile(seed, i, j);
    let b = (a ^ 0x5BD1_E995).wrapping_mul(0x2C1B_3C6D);
    [a, b ^ (b >> 15)]
}

/// One 32-bit hash of (seed, cell (i, j)) for choosing a tile, built for latency: the
/// folded coordinates and the seed are combined by odd multipliers and finished by
/// Wellons' `lowbias32` (two multiply–xorshift rounds), so the chain is about half as
/// long as a PCG hash's. The toroidal rule's per-cell choice, on its sample path.
#[inline(always)]
pub fn hash_tile(seed: u32, i: i64, j: i64) -> u32 {
    hash_tile_keyed(tile_key(seed), i, j)
}

/// The seed's term in [`hash_tile`], for callers that hash many cells with one seed.
#[inline(always)]
pub fn tile_key(seed: u32) -> u32 {
    seed.wrapping_mul(0xC2B2_AE3D).wrapping_add(0x2545_F491)
}

/// [`hash_tile`] with the seed's term [`tile_key`] computed once.
#[inline(always)]
pub fn hash_tile_keyed(key: u32, i: i64, j: i64) -> u32 {
    let mut h =
        fold_cell(i).wrapping_mul(0x9E37_79B1) ^ fold_cell(j).wrapping_mul(0x85EB_CA77) ^ key;
    h ^= h >> 16;
    h = h.wrapping_mul(0x7FEB_352D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846C_A68B);
    h ^ (h >> 16)
}

/// Hash of (seed, cell (i, j), stream): the entry point every placement rule uses.
#[inline(always)]
pub fn hash_cell(seed: u32, i: i64, j: i64, stream: u32) -> [u32; 4] {
    pcg4d([seed, fold_cell(i), fold_cell(j), stream])
}

/// Tile index in 0..k from a hash word: ⌊(h >> 16) · k / 2¹⁶⌋.
///
/// Multiply-shift range reduction (Lemire 2019) on the word's high half: no division and
/// no branch, in 32-bit arithmetic the WGSL twin can repeat. Uniform to within 1/2¹⁶ for
/// any k ≤ 2¹⁶ (banks hold at most 4096 tiles).
#[inline(always)]
pub fn pick_tile(h: u32, k: u32) -> u32 {
    debug_assert!(k <= 1 << 16);
    ((h >> 16) * k) >> 16
}

/// The Wang tile of cell (i, j) with K colours per edge direction (ALGORITHMS.md §6):
/// the vertical edge left of cell (i, j) has colour `pick_tile(hash_cell(seed, i, j, 1)[0], K)`,
/// the horizontal edge below it (row 0 side) `pick_tile(hash_cell(seed, i, j, 2)[0], K)`;
/// the cell shows tile ((W·K + E)·K + S)·K + N with W, E its left and right vertical
/// edges and S, N its row-0 and far horizontal edges.
#[inline(always)]
pub fn wang_tile(seed: u32, i: i64, j: i64, k: u32) -> u32 {
    let colour = |i: i64, j: i64, stream: u32| pick_tile(hash_cell(seed, i, j, stream)[0], k);
    let (w, e) = (colour(i, j, 1), colour(i.wrapping_add(1), j, 1));
    let (s, n) = (colour(i, j, 2), colour(i, j.wrapping_add(1), 2));
    ((w * k + e) * k + s) * k + n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Known answers computed independently (Python, 32-bit masked arithmetic, from
    /// the listing in Jarzynski & Olano 2020).
    #[test]
    fn pcg4d_known_answers() {
        assert_eq!(pcg4d([0, 0, 0, 0]), KNOWN_0000);
        assert_eq!(pcg4d([1, 2, 3, 4]), KNOWN_1234);
    }
    /// Known answers computed independently (Python, 32-bit masked arithmetic).
    #[test]
    fn pick_tile_is_uniform_and_in_range() {
        for k in [1u32, 3, 7, 8, 4096] {
            let mut count = vec![0u32; k as usize];
            let n = 60_000u32;
            for c in 0..n {
                let t = pick_tile(hash_vertex(5, (c % 300) as i64, (c / 300) as i64)[0], k);
                count[t as usize] += 1;
            }
            let expect = n as f64 / k as f64;
            if k <= 8 {
                for &m in &count {
                    // 5 standard deviations of a binomial count.
                    assert!(
                        (m as f64 - expect).abs() < 5.0 * expect.sqrt(),
                        "k={k}: {count:?}"
                    );
                }
            } else {
                assert!(count.iter().filter(|&&m| m > 0).count() > 4000, "k={k}");
            }
        }
    }

    const KNOWN_0000: [u32; 4] = [251_852_841, 760_645_481, 850_445_371, 3_542_436_074];
    const KNOWN_1234: [u32; 4] = [908_250_390, 4_044_648_920, 3_775_961_919, 45_698_095];

    #[test]
    fn fold_keeps_small_cells_distinct_and_separates_far_ones() {
        assert_ne!(fold_cell(-1), fold_cell(1));
        assert_ne!(fold_cell(5), fold_cell(5 + (1 << 32)));
        assert_eq!(fold_cell(7), 7);
    }

    /// Each output bit of the hash of neighbouring cells is set about half the time,
    /// and flipping one input bit flips about half of the output bits (avalanche).
    #[test]
    fn hash_is_balanced_and_avalanches() {
        let mut ones = [0u32; 32];
        let n = 20_000u32;
        let mut flips = 0u64;
        for k in 0..n {
            let i = (k % 200) as i64 - 100;
            let j = (k / 200) as i64 - 50;
            let h = hash_cell(9, i, j, 0)[0];
            for (b, one) in ones.iter_mut().enumerate() {
                *one += (h >> b) & 1;
            }
            let h2 = hash_cell(9, i ^ 1, j, 0)[0];
            flips += (h ^ h2).count_ones() as u64;
        }
        for (b, &one) in ones.iter().enumerate() {
            let p = one as f64 / n as f64;
            assert!((p - 0.5).abs() < 0.02, "bit {b} set with frequency {p}");
        }
        let mean_flips = flips as f64 / n as f64;
        assert!(
            (mean_flips - 16.0).abs() < 0.5,
            "mean flipped bits {mean_flips}"
        );
    }

    /// Known answers computed independently (Python, 32-bit masked arithmetic).
    #[test]
    fn hash_tile_known_answers() {
        assert_eq!(hash_tile(0, 0, 0), 2_409_258_929);
        assert_eq!(hash_tile(7, 1, 2), 537_358_485);
        assert_eq!(hash_tile(3, -5, 1 << 40), 1_248_865_056);
    }

    /// `hash_tile` is balanced over neighbouring cells, avalanches, and spreads a block
    /// of cells evenly over 4 tiles (each within 3% of a quarter).
    #[test]
    fn hash_tile_is_balanced_and_avalanches() {
        let mut ones = [0u32; 32];
        let mut counts = [0u32; 4];
        let n = 20_000u32;
        let mut flips = 0u64;
        for k in 0..n {
            let (i, j) = ((k % 200) as i64 - 100, (k / 200) as i64 - 50);
            let h = hash_tile(9, i, j);
            for (b, one) in ones.iter_mut().enumerate() {
                *one += (h >> b) & 1;
            }
            counts[pick_tile(h, 4) as usize] += 1;
            flips += (h ^ hash_tile(9, i ^ 1, j)).count_ones() as u64;
            flips += (h ^ hash_tile(9, i, j ^ 1)).count_ones() as u64;
        }
        for (b, &one) in ones.iter().enumerate() {
            let p = one as f64 / n as f64;
            assert!((p - 0.5).abs() < 0.02, "bit {b} set with frequency {p}");
        }
        let mean_flips = flips as f64 / (2 * n) as f64;
        assert!(
            (mean_flips - 16.0).abs() < 0.5,
            "mean flipped bits {mean_flips}"
        );
        for c in counts {
            assert!(
                (c as f64 / n as f64 - 0.25).abs() < 0.03,
                "tile counts {counts:?}"
            );
        }
    }
    /// Known answers computed independently (Python, 32-bit masked arithmetic).
    #[test]
    fn hash_vertex_known_answers() {
        assert_eq!(hash_vertex(0, 0, 0), [2_409_258_929, 2_293_885_989]);
        assert_eq!(hash_vertex(7, 1, 2), [537_358_485, 691_763_062]);
        assert_eq!(hash_vertex(11, -3, 0), [1_100_717_043, 1_027_925_991]);
        assert_eq!(hash_vertex(3, -5, 1 << 40), [1_248_865_056, 278_491_683]);
    }

    /// The offset word of `hash_vertex` is balanced bit by bit, and the offsets do not
    /// follow the tile: over 40 000 vertices and 8 tiles of 256², each tile's mean x and
    /// y offset is within 4 px of the uniform 127.5 (its standard error is about 2 px).
    #[test]
    fn hash_vertex_offsets_are_balanced_and_independent_of_the_tile() {
        let n = 40_000u32;
        let mut ones = [0u32; 32];
        let mut sums = [[0.0f64; 3]; 8];
        for k in 0..n {
            let (i, j) = ((k % 200) as i64 - 100, (k / 200) as i64 - 100);
            let [a, b] = hash_vertex(2, i, j);
            for (bit, one) in ones.iter_mut().enumerate() {
                *one += (b >> bit) & 1;
            }
            let t = pick_tile(a, 8) as usize;
            sums[t][0] += (b & 255) as f64;
            sums[t][1] += ((b >> 16) & 255) as f64;
            sums[t][2] += 1.0;
        }
        for (bit, &one) in ones.iter().enumerate() {
            let p = one as f64 / n as f64;
            assert!(
                (p - 0.5).abs() < 0.02,
                "offset bit {bit} set with frequency {p}"
            );
        }
        for (t, [sx, sy, m]) in sums.iter().enumerate() {
            let (mx, my) = (sx / m, sy / m);
            assert!(
                (mx - 127.5).abs() < 4.0 && (my - 127.5).abs() < 4.0,
                "tile {t}: mean offsets ({mx:.1}, {my:.1}) over {m} vertices"
            );
        }
    }
}
