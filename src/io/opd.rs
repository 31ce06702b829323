//! Wyko/Veeco OPD (Vision): a directory of 24-byte entries (name, type, length,
//! flags) after a leading u16 1, then every block's data in directory order. The
//! height array (`RAW_DATA`, `RAW DATA`, `OPD`, `SAMPLE_DATA` or `Raw`) holds u16
//! columns, rows and element size, then f32, i16 or u8 values in waves, stored column
//! by column from the bottom row up. Height = value · `Wavelength` (nm) / `Mult`;
//! spacing `Pixel_size` (mm) along x, times `Aspect` along y. Invalid: f32 ≥ 1e38 or
//! not finite, i16 ≥ 32766.

use super::ImageFile;
use super::bytes::{Bytes, Order, positive};
use crate::error::Result;
use crate::raster::Raster;

const ENTRY: usize = 24;
const HEIGHT_NAMES: [&str; 5] = ["RAW_DATA", "RAW DATA", "OPD", "SAMPLE_DATA", "Raw"];

/// Whether `bytes` start like an OPD file: u16 1, then the `Directory` entry of type 1.
pub(super) fn sniff(bytes: &[u8]) -> bool {
    bytes.len() >= 26 && bytes.starts_with(b"\x01\x00Directory") && bytes[18..20] == [1, 0]
}

/// A block: name, type, data offset and length.
struct Block {
    name: String,
    kind: u16,
    at: usize,
    len: usize,
}

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let b = Bytes::new(bytes, what);
    let le = Order::Little;
    if !sniff(bytes) {
        return Err(b.bad("not an OPD file (it does not start with its 'Directory' entry)"));
    }
    let dir_len = b.u32("directory length", 20, le)? as usize;
    if !dir_len.is_multiple_of(ENTRY) || dir_len == 0 {
        return Err(b.bad(format!(
            "its OPD directory is {dir_len} bytes; expected a multiple of {ENTRY}"
        )));
    }
    b.slice("directory", 2, dir_len)?;
    let mut pos = 2 + dir_len;
    let mut blocks = Vec::new();
    for i in 1..dir_len / ENTRY {
        let e = 2 + ENTRY * i;
        let name = b.text("block name", e, 16)?;
        let kind = b.u16("block type", e + 16, le)?;
        let len = b.u32("block length", e + 18, le)? as usize;
        if len == 0 {
            continue;
        }
        b.slice(&format!("block '{name}'"), pos, len)?;
        blocks.push(Block {
            name,
            kind,
            at: pos,
            len,
        });
        pos += len;
    }
    let find = |name: &str, kind: u16| blocks.iter().find(|k| k.name == name && k.kind == kind);
    let f32_of = |name: &str| -> Result<Option<f64>> {
        match find(name, 7) {
            Some(k) if k.len >= 4 => Ok(Some(b.f32(name, k.at, le)? as f64)),
            Some(_) => Err(b.bad(format!("its OPD block '{name}' is shorter than a float"))),
            None => Ok(None),
        }
    };
    let wavelength = f32_of("Wavelength")?
        .ok_or_else(|| b.bad("its OPD file has no Wavelength block: heights cannot be scaled"))?;
    let wavelength = positive(&b, "Wavelength", wavelength)?;
    let pixel = f32_of("Pixel_size")?
        .ok_or_else(|| b.bad("its OPD file has no Pixel_size block: the spacing is unknown"))?;
    let pixel = positive(&b, "Pixel_size", pixel.abs())?;
    let aspect = match f32_of("Aspect")? {
        Some(a) => positive(&b, "Aspect", a.abs())?,
        None => 1.0,
    };
    let mult = match find("Mult", 6) {
        Some(k) if k.len >= 2 => match b.i16("Mult", k.at, le)? {
            0 => 1.0,
            m => m as f64,
        },
        _ => 1.0,
    };
    let array = blocks
        .iter()
        .find(|k| k.kind == 3 && HEIGHT_NAMES.contains(&k.name.as_str()))
        .ok_or_else(|| {
            b.bad("its OPD file has no height array (RAW_DATA, RAW DATA, OPD, SAMPLE_DATA or Raw)")
        })?;
    let nx = b.u16("array columns", array.at, le)? as usize;
    let ny = b.u16("array rows", array.at + 2, le)? as usize;
    let elem = b.u16("array element size", array.at + 4, le)? as usize;
    if !matches!(elem, 1 | 2 | 4) {
        return Err(b.bad(format!(
            "its OPD height array has {elem}-byte elements; expected 1, 2 or 4"
        )));
    }
    // The array lies inside its block, which lies inside the file.
    let inner = Bytes::new(&bytes[..array.at + array.len], what);
    let data = inner.grid(array.at + 6, (ny, nx), elem, None)?;
    let scale = wavelength / mult * 1e-3;
    let mut heights = vec![f32::NAN; nx * ny];
    for (k, c) in data.chunks_exact(elem).enumerate() {
        let (x, j) = (k / ny, k % ny);
        let h = match elem {
            4 => {
                let v = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
                (v < 1e38 && v.is_finite()).then_some(v as f64)
            }
            2 => {
                let v = i16::from_le_bytes([c[0], c[1]]);
                (v < 32766).then_some(v as f64)
            }
            _ => Some(c[0] as f64),
        };
        if let Some(h) = h {
            heights[(ny - 1 - j) * nx + x] = (h * scale) as f32;
        }
    }
    let mut image = ImageFile::new(Raster::from_vec(nx, ny, 1, heights)?, Some(pixel * 1e3));
    image.spacing_y_um = Some(pixel * aspect * 1e3);
    image.unit = Some(super::Unit::Nm);
    Ok(image)
}
