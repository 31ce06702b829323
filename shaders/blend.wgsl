// The variance-preserving triangle-grid blend rule: the twin of src/stream/blend.rs.
// Needs hash.wgsl before it (src/gpu/shaders.rs composes the module).
//
// Each vertex of the equilateral triangle grid picks a tile and an offset by
// hash_vertex; a sample blends its triangle's three tiles with barycentric weights,
// renormalised by √(Σw²) around the mean (Heitz & Neyret 2018, eq. 4), then maps the
// result through the stored T⁻¹ table.

// What a region fill is told about each of its columns and rows (src/gpu/fill.rs `Axis`).
//
// The host computes every coordinate in f64, as the CPU fill does, and passes it split:
// an integer offset `d` from the region's origin texel (whose absolute position is
// passed once, as 64-bit words) and an f32 fraction `f`. `u` and `v` carry the skewed
// grid's coordinates (x·a − y·b, y·c) in the same split form, the x term by column and
// the y terms by row. So a region a billion pixels out is as precise as one
// at the origin: no f32 ever holds an absolute coordinate.
struct Axis {
    d: i32,
    f: f32,
    ui: i32,
    uf: f32,
    vi: i32,
    vf: f32,
    pad0: u32,
    pad1: u32,
}

struct BlendLevel {
    w: u32,
    h: u32,
    tile_stride: u32,
    texel_base: u32,
    lut_base: u32,
    pad0: u32,
    // 2^−L, and a level-L texel's centre in level-0 pixels ((2^L − 1)/2).
    scale: f32,
    centre: f32,
    mean: vec4<f32>,
    lut_scale: vec4<f32>,
}

struct BlendParams {
    width: u32,
    height: u32,
    channels: u32,
    tiles: u32,
    seed: u32,
    tile_shift: u32,
    lut_size: u32,
    pad0: u32,
    // Weight of the second level (slot 1); 0 reads slot 0 only.
    t: f32,
    lut_last: f32,
    lut_centre: f32,
    pad1: u32,
    // Offset masks (level-0 tile size − 1), and the origin texel's x and y under them.
    mask_x: u32,
    mask_y: u32,
    xm0: u32,
    ym0: u32,
    // The skewed grid cell of the origin's split coordinates, as 64-bit words.
    bx0: vec2<u32>,
    by0: vec2<u32>,
    level: array<BlendLevel, 2>,
}

@group(0) @binding(0) var<uniform> params: BlendParams;
@group(0) @binding(1) var<storage, read> texels: array<f32>;
@group(0) @binding(2) var<storage, read> cols: array<Axis>;
@group(0) @binding(3) var<storage, read> rows: array<Axis>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;
// T⁻¹ of every level and channel, as (value, next value − value) pairs.
@group(0) @binding(5) var<storage, read> luts: array<vec2<f32>>;

struct Vertex {
    tile: u32,
    ox: u32,
    oy: u32,
}

// Hashed tile and offset of the triangle-grid vertex (i, j) (BlendSurface::vertex).
fn vertex(i: vec2<u32>, j: vec2<u32>) -> Vertex {
    let h = hash_vertex(params.seed, i, j);
    var tile: u32;
    if params.tile_shift != 0u {
        tile = (h.x >> 16u) >> params.tile_shift;
    } else {
        tile = pick_tile(h.x, params.tiles);
    }
    return Vertex(tile, h.y & params.mask_x, (h.y >> 16u) & params.mask_y);
}

// Interpolation in channel c's T⁻¹ table of level slot l at fractional index t, clamped
// to the table (BlendSurface::lut_eval).
fn lut_eval(l: u32, c: u32, t_in: f32) -> f32 {
    let t = min(max(t_in, 0.0), params.lut_last);
    let i = u32(t);
    let f = t - f32(i);
    let e = luts[params.level[l].lut_base + c * params.lut_size + i];
    return e.x + e.y * f;
}

// Σ corner weights × texels of `tile` around texel (ix, iy), wrapped, every channel
// (blend.rs `bilinear`).
fn bilinear(l: u32, tile: u32, ix: u32, iy: u32, corner: vec4<f32>) -> vec4<f32> {
    let lv = params.level[l];
    let x0 = ix & (lv.w - 1u);
    let x1 = (ix + 1u) & (lv.w - 1u);
    let y0 = iy & (lv.h - 1u);
    let y1 = (iy + 1u) & (lv.h - 1u);
    let c = params.channels;
    let base = lv.texel_base + tile * lv.tile_stride;
    let r0 = base + y0 * lv.w * c;
    let r1 = base + y1 * lv.w * c;
    var acc = vec4<f32>(0.0);
    for (var k = 0u; k < c; k++) {
        let a = texels[r0 + x0 * c + k];
        let b = texels[r0 + x1 * c + k];
        let d = texels[r1 + x0 * c + k];
        let e = texels[r1 + x1 * c + k];
        acc[k] = (a * corner.x + b * corner.y) + (d * corner.z + e * corner.w);
    }
    return acc;
}

