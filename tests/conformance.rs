//! One conformance suite for every kind in the registry (`surftile::kinds::KINDS`),
//! each opened through the front door (`surftile::open`) from a file or preset:
//! - split invariance: 4 random sub-regions equal the whole, bit for bit, on 1 and 2
//!   threads, near the origin, at x = −10⁹ and at 10¹², at steps 1, 2.5 and 0.75;
//! - fill ⇄ sample: `fill` equals `sample_footprint` pixel by pixel, at step 1 and at a
//!   zoomed-out step;
//! - NaN and refusal outside the coordinate range: NaN samples, refused fills;
//! - the same cost far away: a fill at (10¹², −10¹²) costs no more than a few times the
//!   same fill at the origin (a complexity guard against work that grows with the
//!   coordinate, not a speed target: those are in `benches/`).
//!
//! A kind added to the registry without an example here fails `every_kind_conforms`.

mod common;

use std::path::PathBuf;
use std::sync::OnceLock;
use std::time::Instant;

use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use surftile::bake::Baker;
use surftile::bake::rsgf::RsgfOptions;
use surftile::bank::{Bank, Method};
use surftile::io::{ReadOptions, read_image};
use surftile::kinds::KINDS;
use surftile::models::milling::{MillingConfig, MillingSurface};
use surftile::models::synth::SynthParams;
use surftile::stream::{MAX_COORDINATE, Region, Surface, fill_parallel};

/// Banks written once per test binary into a temporary folder, opened by path.
fn bank_dir() -> &'static tempfile::TempDir {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| tempfile::tempdir().unwrap())
}

fn write_bank(name: &str, bank: Bank) -> String {
    let path: PathBuf = bank_dir().path().join(format!("{name}.bank"));
    if !path.exists() {
        bank.write(&path).unwrap();
    }
    path.display().to_string()
}

fn bake(method: Method, exemplar: &str) -> Bank {
    let image = read_image(&common::repo(exemplar), &ReadOptions::default()).unwrap();
    let builder = Baker::builder().method(method).seed(2);
    let baker = match method {
        // Photos in stochastic mode; the ridged profile on its estimated lattice.
        Method::Rsgf => builder
            .rsgf(RsgfOptions {
                stochastic: exemplar.ends_with(".png"),
                ..RsgfOptions::default()
            })
            .build(),
        Method::Synth => builder
            .synth(SynthParams {
                levels: 3,
                ..SynthParams::default()
            })
            .build(),
        // A penalty given, so that the bake runs no trial fills.
        Method::Quilting => builder
            .quilting(surftile::bake::quilting::QuiltingOptions {
                penalty: Some(0.2),
                ..Default::default()
            })
            .build(),
        _ => builder.build(),
    }
    .unwrap();
    baker.bake(&image, exemplar, &mut |_| {}).unwrap()
}

/// What each kind is opened from: bank files, `.toml` files or preset names.
fn examples(kind: &str) -> Vec<String> {
    match kind {
        "blend" => vec![write_bank("blend", common::demo_bank().clone())],
        "toroidal" => vec![write_bank(
            "toroidal",
            bake(Method::Roller, "tiles/di-6.npy"),
        )],
        "wang" => vec![write_bank("wang", bake(Method::Quilt, "tiles/di-6.npy"))],
        "rsgf" => vec![
            write_bank(
                "rsgf-stochastic",
                bake(Method::Rsgf, "tests/data/gimp-dried-mud.png"),
            ),
            write_bank("rsgf-lattice", bake(Method::Rsgf, "tiles/x3p-2-crop.npy")),
        ],
        "synth" => vec![write_bank(
            "synth",
            bake(Method::Synth, "tests/data/gimp-dried-mud.png"),
        )],
        "quilting" => vec![write_bank(
            "quilting",
            bake(Method::Quilting, "tests/data/gimp-dried-mud.png"),
        )],
        "milling" => {
            let (config, _) = MillingConfig::load("spiral-d4-ae05".as_ref()).unwrap();
            let bank = MillingSurface::new(&config, 8.0, 0)
                .unwrap()
                .to_bank("spiral-d4-ae05")
                .unwrap();
            vec![
                "parallel-d4-ae05".into(),
                common::repo("tiles/milling/parallel-d8-ae08.toml")
                    .display()
                    .to_string(),
                write_bank("milling", bank),
            ]
        }
        "models" => vec!["rock".into(), "cells-convex".into()],
        other => panic!("kind {other} is registered but has no example in tests/conformance.rs"),
    }
}

/// A region of `w × h` at (x, y), filled on `threads` threads.
fn filled(s: &dyn Surface, region: &Region, threads: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; region.len() * s.channels()];
    fill_parallel(s, region, &mut out, threads).unwrap();
    out
}

fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// Split invariance: 4 random sub-regions of a region at (x, y) with `step` equal the
/// whole on 1 and 2 threads.
fn split_invariance(
    name: &str,
    s: &dyn Surface,
    (x, y, step): (f64, f64, f64),
    rng: &mut Xoshiro256PlusPlus,
) {
    let c = s.channels();
    let whole_region = Region::new(x, y, 96, 72).with_step(step);
    let whole = filled(s, &whole_region, 2);
    assert!(
        whole.iter().all(|v| v.is_finite()),
        "{name}: non-finite values at ({x}, {y})"
    );
    for k in 0..4 {
        let (w, h) = (rng.random_range(1..=60usize), rng.random_range(1..=50usize));
        let (col, row) = (rng.random_range(0..=96 - w), rng.random_range(0..=72 - h));
        let sub = whole_region.sub(col, row, w, h).unwrap();
        for threads in [1, 2] {
            let part = filled(s, &sub, threads);
            for r in 0..h {
                let from = ((row + r) * 96 + col) * c;
                assert!(
                    same_bits(
                        &part[r * w * c..(r + 1) * w * c],
                        &whole[from..from + w * c]
                    ),
                    "{name}: sub-region {k} ({col}, {row}, {w}×{h}) at ({x}, {y}) step {step} differs from the whole on {threads} thread(s), row {r}"
                );
            }
        }
    }
}

/// fill ⇄ sample at 40 random pixels of a region, at step 1 and step 3.
fn fill_matches_sample(name: &str, s: &dyn Surface, rng: &mut Xoshiro256PlusPlus) {
    let c = s.channels();
    for (x, y, step) in [
        (-37.25, 12.5, 1.0),
        (1e9 + 0.5, -3e8, 1.0),
        (500.0, -20.0, 3.0),
        (-7.0, 3.5, 0.75),
    ] {
        let region = Region::new(x, y, 48, 40).with_step(step);
        let out = filled(s, &region, 2);
        let mut v = vec![0.0f32; c];
        for _ in 0..40 {
            let (col, row) = (rng.random_range(0..48), rng.random_range(0..40));
            s.sample_footprint(region.x_at(col), region.y_at(row), step, &mut v);
            let at = (row * 48 + col) * c;
            assert!(
                same_bits(&v, &out[at..at + c]),
                "{name}: sample {v:?} ≠ fill {:?} at ({col}, {row}) of ({x}, {y}) step {step}",
                &out[at..at + c]
            );
        }
    }
}

/// NaN samples and refused fills outside the coordinate range.
fn refuses_outside(name: &str, s: &dyn Surface) {
    let mut v = vec![0.0f32; s.channels()];
    for (x, y) in [
        (f64::NAN, 0.0),
        (0.0, f64::NAN),
        (2.0 * MAX_COORDINATE, 0.0),
        (0.0, -2.0 * MAX_COORDINATE),
        (f64::INFINITY, 1.0),
    ] {
        s.sample(x, y, &mut v);
        assert!(
            v.iter().all(|v| v.is_nan()),
            "{name}: sample at ({x}, {y}) is {v:?}"
        );
        assert!(s.height(x, y).is_nan(), "{name}: height at ({x}, {y})");
    }
    for region in [
        Region::new(2.0 * MAX_COORDINATE, 0.0, 8, 8),
        Region::new(f64::NAN, 0.0, 8, 8),
        Region::new(MAX_COORDINATE - 4.0, 0.0, 8, 8),
    ] {
        let mut out = vec![0.0f32; 64 * s.channels()];
        let e = s.fill(&region, &mut out);
        assert!(
            e.is_err(),
            "{name}: a fill at ({}, {}) was not refused",
            region.x,
            region.y
        );
        let text = e.unwrap_err().to_string();
        assert!(!text.contains('\n'), "{name}: one line: {text}");
    }
}

