//! Exemplar and output formats: round trips, metadata, and decoding of what other tools
//! write (8-bit RGB(A) PNG, 16-bit PNG without metadata, integer TIFF, f64/u8/u16 and
//! Fortran-order .npy, raw f32).

mod common;

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use surftile::Raster;
use surftile::io::{ReadOptions, read_image, write_heights, write_png8};

fn ramp(w: usize, h: usize, c: usize) -> Raster {
    let data = (0..w * h * c)
        .map(|i| -3.0 + 0.0137 * i as f32 + ((i * 31) % 11) as f32 * 0.25)
        .collect();
    Raster::from_vec(w, h, c, data).unwrap()
}

#[test]
fn png16_round_trip_keeps_heights_to_one_level_and_spacing() {
    let dir = tempfile::tempdir().unwrap();
    let r = ramp(37, 23, 1);
    let p = dir.path().join("h.png");
    write_heights(&p, &r, Some(0.25)).unwrap();
    let back = read_image(&p, &ReadOptions::default()).unwrap();
    assert_eq!(back.spacing_um, Some(0.25));
    let (lo, hi) = r
        .data
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, u), &v| (l.min(v), u.max(v)));
    let level = (hi - lo) / 65535.0;
    for (a, b) in r.data.iter().zip(&back.raster.data) {
        assert!((a - b).abs() <= 0.5 * level + 1e-5, "{a} vs {b}");
    }
}

/// The 16-bit levels of a PNG, decoded by the png crate itself (no metadata applied).
fn png16_levels(path: &Path) -> (png::ColorType, Vec<u16>) {
    let dec = png::Decoder::new(std::io::BufReader::new(File::open(path).unwrap()));
    let mut reader = dec.read_info().unwrap();
    let mut buf = vec![0u8; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.bit_depth, png::BitDepth::Sixteen);
    let levels = buf[..info.buffer_size()]
        .chunks_exact(2)
        .map(|b| u16::from_be_bytes([b[0], b[1]]))
        .collect();
    (info.color_type, levels)
}

/// A colour synthesis of an 8-bit photo (values 0–255) is written on the photo's own
/// scale, so any viewer shows the photo's colours: level = v / 255 · 65535, not stretched
/// to its own range (which turned a pale lavender photo deep blue). Unit colour uses 1,
/// 16-bit colour 65535; heights, and colour outside [0, 65535], stay min–max scaled.
/// A synthesis that leaves the photo's range by a little (a roller's healed tiles read
/// up to 259.3 on GIMP's 8-bit rain, which was written as 16-bit levels: black) keeps
/// the 8-bit scale, clamped. Every case reads back within half a level of the clamped
/// value.
#[test]
fn colour_pngs_keep_their_levels_and_heights_are_stretched() {
    use surftile::io::{COLOUR_OVERSHOOT, colour_full_scale};
    let above = |v: f32| f32::from_bits(v.to_bits() + 1);
    let over = |full: f32| above(full * (1.0 + COLOUR_OVERSHOOT));
    assert_eq!(colour_full_scale(3, 0.0, above(255.0)), Some(255.0));
    assert_eq!(colour_full_scale(3, 0.0, 259.3), Some(255.0));
    assert_eq!(colour_full_scale(3, 0.0, 255.0 * 1.05), Some(255.0));
    assert_eq!(colour_full_scale(3, 0.0, over(255.0)), Some(65535.0));
    assert_eq!(colour_full_scale(3, 0.0, above(1.0)), Some(1.0));
    assert_eq!(colour_full_scale(3, 0.0, over(1.0)), Some(255.0));
    assert_eq!(colour_full_scale(3, -0.5, 200.0), Some(255.0));
    assert_eq!(colour_full_scale(3, -20.0, 200.0), Some(65535.0));
    assert_eq!(colour_full_scale(3, -4000.0, 200.0), None);
    assert_eq!(colour_full_scale(3, 0.0, over(65535.0)), None);
    assert_eq!(colour_full_scale(3, f32::NAN, 200.0), None);
    assert_eq!(colour_full_scale(1, 0.0, 200.0), None);
    let dir = tempfile::tempdir().unwrap();
    let pale: Vec<f32> = (0..24).map(|i| 199.0 + 2.25 * i as f32).collect(); // 199 … 250.75
    for (name, c, scale, full) in [
        ("rgb8.png", 3, 1.0f32, Some(255.0f32)),
        // Blending two 255s in f32 can give 255.00002: still the 8-bit scale.
        ("overshoot.png", 3, 255.00002 / 250.75, Some(255.0)),
        // A roller's healed tiles on GIMP's rain: up to 259.3, still the 8-bit scale.
        ("healed.png", 3, 259.3 / 250.75, Some(255.0)),
        ("unit.png", 3, 1.0 / 255.0, Some(1.0)),
        ("rgb16.png", 3, 257.0, Some(65535.0)),
        ("wide.png", 3, 300.0, None),
        ("grey.png", 1, 1.0, None),
    ] {
        let data: Vec<f32> = pale.iter().map(|v| v * scale).collect();
        let r = Raster::from_vec(8 / c.min(2), 3 * c.min(2) / c, c, data).unwrap();
        let p = dir.path().join(name);
        write_heights(&p, &r, None).unwrap();
        let (colour, levels) = png16_levels(&p);
        let want = if c == 3 {
            png::ColorType::Rgb
        } else {
            png::ColorType::Grayscale
        };
        assert_eq!(colour, want, "{name}");
        let (lo, hi) = match full {
            Some(f) => (0.0, f),
            None => (199.0 * scale, 250.75 * scale),
        };
        for (v, &l) in r.data.iter().zip(&levels) {
            let expect = ((v - lo) as f64 / (hi - lo) as f64).min(1.0) * 65535.0;
            let expect = expect.round();
            assert_eq!(l as f64, expect, "{name}: {v}");
        }
        let back = read_image(&p, &ReadOptions::default()).unwrap().raster;
        for (a, b) in r.data.iter().zip(&back.data) {
            assert!(
                (a.min(hi) - b).abs() <= 0.5 * (hi - lo) / 65535.0 * 1.001 + 1e-4 * scale,
                "{name}: {a} vs {b}"
            );
        }
    }
}

