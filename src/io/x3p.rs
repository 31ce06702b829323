//! X3P, ISO 25178-72 (the XML 3D surface profile format of ISO 5436-2): a zip archive
//! holding `main.xml` (axes, sizes, checksums) and the point data (`bindata/data.bin`,
//! X fastest, little-endian), with MD5 checksums of both.
//!
//! Read: areal surfaces (`FeatureType` SUR) on incremental X and Y axes; Z of data type
//! I (int16), L (int32), F (float32) or D (float64), scaled by the Z axis's increment
//! and offset where given; invalid points (NaN, or a 0 bit of `bindata/valid.bin`)
//! become NaN. Heights are converted from metres to µm, the X increment gives the
//! spacing in µm per pixel. The point data's MD5 is checked when `main.xml` gives it,
//! and every size is checked against `main.xml` and the bytes present before anything
//! of that size is allocated.
//!
//! Write: D (float64) heights in metres from µm, increments in metres from the spacing,
//! both MD5 checksums, and the generating command in `Record2/Comment`. The zip's entry
//! times are fixed, so the same heights give the same bytes.

use std::io::{Cursor, Read, Seek, Write};

use md5::{Digest, Md5};

use super::ImageFile;
use crate::error::{Error, Result};
use crate::raster::Raster;

/// Largest `main.xml` read (its text is a few kilobytes).
const MAX_XML_BYTES: u64 = 1 << 22;

/// Metres per µm.
const UM: f64 = 1e-6;

fn bad(what: &str, message: impl Into<String>) -> Error {
    Error::decode(what, message)
}

/// The text of the element at `path` (tag names from the root, namespaces ignored).
fn find<'a>(doc: &'a roxmltree::Document, path: &[&str]) -> Option<&'a str> {
    let mut node = doc.root_element();
    for name in path {
        node = node
            .children()
            .find(|n| n.is_element() && n.tag_name().name() == *name)?;
    }
    Some(node.text().unwrap_or("").trim())
}

/// The number at `path`, checked finite; `what` names the file.
fn number(doc: &roxmltree::Document, path: &[&str], what: &str) -> Result<Option<f64>> {
    let Some(text) = find(doc, path) else {
        return Ok(None);
    };
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(Some(v)),
        _ => Err(bad(
            what,
            format!(
                "main.xml's {} is '{text}'; expected a finite number",
                path.join("/")
            ),
        )),
    }
}

/// A whole number at `path`.
fn count(doc: &roxmltree::Document, path: &[&str], what: &str) -> Result<usize> {
    let text =
        find(doc, path).ok_or_else(|| bad(what, format!("main.xml has no {}", path.join("/"))))?;
    text.parse::<usize>().map_err(|_| {
        bad(
            what,
            format!(
                "main.xml's {} is '{text}'; expected a whole number",
                path.join("/")
            ),
        )
    })
}

/// Reads at most `limit` bytes of a zip entry (a lying size or a decompression bomb
/// stops there). What is reserved up front is at most `file_len` (the archive's size),
/// whatever size the entry claims; more grows only as data arrives.
fn read_entry<R: Read + Seek>(
    archive: &mut zip::ZipArchive<R>,
    name: &str,
    limit: u64,
    file_len: usize,
    what: &str,
) -> Result<Option<Vec<u8>>> {
    let mut entry = match archive.by_name(name) {
        Ok(e) => e,
        Err(zip::result::ZipError::FileNotFound) => return Ok(None),
        Err(e) => return Err(bad(what, format!("{name}: {e}"))),
    };
    let reserve = entry.size().min(limit).min(file_len as u64);
    let mut out = Vec::with_capacity(reserve as usize);
    (&mut entry)
        .take(limit)
        .read_to_end(&mut out)
        .map_err(|e| bad(what, format!("{name}: {e}")))?;
    Ok(Some(out))
}

