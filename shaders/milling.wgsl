// Face milling (seed 000 §4): the twin of src/models/milling/ring.rs (`Drawn::value`,
// `part_of`, `along`, `weight`, `shape_plane`, `noise_at`, `atan2_turns`) and of
// `MillingSurface::fold_drawn` / `adapt` in src/models/milling/mod.rs.
// Stands alone (no hashes here: the host draws every ring's random numbers once, in
// f64, exactly as the CPU does).
//
// The host finds the rings that can reach each BLOCK × BLOCK block of the region (the
// search of `MillingSurface::rings_reaching_rect`, sorted into milling order) and
// passes them as one deduplicated ring table plus a list of ring indices per block.
// Each invocation folds its block's rings at its pixel.
//
// Precision: coordinates are millimetres relative to the band's first sample, split
// into an f32 high part and an f32 low part (x = hi + lo) for both the pixels and the
// ring centres, so dx = (hi_p − hi_c) + (lo_p − lo_c) keeps about 2⁻²⁴ of the ring
// radius however far the band lies from the origin. A pixel whose distance from some
// ring lies within `tol` mm of a part border (where the model is discontinuous: the
// indicator's jump, the noise or a later ring starting) cannot be decided in f32; the
// shader writes NaN there (NAN_BITS) and the host recomputes that pixel in f64 on the CPU.

const SHAPE_LUT: u32 = 1025u;
const NOISE_SAMPLES: u32 = 2048u;
const NOISE_PROFILES: u32 = 64u;
// A quiet NaN: the pixel is left to the host.
const NAN_BITS: u32 = 0x7FC00000u;

const SHAPE_INDICATOR: u32 = 0u;
const SHAPE_BUMP: u32 = 2u;
const INTERACTION_MIN: u32 = 0u;
const INTERACTION_LATEST: u32 = 1u;
const INTERACTION_CONVEX: u32 = 2u;

// src/gpu/milling.rs `MillAxis`: a column's or row's position (mm from the band's
// first sample, hi + lo) and its block.
struct MillAxis {
    hi: f32,
    lo: f32,
    block: u32,
    pad: u32,
}

// src/gpu/milling.rs `MillRing`: one ring's draws (`ring::Drawn`), its centre split as
// the axes are.
struct MillRing {
    cx_hi: f32,
    cx_lo: f32,
    cy_hi: f32,
    cy_lo: f32,
    cos_t: f32,
    sin_t: f32,
    w_minus: f32,
    w_inner: f32,
    w_outer: f32,
    noise_word: u32,
    weight_a: f32,
    weight_b: f32,
    // (low, high) of the tilting plane of the indentation, inner and outer parts.
    plane0: vec2<f32>,
    plane1: vec2<f32>,
    plane2: vec2<f32>,
    pad0: u32,
    pad1: u32,
}

struct MillParams {
    width: u32,
    height: u32,
    blocks_x: u32,
    // Points per footprint axis (1 at steps up to 1 pixel; `sample_footprint`'s n).
    n: u32,
    shape: u32,
    interaction: u32,
    adapt: u32,
    pad0: u32,
    r: f32,
    support_in: f32,
    support_out: f32,
    noise_scale: f32,
    tol: f32,
    adapt_scale: f32,
    model_mean: f32,
    target_mean: f32,
    // Footprint point offsets (mm), the first n used.
    offsets: vec4<f32>,
}

@group(0) @binding(0) var<uniform> mp: MillParams;
@group(0) @binding(1) var<storage, read> rings: array<MillRing>;
// Per block: (first index in `ring_index`, count).
@group(0) @binding(2) var<storage, read> block_lists: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read> ring_index: array<u32>;
@group(0) @binding(4) var<storage, read> mill_cols: array<MillAxis>;
@group(0) @binding(5) var<storage, read> mill_rows: array<MillAxis>;
// f32 bits, or NAN_BITS where the host must recompute the pixel.
@group(0) @binding(6) var<storage, read_write> mill_out: array<u32>;
@group(0) @binding(7) var<storage, read> shape_lut: array<f32>;
@group(0) @binding(8) var<storage, read> noise_q: array<i32>;

