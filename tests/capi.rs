//! The C ABI from C: the header is cbindgen's output for `src/capi.rs` as it stands,
//! and a C program (`tests/capi/check.c`), compiled with the system `cc` against the
//! installed header and library (through their pkg-config file), samples a bank and a
//! milling preset from two threads with the Rust library's values bit for bit, and gets
//! a status and a one-line message from every error path. A C++ program uses the same
//! header and library. The C program also runs
//! linked statically, and under valgrind where it is installed
//! (`SURFTILE_REQUIRE_VALGRIND=1`, set by `.ci/run`, makes a missing valgrind fail).
//!
//! The library is built by `include/install` (`cargo rustc --crate-type cdylib
//! --crate-type staticlib --features capi`) in its own target folder, `target/capi`,
//! so it does not wait on the lock of the build running this test.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use surftile::bake::Baker;
use surftile::io::{ReadOptions, read_image};
use surftile::{Region, Surface};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The header cbindgen writes for src/capi.rs with include/cbindgen.toml.
fn generated_header() -> String {
    let root = Path::new(ROOT);
    let config = cbindgen::Config::from_file(root.join("include/cbindgen.toml")).unwrap();
    let mut out = Vec::new();
    cbindgen::Builder::new()
        .with_config(config)
        .with_src(root.join("src/capi.rs"))
        .generate()
        .expect("cbindgen parses src/capi.rs")
        .write(&mut out);
    String::from_utf8(out).unwrap()
}

#[test]
fn header_is_current() {
    let path = Path::new(ROOT).join("include/surftile.h");
    let generated = generated_header();
    if std::env::var_os("SURFTILE_BLESS").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        checked_in == generated,
        "include/surftile.h is stale: regenerate it with \
         `SURFTILE_BLESS=1 cargo test --release --test capi header` and commit it"
    );
    for name in [
        "surftile_open",
        "surftile_free",
        "surftile_height",
        "surftile_fill",
        "surftile_channels",
        "surftile_spacing_um",
        "surftile_last_error",
        "surftile_abi_version",
        "SURFTILE_ABI_VERSION",
        "SURFTILE_STATUS_NULL_POINTER",
    ] {
        assert!(generated.contains(name), "the header lacks {name}");
    }
}

/// Runs `cmd`, panicking with its output when it fails; returns its stdout.
fn run(cmd: &mut Command, what: &str) -> String {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("{what}: cannot start: {e}"));
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{what} failed ({}):\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// `pkg-config ARGS surftile` against the installed prefix, split into arguments.
fn pkg_config(prefix: &Path, args: &[&str]) -> Vec<String> {
    let out = run(
        Command::new("pkg-config")
            .args(args)
            .arg("surftile")
            .env("PKG_CONFIG_PATH", prefix.join("lib/pkgconfig")),
        "pkg-config",
    );
    out.split_whitespace().map(str::to_string).collect()
}

/// One parsed `fill` line of the C program.
struct Fill {
    x: f64,
    y: f64,
    step: f64,
    width: usize,
    height: usize,
    bits: Vec<u32>,
}

/// What the C program printed, by spec.
#[derive(Default)]
struct Printed {
    channels: HashMap<String, usize>,
    spacing: HashMap<String, f64>,
    heights: Vec<(String, f64, f64, u32)>,
    fills: Vec<(String, Fill)>,
    agree: HashMap<String, bool>,
    errors: HashMap<String, (i32, String)>,
}

fn parse(stdout: &str) -> Printed {
    let mut p = Printed::default();
    for line in stdout.lines() {
        let f: Vec<&str> = line.split(' ').collect();
        let hex = |s: &str| u32::from_str_radix(s, 16).unwrap();
        match f[0] {
            "open" => {
                p.channels.insert(f[1].into(), f[3].parse().unwrap());
                p.spacing.insert(f[1].into(), f[5].parse().unwrap());
            }
            "height" => p.heights.push((
                f[1].into(),
                f[2].parse().unwrap(),
                f[3].parse().unwrap(),
                hex(f[4]),
            )),
            "fill" => p.fills.push((
                f[1].into(),
                Fill {
                    x: f[2].parse().unwrap(),
                    y: f[3].parse().unwrap(),
                    step: f[4].parse().unwrap(),
                    width: f[5].parse().unwrap(),
                    height: f[6].parse().unwrap(),
                    bits: f[8..].iter().map(|s| hex(s)).collect(),
                },
            )),
            "agree" => {
                p.agree.insert(f[1].into(), f[2] == "1");
            }
            "error" => {
                p.errors
                    .insert(f[1].into(), (f[2].parse().unwrap(), f[3..].join(" ")));
            }
            "abi" => assert_eq!(f[1], "1", "ABI version"),
            other => panic!("unexpected line from the C program ({other}): {line}"),
        }
    }
    p
}

