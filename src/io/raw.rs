//! Raw little-endian f32 files with a shape given by the caller.

use super::ImageFile;
use crate::error::{Error, Result};
use crate::raster::Raster;

pub(super) fn read(
    bytes: &[u8],
    what: &str,
    (w, h, c): (usize, usize, usize),
) -> Result<ImageFile> {
    let expected = super::check_shape(what, w, h, c)? * 4;
    if bytes.len() != expected {
        return Err(Error::decode(
            what,
            format!(
                "raw f32 file has {} bytes; the shape {w}x{h}x{c} needs {expected}",
                bytes.len()
            ),
        ));
    }
    let data = bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    Ok(ImageFile::new(Raster::from_vec(w, h, c, data)?, None))
}
