// The toroidal placement rule (roller banks): the twin of src/stream/toroidal.rs.
// Needs hash.wgsl before it (src/gpu/shaders.rs composes the module).
//
// Cells are the HNF rectangles A × C of a level's lattice, each row shifted by B; cell
// (i, j) shows tile pick_tile(hash_tile(seed, i, j), K), or for several tiles on an
// oblique lattice the tile of its rhomboid cell (s, t), or for a Wang bank wang_tile.

// One column or row of a region (src/gpu/fill.rs `TorAxis`). The host computes each
// coordinate in f64 as the CPU fill does and passes it split: the texel's integer offset
// `d` from the region's origin texel and its f32 fraction `f`. The rhomboid numerators'
// changes from the origin (exact integers) come as quotient and remainder by det: (sq,
// sr) for s, (tq, tr) for t. No f32 ever holds an absolute coordinate.
struct TorAxis {
    d: i32,
    f: f32,
    sq: i32,
    sr: i32,
    tq: i32,
    tr: i32,
    pad0: u32,
    pad1: u32,
}

struct TorLevel {
    a: i32,
    b: i32,
    c: i32,
    tile_stride: u32,
    texel_base: u32,
    // The origin texel's position inside its HNF cell.
    lx0: i32,
    ly0: i32,
    // Remainder by det of the origin texel's s numerator.
    rs0: i32,
    // The origin texel's HNF cell (i, j) and the quotients by det of its rhomboid
    // numerators (s0, t0).
    i0: vec2<u32>,
    j0: vec2<u32>,
    s0: vec2<u32>,
    t0: vec2<u32>,
    // The numerators' change per texel step in x (ds_x, dt_x) and in y.
    ds_x: i32,
    dt_x: i32,
    ds_y: i32,
    dt_y: i32,
    // Remainder by det of the origin texel's t numerator.
    rt0: i32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

struct TorParams {
    width: u32,
    height: u32,
    channels: u32,
    tiles: u32,
    seed: u32,
    // det of the reduced basis where tiles are chosen by rhomboid cell, else 0.
    det: i32,
    // Weight of the second level (slot 1); 0 reads slot 0 only.
    t: f32,
    // Wang banks: colours per edge direction (the cell's tile is wang_tile); 0 otherwise.
    colours: u32,
    level: array<TorLevel, 2>,
}

@group(0) @binding(0) var<uniform> params: TorParams;
@group(0) @binding(1) var<storage, read> texels: array<f32>;
// Slot k of the columns at k·width, of the rows at k·height.
@group(0) @binding(2) var<storage, read> cols: array<TorAxis>;
@group(0) @binding(3) var<storage, read> rows: array<TorAxis>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

// Cell (i, j) (as steps from the origin's cell) and position (lx, ly) in the HNF tile
// of the texel (dx, dy) steps from the origin texel of level slot `l` (Level::locate).
fn locate(l: u32, dx: i32, dy: i32) -> vec4<i32> {
    let lv = params.level[l];
    let yy = lv.ly0 + dy;
    let dj = div_floor(yy, lv.c);
    let xs = lv.lx0 + dx - dj * lv.b;
    let di = div_floor(xs, lv.a);
    return vec4<i32>(di, dj, xs - di * lv.a, yy - dj * lv.c);
}

// The tile shown at a texel (ToroidalSurface::tile_of): by HNF cell, or by rhomboid
// cell (Rhomboid::cell, exact) of the texel at col, row plus (ex, ey) texel steps.
fn tile_of(l: u32, cell: vec2<i32>, col: TorAxis, row: TorAxis, ex: i32, ey: i32) -> u32 {
    if params.tiles == 1u {
        return 0u;
    }
    let lv = params.level[l];
    var i = cell_add(lv.i0, cell.x);
    var j = cell_add(lv.j0, cell.y);
    if params.colours != 0u {
        return wang_tile(params.seed, i, j, params.colours);
    }
    if params.det != 0 {
        let rs = lv.rs0 + col.sr + row.sr + ex * lv.ds_x + ey * lv.ds_y;
        let rt = lv.rt0 + col.tr + row.tr + ex * lv.dt_x + ey * lv.dt_y;
        i = cell_add(lv.s0, col.sq + row.sq + div_floor(rs, params.det));
        j = cell_add(lv.t0, col.tq + row.tq + div_floor(rt, params.det));
    }
    return pick_tile(hash_tile(params.seed, i, j), params.tiles);
}

// Offset in `texels` of the texel (dx, dy) + (ex, ey) of level slot `l`
// (ToroidalSurface::texel_at).
fn texel_at(l: u32, col: TorAxis, row: TorAxis, ex: i32, ey: i32) -> u32 {
    let lv = params.level[l];
    let p = locate(l, col.d + ex, row.d + ey);
    let tile = tile_of(l, p.xy, col, row, ex, ey);
    return lv.texel_base + tile * lv.tile_stride + u32(p.w * lv.a + p.z) * params.channels;
}

// Bilinear sample of every channel of level slot `l` (ToroidalSurface::bilinear),
// weighted by w.
fn bilinear(l: u32, col: TorAxis, row: TorAxis, w: f32) -> vec4<f32> {
    let lv = params.level[l];
    let p = locate(l, col.d, row.d);
    var p00: u32;
    var p10: u32;
    var p01: u32;
    var p11: u32;
    if p.z + 1 < lv.a && p.w + 1 < lv.c {
        // All four corners in one cell: one tile, from the first corner.
        let tile = tile_of(l, p.xy, col, row, 0, 0);
        p00 = lv.texel_base + tile * lv.tile_stride + u32(p.w * lv.a + p.z) * params.channels;
        p10 = p00 + params.channels;
        p01 = p00 + u32(lv.a) * params.channels;
        p11 = p01 + params.channels;
    } else {
        p00 = texel_at(l, col, row, 0, 0);
        p10 = texel_at(l, col, row, 1, 0);
        p01 = texel_at(l, col, row, 0, 1);
        p11 = texel_at(l, col, row, 1, 1);
    }
    var acc = vec4<f32>(0.0);
    for (var c = 0u; c < params.channels; c++) {
        let a = texels[p00 + c];
        let b = texels[p10 + c];
        let d = texels[p01 + c];
        let e = texels[p11 + c];
        let top = a + (b - a) * col.f;
        let bottom = d + (e - d) * col.f;
        acc[c] = w * (top + (bottom - top) * row.f);
    }
    return acc;
}

@compute @workgroup_size(16, 16)
fn fill_toroidal(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    // −0 + v = v: a weight of 1 returns the texel's exact bits, as on the CPU.
    var acc = vec4<f32>(-0.0) + bilinear(0u, cols[id.x], rows[id.y], 1.0 - params.t);
    if params.t > 0.0 {
        acc += bilinear(1u, cols[params.width + id.x], rows[params.height + id.y], params.t);
    }
    let base = (id.y * params.width + id.x) * params.channels;
    for (var c = 0u; c < params.channels; c++) {
        out[base + c] = acc[c];
    }
}
