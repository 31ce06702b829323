// The coordinate hashes of surftile: the WGSL twin of src/hash.rs, bit for bit.
//
// Same names and argument order as the Rust functions. WGSL has no 64-bit integers, so
// a signed 64-bit cell index travels as vec2<u32>(low word, high word), two's complement;
// `cell_add` moves such a cell by a small signed step with the carry the i64 sum has.
// Only 32-bit wrapping multiply, add, xor and shift are used, which WGSL's u32 defines
// exactly as Rust's wrapping_* operations.

// fold_cell (hash.rs): the low word, with the high word mixed in by a Weyl constant.
fn fold_cell(i: vec2<u32>) -> u32 {
    return i.x ^ (i.y * 0x9E3779B9u);
}

// The i64 sum `i + d` of a cell and a small signed step, as (low, high) words.
fn cell_add(i: vec2<u32>, d: i32) -> vec2<u32> {
    let lo = i.x + u32(d);
    let carry = select(0u, 1u, lo < i.x);
    let sign = select(0u, 0xFFFFFFFFu, d < 0);
    return vec2<u32>(lo, i.y + sign + carry);
}

// A signed 32-bit cell index as the (low, high) words of its i64: the cell index of
// `i as i64` in Rust.
fn cell_from_i32(v: i32) -> vec2<u32> {
    return vec2<u32>(u32(v), select(0u, 0xFFFFFFFFu, v < 0));
}

// pcg4d (Jarzynski & Olano, JCGT 2020): 4 words in, 4 words out.
fn pcg4d(v_in: vec4<u32>) -> vec4<u32> {
    var v = v_in * 1664525u + vec4<u32>(1013904223u);
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    v = v ^ (v >> vec4<u32>(16u));
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    return v;
}

// hash_tile: one word for a cell's tile choice (odd multipliers, Wellons' lowbias32).
fn hash_tile(seed: u32, i: vec2<u32>, j: vec2<u32>) -> u32 {
    var h = (fold_cell(i) * 0x9E3779B1u) ^ (fold_cell(j) * 0x85EBCA77u)
        ^ (seed * 0xC2B2AE3Du + 0x2545F491u);
    h ^= h >> 16u;
    h *= 0x7FEB352Du;
    h ^= h >> 15u;
    h *= 0x846CA68Bu;
    return h ^ (h >> 16u);
}

// hash_vertex: the blend rule's vertex, word 0 the tile, word 1 the offsets.
fn hash_vertex(seed: u32, i: vec2<u32>, j: vec2<u32>) -> vec2<u32> {
    let a = hash_tile(seed, i, j);
    let b = (a ^ 0x5BD1E995u) * 0x2C1B3C6Du;
    return vec2<u32>(a, b ^ (b >> 15u));
}

// hash_cell: (seed, cell i, cell j, stream) through pcg4d.
fn hash_cell(seed: u32, i: vec2<u32>, j: vec2<u32>, stream: u32) -> vec4<u32> {
    return pcg4d(vec4<u32>(seed, fold_cell(i), fold_cell(j), stream));
}

// pick_tile: ⌊(h >> 16) · k / 2¹⁶⌋, a tile index in 0..k for k ≤ 2¹⁶.
fn pick_tile(h: u32, k: u32) -> u32 {
    return ((h >> 16u) * k) >> 16u;
}

// wang_tile (hash.rs): the Wang tile of cell (i, j) with k colours per edge direction,
// from the hashed colours of its four edges: ((x0·k + x1)·k + y0)·k + y1.
fn wang_tile(seed: u32, i: vec2<u32>, j: vec2<u32>, k: u32) -> u32 {
    let x0 = pick_tile(hash_cell(seed, i, j, 1u).x, k);
    let x1 = pick_tile(hash_cell(seed, cell_add(i, 1), j, 1u).x, k);
    let y0 = pick_tile(hash_cell(seed, i, j, 2u).x, k);
    let y1 = pick_tile(hash_cell(seed, i, cell_add(j, 1), 2u).x, k);
    return ((x0 * k + x1) * k + y0) * k + y1;
}

// ⌊v / d⌋ for d > 0, rounding toward −∞ (WGSL's `/` truncates). Only non-negative
// operands are divided: GLSL leaves `/` and `%` of negative integers undefined, and the
// GL backend's translation gave wrong cells for negative v (oblique lattices on Mesa's
// llvmpipe). For v < 0, ⌊v/d⌋ = −(⌊(−v − 1)/d⌋ + 1), which cannot overflow.
fn div_floor(v: i32, d: i32) -> i32 {
    if v >= 0 {
        return v / d;
    }
    return -((-(v + 1)) / d + 1);
}