/// Checks the C program's output against the Rust library.
fn compare(stdout: &str, specs: &[&str], seed: u32) {
    let p = parse(stdout);
    for spec in specs {
        let source = surftile::open(spec).unwrap();
        let surface = source.surface(seed).unwrap();
        let c = surface.channels();
        assert_eq!(p.channels[*spec], c, "{spec}: channels");
        let spacing = source.spacing_um().unwrap_or(f64::NAN);
        let printed = p.spacing[*spec];
        assert!(
            printed == spacing || (printed.is_nan() && spacing.is_nan()),
            "{spec}: spacing {printed} from C, {spacing} from Rust"
        );
        assert!(p.agree[*spec], "{spec}: the two C threads disagree");
        let heights: Vec<_> = p.heights.iter().filter(|h| h.0 == *spec).collect();
        assert_eq!(heights.len(), 6, "{spec}: heights printed");
        for (_, x, y, bits) in heights {
            let rust = surface.height(*x, *y).to_bits();
            assert_eq!(
                *bits, rust,
                "{spec}: height at ({x}, {y}) is {bits:08x} from C, {rust:08x} from Rust"
            );
        }
        let fills: Vec<_> = p.fills.iter().filter(|f| f.0 == *spec).collect();
        assert_eq!(fills.len(), 2, "{spec}: fills printed");
        for (_, fill) in fills {
            let region = Region::new(fill.x, fill.y, fill.width, fill.height).with_step(fill.step);
            let mut rust = vec![0.0f32; fill.width * fill.height * c];
            surface.fill(&region, &mut rust).unwrap();
            let rust: Vec<u32> = rust.iter().map(|v| v.to_bits()).collect();
            assert_eq!(rust.len(), fill.bits.len(), "{spec}: fill length");
            let differ = rust.iter().zip(&fill.bits).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{spec}: {differ} fill values differ from Rust's");
        }
    }
    // (case, status code, a word its message must hold)
    let expected = [
        ("missing-file", 3, "missing.bank"),
        ("corrupt-bank", 4, "bank"),
        ("unknown-preset", 2, "no-such-preset"),
        ("null-spec", 1, "spec"),
        ("null-out", 1, "out"),
        ("null-surface", 1, "surface"),
        ("null-buffer", 1, "out"),
        ("zero-width", 2, "size"),
        ("zero-height", 2, "size"),
        ("short-stride", 2, "row_stride"),
        ("nan-origin", 2, "region"),
        ("zero-step", 2, "step"),
        ("far-origin", 2, "region"),
        ("huge-size", 5, "surftile_fill"),
        ("null-height", 1, "surftile_height"),
    ];
    for (case, code, word) in expected {
        let (got, message) = &p.errors[case];
        assert_eq!(
            *got, code,
            "{case}: status {got} ({message}), expected {code}"
        );
        assert!(
            message.contains(word) && !message.contains('\n'),
            "{case}: message {message:?} should name {word:?}"
        );
    }
    assert_eq!(p.errors.len(), expected.len(), "error cases printed");
}

