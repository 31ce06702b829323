//! Sensofar PLU (PLu 2000 to 2013): a 500-byte little-endian header that starts with
//! a `ctime` date, then per layer u32 rows, u32 columns and float32 heights in µm, row
//! by row from the top. Invalid points hold 1000001. The x and y spacing (µm per pixel)
//! are float32 at 404 and 408; the measurement type (u32 at 428) must be 3, a
//! topography. Layer 0 is read.

use super::ImageFile;
use super::bytes::{Bytes, Order, positive};
use crate::error::Result;
use crate::raster::Raster;

const HEADER: usize = 500;
/// Sensofar's "lost pixel" value.
const LOST: f32 = 1_000_001.0;

/// Whether `bytes` look like a PLU file: a `ctime` date at the start ("Www Mmm dd
/// hh:mm:ss yyyy") and a known format-version byte at 490. PLU has no magic number, so
/// this is tried after every format that has one.
pub(super) fn sniff(bytes: &[u8]) -> bool {
    if bytes.len() < 512 {
        return false;
    }
    let days = ["Mon", "Tue", "Wed", "Thu", "Fri", "Sat", "Sun"];
    let months = [
        "Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec",
    ];
    let s = &bytes[..24];
    let word = |range: std::ops::Range<usize>, set: &[&str]| {
        set.iter().any(|w| w.as_bytes() == &s[range.clone()])
    };
    let digit = |i: usize| s[i].is_ascii_digit();
    let date = word(0..3, &days)
        && s[3] == b' '
        && word(4..7, &months)
        && s[7] == b' '
        && (digit(8) || s[8] == b' ')
        && digit(9)
        && s[10] == b' '
        && digit(11)
        && digit(12)
        && s[13] == b':'
        && (20..24).all(digit);
    let version = bytes[490];
    date && (bytes[24] == 0 || bytes[24].is_ascii_whitespace()) && (version == 0 || version >= 0xF0)
}

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let b = Bytes::new(bytes, what);
    if bytes.len() < HEADER + 8 {
        return Err(b.bad(format!(
            "truncated: a PLU file holds a {HEADER}-byte header and a layer's size, the file has {} bytes",
            bytes.len()
        )));
    }
    let kind = b.u32("measurement type", 428, Order::Little)?;
    match kind {
        3 => {}
        0 => return Err(b.bad("its PLU measurement type 0 is an image, not a topography")),
        1 | 2 | 5 => {
            return Err(b.bad(format!(
                "its PLU measurement type {kind} is a profile, not an areal topography"
            )));
        }
        _ => {
            return Err(b.bad(format!(
                "its PLU measurement type {kind} is not supported; expected 3 (topography)"
            )));
        }
    }
    if bytes[489] == 0 {
        return Err(b.bad("its PLU header says it holds no data layers"));
    }
    let dx = positive(
        &b,
        "x pixel size",
        (b.f32("x pixel size", 404, Order::Little)? as f64).abs(),
    )?;
    let dy = positive(
        &b,
        "y pixel size",
        (b.f32("y pixel size", 408, Order::Little)? as f64).abs(),
    )?;
    let ny = b.u32("layer rows", HEADER, Order::Little)? as usize;
    let nx = b.u32("layer columns", HEADER + 4, Order::Little)? as usize;
    let block = b.grid(HEADER + 8, (nx, ny), 4, None)?;
    // The layer ends with its minimum and maximum (8 bytes).
    b.slice("layer's minimum and maximum", HEADER + 8 + block.len(), 8)?;
    let heights = block
        .chunks_exact(4)
        .map(|c| {
            let v = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
            if v == LOST || !v.is_finite() {
                f32::NAN
            } else {
                v
            }
        })
        .collect();
    let mut image = ImageFile::new(Raster::from_vec(nx, ny, 1, heights)?, Some(dx));
    image.spacing_y_um = Some(dy);
    image.unit = Some(super::Unit::Um);
    Ok(image)
}
