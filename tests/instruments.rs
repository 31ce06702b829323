//! Instrument formats (issue 36): crops of real AL3D, PLU, SUR, OPD, Nanoscope and
//! MetroPro files, and an ISO 25178-71 SDF file, read to the heights SurfaceTopography
//! gives (tests/data/instruments/README.md says how each was cut), with their spacing,
//! unit and missing points; recognised by content whatever their name; and truncated or
//! lying files refused with one-line errors that allocate no more than the file's size.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::{Read, Write};

use common::repo;
use surftile::io::{
    Format, ImageFile, ReadOptions, Unit, WriteMeta, read_image, read_image_bytes,
    write_heights_with,
};

/// Counts this thread's live heap bytes and their peak, so a test can bound what one
/// call allocates (tests run on several threads; each counts its own).
struct Counting;

thread_local! {
    static LIVE: Cell<usize> = const { Cell::new(0) };
    static PEAK: Cell<usize> = const { Cell::new(0) };
}

// SAFETY: forwards every call to the system allocator unchanged; the counters are
// const-initialised thread-locals without destructors, which never allocate.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let _ = LIVE.try_with(|l| {
                let now = l.get() + layout.size();
                l.set(now);
                let _ = PEAK.try_with(|p| p.set(p.get().max(now)));
            });
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        let _ = LIVE.try_with(|l| l.set(l.get().saturating_sub(layout.size())));
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            let _ = LIVE.try_with(|l| {
                let now = l.get().saturating_sub(layout.size()) + new_size;
                l.set(now);
                let _ = PEAK.try_with(|p| p.set(p.get().max(now)));
            });
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The most bytes live at once during `f` beyond those live before it.
fn peak_during<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.with(|l| l.get());
    PEAK.with(|p| p.set(base));
    let out = f();
    (out, PEAK.with(|p| p.get()) - base)
}

/// (crop file, expected x and y spacing in µm, the file's height unit).
const CROPS: [(&str, f64, f64, Unit); 6] = [
    ("al3d-1-crop.al3d", 0.438027, 0.438027, Unit::M),
    (
        "plu-1-crop.plu",
        1.6600000858306885,
        1.6600000858306885,
        Unit::Um,
    ),
    (
        "sur-2-crop.sur",
        3.4840002190321684,
        3.4840002190321684,
        Unit::Mm,
    ),
    (
        "opd-1-crop.opd",
        0.19673303177114576,
        0.19673303177114576,
        Unit::Nm,
    ),
    ("di-6-crop.di", 0.01953125, 0.01953125, Unit::Nm),
    (
        "metropro-1-crop.dat",
        1.0982520279867458,
        1.0982520279867458,
        Unit::M,
    ),
];

fn instrument(name: &str) -> std::path::PathBuf {
    repo(&format!("tests/data/instruments/{name}"))
}

fn expected(name: &str) -> ImageFile {
    let stem = name.rsplit_once('.').unwrap().0;
    read_image(&instrument(&format!("{stem}.npy")), &ReadOptions::default()).unwrap()
}

