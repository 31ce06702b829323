//! `export-shader`: a bank's point sampler in a renderer's shading language, with the
//! bank's tiles, tables and parameters laid out for the GPU, so that a renderer samples
//! the infinite surface in its own shader without surftile at run time (Heitz–Neyret
//! style).
//!
//! - Blend banks (RPN, ADSN): `shaders/blend_sampler.wgsl` after `hash.wgsl` and
//!   `blend.wgsl`, calling the GPU fill's own `triangle`, `eval_level`, `bilinear` and
//!   `lut_eval` with its uniform: one source of truth.
//! - Toroidal (roller) and Wang (quilt) banks: `shaders/sampler.wgsl` after `hash.wgsl`
//!   (the GPU fill's hashes and its `wang_tile`; the toroidal fill's cell arithmetic works
//!   on host-split axes, so the point functions are its twins).
//!
//! naga validates the module and translates it. `tests/export_shader.rs` also checks the
//! GLSL with glslangValidator, and runs it through naga's GLSL frontend against the CPU
//! fill.

use std::path::Path;

use serde_json::json;

use super::StagedDir;
use crate::bank::{Bank, Record, Rule};
use crate::error::{Error, Result};
use crate::lattice::Lattice;

/// A shading language `export-shader` writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum ShaderLang {
    /// WGSL (WebGPU, wgpu, Bevy): the source itself.
    Wgsl,
    /// GLSL 4.50 core, a compute shader whose functions a renderer copies (OpenGL, Vulkan
    /// through glslang).
    Glsl,
    /// HLSL shader model 5.1 (Direct3D 11/12, Unity, Unreal).
    Hlsl,
    /// Metal Shading Language 2.0.
    Msl,
}

impl ShaderLang {
    /// The file the sampler is written to.
    pub fn file_name(self) -> &'static str {
        match self {
            ShaderLang::Wgsl => "surftile.wgsl",
            ShaderLang::Glsl => "surftile.comp.glsl",
            ShaderLang::Hlsl => "surftile.hlsl",
            ShaderLang::Msl => "surftile.metal",
        }
    }

    fn name(self) -> &'static str {
        match self {
            ShaderLang::Wgsl => "WGSL",
            ShaderLang::Glsl => "GLSL",
            ShaderLang::Hlsl => "HLSL",
            ShaderLang::Msl => "MSL",
        }
    }
}

/// The sampler's uniform `SurftileParams` (shaders/sampler.wgsl), 64 bytes as the GPU
/// reads them (std140 and WGSL uniform layout agree for it).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SamplerParams {
    /// HNF A (tile width).
    pub a: i32,
    /// HNF B (row shift).
    pub b: i32,
    /// HNF C (tile height).
    pub c: i32,
    /// K tiles.
    pub tiles: u32,
    /// Values per texel.
    pub channels: u32,
    /// Placement seed.
    pub seed: u32,
    /// det of the reduced basis where tiles are chosen by rhomboid cell, else 0.
    pub det: i32,
    /// Wang colours per edge direction, 0 for toroidal banks.
    pub colours: u32,
    /// Reduced basis u.
    pub u: [i32; 2],
    /// Reduced basis v.
    pub v: [i32; 2],
    /// (A, 0) in the reduced basis.
    pub hnf_a: [i32; 2],
    /// (B, C) in the reduced basis.
    pub hnf_b: [i32; 2],
}

/// The rules `export-shader` handles, for errors.
const EXPORTABLE: &str = "blend (rpn, adsn), toroidal (roller) and Wang (quilt) banks";

/// Refuses banks whose rule has no exported sampler, naming those that have one.
fn check_rule(bank: &Bank) -> Result<()> {
    let rule = bank.header.rule();
    if !matches!(rule, Rule::Toroidal | Rule::Wang | Rule::Blend) {
        return Err(Error::Unsupported(format!(
            "export-shader of a {rule} bank: its sampler is not exported yet; export-shader takes {EXPORTABLE}"
        )));
    }
    bank.validate("given to export-shader")
}

