//! Renderer exports (issue 37, first step): float OpenEXR heights and colours that
//! round-trip bit for bit with their spacing and unit, and tangent-space normal maps
//! that agree with analytic normals.

mod common;

use std::path::Path;
use std::process::Command;

use surftile::io::{ReadOptions, Unit, WriteMeta, read_image, write_heights_with};
use surftile::normals::{NormalConvention, normal_map, tangent_normal};
use surftile::raster::Raster;

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

/// Heights (with a missing point) and colours written as EXR read back with the same
/// f32 bits, spacings and unit.
#[test]
fn exr_round_trips_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    for channels in [1, 3, 4] {
        let (w, h) = (13, 7);
        let mut data: Vec<f32> = (0..w * h * channels)
            .map(|k| (k as f32 * 0.731).sin() * 10f32.powi(k as i32 % 7 - 3))
            .collect();
        data[5] = f32::NAN;
        let raster = Raster::from_vec(w, h, channels, data.clone()).unwrap();
        let path = dir.path().join(format!("c{channels}.exr"));
        let meta = WriteMeta {
            spacing_um: Some(0.25),
            spacing_y_um: Some(0.5),
            unit: Unit::Um,
            levels: None,
        };
        write_heights_with(&path, &raster, &meta).unwrap();
        let back = read_image(&path, &ReadOptions::default()).unwrap();
        // Alpha is dropped, as every reader does.
        let kept = channels.min(3);
        assert_eq!(
            (back.raster.width, back.raster.height, back.raster.channels),
            (w, h, kept)
        );
        for (px, back_px) in data
            .chunks_exact(channels)
            .zip(back.raster.data.chunks_exact(kept))
        {
            for (a, b) in px.iter().zip(back_px) {
                assert_eq!(
                    a.to_bits(),
                    b.to_bits(),
                    "{channels} channels: {a} became {b}"
                );
            }
        }
        assert_eq!(
            (back.spacing_um, back.spacing_y_um),
            (Some(0.25), Some(0.5))
        );
    }
}

/// Normals of a tilted plane are exact, and those of a sine agree with the analytic
/// ones within 1e-4 per component, in both conventions (DirectX flips green).
#[test]
fn normals_agree_with_analytic_surfaces() {
    let (w, h, d) = (70, 40, 0.5); // spacing 0.5 µm
    let (a, b) = (0.3, -0.7); // slopes along x and down the rows
    let plane: Vec<f32> = (0..w * h)
        .map(|i| (a * (i % w) as f64 * d + b * (i / w) as f64 * d) as f32)
        .collect();
    let r = Raster::from_vec(w, h, 1, plane).unwrap();
    for convention in [NormalConvention::Gl, NormalConvention::Dx] {
        let n = normal_map(&r, d, convention).unwrap();
        assert_eq!((n.width, n.height, n.channels), (w - 4, h - 4, 3));
        let want = tangent_normal(a, b, convention);
        for px in n.data.chunks_exact(3) {
            for k in 0..3 {
                assert!(
                    (px[k] as f64 - want[k]).abs() < 1e-4,
                    "{convention:?}: {px:?} vs {want:?}"
                );
            }
        }
    }
    // GL: a surface rising down the image (b < 0 rises up it) has green > 0.
    assert!(tangent_normal(0.0, 1.0, NormalConvention::Gl)[1] > 0.0);
    assert!(tangent_normal(0.0, 1.0, NormalConvention::Dx)[1] < 0.0);
    // z = A sin(k x): n ∝ (−A k cos kx, 0, 1).
    let (amp, k) = (0.8, 2.0 * std::f64::consts::PI / (64.0 * d));
    let sine: Vec<f32> = (0..w * h)
        .map(|i| (amp * (k * (i % w) as f64 * d).sin()) as f32)
        .collect();
    let r = Raster::from_vec(w, h, 1, sine).unwrap();
    let n = normal_map(&r, d, NormalConvention::Gl).unwrap();
    let mut worst = 0.0f64;
    for (i, px) in n.data.chunks_exact(3).enumerate() {
        let x = (i % n.width + 2) as f64 * d;
        let want = tangent_normal(amp * k * (k * x).cos(), 0.0, NormalConvention::Gl);
        for c in 0..3 {
            worst = worst.max((px[c] as f64 - want[c]).abs());
        }
    }
    assert!(worst < 1e-4, "worst component error {worst:e}");
}