/// Seconds of the fastest of 3 fills of a 128 × 96 region at (x, y).
fn fill_seconds(s: &dyn Surface, x: f64, y: f64) -> f64 {
    (0..3)
        .map(|k| {
            // A new region each time (shifted by a block), so caches of the last fill
            // do not serve it.
            let region = Region::new(x + 4096.0 * k as f64, y, 128, 96);
            let start = Instant::now();
            filled(s, &region, 2);
            start.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The same cost far away: within 4× (plus 50 ms of slack) of the origin's.
fn same_cost_far_away(name: &str, s: &dyn Surface) {
    let near = fill_seconds(s, 0.0, 0.0);
    let far = fill_seconds(s, 1e12, -1e12);
    assert!(
        far <= 4.0 * near + 0.05,
        "{name}: a fill at (10¹², −10¹²) took {far:.3} s against {near:.3} s at the origin"
    );
}

#[test]
fn every_kind_conforms() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(31);
    let mut checked = Vec::new();
    for kind in KINDS {
        for spec in examples(kind.name()) {
            let source = surftile::open(&spec).unwrap_or_else(|e| panic!("{spec}: {e}"));
            assert_eq!(
                source.kind().name(),
                kind.name(),
                "{spec} opened as the wrong kind"
            );
            let surface = source.surface(5).unwrap();
            let name = format!("{} ({spec})", kind.name());
            let s = surface.as_ref();
            for at in [
                (3.5, -7.25, 1.0),
                (-1e9, 2.5e8, 1.0),
                (-12345.5, 678.25, 2.5),
                (1e12, -1e12, 0.75),
            ] {
                split_invariance(&name, s, at, &mut rng);
            }
            fill_matches_sample(&name, s, &mut rng);
            refuses_outside(&name, s);
            same_cost_far_away(&name, s);
            checked.push(name);
        }
    }
    eprintln!("conformance: {}", checked.join("; "));
    assert!(checked.len() >= KINDS.len());
}

/// The registry answers for every bank rule, and its lines for `info` are one per line.
#[test]
fn every_rule_has_one_kind() {
    use surftile::bank::Rule;
    for rule in [
        Rule::Blend,
        Rule::Toroidal,
        Rule::Wang,
        Rule::Rsgf,
        Rule::Synth,
        Rule::Quilting,
        Rule::Milling,
    ] {
        let kinds: Vec<&str> = KINDS
            .iter()
            .filter(|k| k.rule() == Some(rule))
            .map(|k| k.name())
            .collect();
        assert_eq!(kinds.len(), 1, "{rule}: {kinds:?}");
    }
}

/// The suite can fail: a surface whose fill depends on where a region starts (a split
/// shows), and one whose samples disagree with its fill, are both caught.
#[test]
fn the_checks_catch_broken_surfaces() {
    use std::ops::Range;
    struct Broken {
        inner: Box<dyn Surface>,
        /// Adds the region's column offset to filled values (split-dependent).
        by_split: bool,
    }
    impl Surface for Broken {
        fn channels(&self) -> usize {
            self.inner.channels()
        }
        fn sample_footprint(&self, x: f64, y: f64, footprint: f64, out: &mut [f32]) {
            self.inner.sample_footprint(x, y, footprint, out);
        }
        fn fill_rows(&self, region: &Region, rows: Range<usize>, out: &mut [f32]) {
            self.inner.fill_rows(region, rows, out);
            let bias = if self.by_split {
                region.col0 as f32
            } else {
                1e-3
            };
            out.iter_mut().for_each(|v| *v += bias);
        }
    }
    let surface = |by_split| Broken {
        inner: surftile::open("rock").unwrap().surface(1).unwrap(),
        by_split,
    };
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
    let split = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        split_invariance("broken", &surface(true), (0.0, 0.0, 1.0), &mut rng)
    }));
    assert!(
        split.is_err(),
        "a split-dependent fill passed split invariance"
    );
    let twin = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        fill_matches_sample("broken", &surface(false), &mut rng)
    }));
    assert!(
        twin.is_err(),
        "a fill that is not its samples passed fill ⇄ sample"
    );
}

/// A model kind's record is checked by its kind: a bank whose container is sound but
/// whose synth candidates, RSGF parameters or milling tables are not is refused when read
/// through the registry, written through it, or opened, with one line naming the bank.
#[test]
fn kinds_refuse_broken_records() {
    use surftile::bank::Record;
    let dir = tempfile::tempdir().unwrap();
    let mut broken = Vec::new();
    // A synth candidate outside the exemplar.
    let mut synth = bake(Method::Synth, "tests/data/gimp-dried-mud.png");
    let last = synth.extra[0].len() - 1;
    synth.extra[0][last] = 1e9;
    broken.push(("synth", synth, "candidates outside the exemplar"));
    // RSGF blocks of 0 px.
    let mut rsgf = bake(Method::Rsgf, "tests/data/gimp-dried-mud.png");
    if let Record::Rsgf(v) = &mut rsgf.header.record {
        v["block_px"] = 0.into();
    }
    broken.push(("rsgf", rsgf, "block"));
    // A milling shape table outside [−1, 1].
    let (config, _) = MillingConfig::load("parallel-d4-ae05".as_ref()).unwrap();
    let mut milling = MillingSurface::new(&config, 6.1, 0)
        .unwrap()
        .to_bank("parallel-d4-ae05")
        .unwrap();
    milling.luts[0][7] = 2.0;
    broken.push(("milling", milling, "outside [−1, 1]"));
    for (name, bank, word) in broken {
        let path = dir.path().join(format!("{name}.bank"));
        // The container is sound: it writes and reads as bytes.
        bank.write(&path).unwrap();
        Bank::read(&path).unwrap();
        for e in [
            surftile::kinds::read_bank(&path).unwrap_err(),
            surftile::open(&path).err().unwrap(),
            surftile::kinds::open(&bank, 0).err().unwrap(),
            surftile::kinds::write_bank(&bank, &dir.path().join("out.bank")).unwrap_err(),
        ] {
            let text = e.to_string();
            assert!(text.contains(word), "{name}: {text}");
            assert!(!text.contains('\n'), "{name}: one line: {text}");
        }
        assert!(
            !dir.path().join("out.bank").exists(),
            "{name}: written anyway"
        );
    }
}
