//! The one coordinate hash of surftile, shared bit for bit with `shaders/`.
//!
//! `pcg4d` is the 4-D PCG-family hash of Jarzynski & Olano, "Hash Functions for GPU
//! Rendering" (JCGT 9(3), 2020). It maps (seed, cell i, cell j, stream) to four
//! well-mixed u32 words using only 32-bit wrapping multiply, add, xor and shift, so the
//! WGSL twin gives identical bits. Never `fract(sin(x) * 43758.5453)`: it bands and
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

/// Hash of (seed, cell (i, j), stream): the entry point every placement rule uses.
#[inline(always)]
pub fn hash_cell(seed: u32, i: i64, j: i64, stream: u32) -> [u32; 4] {
    pcg4d([seed, fold_cell(i), fold_cell(j), stream])
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
}
