//! Exemplar and output formats.
//!
//! Read: PNG 8/16-bit (grey, grey+alpha, RGB, RGBA; alpha is dropped), TIFF (8/16-bit
//! integer, 32/64-bit float; grey or RGB), NumPy `.npy` (f32, f64, u8, u16, i16, i32; C or
//! Fortran order; H×W or H×W×C), raw little-endian f32 with a given shape, and X3P
//! (ISO 25178-72; heights in µm).
//!
//! Write: 16-bit PNG (the height range is stored in a `surftile` text chunk so heights
//! can be recovered), 32-bit float TIFF (metadata in ImageDescription), `.npy`
//! (float32) and X3P (float64 metres, the command line in its comment). The pixel
//! spacing (µm per pixel) travels in the PNG, TIFF and X3P metadata; for `.npy` and raw
//! files it comes from the caller (the CLI's `--spacing`).
//!
//! Every write goes to a temporary file beside the target and is renamed into place
//! only when complete, so a failed write never leaves a half-written output.

mod npy;
mod png;
mod raw;
mod tiff;
mod x3p;

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::raster::Raster;

pub use self::png::{MAX_PNG_SIDE, check_size as check_png_size, read_unit, write_png8};

/// A decoded image and what its file said about it.
#[derive(Clone, Debug)]
pub struct ImageFile {
    /// The samples.
    pub raster: Raster,
    /// Pixel spacing in µm per pixel, when the file records it.
    pub spacing_um: Option<f64>,
}

/// Most pixels any reader decodes (2²⁵, e.g. 5792²): at 4 channels of f32 that is 512 MiB,
/// so a small file claiming a huge image (a decompression bomb, a lying header) is
/// refused before anything is allocated.
pub const MAX_IMAGE_PIXELS: usize = 1 << 25;

/// Checks a shape read from a file (or given for a raw one) before anything is
/// allocated for it: 1 to 4 channels, sides of at least 1, and at most
/// [`MAX_IMAGE_PIXELS`] pixels, with checked arithmetic. Returns the sample count.
pub(crate) fn check_shape(what: &str, w: usize, h: usize, c: usize) -> Result<usize> {
    if !(1..=4).contains(&c) {
        return Err(Error::decode(
            what,
            format!("{c} channels; expected 1 to 4"),
        ));
    }
    match w.checked_mul(h) {
        Some(n) if n > 0 && n <= MAX_IMAGE_PIXELS => Ok(n * c),
        Some(0) => Err(Error::decode(what, format!("an empty image ({w}×{h})"))),
        _ => Err(Error::Limits(format!(
            "{what}: {w}×{h} pixels; this reader takes at most {MAX_IMAGE_PIXELS} (2^25) pixels"
        ))),
    }
}

/// Options for reading; only raw files need any.
#[derive(Clone, Copy, Debug, Default)]
pub struct ReadOptions {
    /// Shape of a raw f32 file: (width, height, channels).
    pub raw_shape: Option<(usize, usize, usize)>,
}

/// The metadata surftile writes beside heights in PNG and TIFF files.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct HeightMeta {
    /// Height mapped to grey level 0 (PNG only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height_min: Option<f64>,
    /// Height mapped to the largest grey level (PNG only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height_max: Option<f64>,
    /// Pixel spacing in µm per pixel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spacing_um: Option<f64>,
}

/// Image formats, chosen by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// `.png`
    Png,
    /// `.tif`, `.tiff`
    Tiff,
    /// `.npy`
    Npy,
    /// `.raw`, `.f32`, `.bin`: little-endian f32
    Raw,
    /// `.x3p`: ISO 25178-72
    X3p,
}

impl Format {
    /// The format of `path` by its extension.
    pub fn from_path(path: &Path) -> Result<Format> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "png" => Ok(Format::Png),
            "tif" | "tiff" => Ok(Format::Tiff),
            "npy" => Ok(Format::Npy),
            "raw" | "f32" | "bin" => Ok(Format::Raw),
            "x3p" => Ok(Format::X3p),
            _ => Err(Error::Unsupported(format!(
                "{}: unknown image extension '{ext}'; expected .png, .tif/.tiff, .npy, .x3p or .raw/.f32",
                path.display()
            ))),
        }
    }
}