struct Triangle {
    w: vec3<f32>,
    v0: Vertex,
    v1: Vertex,
    v2: Vertex,
}

// The triangle of skewed cell (i, j) at fraction (fx, fy): its three vertices' hashed
// choices and barycentric weights (BlendSurface::triangle and vertices).
fn triangle(i: vec2<u32>, j: vec2<u32>, fx: f32, fy: f32) -> Triangle {
    let z = 1.0 - fx - fy;
    if z > 0.0 {
        return Triangle(vec3<f32>(z, fy, fx), vertex(i, j), vertex(i, cell_add(j, 1)), vertex(cell_add(i, 1), j));
    }
    let i1 = cell_add(i, 1);
    let j1 = cell_add(j, 1);
    return Triangle(vec3<f32>(-z, 1.0 - fy, 1.0 - fx), vertex(i1, j1), vertex(i1, j), vertex(i, j1));
}

// The blend of the three vertices' tiles at level slot l, mapped through T⁻¹
// (BlendSurface::eval_level). (xm, ym): the level-0 texel under the offset masks;
// (fx, fy): its fraction.
fn eval_level(l: u32, xm: u32, ym: u32, fx: f32, fy: f32, tri: Triangle) -> vec4<f32> {
    let w = tri.w;
    let verts = array<Vertex, 3>(tri.v0, tri.v1, tri.v2);
    let lv = params.level[l];
    let norm = 1.0 / sqrt(w.x * w.x + w.y * w.y + w.z * w.z);
    let wsum = w.x + w.y + w.z;
    var g: array<vec4<f32>, 3>;
    for (var k = 0u; k < 3u; k++) {
        let v = verts[k];
        let xr = (xm + v.ox) & params.mask_x;
        let yr = (ym + v.oy) & params.mask_y;
        var ix = xr;
        var iy = yr;
        var tx = fx;
        var ty = fy;
        if lv.scale != 1.0 {
            // ((x mod period) + fx − centre)·2^−L: the integer part exact, the fraction
            // added after, so it keeps all its bits.
            let px = (f32(xr) - lv.centre) * lv.scale;
            let py = (f32(yr) - lv.centre) * lv.scale;
            let qx = fract(px) + fx * lv.scale;
            let qy = fract(py) + fy * lv.scale;
            ix = u32(i32(floor(px)) + i32(floor(qx)));
            iy = u32(i32(floor(py)) + i32(floor(qy)));
            tx = fract(qx);
            ty = fract(qy);
        }
        let wk = w[k] * norm;
        let corner = vec4<f32>(
            (1.0 - tx) * (1.0 - ty) * wk,
            tx * (1.0 - ty) * wk,
            (1.0 - tx) * ty * wk,
            tx * ty * wk,
        );
        g[k] = bilinear(l, v.tile, ix, iy, corner);
    }
    var o = vec4<f32>(0.0);
    for (var c = 0u; c < params.channels; c++) {
        let offset = params.lut_centre - lv.mean[c] * wsum * norm * lv.lut_scale[c];
        let t = ((g[0][c] + g[1][c]) + g[2][c]) * lv.lut_scale[c] + offset;
        o[c] = lut_eval(l, c, t);
    }
    return o;
}

@compute @workgroup_size(16, 16)
fn fill_blend(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let col = cols[id.x];
    let row = rows[id.y];
    // The skewed cell and fraction (BlendSurface::triangle), from split coordinates.
    let su = col.uf + row.uf;
    let fx = fract(su);
    let fy = row.vf;
    let i = cell_add(params.bx0, col.ui + row.ui + i32(floor(su)));
    let j = cell_add(params.by0, row.vi);
    let tri = triangle(i, j, fx, fy);
    let xm = (params.xm0 + u32(col.d)) & params.mask_x;
    let ym = (params.ym0 + u32(row.d)) & params.mask_y;
    var a = eval_level(0u, xm, ym, col.f, row.f, tri);
    if params.t > 0.0 {
        let b = eval_level(1u, xm, ym, col.f, row.f, tri);
        a += (b - a) * params.t;
    }
    let base = (id.y * params.width + id.x) * params.channels;
    for (var c = 0u; c < params.channels; c++) {
        out[base + c] = a[c];
    }
}