/// Every crop reads to SurfaceTopography's heights within 1e-5 of their largest
/// magnitude, with the same missing points, the spacing within 1e-9 and the unit the
/// file stores.
#[test]
fn instrument_crops_read_to_surfacetopography_heights() {
    for (name, dx, dy, unit) in CROPS {
        let got = read_image(&instrument(name), &ReadOptions::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let want = expected(name);
        let (a, b) = (&got.raster, &want.raster);
        assert_eq!((a.width, a.height), (b.width, b.height), "{name}");
        let scale = b
            .data
            .iter()
            .filter(|v| v.is_finite())
            .fold(0.0f64, |m, v| m.max(v.abs() as f64));
        let mut worst = 0.0f64;
        for (x, y) in a.data.iter().zip(&b.data) {
            assert_eq!(x.is_nan(), y.is_nan(), "{name}: missing points differ");
            if y.is_finite() {
                worst = worst.max((*x as f64 - *y as f64).abs() / scale);
            }
        }
        assert!(worst <= 1e-5, "{name}: relative error {worst:e}");
        let sx = got.spacing_um.unwrap();
        let sy = got.spacing_y().unwrap();
        assert!((sx / dx - 1.0).abs() < 1e-9, "{name}: x spacing {sx}");
        assert!((sy / dy - 1.0).abs() < 1e-9, "{name}: y spacing {sy}");
        assert_eq!(got.unit, Some(unit), "{name}");
    }
    // The crops that hold missing points hold the count the README gives.
    let nan = |name: &str| {
        read_image(&instrument(name), &ReadOptions::default())
            .unwrap()
            .raster
            .count_nan()
    };
    assert_eq!(nan("sur-2-crop.sur"), 39);
    assert_eq!(nan("opd-1-crop.opd"), 95);
}

/// The SDF sample (ISO 25178-71's own example): 7 points by 4 profiles, 1 µm apart,
/// values as written in the file (Zscale 1e-6 m).
#[test]
fn the_iso_sdf_example_reads_as_written() {
    let sdf = read_image(&instrument("sdf-1.sdf"), &ReadOptions::default()).unwrap();
    assert_eq!((sdf.raster.width, sdf.raster.height), (7, 4));
    assert_eq!(sdf.spacing_um, Some(1.0));
    assert_eq!(sdf.spacing_y_um, None, "square pixels");
    let first = [1.0, 0.99874, 0.99495, 0.98865, 0.97986, 0.96858, 1.0];
    let last = [
        0.97986, 0.97862, 0.97491, 0.96874, 0.96012, 0.94907, 0.97986,
    ];
    for k in 0..7 {
        assert!((sdf.raster.data[k] as f64 - first[k]).abs() < 1e-6);
        assert!((sdf.raster.data[21 + k] as f64 - last[k]).abs() < 1e-6);
    }
}

/// Formats are recognised by content: each crop, named `.bin` (which would be raw
/// f32), still reads as its own format.
#[test]
fn formats_are_recognised_by_content() {
    let dir = tempfile::tempdir().unwrap();
    for (name, ..) in CROPS {
        let bytes = std::fs::read(instrument(name)).unwrap();
        assert!(Format::sniff(&bytes).is_some(), "{name} not recognised");
        let renamed = dir.path().join(format!("{name}.bin"));
        std::fs::write(&renamed, &bytes).unwrap();
        let got = read_image(&renamed, &ReadOptions::default()).unwrap();
        assert_eq!(got.raster.data.len(), expected(name).raster.data.len());
    }
}

/// Truncated files (mid-header and mid-data, AL3D and PLU among them) are refused in
/// one line naming the file, and no read allocates more than the file's size (plus 64
/// KiB of header text and error message).
#[test]
fn truncated_instrument_files_are_refused_within_their_size() {
    for (name, ..) in CROPS.iter().chain(&[("sdf-1.sdf", 1.0, 1.0, Unit::M)]) {
        let bytes = std::fs::read(instrument(name)).unwrap();
        let format = Format::sniff(&bytes).unwrap();
        // The SDF's last 100 bytes are an optional trailer: its cuts end in the data.
        let cuts = if *name == "sdf-1.sdf" {
            [8, 100, 200, 300, 400]
        } else {
            [8, 100, 600, bytes.len() / 2, bytes.len() - 3]
        };
        for cut in cuts {
            let part = &bytes[..cut];
            let (result, peak) =
                peak_during(|| read_image_bytes(part, format, "cut.file", &ReadOptions::default()));
            let e = match result {
                Err(e) => e.to_string(),
                Ok(_) => panic!("{name} cut to {cut} bytes was read"),
            };
            assert!(
                e.contains("cut.file") && !e.contains('\n'),
                "{name} at {cut}: {e}"
            );
            assert!(
                peak <= part.len() + (64 << 10),
                "{name} cut to {cut} bytes allocated {peak} bytes"
            );
        }
    }
    // Mid-data, the error says so.
    for name in ["al3d-1-crop.al3d", "plu-1-crop.plu"] {
        let bytes = std::fs::read(instrument(name)).unwrap();
        let e = read_image_bytes(
            &bytes[..bytes.len() * 2 / 3],
            Format::sniff(&bytes).unwrap(),
            name,
            &ReadOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("truncated") && e.contains(name), "{e}");
    }
}

/// Headers that claim a huge grid over a small file are refused before anything of
/// that size is allocated.
#[test]
fn lying_sizes_are_refused_within_the_file_size() {
    // PLU: the layer's rows and columns at 500 and 504.
    let mut plu = std::fs::read(instrument("plu-1-crop.plu")).unwrap();
    plu[500..504].copy_from_slice(&60000u32.to_le_bytes());
    plu[504..508].copy_from_slice(&500u32.to_le_bytes());
    // SUR: points per line, lines and their product at 108, 112 and 116.
    let mut sur = std::fs::read(instrument("sur-2-crop.sur")).unwrap();
    sur[108..112].copy_from_slice(&5000i32.to_le_bytes());
    sur[112..116].copy_from_slice(&5000i32.to_le_bytes());
    sur[116..120].copy_from_slice(&25_000_000i32.to_le_bytes());
    // MetroPro: the phase array's width, height and byte count (big-endian).
    let mut dat = std::fs::read(instrument("metropro-1-crop.dat")).unwrap();
    dat[68..70].copy_from_slice(&4000u16.to_be_bytes());
    dat[70..72].copy_from_slice(&4000u16.to_be_bytes());
    dat[72..76].copy_from_slice(&64_000_000u32.to_be_bytes());
    for (name, bytes) in [("plu", plu), ("sur", sur), ("dat", dat)] {
        let format = Format::sniff(&bytes).unwrap();
        let (result, peak) =
            peak_during(|| read_image_bytes(&bytes, format, "lying.file", &ReadOptions::default()));
        let e = result.unwrap_err().to_string();
        assert!(e.contains("truncated") && !e.contains('\n'), "{name}: {e}");
        assert!(peak <= bytes.len() + (64 << 10), "{name}: allocated {peak}");
    }
}

/// How a test rewrites one archive entry: its new bytes, or `None` to drop it.
type Edit<'a> = dyn Fn(&str, &[u8]) -> Option<Vec<u8>> + 'a;

/// A zip of `files` (name, bytes), each rewritten by `edit`.
fn rezip(files: &[(String, Vec<u8>)], edit: &Edit) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    let mut w = zip::ZipWriter::new(&mut out);
    for (name, bytes) in files {
        if name.ends_with('/') {
            continue;
        }
        if let Some(b) = edit(name, bytes) {
            w.start_file(name.as_str(), zip::write::SimpleFileOptions::default())
                .unwrap();
            w.write_all(&b).unwrap();
        }
    }
    w.finish().unwrap();
    out.into_inner()
}

