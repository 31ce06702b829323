//! Format stability: `tests/data/golden-v1.bank` was written by the first build of the v1
//! format (`cargo test --release --test golden_bank -- --ignored` rewrites it; do that
//! only when the format version changes). Every later build must read it, describe it
//! as baked, write it back byte for byte, and sample it as the rule defines.

mod common;

use surftile::Raster;
use surftile::analysis::gauss::lut_eval;
use surftile::bake::Baker;
use surftile::bank::{Bank, Method, Rule};
use surftile::hash::{hash_vertex, pick_tile};
use surftile::io::ImageFile;
use surftile::stream::{BlendSurface, Surface};

const GOLDEN: &str = "tests/data/golden-v1.bank";

/// The synthetic exemplar the golden bank was baked from.
fn exemplar() -> ImageFile {
    let (w, h) = (32, 32);
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            (0.7 * x).sin() + 0.5 * (0.45 * y + 0.3 * x).cos() + ((i * 7919) % 13) as f32 * 0.05
        })
        .collect();
    ImageFile::new(Raster::from_vec(w, h, 1, data).unwrap(), Some(2.5))
}

#[test]
#[ignore = "rewrites the golden file; run only when the bank format version changes"]
fn regenerate_golden_bank() {
    let bank = Baker::builder()
        .patch(8)
        .bank_size(2)
        .seed(5)
        .build()
        .unwrap()
        .bake(&exemplar(), "synthetic", &mut |_| {})
        .unwrap();
    bank.write(&common::repo(GOLDEN)).unwrap();
}

#[test]
fn golden_bank_reads_and_says_what_it_is() {
    let bank = Bank::read(&common::repo(GOLDEN)).expect("the golden v1 bank must stay readable");
    let h = &bank.header;
    assert_eq!(
        (h.rule(), h.method, h.channels, h.tiles),
        (Rule::Blend, Method::Rpn, 1, 2)
    );
    assert_eq!(h.tile_size, [8, 8]);
    assert_eq!(h.triangle_edge(), 4.0);
    assert_eq!(h.spacing_um, Some(2.5));
    assert_eq!(h.seed, 5);
    assert_eq!(h.levels.len(), 2, "8 → 4 texels");
    assert_eq!((h.exemplar.width, h.exemplar.height), (32, 32));
}

#[test]
fn golden_bank_writes_back_byte_for_byte() {
    let bytes = std::fs::read(common::repo(GOLDEN)).unwrap();
    let bank = Bank::from_bytes(&bytes, "golden").unwrap();
    let again = bank.to_bytes().unwrap();
    let first_diff = again.iter().zip(&bytes).position(|(a, b)| a != b);
    assert!(
        again.len() == bytes.len() && first_diff.is_none(),
        "rewritten bank differs: {} vs {} bytes, first difference at {first_diff:?}",
        again.len(),
        bytes.len()
    );
}

/// At a triangle-grid vertex the blend has one weight of 1, so the surface equals
/// T⁻¹ of the vertex's hashed tile at its hashed offset: computed here from the raw
/// texels, the hash and the table, independently of the runtime.
#[test]
fn golden_bank_samples_its_vertices_as_the_rule_says() {
    let bank = Bank::read(&common::repo(GOLDEN)).unwrap();
    let h = &bank.header;
    let (e, [w, _]) = (h.triangle_edge(), h.tile_size);
    let seed = 11u32;
    let surface = BlendSurface::new(&bank, seed).unwrap();
    // Vertices with j = 0 lie at (E·i, 0): integer coordinates for E = 4.
    for i in -5i64..5 {
        let (x, y) = (e * i as f64, 0.0);
        let hsh = hash_vertex(seed, i, 0);
        let tile = pick_tile(hsh[0], h.tiles as u32) as usize;
        let (ox, oy) = ((hsh[1] & 7) as usize, ((hsh[1] >> 16) & 7) as usize);
        let tx = ((x as i64 + ox as i64).rem_euclid(8)) as usize;
        let g = bank.texels[0][tile * 64 + oy * w + tx] as f64;
        let z = ((g - h.levels[0].mean[0]) / h.levels[0].sigma[0]) as f32;
        let expected = lut_eval(&bank.luts[0], z, h.lut_z_range() as f32);
        let got = surface.height(x, y);
        assert!(
            (got - expected).abs() <= 1e-6 * expected.abs().max(1.0),
            "vertex {i}: {got} vs {expected}"
        );
    }
}

