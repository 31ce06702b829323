//! Issue 33's findings: input whose checksum and syntax are right and whose content is
//! absurd gets one clear line, never a panic, a hang or a huge allocation. Each test here
//! failed (panicked, hung, aborted or accepted the input) before its fix.

mod common;

use surftile::bake::Baker;
use surftile::bank::{Bank, Method};
use surftile::io::{Format, ReadOptions, read_image, read_image_bytes};

/// A bank's bytes with its JSON header rewritten by `edit` and the checksum recomputed.
fn with_header(bytes: &[u8], edit: impl Fn(&mut serde_json::Value)) -> Vec<u8> {
    let header_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let mut header: serde_json::Value =
        serde_json::from_slice(&bytes[16..16 + header_len]).unwrap();
    edit(&mut header);
    let header = serde_json::to_vec(&header).unwrap();
    let mut out = bytes[..12].to_vec();
    out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    out.extend_from_slice(&header);
    out.extend_from_slice(&bytes[16 + header_len..bytes.len() - 4]);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

fn one_line(e: impl std::fmt::Display) -> String {
    let text = e.to_string();
    assert!(!text.contains('\n'), "one line: {text}");
    text
}

/// Finding 1: sizes in a bank header whose byte counts overflow (a huge table, a huge
/// level) are refused as truncated data, not a wrapped slice index.
#[test]
fn bank_sizes_cannot_overflow_the_reader() {
    let golden = std::fs::read(common::repo("tests/data/golden-v1.bank")).unwrap();
    let huge_table = with_header(&golden, |h| h["lut_size"] = 4611686018427387903u64.into());
    let huge_level = with_header(&golden, |h| {
        h["levels"][1]["size"] = serde_json::json!([4611686018427387903u64, 1]);
    });
    for bytes in [huge_table, huge_level] {
        let e = one_line(Bank::from_bytes(&bytes, "crafted").unwrap_err());
        assert!(e.contains("crafted"), "{e}");
    }
}

/// Finding 2: lattice vectors with components near i64::MIN are refused up front (they
/// overflowed the extended Euclid of the Hermite normal form).
#[test]
fn absurd_lattice_vectors_are_refused() {
    for method in [Method::Roller, Method::Rsgf] {
        let e = Baker::builder()
            .method(method)
            .lattice((0, i64::MIN), (1, -1))
            .build()
            .unwrap_err();
        assert!(one_line(e).contains("2^30"));
    }
    assert!(surftile::lattice::Lattice::from_basis((i64::MAX, 0), (0, 1)).is_err());
}

/// Finding 4: an RSGF lattice whose cell is taller than the exemplar's patch positions
/// is refused at once (it hung in the search for near residues).
#[test]
fn an_rsgf_cell_larger_than_the_exemplar_is_refused() {
    let ex = read_image(
        &common::repo("tiles/x3p-2-crop.npy"),
        &ReadOptions::default(),
    )
    .unwrap();
    let start = std::time::Instant::now();
    let e = Baker::builder()
        .method(Method::Rsgf)
        .lattice((71, 0), (5, 1025))
        .build()
        .unwrap()
        .bake(&ex, "x3p-2-crop", &mut |_| {})
        .unwrap_err();
    let e = one_line(e);
    assert!(e.contains("lattice") && e.contains("71×1025"), "{e}");
    assert!(start.elapsed().as_secs() < 10, "took {:?}", start.elapsed());
}

/// Finding 5: an `.npy` header claiming 2³² × 2³² pixels with no data is refused by its
/// shape (the product wrapped to 0 and the Fortran reorder panicked).
#[test]
fn npy_shapes_are_checked_before_use() {
    let npy = |shape: &str| {
        let mut header = format!("{{'descr': '<f4', 'fortran_order': True, 'shape': {shape}, }}");
        while !(10 + header.len() + 1).is_multiple_of(64) {
            header.push(' ');
        }
        header.push('\n');
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
        bytes.extend_from_slice(header.as_bytes());
        bytes
    };
    let read = |bytes: &[u8]| {
        one_line(
            read_image_bytes(bytes, Format::Npy, "huge.npy", &ReadOptions::default()).unwrap_err(),
        )
    };
    // 2³²·2³² is 2⁶⁴: refused from the header's element count; a count that fits is
    // refused by the pixel limit, 2^25.
    let e = read(&npy("(4294967296, 4294967296, 1)"));
    assert!(e.contains("element count"), "{e}");
    let e = read(&npy("(4294967296, 4294967, 1)"));
    assert!(e.contains("2^25"), "{e}");
}

/// Findings 6 and 7: a real decompression bomb (a 20000² PNG of zeros, a few hundred
/// kilobytes) is refused before its pixels are decoded, naming the limit.
#[test]
fn png_bombs_are_refused_before_decoding() {
    let side = 20_000u32;
    let mut file = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut file, side, side);
        encoder.set_color(png::ColorType::Grayscale);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_compression(png::Compression::Fast);
        let mut writer = encoder.write_header().unwrap();
        let mut stream = writer.stream_writer().unwrap();
        let row = vec![0u8; side as usize];
        for _ in 0..side {
            std::io::Write::write_all(&mut stream, &row).unwrap();
        }
        stream.finish().unwrap();
    }
    assert!(
        file.len() < 2 << 20,
        "the bomb is small: {} bytes",
        file.len()
    );
    let e = read_image_bytes(&file, Format::Png, "bomb.png", &ReadOptions::default());
    let e = one_line(e.unwrap_err());
    assert!(e.contains("20000×20000") && e.contains("2^25"), "{e}");
}