// A ring's value at a point: covered, R_k, A_k, and whether f32 cannot decide the part.
struct RingValue {
    covered: bool,
    ambiguous: bool,
    r: f32,
    a: f32,
}

// The part at distance `dist` (0 indentation, 1 inner, 2 outer, 3 none), with the
// profile's centre and width; `ambiguous` when `dist` lies within tol of a border.
struct PartOf {
    part: u32,
    ambiguous: bool,
    centre: f32,
    width: f32,
}

fn near_border(dist: f32, border: f32) -> bool {
    return abs(dist - border) <= mp.tol;
}

fn part_of(dist: f32, w_minus: f32, w_inner: f32, w_outer: f32) -> PartOf {
    let r = mp.r;
    let edge = r - w_minus;
    var p = PartOf(3u, false, 0.0, 0.0);
    if (w_minus > 0.0) {
        p.ambiguous = near_border(dist, edge) || near_border(dist, r);
    }
    if (dist >= edge && dist <= r && w_minus > 0.0) {
        p.part = 0u;
        p.centre = r - 0.5 * w_minus;
        p.width = w_minus;
    } else if (mp.shape != SHAPE_BUMP) {
        return p;
    } else if (dist < edge) {
        if (w_inner > 0.0) {
            p.ambiguous = p.ambiguous || near_border(dist, edge - w_inner) || near_border(dist, edge);
            if (dist >= edge - w_inner) {
                p.part = 1u;
                p.centre = edge - 0.5 * w_inner;
                p.width = w_inner;
            }
        }
    } else {
        if (w_outer > 0.0) {
            p.ambiguous = p.ambiguous || near_border(dist, r) || near_border(dist, r + w_outer);
            if (dist > r && dist <= r + w_outer) {
                p.part = 2u;
                p.centre = r + 0.5 * w_outer;
                p.width = w_outer;
            }
        }
    }
    return p;
}

fn along(cos_t: f32, sin_t: f32, dx: f32, dy: f32) -> f32 {
    return (cos_t * dx + sin_t * dy) * (0.5 / mp.r);
}

fn weight(a: f32, b: f32, along_v: f32) -> f32 {
    if (mp.interaction == INTERACTION_CONVEX) {
        return clamp((a - b) * along_v + 0.5 * (a + b), 0.0, 1.0);
    }
    return 1.0;
}

fn shape_plane(part: u32, centre: f32, width: f32, dist: f32, along_v: f32, plane: vec2<f32>) -> f32 {
    var s = -1.0;
    if (mp.shape != SHAPE_INDICATOR) {
        let d = clamp((dist - centre) * (2.0 / width), -1.0, 1.0);
        let pos = (d + 1.0) * (0.5 * f32(SHAPE_LUT - 1u));
        let i = min(u32(pos), SHAPE_LUT - 2u);
        let f = pos - f32(i);
        let c = shape_lut[i] + (shape_lut[i + 1u] - shape_lut[i]) * f;
        s = select(c, -c, part == 0u);
    }
    let low = plane.x;
    let high = plane.y;
    return s * ((high - low) * along_v + 0.5 * (high + low));
}

// atan2(y, x) / 2π in [−½, ½]: the same minimax polynomial as the CPU's.
fn atan2_turns(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    let lo = min(ax, ay);
    let hi = max(ax, ay);
    if (hi == 0.0) {
        return 0.0;
    }
    let z = lo / hi;
    let z2 = z * z;
    var a = z * (0.99997726 + z2 * (-0.33262347 + z2 * (0.19354346
        + z2 * (-0.11643287 + z2 * (0.05265332 - 0.0117212 * z2)))));
    if (ay > ax) {
        a = 1.5707963267948966 - a;
    }
    if (x < 0.0) {
        a = 3.141592653589793 - a;
    }
    if (y < 0.0) {
        a = -a;
    }
    return a * (1.0 / 6.283185307179586);
}