#[test]
fn tiff_and_npy_round_trips_are_exact() {
    let dir = tempfile::tempdir().unwrap();
    for (name, c) in [("h.tiff", 1), ("h.tif", 3), ("h.npy", 1), ("c.npy", 3)] {
        let r = ramp(19, 11, c);
        let p = dir.path().join(name);
        write_heights(&p, &r, Some(1.5)).unwrap();
        let back = read_image(&p, &ReadOptions::default()).unwrap();
        assert_eq!(back.raster, r, "{name}");
        if name.contains("tif") {
            assert_eq!(back.spacing_um, Some(1.5), "{name}");
        }
    }
}

#[test]
fn raw_f32_needs_the_right_shape() {
    let dir = tempfile::tempdir().unwrap();
    let r = ramp(8, 5, 1);
    let p = dir.path().join("h.raw");
    write_heights(&p, &r, None).unwrap();
    let opts = ReadOptions {
        raw_shape: Some((8, 5, 1)),
    };
    assert_eq!(read_image(&p, &opts).unwrap().raster, r);
    let wrong = ReadOptions {
        raw_shape: Some((8, 6, 1)),
    };
    let err = read_image(&p, &wrong).unwrap_err().to_string();
    assert!(err.contains("160 bytes") && err.contains("192"), "{err}");
    assert!(
        read_image(&p, &ReadOptions::default())
            .unwrap_err()
            .to_string()
            .contains("raw-shape")
    );
}

fn write_png(
    path: &Path,
    w: u32,
    h: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    bytes: &[u8],
) {
    let mut enc = png::Encoder::new(BufWriter::new(File::create(path).unwrap()), w, h);
    enc.set_color(color);
    enc.set_depth(depth);
    enc.write_header().unwrap().write_image_data(bytes).unwrap();
}

#[test]
fn foreign_pngs_decode_to_their_levels_and_drop_alpha() {
    let dir = tempfile::tempdir().unwrap();
    // 8-bit RGBA, 2×1: alpha dropped, levels kept.
    let p = dir.path().join("rgba.png");
    write_png(
        &p,
        2,
        1,
        png::ColorType::Rgba,
        png::BitDepth::Eight,
        &[10, 20, 30, 255, 40, 50, 60, 0],
    );
    let r = read_image(&p, &ReadOptions::default()).unwrap().raster;
    assert_eq!(
        (r.channels, r.data.clone()),
        (3, vec![10., 20., 30., 40., 50., 60.])
    );
    // 16-bit grey without surftile metadata: raw levels.
    let p = dir.path().join("g16.png");
    write_png(
        &p,
        2,
        1,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &[0x12, 0x34, 0xff, 0xff],
    );
    let r = read_image(&p, &ReadOptions::default()).unwrap();
    assert_eq!(r.raster.data, vec![4660.0, 65535.0]);
    assert_eq!(r.spacing_um, None);
    // 8-bit RGB through the library's own writer.
    let p = dir.path().join("rgb8.png");
    write_png8(&p, 1, 2, 3, &[1, 2, 3, 4, 5, 6]).unwrap();
    let r = read_image(&p, &ReadOptions::default()).unwrap().raster;
    assert_eq!(
        (r.width, r.height, r.data),
        (1, 2, vec![1., 2., 3., 4., 5., 6.])
    );
}

