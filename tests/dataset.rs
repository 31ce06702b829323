//! Datasets (issue 35): shards are the same bytes on any thread count and in any order,
//! samples equal the surfaces they record, draws follow the spec's weights and
//! probabilities, a rerun resumes, a changed spec is refused, and bad specs are refused
//! by name with nothing written.

use std::path::{Path, PathBuf};

use surftile::dataset::{Dataset, INDEX_FILE};
use surftile::defects::{DefectConfig, Defected, Defects};
use surftile::imperfect::{Imperfect, ImperfectConfig};
use surftile::stream::{Region, Surface};

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")
}

/// Two sources (an RPN bank and a milling preset), a dust layer on half the samples,
/// scratches and dents; 10 samples of 48 × 40 in shards of 4 (the last holds 2).
const SPEC: &str = r#"
[dataset]
samples = 10
samples_per_shard = 4
seed = 11
size = [48, 40]
spacing_um = 2.0
outputs = ["height", "mask", "json", "shaded"]

[[source]]
path = "golden-v1.bank"
weight = 1.0

[[source]]
path = "parallel-d4-ae05"
weight = 1.0

[[layer]]
config = "dust"
probability = 0.5
age = [0.5, 1.5]

[[defect]]
kind = "scratch"
probability = 0.8
cell_um = 60.0
cell_probability = 0.9
length_um = [20.0, 60.0]
width_um = [3.0, 6.0]
depth_um = [1.0, 3.0]
profile = "v"

[[defect]]
kind = "dent"
probability = 0.6
cell_um = 50.0
cell_probability = 0.8
diameter_um = [8.0, 16.0]
depth_um = [1.0, 3.0]
rim = [0.1, 0.2]
"#;

fn dataset(text: &str) -> Dataset {
    Dataset::from_toml(text, &data(), "test.toml").unwrap()
}