/// Finding 8: an imperfection layer with fewer colours than it shows is refused by its
/// validator (the colour image indexed past the list).
#[test]
fn imperfection_colours_must_cover_the_layers() {
    let peeling = std::fs::read_to_string(common::repo("tiles/imperfect/peeling.toml")).unwrap();
    let short = format!("{peeling}colours = [[0.8, 0.6, 0.2], [0.6, 0.2, 0.1]]\n");
    let e = one_line(surftile::imperfect::ImperfectConfig::from_toml(&short, "short").unwrap_err());
    assert!(
        e.contains("layers.colours") && e.contains("at least 4"),
        "{e}"
    );
    let dust = std::fs::read_to_string(common::repo("tiles/imperfect/dust.toml")).unwrap();
    let short = format!("{dust}colours = [[0.5, 0.5, 0.5]]\n");
    assert!(surftile::imperfect::ImperfectConfig::from_toml(&short, "short").is_err());
    let full = format!("{dust}colours = [[0.5, 0.5, 0.5], [0.9, 0.9, 0.8]]\n");
    surftile::imperfect::ImperfectConfig::from_toml(&full, "full").unwrap();
}

/// Finding 11 (raw shapes): a shape whose byte count overflows is refused by its product,
/// not passed by a wrapped size check.
#[test]
fn raw_shapes_are_checked_with_checked_arithmetic() {
    for shape in [(4611686018427387905, 1, 1), (4294967296, 4294967296, 4)] {
        let options = ReadOptions {
            raw_shape: Some(shape),
        };
        let e = read_image_bytes(&[0u8; 4], Format::Raw, "r.f32", &options).unwrap_err();
        assert!(one_line(e).contains("2^25"));
    }
}

/// Finding 9: the cells models are finite up to the edge of the coordinate range (their
/// fractal texture was read at an offset that could leave it: NaN at y = 4503599627000000).
#[test]
fn cells_are_finite_up_to_the_coordinate_limit() {
    use surftile::Surface;
    let edge = surftile::stream::MAX_COORDINATE;
    for preset in ["cells-convex", "cells-concave"] {
        let s = surftile::open(preset).unwrap().surface(0).unwrap();
        for k in 0..200 {
            let t = k as f64 * 1.9e6 + 0.25;
            for (x, y) in [
                (0.0, edge - 1.0 - t),
                (edge - 1.0 - t, 0.0),
                (-(edge - 1.0 - t), 17.5),
                (3.0, -(edge - 1.0 - t)),
            ] {
                assert!(s.height(x, y).is_finite(), "{preset} at ({x}, {y})");
            }
        }
        assert!(s.height(0.0, 4503599627000000.0).is_finite(), "{preset}");
    }
}

