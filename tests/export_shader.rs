//! `export-shader` (issue 37): the sampler of a blend (RPN) bank, a rectangular roller
//! bank, an oblique one (tiles chosen by rhomboid cell) and a Wang bank, in WGSL, GLSL,
//! HLSL and MSL.
//! - Every language is validated by naga: WGSL and GLSL parsed back (naga's WGSL and
//!   GLSL frontends) and validated; HLSL and MSL are written from a module naga
//!   validated, and hold the sampler's functions.
//! - GLSL also passes `glslangValidator` (`SURFTILE_REQUIRE_GLSLANG=1`, set by
//!   `.ci/run`, makes its absence a failure).
//! - The exported GLSL, compiled by naga's GLSL frontend for the GPU (SPIR-V on Vulkan),
//!   fills regions at x = −5·10⁷ (and ±10⁹) with the CPU fill's values within 1e-5
//!   relative error (toroidal and Wang bit for bit).
//! - Bad input (unknown language, a rule without an exported sampler, an output path
//!   that is a file) is refused in one line with nothing written.

mod common;

use std::path::Path;
use std::process::Command;

use surftile::Surface;
use surftile::gpu::{Gpu, gpu_required};
use surftile::stream::Region;
use wgpu::util::DeviceExt;

fn surftile(dir: &Path, args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_surftile"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run surftile");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Bakes the three banks into `dir`: (name, bank file).
fn banks(dir: &Path) -> Vec<(&'static str, String)> {
    let pattern = surftile::lattice::periodic_pattern(200, 160, (40, 0), (13, 29));
    surftile::io::write_heights(&dir.join("grid.npy"), &pattern, None).unwrap();
    let di6 = common::repo("tiles/di-6.npy");
    let di6 = di6.to_str().unwrap();
    let recipes: [(&str, &[&str]); 4] = [
        ("blend", &[di6, "--method", "rpn"]),
        ("rect", &[di6, "--method", "roller", "--tiles", "4"]),
        (
            "oblique",
            &[
                "grid.npy",
                "--method",
                "roller",
                "--tiles",
                "3",
                "--lattice",
                "40,0;13,29",
            ],
        ),
        ("wang", &[di6, "--method", "quilt", "--colours", "2"]),
    ];
    recipes
        .iter()
        .map(|(name, recipe)| {
            let bank = format!("{name}.bank");
            let mut args = vec!["bake"];
            args.extend(*recipe);
            args.extend(["--out", bank.as_str()]);
            let (code, err) = surftile(dir, &args);
            assert_eq!(code, 0, "{name}: {err}");
            (*name, bank)
        })
        .collect()
}

fn validate(module: &naga::Module, what: &str) {
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(module)
    .unwrap_or_else(|e| panic!("{what}: naga validation: {e:?}"));
}

fn has_glslang() -> bool {
    let found = Command::new("glslangValidator")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        assert!(
            std::env::var_os("SURFTILE_REQUIRE_GLSLANG").is_none(),
            "SURFTILE_REQUIRE_GLSLANG is set but glslangValidator is not installed"
        );
        eprintln!("glslangValidator is not installed: GLSL checked by naga only");
    }
    found
}