#[test]
fn integer_tiff_decodes() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("u16.tif");
    let mut enc =
        tiff::encoder::TiffEncoder::new(BufWriter::new(File::create(&p).unwrap())).unwrap();
    enc.write_image::<tiff::encoder::colortype::Gray16>(3, 2, &[0, 1, 2, 300, 4000, 65535])
        .unwrap();
    drop(enc);
    let r = read_image(&p, &ReadOptions::default()).unwrap().raster;
    assert_eq!(r.data, vec![0., 1., 2., 300., 4000., 65535.]);
}

fn npy_bytes(descr: &str, fortran: bool, shape: &str, data: &[u8]) -> Vec<u8> {
    let header = format!(
        "{{'descr': '{descr}', 'fortran_order': {}, 'shape': {shape}, }}",
        if fortran { "True" } else { "False" }
    );
    let pad = 64 - (10 + header.len() + 1) % 64;
    let full = format!("{header}{}\n", " ".repeat(pad % 64));
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(full.len() as u16).to_le_bytes());
    bytes.extend_from_slice(full.as_bytes());
    bytes.extend_from_slice(data);
    bytes
}

#[test]
fn npy_dtypes_and_fortran_order_decode() {
    let dir = tempfile::tempdir().unwrap();
    let read = |name: &str, bytes: Vec<u8>| {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        read_image(&p, &ReadOptions::default())
    };
    let f64s: Vec<u8> = [1.5f64, -2.0, 3.25, 4.0, 5.0, 6.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    // C order (2, 3): rows [1.5, -2, 3.25], [4, 5, 6].
    let r = read("c.npy", npy_bytes("<f8", false, "(2, 3)", &f64s))
        .unwrap()
        .raster;
    assert_eq!(
        (r.width, r.height, r.data),
        (3, 2, vec![1.5, -2.0, 3.25, 4.0, 5.0, 6.0])
    );
    // Fortran order (2, 3): the same bytes are columns: rows [1.5, 3.25, 5], [-2, 4, 6].
    let r = read("f.npy", npy_bytes("<f8", true, "(2, 3)", &f64s))
        .unwrap()
        .raster;
    assert_eq!(r.data, vec![1.5, 3.25, 5.0, -2.0, 4.0, 6.0]);
    let r = read("u8.npy", npy_bytes("|u1", false, "(1, 3)", &[0, 7, 255]))
        .unwrap()
        .raster;
    assert_eq!(r.data, vec![0., 7., 255.]);
    let u16s: Vec<u8> = [9u16, 65535].iter().flat_map(|v| v.to_le_bytes()).collect();
    let r = read("u16.npy", npy_bytes("<u2", false, "(2, 1)", &u16s))
        .unwrap()
        .raster;
    assert_eq!((r.width, r.data), (1, vec![9., 65535.]));
    // A 1-D array and a truncated file are clear errors.
    let e = read("1d.npy", npy_bytes("<f8", false, "(6,)", &f64s))
        .unwrap_err()
        .to_string();
    assert!(e.contains("shape"), "{e}");
    let e = read("cut.npy", npy_bytes("<f8", false, "(4, 3)", &f64s))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cut.npy") && e.contains("truncated"), "{e}");
}

#[test]
fn measured_map_reads_with_its_known_shape() {
    // MANIFEST: al3d-1 is 296 rows × 200 columns, no missing points, Sq_lev 0.2898 µm.
    let r = read_image(
        &common::repo("tests/data/al3d-1.npy"),
        &ReadOptions::default(),
    )
    .unwrap()
    .raster;
    assert_eq!(
        (r.width, r.height, r.channels, r.count_nan()),
        (200, 296, 1, 0)
    );
    let mut levelled = r.clone();
    surftile::prep::level::level_plane(&mut levelled);
    let sq = (levelled
        .data
        .iter()
        .map(|&v| (v as f64).powi(2))
        .sum::<f64>()
        / levelled.data.len() as f64)
        .sqrt();
    assert!((sq - 0.2898).abs() < 0.0005, "Sq after levelling {sq}");
}

/// Raw levels of a `.pillow.npy` reference (uint8, (H, W) or (H, W, 3)).
fn pillow_levels(path: &Path) -> Vec<f32> {
    let bytes = std::fs::read(path).unwrap();
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    bytes[10 + header_len..]
        .iter()
        .map(|&b| f32::from(b))
        .collect()
}

/// JPEG photos (`tests/data/jpeg/`, written by Pillow from the repository's photos)
/// decode to the levels an independent decoder gives (Pillow 13.0 on libjpeg-turbo, its
/// decodes kept beside them as `.pillow.npy`): colour stays three channels, grey one,
/// as 0–255 levels like an 8-bit PNG's, recognised by content whatever the name. Two
/// IDCTs may round differently, and 4:2:0 chroma may be upsampled differently (zune
/// and libjpeg-turbo both interpolate, not identically): within 2 levels and 0.05 on
/// average without subsampling, 4 and 0.3 with it (measured: 2 and 0.011, 1 and 0.015
/// grey, 3 and 0.126 progressive 4:2:0).
#[test]
fn jpeg_photos_decode_to_their_levels() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/jpeg");
    for (name, (w, h, c), (max_diff, mean_diff)) in [
        ("mud-444", (100, 100, 3), (2.0, 0.05)),
        ("gravel-grey", (96, 64, 1), (2.0, 0.05)),
        ("mud-420-progressive", (100, 100, 3), (4.0, 0.3)),
    ] {
        let image = read_image(&dir.join(format!("{name}.jpg")), &ReadOptions::default()).unwrap();
        let r = &image.raster;
        assert_eq!((r.width, r.height, r.channels), (w, h, c), "{name}");
        assert_eq!(image.spacing_um, None);
        let want = pillow_levels(&dir.join(format!("{name}.pillow.npy")));
        assert_eq!(want.len(), r.data.len(), "{name}");
        let (mut worst, mut total) = (0.0f32, 0.0f64);
        for (a, b) in r.data.iter().zip(&want) {
            assert_eq!(a.fract(), 0.0, "{name}: levels are integers");
            worst = worst.max((a - b).abs());
            total += f64::from((a - b).abs());
        }
        let mean = total / want.len() as f64;
        eprintln!("{name}: max {worst} levels, mean {mean:.3} from libjpeg-turbo's decode");
        assert!(
            worst <= max_diff && mean <= mean_diff,
            "{name}: max {worst}, mean {mean}"
        );
    }
    // By content: a JPEG named .png.
    let tmp = tempfile::tempdir().unwrap();
    let renamed = tmp.path().join("photo.png");
    std::fs::copy(dir.join("mud-444.jpg"), &renamed).unwrap();
    assert_eq!(
        read_image(&renamed, &ReadOptions::default())
            .unwrap()
            .raster
            .channels,
        3
    );
}