/// The toroidal and Wang sampler's parameters for `bank` placed with `seed`, refusing
/// banks of other rules (naming those it takes) and sizes the sampler's i32 arithmetic
/// cannot hold.
pub fn sampler_params(bank: &Bank, seed: u32) -> Result<SamplerParams> {
    let h = &bank.header;
    check_rule(bank)?;
    if h.rule() == Rule::Blend {
        return Err(Error::Unsupported(
            "sampler_params of a blend bank: its sampler takes blend.wgsl's BlendParams".into(),
        ));
    }
    if !(1..=4).contains(&h.channels) {
        return Err(Error::Unsupported(format!(
            "export-shader of a {}-channel bank; expected 1 to 4 channels",
            h.channels
        )));
    }
    let level = &h.levels[0];
    let [a, c] = level.size.map(|s| s as i64);
    let b = level.shift.unwrap_or(0) as i64;
    let texels = bank.texels[0].len();
    if a > 1 << 15 || c > 1 << 15 || texels > u32::MAX as usize {
        return Err(Error::Limits(format!(
            "export-shader of {} tiles of {a}×{c}: the sampler indexes at most 2^32 texels \
             and tiles of at most 32768 a side",
            h.tiles
        )));
    }
    let colours = match h.record {
        Record::Wang { colours, .. } => colours as u32,
        _ => 0,
    };
    let mut p = SamplerParams {
        a: a as i32,
        b: b as i32,
        c: c as i32,
        tiles: h.tiles as u32,
        channels: h.channels as u32,
        seed,
        det: 0,
        colours,
        u: [0; 2],
        v: [0; 2],
        hnf_a: [0; 2],
        hnf_b: [0; 2],
    };
    // As ToroidalSurface::from_levels: several tiles on an oblique lattice pick their tile
    // by rhomboid cell.
    if h.tiles > 1 && b != 0 && colours == 0 {
        let [u, v] = Lattice { a, b, c }.reduced_basis();
        let det = u.0 * v.1 - u.1 * v.0;
        // A lattice point L in the basis (u, v): ((v₂·Lx − v₁·Ly) / det, (u₁·Ly − u₂·Lx) / det),
        // exact since L is on the lattice.
        let coords = |lx: i64, ly: i64| {
            let (s, t) = (v.1 * lx - v.0 * ly, u.0 * ly - u.1 * lx);
            debug_assert!(s % det == 0 && t % det == 0);
            [(s / det) as i32, (t / det) as i32]
        };
        p.det = det as i32;
        p.u = [u.0 as i32, u.1 as i32];
        p.v = [v.0 as i32, v.1 as i32];
        p.hnf_a = coords(a, 0);
        p.hnf_b = coords(b, c);
    }
    Ok(p)
}

/// The largest |ip| (a power of two, at most 2^30) for which every intermediate of
/// `shaders/sampler.wgsl` (cell, shifted x, rhomboid coordinates, the +1 neighbours)
/// fits in an i32 for these parameters.
pub fn max_coordinate(p: &SamplerParams) -> i64 {
    let fits = |r: i64| {
        let (a, b, c) = (p.a as i64, p.b.unsigned_abs() as i64, p.c as i64);
        let j = r / c + 2;
        let xs = r + 1 + j * b;
        let i = xs / a + 2;
        let rhomboid = |k: usize| {
            i * (p.hnf_a[k].unsigned_abs() as i64) + j * (p.hnf_b[k].unsigned_abs() as i64) + 2
        };
        [j * b, xs, i, rhomboid(0), rhomboid(1)]
            .iter()
            .all(|&v| v < i32::MAX as i64)
    };
    let mut r = 1i64 << 30;
    while r > 1 && !fits(r) {
        r /= 2;
    }
    r
}

/// The WGSL of the sampler module for a bank of `rule` (`sampler` for toroidal and Wang
/// banks, `blend_sampler` for blend banks).
pub fn sampler_wgsl(rule: Rule) -> String {
    crate::gpu::module_source(if rule == Rule::Blend {
        "blend_sampler"
    } else {
        "sampler"
    })
}