/// `render --out h.exr --normal-map n.exr`: the EXR heights are the .npy render's bits,
/// the normals are those of the written heights (on their interior, where both see the
/// same samples), a 16-bit PNG normal map holds the same normals within a level, and a
/// normal map in another format is refused before anything is written.
#[test]
fn render_writes_exr_and_normal_maps() {
    let dir = tempfile::tempdir().unwrap();
    let region = [
        "parallel-d4-ae05",
        "--w",
        "48",
        "--h",
        "32",
        "--x",
        "-9",
        "--spacing",
        "3",
    ];
    let run = |extra: &[&str]| {
        let mut args = vec!["render"];
        args.extend(region);
        args.extend(extra);
        surftile(dir.path(), &args)
    };
    let (code, err) = run(&["--out", "h.exr", "--normal-map", "n.exr"]);
    assert_eq!(code, 0, "{err}");
    let (code, err) = run(&[
        "--out",
        "h.npy",
        "--normal-map",
        "n.png",
        "--normal-convention",
        "dx",
    ]);
    assert_eq!(code, 0, "{err}");
    let read = |p: &str| read_image(&dir.path().join(p), &ReadOptions::default()).unwrap();
    let (exr, npy) = (read("h.exr"), read("h.npy"));
    assert!(
        exr.raster
            .data
            .iter()
            .zip(&npy.raster.data)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    );
    assert_eq!(exr.spacing_um, Some(3.0));
    let normals = read("n.exr");
    assert_eq!(
        (
            normals.raster.width,
            normals.raster.height,
            normals.raster.channels
        ),
        (48, 32, 3)
    );
    let inner = normal_map(&npy.raster, 3.0, NormalConvention::Gl).unwrap();
    for y in 0..inner.height {
        for x in 0..inner.width {
            for c in 0..3 {
                let a = normals.raster.get(x + 2, y + 2, c);
                assert_eq!(a.to_bits(), inner.get(x, y, c).to_bits(), "({x}, {y}, {c})");
            }
        }
    }
    // The PNG: components mapped to (v + 1)/2 of 65535, green flipped for DirectX.
    let png = surftile::io::read_unit(&dir.path().join("n.png")).unwrap();
    for (k, (p, e)) in png.data.iter().zip(&normals.raster.data).enumerate() {
        let want = if k % 3 == 1 { -*e } else { *e };
        assert!(
            ((*p as f64) * 2.0 - 1.0 - want as f64).abs() < 3.1e-5,
            "{k}: {p} vs {want}"
        );
    }
    for bad in [
        &["--out", "a.npy", "--normal-map", "n.tif"][..],
        &[
            "--out",
            "b.npy",
            "--normal-map",
            "n2.exr",
            "--imperfect",
            "dust",
        ][..],
    ] {
        let (code, err) = run(bad);
        assert_ne!(code, 0);
        assert!(
            err.contains("normal-map") && err.trim().lines().count() == 1,
            "{err}"
        );
        assert!(!dir.path().join(bad[1]).exists(), "{} was written", bad[1]);
    }
}

/// The one-line error of reading `bytes` as an EXR named `name` (it must fail).
fn exr_error(bytes: &[u8], name: &str) -> String {
    surftile::io::read_image_bytes(
        bytes,
        surftile::io::Format::Exr,
        name,
        &ReadOptions::default(),
    )
    .unwrap_err()
    .to_string()
}

/// EXR fuzz findings, kept in `fuzz/seeds/exr/`, each refused before decoding with a
/// one-line error naming the file:
/// - a single-resolution tiled file whose tile chunk claims resolution level (0, 1), on
///   which the exr crate's debug assertion fired;
/// - another whose tile at the offset table's offset claims level (0, 1), while the
///   chunks in file order claim none (the check first read them in file order, and
///   missed it; a CI fuzz run found it);
/// - a 24 × 16 tiled file whose header claims tiles of 825194048 × 131585 pixels, on
///   which the exr crate took 1.6 GB sizing its buffers by the claimed tile before any
///   pixel was read (the fuzz run's 2 GiB limit stopped it).
#[test]
fn exr_fuzz_findings_are_refused() {
    for (seed, needle) in [
        ("tile-of-another-level.exr", "resolution level (0, 1)"),
        (
            "tile-level-at-the-table-offset.exr",
            "resolution level (0, 1)",
        ),
        ("tile-larger-than-the-image.exr", "825194048×131585"),
    ] {
        let bytes = std::fs::read(common::repo(&format!("fuzz/seeds/exr/{seed}"))).unwrap();
        let e = exr_error(&bytes, "lying.exr");
        assert!(
            e.contains("lying.exr") && e.contains(needle) && !e.contains('\n'),
            "{seed}: {e}"
        );
    }
}

