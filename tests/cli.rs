//! The CLI binary: happy paths and every bad input of issue 2's acceptance list. Each bad
//! input must give exactly one error line, a non-zero exit, no panic, and leave no
//! output file (nor temporary file) behind.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use surftile::Raster;
use surftile::bank::Bank;
use surftile::io::write_heights;
use surftile::stream::{BlendSurface, Surface};

struct Run {
    code: i32,
    stdout: String,
    stderr: String,
}

fn surftile(dir: &Path, args: &[&str]) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_surftile"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run surftile");
    Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn exemplar() -> String {
    common::repo("tiles/di-6.npy").display().to_string()
}

/// `surftile render BANK --x 0 --y 0 --w W --h H --out OUT EXTRA…`
fn render(dir: &Path, bank: &str, (w, h): (&str, &str), out: &str, extra: &[&str]) -> Run {
    let mut args = vec![
        "render", bank, "--x", "0", "--y", "0", "--w", w, "--h", h, "--out", out,
    ];
    args.extend_from_slice(extra);
    surftile(dir, &args)
}

/// Bakes the bundled exemplar into `dir/good.bank` through the CLI.
fn bake_good(dir: &Path) -> PathBuf {
    let r = surftile(
        dir,
        &[
            "bake",
            &exemplar(),
            "--method",
            "rpn",
            "--out",
            "good.bank",
            "--seed",
            "3",
            "--bank-size",
            "4",
        ],
    );
    assert_eq!(r.code, 0, "bake failed: {}", r.stderr);
    dir.join("good.bank")
}

/// The bad-input contract: one line, non-zero, no panic, nothing left behind.
fn assert_clean_failure(dir: &Path, r: &Run, expect_in_message: &str, output: &str) {
    assert_ne!(r.code, 0, "expected failure, stderr: {}", r.stderr);
    assert!(!r.stderr.contains("panicked"), "panic: {}", r.stderr);
    let lines: Vec<&str> = r.stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "expected one error line, got: {:?}", lines);
    assert!(lines[0].starts_with("error: "), "{}", lines[0]);
    assert!(
        lines[0]
            .to_lowercase()
            .contains(&expect_in_message.to_lowercase()),
        "message {:?} lacks {expect_in_message:?}",
        lines[0]
    );
    assert!(!dir.join(output).exists(), "{output} was left behind");
    let leftovers: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".part-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

#[test]
fn truncated_bank_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = bake_good(dir.path());
    let bytes = std::fs::read(&good).unwrap();
    std::fs::write(dir.path().join("cut.bank"), &bytes[..bytes.len() / 2]).unwrap();
    let r = render(dir.path(), "cut.bank", ("16", "16"), "o.png", &[]);
    assert_clean_failure(dir.path(), &r, "bank cut.bank", "o.png");
}

#[test]
fn bank_with_one_flipped_byte_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = bake_good(dir.path());
    let mut bytes = std::fs::read(&good).unwrap();
    let at = bytes.len() * 2 / 3;
    bytes[at] ^= 0x10;
    std::fs::write(dir.path().join("flip.bank"), &bytes).unwrap();
    let r = surftile(dir.path(), &["sample", "flip.bank", "1", "2"]);
    assert_clean_failure(dir.path(), &r, "checksum", "none");
    let r = render(dir.path(), "flip.bank", ("8", "8"), "o.npy", &[]);
    assert_clean_failure(dir.path(), &r, "checksum", "o.npy");
}

#[test]
fn empty_png_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("empty.png"), b"").unwrap();
    let r = surftile(dir.path(), &["bake", "empty.png", "--out", "b.bank"]);
    assert_clean_failure(dir.path(), &r, "empty.png", "b.bank");
    // A PNG signature with nothing after it is no better.
    std::fs::write(dir.path().join("sig.png"), b"\x89PNG\r\n\x1a\n").unwrap();
    let r = surftile(dir.path(), &["bake", "sig.png", "--out", "b.bank"]);
    assert_clean_failure(dir.path(), &r, "not a valid PNG", "b.bank");
}

#[test]
fn one_pixel_image_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let one = Raster::from_vec(1, 1, 1, vec![0.5]).unwrap();
    write_heights(&dir.path().join("one.png"), &one, None).unwrap();
    let r = surftile(dir.path(), &["bake", "one.png", "--out", "b.bank"]);
    assert_clean_failure(dir.path(), &r, "1×1", "b.bank");
}

#[test]
fn nan_npy_without_fill_missing_is_refused_and_filled_with_it() {
    let dir = tempfile::tempdir().unwrap();
    let mut data: Vec<f32> = (0..64 * 64)
        .map(|i| ((i * 7919) % 101) as f32 * 0.01)
        .collect();
    data[100] = f32::NAN;
    data[2000] = f32::NAN;
    // write_heights refuses NaN, so write the .npy by hand: header then f32 data.
    let header = "{'descr': '<f4', 'fortran_order': False, 'shape': (64, 64), }";
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    let pad = 64 - (10 + header.len() + 1) % 64;
    let full = format!("{header}{}\n", " ".repeat(pad));
    bytes.extend_from_slice(&(full.len() as u16).to_le_bytes());
    bytes.extend_from_slice(full.as_bytes());
    for v in &data {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(dir.path().join("holes.npy"), &bytes).unwrap();
    let r = surftile(dir.path(), &["bake", "holes.npy", "--out", "b.bank"]);
    assert_clean_failure(
        dir.path(),
        &r,
        "2 of 4096 height points are missing",
        "b.bank",
    );
    let r = surftile(
        dir.path(),
        &["bake", "holes.npy", "--out", "b.bank", "--fill-missing"],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(dir.path().join("b.bank").exists());
}

#[test]
fn zero_and_negative_sizes_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    bake_good(dir.path());
    for (w, h, msg) in [
        ("0", "8", "invalid w = 0"),
        ("-5", "8", "invalid w = -5"),
        ("8", "-1", "invalid h = -1"),
    ] {
        let r = render(dir.path(), "good.bank", (w, h), "o.png", &[]);
        assert_clean_failure(dir.path(), &r, msg, "o.png");
    }
    let r = render(
        dir.path(),
        "good.bank",
        ("8", "8"),
        "o.png",
        &["--step", "-2"],
    );
    assert_clean_failure(dir.path(), &r, "invalid step", "o.png");
    let r = render(dir.path(), "good.bank", ("100000", "100000"), "o.png", &[]);
    assert_clean_failure(dir.path(), &r, "too large", "o.png");
    let r = surftile(dir.path(), &["sample", "good.bank", "NaN", "0"]);
    assert_clean_failure(dir.path(), &r, "invalid x", "none");
}

#[test]
fn unknown_method_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let r = surftile(
        dir.path(),
        &["bake", &exemplar(), "--method", "magic", "--out", "b.bank"],
    );
    assert_clean_failure(dir.path(), &r, "expected one of: rpn, adsn", "b.bank");
}

