// Runs the hashes of hash.wgsl on a list of inputs, for the parity test against
// src/hash.rs (src/gpu/fill.rs `gpu_hashes`).

struct HashIn {
    seed: u32,
    stream: u32,
    i: vec2<u32>,
    j: vec2<u32>,
    k: u32,
    // A step for cell_add(i, d).
    d: i32,
}

struct HashOut {
    cell: vec4<u32>,
    vertex: vec2<u32>,
    tile: u32,
    pick: u32,
    sum: vec2<u32>,
    pad: vec2<u32>,
}

@group(0) @binding(0) var<storage, read> inputs: array<HashIn>;
@group(0) @binding(1) var<storage, read_write> outputs: array<HashOut>;

@compute @workgroup_size(64)
fn check_hashes(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&inputs) {
        return;
    }
    let v = inputs[id.x];
    let tile = hash_tile(v.seed, v.i, v.j);
    outputs[id.x] = HashOut(
        hash_cell(v.seed, v.i, v.j, v.stream),
        hash_vertex(v.seed, v.i, v.j),
        tile,
        pick_tile(tile, v.k),
        cell_add(v.i, v.d),
        vec2<u32>(0u),
    );
}