/// The sampler for a bank of `rule` translated into `lang` by naga, after naga validated
/// the module.
pub fn translate(rule: Rule, lang: ShaderLang) -> Result<String> {
    let source = sampler_wgsl(rule);
    let bug = |stage: &str, e: String| {
        Error::Gpu(format!(
            "the sampler's {} translation failed at {stage} (a bug in surftile): {}",
            lang.name(),
            e.replace('\n', " ")
        ))
    };
    let module = naga::front::wgsl::parse_str(&source)
        .map_err(|e| bug("parsing", e.emit_to_string(&source)))?;
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module)
    .map_err(|e| bug("validation", e.emit_to_string(&source)))?;
    let entry = "surftile_fill".to_string();
    let stage = naga::ShaderStage::Compute;
    Ok(match lang {
        ShaderLang::Wgsl => source,
        ShaderLang::Glsl => {
            let mut binding_map = naga::back::glsl::BindingMap::default();
            for binding in 0..8 {
                binding_map.insert(naga::ResourceBinding { group: 0, binding }, binding as u8);
            }
            let options = naga::back::glsl::Options {
                version: naga::back::glsl::Version::Desktop(450),
                binding_map,
                ..Default::default()
            };
            let pipeline = naga::back::glsl::PipelineOptions {
                shader_stage: stage,
                entry_point: entry,
                multiview: None,
            };
            let mut out = String::new();
            let mut writer = naga::back::glsl::Writer::new(
                &mut out,
                &module,
                &info,
                &options,
                &pipeline,
                naga::proc::BoundsCheckPolicies::default(),
            )
            .map_err(|e| bug("GLSL setup", e.to_string()))?;
            writer.write().map_err(|e| bug("GLSL", e.to_string()))?;
            out
        }
        ShaderLang::Hlsl => {
            let options = naga::back::hlsl::Options::default();
            let pipeline = naga::back::hlsl::PipelineOptions { entry_point: None };
            let mut out = String::new();
            naga::back::hlsl::Writer::new(&mut out, &options, &pipeline)
                .write(&module, &info, None)
                .map_err(|e| bug("HLSL", e.to_string()))?;
            out
        }
        ShaderLang::Msl => {
            let options = naga::back::msl::Options {
                lang_version: (2, 0),
                ..Default::default()
            };
            let pipeline = naga::back::msl::PipelineOptions::default();
            naga::back::msl::write_string(&module, &info, &options, &pipeline)
                .map_err(|e| bug("MSL", e.to_string()))?
                .0
        }
    })
}

/// What [`export_shader`] wrote.
#[derive(Clone, Debug)]
pub struct ShaderExport {
    /// The bank's rule.
    pub rule: Rule,
    /// The sampler's file name in the directory.
    pub file: &'static str,
    /// The data files, by binding: (binding, file, bytes, uniform or storage).
    pub buffers: Vec<(u32, &'static str, usize, &'static str)>,
    /// The binding of the example entry point's region uniform.
    pub region_binding: u32,
    /// The binding of the example entry point's output buffer.
    pub out_binding: u32,
}

/// One buffer the sampler reads.
struct Buffer {
    binding: u32,
    file: &'static str,
    uniform: bool,
    what: &'static str,
    bytes: Vec<u8>,
}

/// What a sampler needs: its buffers, the example's region and output bindings, and
/// the largest |ip| it takes.
struct Plan {
    buffers: Vec<Buffer>,
    region_binding: u32,
    out_binding: u32,
    max_coordinate: i64,
}