/// An EXR whose header claims a 20000² layer over a few kilobytes is refused in one
/// line before any pixel is decoded.
#[test]
fn exr_claiming_a_huge_layer_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("small.exr");
    let raster = Raster::from_vec(4, 3, 1, vec![0.5; 12]).unwrap();
    write_heights_with(&path, &raster, &WriteMeta::um(Some(1.0))).unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("a dataWindow attribute")
        + key.len()
        + 4;
    // xMax and yMax of the box (xMin, yMin, xMax, yMax as i32).
    bytes[at + 8..at + 12].copy_from_slice(&19_999i32.to_le_bytes());
    bytes[at + 12..at + 16].copy_from_slice(&19_999i32.to_le_bytes());
    let e = exr_error(&bytes, "huge.exr");
    assert!(e.contains("huge.exr") && !e.contains('\n'), "{e}");
}

/// An engine's placement of exported tiles, written from `layout.json` alone (its
/// formulas, reimplemented here, not surftile's code), with the tiles read by the `exr`
/// crate directly.
struct Engine {
    a: i64,
    b: i64,
    c: i64,
    by: String,
    key: u32,
    seed: u32,
    k: u32,
    rhomboid: [i64; 5],
    tiles: Vec<Vec<f32>>,
}

impl Engine {
    fn load(dir: &Path) -> Engine {
        let text = std::fs::read_to_string(dir.join("layout.json")).unwrap();
        let layout: serde_json::Value = serde_json::from_str(&text).unwrap();
        let int = |v: &serde_json::Value| v.as_i64().unwrap();
        let lattice = &layout["lattice"];
        let choice = &layout["choice"];
        let tiles = layout["tiles"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| {
                let path = dir.join(t["file"].as_str().unwrap());
                let image = exr::prelude::read_first_flat_layer_from_file(&path).unwrap();
                let y = &image.layer_data.channel_data.list[0];
                assert_eq!(y.name.to_string(), "Y");
                y.sample_data.values_as_f32().collect()
            })
            .collect();
        let uv = |n: &str, i: usize| choice.get(n).map_or(0, |v| int(&v[i]));
        Engine {
            a: int(&lattice["a"]),
            b: int(&lattice["b"]),
            c: int(&lattice["c"]),
            by: choice["by"].as_str().unwrap().to_string(),
            key: choice.get("key").map_or(0, |k| int(k) as u32),
            seed: int(&choice["seed"]) as u32,
            k: int(&choice["tiles"]) as u32,
            rhomboid: [
                uv("u", 0),
                uv("u", 1),
                uv("v", 0),
                uv("v", 1),
                choice.get("det").map_or(1, int),
            ],
            tiles,
        }
    }

    fn fold(i: i64) -> u32 {
        (i as u32) ^ ((i >> 32) as u32).wrapping_mul(0x9E37_79B9)
    }

    fn pick(h: u32, k: u32) -> u32 {
        ((h >> 16) * k) >> 16
    }

    fn hash_tile(&self, i: i64, j: i64) -> u32 {
        let mut h = Self::fold(i).wrapping_mul(0x9E37_79B1)
            ^ Self::fold(j).wrapping_mul(0x85EB_CA77)
            ^ self.key;
        h ^= h >> 16;
        h = h.wrapping_mul(0x7FEB_352D);
        h ^= h >> 15;
        h = h.wrapping_mul(0x846C_A68B);
        h ^ (h >> 16)
    }

    fn pcg4d(v: [u32; 4]) -> [u32; 4] {
        let [mut x, mut y, mut z, mut w] =
            v.map(|v| v.wrapping_mul(1_664_525).wrapping_add(1_013_904_223));
        for round in 0..2 {
            x = x.wrapping_add(y.wrapping_mul(w));
            y = y.wrapping_add(z.wrapping_mul(x));
            z = z.wrapping_add(x.wrapping_mul(y));
            w = w.wrapping_add(y.wrapping_mul(z));
            if round == 0 {
                [x, y, z, w] = [x ^ (x >> 16), y ^ (y >> 16), z ^ (z >> 16), w ^ (w >> 16)];
            }
        }
        [x, y, z, w]
    }