/// A missing argument is named on the error line (clap puts the names on the lines
/// below its first, which a one-line error used to drop), with the subcommand's help to
/// open; `render` starts at the origin when --x and --y are left out.
#[test]
fn missing_arguments_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let r = surftile(
        dir.path(),
        &["render", "rock", "--w", "8", "--out", "o.tif"],
    );
    assert_clean_failure(dir.path(), &r, "missing argument: --h <H>", "o.tif");
    assert!(
        r.stderr.contains("see 'surftile render --help'"),
        "{}",
        r.stderr
    );
    let r = surftile(dir.path(), &["stats"]);
    assert_clean_failure(dir.path(), &r, "missing argument: <A>", "none");
    let r = surftile(dir.path(), &["convert"]);
    assert_clean_failure(
        dir.path(),
        &r,
        "missing arguments: <INPUT>, <OUTPUT>",
        "none",
    );
    let r = surftile(dir.path(), &["bake", "--out", "b.bank"]);
    assert_clean_failure(dir.path(), &r, "missing argument: <EXEMPLAR>", "b.bank");
    // Negative numbers reach the argument's own check, or are named as not whole.
    let sandblast = |out: &str, extra: &[&str]| {
        let mut args = vec!["sandblast", "x.npy", "--w", "8", "--h", "8", "--out", out];
        args.extend_from_slice(extra);
        surftile(dir.path(), &args)
    };
    let r = sandblast("o.tif", &["--spacing", "-1"]);
    assert_clean_failure(dir.path(), &r, "invalid spacing = -1", "o.tif");
    let r = sandblast("o.tif", &["--patch", "-64"]);
    assert_clean_failure(
        dir.path(),
        &r,
        "'-64' for '--patch <PATCH>': expected a whole number",
        "o.tif",
    );
    // The output's format is checked before the measurement is even read.
    let r = sandblast("o.bmp", &[]);
    assert_clean_failure(dir.path(), &r, "unknown image extension 'bmp'", "o.bmp");
    let r = sandblast("o.tif", &["--spacing", "abc"]);
    assert_clean_failure(
        dir.path(),
        &r,
        "'abc' for '--spacing <SPACING>': expected a number",
        "o.tif",
    );

    let origin = |args: &[&str], out: &str| {
        let r = surftile(dir.path(), args);
        assert_eq!(r.code, 0, "{}", r.stderr);
        surftile::io::read_image(&dir.path().join(out), &Default::default())
            .unwrap()
            .raster
            .data
    };
    let left_out = origin(
        &["render", "rock", "--w", "8", "--h", "8", "--out", "a.tif"],
        "a.tif",
    );
    let given = origin(
        &[
            "render", "rock", "--x", "0", "--y", "0", "--w", "8", "--h", "8", "--out", "b.tif",
        ],
        "b.tif",
    );
    assert_eq!(left_out, given);
    let moved = origin(
        &[
            "render", "rock", "--x", "3", "--y", "0", "--w", "8", "--h", "8", "--out", "c.tif",
        ],
        "c.tif",
    );
    assert_ne!(
        left_out, moved,
        "the test cannot tell the origin from elsewhere"
    );
}

#[test]
fn missing_file_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let r = surftile(dir.path(), &["bake", "nowhere.png", "--out", "b.bank"]);
    assert_clean_failure(dir.path(), &r, "nowhere.png", "b.bank");
    let r = render(dir.path(), "nowhere.bank", ("8", "8"), "o.png", &[]);
    assert_clean_failure(dir.path(), &r, "nowhere.bank", "o.png");
    // A file name (it has a dot; no preset has) is reported as missing, not as an
    // unknown preset.
    assert!(
        r.stderr
            .contains("nowhere.bank: no such file, and not a preset name"),
        "{}",
        r.stderr
    );
}