/// Reads an image file, choosing the decoder by extension.
pub fn read_image(path: &Path, options: &ReadOptions) -> Result<ImageFile> {
    let format = Format::from_path(path)?;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let what = path.display().to_string();
    read_image_bytes(&bytes, format, &what, options)
}

/// Decodes an image held in memory (`what` names it in errors).
pub fn read_image_bytes(
    bytes: &[u8],
    format: Format,
    what: &str,
    options: &ReadOptions,
) -> Result<ImageFile> {
    if bytes.is_empty() {
        return Err(Error::decode(what, "the file is empty"));
    }
    let image = match format {
        Format::Png => png::read(bytes, what)?,
        Format::Tiff => tiff::read(bytes, what)?,
        Format::Npy => npy::read(bytes, what)?,
        Format::X3p => x3p::read(bytes, what)?,
        Format::Raw => {
            let shape = options.raw_shape.ok_or_else(|| {
                Error::param("raw-shape", "none", "WxH or WxHxC for a raw f32 file")
            })?;
            raw::read(bytes, what, shape)?
        }
    };
    if image.raster.width == 0 || image.raster.height == 0 {
        return Err(Error::decode(
            what,
            "the image has no pixels (0 width or height)",
        ));
    }
    Ok(image)
}

/// Writes heights (or colours) to `path` in the format its extension names: 16-bit PNG,
/// 32-bit float TIFF or float32 `.npy`. Non-finite samples are refused.
pub fn write_heights(path: &Path, raster: &Raster, spacing_um: Option<f64>) -> Result<()> {
    if raster.data.iter().any(|v| !v.is_finite()) {
        return Err(Error::param(
            "output samples",
            "non-finite",
            "finite heights (NaN or infinite values cannot be written)",
        ));
    }
    let format = Format::from_path(path)?;
    write_atomically(path, |w| match format {
        Format::Png => png::write16(w, raster, spacing_um),
        Format::Tiff => tiff::write(w, raster, spacing_um),
        Format::Npy => npy::write(w, raster),
        Format::X3p => {
            // The generating command, as the X3P record's comment.
            let command: Vec<String> = std::env::args().collect();
            x3p::write(w, raster, spacing_um, &command.join(" "))
        }
        Format::Raw => {
            for v in &raster.data {
                std::io::Write::write_all(w, &v.to_le_bytes()).map_err(|e| Error::io(path, e))?;
            }
            Ok(())
        }
    })
}

/// A raster as the bytes of a float32 `.npy` file ((H, W) or (H, W, C), C order): what
/// [`write_heights`] writes to a `.npy` path, for containers such as a dataset's shards.
pub fn npy_bytes(raster: &Raster) -> Result<Vec<u8>> {
    let mut out = Vec::with_capacity(raster.data.len() * 4 + 128);
    npy::write(&mut out, raster)?;
    Ok(out)
}

/// An 8-bit PNG (grey, RGB or RGBA by `channels`) as bytes, compressed for speed (the
/// pixels [`write_png8`] writes, in a somewhat larger file): a dataset's masks.
pub fn png8_bytes(width: usize, height: usize, channels: usize, pixels: &[u8]) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    png::encode8(
        &mut out,
        width,
        height,
        channels,
        pixels,
        ::png::Compression::Fast,
    )?;
    Ok(out)
}

