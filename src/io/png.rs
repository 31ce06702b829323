//! PNG reading (8/16-bit grey, grey+alpha, RGB, RGBA, palette) and writing.

use std::io::{Cursor, Write};

use png::{BitDepth, ColorType, Compression, Transformations};

use super::{HeightMeta, ImageFile, drop_alpha};
use crate::error::{Error, Result};
use crate::raster::Raster;

const META_KEY: &str = "surftile";

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    read_scaled(bytes, what, false)
}

/// An 8- or 16-bit PNG as grey levels in [0, 1] (0 black, 1 white; alpha dropped),
/// ignoring any height metadata: for masks and other images that are not heights.
pub fn read_unit(path: &std::path::Path) -> Result<Raster> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    Ok(read_scaled(&bytes, &path.display().to_string(), true)?.raster)
}

fn read_scaled(bytes: &[u8], what: &str, unit: bool) -> Result<ImageFile> {
    let bad = |e: png::DecodingError| Error::decode(what, format!("not a valid PNG ({e})"));
    let mut decoder =
        png::Decoder::new_with_limits(Cursor::new(bytes), png::Limits { bytes: 1 << 32 });
    decoder.set_transformations(Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(bad)?;
    let meta: Option<HeightMeta> = reader
        .info()
        .uncompressed_latin1_text
        .iter()
        .find(|t| t.keyword == META_KEY)
        .and_then(|t| serde_json::from_str(&t.text).ok());
    {
        let info = reader.info();
        super::check_shape(what, info.width as usize, info.height as usize, 1)?;
        // png 0.18.1 panics expanding a palette whose PLTE chunk is not a whole number
        // of RGB entries (found by the png fuzz target; CRCs correct). The PNG
        // specification asks for 1 to 256 entries of 3 bytes.
        if info.color_type == ColorType::Indexed {
            let len = info.palette.as_deref().map_or(0, <[u8]>::len);
            if len == 0 || len % 3 != 0 || len > 768 {
                return Err(Error::decode(
                    what,
                    format!(
                        "not a valid PNG (a palette image whose PLTE chunk has {len} bytes; expected 3 to 768, a multiple of 3)"
                    ),
                ));
            }
        }
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| Error::Limits(format!("{what}: PNG too large to decode")))?;
    let mut buf = vec![0u8; size];
    let info = reader.next_frame(&mut buf).map_err(bad)?;
    buf.truncate(info.buffer_size());
    let (w, h) = (info.width as usize, info.height as usize);
    let channels = match info.color_type {
        ColorType::Grayscale => 1,
        ColorType::GrayscaleAlpha => 2,
        ColorType::Rgb => 3,
        ColorType::Rgba => 4,
        ColorType::Indexed => {
            return Err(Error::Unsupported(format!(
                "{what}: palette PNG after expansion"
            )));
        }
    };
    let (levels, max_level) = match info.bit_depth {
        BitDepth::Sixteen => (
            buf.chunks_exact(2)
                .map(|b| u16::from_be_bytes([b[0], b[1]]) as f32)
                .collect::<Vec<f32>>(),
            65535.0,
        ),
        _ => (buf.iter().map(|&b| b as f32).collect(), 255.0),
    };
    let row = w * channels;
    let mut data = Vec::with_capacity(w * h * channels);
    for r in 0..h {
        // Rows may be padded in the decoder's buffer; take exactly what the image holds.
        let start = r * (levels.len() / h.max(1));
        data.extend_from_slice(&levels[start..start + row]);
    }
    let (mut data, channels) = drop_alpha(data, channels);
    if unit {
        for v in &mut data {
            *v /= max_level as f32;
        }
    } else if let Some(meta) = &meta
        && let (Some(lo), Some(hi)) = (meta.height_min, meta.height_max)
    {
        let scale = ((hi - lo) / max_level) as f32;
        for v in &mut data {
            *v = lo as f32 + *v * scale;
        }
    }
    let mut image = ImageFile::new(Raster::from_vec(w, h, channels, data)?, None);
    if let (false, Some(meta)) = (unit, &meta) {
        meta.apply(&mut image, what)?;
    }
    Ok(image)
}

/// 16-bit PNG of `raster` (1 or 3 channels); the range and spacing go into a
/// `surftile` tEXt chunk as JSON. Heights (one channel) are min–max scaled over all
/// samples. Colour (three channels) keeps its levels where it can, so that a synthesis
/// of a photo looks like the photo in any viewer: [0, full] maps to [0, 65535] with full
/// the smallest of 1, 255 and 65535 that holds every sample ([`super::colour_full_scale`]);
/// colour outside [0, 65535] is min–max scaled like heights. A photo's synthesis whose
/// bank records the photo's scale (`meta.levels`, [`super::photo_full_scale`]), grey
/// or colour, keeps those levels where every sample lies in [0, full] (within
/// [`super::COLOUR_OVERSHOOT`], clamped), and is min–max scaled otherwise.
pub(super) fn write16(w: &mut impl Write, raster: &Raster, meta: &super::WriteMeta) -> Result<()> {
    let (lo, hi) = raster
        .data
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, u), &v| (l.min(v), u.max(v)));
    // A photo's recorded scale decides where it is known; colour of unknown source is
    // read from its range.
    let full = match meta.levels {
        Some(full) => Some(full).filter(|&full| super::holds_levels(lo, hi, full)),
        None => super::colour_full_scale(raster.channels, lo, hi),
    };
    match full {
        Some(full) => write16_in(w, raster, meta, 0.0, full),
        None => write16_in(w, raster, meta, lo, hi),
    }
}