#[test]
fn c_program_matches_rust_from_two_threads_and_reports_errors() {
    let root = PathBuf::from(ROOT);
    let dir = tempfile::tempdir().unwrap();
    let prefix = dir.path().join("prefix");
    run(
        Command::new(root.join("include/install"))
            .arg(&prefix)
            .env("CARGO_TARGET_DIR", root.join("target/capi")),
        "include/install",
    );

    // A bank, and a corrupt copy of it (its payload cut short).
    let exemplar = read_image(&root.join("tiles/di-6.npy"), &ReadOptions::default()).unwrap();
    let bank = Baker::builder()
        .seed(1)
        .build()
        .unwrap()
        .bake(&exemplar, "di-6", &mut |_| {})
        .unwrap();
    let bank_path = dir.path().join("di6.bank");
    bank.write(&bank_path).unwrap();
    let bytes = std::fs::read(&bank_path).unwrap();
    let corrupt = dir.path().join("corrupt.bank");
    std::fs::write(&corrupt, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let bank_spec = bank_path.to_str().unwrap();
    let preset = "parallel-d4-ae05";
    let args = [bank_spec, preset, corrupt.to_str().unwrap()];

    // Dynamic, through pkg-config (its flags are checked against the layout first).
    let cflags = pkg_config(&prefix, &["--cflags"]);
    let libs = pkg_config(&prefix, &["--libs"]);
    assert_eq!(cflags, [format!("-I{}", prefix.join("include").display())]);
    assert_eq!(
        libs,
        [
            format!("-L{}", prefix.join("lib").display()),
            "-lsurftile".into()
        ]
    );
    let dynamic = dir.path().join("check");
    run(
        Command::new("cc")
            .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-O1"])
            .arg(root.join("tests/capi/check.c"))
            .args(&cflags)
            .args(&libs)
            .arg(format!("-Wl,-rpath,{}", prefix.join("lib").display()))
            .args(["-lpthread", "-lm", "-o"])
            .arg(&dynamic),
        "cc (dynamic)",
    );
    let out = run(Command::new(&dynamic).args(args), "the C program");
    compare(&out, &[bank_spec, preset], 7);

    // C++: the same header and library from c++ (the handle in a unique_ptr).
    let cpp = dir.path().join("check-cpp");
    run(
        Command::new("c++")
            .args(["-std=c++17", "-Wall", "-Wextra", "-Werror", "-O1"])
            .arg(root.join("tests/capi/check.cpp"))
            .args(&cflags)
            .args(&libs)
            .arg(format!("-Wl,-rpath,{}", prefix.join("lib").display()))
            .arg("-o")
            .arg(&cpp),
        "c++",
    );
    let out = run(Command::new(&cpp).arg(preset), "the C++ program");
    let rust = surftile::open(preset).unwrap().surface(7).unwrap();
    let h = rust.height(-5.0e7 + 3.0, 3.5).to_bits();
    assert_eq!(
        out.trim(),
        format!("{h:08x} {h:08x}"),
        "C++: height and fill at (-5e7 + 3, 3.5)"
    );

    // Static: the archive and pkg-config's private libraries.
    let static_exe = dir.path().join("check-static");
    run(
        Command::new("cc")
            .args(["-std=c11", "-O1"])
            .arg(root.join("tests/capi/check.c"))
            .args(&cflags)
            .arg(prefix.join("lib/libsurftile.a"))
            .args(
                pkg_config(&prefix, &["--static", "--libs-only-l"])
                    .iter()
                    .filter(|l| *l != "-lsurftile"),
            )
            .args(["-lpthread", "-lm", "-o"])
            .arg(&static_exe),
        "cc (static)",
    );
    let out = run(Command::new(&static_exe).args(args), "the static C program");
    compare(&out, &[bank_spec, preset], 7);

    // Memory errors and leaks: valgrind, where it is installed.
    let has_valgrind = Command::new("valgrind")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_valgrind {
        assert!(
            std::env::var_os("SURFTILE_REQUIRE_VALGRIND").is_none(),
            "SURFTILE_REQUIRE_VALGRIND is set but valgrind is not installed"
        );
        eprintln!("valgrind is not installed: the C program ran without it");
        return;
    }
    let out = run(
        Command::new("valgrind")
            .args([
                "--quiet",
                "--error-exitcode=97",
                "--leak-check=full",
                "--errors-for-leak-kinds=definite",
            ])
            .arg(&dynamic)
            .args(args),
        "the C program under valgrind",
    );
    compare(&out, &[bank_spec, preset], 7);
}