/// Re-frames a header and payload as a bank file with a correct checksum.
fn frame(version: u32, header: &[u8], payload: &[u8]) -> Vec<u8> {
    let mut out = b"SURFTILE".to_vec();
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    out.extend_from_slice(header);
    out.extend_from_slice(payload);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Validation beyond the checksum: a header that disagrees with the data, non-finite
/// texels and a newer version are each refused with a message that names the problem.
#[test]
fn validation_catches_what_a_checksum_cannot() {
    let bytes = std::fs::read(common::repo(GOLDEN)).unwrap();
    let header_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let header: serde_json::Value = serde_json::from_slice(&bytes[16..16 + header_len]).unwrap();
    let payload = &bytes[16 + header_len..bytes.len() - 4];

    let mut more_tiles = header.clone();
    more_tiles["tiles"] = serde_json::json!(3);
    let e = Bank::from_bytes(
        &frame(1, &serde_json::to_vec(&more_tiles).unwrap(), payload),
        "x",
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("shorter than the header says"),
        "{e}"
    );

    let mut nan_payload = payload.to_vec();
    nan_payload[40..44].copy_from_slice(&f32::NAN.to_le_bytes());
    let e =
        Bank::from_bytes(&frame(1, &bytes[16..16 + header_len], &nan_payload), "x").unwrap_err();
    assert!(e.to_string().contains("not finite"), "{e}");

    let e = Bank::from_bytes(&frame(2, &bytes[16..16 + header_len], payload), "x").unwrap_err();
    assert!(e.to_string().contains("format version 2"), "{e}");

    let e = Bank::from_bytes(&frame(1, b"{not json", payload), "x").unwrap_err();
    assert!(e.to_string().contains("header is not valid"), "{e}");
}

/// Banks of the model kinds written by commit 78e00e5, before the header became common
/// fields plus a per-rule record (tests/data/README.md says how they were made): each
/// reads and is checked through the registry, says what it is, and samples what that
/// build's `surftile sample --seed 3` printed, bit for bit.
#[test]
fn model_kind_banks_of_the_first_v1_builds_read_and_sample_the_same() {
    /// (x, y, what the old build printed there).
    type Samples = [(f64, f64, &'static str); 3];
    let cases: [(&str, Rule, Samples); 3] = [
        (
            "tests/data/golden-v1-rsgf.bank",
            Rule::Rsgf,
            [
                (3.5, -7.25, "0.0100589525"),
                (1e9, 42.5, "0.0010944817"),
                (-123456.0, 0.75, "0.004860184"),
            ],
        ),
        (
            "tests/data/golden-v1-synth.bank",
            Rule::Synth,
            [
                (3.5, -7.25, "-0.00261829"),
                (1e9, 42.5, "-0.0042008045"),
                (-123456.0, 0.75, "-0.0015097684"),
            ],
        ),
        (
            "tests/data/golden-v1-milling.bank",
            Rule::Milling,
            [
                (3.5, -7.25, "0.25985724"),
                (1e9, 42.5, "-0.41195816"),
                (-123456.0, 0.75, "0.13323636"),
            ],
        ),
    ];
    for (file, rule, samples) in cases {
        let bank = surftile::kinds::read_bank(&common::repo(file))
            .unwrap_or_else(|e| panic!("{file} must stay readable: {e}"));
        assert_eq!(bank.header.rule(), rule, "{file}");
        assert!(!surftile::kinds::describe(&bank).unwrap().is_empty());
        let surface = surftile::kinds::open(&bank, 3).unwrap();
        for (x, y, printed) in samples {
            let want: f32 = printed.parse().unwrap();
            assert_eq!(
                surface.height(x, y).to_bits(),
                want.to_bits(),
                "{file} at ({x}, {y})"
            );
        }
    }
}
