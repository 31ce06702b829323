//! JPEG reading (baseline and progressive; grey, YCbCr, CMYK), by `zune-jpeg`: a
//! photo as its 8-bit levels 0–255, as the PNG reader gives an 8-bit PNG. Grey stays
//! one channel; everything else decodes to RGB. JPEG holds no spacing or height unit.
//! Decoding is strict: a truncated or corrupt stream, or stray bytes between markers,
//! is refused rather than patched with grey.

use zune_jpeg::JpegDecoder;
use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;

use super::ImageFile;
use crate::error::{Error, Result};
use crate::raster::Raster;

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let bad =
        |e: zune_jpeg::errors::DecodeErrors| Error::decode(what, format!("not a valid JPEG ({e})"));
    // JPEG sides are 16-bit; the pixel budget is check_shape's.
    let options = DecoderOptions::default()
        .set_max_width(usize::from(u16::MAX))
        .set_max_height(usize::from(u16::MAX))
        // Strict: a truncated or corrupt stream is an error. A lenient decode fills
        // what is missing with grey and goes on, and a half-grey photo would be baked
        // as if it were the texture.
        .set_strict_mode(true);
    // The headers first, for the size and the colour space, before anything is
    // decoded or allocated.
    let mut headers = JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    headers.decode_headers().map_err(bad)?;
    let (w, h) = headers
        .dimensions()
        .ok_or_else(|| Error::decode(what, "not a valid JPEG (no frame header)"))?;
    let grey = matches!(
        headers.input_colorspace(),
        Some(ColorSpace::Luma | ColorSpace::LumaA)
    );
    let (space, channels) = if grey {
        (ColorSpace::Luma, 1)
    } else {
        (ColorSpace::RGB, 3)
    };
    super::check_shape(what, w, h, channels)?;
    // The output colour space is fixed when a decoder reads its headers: a second one.
    let mut decoder =
        JpegDecoder::new_with_options(ZCursor::new(bytes), options.jpeg_set_out_colorspace(space));
    decoder.decode_headers().map_err(bad)?;
    let size = decoder
        .output_buffer_size()
        .filter(|&n| n == w * h * channels)
        .ok_or_else(|| Error::decode(what, "not a valid JPEG (its frame size changed)"))?;
    let mut levels = vec![0u8; size];
    decoder.decode_into(&mut levels).map_err(bad)?;
    let data = levels.into_iter().map(f32::from).collect();
    Ok(ImageFile::new(
        Raster::from_vec(w, h, channels, data)?,
        None,
    ))
}
