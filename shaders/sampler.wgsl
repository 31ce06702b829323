// The point sampler of tile banks (toroidal and Wang rules) for a renderer's own shaders:
// the height or colour at any texel position, Heitz–Neyret style, without surftile at
// run time. `surftile export-shader` translates this file (after hash.wgsl) with naga into
// GLSL, HLSL or MSL, and writes the bank's tiles and these parameters beside it.
//
// Twin of src/stream/toroidal.rs at level 0 (Level::locate, ToroidalSurface::tile_of,
// texel_at, bilinear); Wang banks pick their tile with hash.wgsl's wang_tile, as the
// GPU fill does. A position is an integer texel ip and a
// fraction fp in [0, 1), so that no f32 holds a large coordinate: a renderer keeps its
// own integer offset (tile origins, a camera-relative origin). |ip| < 2^30, or the
// smaller max_coordinate that export-shader's layout.json gives for long, sheared cells.

struct SurftileParams {
    // The Hermite normal form (A, 0), (B, C) of the lattice: tiles are A × C texels.
    a: i32,
    b: i32,
    c: i32,
    // K tiles; channels per texel (1 heights, 3 RGB).
    tiles: u32,
    channels: u32,
    // The placement seed (render --seed).
    seed: u32,
    // Several tiles on an oblique lattice: det of the reduced basis u, v (tiles are chosen
    // by rhomboid cell); 0 otherwise.
    det: i32,
    // Wang banks: colours per edge direction K (tiles = K^4); 0 for toroidal banks.
    colours: u32,
    // The reduced basis, and the HNF basis vectors (A, 0) and (B, C) in it:
    // (A, 0) = hnf_a.x·u + hnf_a.y·v, (B, C) = hnf_b.x·u + hnf_b.y·v.
    u: vec2<i32>,
    v: vec2<i32>,
    hnf_a: vec2<i32>,
    hnf_b: vec2<i32>,
}

@group(0) @binding(0) var<uniform> surftile_params: SurftileParams;
// K tiles of C rows of A texels of `channels` values, tile after tile.
@group(0) @binding(1) var<storage, read> surftile_texels: array<f32>;

// The tile shown at the texel (lx, ly) of HNF cell (i, j) (ToroidalSurface::tile_of).
fn surftile_tile(i: i32, j: i32, lx: i32, ly: i32) -> u32 {
    let p = surftile_params;
    if p.colours > 0u {
        return wang_tile(p.seed, cell_from_i32(i), cell_from_i32(j), p.colours);
    }
    if p.tiles == 1u {
        return 0u;
    }
    if p.det != 0 {
        // Rhomboid::cell of the texel: the cell's lattice point in the reduced basis, plus
        // the rhomboid cell of (lx, ly) from it (exact: small numerators).
        let s = i * p.hnf_a.x + j * p.hnf_b.x + div_floor(p.v.y * lx - p.v.x * ly, p.det);
        let t = i * p.hnf_a.y + j * p.hnf_b.y + div_floor(p.u.x * ly - p.u.y * lx, p.det);
        return pick_tile(hash_tile(p.seed, cell_from_i32(s), cell_from_i32(t)), p.tiles);
    }
    return pick_tile(hash_tile(p.seed, cell_from_i32(i), cell_from_i32(j)), p.tiles);
}

// Offset in surftile_texels of the integer texel (x, y) (ToroidalSurface::texel_at).
fn surftile_texel(x: i32, y: i32) -> u32 {
    let p = surftile_params;
    let j = div_floor(y, p.c);
    let xs = x - j * p.b;
    let i = div_floor(xs, p.a);
    let lx = xs - i * p.a;
    let ly = y - j * p.c;
    let tile = surftile_tile(i, j, lx, ly);
    return (tile * u32(p.a * p.c) + u32(ly * p.a + lx)) * p.channels;
}

// Every channel at texel position ip + fp: bilinear between texel centres, each corner
// from its own cell (ToroidalSurface::bilinear at level 0, full resolution).
fn surftile_sample(ip: vec2<i32>, fp: vec2<f32>) -> vec4<f32> {
    let p00 = surftile_texel(ip.x, ip.y);
    let p10 = surftile_texel(ip.x + 1, ip.y);
    let p01 = surftile_texel(ip.x, ip.y + 1);
    let p11 = surftile_texel(ip.x + 1, ip.y + 1);
    // −0 + v = v: a texel centre returns the texel's exact bits, as on the CPU.
    var acc = vec4<f32>(-0.0);
    for (var ch = 0u; ch < surftile_params.channels; ch++) {
        let a = surftile_texels[p00 + ch];
        let b = surftile_texels[p10 + ch];
        let d = surftile_texels[p01 + ch];
        let e = surftile_texels[p11 + ch];
        let top = a + (b - a) * fp.x;
        let bottom = d + (e - d) * fp.x;
        acc[ch] += top + (bottom - top) * fp.y;
    }
    return acc;
}

// Channel 0 (the height) at texel position ip + fp.
fn surftile_height(ip: vec2<i32>, fp: vec2<f32>) -> f32 {
    return surftile_sample(ip, fp).x;
}

// An example entry point, and what the parity test runs: fills width × height samples
// one texel apart from origin + frac into surftile_out (row-major, `channels` values
// each), as surftile's CPU fill of Region::new(origin + frac, width, height) does.
struct SurftileRegion {
    origin: vec2<i32>,
    frac: vec2<f32>,
    width: u32,
    height: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(2) var<uniform> surftile_region: SurftileRegion;
@group(0) @binding(3) var<storage, read_write> surftile_out: array<f32>;

@compute @workgroup_size(8, 8)
fn surftile_fill(@builtin(global_invocation_id) id: vec3<u32>) {
    let r = surftile_region;
    if id.x >= r.width || id.y >= r.height {
        return;
    }
    let v = surftile_sample(r.origin + vec2<i32>(id.xy), r.frac);
    let base = (id.y * r.width + id.x) * surftile_params.channels;
    for (var ch = 0u; ch < surftile_params.channels; ch++) {
        surftile_out[base + ch] = v[ch];
    }
}