    /// The texel at integer (x, y).
    fn texel(&self, x: i64, y: i64) -> f32 {
        let j = y.div_euclid(self.c);
        let i = (x - j * self.b).div_euclid(self.a);
        let (lx, ly) = (x - j * self.b - i * self.a, y - j * self.c);
        let tile = match self.by.as_str() {
            "single" => 0,
            "cell" => Self::pick(self.hash_tile(i, j), self.k),
            "rhomboid" => {
                let [u0, u1, v0, v1, det] = self.rhomboid;
                let s = (v1 * x - v0 * y).div_euclid(det);
                let t = (u0 * y - u1 * x).div_euclid(det);
                Self::pick(self.hash_tile(s, t), self.k)
            }
            "wang" => {
                let kc = (self.k as f64).powf(0.25).round() as u32;
                let colour = |i: i64, j: i64, stream: u32| {
                    let h = Self::pcg4d([self.seed, Self::fold(i), Self::fold(j), stream]);
                    Self::pick(h[0], kc)
                };
                let (x0, x1) = (colour(i, j, 1), colour(i + 1, j, 1));
                let (y0, y1) = (colour(i, j, 2), colour(i, j + 1, 2));
                ((x0 * kc + x1) * kc + y0) * kc + y1
            }
            other => panic!("unknown choice {other}"),
        };
        self.tiles[tile as usize][(ly * self.a + lx) as usize]
    }

    /// Bilinear at (x, y), as layout.json's "sampling" says.
    fn sample(&self, x: f64, y: f64) -> f32 {
        let (xf, yf) = (x.floor(), y.floor());
        let (xi, yi) = (xf as i64, yf as i64);
        let (fx, fy) = ((x - xf) as f32, (y - yf) as f32);
        let (t00, t10) = (self.texel(xi, yi), self.texel(xi + 1, yi));
        let (t01, t11) = (self.texel(xi, yi + 1), self.texel(xi + 1, yi + 1));
        let top = t00 + (t10 - t00) * fx;
        let bottom = t01 + (t11 - t01) * fx;
        -0.0 + (top + (bottom - top) * fy)
    }
}

/// `export-tiles` of a rectangular roller bank, an oblique one (rhomboid choice) and a
/// Wang bank: an engine placing the tiles from layout.json alone reproduces `render`'s
/// pixels bit for bit at integer and fractional origins 5·10⁷ px away; the tiles agree
/// wherever they meet (any toroidal tile beside any other, Wang tiles on a shared
/// colour), so the engine's own placements are seamless too; the PNG export decodes to
/// the EXR values within half a level.
#[test]
fn exported_tiles_placed_from_the_json_reproduce_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let pattern = surftile::lattice::periodic_pattern(200, 160, (40, 0), (13, 29));
    surftile::io::write_heights(&d.join("grid.npy"), &pattern, None).unwrap();
    let di6 = common::repo("tiles/di-6.npy");
    let di6 = di6.to_str().unwrap();
    let banks: [(&str, &[&str]); 3] = [
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
    for (name, bake) in banks {
        let bank = format!("{name}.bank");
        let mut args = vec!["bake"];
        args.extend(bake);
        args.extend(["--out", bank.as_str()]);
        let (code, err) = surftile(d, &args);
        assert_eq!(code, 0, "{name}: {err}");
        let out = format!("{name}-tiles");
        let (code, err) = surftile(d, &["export-tiles", &bank, "--out", &out, "--seed", "5"]);
        assert_eq!(code, 0, "{name}: {err}");
        let engine = Engine::load(&d.join(&out));
        let expected_by = ["cell", "rhomboid", "wang"][["rect", "oblique", "wang"]
            .iter()
            .position(|n| *n == name)
            .unwrap()];
        assert_eq!(engine.by, expected_by, "{name}");

        for (x, y) in [(-50_000_000.0, 1234.0), (-49_999_937.25, -77.5)] {
            let (xs, ys) = (format!("{x}"), format!("{y}"));
            let png = format!("{name}.npy");
            let args = [
                "render", &bank, "--seed", "5", "--x", &xs, "--y", &ys, "--w", "211", "--h", "150",
                "--out", &png,
            ];
            let (code, err) = surftile(d, &args);
            assert_eq!(code, 0, "{name}: {err}");
            let render = read_image(&d.join(&png), &ReadOptions::default())
                .unwrap()
                .raster;
            let mut differ = 0;
            for row in 0..render.height {
                for col in 0..render.width {
                    let e = engine.sample(x + col as f64, y + row as f64);
                    differ += (e.to_bits() != render.get(col, row, 0).to_bits()) as usize;
                }
            }
            assert_eq!(differ, 0, "{name} at ({x}, {y}): {differ} pixels differ");
        }

        // Seamless in any arrangement: borders shared as the rule says.
        let (a, c) = (engine.a as usize, engine.c as usize);
        let col = |t: usize, x: usize| -> Vec<u32> {
            (0..c)
                .map(|y| engine.tiles[t][y * a + x].to_bits())
                .collect()
        };
        let row = |t: usize, y: usize| -> Vec<u32> {
            (0..a)
                .map(|x| engine.tiles[t][y * a + x].to_bits())
                .collect()
        };
        let n = engine.tiles.len();
        let kc = (n as f64).powf(0.25).round() as usize;
        // Wang tile index ((x0·K + x1)·K + y0)·K + y1: edge p is digit 3 − p.
        let edge = |t: usize, p: u32| (t / kc.pow(3 - p)) % kc;
        for t in 0..n {
            for u in 0..n {
                let same = |p: u32| match name {
                    "wang" => edge(t, p) == edge(u, p),
                    "rect" => true,
                    _ => false, // oblique: the tiles differ inside their rhomboids
                };
                let what = |side: &str| format!("{name}: tiles {t} and {u}, {side}");
                if same(0) {
                    assert_eq!(col(t, 0), col(u, 0), "{}", what("first column"));
                }
                if same(1) {
                    assert_eq!(col(t, a - 1), col(u, a - 1), "{}", what("last column"));
                }
                if same(2) {
                    assert_eq!(row(t, 0), row(u, 0), "{}", what("first row"));
                }
                if same(3) {
                    assert_eq!(row(t, c - 1), row(u, c - 1), "{}", what("last row"));
                }
            }
        }
    }
}