/// Finding 11 (names): a legal 254-byte output name is written (its temporary name used to
/// pass 255 bytes), and no temporary file is left beside it.
#[test]
fn long_output_names_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let name = format!("{}.npy", "é".repeat(125));
    assert_eq!(name.len(), 254);
    let r = surftile::Raster::from_vec(4, 4, 1, vec![0.5; 16]).unwrap();
    let path = dir.path().join(&name);
    surftile::io::write_heights(&path, &r, None).unwrap();
    let back = read_image(&path, &ReadOptions::default()).unwrap().raster;
    assert_eq!(back.data, r.data);
    let files: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(files.len(), 1, "a temporary file was left");
}

/// Finding 11 (outputs): an imperfect render whose later output cannot be written
/// leaves none of its outputs behind, and two outputs on one path are refused before
/// any work.
#[test]
fn imperfect_renders_write_all_their_outputs_or_none() {
    use surftile::imperfect::{Imperfect, ImperfectConfig};
    use surftile::render::{LayerOutputs, render_imperfect};
    let dir = tempfile::tempdir().unwrap();
    let (config, base) = ImperfectConfig::load("peeling".as_ref()).unwrap();
    let surface = surftile::open("cells-convex").unwrap().surface(1).unwrap();
    let layer = Imperfect::new(surface, &config, base.as_deref(), 1).unwrap();
    let region = surftile::Region::new(0.0, 0.0, 48, 32);
    let out = dir.path().join("h.npy");
    let mask = dir.path().join("m.png");
    // The tendency's folder does not exist: the last write fails.
    let missing = dir.path().join("no-such-folder").join("t.npy");
    let e = render_imperfect(
        &layer,
        &region,
        &out,
        None,
        None,
        LayerOutputs {
            mask: Some(&mask),
            tendency: Some(&missing),
            colour: None,
        },
        &mut |_| {},
    )
    .unwrap_err();
    one_line(e);
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n != "no-such-folder")
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
    // The same path twice.
    let e = render_imperfect(
        &layer,
        &region,
        &mask,
        None,
        None,
        LayerOutputs {
            mask: Some(&mask),
            tendency: None,
            colour: None,
        },
        &mut |_| {},
    )
    .unwrap_err();
    assert!(one_line(e).contains("other than"));
    // And a good render writes both.
    render_imperfect(
        &layer,
        &region,
        &out,
        None,
        None,
        LayerOutputs {
            mask: Some(&mask),
            tendency: None,
            colour: None,
        },
        &mut |_| {},
    )
    .unwrap();
    assert!(out.exists() && mask.exists());
}

/// Finding 11 (extensions): PNG bytes go only to a `.png` name (`lattice --plot p.npy`
/// wrote PNG bytes), and a bank never to an image's name (`bake --out b.png`).
#[test]
fn outputs_match_their_extensions() {
    let dir = tempfile::tempdir().unwrap();
    let npy = dir.path().join("p.npy");
    let e = surftile::io::write_png8(&npy, 2, 2, 1, &[0, 1, 2, 3]).unwrap_err();
    assert!(one_line(e).contains(".png"));
    assert!(!npy.exists());
    let bank = Bank::read(&common::repo("tests/data/golden-v1.bank")).unwrap();
    for name in ["b.png", "b.tif", "b.npy"] {
        let path = dir.path().join(name);
        assert!(one_line(bank.write(&path).unwrap_err()).contains("bank"));
        assert!(!path.exists());
    }
    bank.write(&dir.path().join("b.bank")).unwrap();
    bank.write(&dir.path().join("plain")).unwrap();
}