#[test]
fn every_language_validates() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let glslang = has_glslang();
    for (name, bank) in banks(d) {
        for lang in ["wgsl", "glsl", "hlsl", "msl"] {
            let out = format!("{name}-{lang}");
            let (code, err) = surftile(
                d,
                &[
                    "export-shader",
                    &bank,
                    "--lang",
                    lang,
                    "--out",
                    &out,
                    "--seed",
                    "5",
                ],
            );
            assert_eq!(code, 0, "{name} {lang}: {err}");
            let layout: serde_json::Value = serde_json::from_str(
                &std::fs::read_to_string(d.join(&out).join("layout.json")).unwrap(),
            )
            .unwrap();
            let file = d.join(&out).join(layout["file"].as_str().unwrap());
            let code = std::fs::read_to_string(&file).unwrap();
            let what = format!("{name} {lang}");
            match lang {
                "wgsl" => {
                    let module = naga::front::wgsl::parse_str(&code)
                        .unwrap_or_else(|e| panic!("{what}: {}", e.emit_to_string(&code)));
                    validate(&module, &what);
                }
                "glsl" => {
                    let options = naga::front::glsl::Options::from(naga::ShaderStage::Compute);
                    let module = naga::front::glsl::Frontend::default()
                        .parse(&options, &code)
                        .unwrap_or_else(|e| panic!("{what}: {}", e.emit_to_string(&code)));
                    validate(&module, &what);
                    if glslang {
                        let out = Command::new("glslangValidator")
                            .args(["-S", "comp"])
                            .arg(&file)
                            .output()
                            .unwrap();
                        assert!(
                            out.status.success(),
                            "{what}: glslangValidator: {}",
                            String::from_utf8_lossy(&out.stdout)
                        );
                    }
                }
                _ => {
                    for f in ["surftile_sample", "surftile_height", "surftile_fill"] {
                        assert!(code.contains(f), "{what}: {f} missing");
                    }
                }
            }
            let readme = std::fs::read_to_string(d.join(&out).join("README.md")).unwrap();
            assert!(readme.contains("binding") && readme.contains("surftile_height"));
            // The GPU test samples at ±10⁹.
            assert_eq!(layout["max_coordinate"], 1 << 30, "{what}");
            for b in layout["buffers"].as_array().unwrap() {
                let bytes = std::fs::metadata(d.join(&out).join(b["file"].as_str().unwrap()))
                    .unwrap()
                    .len();
                assert_eq!(bytes, b["bytes"].as_u64().unwrap(), "{what}: {b}");
            }
        }
    }
}

/// The shared device, or `None` where there is no adapter and none is required.
fn gpu() -> Option<Gpu> {
    match Gpu::new() {
        Ok(g) => Some(g),
        Err(e) if gpu_required() => panic!("SURFTILE_REQUIRE_GPU is set, but {e}"),
        Err(e) => {
            eprintln!("skipping the exported GLSL's GPU run: {e}");
            None
        }
    }
}

/// The exported sampler as layout.json lists it: the GLSL, its buffers by binding
/// (binding, bytes, uniform), and the example's region and output bindings.
struct Exported {
    glsl: String,
    buffers: Vec<(u32, Vec<u8>, bool)>,
    region: u32,
    out: u32,
}

impl Exported {
    fn load(dir: &Path) -> Exported {
        let layout: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("layout.json")).unwrap())
                .unwrap();
        let buffers = layout["buffers"]
            .as_array()
            .unwrap()
            .iter()
            .map(|b| {
                (
                    b["binding"].as_u64().unwrap() as u32,
                    std::fs::read(dir.join(b["file"].as_str().unwrap())).unwrap(),
                    b["type"] == "uniform",
                )
            })
            .collect();
        Exported {
            glsl: std::fs::read_to_string(dir.join(layout["file"].as_str().unwrap())).unwrap(),
            buffers,
            region: layout["example"]["region_binding"].as_u64().unwrap() as u32,
            out: layout["example"]["out_binding"].as_u64().unwrap() as u32,
        }
    }

    /// Runs the GLSL's entry point `surftile_fill` on the GPU over `w × h` samples from
    /// origin + frac.
    fn run(
        &self,
        gpu: &Gpu,
        origin: [i32; 2],
        frac: [f32; 2],
        (w, h): (u32, u32),
        channels: u32,
    ) -> Vec<f32> {
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("exported GLSL"),
            source: wgpu::ShaderSource::Glsl {
                shader: self.glsl.as_str().into(),
                stage: naga::ShaderStage::Compute,
                defines: &[],
            },
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("surftile_fill"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let mut region = Vec::new();
        region.extend(bytemuck::cast_slice(&origin));
        region.extend(bytemuck::cast_slice(&frac));
        region.extend(bytemuck::cast_slice(&[w, h, 0, 0]));
        let init = |contents: &[u8], uniform: bool| {
            let usage = if uniform {
                wgpu::BufferUsages::UNIFORM
            } else {
                wgpu::BufferUsages::STORAGE
            };
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: None,
                contents,
                usage,
            })
        };
        let mut buffers: Vec<(u32, wgpu::Buffer)> = self
            .buffers
            .iter()
            .map(|(binding, bytes, uniform)| (*binding, init(bytes, *uniform)))
            .collect();
        buffers.push((self.region, init(&region, true)));
        let bytes = (w * h * channels) as u64 * 4;
        let out = device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .map(|(binding, buffer)| wgpu::BindGroupEntry {
                binding: *binding,
                resource: buffer.as_entire_binding(),
            })
            .collect();
        entries.push(wgpu::BindGroupEntry {
            binding: self.out,
            resource: out.as_entire_binding(),
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
        }
        encoder.copy_buffer_to_buffer(&out, 0, &staging, 0, bytes);
        gpu.queue.submit([encoder.finish()]);
        let slice = staging.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| tx.send(r).unwrap());
        device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
        rx.recv().unwrap().unwrap();
        let values = bytemuck::cast_slice(&slice.get_mapped_range().unwrap()).to_vec();
        staging.unmap();
        values
    }
}

