//! TIFF reading (8/16/32-bit integer, 32/64-bit float; grey, grey+alpha, RGB, RGBA) and
//! 32-bit float writing. surftile's metadata (spacing) is JSON in ImageDescription.

use std::io::{Cursor, Seek, Write};

use tiff::ColorType;
use tiff::decoder::{Decoder, DecodingResult};
use tiff::encoder::{TiffEncoder, colortype};
use tiff::tags::Tag;

use super::{HeightMeta, ImageFile, drop_alpha};
use crate::error::{Error, Result};
use crate::raster::Raster;

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let bad = |e: tiff::TiffError| match e {
        // Built without tiff's JPEG codec (see Cargo.toml): say why, and what is read.
        tiff::TiffError::UnsupportedError(
            tiff::TiffUnsupportedError::UnsupportedCompressionMethod(method),
        ) => Error::Unsupported(format!(
            "{what}: TIFF compression {method:?}; expected none, LZW, deflate or fax (lossy \
             JPEG-in-TIFF is not read: save the photo as .jpg or .png)"
        )),
        e => Error::decode(what, format!("not a readable TIFF ({e})")),
    };
    let mut dec = Decoder::new(Cursor::new(bytes)).map_err(bad)?;
    let (w, h) = dec.dimensions().map_err(bad)?;
    let channels = match dec.colortype().map_err(bad)? {
        ColorType::Gray(_) => 1,
        ColorType::GrayA(_) => 2,
        ColorType::RGB(_) => 3,
        ColorType::RGBA(_) => 4,
        other => {
            return Err(Error::Unsupported(format!(
                "{what}: TIFF colour type {other:?}; expected grey or RGB"
            )));
        }
    };
    super::check_shape(what, w as usize, h as usize, channels)?;
    let meta = dec
        .get_tag_ascii_string(Tag::ImageDescription)
        .ok()
        .and_then(|s| serde_json::from_str::<HeightMeta>(&s).ok());
    let data: Vec<f32> = match dec.read_image().map_err(bad)? {
        DecodingResult::U8(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U32(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::I8(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I32(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::F32(v) => v,
        DecodingResult::F64(v) => v.into_iter().map(|x| x as f32).collect(),
        _ => {
            return Err(Error::Unsupported(format!(
                "{what}: TIFF sample type; expected 8/16/32-bit integer or 32/64-bit float"
            )));
        }
    };
    let (w, h) = (w as usize, h as usize);
    if data.len() < w * h * channels {
        return Err(Error::decode(
            what,
            "TIFF holds fewer samples than its size says",
        ));
    }
    let mut data = data;
    data.truncate(w * h * channels);
    let (data, channels) = drop_alpha(data, channels);
    let mut image = ImageFile::new(Raster::from_vec(w, h, channels, data)?, None);
    if let Some(meta) = meta {
        meta.apply(&mut image, what)?;
    }
    Ok(image)
}

pub(super) fn write(
    w: &mut (impl Write + Seek),
    raster: &Raster,
    meta: &super::WriteMeta,
) -> Result<()> {
    let err = |e: tiff::TiffError| Error::decode("TIFF output", e.to_string());
    let (wd, ht) = (
        u32::try_from(raster.width).map_err(|_| Error::Limits("TIFF width".into()))?,
        u32::try_from(raster.height).map_err(|_| Error::Limits("TIFF height".into()))?,
    );
    let meta = serde_json::to_string(&HeightMeta::of(meta))
        .map_err(|e| Error::decode("TIFF metadata", e.to_string()))?;
    let mut enc = TiffEncoder::new(w).map_err(err)?;
    match raster.channels {
        1 => {
            let mut img = enc
                .new_image::<colortype::Gray32Float>(wd, ht)
                .map_err(err)?;
            img.encoder()
                .write_tag(Tag::ImageDescription, meta.as_str())
                .map_err(err)?;
            img.write_data(&raster.data).map_err(err)
        }
        3 => {
            let mut img = enc
                .new_image::<colortype::RGB32Float>(wd, ht)
                .map_err(err)?;
            img.encoder()
                .write_tag(Tag::ImageDescription, meta.as_str())
                .map_err(err)?;
            img.write_data(&raster.data).map_err(err)
        }
        c => Err(Error::Unsupported(format!("writing a {c}-channel TIFF"))),
    }
}