/// Finding 11 (absurd values): an exemplar of ±3·10³⁸ is refused by the preprocessing,
/// naming the file and the limit (the error used to come from the bank it made).
#[test]
fn absurd_exemplar_values_are_refused_as_the_exemplars_fault() {
    let data: Vec<f32> = (0..64 * 64)
        .map(|i| if i % 2 == 0 { 3e38 } else { -3e38 })
        .collect();
    let image =
        surftile::io::ImageFile::new(surftile::Raster::from_vec(64, 64, 1, data).unwrap(), None);
    let e = Baker::builder()
        .build()
        .unwrap()
        .bake(&image, "huge.npy", &mut |_| {})
        .unwrap_err();
    let e = one_line(e);
    assert!(e.starts_with("huge.npy") && e.contains("1e30"), "{e}");
}

/// A constant exemplar has nothing to synthesise: GIMP's `Stripes1px` pattern holds its
/// stripes in the alpha channel over black, and baked, with `auto` reporting coherence
/// "NaN", into a black bank. Every method now refuses a constant exemplar in one line,
/// naming the file and the value; an image that varies in one channel only still bakes.
#[test]
fn a_constant_exemplar_is_refused() {
    let rgba: Vec<u8> = (0..48 * 48)
        .flat_map(|i| [0, 0, 0, if i % 4 < 2 { 255 } else { 0 }])
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("alpha-stripes.png");
    let mut encoder = png::Encoder::new(std::fs::File::create(&png).unwrap(), 48, 48);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder
        .write_header()
        .unwrap()
        .write_image_data(&rgba)
        .unwrap();
    for method in [Method::Auto, Method::Rpn, Method::Roller, Method::Synth] {
        let image = read_image(&png, &ReadOptions::default()).unwrap();
        let e = Baker::builder()
            .method(method)
            .build()
            .unwrap()
            .bake(&image, "alpha-stripes.png", &mut |_| {})
            .unwrap_err();
        let e = one_line(e);
        assert!(
            e.starts_with("alpha-stripes.png: every pixel is the same (0, 0, 0) as prepared"),
            "{method:?}: {e}"
        );
    }
    let mut one_channel = vec![0.0f32; 48 * 48 * 3];
    for (i, px) in one_channel.chunks_exact_mut(3).enumerate() {
        px[2] = ((i * 37) % 251) as f32;
    }
    let image = surftile::io::ImageFile::new(
        surftile::Raster::from_vec(48, 48, 3, one_channel).unwrap(),
        None,
    );
    Baker::builder()
        .method(Method::Rpn)
        .build()
        .unwrap()
        .bake(&image, "blue.png", &mut |_| {})
        .unwrap();
}

/// Finding 11 (absurd values): every real parameter of a model, milling or imperfection
/// file is bounded (`surftile::error::MAX_PARAMETER`, 10³⁰, or tighter where the model
/// needs it), so a file with 10³⁰⁰ in it is refused by name instead of sampling ±inf.
#[test]
fn absurd_model_parameters_are_refused_by_name() {
    use surftile::imperfect::ImperfectConfig;
    use surftile::models::milling::MillingConfig;
    use surftile::models::rugged::ModelConfig;
    let text = |path: &str| std::fs::read_to_string(common::repo(path)).unwrap();
    let swap = |path: &str, from: &str, to: &str| {
        let t = text(path);
        assert!(t.contains(from), "{path} has no '{from}'");
        t.replacen(from, to, 1)
    };
    let cells = "tiles/models/cells-convex.toml";
    let rock = "tiles/models/rock.toml";
    for (t, key) in [
        (
            swap(cells, "density = 0.000244140625", "density = 1e-300"),
            "density",
        ),
        (swap(cells, "radius = 1.5", "radius = 1e300"), "radius"),
        (
            swap(cells, "amplitude = 4.0", "amplitude = 1e308"),
            "amplitude",
        ),
        (
            swap(rock, "amplitude = 64.0", "amplitude = 1e308"),
            "amplitude",
        ),
    ] {
        let e = one_line(ModelConfig::from_toml(&t, "m.toml").unwrap_err());
        assert!(
            e.contains(&format!("`{key}`")) || e.contains(key),
            "{key}: {e}"
        );
        // Density has its own range (centres 1 to 2³² px apart); the rest the common bound.
        assert!(
            e.contains("1e30") || e.contains("2³²"),
            "the bound is named: {e}"
        );
    }
    // Each model still opens with the values as shipped, and samples finite heights.
    for path in [cells, rock] {
        let m = ModelConfig::from_toml(&text(path), path).unwrap();
        assert!(m.surface(1).unwrap().height(1.0e15, -3.5).is_finite());
    }
    let milling = "tiles/milling/parallel-d4-ae05.toml";
    for (t, key) in [
        (
            swap(milling, "[tool]", "[noise]\namplitude_um = 1e300\n[tool]"),
            "noise.amplitude_um",
        ),
        (
            text(milling) + "\n[adapt]\nstd_um = 1e308\n",
            "adapt.std_um",
        ),
        (
            text(milling) + "\n[adapt]\nmean_um = -1e300\n",
            "adapt.mean_um",
        ),
    ] {
        let e = one_line(MillingConfig::from_toml(&t, "p.toml").unwrap_err());
        assert!(e.contains(key), "{key}: {e}");
    }
    let peeling = "tiles/imperfect/peeling.toml";
    for (t, key) in [
        (swap(peeling, "age = 1.0", "age = 1e300"), "age"),
        (
            swap(peeling, "octaves = 5", "octaves = 5\nlacunarity = 1e300"),
            "noise.lacunarity",
        ),
        (swap(peeling, "gamma = 0.35", "gamma = -1e300"), "gamma"),
    ] {
        let e = one_line(ImperfectConfig::from_toml(&t, "i.toml").unwrap_err());
        assert!(e.contains(key), "{key}: {e}");
    }
}

