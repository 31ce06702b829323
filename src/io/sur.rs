//! Digital Surf SUR (MountainsMap): a 512-byte little-endian object header, optional
//! comment and private zones, then 16- or 32-bit signed integers row by row from the
//! top (`DIGITAL SURF`), or the same block as zlib streams (`DSCOMPRESSED`). Height =
//! raw · Z spacing + Z offset in the Z step unit; with special points flagged, a raw
//! value of Zmin − 2 is a non-measured point. The first object of a file is read.

use std::io::Read;

use super::ImageFile;
use super::bytes::{Bytes, Order, positive};
use crate::error::Result;
use crate::raster::Raster;

const HEADER: usize = 512;
/// Most zlib streams a compressed block may name.
const MAX_STREAMS: usize = 1024;

/// A length unit's size in µm (`None`: not a length).
fn unit_um(unit: &str) -> Option<(f64, super::Unit)> {
    use super::Unit;
    let u = unit.trim().trim_matches('\0');
    Some(match u {
        "m" => (1e6, Unit::M),
        "mm" => (1e3, Unit::Mm),
        "µm" | "um" | "\u{3bc}m" => (1.0, Unit::Um),
        "nm" => (1e-3, Unit::Nm),
        "Å" | "A" => (1e-4, Unit::Angstrom),
        "pm" => (1e-6, Unit::Pm),
        _ => return None,
    })
}

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let b = Bytes::new(bytes, what);
    let signature = b.slice("signature", 0, 12)?;
    let compressed = match signature {
        b"DIGITAL SURF" => false,
        b"DSCOMPRESSED" => true,
        _ => return Err(b.bad("not a SUR file (it does not start with 'DIGITAL SURF')")),
    };
    b.slice("512-byte header", 0, HEADER)?;
    let le = Order::Little;
    if b.u16("format", 12, le)? == 257 {
        return Err(b.bad("it is a big-endian (Macintosh) SUR file; only PC files are read"));
    }
    let kind = b.i16("object type", 18, le)?;
    if !matches!(kind, 2 | 5 | 8 | 13 | 16) {
        return Err(b.bad(format!(
            "its SUR object type {kind} is not a surface (2, or a series/multilayer/RGB surface)"
        )));
    }
    if b.u32("W size", 94, le)? > 1 {
        return Err(b.bad("it is a SUR spectrum (W size above 1), not a surface"));
    }
    let bits = b.i16("point size", 98, le)?;
    if bits != 16 && bits != 32 {
        return Err(b.bad(format!(
            "its SUR point size is {bits} bits; expected 16 or 32"
        )));
    }
    let elem = bits as usize / 8;
    let special = b.i16("special points", 86, le)? != 0;
    let zmin = b.i32("Zmin", 100, le)? as i64;
    let (nx, ny) = (b.i32("points per line", 108, le)?, b.i32("lines", 112, le)?);
    if nx <= 0 || ny <= 0 {
        return Err(b.bad(format!(
            "its SUR grid is {nx}×{ny}; expected positive sizes"
        )));
    }
    let (nx, ny) = (nx as usize, ny as usize);
    let total = b.i32("total points", 116, le)?;
    if total as i64 != nx as i64 * ny as i64 {
        return Err(b.bad(format!(
            "its SUR header says {total} points but the grid is {nx}×{ny}"
        )));
    }
    let unit = |field: &str, at: usize| -> Result<(f64, super::Unit)> {
        // Latin-1: 0xB5 is µ, 0xC5 is Å.
        let text: String = b
            .slice(field, at, 16)?
            .iter()
            .map(|&c| c as char)
            .collect::<String>()
            .trim_matches(|c: char| c == '\0' || c.is_whitespace())
            .to_string();
        unit_um(&text)
            .ok_or_else(|| b.bad(format!("its SUR {field} is '{text}', not a length unit")))
    };
    let (ux, _) = unit("X step unit", 180)?;
    let (uy, _) = unit("Y step unit", 196)?;
    let (uz, zunit) = unit("Z step unit", 212)?;
    let dx = positive(&b, "X spacing", (b.f32("X spacing", 120, le)? as f64).abs())? * ux;
    let dy = positive(&b, "Y spacing", (b.f32("Y spacing", 124, le)? as f64).abs())? * uy;
    let dz = b.f32("Z spacing", 128, le)? as f64;
    let z0 = b.f32("Z offset", 474, le)? as f64;
    if !dz.is_finite() || dz == 0.0 || !z0.is_finite() {
        return Err(b.bad(format!(
            "its SUR Z spacing {dz} or offset {z0} is not finite (or the spacing is 0)"
        )));
    }
    let zones = b.u16("comment size", 334, le)? as usize + b.u16("private size", 336, le)? as usize;
    let offset = HEADER + zones;
    super::check_shape(what, nx, ny, 1)?;
    let inflated;
    let block: &[u8] = if compressed {
        let n = b.u32("stream count", offset, le)? as usize;
        if n == 0 || n > MAX_STREAMS {
            return Err(b.bad(format!(
                "its SUR compressed block names {n} streams; expected 1 to {MAX_STREAMS}"
            )));
        }
        let mut at = offset + 4 + 8 * n;
        b.slice("stream directory", offset + 4, 8 * n)?;
        let want = nx * ny * elem;
        // The whole directory is checked before anything is inflated: the streams'
        // sizes must add up to the grid's, and their compressed bytes must be present.
        let mut sizes = Vec::with_capacity(n);
        let (mut raw_total, mut zipped_total) = (0u64, 0u64);
        for k in 0..n {
            let raw = b.u32("stream size", offset + 4 + 8 * k, le)? as usize;
            let zipped = b.u32("stream size", offset + 8 + 8 * k, le)? as usize;
            raw_total += raw as u64;
            zipped_total += zipped as u64;
            sizes.push((raw, zipped));
        }
        if raw_total != want as u64 {
            return Err(b.bad(format!(
                "its SUR streams hold {raw_total} bytes; a {nx}×{ny} grid of {bits}-bit points needs {want}"
            )));
        }
        b.slice("compressed streams", at, zipped_total as usize)?;
        // Nothing is reserved from the header's sizes: the buffer grows as data inflates.
        let mut out = Vec::new();
        for (k, &(raw, zipped)) in sizes.iter().enumerate() {
            let stream = b.slice("compressed stream", at, zipped)?;
            at += zipped;
            let before = out.len();
            flate2::read::ZlibDecoder::new(stream)
                .take(raw as u64 + 1)
                .read_to_end(&mut out)
                .map_err(|e| b.bad(format!("its SUR stream {k} does not inflate: {e}")))?;
            if out.len() - before != raw {
                return Err(b.bad(format!(
                    "its SUR stream {k} inflates to {} bytes; its directory says {raw}",
                    out.len() - before
                )));
            }
        }
        if out.len() != want {
            return Err(b.bad(format!(
                "its SUR streams hold {} bytes; a {nx}×{ny} grid of {bits}-bit points needs {want}",
                out.len()
            )));
        }
        inflated = out;
        &inflated
    } else {
        b.grid(offset, (nx, ny), elem, None)?
    };
    let missing = zmin - 2;
    let k = uz;
    let heights = block
        .chunks_exact(elem)
        .map(|c| {
            let raw = if elem == 2 {
                i16::from_le_bytes([c[0], c[1]]) as i64
            } else {
                i32::from_le_bytes([c[0], c[1], c[2], c[3]]) as i64
            };
            if special && raw == missing {
                f32::NAN
            } else {
                ((raw as f64 * dz + z0) * k) as f32
            }
        })
        .collect();
    let mut image = ImageFile::new(Raster::from_vec(nx, ny, 1, heights)?, Some(dx));
    image.spacing_y_um = Some(dy);
    image.unit = Some(zunit);
    Ok(image)
}