#[test]
fn exported_glsl_on_the_gpu_matches_the_cpu_fill_at_minus_5e7_and_1e9() {
    let Some(gpu) = gpu() else { return };
    eprintln!("GPU: {}", gpu.describe());
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (name, bank) in banks(d) {
        let out = format!("{name}-glsl");
        let (code, err) = surftile(
            d,
            &[
                "export-shader",
                &bank,
                "--lang",
                "glsl",
                "--out",
                &out,
                "--seed",
                "5",
            ],
        );
        assert_eq!(code, 0, "{name}: {err}");
        let exported = Exported::load(&d.join(&out));
        let surface = surftile::open(d.join(&bank)).unwrap().surface(5).unwrap();
        let c = surface.channels();
        for (origin, frac) in [
            ([-50_000_000, 1234], [0.0, 0.0]),
            ([-50_000_000, -77], [0.25, 0.625]),
            ([1_000_000_000, -1_000_000_000], [0.5, 0.125]),
        ] {
            let (w, h) = (173u32, 131u32);
            let gpu_values = exported.run(&gpu, origin, frac, (w, h), c as u32);
            let x = origin[0] as f64 + frac[0] as f64;
            let y = origin[1] as f64 + frac[1] as f64;
            let mut cpu = vec![0.0f32; (w * h) as usize * c];
            surface
                .fill(&Region::new(x, y, w as usize, h as usize), &mut cpu)
                .unwrap();
            let scale = cpu.iter().fold(0.0f32, |m, v| m.max(v.abs()));
            let worst = gpu_values
                .iter()
                .zip(&cpu)
                .fold(0.0f32, |m, (g, c)| m.max((g - c).abs()));
            let identical = gpu_values
                .iter()
                .zip(&cpu)
                .filter(|(g, c)| g.to_bits() == c.to_bits())
                .count();
            eprintln!(
                "{name} at ({x}, {y}): max relative error {:.2e}, {identical} of {} bit-identical",
                worst / scale,
                cpu.len()
            );
            assert!(
                worst / scale <= 1e-5,
                "{name} at ({x}, {y}): max relative error {:.2e}",
                worst / scale
            );
        }
    }
}

#[test]
fn export_shader_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let di6 = common::repo("tiles/di-6.npy");
    let (code, err) = surftile(
        d,
        &[
            "bake",
            "parallel-d4-ae05",
            "--method",
            "milling",
            "--spacing",
            "6.1",
            "--out",
            "m.bank",
        ],
    );
    assert_eq!(code, 0, "{err}");
    let (code, err) = surftile(
        d,
        &[
            "bake",
            di6.to_str().unwrap(),
            "--method",
            "quilt",
            "--out",
            "q.bank",
        ],
    );
    assert_eq!(code, 0, "{err}");
    std::fs::write(d.join("a-file"), b"keep").unwrap();
    let cases: [(&[&str], &str); 4] = [
        (
            &["q.bank", "--lang", "cuda", "--out", "s1"],
            "wgsl, glsl, hlsl, msl",
        ),
        (
            &["m.bank", "--lang", "glsl", "--out", "s2"],
            "milling bank: its sampler is not exported yet; export-shader takes blend (rpn, adsn), toroidal (roller) and Wang (quilt) banks",
        ),
        (
            &["q.bank", "--lang", "glsl", "--out", "a-file"],
            "existing file",
        ),
        (&["rock", "--lang", "glsl", "--out", "s3"], "not a bank"),
    ];
    for (args, expect) in cases {
        let mut all = vec!["export-shader"];
        all.extend(args);
        let (code, err) = surftile(d, &all);
        assert_ne!(code, 0, "{args:?}");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
    }
    assert_eq!(std::fs::read(d.join("a-file")).unwrap(), b"keep");
    let mut left: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["a-file", "m.bank", "q.bank"]);
}