/// The X3P bad inputs of the issue (a wrong MD5, a zip without main.xml, sizes that
/// disagree with the data, a truncated archive) allocate no more than the file's size.
#[test]
fn damaged_x3p_files_are_refused_within_their_size() {
    let good = std::fs::read(repo("tests/data/x3p-2-crop.x3p")).unwrap();
    let mut z = zip::ZipArchive::new(std::io::Cursor::new(&good)).unwrap();
    let files: Vec<(String, Vec<u8>)> = (0..z.len())
        .map(|i| {
            let mut f = z.by_index(i).unwrap();
            let mut v = Vec::new();
            f.read_to_end(&mut v).unwrap();
            (f.name().unwrap().to_string(), v)
        })
        .collect();
    let rezip = |edit: &Edit| rezip(&files, edit);
    let xml = |f: &dyn Fn(String) -> String| {
        rezip(&|n, b| {
            Some(if n == "main.xml" {
                f(String::from_utf8(b.to_vec()).unwrap()).into_bytes()
            } else {
                b.to_vec()
            })
        })
    };
    let bad = [
        rezip(&|n, b| {
            let mut b = b.to_vec();
            if n == "bindata/data.bin" {
                b[7] ^= 0x20;
            }
            Some(b)
        }),
        rezip(&|n, b| (n != "main.xml").then(|| b.to_vec())),
        xml(&|t| t.replace("<SizeY>96</SizeY>", "<SizeY>97</SizeY>")),
        xml(&|t| {
            t.replace("<SizeX>128</SizeX>", "<SizeX>5000</SizeX>")
                .replace("<SizeY>96</SizeY>", "<SizeY>5000</SizeY>")
        }),
        good[..good.len() * 3 / 4].to_vec(),
    ];
    for (k, bytes) in bad.iter().enumerate() {
        let (result, peak) = peak_during(|| {
            read_image_bytes(bytes, Format::X3p, "bad.x3p", &ReadOptions::default())
        });
        let e = result.unwrap_err().to_string();
        assert!(e.contains("bad.x3p") && !e.contains('\n'), "case {k}: {e}");
        assert!(
            peak <= bytes.len() + (64 << 10),
            "case {k}: allocated {peak} for a {}-byte file",
            bytes.len()
        );
    }
}

/// X3P keeps non-square pixels and any unit: written with x and y spacings and heights
/// in nm, it reads back in µm with both spacings, the same f32 heights (×1e-3), and its
/// missing points.
#[test]
fn x3p_keeps_non_square_spacing_units_and_missing_points() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (9, 5);
    let mut data: Vec<f32> = (0..w * h)
        .map(|k| (k as f32 * 0.37).sin() * 250.0)
        .collect();
    data[7] = f32::NAN;
    let raster = surftile::raster::Raster::from_vec(w, h, 1, data.clone()).unwrap();
    let path = dir.path().join("nm.x3p");
    let meta = WriteMeta {
        spacing_um: Some(0.1277),
        spacing_y_um: Some(0.3146),
        unit: Unit::Nm,
        levels: None,
    };
    write_heights_with(&path, &raster, &meta).unwrap();
    let back = read_image(&path, &ReadOptions::default()).unwrap();
    assert!((back.spacing_um.unwrap() / 0.1277 - 1.0).abs() < 1e-12);
    assert!((back.spacing_y_um.unwrap() / 0.3146 - 1.0).abs() < 1e-12);
    assert_eq!(back.unit, Some(Unit::M));
    for (a, b) in data.iter().zip(&back.raster.data) {
        if a.is_nan() {
            assert!(b.is_nan());
        } else {
            let want = *a as f64 * 1e-3;
            assert!(
                (want - *b as f64).abs() <= 1e-6 * want.abs(),
                "{a} nm became {b} µm"
            );
        }
    }
}