/// A truncated JPEG (baseline or progressive) and one whose frame header claims 65535 × 65535 pixels (past the
/// readers' 2^25-pixel budget) are one-line errors naming the file, before any
/// allocation of the image.
#[test]
fn bad_jpegs_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let good =
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/jpeg/mud-444.jpg"))
            .unwrap();
    let cut = dir.path().join("cut.jpg");
    std::fs::write(&cut, &good[..good.len() / 3]).unwrap();
    let progressive = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/jpeg/mud-420-progressive.jpg"),
    )
    .unwrap();
    let cut_progressive = dir.path().join("cut-progressive.jpg");
    std::fs::write(&cut_progressive, &progressive[..progressive.len() / 2]).unwrap();
    let huge = dir.path().join("huge.jpg");
    let mut big = good.clone();
    let sof = big
        .windows(2)
        .position(|m| m == [0xff, 0xc0])
        .expect("a baseline frame header");
    big[sof + 5..sof + 9].copy_from_slice(&[0xff, 0xff, 0xff, 0xff]);
    std::fs::write(&huge, &big).unwrap();
    for (path, needle) in [
        (&cut, "cut.jpg"),
        (&cut_progressive, "cut-progressive.jpg"),
        (&huge, "65535"),
    ] {
        let e = read_image(path, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains(needle) && !e.contains('\n'), "{e}");
    }
}