fn noise_at(noise_word: u32, dx: f32, dy: f32) -> f32 {
    let profile = (noise_word >> 10u) % NOISE_PROFILES;
    let turn = atan2_turns(dy, dx) + f32(noise_word & 0x3FFu) * (1.0 / 1024.0);
    let pos = (turn - floor(turn)) * f32(NOISE_SAMPLES);
    let i = min(u32(pos), NOISE_SAMPLES - 1u);
    let f = pos - f32(i);
    let base = profile * NOISE_SAMPLES;
    let a = f32(noise_q[base + i]);
    let b = f32(noise_q[base + (i + 1u) % NOISE_SAMPLES]);
    return mp.noise_scale * (a + (b - a) * f);
}

// `Drawn::value`: the ring at offset (dx, dy) mm from its centre.
fn value(ring: MillRing, dx: f32, dy: f32) -> RingValue {
    var v = RingValue(false, false, 0.0, 1.0);
    let dist2 = dx * dx + dy * dy;
    if (!(dist2 >= mp.support_in && dist2 <= mp.support_out)) {
        return v;
    }
    let dist = sqrt(dist2);
    let p = part_of(dist, ring.w_minus, ring.w_inner, ring.w_outer);
    v.ambiguous = p.ambiguous;
    if (p.part == 3u) {
        return v;
    }
    let al = along(ring.cos_t, ring.sin_t, dx, dy);
    var plane = ring.plane0;
    if (p.part == 1u) {
        plane = ring.plane1;
    } else if (p.part == 2u) {
        plane = ring.plane2;
    }
    var r = shape_plane(p.part, p.centre, p.width, dist, al, plane);
    if (mp.noise_scale != 0.0) {
        r = r + noise_at(ring.noise_word, dx, dy);
    }
    v.covered = true;
    v.r = r;
    v.a = weight(ring.weight_a, ring.weight_b, al);
    return v;
}

// The fold at one point: the height, or `ambiguous` when f32 cannot decide a ring's part.
struct Folded {
    f: f32,
    ambiguous: bool,
}

// `MillingSurface::fold_drawn` over the block's list at the point (x, y) (hi, lo pairs).
fn fold_drawn(list: vec2<u32>, x: vec2<f32>, y: vec2<f32>) -> Folded {
    var f = 0.0;
    for (var q = 0u; q < list.y; q = q + 1u) {
        let ring = rings[ring_index[list.x + q]];
        let dx = (x.x - ring.cx_hi) + (x.y - ring.cx_lo);
        let dy = (y.x - ring.cy_hi) + (y.y - ring.cy_lo);
        let v = value(ring, dx, dy);
        if (v.ambiguous) {
            return Folded(0.0, true);
        }
        if (!v.covered) {
            continue;
        }
        if (mp.interaction == INTERACTION_MIN) {
            f = min(f, v.r);
        } else if (mp.interaction == INTERACTION_LATEST) {
            f = v.r;
        } else {
            f = v.a * v.r + (1.0 - v.a) * f;
        }
    }
    return Folded(f, false);
}

fn adapt(h: f32) -> f32 {
    if (mp.adapt != 0u) {
        return (h - mp.model_mean) * mp.adapt_scale + mp.target_mean;
    }
    return h;
}

@compute @workgroup_size(16, 16)
fn fill_milling(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= mp.width || gid.y >= mp.height) {
        return;
    }
    let col = mill_cols[gid.x];
    let row = mill_rows[gid.y];
    let list = block_lists[row.block * mp.blocks_x + col.block];
    let n = mp.n;
    var sum = 0.0;
    for (var b = 0u; b < n; b = b + 1u) {
        for (var a = 0u; a < n; a = a + 1u) {
            let x = vec2<f32>(col.hi, col.lo + mp.offsets[a]);
            let y = vec2<f32>(row.hi, row.lo + mp.offsets[b]);
            let h = fold_drawn(list, x, y);
            if (h.ambiguous) {
                mill_out[gid.y * mp.width + gid.x] = NAN_BITS;
                return;
            }
            sum = sum + adapt(h.f);
        }
    }
    mill_out[gid.y * mp.width + gid.x] = bitcast<u32>(sum / f32(n * n));
}