/// Deliver 2 (a bank's values pass the bake's bounds): a checksum-correct bank with a
/// texel of 3·10³⁸ (finite in f32, beyond the 10³⁰ the bake accepts from a map) or a
/// spacing of 10³⁰⁰ µm is refused on read, naming the bound.
#[test]
fn bank_values_are_held_to_the_bakes_bounds() {
    let golden = std::fs::read(common::repo("tests/data/golden-v1.bank")).unwrap();
    let header_len = u32::from_le_bytes(golden[12..16].try_into().unwrap()) as usize;
    let mut huge_texel = golden.clone();
    let at = 16 + header_len;
    huge_texel[at..at + 4].copy_from_slice(&3.0e38f32.to_le_bytes());
    let body = huge_texel.len() - 4;
    let crc = crc32fast::hash(&huge_texel[..body]);
    huge_texel[body..].copy_from_slice(&crc.to_le_bytes());
    let huge_spacing = with_header(&golden, |h| h["spacing_um"] = 1e300.into());
    for (bytes, needle) in [(huge_texel, "texels"), (huge_spacing, "spacing")] {
        let e = one_line(Bank::from_bytes(&bytes, "b.bank").unwrap_err());
        assert!(e.contains(needle) && e.contains("1e30"), "{e}");
    }
    // The untouched golden still reads.
    Bank::from_bytes(&golden, "b.bank").unwrap();
}