/// [`write16`] scaled from the range [lo, hi] given, so that several files share one
/// scale: level = round((v − lo) / (hi − lo) · 65535), samples outside [lo, hi] clamped
/// (callers give a range that holds them, but for a colour's float overshoot).
pub(super) fn write16_in(
    w: &mut impl Write,
    raster: &Raster,
    meta: &super::WriteMeta,
    lo: f32,
    hi: f32,
) -> Result<()> {
    let color = match raster.channels {
        1 => ColorType::Grayscale,
        3 => ColorType::Rgb,
        c => return Err(Error::Unsupported(format!("writing a {c}-channel PNG"))),
    };
    let span = (hi - lo) as f64;
    let meta = HeightMeta {
        height_min: Some(lo as f64),
        height_max: Some(hi as f64),
        ..HeightMeta::of(meta)
    };
    let row_len = raster.width * raster.channels;
    encode(
        w,
        raster.width,
        raster.height,
        (color, BitDepth::Sixteen),
        Some(&meta),
        Compression::Balanced,
        |y, bytes| {
            for &v in &raster.data[y * row_len..(y + 1) * row_len] {
                let level = if span > 0.0 {
                    // Clamped: a colour's full scale tolerates float overshoot.
                    (((v - lo) as f64 / span).clamp(0.0, 1.0) * 65535.0).round() as u16
                } else {
                    0
                };
                bytes.extend_from_slice(&level.to_be_bytes());
            }
        },
    )
}

/// 16-bit RGB PNG of values in [−1, 1] (unit normals), each mapped to
/// round((v + 1) / 2 · 65535): what normal-map readers expect.
pub(super) fn write_signed_unit16(w: &mut impl Write, raster: &Raster) -> Result<()> {
    if raster.channels != 3 {
        return Err(Error::Unsupported(format!(
            "a {}-channel normal map (3 expected)",
            raster.channels
        )));
    }
    let row_len = raster.width * 3;
    encode(
        w,
        raster.width,
        raster.height,
        (ColorType::Rgb, BitDepth::Sixteen),
        None,
        Compression::Balanced,
        |y, bytes| {
            for &v in &raster.data[y * row_len..(y + 1) * row_len] {
                let level = (((v.clamp(-1.0, 1.0) as f64 + 1.0) / 2.0) * 65535.0).round() as u16;
                bytes.extend_from_slice(&level.to_be_bytes());
            }
        },
    )
}

