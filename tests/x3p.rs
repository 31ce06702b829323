//! X3P (ISO 25178-72, issue 36): a MountainsMap file reads to SurfaceTopography's
//! heights and spacing, surftile's own files round-trip bit for bit with correct
//! checksums, and damaged files are refused with one-line errors.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use md5::{Digest, Md5};
use surftile::io::{Format, ReadOptions, read_image, read_image_bytes, write_heights};
use surftile::raster::Raster;

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn md5_hex(bytes: &[u8]) -> String {
    Md5::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// A zip archive's entries: (name, bytes).
type Entries = Vec<(String, Vec<u8>)>;

/// The entries of a zip archive, by name.
fn entries(bytes: &[u8]) -> Entries {
    let mut z = zip::ZipArchive::new(std::io::Cursor::new(bytes)).unwrap();
    (0..z.len())
        .map(|i| {
            let mut f = z.by_index(i).unwrap();
            let mut v = Vec::new();
            f.read_to_end(&mut v).unwrap();
            (f.name().unwrap().to_string(), v)
        })
        .collect()
}

/// A zip of `files` as bytes.
fn zip_of(files: &Entries) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    {
        let mut z = zip::ZipWriter::new(&mut out);
        let o = zip::write::SimpleFileOptions::default();
        for (name, bytes) in files {
            if name.ends_with('/') {
                continue;
            }
            z.start_file(name.as_str(), o).unwrap();
            z.write_all(bytes).unwrap();
        }
        z.finish().unwrap();
    }
    out.into_inner()
}

#[test]
fn a_mountainsmap_file_reads_to_surfacetopography_heights() {
    let x3p = read_image(&repo("tests/data/x3p-2-crop.x3p"), &ReadOptions::default()).unwrap();
    let npy = read_image(&repo("tiles/x3p-2-crop.npy"), &ReadOptions::default()).unwrap();
    let (w, h) = (x3p.raster.width, x3p.raster.height);
    assert_eq!((w, h), (128, 96));
    let scale = npy.raster.data.iter().fold(0.0f32, |m, v| m.max(v.abs())) as f64;
    let mut worst = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let a = x3p.raster.data[y * w + x] as f64;
            let b = npy.raster.data[y * npy.raster.width + x] as f64;
            worst = worst.max((a - b).abs() / scale);
        }
    }
    assert!(
        worst <= 1e-5,
        "largest difference {worst:e} of the height range"
    );
    let spacing = x3p.spacing_um.unwrap();
    assert!(
        (spacing / 0.127656509837346 - 1.0).abs() < 1e-9,
        "{spacing}"
    );
    assert!(x3p.raster.data.iter().all(|v| v.is_finite()));
}

fn sample_raster() -> Raster {
    let (w, h) = (37, 23);
    let data = (0..w * h)
        .map(|k| {
            ((k as f32 * 0.7312).sin() * 3.5 + (k % 7) as f32 * 1e-3) * 10f32.powi(k as i32 % 5 - 2)
        })
        .collect();
    Raster::from_vec(w, h, 1, data).unwrap()
}

#[test]
fn written_files_round_trip_bit_for_bit_with_correct_checksums() {
    let dir = tempfile::tempdir().unwrap();
    let raster = sample_raster();
    let path = dir.path().join("out.x3p");
    write_heights(&path, &raster, Some(0.37)).unwrap();
    let back = read_image(&path, &ReadOptions::default()).unwrap();
    assert_eq!((back.raster.width, back.raster.height), (37, 23));
    for (a, b) in raster.data.iter().zip(&back.raster.data) {
        assert_eq!(a.to_bits(), b.to_bits(), "{a} became {b}");
    }
    assert!((back.spacing_um.unwrap() / 0.37 - 1.0).abs() < 1e-12);
    // The checksums, computed here from the archive's entries.
    let bytes = std::fs::read(&path).unwrap();
    let files = entries(&bytes);
    let get = |name: &str| &files.iter().find(|(n, _)| n == name).unwrap().1;
    let xml = String::from_utf8(get("main.xml").clone()).unwrap();
    let data = get("bindata/data.bin");
    assert_eq!(data.len(), 37 * 23 * 8);
    assert!(xml.contains(&format!(
        "<MD5ChecksumPointData>{}</MD5ChecksumPointData>",
        md5_hex(data).to_uppercase()
    )));
    assert_eq!(
        String::from_utf8(get("md5checksum.hex").clone()).unwrap(),
        format!("{} *main.xml\n", md5_hex(xml.as_bytes()))
    );
    // The structure ISO 5436-2's schema gives: the four records in order, the axes.
    let order: Vec<usize> = ["<Record1>", "<Record2>", "<Record3>", "<Record4>"]
        .iter()
        .map(|r| xml.find(r).unwrap())
        .collect();
    assert!(order.windows(2).all(|p| p[0] < p[1]));
    for needle in [
        "<FeatureType>SUR</FeatureType>",
        "<SizeX>37</SizeX>",
        "<SizeY>23</SizeY>",
        "<SizeZ>1</SizeZ>",
        "<Increment>3.7e-7</Increment>",
        "<DataType>D</DataType>",
        "<PointDataLink>bindata/data.bin</PointDataLink>",
        "<ChecksumFile>md5checksum.hex</ChecksumFile>",
    ] {
        assert!(xml.contains(needle), "{needle} missing from:\n{xml}");
    }
    // The same heights give the same bytes.
    let again = dir.path().join("again.x3p");
    write_heights(&again, &raster, Some(0.37)).unwrap();
    assert_eq!(std::fs::read(&again).unwrap(), bytes);
}

#[test]
fn damaged_files_are_refused_in_one_line() {
    let good = std::fs::read(repo("tests/data/x3p-2-crop.x3p")).unwrap();
    let files = entries(&good);
    let edit = |f: &dyn Fn(&mut Entries)| {
        let mut copy = files.clone();
        f(&mut copy);
        zip_of(&copy)
    };
    let wrong_md5 = edit(&|fs| {
        let data = fs
            .iter_mut()
            .find(|(n, _)| n == "bindata/data.bin")
            .unwrap();
        data.1[100] ^= 1;
    });
    let no_xml = edit(&|fs| fs.retain(|(n, _)| n != "main.xml"));
    let sizes = edit(&|fs| {
        let xml = fs.iter_mut().find(|(n, _)| n == "main.xml").unwrap();
        let text = String::from_utf8(xml.1.clone()).unwrap();
        xml.1 = text
            .replace("<SizeX>128</SizeX>", "<SizeX>129</SizeX>")
            .into_bytes();
    });
    let huge = edit(&|fs| {
        let xml = fs.iter_mut().find(|(n, _)| n == "main.xml").unwrap();
        let text = String::from_utf8(xml.1.clone()).unwrap();
        xml.1 = text
            .replace("<SizeX>128</SizeX>", "<SizeX>4000000</SizeX>")
            .replace("<SizeY>96</SizeY>", "<SizeY>4000000</SizeY>")
            .into_bytes();
    });
    let truncated = good[..good.len() / 2].to_vec();
    for (bytes, expected) in [
        (wrong_md5, "MD5"),
        (no_xml, "without main.xml"),
        (sizes, "need 99072"),
        (huge, "at most 33554432"),
        (truncated, "not an X3P file"),
        (b"PK\x03\x04 not really".to_vec(), "not an X3P file"),
    ] {
        let e = read_image_bytes(&bytes, Format::X3p, "bad.x3p", &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains(expected), "expected {expected:?} in: {e}");
        assert!(e.contains("bad.x3p") && !e.contains('\n'), "{e}");
    }
}
