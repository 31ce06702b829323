// Display of a height field for the viewer: the height view (a linear grey ramp) and
// Phong/Blinn shading (seed 001, eqs. (1)–(4)), the twin of src/shade.rs
// (`normal_from_gradient`, `half_vector`, `reflectance`).
//
// The heights come as a storage buffer of (width + 2) × (height + 2) f32 values: the
// screen's samples with a one-sample margin, so every pixel has the four neighbours of
// its central differences. NaN marks a sample not yet available (a page still being
// generated); it is drawn as a neutral grey. In the colour view (mode 2) each value's
// bits are a colour's 8-bit levels r | g << 8 | b << 16 (`pack_colour` in
// src/view/mod.rs), which are never a NaN's. The buffer is read as u32 so that no
// value is touched as a float before it is known to be one.

struct ShadeParams {
    width: u32,
    height: u32,
    // 0 height, 1 shaded, 2 colour.
    mode: u32,
    pad0: u32,
    // Heights mapped to black and white in the height view.
    lo: f32,
    hi: f32,
    // Exaggeration of slopes in height per sample.
    exaggeration: f32,
    ambient: f32,
    // Unit vectors toward the light and the H bisector (xyz).
    light: vec4<f32>,
    half: vec4<f32>,
    diffuse: f32,
    specular: f32,
    shininess: f32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> sp: ShadeParams;
@group(0) @binding(1) var<storage, read> heights: array<u32>;

fn normal_from_gradient(gx: f32, gy: f32, exaggeration: f32) -> vec3<f32> {
    return normalize(vec3<f32>(-gx * exaggeration, -gy * exaggeration, 1.0));
}

fn half_vector(l: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    return normalize(l + v);
}

fn reflectance(n: vec3<f32>, l: vec3<f32>, half: vec3<f32>, ambient: f32, diffuse: f32, specular: f32, shininess: f32) -> f32 {
    let d = max(dot(n, l), 0.0);
    let s = pow(max(dot(n, half), 0.0), shininess);
    return ambient + diffuse * d + specular * s;
}

// The height view's grey level of height h.
fn height_grey(h: f32, lo: f32, hi: f32) -> f32 {
    return clamp((h - lo) / (hi - lo), 0.0, 1.0);
}

fn height_at(x: u32, y: u32) -> f32 {
    return bitcast<f32>(heights[y * (sp.width + 2u) + x]);
}

// The colour packed in a sample's bits (mode 2).
fn unpack_colour(bits: u32) -> vec3<f32> {
    return unpack4x8unorm(bits).xyz;
}

// One triangle that covers the screen.
@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let x = f32((i << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(i & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

@fragment
fn fs_main(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let x = min(u32(pos.x), sp.width - 1u) + 1u;
    let y = min(u32(pos.y), sp.height - 1u) + 1u;
    let bits = heights[y * (sp.width + 2u) + x];
    // A NaN: every exponent bit set and a non-zero mantissa.
    if ((bits & 0x7f800000u) == 0x7f800000u && (bits & 0x007fffffu) != 0u) {
        return vec4<f32>(0.25, 0.25, 0.25, 1.0);
    }
    if (sp.mode == 2u) {
        return vec4<f32>(unpack_colour(bits), 1.0);
    }
    let h = bitcast<f32>(bits);
    var g = 0.0;
    if (sp.mode == 0u) {
        g = height_grey(h, sp.lo, sp.hi);
    } else {
        var gx = 0.5 * (height_at(x + 1u, y) - height_at(x - 1u, y));
        var gy = 0.5 * (height_at(x, y + 1u) - height_at(x, y - 1u));
        // A missing neighbour: a flat normal rather than a NaN.
        if (gx != gx) {
            gx = 0.0;
        }
        if (gy != gy) {
            gy = 0.0;
        }
        let n = normal_from_gradient(gx, gy, sp.exaggeration);
        g = clamp(reflectance(n, sp.light.xyz, sp.half.xyz, sp.ambient, sp.diffuse, sp.specular, sp.shininess), 0.0, 1.0);
    }
    return vec4<f32>(g, g, g, 1.0);
}