/// JPEG structures no camera or editor writes are refused by the structure check before
/// zune-jpeg decodes a byte (zune-jpeg 0.5.15 panics inside its IDCT on some of them;
/// `fuzz/run jpeg` found one): each is a one-line error naming the file and the fault.
/// Every real JPEG on hand still decodes: the three in `tests/data/jpeg/` here, the fuzz
/// seeds in `fuzz_seeds_still_read`.
#[test]
fn odd_jpeg_structures_are_refused_before_decoding() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/jpeg");
    let baseline = std::fs::read(data.join("mud-444.jpg")).unwrap();
    let progressive = std::fs::read(data.join("mud-420-progressive.jpg")).unwrap();
    let find = |bytes: &[u8], marker: u8| {
        bytes
            .windows(2)
            .position(|m| m == [0xff, marker])
            .expect("the marker")
    };
    let sof = find(&baseline, 0xc0);
    // SOF: FF C0, length (2), precision, height (2), width (2), count, then per
    // component id, sampling (H << 4 | V), table.
    let mut twelve_bit = baseline.clone();
    twelve_bit[sof + 4] = 12;
    let mut three_by_one = baseline.clone();
    three_by_one[sof + 10 + 3 + 1] = 0x31;
    let mut chroma_above_luma = baseline.clone();
    chroma_above_luma[sof + 10 + 3 + 1] = 0x22;
    let mut arithmetic = baseline.clone();
    arithmetic[sof + 1] = 0xc9;
    // A second scan in a sequential image: its one scan again, before EOI.
    let sos = find(&baseline, 0xda);
    let end = baseline.len() - 2;
    let two_scans = [&baseline[..end], &baseline[sos..end], &baseline[end..]].concat();
    // A progressive image whose first scan claims to refine bits (Ah = Al + 1) that no
    // earlier scan decoded.
    let first_scan = find(&progressive, 0xda);
    let ns = usize::from(progressive[first_scan + 4]);
    let approx = first_scan + 4 + 1 + 2 * ns + 2;
    let mut refine_first = progressive.clone();
    let al = refine_first[approx] & 15;
    refine_first[approx] = ((al + 1) << 4) | al;
    // zune-jpeg 0.5.15 panics decoding this one (tests/data/README.md).
    let idct_past_row = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bad/jpeg-idct-past-row.jpg"),
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes, needle) in [
        (
            "idct-past-row.jpg",
            idct_past_row,
            "component 3 samples 2 x 1 against the first's 1 x 1",
        ),
        ("twelve-bit.jpg", twelve_bit, "12-bit samples; expected 8"),
        ("three-by-one.jpg", three_by_one, "samples 3 x 1"),
        (
            "chroma-above-luma.jpg",
            chroma_above_luma,
            "samples 2 x 2 against the first's 1 x 1",
        ),
        ("arithmetic.jpg", arithmetic, "0xFFC9"),
        (
            "two-scans.jpg",
            two_scans,
            "sequential image in more than one scan",
        ),
        (
            "refine-first.jpg",
            refine_first,
            "refines bits out of order",
        ),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let e = read_image(&path, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(name) && e.contains(needle) && !e.contains('\n'),
            "{name}: {e}"
        );
    }
}

/// The fuzz seeds (grey, 4:4:4, progressive 4:2:0, CMYK) pass the structure check and
/// decode to their full size.
#[test]
fn fuzz_seeds_still_read() {
    let seeds = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds/jpeg");
    let mut read = 0;
    for entry in std::fs::read_dir(seeds).unwrap() {
        let path = entry.unwrap().path();
        let image = read_image(&path, &ReadOptions::default())
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let r = &image.raster;
        assert!(r.width > 0 && r.height > 0, "{}", path.display());
        assert_eq!(r.data.len(), r.width * r.height * r.channels);
        read += 1;
    }
    assert_eq!(read, 4);
}

/// A JPEG-compressed TIFF is refused in one line that names the compression and what is
/// read instead (tiff is built without its JPEG codec; see Cargo.toml).
#[test]
fn jpeg_compressed_tiff_is_refused_with_the_reason() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bad/tiff-jpeg-compressed.tif");
    let e = read_image(&path, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("tiff-jpeg-compressed.tif")
            && e.contains("compression")
            && e.contains("expected none, LZW, deflate or fax")
            && !e.contains('\n'),
        "{e}"
    );
}