/// The buffers and example bindings of `bank`'s sampler placed with `seed`.
fn plan(bank: &Bank, seed: u32) -> Result<Plan> {
    check_rule(bank)?;
    let tiles = Buffer {
        binding: 1,
        file: "tiles.f32",
        uniform: false,
        what: "the level-0 tiles: tiles × rows × columns × channels, little-endian f32",
        bytes: bank.texels[0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect(),
    };
    if bank.header.rule() != Rule::Blend {
        let params = sampler_params(bank, seed)?;
        let max_coordinate = max_coordinate(&params);
        let params = Buffer {
            binding: 0,
            file: "params.bin",
            uniform: true,
            what: "SurftileParams (64 bytes): a, b, c, tiles, channels, seed, det, colours (4 bytes each), u, v, hnf_a, hnf_b (2 × i32 each)",
            bytes: bytemuck::bytes_of(&params).to_vec(),
        };
        return Ok(Plan {
            buffers: vec![params, tiles],
            region_binding: 2,
            out_binding: 3,
            max_coordinate,
        });
    }
    let surface = crate::stream::BlendSurface::new(bank, seed)?;
    if bank.texels[0].len() > u32::MAX as usize {
        return Err(Error::Limits(
            "export-shader of a blend bank of more than 2^32 texels".into(),
        ));
    }
    let params = Buffer {
        binding: 0,
        file: "params.bin",
        uniform: true,
        what: "blend.wgsl's BlendParams (208 bytes), level 0 in slot 0, region fields zero",
        bytes: crate::gpu::blend_sampler_params(&surface)?,
    };
    let luts = Buffer {
        binding: 5,
        file: "luts.f32",
        uniform: false,
        what: "the level-0 T⁻¹ tables, per channel lut_size (value, next − value) pairs of f32",
        bytes: surface.levels[0]
            .lut
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect(),
    };
    let (a, b, c) = (surface.skew_a, surface.skew_b, surface.skew_c);
    let mut skew: Vec<f32> = Vec::with_capacity(12);
    for k in [a, -b, c] {
        skew.extend(chunks(k));
    }
    let skew = Buffer {
        binding: 6,
        file: "skew.bin",
        uniform: true,
        what: "SurftileSkew (48 bytes): a = 1/E, −b = −1/(√3·E), c = 2/(√3·E), each as four f32 chunks of 13 bits",
        bytes: bytemuck::cast_slice(&skew).to_vec(),
    };
    // blend_sampler.wgsl's chunks of ip take |ip| ≤ 2^30, and the skew's integer parts
    // (|ip|·c, c ≤ 2/√3 for E ≥ 1) stay below 2^31.
    Ok(Plan {
        buffers: vec![params, tiles, luts, skew],
        region_binding: 7,
        out_binding: 4,
        max_coordinate: 1 << 30,
    })
}

/// `k` as four f32 of at most 13 significant bits whose sum is `k` to 52 bits, so that
/// a 10-bit integer times a chunk is exact in f32 (shaders/blend_sampler.wgsl).
fn chunks(k: f64) -> [f32; 4] {
    let mut rest = k;
    let mut out = [0.0f32; 4];
    for chunk in &mut out {
        if rest == 0.0 {
            break;
        }
        let scale = 2f64.powi(12 - rest.abs().log2().floor() as i32);
        let q = (rest * scale).round() / scale;
        *chunk = q as f32;
        debug_assert_eq!(*chunk as f64, q);
        rest -= q;
    }
    out
}

/// Writes into the new directory `dir`, all or nothing: the sampler in `lang`, its
/// buffers (tiles, tables, parameters) as the files `layout.json` lists by binding, and a
/// README with the bindings and a usage snippet.
pub fn export_shader(bank: &Bank, seed: u32, lang: ShaderLang, dir: &Path) -> Result<ShaderExport> {
    let Plan {
        buffers,
        region_binding,
        out_binding,
        max_coordinate,
    } = plan(bank, seed)?;
    let rule = bank.header.rule();
    let code = translate(rule, lang)?;
    let staged = StagedDir::new(dir, "--out")?;
    let file = lang.file_name();
    let write = |name: &str, bytes: &[u8]| {
        let path = staged.path(name);
        crate::io::write_atomically(&path, |w| {
            std::io::Write::write_all(w, bytes).map_err(|e| Error::io(&path, e))
        })
    };
    write(file, code.as_bytes())?;
    for b in &buffers {
        write(b.file, &b.bytes)?;
    }
    let h = &bank.header;
    let rule_name = match h.record {
        Record::Wang { .. } => "wang",
        _ if rule == Rule::Blend => "blend",
        _ => "toroidal",
    };
    let layout = json!({
        "format": "surftile-shader",
        "version": 1,
        "language": lang.name(),
        "file": file,
        "rule": rule_name,
        "seed": seed,
        "channels": h.channels,
        "spacing_um": h.spacing_um,
        "height_unit": h.height_unit,
        "buffers": buffers.iter().map(|b| json!({
            "binding": b.binding,
            "file": b.file,
            "type": if b.uniform { "uniform" } else { "storage, read-only" },
            "bytes": b.bytes.len(),
            "what": b.what,
        })).collect::<Vec<_>>(),
        "example": {
            "entry_point": "surftile_fill",
            "region_binding": region_binding,
            "region": "SurftileRegion (32 bytes): origin i32×2, frac f32×2, width, height, 2 pads",
            "out_binding": out_binding,
            "out": "storage, read-write, array of f32: width × height × channels, row-major",
        },
        "max_coordinate": max_coordinate,
        "position": "surftile_sample(ip, fp) / surftile_height(ip, fp): integer texel ip (|ip| < max_coordinate) plus fraction fp in [0, 1); surface pixel (x, y) is ip = floor, fp = x - floor(x)",
    });
    let text = serde_json::to_string_pretty(&layout).expect("a JSON value prints");
    write("layout.json", text.as_bytes())?;
    write(
        "README.md",
        readme(
            lang,
            rule_name,
            seed,
            &buffers,
            [region_binding, out_binding],
            max_coordinate,
        )
        .as_bytes(),
    )?;
    staged.commit()?;
    Ok(ShaderExport {
        rule,
        file,
        buffers: buffers
            .iter()
            .map(|b| {
                let kind = if b.uniform { "uniform" } else { "storage" };
                (b.binding, b.file, b.bytes.len(), kind)
            })
            .collect(),
        region_binding,
        out_binding,
    })
}

/// The README written beside the sampler.
fn readme(
    lang: ShaderLang,
    rule: &str,
    seed: u32,
    buffers: &[Buffer],
    [region_binding, out_binding]: [u32; 2],
    max_coordinate: i64,
) -> String {
    let file = lang.file_name();
    let (name, how) = match lang {
        ShaderLang::Wgsl => (
            "WGSL",
            "Paste the module (everything but the entry points) into yours, or use the file \
             as is for a compute pass.",
        ),
        ShaderLang::Glsl => (
            "GLSL 4.50",
            "naga wrote the file as a compute shader around the example entry point; copy its \
             blocks and functions (`surftile_sample`, `surftile_height` and what they call) \
             into your shader. naga names the blocks' instances after their bindings \
             (`_group_0_binding_0_cs`, …).",
        ),
        ShaderLang::Hlsl => (
            "HLSL (shader model 5.1)",
            "Uniforms are constant buffers at register(bN), storage buffers \
             ByteAddressBuffers at register(tN) or (uN), N the binding; naga's names are in \
             the file.",
        ),
        ShaderLang::Msl => (
            "Metal Shading Language 2.0",
            "The entry points take the buffers as arguments; call `surftile_sample` with \
             them from your own kernels or fragment functions.",
        ),
    };
    // Every binding in order, the example entry point's two among the buffers.
    let mut rows: Vec<(u32, String)> = buffers
        .iter()
        .map(|b| {
            let kind = if b.uniform {
                "uniform"
            } else {
                "storage, read-only"
            };
            (
                b.binding,
                format!("| {} | {kind}: {} | `{}` |\n", b.binding, b.what, b.file),
            )
        })
        .collect();
    rows.push((
        region_binding,
        format!(
            "| {region_binding} | uniform `SurftileRegion` of the example entry point `surftile_fill` | |\n"
        ),
    ));
    rows.push((
        out_binding,
        format!("| {out_binding} | storage, read-write: `surftile_fill`'s output | |\n"),
    ));
    rows.sort();
    let table: String = rows.into_iter().map(|(_, row)| row).collect();
    format!(
        "# surftile sampler: {name}

`{file}` samples this bank's infinite surface ({rule} rule, seed {seed}):
`surftile_sample(ip, fp)` returns every channel (vec4) and `surftile_height(ip, fp)`
channel 0, at texel position ip + fp: ip an integer texel (|ip| < {max_coordinate}), fp in [0, 1).
Keep your own integer offset so that no f32 holds a large coordinate. The values are
surftile's CPU fill's at level 0 (full resolution), within float rounding; no mip
levels are exported.

| binding (group 0) | what | file |
|---|---|---|
{table}
{how}

Usage, in a compute or fragment shader (WGSL shown; the other languages have the same
functions and arguments):

```wgsl
let world = vec2<f32>(…);                       // your coordinate, in surface pixels
let ip = tile_origin + vec2<i32>(floor(world)); // tile_origin: your integer offset
let h = surftile_height(ip, fract(world));
```

`layout.json` lists the same, with byte sizes.
"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Chunks sum to the constant to 52 bits, each with at most 13 significant bits.
    #[test]
    fn chunks_are_exact_and_short() {
        for k in [
            1.0 / 128.0,
            1.0 / (1.732_050_807_568_877_2 * 100.0),
            -0.011_547,
            1.154_7,
        ] {
            let c = chunks(k);
            let sum: f64 = c.iter().map(|&v| v as f64).sum();
            assert!((sum - k).abs() <= k.abs() * 2f64.powi(-51), "{k}: {sum}");
            for v in c {
                let bits = (v.to_bits() & 0x7F_FFFF).trailing_zeros();
                assert!(
                    v == 0.0 || bits >= 23 - 12,
                    "{k}: chunk {v} has too many bits"
                );
            }
        }
    }

    /// A long, sheared cell narrows the coordinate range; a square one keeps 2^30.
    #[test]
    fn max_coordinate_shrinks_for_sheared_cells() {
        let p = |a, b, c| SamplerParams {
            a,
            b,
            c,
            tiles: 1,
            channels: 1,
            seed: 0,
            det: 0,
            colours: 0,
            u: [0; 2],
            v: [0; 2],
            hnf_a: [0; 2],
            hnf_b: [0; 2],
        };
        assert_eq!(max_coordinate(&p(256, 0, 256)), 1 << 30);
        let thin = p(4000, 3999, 1);
        let r = max_coordinate(&thin);
        assert!(r < 1 << 20, "{r}");
        assert!((r + 2) * 3999 < i32::MAX as i64);
    }
}
