//! OpenEXR (through the `exr` crate): 32-bit float samples, one channel (`Y`) for
//! heights, `R`, `G`, `B` (and `A`) for colour, ZIP-compressed scan lines, top row
//! first. The spacing and height unit go into a `surftile` text attribute (the same
//! JSON as PNG and TIFF); heights are written as they are, so a write → read round trip
//! gives the same f32 bits. Read: the first layer's largest resolution level, any
//! sample type (f16, f32, u32) as f32; `Y`, or `R`, `G`, `B` (`A` dropped), or a single
//! channel of any name.

use std::io::{Cursor, Seek, Write};

use exr::prelude::*;

use super::{HeightMeta, ImageFile, WriteMeta};
use crate::error::{Error, Result};
use crate::raster::Raster;

/// The text attribute holding surftile's metadata.
const META: &str = "surftile";

/// Tile area accepted whatever the image's size (256², a common tile).
const TILE_PX_ALWAYS: usize = 1 << 16;

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let bad = |m: String| Error::decode(what, m);
    // The header first: sizes are checked before any pixel is decoded.
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(|e| bad(format!("not a readable OpenEXR file: {e}")))?;
    let header = meta
        .headers
        .first()
        .ok_or_else(|| bad("an OpenEXR file without a layer".into()))?;
    let size = header.layer_size;
    let channels = header.channels.list.len();
    // Every channel is decoded: the pixel budget of the other readers (2^25 pixels of
    // at most 4 channels) bounds pixels × channels, however many channels there are.
    let pixels = super::check_shape(what, size.width(), size.height(), 1)?;
    if channels == 0 || pixels.saturating_mul(channels) > 4 * super::MAX_IMAGE_PIXELS {
        return Err(Error::Limits(format!(
            "{what}: an OpenEXR layer of {}×{} pixels and {channels} channels; at most {} samples (2^25 pixels of 4 channels)",
            size.width(),
            size.height(),
            4 * super::MAX_IMAGE_PIXELS
        )));
    }
    // Multi-resolution files are refused, and every tile chunk must then be of level
    // (0, 0) (checked below), before decoding: the exr crate files a chunk by the level the chunk
    // itself claims, so a lying one hands a line of another level to the reader of
    // the first (a fuzz finding: the crate's debug assertion fires, and a release
    // build would place the line by the wrong level's geometry). Heights are written
    // single-resolution.
    if let exr::meta::BlockDescription::Tiles(tiles) = &header.blocks {
        // A tile larger than the image is never needed, and the exr crate sizes its
        // buffers by the tile the header claims (a fuzz finding: a 24 × 16 image with
        // tiles of 825194048 × 131585 pixels took 1.6 GB before any pixel was read).
        let (tw, th) = (tiles.tile_size.width(), tiles.tile_size.height());
        let tile_px = (tw as u128) * (th as u128);
        if tile_px > (pixels.max(TILE_PX_ALWAYS) as u128)
            || tile_px * channels as u128 > 4 * super::MAX_IMAGE_PIXELS as u128
        {
            return Err(bad(format!(
                "OpenEXR tiles of {tw}×{th} pixels for a {}×{} image; expected tiles no larger than the image (or {TILE_PX_ALWAYS} pixels)",
                size.width(),
                size.height()
            )));
        }
        if tiles.level_mode != exr::meta::attribute::LevelMode::Singular {
            return Err(bad(format!(
                "a multi-resolution ({:?}) OpenEXR image; surftile reads single-resolution images",
                tiles.level_mode
            )));
        }
    }
    // Every tile chunk must be of level (0, 0), read as the decoder reads them: at the
    // offsets the offset table gives. (Read in file order, as this check first did,
    // they missed a second fuzz finding, `fuzz/seeds/exr/tile-level-at-the-table-offset.exr`,
    // whose tile at the table's offset claims level (0, 1).)
    if meta
        .headers
        .iter()
        .any(|h| matches!(h.blocks, exr::meta::BlockDescription::Tiles(_)))
    {
        let chunks = exr::block::read(Cursor::new(bytes), false)
            .and_then(|r| r.filter_chunks(false, |_, _, _| true))
            .map_err(|e| bad(format!("OpenEXR: {e}")))?;
        for chunk in chunks {
            let chunk = chunk.map_err(|e| bad(format!("OpenEXR: {e}")))?;
            if let exr::block::chunk::CompressedBlock::Tile(t) = &chunk.compressed_block
                && t.coordinates.level_index != Vec2(0, 0)
            {
                let l = t.coordinates.level_index;
                return Err(bad(format!(
                    "a tile of resolution level ({}, {}) in a single-resolution OpenEXR image",
                    l.x(),
                    l.y()
                )));
            }
        }
    }
    if header.deep {
        return Err(bad(
            "a deep OpenEXR image; surftile reads flat images".into()
        ));
    }
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| bad(format!("OpenEXR: {e}")))?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let list = &layer.channel_data.list;
    let find = |name: &str| list.iter().find(|c| c.name.eq(name));
    let planes: Vec<&AnyChannel<FlatSamples>> = if let Some(y) = find("Y") {
        vec![y]
    } else if let (Some(r), Some(g), Some(b)) = (find("R"), find("G"), find("B")) {
        vec![r, g, b]
    } else if list.len() == 1 {
        vec![&list[0]]
    } else {
        let names: Vec<String> = list.iter().map(|c| c.name.to_string()).collect();
        return Err(bad(format!(
            "OpenEXR channels {}; expected Y, or R, G and B, or a single channel",
            names.join(", ")
        )));
    };
    let c = planes.len();
    let mut data = vec![0.0f32; w * h * c];
    for (k, plane) in planes.iter().enumerate() {
        for (i, v) in plane.sample_data.values_as_f32().enumerate().take(w * h) {
            data[i * c + k] = v;
        }
    }
    let mut out = ImageFile::new(Raster::from_vec(w, h, c, data)?, None);
    if let Some(AttributeValue::Text(text)) = layer.attributes.other.get(&Text::from(META))
        && let Ok(m) = serde_json::from_str::<HeightMeta>(&text.to_string())
    {
        m.apply(&mut out, what)?;
    }
    Ok(out)
}

pub(super) fn write<W: Write + Seek>(w: W, raster: &Raster, meta: &WriteMeta) -> Result<()> {
    let err = |e: exr::error::Error| Error::decode("OpenEXR output", e.to_string());
    let names: &[&str] = match raster.channels {
        1 => &["Y"],
        3 => &["R", "G", "B"],
        4 => &["R", "G", "B", "A"],
        c => {
            return Err(Error::Unsupported(format!(
                "writing a {c}-channel OpenEXR (1, 3 or 4 channels)"
            )));
        }
    };
    let c = raster.channels;
    let channels = names
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let plane = raster.data.iter().skip(k).step_by(c).copied().collect();
            AnyChannel::new(*name, FlatSamples::F32(plane))
        })
        .collect();
    let mut attributes = LayerAttributes::default();
    let json = serde_json::to_string(&HeightMeta::of(meta))
        .map_err(|e| Error::decode("OpenEXR metadata", e.to_string()))?;
    let text = Text::new_or_none(&json)
        .ok_or_else(|| Error::decode("OpenEXR metadata", format!("{json} is not Latin-1 text")))?;
    attributes
        .other
        .insert(Text::from(META), AttributeValue::Text(text));
    let layer = Layer::new(
        (raster.width, raster.height),
        attributes,
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(channels),
    );
    Image::from_layer(layer)
        .write()
        .non_parallel()
        .to_buffered(w)
        .map_err(err)
}
