//! ISO 25178-71 surface data files (SDF). ASCII (`aISO-1.0`): `Key = value` header
//! lines up to a `*` line, then NumPoints × NumProfiles numbers, profile after profile
//! (`BAD` marks a missing point), up to the next `*`. Binary (`bISO-1.0`): an 81-byte
//! little-endian header and the values as one of eight data types. Heights (m) = value ·
//! Zscale; spacings Xscale and Yscale in metres.

use super::ImageFile;
use super::bytes::{Bytes, Order, positive};
use crate::error::Result;
use crate::raster::Raster;

/// The header's scales and sizes.
struct Header {
    nx: usize,
    ny: usize,
    dx: f64,
    dy: f64,
    dz: f64,
}

fn scaled(h: &Header, values: Vec<f32>) -> Result<ImageFile> {
    let mut image = ImageFile::new(Raster::from_vec(h.nx, h.ny, 1, values)?, Some(h.dx * 1e6));
    image.spacing_y_um = Some(h.dy * 1e6);
    image.unit = Some(super::Unit::M);
    Ok(image)
}

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let b = Bytes::new(bytes, what);
    match bytes.get(..8) {
        Some(b"aISO-1.0") => read_text(&b),
        Some(b"bISO-1.0") => read_binary(&b),
        _ => Err(b.bad("not an SDF file (it does not start with aISO-1.0 or bISO-1.0)")),
    }
}

fn check(b: &Bytes, h: &Header, compression: u64) -> Result<()> {
    if compression != 0 {
        return Err(b.bad(format!(
            "its SDF Compression is {compression}; compressed data is not supported"
        )));
    }
    positive(b, "Xscale", h.dx)?;
    positive(b, "Yscale", h.dy)?;
    positive(b, "Zscale", h.dz)?;
    super::check_shape(b.what, h.nx, h.ny, 1)?;
    Ok(())
}

fn read_text(b: &Bytes) -> Result<ImageFile> {
    let text = String::from_utf8_lossy(b.bytes);
    let mut lines = text.lines().skip(1);
    let mut keys: Vec<(String, String)> = Vec::new();
    loop {
        let line = lines
            .next()
            .ok_or_else(|| b.bad("truncated: its SDF header has no closing '*' line"))?;
        let line = line.trim();
        if line.starts_with('*') {
            break;
        }
        if line.is_empty() || line.starts_with(';') {
            continue;
        }
        let (k, v) = line
            .split_once('=')
            .or_else(|| line.split_once(char::is_whitespace))
            .ok_or_else(|| b.bad(format!("its SDF header line '{line}' is not 'Key = value'")))?;
        keys.push((k.trim().to_string(), v.trim().to_string()));
    }
    let get = |key: &str| {
        keys.iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(key))
            .map(|(_, v)| v.as_str())
    };
    let number = |key: &str| -> Result<f64> {
        let v = get(key).ok_or_else(|| b.bad(format!("its SDF header has no {key}")))?;
        v.parse()
            .map_err(|_| b.bad(format!("its SDF {key} is '{v}'; expected a number")))
    };
    let whole = |key: &str, default: Option<u64>| -> Result<u64> {
        match (get(key), default) {
            (None, Some(d)) => Ok(d),
            (None, None) => Err(b.bad(format!("its SDF header has no {key}"))),
            (Some(v), _) => v
                .parse()
                .map_err(|_| b.bad(format!("its SDF {key} is '{v}'; expected a whole number"))),
        }
    };
    let h = Header {
        nx: whole("NumPoints", None)? as usize,
        ny: whole("NumProfiles", None)? as usize,
        dx: number("Xscale")?,
        dy: number("Yscale")?,
        dz: number("Zscale")?,
    };
    check(b, &h, whole("Compression", Some(0))?)?;
    let n = h.nx * h.ny;
    // Each value takes at least two bytes (a digit and a separator).
    if n > b.bytes.len() / 2 {
        return Err(b.bad(format!(
            "truncated: its SDF header names {}×{} values, more than its {} bytes can hold",
            h.nx,
            h.ny,
            b.bytes.len()
        )));
    }
    let mut values = Vec::with_capacity(n);
    let mut extra = 0usize;
    for line in lines {
        if line.trim_start().starts_with('*') {
            break;
        }
        for token in line.split_whitespace() {
            if values.len() == n {
                extra += 1;
                continue;
            }
            let v = if token.eq_ignore_ascii_case("bad") {
                f32::NAN
            } else {
                let v: f64 = token.parse().map_err(|_| {
                    b.bad(format!(
                        "its SDF data holds '{token}'; expected a number or BAD"
                    ))
                })?;
                (v * h.dz * 1e6) as f32
            };
            values.push(if v.is_finite() { v } else { f32::NAN });
        }
    }
    if values.len() != n || extra > 0 {
        return Err(b.bad(format!(
            "{}its SDF data holds {} values; the header says {}×{} = {n}",
            if extra > 0 { "" } else { "truncated: " },
            values.len() + extra,
            h.nx,
            h.ny
        )));
    }
    scaled(&h, values)
}

fn read_binary(b: &Bytes) -> Result<ImageFile> {
    let le = Order::Little;
    let h = Header {
        nx: b.u16("NumPoints", 42, le)? as usize,
        ny: b.u16("NumProfiles", 44, le)? as usize,
        dx: b.f64("Xscale", 46, le)?,
        dy: b.f64("Yscale", 54, le)?,
        dz: b.f64("Zscale", 62, le)?,
    };
    let compression = b.slice("Compression", 78, 1)?[0];
    check(b, &h, compression as u64)?;
    let kind = b.slice("DataType", 79, 1)?[0];
    let elem = match kind {
        0 | 4 => 1,
        1 | 5 => 2,
        2 | 3 | 6 => 4,
        7 => 8,
        _ => {
            return Err(b.bad(format!("its SDF DataType is {kind}; expected 0 to 7")));
        }
    };
    let data = b.grid(81, (h.nx, h.ny), elem, None)?;
    let k = h.dz * 1e6;
    let values = data
        .chunks_exact(elem)
        .map(|c| {
            let v: Option<f64> = match kind {
                0 => Some(c[0] as f64),
                1 => Some(u16::from_le_bytes([c[0], c[1]]) as f64),
                2 => Some(u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64),
                3 => Some(f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64),
                4 => Some(c[0] as i8 as f64),
                5 => Some(i16::from_le_bytes([c[0], c[1]]))
                    .filter(|&v| v != i16::MIN)
                    .map(f64::from),
                6 => Some(i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .filter(|&v| v != i32::MIN)
                    .map(f64::from),
                _ => Some(f64::from_le_bytes([
                    c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7],
                ])),
            };
            v.map(|v| (v * k) as f32)
                .filter(|v| v.is_finite())
                .unwrap_or(f32::NAN)
        })
        .collect();
    scaled(&h, values)
}