/// Widest and tallest PNG written: libpng's default user limit
/// (`PNG_USER_WIDTH_MAX`/`PNG_USER_HEIGHT_MAX`), beyond which libpng-based readers and
/// most viewers refuse the file. It also bounds the encoder's row buffers.
pub const MAX_PNG_SIDE: usize = 1_000_000;

/// Refuses a PNG of `width × height` beyond [`MAX_PNG_SIDE`], before anything is
/// rendered or allocated.
pub fn check_size(width: usize, height: usize) -> Result<()> {
    if width > MAX_PNG_SIDE || height > MAX_PNG_SIDE {
        return Err(Error::Limits(format!(
            "a {width}×{height} PNG is over {MAX_PNG_SIDE} pixels a side, which libpng and most viewers refuse; write .tif or .npy, or render it in tiles"
        )));
    }
    Ok(())
}

/// Writes an 8-bit PNG (grey, RGB or RGBA by `channels`: 1, 3 or 4) atomically to `path`.
pub fn write_png8(
    path: &std::path::Path,
    width: usize,
    height: usize,
    channels: usize,
    pixels: &[u8],
) -> Result<()> {
    if super::Format::from_path(path).ok() != Some(super::Format::Png) {
        return Err(Error::param(
            "output",
            path.display(),
            "a .png file (this is an 8-bit PNG image)",
        ));
    }
    super::write_atomically(path, |w| {
        encode8(w, width, height, channels, pixels, Compression::Balanced)
    })
}

/// Encodes an 8-bit PNG (grey, RGB or RGBA by `channels`) to `w` at `compression`.
pub(super) fn encode8(
    w: &mut impl Write,
    width: usize,
    height: usize,
    channels: usize,
    pixels: &[u8],
    compression: Compression,
) -> Result<()> {
    let color = match channels {
        1 => ColorType::Grayscale,
        3 => ColorType::Rgb,
        4 => ColorType::Rgba,
        c => {
            return Err(Error::Unsupported(format!(
                "writing a {c}-channel 8-bit PNG"
            )));
        }
    };
    let row_len = width * channels;
    if pixels.len() != row_len * height {
        return Err(Error::param(
            "pixels",
            pixels.len(),
            format!("{width}×{height}×{channels} bytes"),
        ));
    }
    encode(
        w,
        width,
        height,
        (color, BitDepth::Eight),
        None,
        compression,
        |y, bytes| {
            bytes.extend_from_slice(&pixels[y * row_len..(y + 1) * row_len]);
        },
    )
}

/// Encodes a PNG row by row: `row(y, bytes)` appends row y's bytes. The image data is
/// streamed into IDAT chunks, so no whole-image buffer (raw or compressed) is held.
fn encode(
    w: &mut impl Write,
    width: usize,
    height: usize,
    (color, depth): (ColorType, BitDepth),
    meta: Option<&HeightMeta>,
    compression: Compression,
    mut row: impl FnMut(usize, &mut Vec<u8>),
) -> Result<()> {
    let err = |e: png::EncodingError| Error::decode("PNG output", e.to_string());
    check_size(width, height)?;
    let mut enc = png::Encoder::new(w, width as u32, height as u32);
    enc.set_color(color);
    enc.set_depth(depth);
    enc.set_compression(compression);
    if let Some(meta) = meta {
        let text = serde_json::to_string(meta)
            .map_err(|e| Error::decode("PNG metadata", e.to_string()))?;
        enc.add_text_chunk(META_KEY.to_string(), text)
            .map_err(err)?;
    }
    let mut writer = enc.write_header().map_err(err)?;
    let mut stream = writer.stream_writer_with_size(1 << 16).map_err(err)?;
    let mut bytes = Vec::new();
    for y in 0..height {
        bytes.clear();
        row(y, &mut bytes);
        stream
            .write_all(&bytes)
            .map_err(|e| Error::decode("PNG output", e.to_string()))?;
    }
    stream.finish().map_err(err)?;
    writer.finish().map_err(err)
}