/// Writes a file through a temporary sibling that is renamed into place on success and
/// removed on failure, so `path` is either complete or untouched.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<()> {
    let tmp = temp_sibling(path, &format!(".part-{}", std::process::id()));
    let result = (|| {
        let file = File::create(&tmp).map_err(|e| Error::io(path, e))?;
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w
            .into_inner()
            .map_err(|e| Error::io(path, e.into_error()))?;
        file.sync_all().map_err(|e| Error::io(path, e))?;
        std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Outputs that appear together or not at all: each is written (atomically) under a
/// staged name beside its final one, and [`Staged::commit`] renames them all; dropped
/// without a commit (an error on the way), the staged files are removed. So a command
/// with several outputs never leaves some of them behind.
#[derive(Debug, Default)]
pub struct Staged {
    moves: Vec<(PathBuf, PathBuf)>,
}

impl Staged {
    /// Nothing staged yet.
    pub fn new() -> Staged {
        Staged::default()
    }

    /// Checks that `paths` name different files (as absolute paths), so that no output
    /// silently overwrites another; each path comes with the name of its option.
    pub fn distinct(paths: &[(&str, &Path)]) -> Result<()> {
        for (i, (a_name, a)) in paths.iter().enumerate() {
            for (b_name, b) in &paths[..i] {
                let same = std::path::absolute(a).ok() == std::path::absolute(b).ok();
                if same {
                    return Err(Error::param(
                        *a_name,
                        a.display(),
                        format!("a file other than the {b_name} output"),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Where to write the output that will become `path`.
    pub fn path(&mut self, path: &Path) -> PathBuf {
        // The staged name keeps the extension: the writers choose the format by it.
        let ext = path
            .extension()
            .map(|e| format!(".{}", e.to_string_lossy()))
            .unwrap_or_default();
        let staged = temp_sibling(path, &format!(".staged-{}{ext}", std::process::id()));
        self.moves.push((staged.clone(), path.to_path_buf()));
        staged
    }

    /// Renames every staged output to its final name; if a rename fails, the staged
    /// outputs not yet renamed are removed.
    pub fn commit(mut self) -> Result<()> {
        let moves = std::mem::take(&mut self.moves);
        for (k, (staged, path)) in moves.iter().enumerate() {
            if let Err(e) = std::fs::rename(staged, path) {
                for (rest, _) in &moves[k..] {
                    let _ = std::fs::remove_file(rest);
                }
                return Err(Error::io(path, e));
            }
        }
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        for (staged, _) in &self.moves {
            let _ = std::fs::remove_file(staged);
        }
    }
}

/// A temporary name beside `path`: `.NAME` then `suffix` (e.g. `.part-PID`), or, where
/// that would pass the 255-byte limit of a file name, NAME's start and a checksum of the
/// whole name (so a legal 254-byte name still gets a legal temporary one).
pub(crate) fn temp_sibling(path: &Path, suffix: &str) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let short = format!(".{name}{suffix}");
    if short.len() <= 255 {
        return path.with_file_name(short);
    }
    let tag = format!("~{:08x}", crc32fast::hash(name.as_bytes()));
    let mut keep = 254usize
        .saturating_sub(tag.len() + suffix.len())
        .min(name.len());
    while !name.is_char_boundary(keep) {
        keep -= 1;
    }
    path.with_file_name(format!(".{}{tag}{suffix}", &name[..keep]))
}

/// Drops a trailing alpha channel: 2 → 1 and 4 → 3 channels.
fn drop_alpha(data: Vec<f32>, channels: usize) -> (Vec<f32>, usize) {
    if channels == 2 || channels == 4 {
        let keep = channels - 1;
        let out = data
            .chunks_exact(channels)
            .flat_map(|px| px[..keep].to_vec())
            .collect();
        (out, keep)
    } else {
        (data, channels)
    }
}

/// Parses "WxH" or "WxHxC" (also with '×').
pub fn parse_shape(text: &str) -> Result<(usize, usize, usize)> {
    let bad = || {
        Error::param(
            "raw-shape",
            text,
            "WxH or WxHxC with positive integers, e.g. 512x512",
        )
    };
    let parts: Vec<usize> = text
        .split(['x', 'X', '×'])
        .map(|p| p.trim().parse::<usize>().map_err(|_| bad()))
        .collect::<Result<_>>()?;
    match parts[..] {
        [w, h] if w > 0 && h > 0 => Ok((w, h, 1)),
        [w, h, c] if w > 0 && h > 0 && (1..=4).contains(&c) => Ok((w, h, c)),
        _ => Err(bad()),
    }
}
