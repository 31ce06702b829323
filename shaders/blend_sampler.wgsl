// The point sampler of blend banks (RPN, ADSN) for a renderer's own shaders. Needs
// hash.wgsl and blend.wgsl before it: it calls the GPU fill's own `triangle` and
// `eval_level` with the fill's uniform `params`, and only replaces the fill's entry
// point (whose host splits each coordinate in f64) with a point function.
// `surftile export-shader` translates the three files with naga.
//
// A position is an integer texel ip (|ip| < 2^30) and a fraction fp in [0, 1). The skewed
// grid coordinates (x·a − y·b, y·c) of BlendSurface::triangle are computed without an
// f32 ever holding a large value: each constant comes as four f32 chunks of at most 13
// significant bits (52 bits in all), ip as three 10-bit chunks, so every partial product
// is exact in f32; their integer parts are summed as integers and their fractions as
// floats.

struct SurftileSkew {
    // a = 1/E, −b = −1/(√3·E) and c = 2/(√3·E), each the sum of its four chunks.
    a: vec4<f32>,
    nb: vec4<f32>,
    c: vec4<f32>,
}

@group(0) @binding(6) var<uniform> surftile_skew: SurftileSkew;

// (v + f)·k as an integer and a fraction in [0, 1), k the sum of its chunks.
struct SurftileSplit {
    i: i32,
    f: f32,
}

fn surftile_mul(v: i32, f: f32, k: vec4<f32>) -> SurftileSplit {
    let parts = vec3<f32>(f32(v & 1023), f32((v >> 10u) & 1023) * 1024.0, f32(v >> 20u) * 1048576.0);
    var whole = 0;
    var frac = f * k.x + f * k.y;
    for (var m = 0u; m < 3u; m++) {
        for (var n = 0u; n < 4u; n++) {
            let p = parts[m] * k[n];
            let fl = floor(p);
            whole += i32(fl);
            frac += p - fl;
        }
    }
    let fl = floor(frac);
    return SurftileSplit(whole + i32(fl), frac - fl);
}

// Every channel at texel position ip + fp (BlendSurface at level 0, full resolution; the
// body of fill_blend with the coordinates split here instead of on the host).
fn surftile_sample(ip: vec2<i32>, fp: vec2<f32>) -> vec4<f32> {
    let ux = surftile_mul(ip.x, fp.x, surftile_skew.a);
    let uy = surftile_mul(ip.y, fp.y, surftile_skew.nb);
    let vy = surftile_mul(ip.y, fp.y, surftile_skew.c);
    let su = ux.f + uy.f;
    let fx = fract(su);
    let fy = vy.f;
    let i = cell_from_i32(ux.i + uy.i + i32(floor(su)));
    let j = cell_from_i32(vy.i);
    let tri = triangle(i, j, fx, fy);
    let xm = u32(ip.x) & params.mask_x;
    let ym = u32(ip.y) & params.mask_y;
    return eval_level(0u, xm, ym, fp.x, fp.y, tri);
}

// Channel 0 (the height) at texel position ip + fp.
fn surftile_height(ip: vec2<i32>, fp: vec2<f32>) -> f32 {
    return surftile_sample(ip, fp).x;
}

// An example entry point, and what the parity test runs: width × height samples one
// texel apart from origin + frac, into blend.wgsl's `out` (row-major, `channels` values
// each), as the CPU fill of Region::new(origin + frac, width, height).
struct SurftileRegion {
    origin: vec2<i32>,
    frac: vec2<f32>,
    width: u32,
    height: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(7) var<uniform> surftile_region: SurftileRegion;

@compute @workgroup_size(8, 8)
fn surftile_fill(@builtin(global_invocation_id) id: vec3<u32>) {
    let r = surftile_region;
    if id.x >= r.width || id.y >= r.height {
        return;
    }
    let v = surftile_sample(r.origin + vec2<i32>(id.xy), r.frac);
    let base = (id.y * r.width + id.x) * params.channels;
    for (var ch = 0u; ch < params.channels; ch++) {
        out[base + ch] = v[ch];
    }
}