/// A zlib-compressed SUR (`DSCOMPRESSED`, two streams) made from the plain crop reads to
/// the same heights; one whose header claims a 5792² grid over the same few bytes is
/// refused without allocating for that grid.
#[test]
fn compressed_sur_reads_and_a_lying_one_is_refused_within_its_size() {
    use flate2::Compression;
    use flate2::write::ZlibEncoder;
    let plain = std::fs::read(instrument("sur-2-crop.sur")).unwrap();
    let data = &plain[512..];
    let half = data.len() / 2;
    let mut streams = Vec::new();
    for part in [&data[..half], &data[half..]] {
        let mut z = ZlibEncoder::new(Vec::new(), Compression::default());
        z.write_all(part).unwrap();
        streams.push((part.len() as u32, z.finish().unwrap()));
    }
    let compress = |header: &[u8]| {
        let mut out = header[..512].to_vec();
        out[..12].copy_from_slice(b"DSCOMPRESSED");
        out.extend_from_slice(&2u32.to_le_bytes());
        for (raw, z) in &streams {
            out.extend_from_slice(&raw.to_le_bytes());
            out.extend_from_slice(&(z.len() as u32).to_le_bytes());
        }
        for (_, z) in &streams {
            out.extend_from_slice(z);
        }
        out
    };
    let packed = compress(&plain);
    let a = read_image_bytes(
        &packed,
        Format::sniff(&packed).unwrap(),
        "c.sur",
        &ReadOptions::default(),
    )
    .unwrap();
    let b = read_image(&instrument("sur-2-crop.sur"), &ReadOptions::default()).unwrap();
    assert_eq!(a.raster.width, b.raster.width);
    assert!(
        a.raster
            .data
            .iter()
            .zip(&b.raster.data)
            .all(|(x, y)| x.to_bits() == y.to_bits())
    );
    let mut lying = plain.clone();
    lying[108..112].copy_from_slice(&5792i32.to_le_bytes());
    lying[112..116].copy_from_slice(&5792i32.to_le_bytes());
    lying[116..120].copy_from_slice(&(5792i32 * 5792).to_le_bytes());
    let lying = compress(&lying);
    let (result, peak) =
        peak_during(|| read_image_bytes(&lying, Format::Sur, "lying.sur", &ReadOptions::default()));
    let e = result.unwrap_err().to_string();
    assert!(e.contains("lying.sur") && e.contains("streams hold"), "{e}");
    assert!(peak <= lying.len() + (64 << 10), "allocated {peak}");
}

/// An SDF whose data holds more values than its header's grid is refused, as is one
/// holding fewer.
#[test]
fn sdf_value_counts_must_match_the_header() {
    let good = std::fs::read_to_string(instrument("sdf-1.sdf")).unwrap();
    for (from, to) in [
        ("NumProfiles = 4", "NumProfiles = 3"),
        ("NumProfiles = 4", "NumProfiles = 5"),
    ] {
        let bad = good.replace(from, to);
        let e = read_image_bytes(
            bad.as_bytes(),
            Format::Sdf,
            "n.sdf",
            &ReadOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("28 values"), "{to}: {e}");
    }
}

/// TIFF and PNG record the height unit (in ASCII, Å as `A`) and their readers return
/// µm: heights written in Å and nm read back ×1e-4 and ×1e-3.
#[test]
fn tiff_and_png_record_the_height_unit() {
    let dir = tempfile::tempdir().unwrap();
    let data: Vec<f32> = (0..64).map(|k| (k as f32 * 0.3).sin() * 500.0).collect();
    let raster = surftile::raster::Raster::from_vec(8, 8, 1, data.clone()).unwrap();
    for (name, unit, k, tol) in [
        ("a.tif", Unit::Angstrom, 1e-4, 1e-6),
        ("n.png", Unit::Nm, 1e-3, 2e-5),
    ] {
        let path = dir.path().join(name);
        let meta = WriteMeta {
            spacing_um: Some(0.5),
            spacing_y_um: Some(0.25),
            unit,
            levels: None,
        };
        write_heights_with(&path, &raster, &meta).unwrap();
        let back = read_image(&path, &ReadOptions::default()).unwrap();
        assert_eq!(back.unit, Some(unit), "{name}");
        assert_eq!(
            (back.spacing_um, back.spacing_y_um),
            (Some(0.5), Some(0.25))
        );
        for (a, b) in data.iter().zip(&back.raster.data) {
            let want = *a as f64 * k;
            // PNG quantises to 16 bits over the range.
            assert!((want - *b as f64).abs() <= tol, "{name}: {want} vs {b}");
        }
    }
}
