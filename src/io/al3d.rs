//! Alicona AL3D: a text header of 52-byte tag records (`key[20] value[30] \r\n`) and
//! the depth image as little-endian float32 metres, rows padded to 8 bytes, first row
//! on top. Invalid points are NaN or the header's `InvalidPixelValue` (compared in
//! float32, as stored). Spacing from `PixelSizeXMeter` / `PixelSizeYMeter`.

use super::ImageFile;
use super::bytes::{Bytes, positive};
use crate::error::Result;
use crate::raster::Raster;

const MAGIC: &[u8] = b"AliconaImaging\0\r\n";
const RECORD: usize = 52;

/// The header's tag records as (key, value bytes).
type Tags<'a> = Vec<(String, &'a [u8])>;

/// The tag records of the header: (key, value bytes), and the header's length.
fn tags<'a>(b: &Bytes<'a>) -> Result<(Tags<'a>, usize)> {
    let record = |k: usize| -> Result<(String, &'a [u8])> {
        let at = MAGIC.len() + k * RECORD;
        let r = b.slice("header's tag records", at, RECORD)?;
        if &r[50..52] != b"\r\n" {
            return Err(b.bad(format!(
                "the AL3D tag record at offset {at} does not end in CR LF; the header is damaged"
            )));
        }
        let end = r[..20].iter().position(|&c| c == 0).unwrap_or(20);
        Ok((
            String::from_utf8_lossy(&r[..end]).trim().to_string(),
            &r[20..50],
        ))
    };
    let (version, _) = record(0)?;
    let (count_key, count) = record(1)?;
    if version != "Version" || count_key != "TagCount" {
        return Err(b.bad("its AL3D header does not start with the Version and TagCount tags"));
    }
    let n: usize = text(count).parse().map_err(|_| {
        b.bad(format!(
            "its AL3D TagCount is '{}'; expected a whole number",
            text(count)
        ))
    })?;
    let header = n
        .checked_add(2)
        .and_then(|k| k.checked_mul(RECORD))
        .and_then(|v| v.checked_add(MAGIC.len() + 256))
        .filter(|&h| h <= b.bytes.len())
        .ok_or_else(|| {
            b.bad(format!(
                "truncated: its AL3D header of {n} tags does not fit in the file's {} bytes",
                b.bytes.len()
            ))
        })?;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        out.push(record(k + 2)?);
    }
    Ok((out, header))
}

/// A value field as text: up to its first NUL, trimmed.
fn text(value: &[u8]) -> String {
    let end = value.iter().position(|&c| c == 0).unwrap_or(value.len());
    String::from_utf8_lossy(&value[..end]).trim().to_string()
}

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let b = Bytes::new(bytes, what);
    if !bytes.starts_with(MAGIC) {
        return Err(b.bad("not an AL3D file (it does not start with 'AliconaImaging')"));
    }
    let (tags, header) = tags(&b)?;
    let get = |key: &str| tags.iter().find(|(k, _)| k == key).map(|(_, v)| text(v));
    let need =
        |key: &str| get(key).ok_or_else(|| b.bad(format!("its AL3D header has no {key} tag")));
    let int = |key: &str| -> Result<usize> {
        let v = need(key)?;
        v.parse()
            .map_err(|_| b.bad(format!("its AL3D {key} is '{v}'; expected a whole number")))
    };
    let float = |key: &str| -> Result<f64> {
        let v = need(key)?;
        let lower = v.to_ascii_lowercase();
        v.parse::<f64>().or_else(|_| {
            if lower.contains("nan") || lower.contains('#') {
                Ok(f64::NAN)
            } else {
                Err(b.bad(format!("its AL3D {key} is '{v}'; expected a number")))
            }
        })
    };
    let (nx, ny) = (int("Cols")?, int("Rows")?);
    let dx = positive(&b, "PixelSizeXMeter", float("PixelSizeXMeter")?.abs())?;
    let dy = positive(&b, "PixelSizeYMeter", float("PixelSizeYMeter")?.abs())?;
    let offset = match get("DepthImageOffset") {
        Some(_) => int("DepthImageOffset")?,
        None => 0,
    };
    if offset == 0 {
        return Err(b.bad("its AL3D file holds no depth image (DepthImageOffset is 0 or absent): a texture-only file"));
    }
    if offset < header {
        return Err(b.bad(format!(
            "its AL3D DepthImageOffset {offset} points into the {header}-byte header"
        )));
    }
    let invalid = match get("InvalidPixelValue") {
        Some(_) => float("InvalidPixelValue")? as f32,
        None => f32::NAN,
    };
    // Rows are padded to a multiple of 8 bytes.
    let stride = nx
        .checked_mul(4)
        .and_then(|v| v.checked_add(7))
        .map(|v| v / 8 * 8 / 4)
        .ok_or_else(|| b.bad(format!("its AL3D Cols {nx} is out of range")))?;
    super::check_shape(what, nx, ny, 1)?;
    // The last row's padding need not be present.
    let len = (ny - 1)
        .checked_mul(stride * 4)
        .and_then(|v| v.checked_add(nx * 4))
        .ok_or_else(|| b.bad(format!("its AL3D grid of {nx}×{ny} is out of range")))?;
    let block = b.slice(&format!("{nx}×{ny} depth image"), offset, len)?;
    let mut heights = Vec::with_capacity(nx * ny);
    for row in 0..ny {
        let start = row * stride * 4;
        for k in 0..nx {
            let at = start + k * 4;
            let v = f32::from_le_bytes([block[at], block[at + 1], block[at + 2], block[at + 3]]);
            // The tag is stored as text with more digits than an f32 holds.
            let bad = !v.is_finite()
                || v == invalid
                || (v as f64 - invalid as f64).abs() <= 1.5e-7 * (invalid as f64).abs();
            heights.push(if bad {
                f32::NAN
            } else {
                (v as f64 * 1e6) as f32
            });
        }
    }
    let mut image = ImageFile::new(Raster::from_vec(nx, ny, 1, heights)?, Some(dx * 1e6));
    image.spacing_y_um = Some(dy * 1e6);
    image.unit = Some(super::Unit::M);
    Ok(image)
}