/// The length (read up to `limit` bytes) and MD5 of a zip entry, streamed through a
/// small buffer: a file's sizes and checksum are checked before its point data is held
/// in memory, so a damaged file costs no more than its own size.
fn digest_entry<R: Read + Seek>(
    archive: &mut zip::ZipArchive<R>,
    name: &str,
    limit: u64,
    what: &str,
) -> Result<Option<(u64, String)>> {
    let entry = match archive.by_name(name) {
        Ok(e) => e,
        Err(zip::result::ZipError::FileNotFound) => return Ok(None),
        Err(e) => return Err(bad(what, format!("{name}: {e}"))),
    };
    let mut hasher = Md5::new();
    let mut reader = entry.take(limit);
    let mut buf = vec![0u8; 1 << 14];
    let mut len = 0u64;
    loop {
        let n = reader
            .read(&mut buf)
            .map_err(|e| bad(what, format!("{name}: {e}")))?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
        len += n as u64;
    }
    let hex = hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02X}"))
        .collect();
    Ok(Some((len, hex)))
}

fn md5_hex(bytes: &[u8]) -> String {
    Md5::digest(bytes)
        .iter()
        .map(|b| format!("{b:02X}"))
        .collect()
}

/// Decodes an X3P file held in memory.
pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let mut archive = zip::ZipArchive::new(Cursor::new(bytes))
        .map_err(|e| bad(what, format!("not an X3P file (a zip archive): {e}")))?;
    let xml = read_entry(
        &mut archive,
        "main.xml",
        MAX_XML_BYTES + 1,
        bytes.len(),
        what,
    )?
    .ok_or_else(|| bad(what, "an X3P archive without main.xml"))?;
    if xml.len() as u64 > MAX_XML_BYTES {
        return Err(bad(what, format!("main.xml is over {MAX_XML_BYTES} bytes")));
    }
    let text = std::str::from_utf8(&xml).map_err(|_| bad(what, "main.xml is not UTF-8"))?;
    let doc = roxmltree::Document::parse(text).map_err(|e| bad(what, format!("main.xml: {e}")))?;
    let feature = find(&doc, &["Record1", "FeatureType"]).unwrap_or("");
    if feature != "SUR" {
        return Err(Error::Unsupported(format!(
            "{what}: X3P feature type '{feature}'; surftile reads areal surfaces (SUR)"
        )));
    }
    for axis in ["CX", "CY"] {
        let kind = find(&doc, &["Record1", "Axes", axis, "AxisType"]).unwrap_or("");
        if kind != "I" {
            return Err(Error::Unsupported(format!(
                "{what}: X3P axis {axis} of type '{kind}'; surftile reads incremental (I) X and Y axes"
            )));
        }
    }
    let increment = |axis: &str| -> Result<f64> {
        match number(&doc, &["Record1", "Axes", axis, "Increment"], what)? {
            Some(v) if v > 0.0 => Ok(v),
            Some(v) => Err(bad(
                what,
                format!("main.xml's {axis} increment is {v}; expected a spacing above 0"),
            )),
            None => Err(bad(what, format!("main.xml has no {axis} increment"))),
        }
    };
    let (dx, dy) = (increment("CX")?, increment("CY")?);
    let z_type = find(&doc, &["Record1", "Axes", "CZ", "DataType"]).unwrap_or("");
    let size = match z_type {
        "I" => 2,
        "L" => 4,
        "F" => 4,
        "D" => 8,
        other => {
            return Err(bad(
                what,
                format!("main.xml's CZ data type is '{other}'; expected I, L, F or D"),
            ));
        }
    };
    let z_scale = number(&doc, &["Record1", "Axes", "CZ", "Increment"], what)?.unwrap_or(1.0);
    let z_offset = number(&doc, &["Record1", "Axes", "CZ", "Offset"], what)?.unwrap_or(0.0);
    let dims = ["Record3", "MatrixDimension"];
    let sx = count(&doc, &[dims[0], dims[1], "SizeX"], what)?;
    let sy = count(&doc, &[dims[0], dims[1], "SizeY"], what)?;
    let sz = count(&doc, &[dims[0], dims[1], "SizeZ"], what)?;
    if sz != 1 {
        return Err(Error::Unsupported(format!(
            "{what}: X3P with SizeZ = {sz}; surftile reads one layer (SizeZ = 1)"
        )));
    }
    let n = super::check_shape(what, sx, sy, 1)?;
    let expected = (n * size) as u64;
    let link = find(&doc, &["Record3", "DataLink", "PointDataLink"])
        .filter(|l| !l.is_empty())
        .unwrap_or("bindata/data.bin");
    let (found_len, found_md5) =
        digest_entry(&mut archive, link, expected + 1, what)?.ok_or_else(|| {
            bad(
                what,
                format!("the X3P archive has no {link} (main.xml's point data)"),
            )
        })?;
    if found_len != expected {
        return Err(bad(
            what,
            format!(
                "{link} holds {found_len} bytes; main.xml's {sx} × {sy} points of type {z_type} need {expected}"
            ),
        ));
    }
    if let Some(sum) =
        find(&doc, &["Record3", "DataLink", "MD5ChecksumPointData"]).filter(|s| !s.is_empty())
        && !found_md5.eq_ignore_ascii_case(sum)
    {
        return Err(bad(
            what,
            format!("{link}'s MD5 is {found_md5}; main.xml records {sum} (a damaged file)"),
        ));
    }
    // Sizes and checksum are right: now the data is read for good.
    let data = read_entry(&mut archive, link, expected, expected as usize, what)?
        .filter(|d| d.len() as u64 == expected)
        .ok_or_else(|| bad(what, format!("{link} changed while it was read")))?;
    let valid = match find(&doc, &["Record3", "DataLink", "ValidPointsLink"])
        .filter(|l| !l.is_empty())
    {
        None => None,
        Some(link) => {
            let bits = n.div_ceil(8) as u64;
            let v =
                read_entry(&mut archive, link, bits + 1, bytes.len(), what)?.ok_or_else(|| {
                    bad(
                        what,
                        format!("the X3P archive has no {link} (main.xml's valid points)"),
                    )
                })?;
            if (v.len() as u64) < bits {
                return Err(bad(
                    what,
                    format!("{link} holds {} bytes; {n} points need {bits}", v.len()),
                ));
            }
            Some(v)
        }
    };
    // Metres (after the Z axis's scale and offset) to µm.
    let to_um = |v: f64| ((v * z_scale + z_offset) / UM) as f32;
    let mut heights: Vec<f32> = match z_type {
        "I" => data
            .chunks_exact(2)
            .map(|b| to_um(i16::from_le_bytes([b[0], b[1]]) as f64))
            .collect(),
        "L" => data
            .chunks_exact(4)
            .map(|b| to_um(i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64))
            .collect(),
        "F" => data
            .chunks_exact(4)
            .map(|b| to_um(f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64))
            .collect(),
        _ => data
            .chunks_exact(8)
            .map(|b| to_um(f64::from_le_bytes(b.try_into().expect("8 bytes"))))
            .collect(),
    };
    if let Some(v) = valid {
        for (k, h) in heights.iter_mut().enumerate() {
            if v[k / 8] & (1 << (k % 8)) == 0 {
                *h = f32::NAN;
            }
        }
    }
    for h in &mut heights {
        if !h.is_finite() {
            *h = f32::NAN;
        }
    }
    let mut image = ImageFile::new(Raster::from_vec(sx, sy, 1, heights)?, Some(dx / UM));
    if (dy - dx).abs() > 1e-9 * dx.abs().max(dy.abs()) {
        image.spacing_y_um = Some(dy / UM);
    }
    image.unit = Some(super::Unit::M);
    Ok(image)
}

