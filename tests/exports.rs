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
    let e = surftile::io::read_image_bytes(
        &bytes,
        surftile::io::Format::Exr,
        "huge.exr",
        &ReadOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("huge.exr") && !e.contains('\n'), "{e}");
}