/// Found by the `npy` fuzz target: a shape whose element count passes 2⁶⁴
/// (`tests/data/bad/npy-shape-product-overflow.npy`, its crash input) overflowed inside
/// npyz before any check of ours (a panic in debug builds), and so did one with a zero
/// among dimensions whose other product passes it (`npy-zero-dimension-overflow.npy`);
/// a version-2 header claiming 4 GiB made npyz allocate it; a deeply nested header hung
/// its parser. All are refused from the header alone.
#[test]
fn npy_headers_are_checked_before_npyz_reads_them() {
    let crash = std::fs::read(common::repo(
        "tests/data/bad/npy-shape-product-overflow.npy",
    ))
    .unwrap();
    let e = one_line(
        read_image_bytes(&crash, Format::Npy, "c.npy", &ReadOptions::default()).unwrap_err(),
    );
    assert!(e.contains("element count"), "{e}");
    // Found by the same target later: a zero among the dimensions kept the element count
    // at 0, but npyz multiplies the others first (shape (0, 8209644704054465877, 5)).
    let zero = std::fs::read(common::repo(
        "tests/data/bad/npy-zero-dimension-overflow.npy",
    ))
    .unwrap();
    let e = one_line(
        read_image_bytes(&zero, Format::Npy, "z.npy", &ReadOptions::default()).unwrap_err(),
    );
    assert!(
        e.starts_with("z.npy") && e.contains("non-zero dimensions multiply past"),
        "{e}"
    );
    let mut huge_header = b"\x93NUMPY\x02\x00".to_vec();
    huge_header.extend_from_slice(&u32::MAX.to_le_bytes());
    huge_header.extend_from_slice(b"{'descr'");
    let e = one_line(
        read_image_bytes(&huge_header, Format::Npy, "h.npy", &ReadOptions::default()).unwrap_err(),
    );
    assert!(e.contains("past the end"), "{e}");
    // Found by the same target: 118 bytes of '{' in a header made the header parser
    // (py_literal, inside npyz too) backtrack past 60 s. Refused from the nesting, at once.
    let nested = std::fs::read(common::repo("tests/data/bad/npy-nested-header.npy")).unwrap();
    let start = std::time::Instant::now();
    let e = one_line(
        read_image_bytes(&nested, Format::Npy, "n.npy", &ReadOptions::default()).unwrap_err(),
    );
    assert!(
        e.contains("nests") && start.elapsed().as_secs_f64() < 1.0,
        "{e}"
    );
    // A well-formed file still reads (version 1 and version 2 headers).
    for seed in ["fuzz/seeds/npy/f4-c.npy", "fuzz/seeds/npy/v2-f4.npy"] {
        let bytes = std::fs::read(common::repo(seed)).unwrap();
        read_image_bytes(&bytes, Format::Npy, seed, &ReadOptions::default()).unwrap();
    }
}

/// Finding 10 (sandblast): the pipeline holds its whole output and every RPN patch
/// before stitching. 32768² (then accepted) passed 11.7 GB, and a thin 2^26 × 1 output
/// asked for 262,143 patches of 512² and took all of the machine's memory. Now the
/// output is at most 2^26 pixels, the patches at most 2^28 values, a padded plane at
/// most 2^24 pixels, each refused before any patch is made, naming the limit.
#[test]
fn sandblast_sizes_are_held_to_a_memory_budget() {
    use surftile::sandblast::Sandblast;
    let image = read_image(&common::repo("tiles/di-6.npy"), &ReadOptions::default()).unwrap();
    let e = Sandblast::builder(8193, 8192).build().unwrap_err();
    assert!(one_line(e).contains("67108864"));
    let start = std::time::Instant::now();
    for (b, needle) in [
        (Sandblast::builder(1 << 26, 1), "patches"),
        (Sandblast::builder(1, 1 << 26), "patches"),
        (Sandblast::builder(4097, 4096).padded(true), "padded"),
    ] {
        let e = b
            .build()
            .unwrap()
            .run(&image, "di-6", &mut |_| {})
            .unwrap_err();
        let e = one_line(e);
        assert!(
            e.contains(needle) && (e.contains("limit") || e.contains("budget")),
            "{e}"
        );
    }
    assert!(
        start.elapsed().as_secs_f64() < 10.0,
        "refused before the patches are made"
    );
}

/// Found by the `png` fuzz target (CRCs then recomputed, so a real file does it): a
/// palette image whose PLTE chunk holds 49 bytes, not a whole number of RGB entries,
/// panicked inside png 0.18.1's palette expansion (`surftile stats` exited 101). It is
/// refused from the header, naming the chunk.
#[test]
fn png_palettes_are_checked_before_expansion() {
    let bytes = std::fs::read(common::repo("tests/data/bad/png-plte-49-bytes.png")).unwrap();
    let e = read_image_bytes(&bytes, Format::Png, "p.png", &ReadOptions::default());
    let e = one_line(e.unwrap_err());
    assert!(e.contains("PLTE chunk has 49 bytes"), "{e}");
    // A well-formed 4-bit palette image with transparency still reads.
    let good = std::fs::read(common::repo("fuzz/seeds/png/palette4.png")).unwrap();
    let image = read_image_bytes(&good, Format::Png, "p4.png", &ReadOptions::default()).unwrap();
    assert_eq!((image.raster.width, image.raster.height), (8, 8));
}