/// Escapes text for an XML element.
fn escape(text: &str) -> String {
    text.chars()
        .filter(|c| !c.is_control() || *c == '\n' || *c == '\t')
        .map(|c| match c {
            '&' => "&amp;".to_string(),
            '<' => "&lt;".to_string(),
            '>' => "&gt;".to_string(),
            c => c.to_string(),
        })
        .collect()
}

/// The `main.xml` of a `w × h` surface of D heights.
fn main_xml(w: usize, h: usize, (dx_m, dy_m): (f64, f64), data_md5: &str, comment: &str) -> String {
    let version = env!("CARGO_PKG_VERSION");
    let comment = escape(comment);
    format!(
        r#"<?xml version="1.0" encoding="UTF-8" standalone="no" ?>
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:schemaLocation="http://www.opengps.eu/2008/ISO5436_2 http://www.opengps.eu/2008/ISO5436_2/ISO5436_2.xsd">
  <Record1>
    <Revision>ISO5436 - 2000</Revision>
    <FeatureType>SUR</FeatureType>
    <Axes>
      <CX>
        <AxisType>I</AxisType>
        <DataType>D</DataType>
        <Increment>{dx_m:e}</Increment>
        <Offset>0</Offset>
      </CX>
      <CY>
        <AxisType>I</AxisType>
        <DataType>D</DataType>
        <Increment>{dy_m:e}</Increment>
        <Offset>0</Offset>
      </CY>
      <CZ>
        <AxisType>A</AxisType>
        <DataType>D</DataType>
      </CZ>
    </Axes>
  </Record1>
  <Record2>
    <Date>1970-01-01T00:00:00+00:00</Date>
    <Instrument>
      <Manufacturer>surftile</Manufacturer>
      <Model>surftile</Model>
      <Serial>not available</Serial>
      <Version>{version}</Version>
    </Instrument>
    <CalibrationDate>1970-01-01T00:00:00+00:00</CalibrationDate>
    <ProbingSystem>
      <Type>Software</Type>
      <Identification>surftile {version}</Identification>
    </ProbingSystem>
    <Comment>{comment}</Comment>
  </Record2>
  <Record3>
    <MatrixDimension>
      <SizeX>{w}</SizeX>
      <SizeY>{h}</SizeY>
      <SizeZ>1</SizeZ>
    </MatrixDimension>
    <DataLink>
      <PointDataLink>bindata/data.bin</PointDataLink>
      <MD5ChecksumPointData>{data_md5}</MD5ChecksumPointData>
    </DataLink>
  </Record3>
  <Record4>
    <ChecksumFile>md5checksum.hex</ChecksumFile>
  </Record4>
</p:ISO5436_2>
"#
    )
}