#[test]
fn info_describes_presets_and_configurations() {
    let dir = tempfile::tempdir().unwrap();
    let json = |args: &[&str]| -> serde_json::Value {
        let r = surftile(dir.path(), args);
        assert_eq!(r.code, 0, "{}", r.stderr);
        serde_json::from_str(&r.stdout).unwrap()
    };
    let milling = json(&["info", "parallel-d4-ae05", "--json", "--spacing", "3.5"]);
    assert_eq!(
        milling,
        serde_json::json!({"kind": "milling", "spacing_um": 3.5, "height_unit": "um"})
    );
    let model = json(&["info", "rock", "--json"]);
    assert_eq!(
        model,
        serde_json::json!({"kind": "models", "spacing_um": null, "height_unit": ""})
    );
    let r = surftile(dir.path(), &["info", "rock"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stdout.contains("kind        models"), "{}", r.stdout);
}

#[test]
fn bake_info_render_sample_and_stats_work_together() {
    let dir = tempfile::tempdir().unwrap();
    let bank_path = bake_good(dir.path());
    let r = surftile(dir.path(), &["info", "good.bank", "--json"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let info: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(info["rule"], "blend");
    assert_eq!(info["method"], "rpn");
    assert_eq!(info["channels"], 1);
    assert_eq!(info["tiles"], 4);
    assert_eq!(info["tile_size"], serde_json::json!([256, 256]));
    assert_eq!(info["seed"], 3);
    assert_eq!(info["lattice"][0], serde_json::json!([128.0, 0.0]));
    assert!(info["spacing_um"].is_null(), "a bare .npy has no spacing");

    // sample prints what the library computes.
    let r = surftile(
        dir.path(),
        &["sample", "good.bank", "-1234.5", "99.25", "--seed", "9"],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let printed: f32 = r.stdout.trim().parse().unwrap();
    let bank = Bank::read(&bank_path).unwrap();
    let expected = BlendSurface::new(&bank, 9).unwrap().height(-1234.5, 99.25);
    assert_eq!(printed, expected);

    // render to each format; .npy holds the library's samples exactly.
    for out in ["r.png", "r.tiff", "r.npy"] {
        let r = surftile(
            dir.path(),
            &[
                "render",
                "good.bank",
                "--x",
                "-10",
                "--y",
                "5",
                "--w",
                "64",
                "--h",
                "48",
                "--out",
                out,
            ],
        );
        assert_eq!(r.code, 0, "{out}: {}", r.stderr);
    }
    let npy = surftile::io::read_image(&dir.path().join("r.npy"), &Default::default())
        .unwrap()
        .raster;
    assert_eq!((npy.width, npy.height), (64, 48));
    let s = BlendSurface::new(&bank, 0).unwrap();
    assert_eq!(npy.get(3, 2, 0), s.height(-7.0, 7.0));
    let r = render(dir.path(), "good.bank", ("32", "32"), "s.png", &["--shade"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let r = render(dir.path(), "good.bank", ("32", "32"), "s.npy", &["--shade"]);
    assert_clean_failure(dir.path(), &r, "with --shade", "s.npy");

    let r = surftile(dir.path(), &["stats", &exemplar(), "r.npy", "--cell", "16"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let stats: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    for key in ["w1", "psd_error", "seam_score"] {
        assert!(stats[key].as_f64().is_some(), "{key} missing in {stats}");
    }
    assert!(stats["a"]["sal"].as_f64().unwrap() > 0.0);
    // The seam search at any offset comes with its floor on the output's own content,
    // measured on the same figure.
    let (seams, floor) = (
        &stats["structure"]["seams"],
        &stats["structure"]["seam_noise"],
    );
    let (worst, observed) = (seams["worst"].as_f64(), floor["observed"].as_f64());
    assert!(
        matches!((worst, observed), (Some(a), Some(b)) if (a / b - 1.0).abs() < 1e-9),
        "{stats}"
    );
    for key in ["median", "in_bar", "p_value"] {
        assert!(floor[key].as_f64().is_some(), "{key} missing in {floor}");
    }
    // Beside the PSD error, what the exemplar's own content reads shown evenly.
    assert!(
        stats["psd_error_even"].as_f64().is_some_and(|e| e >= 0.0),
        "{stats}"
    );

    // Inputs the figures cannot be measured on: one clear line each, no JSON.
    let raster = |w: usize, h: usize, f: fn(usize) -> f32| {
        surftile::Raster::from_vec(w, h, 1, (0..w * h).map(f).collect()).unwrap()
    };
    let write = |name: &str, r: &surftile::Raster| {
        surftile::io::write_heights(&dir.path().join(name), r, None).unwrap()
    };
    write("tiny.npy", &raster(4, 4, |i| i as f32));
    write("flat.npy", &raster(32, 32, |_| 1.5));
    // The writers refuse infinite heights, so this one is raw f32.
    let inf: Vec<u8> = (0..32 * 32)
        .flat_map(|i| if i == 40 { f32::INFINITY } else { i as f32 }.to_le_bytes())
        .collect();
    std::fs::write(dir.path().join("inf.f32"), inf).unwrap();
    for (a, b, message) in [
        ("tiny.npy", "r.npy", "at least 8×8"),
        ("r.npy", "tiny.npy", "at least 8×8"),
        ("flat.npy", "r.npy", "A is flat"),
        ("inf.f32", "r.npy", "infinite values"),
        ("r.npy", "inf.f32", "infinite values"),
    ] {
        let r = surftile(dir.path(), &["stats", a, b, "--raw-shape", "32x32"]);
        assert_clean_failure(dir.path(), &r, message, "none");
        assert!(r.stdout.is_empty(), "{a} {b}: {}", r.stdout);
    }
}

#[test]
fn demo_writes_the_gallery() {
    let dir = tempfile::tempdir().unwrap();
    let r = surftile(dir.path(), &["demo"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    for f in [
        "di-6.bank",
        "exemplar.png",
        "height-origin.png",
        "height-far.png",
        "height-zoom8.png",
        "shaded.png",
        "stats.json",
        "x3p-2-roller.bank",
        "roller-exemplar.png",
        "roller-height.png",
        "x3p-2-rsgf.bank",
        "rsgf-height.png",
        "gravel.bank",
        "gravel-synthesis.png",
        "gravel-structure.json",
        "milling-parallel.bank",
        "milling-parallel.png",
        "milling-parallel-shaded.png",
        "milling-spiral-shaded.png",
        "rugged-rock.png",
        "rugged-china.png",
        "rugged-casting.png",
        "rugged-cells-convex.png",
        "rugged-cells-concave.png",
        "imperfect-peeling.png",
        "imperfect-peeling-mask.png",
        "imperfect-dust.png",
        "imperfect-dust-mask.png",
    ] {
        let p = dir.path().join("surftile-demo").join(f);
        assert!(
            p.metadata().map(|m| m.len() > 0).unwrap_or(false),
            "{f} missing"
        );
        assert!(r.stdout.contains(f), "demo output does not mention {f}");
    }
    let stats: serde_json::Value = serde_json::from_slice(
        &std::fs::read(dir.path().join("surftile-demo/stats.json")).unwrap(),
    )
    .unwrap();
    assert!(stats["w1"].as_f64().unwrap() < 0.05, "{stats}");
    // The photo: auto takes RSGF, and the synthesis meets issue 31's bars on
    // repetition (self-repetition ≤ 0.15, copy score ≤ 0.3) and stays far closer to
    // the photo's patches than random phases (coherence 0.203 on the top-left 512², in
    // docs/structure.md; RPN noise reads about 1 or more).
    assert!(
        r.stdout.contains("method auto: ") && r.stdout.contains("rsgf --stochastic"),
        "{}",
        r.stdout
    );
    let figures: serde_json::Value = serde_json::from_slice(
        &std::fs::read(dir.path().join("surftile-demo/gravel-structure.json")).unwrap(),
    )
    .unwrap();
    let figure = |k: &str| figures[k].as_f64().unwrap();
    assert!(figure("coherence") < 0.5, "{figures}");
    assert!(figure("self_repetition") <= 0.15, "{figures}");
    assert!(figure("copy_score") <= 0.3, "{figures}");
}

/// `surftile mill` renders a preset; `bake --method milling` writes a bank that
/// `render` and `info` read; bad configurations and flags give one line and no file.
#[test]
fn mill_and_milling_banks_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let r = surftile(
        dir.path(),
        &[
            "mill",
            "spiral-d8-ae02",
            "--x",
            "-64",
            "--y",
            "-64",
            "--w",
            "128",
            "--h",
            "96",
            "--spacing",
            "20",
            "--out",
            "s.npy",
        ],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let npy = std::fs::read(dir.path().join("s.npy")).unwrap();
    assert!(npy.len() > 128 * 96 * 4);
    let r = surftile(
        dir.path(),
        &[
            "bake",
            "parallel-d4-ae08",
            "--method",
            "milling",
            "--spacing",
            "6.1",
            "--out",
            "m.bank",
        ],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let r = surftile(dir.path(), &["info", "m.bank"]);
    assert!(
        r.stdout.contains("milling: Parallel path, d = 4 mm"),
        "{}",
        r.stdout
    );
    let r = surftile(
        dir.path(),
        &[
            "render", "m.bank", "--x", "0", "--y", "0", "--w", "64", "--h", "64", "--out", "m.png",
        ],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    std::fs::write(dir.path().join("bad.toml"), "[path]\noverlap = 1.2\n").unwrap();
    for (args, expect) in [
        (
            vec![
                "mill",
                "bad.toml",
                "--x",
                "0",
                "--y",
                "0",
                "--w",
                "8",
                "--h",
                "8",
                "--spacing",
                "5",
                "--out",
                "b.png",
            ],
            "path.overlap",
        ),
        (
            vec![
                "mill",
                "no-such-preset",
                "--x",
                "0",
                "--y",
                "0",
                "--w",
                "8",
                "--h",
                "8",
                "--spacing",
                "5",
                "--out",
                "b.png",
            ],
            "preset name",
        ),
        (
            vec![
                "mill",
                "parallel-d4-ae05",
                "--x",
                "0",
                "--y",
                "0",
                "--w",
                "8",
                "--h",
                "8",
                "--spacing",
                "-5",
                "--out",
                "b.png",
            ],
            "spacing",
        ),
        (
            vec![
                "bake",
                "parallel-d4-ae05",
                "--method",
                "milling",
                "--out",
                "b.bank",
            ],
            "spacing",
        ),
    ] {
        let r = surftile(dir.path(), &args);
        assert_ne!(r.code, 0, "{args:?}");
        assert!(r.stderr.contains(expect), "{args:?}: {}", r.stderr);
        assert_eq!(r.stderr.trim().lines().count(), 1, "{}", r.stderr);
    }
    assert!(!dir.path().join("b.png").exists() && !dir.path().join("b.bank").exists());
}

/// Issue 3's bad roller input: `--tiles 0`, a collinear `--lattice`, and a tile plus
/// overlap larger than the exemplar each give one clear line and no bank.
#[test]
fn bad_roller_parameters_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let ex = exemplar();
    let bake = |extra: &[&str]| {
        let mut args = vec!["bake", ex.as_str(), "--method", "roller", "--out", "r.bank"];
        args.extend_from_slice(extra);
        surftile(dir.path(), &args)
    };
    let r = bake(&["--tiles", "0"]);
    assert_clean_failure(dir.path(), &r, "1 to 64 tiles", "r.bank");
    let r = bake(&["--lattice", "4,6;-2,-3"]);
    assert_clean_failure(dir.path(), &r, "not collinear", "r.bank");
    let r = bake(&["--lattice", "4,6"]);
    assert_clean_failure(dir.path(), &r, "ux,uy;vx,vy", "r.bank");
    let r = bake(&["--tile", "500x500"]);
    assert_clean_failure(dir.path(), &r, "needs", "r.bank");
    let r = bake(&["--tile", "200x200", "--tiles", "64"]);
    assert_clean_failure(dir.path(), &r, "64 tiles", "r.bank");
    // The flags belong to the roller only.
    let r = surftile(
        dir.path(),
        &["bake", ex.as_str(), "--tiles", "4", "--out", "r.bank"],
    );
    assert_clean_failure(dir.path(), &r, "roller", "r.bank");
}

/// Issue 5's `surftile lattice`: the JSON names a basis of the synthetic lattice
/// (40, 0)/(13, 29) it was drawn on, `--plot` writes the autocorrelation, and a texture
/// without a lattice fails cleanly, suggesting `--stochastic` or `--lattice`.
#[test]
fn lattice_estimation_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let (u, v) = ((40i64, 0i64), (13i64, 29i64));
    let image = surftile::lattice::periodic_pattern(200, 160, u, v);
    surftile::io::write_heights(&dir.path().join("grid.npy"), &image, None).unwrap();
    let r = surftile(
        dir.path(),
        &["lattice", "grid.npy", "--json", "--plot", "acf.png"],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let j: serde_json::Value = serde_json::from_str(r.stdout.trim()).unwrap();
    let vec = |k: &str| (j[k][0].as_i64().unwrap(), j[k][1].as_i64().unwrap());
    let (a, b) = (vec("v1"), vec("v2"));
    assert!(j["goodness"].as_f64().unwrap() > 0.0);
    assert!(
        surftile::lattice::same_lattice(u, v, a, b),
        "found {a:?}/{b:?}"
    );
    let plot = std::fs::read(dir.path().join("acf.png")).unwrap();
    assert_eq!(&plot[1..4], b"PNG");
    // A true lattice dips between its points: no ridge note.
    assert!(!r.stderr.contains("note:"), "{}", r.stderr);

    let mut state = 7u64;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    // Stripes 12 px apart, with a faint ripple every 20 px along them and noise: γ is a
    // ridge along x with faint bumps, the estimator takes a step along it, and the step
    // is noted as not a measured repetition.
    let stripes: Vec<f32> = (0..160 * 200)
        .map(|i| {
            let (x, y) = ((i % 200) as f32, (i / 200) as f32);
            (std::f32::consts::TAU * y / 12.0).sin()
                + 0.1 * (std::f32::consts::TAU * x / 20.0).sin()
                + 0.1 * uniform()
        })
        .collect();
    let stripes = surftile::Raster::from_vec(200, 160, 1, stripes).unwrap();
    surftile::io::write_heights(&dir.path().join("stripes.npy"), &stripes, None).unwrap();
    let r = surftile(dir.path(), &["lattice", "stripes.npy", "--json"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let j: serde_json::Value = serde_json::from_str(r.stdout.trim()).unwrap();
    let along = ["v1", "v2"]
        .into_iter()
        .find(|k| j[*k][1].as_i64() == Some(0))
        .unwrap_or_else(|| panic!("no vector along the stripes: {j}"));
    assert!(
        r.stderr
            .contains(&format!("does not dip on the way to {along} = ")),
        "{along} of {j}: {}",
        r.stderr
    );

    let noise: Vec<f32> = (0..96 * 96).map(|_| uniform()).collect();
    let noise = surftile::Raster::from_vec(96, 96, 1, noise).unwrap();
    surftile::io::write_heights(&dir.path().join("noise.npy"), &noise, None).unwrap();
    let r = surftile(dir.path(), &["lattice", "noise.npy", "--plot", "none.png"]);
    // `lattice` has no --stochastic of its own: the advice names the bake that does.
    assert_clean_failure(
        dir.path(),
        &r,
        "bake it with --method rsgf and --stochastic",
        "none.png",
    );
    assert!(r.stderr.contains("--lattice"), "{}", r.stderr);
}

/// `bake --method rsgf` estimates the lattice, `info` shows it, `render` streams the
/// surface; bad parameters and a texture without a lattice give one line and no bank.
#[test]
fn rsgf_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let (u, v) = ((23i64, 0i64), (9i64, 19i64));
    let image = surftile::lattice::periodic_pattern(128, 128, u, v);
    surftile::io::write_heights(&dir.path().join("grid.npy"), &image, None).unwrap();
    let r = surftile(
        dir.path(),
        &["bake", "grid.npy", "--method", "rsgf", "--out", "grid.bank"],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stderr.contains("lattice estimated"), "{}", r.stderr);
    assert!(!r.stderr.contains("note:"), "{}", r.stderr);
    // A ridged measurement: the estimated v2 runs along the ridges, and the bake says so.
    let r = surftile(
        dir.path(),
        &[
            "bake",
            &common::repo("tiles/x3p-2-crop.npy").display().to_string(),
            "--method",
            "rsgf",
            "--out",
            "ridges.bank",
        ],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        r.stderr.contains("does not dip on the way to v2"),
        "{}",
        r.stderr
    );
    let r = surftile(dir.path(), &["info", "grid.bank"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        r.stdout.contains("rsgf on lattice") && r.stdout.contains("blocks of 40 px"),
        "{}",
        r.stdout
    );
    let r = surftile(
        dir.path(),
        &[
            "render",
            "grid.bank",
            "--x",
            "-50",
            "--y",
            "7",
            "--w",
            "200",
            "--h",
            "150",
            "--out",
            "grid.npy.out.npy",
        ],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let out = surftile::io::read_image(&dir.path().join("grid.npy.out.npy"), &Default::default())
        .unwrap();
    assert_eq!((out.raster.width, out.raster.height), (200, 150));

    for (args, needle) in [
        (vec!["--block", "200"], "block"),
        (vec!["--border", "20"], "half the block"),
        (
            vec!["--block", "100", "--border", "20"],
            "block + 2 × border",
        ),
        (vec!["--stochastic", "--lattice", "23,0;9,19"], "stochastic"),
    ] {
        let mut all = vec!["bake", "grid.npy", "--method", "rsgf", "--out", "bad.bank"];
        all.extend(args);
        let r = surftile(dir.path(), &all);
        assert_clean_failure(dir.path(), &r, needle, "bad.bank");
    }
    let r = surftile(
        dir.path(),
        &["bake", "grid.npy", "--stochastic", "--out", "bad.bank"],
    );
    assert_clean_failure(dir.path(), &r, "rsgf when", "bad.bank");

    let noise = surftile::io::read_image(&common::repo("tests/data/ps-1.npy"), &Default::default())
        .unwrap()
        .raster
        .crop(0, 0, 128, 128)
        .unwrap();
    surftile::io::write_heights(&dir.path().join("noise.npy"), &noise, None).unwrap();
    let r = surftile(
        dir.path(),
        &["bake", "noise.npy", "--method", "rsgf", "--out", "bad.bank"],
    );
    assert_clean_failure(dir.path(), &r, "no lattice", "bad.bank");
    assert!(
        r.stderr.contains("--stochastic") && r.stderr.contains("--lattice"),
        "{}",
        r.stderr
    );
    let r = surftile(
        dir.path(),
        &[
            "bake",
            "noise.npy",
            "--method",
            "rsgf",
            "--stochastic",
            "--out",
            "noise.bank",
        ],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
}

/// The seed 001 presets render from the command line exactly as the library draws them:
/// heights bit for bit, the shaded PNG byte for byte (with each preset's material), and
/// `sample` prints the same height.
#[test]
fn model_presets_render_and_shade_as_the_library_does() {
    use surftile::models::rugged::ModelConfig;
    use surftile::shade::{shade, shade_slopes};
    use surftile::stream::Region;
    let dir = tempfile::tempdir().unwrap();
    let args = |name: &str, out: &str, extra: &[&str]| {
        let mut a: Vec<String> = [
            "render", name, "--x", "-37", "--y", "11", "--w", "64", "--h", "48", "--seed", "5",
            "--out", out,
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    for name in ModelConfig::preset_names() {
        let model = ModelConfig::preset(name).unwrap();
        let surface = model.surface(5).unwrap();
        let a = args(name, "h.npy", &[]);
        let r = surftile(
            dir.path(),
            &a.iter().map(|s| s.as_str()).collect::<Vec<_>>(),
        );
        assert_eq!(r.code, 0, "{name}: {}", r.stderr);
        let got = surftile::io::read_image(&dir.path().join("h.npy"), &Default::default())
            .unwrap()
            .raster;
        let mut want = vec![0.0f32; 64 * 48];
        surface
            .fill(&Region::new(-37.0, 11.0, 64, 48), &mut want)
            .unwrap();
        assert_eq!((got.width, got.height), (64, 48));
        assert!(
            got.data
                .iter()
                .zip(&want)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{name}: the CLI's heights differ from the library's"
        );

        let a = args(name, "s.png", &["--shade"]);
        let r = surftile(
            dir.path(),
            &a.iter().map(|s| s.as_str()).collect::<Vec<_>>(),
        );
        assert_eq!(r.code, 0, "{name}: {}", r.stderr);
        let (pw, ph, colour, png) = common::png8(&dir.path().join("s.png"));
        assert_eq!((pw, ph, colour), (64, 48, png::ColorType::Grayscale));
        // Normals from the model's analytic gradient where it has one (the region
        // divisions), else from central differences of the heights.
        let want = if surface.gradient(0.0, 0.0).is_some() {
            let slopes: Vec<[f32; 2]> = (0..64 * 48)
                .map(|i| {
                    let g = surface
                        .gradient(-37.0 + (i % 64) as f64, 11.0 + (i / 64) as f64)
                        .unwrap();
                    [g[0] as f32, g[1] as f32]
                })
                .collect();
            shade_slopes(&slopes, &model.material())
        } else {
            let mut margin = vec![0.0f32; 66 * 50];
            surface
                .fill(&Region::new(-38.0, 10.0, 66, 50), &mut margin)
                .unwrap();
            shade(
                &Raster::from_vec(66, 50, 1, margin).unwrap(),
                &model.material(),
            )
        };
        assert_eq!(
            png, want,
            "{name}: the shaded PNG is not the library's shading with the {} material",
            model.material
        );

        let r = surftile(dir.path(), &["sample", name, "3.5", "-1e9", "--seed", "5"]);
        assert_eq!(r.code, 0, "{name}: {}", r.stderr);
        let printed: f32 = r.stdout.trim().parse().unwrap();
        assert_eq!(printed, surface.height(3.5, -1e9), "{name}");
    }
    // Materials differ: the same heights shaded as china (no specular) and casting (no
    // diffuse) are not the same image.
    let mut images = Vec::new();
    for m in ["china", "casting"] {
        let a = args("rock", "m.png", &["--shade", "--material", m]);
        let r = surftile(
            dir.path(),
            &a.iter().map(|s| s.as_str()).collect::<Vec<_>>(),
        );
        assert_eq!(r.code, 0, "{}", r.stderr);
        images.push(std::fs::read(dir.path().join("m.png")).unwrap());
    }
    assert_ne!(images[0], images[1]);
    // An explicit exaggeration is per surface pixel: at step 2, slopes per sample are
    // twice as steep, so the shading uses half the factor per sample.
    let a = args(
        "rock",
        "e.png",
        &["--shade", "--exaggeration", "3", "--step", "2"],
    );
    let r = surftile(
        dir.path(),
        &a.iter().map(|s| s.as_str()).collect::<Vec<_>>(),
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let (_, _, _, png) = common::png8(&dir.path().join("e.png"));
    let rock = ModelConfig::preset("rock").unwrap();
    let mut margin = vec![0.0f32; 66 * 50];
    let grown = Region::new(-39.0, 9.0, 66, 50).with_step(2.0);
    rock.surface(5).unwrap().fill(&grown, &mut margin).unwrap();
    let want = shade(
        &Raster::from_vec(66, 50, 1, margin).unwrap(),
        &surftile::shade::ShadeOptions {
            exaggeration: Some(1.5),
            ..rock.material()
        },
    );
    assert_eq!(png, want, "the exaggeration is not per surface pixel");
}

/// A model `.toml` renders with its own parameters; bad models, shading flags and light
/// directions are one-line errors that leave nothing behind.
#[test]
fn model_files_and_bad_shading_are_handled() {
    use surftile::models::fractal::{FractalKind, FractalParams, FractalSurface};
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::write(
        p.join("m.toml"),
        "material = \"china\"\n[fractal]\nh = 0.3\nlevels = 6\nkind = \"casting\"\n",
    )
    .unwrap();
    let r = surftile(p, &["sample", "m.toml", "-12.25", "40", "--seed", "2"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let want = FractalSurface::new(
        FractalParams {
            h: 0.3,
            levels: 6,
            kind: FractalKind::Casting,
            amplitude: 1.0,
            smooth: false,
        },
        2,
    )
    .unwrap()
    .height(-12.25, 40.0);
    assert_eq!(r.stdout.trim().parse::<f32>().unwrap(), want);

    let bad = [
        ("h15.toml", "[fractal]\nh = 1.5\n", "(0, 1]"),
        ("h0.toml", "[fractal]\nh = 0\n", "does not converge"),
        ("d0.toml", "[cells]\ndensity = 0.0\n", "density"),
        ("dn.toml", "[cells]\ndensity = -0.01\n", "density"),
        ("two.toml", "[fractal]\n[cells]\n", "exactly one"),
        ("typo.toml", "[fractal]\nhh = 0.5\n", "hh"),
    ];
    for (file, text, needle) in bad {
        std::fs::write(p.join(file), text).unwrap();
        let r = render(p, file, ("8", "8"), "o.npy", &[]);
        assert_clean_failure(p, &r, needle, "o.npy");
    }
    let shading = [
        (&["--shade", "--light", "0,0,0"][..], "light"),
        (&["--shade", "--view", "0,0,0"][..], "view"),
        (&["--shade", "--light", "1,2"][..], "x,y,z"),
        (&["--shade", "--light", "1,nan,2"][..], "finite"),
        (
            &["--shade", "--material", "velvet"][..],
            "rock, china, casting",
        ),
        (&["--shade", "--shininess", "-3"][..], "shininess"),
        (&["--shade", "--exaggeration", "0"][..], "exaggeration"),
        (&["--light", "1,1,1"][..], "--shade"),
    ];
    for (extra, needle) in shading {
        let r = render(p, "rock", ("8", "8"), "o.png", extra);
        assert_clean_failure(p, &r, needle, "o.png");
    }
    let r = render(p, "granite", ("8", "8"), "o.npy", &[]);
    assert_clean_failure(p, &r, "cells-convex", "o.npy");
}

/// `render --imperfect` writes the weathered heights, the mask and the tendency exactly
/// as the library computes them (and a colour image); bad layer flags and files are
/// one-line errors that leave nothing behind.
#[test]
fn imperfection_layers_from_the_command_line() {
    use surftile::imperfect::{Imperfect, ImperfectConfig};
    use surftile::models::rugged::ModelConfig;
    use surftile::stream::Region;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    let extra = [
        "--imperfect",
        "peeling",
        "--seed",
        "3",
        "--mask",
        "m.png",
        "--tendency",
        "t.npy",
        "--colour",
        "c.png",
    ];
    let r = render(p, "cells-convex", ("64", "48"), "h.npy", &extra);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let (config, _) = ImperfectConfig::load(Path::new("peeling")).unwrap();
    let cells = ModelConfig::preset("cells-convex").unwrap();
    let layer = Imperfect::new(cells.surface(3).unwrap(), &config, None, 3).unwrap();
    let want = layer.fill_layers(&Region::new(0.0, 0.0, 64, 48)).unwrap();
    let read = |f: &str| {
        surftile::io::read_image(&p.join(f), &Default::default())
            .unwrap()
            .raster
            .data
    };
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&read("h.npy")), bits(&want.heights), "heights");
    assert_eq!(bits(&read("t.npy")), bits(&want.tendency), "tendency");
    let (w, h, colour, mask) = common::png8(&p.join("m.png"));
    assert_eq!((w, h, colour), (64, 48, png::ColorType::Grayscale));
    assert_eq!(mask, want.layers, "mask");
    assert!(mask.iter().any(|&l| l > 0) && mask.contains(&0));
    let (_, _, colour, rgb) = common::png8(&p.join("c.png"));
    assert_eq!((colour, rgb.len()), (png::ColorType::Rgb, 64 * 48 * 3));

    std::fs::write(
        p.join("bad.toml"),
        "pattern = \"dust\"\n[[source]]\nkind = \"ambient\"\n[geometry]\nhalf_exposure_px = 0\n",
    )
    .unwrap();
    let cases: [(&[&str], &str); 7] = [
        (&["--mask", "m2.png"], "--imperfect"),
        (&["--imperfect", "dust", "--mask", "m2.tif"], ".png"),
        (
            &["--imperfect", "dust", "--tendency", "m2.png"],
            ".tif or .npy",
        ),
        (&["--imperfect", "rust"], "dust, patina, peeling"),
        (&["--imperfect", "bad.toml", "--mask", "m2.png"], "d_h > 0"),
        (
            &["--imperfect", "dust", "--age", "-1", "--mask", "m2.png"],
            "age",
        ),
        (&["--imperfect", "dust", "--colour", "c2.npy"], "colour"),
    ];
    for (extra, needle) in cases {
        let r = render(p, "rock", ("8", "8"), "o.npy", extra);
        assert_clean_failure(p, &r, needle, "o.npy");
        for f in ["m2.png", "m2.tif", "c2.npy"] {
            assert!(!p.join(f).exists(), "{extra:?} left {f}");
        }
    }
}

/// A reader that closes the pipe early (`surftile info BANK | head -1`) ends the process
/// quietly, by SIGPIPE as other command-line tools do: no panic about a broken pipe.
#[cfg(unix)]
#[test]
fn a_closed_stdout_pipe_ends_quietly() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    bake_good(dir.path());
    let mut child = Command::new(env!("CARGO_BIN_EXE_surftile"))
        .args(["info", "good.bank"])
        .current_dir(dir.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Close the read end before the child writes anything.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(
        out.status.success() || out.status.signal() == Some(libc::SIGPIPE),
        "{:?}: {stderr}",
        out.status
    );
}

/// Issue 33, finding 10: a render at the sample limit, whatever its shape, is filled in
/// bounded pieces. A 2²⁵ × 1 render of `rock` (its 128 MiB output plus the model's
/// per-row scratch) peaked near 770 MB before (6.15 GB at 2²⁸ × 1); now it runs in a
/// shell whose address space is capped at 500 MB, with progress. A PNG wider than
/// libpng reads is refused before anything is rendered.
#[test]
fn wide_renders_fill_in_bounded_pieces() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v 500000 && exec '{}' render rock --w 33554432 --h 1 --out wide.npy",
            env!("CARGO_BIN_EXE_surftile")
        ))
        .current_dir(dir.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("render: 50%"),
        "progress along one row: {stderr}"
    );
    let wide = std::fs::metadata(dir.path().join("wide.npy"))
        .unwrap()
        .len();
    assert!(wide > 4 * 33554432, "{wide} bytes");
    let start = std::time::Instant::now();
    let r = render(dir.path(), "rock", ("268435456", "1"), "o.png", &[]);
    assert_clean_failure(dir.path(), &r, "libpng", "o.png");
    let r = render(
        dir.path(),
        "rock",
        ("1", "268435456"),
        "o.png",
        &["--shade"],
    );
    assert_clean_failure(dir.path(), &r, "1000000 pixels a side", "o.png");
    assert!(
        start.elapsed().as_secs_f64() < 5.0,
        "refused before rendering"
    );
}

/// `render --defects` (issue 35): the heights are the library's `Defected` fill, the
/// mask its defect ids (under an imperfection layer's where both are given), and a bad
/// configuration is one line with nothing written.
#[test]
fn defects_render_with_their_mask() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "render",
        "parallel-d4-ae05",
        "--w",
        "200",
        "--h",
        "150",
        "--x",
        "-3000",
        "--y",
        "7.5",
        "--spacing",
        "4",
        "--seed",
        "6",
        "--defects",
        "dents",
        "--out",
        "h.npy",
        "--mask",
        "m.png",
    ];
    let r = surftile(dir.path(), &args);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let heights = surftile::io::read_image(&dir.path().join("h.npy"), &Default::default())
        .unwrap()
        .raster;
    let mask = surftile::io::read_image(&dir.path().join("m.png"), &Default::default())
        .unwrap()
        .raster;
    let source = surftile::Open::new("parallel-d4-ae05")
        .spacing_um(4.0)
        .open()
        .unwrap();
    let config = surftile::defects::DefectConfig::load(Path::new("dents")).unwrap();
    let defects = surftile::defects::Defects::new(&config, 4.0, "um", 6).unwrap();
    let surface =
        surftile::defects::Defected::new(source.surface(6).unwrap(), defects.clone()).unwrap();
    let region = surftile::Region::new(-3000.0, 7.5, 200, 150);
    let mut expected = vec![0.0f32; 200 * 150];
    surface.fill(&region, &mut expected).unwrap();
    assert!(
        heights
            .data
            .iter()
            .zip(&expected)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    );
    let mut ids = vec![0u8; 200 * 150];
    defects.fill_ids(&region, &mut ids).unwrap();
    assert!(
        ids.contains(&surftile::defects::DENT_ID),
        "no dent in the region"
    );
    assert!(mask.data.iter().zip(&ids).all(|(&m, &i)| m == i as f32));

    // Under a dust layer, the dents keep their id over the layer's.
    let swap = |from: &str, to: &'static str, list: &mut Vec<&str>| {
        let at = list.iter().position(|a| *a == from).unwrap();
        list[at] = to;
    };
    let mut with_layer = args.to_vec();
    with_layer.extend(["--imperfect", "dust"]);
    swap("m.png", "m2.png", &mut with_layer);
    let r = surftile(dir.path(), &with_layer);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let m2 = surftile::io::read_image(&dir.path().join("m2.png"), &Default::default())
        .unwrap()
        .raster;
    for (m, &i) in m2.data.iter().zip(&ids) {
        if i != 0 {
            assert_eq!(*m, i as f32);
        }
    }
    assert!(m2.data.contains(&1.0), "no dust in the mask");

    std::fs::write(
        dir.path().join("bad.toml"),
        "[[defect]]\nkind = \"dent\"\ncell_um = 800.0\nprobability = 2.0\ndiameter_um = [60.0, 200.0]\ndepth_um = [2.0, 15.0]\n",
    )
    .unwrap();
    let mut bad = args.to_vec();
    swap("dents", "bad.toml", &mut bad);
    swap("h.npy", "b.npy", &mut bad);
    swap("m.png", "b.png", &mut bad);
    let r = surftile(dir.path(), &bad);
    assert_clean_failure(dir.path(), &r, "probability = 2", "b.npy");
    assert!(!dir.path().join("b.png").exists());
}

/// `surftile dataset`: writes its shards and index, a rerun keeps them, a changed spec
/// is refused unless --force, and bad input is one line with a non-zero exit and
/// nothing written.
#[test]
fn dataset_writes_resumes_and_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let spec = |seed: u32, weight: f64| {
        format!(
            "[dataset]\nsamples = 6\nsamples_per_shard = 2\nseed = {seed}\nsize = [40, 30]\n\n\
             [[source]]\npath = \"parallel-d4-ae05\"\nweight = {weight}\n\n\
             [[defect]]\nkind = \"dent\"\nprobability = 1.0\ncell_um = 300.0\n\
             cell_probability = 1.0\ndiameter_um = [60.0, 120.0]\ndepth_um = [2.0, 5.0]\n"
        )
    };
    std::fs::write(dir.path().join("spec.toml"), spec(1, 1.0)).unwrap();
    let r = surftile(dir.path(), &["dataset", "spec.toml", "--out", "ds"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stderr.contains("3 to write"), "{}", r.stderr);
    let shards: Vec<Vec<u8>> = (0..3)
        .map(|s| std::fs::read(dir.path().join(format!("ds/shard-{s:06}.tar"))).unwrap())
        .collect();
    assert!(dir.path().join("ds/dataset.json").exists());
    // One thread, shard 1 rewritten alone: the same bytes.
    std::fs::remove_file(dir.path().join("ds/shard-000001.tar")).unwrap();
    let r = surftile(
        dir.path(),
        &["dataset", "spec.toml", "--out", "ds", "--workers", "1"],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stderr.contains("2 complete, 1 to write"), "{}", r.stderr);
    assert_eq!(
        std::fs::read(dir.path().join("ds/shard-000001.tar")).unwrap(),
        shards[1]
    );
    // A changed spec is refused, then replaced with --force.
    std::fs::write(dir.path().join("spec.toml"), spec(2, 1.0)).unwrap();
    let r = surftile(dir.path(), &["dataset", "spec.toml", "--out", "ds"]);
    assert_ne!(r.code, 0);
    assert!(r.stderr.contains("--force"), "{}", r.stderr);
    assert_eq!(r.stderr.trim().lines().count(), 1, "{}", r.stderr);
    let r = surftile(
        dir.path(),
        &["dataset", "spec.toml", "--out", "ds", "--force"],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert_ne!(
        std::fs::read(dir.path().join("ds/shard-000000.tar")).unwrap(),
        shards[0]
    );
    // Bad input: one line, a non-zero exit, nothing written.
    std::fs::write(dir.path().join("bad.toml"), spec(1, 0.0)).unwrap();
    std::fs::write(dir.path().join("file"), b"x").unwrap();
    for (args, expected) in [
        (vec!["dataset", "bad.toml", "--out", "new"], "weight = 0"),
        (
            vec!["dataset", "spec.toml", "--out", "file"],
            "this is a file",
        ),
        (
            vec!["dataset", "spec.toml", "--out", "new", "--shards", "2..9"],
            "within 0..3",
        ),
        (
            vec!["dataset", "spec.toml", "--out", "new", "--shards", "3..1"],
            "A < B",
        ),
        (
            vec!["dataset", "spec.toml", "--out", "new", "--workers", "0"],
            "workers = 0",
        ),
        (
            vec!["dataset", "missing.toml", "--out", "new"],
            "missing.toml",
        ),
    ] {
        let r = surftile(dir.path(), &args);
        assert_ne!(r.code, 0, "{args:?}");
        assert!(r.stderr.contains(expected), "{args:?}: {}", r.stderr);
        assert_eq!(r.stderr.trim().lines().count(), 1, "{}", r.stderr);
    }
    assert!(!dir.path().join("new").exists());
    assert_eq!(std::fs::read(dir.path().join("file")).unwrap(), b"x");
}

/// `render --out FILE.x3p` writes the heights the `.npy` output holds, with the spacing
/// and the command in the X3P record, and `stats` and `bake` read it as an exemplar.
#[test]
fn x3p_outputs_read_back_as_exemplars() {
    let dir = tempfile::tempdir().unwrap();
    let region = [
        "parallel-d4-ae05",
        "--w",
        "128",
        "--h",
        "96",
        "--x",
        "-300",
        "--spacing",
        "4",
    ];
    for out in ["h.x3p", "h.npy"] {
        let mut args = vec!["render"];
        args.extend(region);
        args.extend(["--out", out]);
        let r = surftile(dir.path(), &args);
        assert_eq!(r.code, 0, "{}", r.stderr);
    }
    let read =
        |name: &str| surftile::io::read_image(&dir.path().join(name), &Default::default()).unwrap();
    let (x3p, npy) = (read("h.x3p"), read("h.npy"));
    assert_eq!(x3p.raster.data.len(), npy.raster.data.len());
    assert!(
        x3p.raster
            .data
            .iter()
            .zip(&npy.raster.data)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    );
    assert!((x3p.spacing_um.unwrap() / 4.0 - 1.0).abs() < 1e-12);
    let bytes = std::fs::read(dir.path().join("h.x3p")).unwrap();
    let mut z = zip::ZipArchive::new(std::io::Cursor::new(bytes)).unwrap();
    let mut xml = String::new();
    std::io::Read::read_to_string(&mut z.by_name("main.xml").unwrap(), &mut xml).unwrap();
    assert!(xml.contains("render parallel-d4-ae05"), "{xml}");
    let r = surftile(dir.path(), &["stats", "h.x3p", "h.npy", "--no-structure"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    // The figures that come with the patch figures stay out of the JSON without them.
    let stats: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    assert!(stats["structure"].is_null() && stats["psd_error_even"].is_null());
    let r = surftile(
        dir.path(),
        &["bake", "h.x3p", "--method", "rpn", "--out", "h.bank"],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(dir.path().join("h.bank").exists());
}

/// `surftile stats` measures the patch figures on bounded regions (their searches grow
/// faster than both maps' pixels: two 4096² maps took more than 9 minutes): an A wider
/// than 512 px gives its central 512 columns, B its top-left corner, the JSON names both
/// regions and stderr says so in one line. Maps within the bounds are measured whole and
/// nothing is said.
#[test]
fn stats_bounds_the_patch_figures_and_says_where_it_measured() {
    let dir = tempfile::tempdir().unwrap();
    let map = |w: usize, h: usize| {
        Raster::from_vec(
            w,
            h,
            1,
            (0..w * h)
                .map(|i| ((i % w) as f32 * 0.37).sin() + ((i / w) as f32 * 0.23).cos())
                .collect(),
        )
        .unwrap()
    };
    write_heights(&dir.path().join("wide.npy"), &map(530, 24), None).unwrap();
    write_heights(&dir.path().join("small.npy"), &map(64, 64), None).unwrap();
    let r = surftile(dir.path(), &["stats", "wide.npy", "small.npy"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let stats: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(
        stats["structure_regions"],
        serde_json::json!({"a": [9, 0, 512, 24], "b": [0, 0, 64, 64]}),
        "{stats}"
    );
    assert!(
        stats["structure"]["coherence"].as_f64().is_some(),
        "{stats}"
    );
    assert_eq!(r.stderr.lines().count(), 1, "{}", r.stderr);
    assert!(r.stderr.contains("A's central 512×24"), "{}", r.stderr);
    let r = surftile(dir.path(), &["stats", "small.npy", "small.npy"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let stats: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(
        stats["structure_regions"],
        serde_json::json!({"a": [0, 0, 64, 64], "b": [0, 0, 64, 64]})
    );
    assert!(r.stderr.is_empty(), "{}", r.stderr);
}

/// `surftile convert` (issue 36): an instrument file to X3P and npy keeps heights,
/// spacing and missing points, prints what it read, converts units on request, and
/// removes form; a PNG of a map with missing points is refused unless they are filled.
#[test]
fn convert_keeps_heights_spacing_and_missing_points() {
    let dir = tempfile::tempdir().unwrap();
    let sur = common::repo("tests/data/instruments/sur-2-crop.sur");
    let sur = sur.to_str().unwrap();
    let r = surftile(dir.path(), &["convert", sur, "a.x3p"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        r.stdout.contains("128×120 points")
            && r.stdout.contains("spacing 3.4840002190321684 µm")
            && r.stdout.contains("heights in mm")
            && r.stdout.contains("39 missing points"),
        "{}",
        r.stdout
    );
    let r = surftile(dir.path(), &["convert", "a.x3p", "b.npy", "--unit", "nm"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let read = |p: &std::path::Path| surftile::io::read_image(p, &Default::default()).unwrap();
    let want = read(&common::repo("tests/data/instruments/sur-2-crop.npy"));
    let x3p = read(&dir.path().join("a.x3p"));
    let nm = read(&dir.path().join("b.npy"));
    assert!((x3p.spacing_um.unwrap() / 3.4840002190321684 - 1.0).abs() < 1e-12);
    for ((a, b), c) in want
        .raster
        .data
        .iter()
        .zip(&x3p.raster.data)
        .zip(&nm.raster.data)
    {
        assert_eq!(a.is_nan(), b.is_nan());
        assert_eq!(a.is_nan(), c.is_nan());
        if a.is_finite() {
            assert!((a - b).abs() <= 1e-5 * a.abs(), "{a} vs {b}");
            assert!((a * 1e3 - c).abs() <= 1e-4 * c.abs(), "{a} µm vs {c} nm");
        }
    }
    // PNG cannot hold missing points: refused in one line, then filled on request.
    let r = surftile(dir.path(), &["convert", sur, "c.png"]);
    assert_ne!(r.code, 0);
    assert!(
        r.stderr.contains("missing points") && r.stderr.trim().lines().count() == 1,
        "{}",
        r.stderr
    );
    assert!(!dir.path().join("c.png").exists());
    let r = surftile(
        dir.path(),
        &[
            "convert",
            sur,
            "c.png",
            "--fill-missing",
            "--level",
            "poly:2",
        ],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    // A bad unit and a bad form removal are named.
    let r = surftile(dir.path(), &["convert", sur, "d.npy", "--unit", "furlong"]);
    assert!(r.code != 0 && r.stderr.contains("unit"), "{}", r.stderr);
    let r = surftile(dir.path(), &["convert", sur, "d.npy", "--level", "poly:99"]);
    assert!(r.code != 0 && r.stderr.contains("poly:N"), "{}", r.stderr);
}

/// `surftile stats A` alone (issue 36): the ISO 25178 parameters of a map on its
/// scale-limited surface, naming the operators; the L-filter needs a spacing.
#[test]
fn stats_of_one_map_names_its_operators() {
    let dir = tempfile::tempdir().unwrap();
    let plu = common::repo("tests/data/instruments/plu-1-crop.plu");
    let plu = plu.to_str().unwrap();
    let r = surftile(
        dir.path(),
        &["stats", plu, "--level", "poly:2", "--lfilter", "50"],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let v: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(v["operators"]["f"], "poly:2");
    assert!(v["operators"]["l"].as_str().unwrap().contains("50 µm"));
    assert_eq!(v["grid"], serde_json::json!([128, 120]));
    let sq = v["iso25178"]["sq"].as_f64().unwrap();
    // Without the L-filter the same map keeps its waviness: a larger Sq.
    let r = surftile(dir.path(), &["stats", plu, "--level", "poly:2"]);
    let w: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    let sq_all = w["iso25178"]["sq"].as_f64().unwrap();
    assert!(
        sq > 0.0 && sq < sq_all,
        "Sq {sq} with the L-filter, {sq_all} without"
    );
    let npy = common::repo("tests/data/instruments/plu-1-crop.npy");
    let r = surftile(
        dir.path(),
        &["stats", npy.to_str().unwrap(), "--lfilter", "50"],
    );
    assert!(
        r.code != 0 && r.stderr.contains("--spacing"),
        "{}",
        r.stderr
    );
}

/// The bake log and the bank's header say what the flat field did: GIMP's `cracked`,
/// whose form is one gain on every channel (colour ratio 0.02), is flat-fielded; its
/// `rain`, whose blue stays while red and green fall across the frame (0.83), is kept as
/// read (`prep::level::LIGHT_COLOUR_RATIO`, 0.75): its bank records the photo's own
/// standard deviation per channel, where the flat-fielded crack's differs.
#[test]
fn bake_says_whether_a_photo_was_flat_fielded() {
    let dir = tempfile::tempdir().unwrap();
    let bake = |file: &str, out: &str| {
        let photo = common::repo(file).display().to_string();
        let r = surftile(
            dir.path(),
            &["bake", &photo, "--method", "rpn", "--out", out],
        );
        assert_eq!(r.code, 0, "{}", r.stderr);
        (r.stderr, Bank::read(&dir.path().join(out)).unwrap())
    };
    // Per channel standard deviation of a photo as read, as the bank records it.
    let std_as_read = |file: &str| -> Vec<f64> {
        let raw =
            surftile::io::read_image(&common::repo(file), &surftile::io::ReadOptions::default())
                .unwrap()
                .raster;
        (0..raw.channels)
            .map(|c| {
                let v = raw.channel_f64(c);
                let m = v.iter().sum::<f64>() / v.len() as f64;
                (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
            })
            .collect()
    };
    let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6 * y);
    let (log, bank) = bake("tests/data/gimp-crack.png", "crack.bank");
    let said = "photo: flat field of degree 2: flat-fielded, colour ratio 0.02 <= 0.75";
    assert!(log.contains(said), "{log}");
    assert!(bank.header.bake.contains(said), "{}", bank.header.bake);
    let read = std_as_read("tests/data/gimp-crack.png");
    assert!(!same(&bank.header.exemplar.std, &read), "{read:?}");
    let (log, bank) = bake("tests/data/gimp-rain.png", "rain.bank");
    let said = "photo: flat field of degree 2: kept as read, colour ratio 0.83 > 0.75";
    assert!(log.contains(said), "{log}");
    assert!(bank.header.bake.contains(said), "{}", bank.header.bake);
    let read = std_as_read("tests/data/gimp-rain.png");
    assert!(
        same(&bank.header.exemplar.std, &read),
        "{:?} against {read:?}",
        bank.header.exemplar.std
    );
}

/// A grey photo's synthesis keeps the photo's levels in a 16-bit PNG, as colour does
/// (level = v / 255 · 65535, within one level of the float render), where a height map's
/// render is stretched to black and white: a dark 8-bit slate photo (levels 34–119) once
/// came out at full contrast. The bank records the scale.
#[test]
fn grey_photo_renders_keep_their_levels() {
    let dir = tempfile::tempdir().unwrap();
    let photo = common::repo("tests/data/gimp-slate.png")
        .display()
        .to_string();
    let r = surftile(dir.path(), &["bake", &photo, "--out", "slate.bank"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let bank = Bank::read(&dir.path().join("slate.bank")).unwrap();
    assert_eq!(bank.header.exemplar.levels, Some(255.0));
    // Plane-levelled, the photo lies about 0: no scale to keep.
    let r = surftile(
        dir.path(),
        &["bake", &photo, "--level", "plane", "--out", "plane.bank"],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let plane = Bank::read(&dir.path().join("plane.bank")).unwrap();
    assert_eq!(plane.header.exemplar.levels, None);
    assert!(
        plane.header.bake.contains("level=Plane"),
        "{}",
        plane.header.bake
    );
    assert!(
        bank.header.bake.contains("flat field of degree 2"),
        "{}",
        bank.header.bake
    );
    let levels_of = |name: &str| {
        let decoder = png::Decoder::new(std::io::BufReader::new(
            std::fs::File::open(dir.path().join(name)).unwrap(),
        ));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0u8; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!(info.color_type, png::ColorType::Grayscale);
        buf[..info.buffer_size()]
            .chunks_exact(2)
            .map(|b| u16::from_be_bytes([b[0], b[1]]))
            .collect::<Vec<u16>>()
    };
    for out in ["slate.png", "slate.npy"] {
        let r = render(dir.path(), "slate.bank", ("96", "64"), out, &[]);
        assert_eq!(r.code, 0, "{}", r.stderr);
    }
    let values = surftile::io::read_image(
        &dir.path().join("slate.npy"),
        &surftile::io::ReadOptions::default(),
    )
    .unwrap()
    .raster;
    let levels = levels_of("slate.png");
    let (lo, hi) = levels
        .iter()
        .fold((u16::MAX, 0u16), |(l, h), &v| (l.min(v), h.max(v)));
    assert!(lo > 0 && hi < 65535, "stretched: levels {lo}–{hi}");
    for (v, &l) in values.data.iter().zip(&levels) {
        let want = (*v as f64 / 255.0 * 65535.0).round();
        assert!((l as f64 - want).abs() <= 1.0, "{v} written as level {l}");
    }
    // A height map's render is stretched over its range.
    bake_good(dir.path());
    let r = render(dir.path(), "good.bank", ("96", "64"), "h.png", &[]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let h = levels_of("h.png");
    assert_eq!(
        h.iter()
            .fold((u16::MAX, 0u16), |(l, m), &v| (l.min(v), m.max(v))),
        (0, 65535)
    );
}

/// `bake --edges` chooses how a stochastic RSGF bank's patches meet the exemplar's
/// edges, and the bank records it: by default the 100² dried-mud photo, which blocks at
/// bounded positions would show with 0.91 of its standard deviation, wraps and says
/// why, with the torus's size; `--edges reflect` keeps mirrored edges; `--edges`
/// without `--stochastic`, mirrored edges with blended patches, and a wrap on an
/// exemplar too small for the torus are refused with the flags named.
#[test]
fn bake_edges_choose_wrapped_or_reflected_patches() {
    let dir = tempfile::tempdir().unwrap();
    let mud = common::repo("tests/data/gimp-dried-mud.png")
        .display()
        .to_string();
    let bake = |extra: &[&str], out: &str| {
        let mut args = vec!["bake", &mud, "--method", "rsgf", "--stochastic"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--out", out]);
        surftile(dir.path(), &args)
    };
    let r = bake(&[], "auto.bank");
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        r.stderr.contains("edges wrapped")
            && r.stderr.contains("torus")
            && r.stderr.contains("0.91"),
        "{}",
        r.stderr
    );
    let auto = Bank::read(&dir.path().join("auto.bank")).unwrap();
    assert!(
        auto.header
            .bake
            .contains("reflect_edges=false wrap_edges=true"),
        "{}",
        auto.header.bake
    );
    let r = bake(&["--edges", "reflect"], "reflect.bank");
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stderr.contains("edges reflected"), "{}", r.stderr);
    let reflect = Bank::read(&dir.path().join("reflect.bank")).unwrap();
    assert!(
        reflect
            .header
            .bake
            .contains("reflect_edges=true wrap_edges=false"),
        "{}",
        reflect.header.bake
    );
    let r = surftile(
        dir.path(),
        &[
            "bake", &mud, "--method", "rsgf", "--edges", "wrap", "--out", "x.bank",
        ],
    );
    assert!(
        r.code != 0 && r.stderr.contains("--edges") && r.stderr.contains("--stochastic"),
        "{}",
        r.stderr
    );
    let r = bake(&["--edges", "reflect", "--join", "blend"], "z.bank");
    assert!(
        r.code != 0 && r.stderr.contains("--edges") && r.stderr.contains("--join"),
        "{}",
        r.stderr
    );
    let r = bake(
        &["--edges", "wrap", "--block", "60", "--border", "12"],
        "y.bank",
    );
    assert!(
        r.code != 0 && r.stderr.contains("block + 4 × border") && r.stderr.contains("100×100"),
        "{}",
        r.stderr
    );
    for refused in ["x.bank", "y.bank", "z.bank"] {
        assert!(!dir.path().join(refused).exists(), "{refused}");
    }
}
