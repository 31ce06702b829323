//! `export-shader`: a toroidal (roller) or Wang (quilt) bank's point sampler in a
//! renderer's shading language, with the bank's tiles and parameters laid out for the
//! GPU, so that a renderer samples the infinite surface in its own shader without
//! surftile at run time (Heitz–Neyret style).
//!
//! The sampler is `shaders/sampler.wgsl` after `shaders/hash.wgsl`: the same hash
//! functions the GPU fill compiles (one source of truth), translated by naga. Every
//! output is validated by naga first; `tests/export_shader.rs` also checks the GLSL with
//! glslangValidator and runs it, through naga's GLSL frontend, against the CPU fill.

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
const EXPORTABLE: &str = "toroidal (roller) and Wang (quilt) banks";

/// The sampler's parameters for `bank` placed with `seed`, refusing banks of other rules
/// (naming those it takes) and sizes the sampler's i32 arithmetic cannot hold.
pub fn sampler_params(bank: &Bank, seed: u32) -> Result<SamplerParams> {
    let h = &bank.header;
    if !matches!(h.rule(), Rule::Toroidal | Rule::Wang) {
        return Err(Error::Unsupported(format!(
            "export-shader of a {} bank: its sampler is not exported yet; export-shader takes {EXPORTABLE}",
            h.rule()
        )));
    }
    bank.validate("given to export-shader")?;
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

/// The sampler module's WGSL: the shared hashes, then the sampler.
pub fn sampler_wgsl() -> String {
    crate::gpu::module_source("sampler")
}

/// The sampler translated into `lang` by naga, after naga validated the module.
pub fn translate(lang: ShaderLang) -> Result<String> {
    let source = sampler_wgsl();
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
            for binding in 0..4 {
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
    /// The sampler's parameters.
    pub params: SamplerParams,
    /// The sampler's file name in the directory.
    pub file: &'static str,
    /// Bytes of `tiles.f32`.
    pub tile_bytes: usize,
}

/// Writes into the new directory `dir`, all or nothing: the sampler in `lang`, the
/// level-0 tiles as `tiles.f32` (the storage buffer, little-endian f32), the uniform as
/// `params.bin`, both described in `layout.json`, and a README with the bindings.
pub fn export_shader(bank: &Bank, seed: u32, lang: ShaderLang, dir: &Path) -> Result<ShaderExport> {
    let params = sampler_params(bank, seed)?;
    let code = translate(lang)?;
    let staged = StagedDir::new(dir, "--out")?;
    let file = lang.file_name();
    let write = |name: &str, bytes: &[u8]| {
        let path = staged.path(name);
        crate::io::write_atomically(&path, |w| {
            std::io::Write::write_all(w, bytes).map_err(|e| Error::io(&path, e))
        })
    };
    write(file, code.as_bytes())?;
    let texels: Vec<u8> = bank.texels[0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    write("tiles.f32", &texels)?;
    write("params.bin", bytemuck::bytes_of(&params))?;
    let h = &bank.header;
    let layout = json!({
        "format": "surftile-shader",
        "version": 1,
        "language": lang.name(),
        "file": file,
        "rule": if params.colours > 0 { "wang" } else { "toroidal" },
        "spacing_um": h.spacing_um,
        "height_unit": h.height_unit,
        "bindings": {
            "0": "uniform SurftileParams: params.bin (64 bytes)",
            "1": "storage buffer, read-only, array of f32: tiles.f32",
            "2": "uniform SurftileRegion of the example entry point surftile_fill (origin i32×2, frac f32×2, width, height, 2 pads)",
            "3": "storage buffer, read-write, array of f32: surftile_fill's output",
        },
        "params": {
            "a": params.a, "b": params.b, "c": params.c, "tiles": params.tiles,
            "channels": params.channels, "seed": params.seed, "det": params.det,
            "colours": params.colours, "u": params.u, "v": params.v,
            "hnf_a": params.hnf_a, "hnf_b": params.hnf_b,
            "byte_offsets": "a 0, b 4, c 8, tiles 12, channels 16, seed 20, det 24, colours 28, u 32, v 40, hnf_a 48, hnf_b 56",
        },
        "tiles_f32": {
            "bytes": texels.len(),
            "layout": "tiles × c rows × a texels × channels, little-endian f32, tile after tile",
        },
        "position": "surftile_sample(ip, fp): integer texel ip (|ip| < 2^30) plus fraction fp in [0, 1); surface pixel (x, y) is ip = floor, fp = x - floor(x)",
    });
    let text = serde_json::to_string_pretty(&layout).expect("a JSON value prints");
    write("layout.json", text.as_bytes())?;
    write("README.md", readme(lang, &params).as_bytes())?;
    staged.commit()?;
    Ok(ShaderExport {
        params,
        file,
        tile_bytes: texels.len(),
    })
}

/// The README written beside the sampler.
fn readme(lang: ShaderLang, p: &SamplerParams) -> String {
    let file = lang.file_name();
    let (name, how) = match lang {
        ShaderLang::Wgsl => (
            "WGSL",
            "Paste the functions (everything but `surftile_fill`) into your module, or use the \
             file as is for a compute pass.",
        ),
        ShaderLang::Glsl => (
            "GLSL 4.50",
            "naga wrote the file as a compute shader around the example entry point; copy its \
             uniform block, buffer block and functions (`surftile_sample`, `surftile_height` and \
             what they call) into your shader. naga names the blocks' instances after their \
             bindings (`_group_0_binding_0_cs`, …).",
        ),
        ShaderLang::Hlsl => (
            "HLSL (shader model 5.1)",
            "SurftileParams is the constant buffer at register(b0), the tiles a ByteAddressBuffer \
             at register(t1); naga's names for them are in the file.",
        ),
        ShaderLang::Msl => (
            "Metal Shading Language 2.0",
            "The entry point takes the params and tiles as buffer arguments; call \
             `surftile_sample` with them from your own kernels or fragment functions.",
        ),
    };
    format!(
        "# surftile sampler ({name})

`{file}` samples this bank's infinite surface: `surftile_sample(ip, fp)` returns every
channel (vec4) and `surftile_height(ip, fp)` channel 0, at texel position ip + fp, ip an
integer texel (|ip| < 2^30) and fp in [0, 1). Keep your own integer offset so that no f32
holds a large coordinate. The values are surftile's CPU fill's at level 0 (full
resolution), within float rounding; no mip levels are exported.

| binding (group 0) | what | file |
|---|---|---|
| 0 | uniform `SurftileParams`, 64 bytes | `params.bin` |
| 1 | storage buffer, read-only, `array<f32>` | `tiles.f32` ({tiles} tiles of {a}×{c}, {ch} channel(s)) |
| 2 | uniform `SurftileRegion` (example entry point only) | |
| 3 | storage buffer, read-write (example entry point only) | |

{how}

Usage, in a compute or fragment shader (WGSL shown; the other languages have the same
functions and arguments):

```wgsl
let world = vec2<f32>(…);                      // your coordinate, in surface pixels
let ip = tile_origin + vec2<i32>(floor(world)); // tile_origin: your integer offset
let h = surftile_height(ip, fract(world));
```

`layout.json` lists the parameters and byte offsets. Rule: {rule}, seed {seed}.
",
        tiles = p.tiles,
        a = p.a,
        c = p.c,
        ch = p.channels,
        rule = if p.colours > 0 {
            "wang"
        } else if p.det != 0 {
            "toroidal, tiles chosen by rhomboid cell"
        } else {
            "toroidal"
        },
        seed = p.seed,
    )
}