/// Writes heights in `meta.unit` (one channel) as X3P: D values in metres (NaN for
/// missing points), the spacings in metres as the X and Y increments (1 µm where
/// unknown, and the comment says so), and `comment` (the generating command) in
/// `Record2/Comment`.
pub(super) fn write<W: Write + Seek>(
    w: W,
    raster: &Raster,
    meta: &super::WriteMeta,
    comment: &str,
) -> Result<()> {
    if raster.channels != 1 {
        return Err(Error::param(
            "output",
            format!("{} channels", raster.channels),
            "heights (one channel) for an X3P file: write colour as .png, .tif or .npy",
        ));
    }
    let err = |e: zip::result::ZipError| Error::decode("X3P output", e.to_string());
    let io = |e: std::io::Error| Error::decode("X3P output", e.to_string());
    let metres = meta.unit.in_um() * UM;
    let mut data = Vec::with_capacity(raster.data.len() * 8);
    for &v in &raster.data {
        data.extend_from_slice(&(v as f64 * metres).to_le_bytes());
    }
    let comment = match meta.spacing_um {
        Some(_) => comment.to_string(),
        None => format!("{comment} (pixel spacing unknown: written as 1 µm)"),
    };
    let dx = meta.spacing_um.unwrap_or(1.0) * UM;
    let dy = meta.spacing_y_um.map_or(dx, |s| s * UM);
    let xml = main_xml(
        raster.width,
        raster.height,
        (dx, dy),
        &md5_hex(&data),
        &comment,
    );
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .last_modified_time(zip::DateTime::default())
        .unix_permissions(0o644);
    let mut zip = zip::ZipWriter::new(w);
    zip.start_file("main.xml", options).map_err(err)?;
    zip.write_all(xml.as_bytes()).map_err(io)?;
    zip.add_directory("bindata/", options).map_err(err)?;
    zip.start_file("bindata/data.bin", options).map_err(err)?;
    zip.write_all(&data).map_err(io)?;
    zip.start_file("md5checksum.hex", options).map_err(err)?;
    let sum = format!("{} *main.xml\n", md5_hex(xml.as_bytes()).to_lowercase());
    zip.write_all(sum.as_bytes()).map_err(io)?;
    zip.finish().map_err(err)?;
    Ok(())
}