fn error(text: &str) -> String {
    match Dataset::from_toml(text, &data(), "test.toml") {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn shard_bytes(dir: &Path, shards: u64) -> Vec<Vec<u8>> {
    (0..shards)
        .map(|s| std::fs::read(dir.join(Dataset::shard_name(s))).unwrap())
        .collect()
}

#[test]
fn shards_are_the_same_bytes_on_any_thread_count_and_in_any_order() {
    let d = dataset(SPEC);
    assert_eq!(d.shards(), 3);
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let (prepared, written) = d.run(a.path(), 0..3, 2, false, &mut |_| {}).unwrap();
    assert_eq!(prepared.todo, vec![0, 1, 2]);
    assert_eq!(
        written.iter().map(|w| w.samples).collect::<Vec<_>>(),
        vec![4, 4, 2]
    );
    // Another folder, one thread, shards in reverse order, each prepared alone.
    for s in [2, 1, 0] {
        d.prepare(b.path(), s..s + 1, false).unwrap();
        d.write_shard(s, b.path(), 1, &mut |_| {}).unwrap();
    }
    assert_eq!(shard_bytes(a.path(), 3), shard_bytes(b.path(), 3));
    assert_eq!(
        std::fs::read(a.path().join(INDEX_FILE)).unwrap(),
        std::fs::read(b.path().join(INDEX_FILE)).unwrap()
    );
    // A spec loaded again (another process, another machine) gives the same hash.
    assert_eq!(dataset(SPEC).hash(), d.hash());
    // The members, in order, and nothing else (no temporary files left).
    for s in 0..3 {
        assert!(d.shard_is_complete(&a.path().join(Dataset::shard_name(s)), s));
    }
    let names: Vec<_> = std::fs::read_dir(a.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 4, "{names:?}");
}

/// Heights and mask of sample k rebuilt from its JSON with the library's surfaces:
/// the source placed with the recorded seed, the drawn defect entries, the layer with
/// its age, over the recorded region (each filled on all cores, in one call).
fn rebuilt(d: &Dataset, meta: &serde_json::Value) -> (Vec<f32>, Vec<u8>) {
    let spec = d.spec();
    let entry = meta["source"]["entry"].as_u64().unwrap() as usize;
    let p = &spec.source[entry].path;
    let path = if data().join(p).exists() {
        data().join(p)
    } else {
        PathBuf::from(p)
    };
    let source = surftile::Open::new(path)
        .spacing_um(spec.dataset.spacing_um)
        .open()
        .unwrap();
    let seed = meta["seed"].as_u64().unwrap() as u32;
    let r = &meta["region"];
    let region = Region::new(
        r["x"].as_f64().unwrap(),
        r["y"].as_f64().unwrap(),
        r["width"].as_u64().unwrap() as usize,
        r["height"].as_u64().unwrap() as usize,
    );
    let n = region.width * region.height;
    let mut surface = source.loaded().surface(seed).unwrap();
    let mut defects = None;
    if let Some(entries) = meta.get("defect_entries") {
        let config = DefectConfig {
            defect: entries
                .as_array()
                .unwrap()
                .iter()
                .map(|e| spec.defect[e.as_u64().unwrap() as usize].defect.clone())
                .collect(),
        };
        let spacing = meta["spacing_um"].as_f64().unwrap();
        let found = Defects::new(&config, spacing, &source.height_unit(), seed).unwrap();
        defects = Some(found.clone());
        surface = Box::new(Defected::new(surface, found).unwrap());
    }
    let mut ids = vec![0u8; n];
    let heights = if meta["layer"].is_null() {
        let mut h = vec![0.0f32; n];
        surface.fill(&region, &mut h).unwrap();
        h
    } else {
        let layer = &meta["layer"];
        let (mut config, base) =
            ImperfectConfig::load(Path::new(layer["config"].as_str().unwrap())).unwrap();
        config.age = layer["age"].as_f64().unwrap();
        let imperfect = Imperfect::new(surface, &config, base.as_deref(), seed).unwrap();
        let fill = imperfect.fill_layers(&region).unwrap();
        let offset = layer["mask_id_offset"].as_u64().unwrap() as u8;
        for (o, &l) in ids.iter_mut().zip(&fill.layers) {
            *o = if l == 0 { 0 } else { l + offset };
        }
        fill.heights
    };
    if let Some(found) = defects {
        let mut extra = vec![0u8; n];
        found.fill_ids(&region, &mut extra).unwrap();
        for (o, &e) in ids.iter_mut().zip(&extra) {
            if e != 0 {
                *o = e;
            }
        }
    }
    (heights, ids)
}

#[test]
fn samples_equal_the_surfaces_they_record() {
    let d = dataset(SPEC);
    let (mut layered, mut defected, mut marked) = (0, 0, 0);
    for k in 0..d.samples() {
        let s = d.sample(k).unwrap();
        let (heights, ids) = rebuilt(&d, &s.meta);
        let same = heights
            .iter()
            .zip(&s.heights.data)
            .all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(same, "sample {k}: heights differ from the rebuilt surface");
        assert_eq!(s.mask.as_deref(), Some(&ids[..]), "sample {k}: mask");
        // Every defect pixel of the mask lies in the mask box of a defect of its id.
        let boxes: Vec<(u64, [u64; 4])> = s.meta["defects"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|p| !p["mask_box"].is_null())
            .map(|p| {
                let b = &p["mask_box"];
                let b = [0, 1, 2, 3].map(|i| b[i].as_u64().unwrap());
                assert!(
                    b[0] <= b[2] && b[2] < 48 && b[1] <= b[3] && b[3] < 40,
                    "{b:?}"
                );
                (p["mask_id"].as_u64().unwrap(), b)
            })
            .collect();
        for (i, &id) in ids.iter().enumerate() {
            let (col, row) = ((i % 48) as u64, (i / 48) as u64);
            if id >= 16 {
                let covered = boxes.iter().any(|&(bid, b)| {
                    bid == id as u64 && (b[0]..=b[2]).contains(&col) && (b[1]..=b[3]).contains(&row)
                });
                assert!(
                    covered,
                    "sample {k}: ({col}, {row}) id {id} outside the boxes"
                );
            }
        }
        layered += !s.meta["layer"].is_null() as usize;
        defected += s.meta.get("defect_entries").is_some() as usize;
        marked += ids.iter().any(|&i| i >= 16) as usize;
        // Every recorded defect lies within its drawn ranges, its box meets the region.
        for p in s.meta["defects"].as_array().unwrap() {
            let entry = &d.spec().defect[p["entry"].as_u64().unwrap() as usize].defect;
            let json = serde_json::to_value(entry).unwrap();
            let depth = p["depth_um"].as_f64().unwrap();
            let span = &json["depth_um"];
            let (lo, hi) = (span[0].as_f64().unwrap(), span[1].as_f64().unwrap());
            assert!(
                depth >= lo * (1.0 - 1e-9) && depth <= hi * (1.0 + 1e-9),
                "sample {k}: depth {depth} outside [{lo}, {hi}]"
            );
            let b = &p["bbox"];
            assert!(b[2].as_f64().unwrap() >= s.draw.x as f64);
            assert!(b[0].as_f64().unwrap() <= (s.draw.x + 47) as f64);
        }
    }
    // The spec's probabilities give every case among ten samples.
    assert!((2..=8).contains(&layered), "{layered} of 10 with a layer");
    assert!(defected >= 5, "{defected} of 10 with defects");
    assert!(marked >= 3, "{marked} of 10 with defect pixels in the mask");
}

#[test]
fn draws_follow_the_spec_weights_and_probabilities() {
    let text =
        SPEC.replace("samples = 10", "samples = 20000")
            .replacen("weight = 1.0", "weight = 3.0", 1);
    let d = dataset(&text);
    let n = d.samples();
    let (mut first, mut layer, mut scratch, mut dent) = (0u64, 0u64, 0u64, 0u64);
    let e = d.spec().dataset.extent_px as i64;
    for k in 0..n {
        let draw = d.draw(k);
        first += (draw.source == 0) as u64;
        layer += draw.layer.is_some() as u64;
        scratch += draw.defects.contains(&0) as u64;
        dent += draw.defects.contains(&1) as u64;
        assert!((-e..e).contains(&draw.x) && (-e..e).contains(&draw.y));
        if let Some((_, age)) = draw.layer {
            assert!((0.5..=1.5).contains(&age));
        }
        assert_eq!(draw, d.draw(k), "a draw is a pure function of k");
    }
    let f = |c: u64| c as f64 / n as f64;
    // Binomial standard errors at 20000 draws are below 0.0036: 0.015 is over 4 of them.
    assert!((f(first) - 0.75).abs() < 0.015, "source 1: {}", f(first));
    assert!((f(layer) - 0.5).abs() < 0.015, "layer: {}", f(layer));
    assert!((f(scratch) - 0.8).abs() < 0.015, "scratch: {}", f(scratch));
    assert!((f(dent) - 0.6).abs() < 0.015, "dent: {}", f(dent));
    // Another seed, other draws.
    let other = dataset(&text.replace("seed = 11", "seed = 12"));
    let differ = (0..100).filter(|&k| other.draw(k) != d.draw(k)).count();
    assert_eq!(differ, 100);
}

#[test]
fn a_rerun_keeps_complete_shards_and_rewrites_the_rest() {
    let d = dataset(SPEC);
    let dir = tempfile::tempdir().unwrap();
    d.run(dir.path(), 0..3, 2, false, &mut |_| {}).unwrap();
    let before = shard_bytes(dir.path(), 3);
    // Shard 0 lost, shard 1 cut short (a copy, not a shard this code wrote), a
    // temporary file of an interrupted write of shard 2.
    std::fs::remove_file(dir.path().join(Dataset::shard_name(0))).unwrap();
    let one = dir.path().join(Dataset::shard_name(1));
    std::fs::write(&one, &before[1][..before[1].len() / 2]).unwrap();
    let temp = dir.path().join(".shard-000002.tar.part-99999");
    std::fs::write(&temp, b"partial").unwrap();
    let (prepared, written) = d.run(dir.path(), 0..3, 2, false, &mut |_| {}).unwrap();
    assert_eq!(prepared.todo, vec![0, 1]);
    assert_eq!(prepared.complete, vec![2]);
    assert_eq!(prepared.broken, vec![1]);
    assert_eq!(written.len(), 2);
    assert!(!temp.exists(), "the interrupted write's file is removed");
    assert_eq!(shard_bytes(dir.path(), 3), before);
    // Everything complete: nothing to do.
    let (prepared, written) = d.run(dir.path(), 0..3, 2, false, &mut |_| {}).unwrap();
    assert_eq!((prepared.complete.len(), written.len()), (3, 0));
}

#[test]
fn a_changed_spec_is_refused_unless_forced() {
    let d = dataset(SPEC);
    let dir = tempfile::tempdir().unwrap();
    d.run(dir.path(), 0..1, 1, false, &mut |_| {}).unwrap();
    let changed = dataset(&SPEC.replace("seed = 11", "seed = 13"));
    assert_ne!(changed.hash(), d.hash());
    let index = std::fs::read(dir.path().join(INDEX_FILE)).unwrap();
    let shard = std::fs::read(dir.path().join(Dataset::shard_name(0))).unwrap();
    let e = changed
        .prepare(dir.path(), 0..3, false)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("of another spec") && e.contains("--force"),
        "{e}"
    );
    let e = changed
        .write_shard(0, dir.path(), 1, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("of another spec"), "{e}");
    // Refused: nothing changed.
    assert_eq!(std::fs::read(dir.path().join(INDEX_FILE)).unwrap(), index);
    assert_eq!(
        std::fs::read(dir.path().join(Dataset::shard_name(0))).unwrap(),
        shard
    );
    // Forced: the old shards go, the new index is written.
    let p = changed.prepare(dir.path(), 1..2, true).unwrap();
    assert_eq!(p.todo, vec![1]);
    assert!(!dir.path().join(Dataset::shard_name(0)).exists());
    let text = std::fs::read_to_string(dir.path().join(INDEX_FILE)).unwrap();
    assert!(text.contains(changed.hash()));
}

#[test]
fn each_layer_entry_has_mask_ids_of_its_own() {
    let text = SPEC.replace(
        "probability = 0.5\nage = [0.5, 1.5]",
        "probability = 0.3\nage = [0.5, 1.5]\n\n[[layer]]\nconfig = \"peeling\"\nprobability = 0.7",
    );
    let d = dataset(&text);
    let legend = &d.index()["mask_legend"];
    assert_eq!(legend["1"], "layer 1: dust");
    let peeling = ImperfectConfig::load(Path::new("peeling")).unwrap().0;
    let levels = peeling.layers.thresholds.len();
    for level in 1..=levels {
        assert_eq!(
            legend[(1 + level).to_string()],
            format!("layer 2: peeling level {level}")
        );
    }
    assert_eq!(legend["16"], "scratch");
    assert_eq!(legend["17"], "dent");
    // A sample under the peeling layer has its ids shifted past dust's.
    let k = (0..d.samples())
        .find(|&k| matches!(d.draw(k).layer, Some((1, _))))
        .expect("a sample with the peeling layer");
    let s = d.sample(k).unwrap();
    assert_eq!(s.meta["layer"]["mask_id_offset"], 1);
    let ids: std::collections::BTreeSet<u8> = s.mask.unwrap().into_iter().collect();
    assert!(!ids.contains(&1), "dust's id in a peeling sample: {ids:?}");
    assert!(ids.iter().all(|&i| i == 0 || i >= 2), "{ids:?}");
}

/// The spec with `from` replaced by `to` (which must occur).
fn with(from: &str, to: &str) -> String {
    assert!(SPEC.contains(from), "{from}");
    SPEC.replacen(from, to, 1)
}

#[test]
fn bad_specs_are_refused_by_name_and_nothing_is_written() {
    let no_sources = {
        let start = SPEC.find("[[source]]").unwrap();
        let end = SPEC.find("[[layer]]").unwrap();
        format!("{}{}", &SPEC[..start], &SPEC[end..])
    };
    let cases: Vec<(String, &str)> = vec![
        (
            with("seed = 11", "seed = 11\ncolour = 3"),
            "unknown field `colour`",
        ),
        (with("weight = 1.0", "weight = 0.0"), "source 1: weight = 0"),
        (
            with("weight = 1.0", "weight = -2.0"),
            "source 1: weight = -2",
        ),
        (no_sources, "at least one [[source]]"),
        (
            with("probability = 0.5", "probability = 1.5"),
            "layer 1: probability = 1.5",
        ),
        (
            with("probability = 0.8", "probability = -0.1"),
            "defect 1: probability = -0.1",
        ),
        (
            with("cell_probability = 0.9", "cell_probability = 2.0"),
            "defect 1 (scratch): cell_probability = 2",
        ),
        (
            with("depth_um = [1.0, 3.0]", "depth_um = [1.0, 5000.0]"),
            "at most 1000",
        ),
        (with("samples = 10", "samples = 0"), "dataset.samples = 0"),
        (with("size = [48, 40]", "size = [48, 100000]"), "size[1]"),
        (with("spacing_um = 2.0", "spacing_um = nan"), "spacing_um"),
        (
            with("path = \"golden-v1.bank\"", "path = \"missing.bank\""),
            "missing.bank",
        ),
        (with("config = \"dust\"", "config = \"dusty\""), "dusty"),
        (
            with("probability = 0.5", "probability = 0.5\nage = [2.0, 1.0]").replacen(
                "age = [0.5, 1.5]\n",
                "",
                1,
            ),
            "age = [2, 1]",
        ),
        (
            with("rim = [0.1, 0.2]", "rim = [0.1, 0.2]\nmask_id = 1"),
            "mask_id = 1",
        ),
    ];
    for (text, expected) in &cases {
        let e = error(text);
        assert!(e.contains(expected), "expected {expected:?} in: {e}");
        assert!(!e.contains('\n'), "one line: {e}");
    }
    // A folder that is a file, and a range outside the dataset: refused before
    // anything is written.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("out");
    std::fs::write(&file, b"not a folder").unwrap();
    let d = dataset(SPEC);
    let e = d.prepare(&file, 0..3, false).unwrap_err().to_string();
    assert!(e.contains("this is a file"), "{e}");
    assert_eq!(std::fs::read(&file).unwrap(), b"not a folder");
    let fresh = dir.path().join("fresh");
    let e = d.prepare(&fresh, 2..5, false).unwrap_err().to_string();
    assert!(e.contains("within 0..3"), "{e}");
    assert!(!fresh.exists());
}