/// `export-tiles` refuses, in one line and writing nothing: a bank of another rule
/// (naming those it takes), a source that is not a bank, an output path that is a file
/// or a directory with files, and an unknown `--format`. The PNG export decodes with
/// layout.json's offset and scale to the EXR tiles within half a level (0.51).
#[test]
fn export_tiles_refuses_bad_input_and_its_png_decodes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let di6 = common::repo("tiles/di-6.npy");
    let di6 = di6.to_str().unwrap();
    for (bank, method) in [("blend.bank", "rpn"), ("wang.bank", "quilt")] {
        let (code, err) = surftile(d, &["bake", di6, "--method", method, "--out", bank]);
        assert_eq!(code, 0, "{err}");
    }
    std::fs::write(d.join("a-file"), b"keep").unwrap();
    std::fs::create_dir(d.join("full")).unwrap();
    std::fs::write(d.join("full/x"), b"keep").unwrap();
    let cases: [(&[&str], &str); 6] = [
        (
            &["blend.bank", "--out", "t1"],
            "takes toroidal (roller) and Wang (quilt) banks",
        ),
        (&["parallel-d4-ae05", "--out", "t2"], "not a bank"),
        (&["wang.bank", "--out", "a-file"], "existing file"),
        (&["wang.bank", "--out", "full"], "new or empty directory"),
        (&["wang.bank", "--out", "t3", "--format", "bmp"], "exr, png"),
        (&["missing.bank", "--out", "t4"], "missing.bank"),
    ];
    for (args, expect) in cases {
        let mut all = vec!["export-tiles"];
        all.extend(args);
        let (code, err) = surftile(d, &all);
        assert_ne!(code, 0, "{args:?}");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
    }
    assert_eq!(std::fs::read(d.join("a-file")).unwrap(), b"keep");
    assert_eq!(std::fs::read_dir(d.join("full")).unwrap().count(), 1);
    let mut left: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["a-file", "blend.bank", "full", "wang.bank"]);

    // An empty directory is fine; PNG levels decode to the EXR values.
    std::fs::create_dir(d.join("png")).unwrap();
    for (out, format) in [("png", "png"), ("exr", "exr")] {
        let (code, err) = surftile(
            d,
            &[
                "export-tiles",
                "wang.bank",
                "--out",
                out,
                "--format",
                format,
            ],
        );
        assert_eq!(code, 0, "{err}");
    }
    let layout: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("png/layout.json")).unwrap()).unwrap();
    let (offset, scale) = (
        layout["png"]["offset"].as_f64().unwrap(),
        layout["png"]["scale"].as_f64().unwrap(),
    );
    assert!(scale > 0.0);
    let mut worst = 0.0f64;
    for t in layout["tiles"].as_array().unwrap() {
        let file = t["file"].as_str().unwrap();
        let levels = surftile::io::read_unit(&d.join("png").join(file)).unwrap();
        let exact =
            Engine::load(&d.join("exr")).tiles[t["index"].as_u64().unwrap() as usize].clone();
        for (l, e) in levels.data.iter().zip(&exact) {
            let decoded = offset + scale * (*l as f64 * 65535.0).round();
            worst = worst.max((decoded - *e as f64).abs() / scale);
        }
    }
    // Half a level, plus the f32 rounding of v − offset before it is scaled.
    assert!(worst <= 0.51, "PNG decodes within {worst} levels");
}
