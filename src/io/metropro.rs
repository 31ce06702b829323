//! Zygo MetroPro `.dat`: a big-endian header (format 1 or 2: 834 bytes, 3: 4096 bytes,
//! named by the magic number), intensity frames (u16), then the phase array as i32
//! rows from the top. Height (m) = raw · interferometric scale factor · wavelength ·
//! obliquity / R, with R = 4096, 32768 or 131072 by the phase resolution, negated when
//! the sign flag is set; raw values ≥ 2147483640 are invalid. Spacing: `lateral_res`
//! (m per pixel).

use super::ImageFile;
use super::bytes::{Bytes, Order, positive};
use crate::error::Result;
use crate::raster::Raster;

/// (magic, header format, header size).
const FORMATS: [(u32, u16, u32); 3] = [
    (0x881B_036F, 1, 834),
    (0x881B_0370, 2, 834),
    (0x881B_0371, 3, 4096),
];
const INVALID: i32 = 2_147_483_640;

pub(super) fn sniff(bytes: &[u8]) -> bool {
    bytes.len() >= 4 && {
        let magic = u32::from_be_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
        FORMATS.iter().any(|f| f.0 == magic)
    }
}

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let b = Bytes::new(bytes, what);
    let be = Order::Big;
    let magic = b.u32("magic number", 0, be)?;
    let format = b.u16("header format", 4, be)?;
    let size = b.u32("header size", 6, be)?;
    if !FORMATS.contains(&(magic, format, size)) {
        return Err(b.bad(format!(
            "not a MetroPro file it can read: magic {magic:#010x}, header format {format}, header size {size}"
        )));
    }
    let header = size as usize;
    b.slice("header", 0, header)?;
    let (aw, ah, buckets) = (
        b.u16("intensity width", 52, be)? as usize,
        b.u16("intensity height", 54, be)? as usize,
        b.u16("intensity buckets", 56, be)? as usize,
    );
    let intensity = b.u32("intensity byte count", 60, be)? as usize;
    if intensity != 2 * aw * ah * buckets {
        return Err(b.bad(format!(
            "its MetroPro intensity byte count {intensity} disagrees with {buckets} frames of {aw}×{ah} u16"
        )));
    }
    let (nx, ny) = (
        b.u16("phase width", 68, be)? as usize,
        b.u16("phase height", 70, be)? as usize,
    );
    if nx == 0 || ny == 0 {
        return Err(b.bad("its MetroPro file holds no phase (height) data, only intensity"));
    }
    let phase_bytes = b.u32("phase byte count", 72, be)? as usize;
    if phase_bytes != 4 * nx * ny {
        return Err(b.bad(format!(
            "its MetroPro phase byte count {phase_bytes} disagrees with a {nx}×{ny} i32 array"
        )));
    }
    let scale = b.f32("interferometric scale factor", 164, be)? as f64;
    let wavelength = positive(&b, "wavelength", b.f32("wavelength", 168, be)? as f64)?;
    let obliquity = b.f32("obliquity factor", 176, be)? as f64;
    let lateral = positive(
        &b,
        "lateral resolution",
        b.f32("lateral resolution", 184, be)? as f64,
    )?;
    let r = match b.i16("phase resolution", 218, be)? {
        0 => 4096.0,
        1 => 32768.0,
        2 => 131072.0,
        other => {
            return Err(b.bad(format!(
                "its MetroPro phase resolution code is {other}; expected 0, 1 or 2"
            )));
        }
    };
    if !(scale.is_finite() && obliquity.is_finite()) {
        return Err(b.bad("its MetroPro scale factor or obliquity is not finite"));
    }
    let sign = if b.i16("sign", 232, be)? != 0 {
        -1.0
    } else {
        1.0
    };
    let k = sign * scale * wavelength * obliquity / r * 1e6;
    if !(k.is_finite() && k != 0.0) {
        return Err(b.bad(format!(
            "its MetroPro height scale (scale factor {scale} × wavelength {wavelength} m × obliquity {obliquity}) is 0 or not finite"
        )));
    }
    let data = b.grid(header + intensity, (nx, ny), 4, None)?;
    let heights = data
        .chunks_exact(4)
        .map(|c| {
            let raw = i32::from_be_bytes([c[0], c[1], c[2], c[3]]);
            if raw >= INVALID {
                f32::NAN
            } else {
                (raw as f64 * k) as f32
            }
        })
        .collect();
    let mut image = ImageFile::new(Raster::from_vec(nx, ny, 1, heights)?, Some(lateral * 1e6));
    image.unit = Some(super::Unit::M);
    Ok(image)
}
