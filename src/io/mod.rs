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

mod al3d;
mod bytes;
mod di;
mod exr;
mod jpeg;
mod metropro;
mod npy;
mod opd;
mod plu;
mod png;
mod raw;
mod sdf;
mod sur;
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
    /// The samples; heights in µm whatever unit the file stored them in.
    pub raster: Raster,
    /// Pixel spacing along x (columns) in µm per pixel, when the file records it.
    pub spacing_um: Option<f64>,
    /// Pixel spacing along y (rows) in µm, where the file gives one that differs from
    /// x's (`None`: square pixels).
    pub spacing_y_um: Option<f64>,
    /// The unit the file stored its heights in, where it says (the raster holds µm).
    pub unit: Option<Unit>,
}

impl ImageFile {
    /// An image of square pixels `spacing_um` apart (where known) and no stated unit.
    pub fn new(raster: Raster, spacing_um: Option<f64>) -> ImageFile {
        ImageFile {
            raster,
            spacing_um,
            spacing_y_um: None,
            unit: None,
        }
    }

    /// The y spacing in µm: [`ImageFile::spacing_y_um`], or x's for square pixels.
    pub fn spacing_y(&self) -> Option<f64> {
        self.spacing_y_um.or(self.spacing_um)
    }

    /// Whether the pixels are not square (y and x spacings differ by more than 1e-9
    /// relative).
    pub fn non_square(&self) -> bool {
        match (self.spacing_um, self.spacing_y_um) {
            (Some(x), Some(y)) => (x - y).abs() > 1e-9 * x.abs().max(y.abs()),
            _ => false,
        }
    }
}

/// A unit of length for heights (and spacings) in files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unit {
    /// Metres.
    M,
    /// Millimetres.
    Mm,
    /// Micrometres.
    Um,
    /// Nanometres.
    Nm,
    /// Ångströms.
    Angstrom,
    /// Picometres.
    Pm,
}

impl Unit {
    /// Micrometres in one of this unit.
    pub fn in_um(self) -> f64 {
        match self {
            Unit::M => 1e6,
            Unit::Mm => 1e3,
            Unit::Um => 1.0,
            Unit::Nm => 1e-3,
            Unit::Angstrom => 1e-4,
            Unit::Pm => 1e-6,
        }
    }

    /// The unit's symbol: `m`, `mm`, `µm` or `nm`.
    pub fn symbol(self) -> &'static str {
        match self {
            Unit::M => "m",
            Unit::Mm => "mm",
            Unit::Um => "µm",
            Unit::Nm => "nm",
            Unit::Angstrom => "Å",
            Unit::Pm => "pm",
        }
    }

    /// The unit's ASCII name, as metadata stores it: `m`, `mm`, `um`, `nm`, `A`, `pm`.
    pub fn ascii(self) -> &'static str {
        match self {
            Unit::M => "m",
            Unit::Mm => "mm",
            Unit::Um => "um",
            Unit::Nm => "nm",
            Unit::Angstrom => "A",
            Unit::Pm => "pm",
        }
    }

    /// The unit a symbol names: `m`, `mm`, `um`/`µm`/`μm`, `nm`, `A`/`Å` or `pm`.
    pub fn parse(text: &str) -> Option<Unit> {
        if matches!(text.trim(), "Å" | "A" | "angstrom") {
            return Some(Unit::Angstrom);
        }
        match text.trim().to_lowercase().as_str() {
            "m" => Some(Unit::M),
            "mm" => Some(Unit::Mm),
            "um" | "µm" | "μm" | "micron" | "microns" => Some(Unit::Um),
            "nm" => Some(Unit::Nm),
            "pm" => Some(Unit::Pm),
            _ => None,
        }
    }
}

impl std::fmt::Display for Unit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.symbol())
    }
}

impl std::str::FromStr for Unit {
    type Err = String;
    fn from_str(text: &str) -> std::result::Result<Unit, String> {
        Unit::parse(text)
            .ok_or_else(|| format!("'{text}' is not a unit; expected um, nm, mm, m, A or pm"))
    }
}

/// What a height file records beside its samples when written: spacings and the unit
/// the samples are in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WriteMeta {
    /// Spacing along x in µm.
    pub spacing_um: Option<f64>,
    /// Spacing along y in µm, where it differs from x's.
    pub spacing_y_um: Option<f64>,
    /// The unit the raster's heights are in (X3P converts them to metres; PNG and TIFF
    /// record it).
    pub unit: Unit,
    /// A photo's full scale ([`photo_full_scale`]): a 16-bit PNG, grey or colour, maps
    /// [0, full] to its levels where every sample lies in it (within
    /// [`COLOUR_OVERSHOOT`], clamped), and is min–max scaled otherwise; None: heights
    /// min–max scaled, colour by [`colour_full_scale`].
    pub levels: Option<f32>,
}

impl WriteMeta {
    /// Square pixels `spacing_um` apart, heights in µm.
    pub fn um(spacing_um: Option<f64>) -> WriteMeta {
        WriteMeta {
            spacing_um,
            spacing_y_um: None,
            unit: Unit::Um,
            levels: None,
        }
    }
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
    /// Pixel spacing in µm per pixel (along x).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spacing_um: Option<f64>,
    /// Pixel spacing along y in µm, where it differs from x's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spacing_y_um: Option<f64>,
    /// The unit of the heights (`m`, `mm`, `µm`, `nm`); µm where absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height_unit: Option<String>,
}

impl HeightMeta {
    /// The metadata a writer stores for `meta`.
    fn of(meta: &WriteMeta) -> HeightMeta {
        HeightMeta {
            spacing_um: meta.spacing_um,
            spacing_y_um: meta.spacing_y_um,
            height_unit: (meta.unit != Unit::Um).then(|| meta.unit.ascii().to_string()),
            ..HeightMeta::default()
        }
    }

    /// Applies what a PNG or TIFF file's metadata says to its decoded image: the
    /// spacings, and heights back to µm from a recorded unit (`what` names the file).
    fn apply(&self, image: &mut ImageFile, what: &str) -> Result<()> {
        image.spacing_um = self.spacing_um;
        image.spacing_y_um = self.spacing_y_um;
        if let Some(symbol) = &self.height_unit {
            let unit = Unit::parse(symbol).ok_or_else(|| {
                Error::decode(
                    what,
                    format!(
                        "its metadata names the height unit '{symbol}'; expected m, mm, µm or nm"
                    ),
                )
            })?;
            let k = unit.in_um() as f32;
            for v in &mut image.raster.data {
                *v *= k;
            }
            image.unit = Some(unit);
        }
        Ok(())
    }
}

/// Image formats, chosen by content where the file's first bytes name one, else by
/// extension.
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
    /// `.al3d`: Alicona AL3D
    Al3d,
    /// `.plu`: Sensofar PLU
    Plu,
    /// `.sur`: Digital Surf SUR
    Sur,
    /// `.opd`: Wyko/Veeco OPD
    Opd,
    /// `.di` or a Nanoscope number extension (`.001`…): Bruker/Veeco Nanoscope
    Di,
    /// `.dat`: Zygo MetroPro
    MetroPro,
    /// `.sdf`: ISO 25178-71 surface data file (ASCII)
    Sdf,
    /// `.exr`: OpenEXR, 32-bit float
    Exr,
    /// `.jpg`, `.jpeg`: a photo (read only), as 8-bit levels
    Jpeg,
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
            "al3d" => Ok(Format::Al3d),
            "plu" | "apx" => Ok(Format::Plu),
            "sur" => Ok(Format::Sur),
            "opd" => Ok(Format::Opd),
            "di" | "spm" => Ok(Format::Di),
            e if e.len() == 3 && e.bytes().all(|b| b.is_ascii_digit()) => Ok(Format::Di),
            "dat" => Ok(Format::MetroPro),
            "sdf" => Ok(Format::Sdf),
            "exr" => Ok(Format::Exr),
            "jpg" | "jpeg" => Ok(Format::Jpeg),
            _ => Err(Error::Unsupported(format!(
                "{}: unknown image extension '{ext}'; expected .png, .jpg, .tif/.tiff, .npy, .x3p, \
                 .exr, .raw/.f32, or an instrument file (.al3d, .plu, .sur, .opd, .di, .dat, .sdf)",
                path.display()
            ))),
        }
    }

    /// The format a file's first bytes name, where they name one (PNG, JPEG, TIFF, NumPy,
    /// zip = X3P, and the instrument formats' signatures).
    pub fn sniff(bytes: &[u8]) -> Option<Format> {
        let starts = |magic: &[u8]| bytes.starts_with(magic);
        if starts(b"\x89PNG\r\n\x1a\n") {
            Some(Format::Png)
        } else if starts(b"II*\0") || starts(b"MM\0*") || starts(b"II+\0") || starts(b"MM\0+") {
            Some(Format::Tiff)
        } else if starts(b"\x93NUMPY") {
            Some(Format::Npy)
        } else if starts(b"PK\x03\x04") {
            Some(Format::X3p)
        } else if starts(b"\x76\x2f\x31\x01") {
            Some(Format::Exr)
        } else if starts(b"\xff\xd8\xff") {
            Some(Format::Jpeg)
        } else if starts(b"AliconaImaging") {
            Some(Format::Al3d)
        } else if starts(b"DIGITAL SURF") || starts(b"DSCOMPRESSED") {
            Some(Format::Sur)
        } else if starts(b"\\*File list")
            || starts(b"\\*EC File list")
            || starts(b"?*File list")
            || starts(b"\\*Force file list")
        {
            Some(Format::Di)
        } else if starts(b"aISO-1.0") || starts(b"bISO-1.0") {
            Some(Format::Sdf)
        } else if metropro::sniff(bytes) {
            Some(Format::MetroPro)
        } else if opd::sniff(bytes) {
            Some(Format::Opd)
        } else if plu::sniff(bytes) {
            Some(Format::Plu)
        } else {
            None
        }
    }

    /// Whether the format can hold missing points (NaN) when written.
    fn holds_missing(self) -> bool {
        matches!(
            self,
            Format::Npy | Format::Tiff | Format::X3p | Format::Raw | Format::Exr
        )
    }
}

/// Largest file any reader takes (4 GiB): a path naming something larger is refused
/// before it is read.
pub const MAX_FILE_BYTES: u64 = 1 << 32;

/// Reads an image file, choosing the decoder by content where the first bytes name a
/// format, else by extension.
pub fn read_image(path: &Path, options: &ReadOptions) -> Result<ImageFile> {
    let by_name = Format::from_path(path);
    let len = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len();
    if len > MAX_FILE_BYTES {
        return Err(Error::Limits(format!(
            "{}: {len} bytes; readers take files of at most {MAX_FILE_BYTES} bytes (4 GiB)",
            path.display()
        )));
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let format = match (Format::sniff(&bytes), by_name) {
        (Some(f), _) => f,
        (None, Ok(f)) => f,
        (None, Err(e)) => return Err(e),
    };
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
        Format::Al3d => al3d::read(bytes, what)?,
        Format::Plu => plu::read(bytes, what)?,
        Format::Sur => sur::read(bytes, what)?,
        Format::Opd => opd::read(bytes, what)?,
        Format::Di => di::read(bytes, what)?,
        Format::MetroPro => metropro::read(bytes, what)?,
        Format::Sdf => sdf::read(bytes, what)?,
        Format::Exr => exr::read(bytes, what)?,
        Format::Jpeg => jpeg::read(bytes, what)?,
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
    let mut image = image;
    if !image.non_square() {
        image.spacing_y_um = None;
    }
    // An instrument's scale can carry a raw value past f32's range: such a point is not
    // a height, so it is missing, as the formats' own invalid markers are.
    if !matches!(
        format,
        Format::Png | Format::Tiff | Format::Npy | Format::Raw | Format::Exr | Format::Jpeg
    ) {
        for v in &mut image.raster.data {
            if v.is_infinite() {
                *v = f32::NAN;
            }
        }
    }
    for (name, s) in [("x", image.spacing_um), ("y", image.spacing_y_um)] {
        if let Some(s) = s
            && !(s.is_finite() && s > 0.0)
        {
            return Err(Error::decode(
                what,
                format!("its {name} spacing is {s} µm; expected a positive, finite length"),
            ));
        }
    }
    Ok(image)
}

/// The full scale of a colour raster's levels: 1 (unit colour, as float images hold
/// it), 255 (an 8-bit photo's levels, as the PNG reader gives them) or 65535 (16-bit),
/// the smallest that holds every sample of [lo, hi] to within [`COLOUR_OVERSHOOT`]
/// ([`holds_levels`]); none for heights (not three channels) or colour outside
/// [0, 65535] by more than that. A 16-bit PNG maps [0, full] to its levels (the
/// overshoot clamped), and the viewer shows [0, full] as black to full intensity, so a
/// synthesis of a photo shows the photo's colours.
pub fn colour_full_scale(channels: usize, lo: f32, hi: f32) -> Option<f32> {
    if channels != 3 {
        return None;
    }
    [1.0f32, 255.0, 65535.0]
        .into_iter()
        .find(|&full| holds_levels(lo, hi, full))
}

/// Whether samples in [lo, hi] are levels of full scale `full`: within [0, full] but
/// for [`COLOUR_OVERSHOOT`] of it either side (false for NaN).
pub fn holds_levels(lo: f32, hi: f32, full: f32) -> bool {
    let (lo, hi, full) = (lo as f64, hi as f64, full as f64);
    let tolerance = COLOUR_OVERSHOOT as f64 * full;
    lo >= -tolerance && hi <= full + tolerance
}

/// Whether an exemplar as read (before preprocessing) is a photo rather than a height
/// map: colour (three or more channels), or grey levels as an 8-bit file holds them
/// (every sample an integer in 0–255). Height maps come as floats (instrument files,
/// X3P, npy, TIFF) or as 16-bit PNG; an 8-bit height map counts as a photo.
pub fn is_photo(raw: &Raster) -> bool {
    raw.channels >= 3
        || raw
            .data
            .iter()
            .all(|&v| (0.0..=255.0).contains(&v) && v.fract() == 0.0)
}

/// The full scale of a photo's levels as read (`raw`, before any preprocessing): 255
/// for grey in 8-bit levels, [`colour_full_scale`] of its range for colour; None for
/// anything else (heights). Banks record it ([`crate::bank::ExemplarInfo::levels`]), so
/// that a render of a grey photo's synthesis keeps the photo's levels as colour does
/// ([`WriteMeta::levels`]) instead of stretching its range to black and white.
pub fn photo_full_scale(raw: &Raster) -> Option<f32> {
    if !is_photo(raw) {
        return None;
    }
    match raw.channels {
        1 => Some(255.0),
        3 => {
            let (lo, hi) = raw
                .data
                .iter()
                .fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
            colour_full_scale(3, lo, hi)
        }
        _ => None,
    }
}

/// Relative overshoot of a photo's full scale that [`holds_levels`] tolerates, either
/// side. Blending two 255s in f32 can give 255.00002, and a synthesis may leave its
/// exemplar's range by a little: the gradient-domain healing of a roller's tiles
/// (`analysis::heal`) reads 121–259 on GIMP's 8-bit `rain` pattern. Such a
/// render keeps the photo's scale, the overshoot clamped; with the old bound of 1e-4
/// it was taken for 16-bit colour and written black.
pub const COLOUR_OVERSHOOT: f32 = 0.05;

/// Writes heights (or colours) to `path` in the format its extension names: 16-bit PNG,
/// 32-bit float TIFF, float32 `.npy` or X3P, with square pixels `spacing_um` apart and
/// heights in µm. Non-finite samples are refused.
pub fn write_heights(path: &Path, raster: &Raster, spacing_um: Option<f64>) -> Result<()> {
    write_finite(path, raster, &WriteMeta::um(spacing_um))
}

/// [`write_heights_with`] for samples that must all be finite (a synthesis): a NaN or
/// infinite sample is refused before anything is written.
pub fn write_finite(path: &Path, raster: &Raster, meta: &WriteMeta) -> Result<()> {
    if raster.data.iter().any(|v| !v.is_finite()) {
        return Err(Error::param(
            "output samples",
            "non-finite",
            "finite heights (NaN or infinite values cannot be written)",
        ));
    }
    write_heights_with(path, raster, meta)
}

/// Writes heights to `path` in the format its extension names, with `meta`'s spacings
/// and unit: 16-bit PNG, 32-bit float TIFF, float32 `.npy`, raw f32 or X3P. Missing
/// points (NaN) are kept where the format holds them (TIFF, `.npy`, raw, X3P) and refused
/// for PNG; infinite samples are always refused.
pub fn write_heights_with(path: &Path, raster: &Raster, meta: &WriteMeta) -> Result<()> {
    let format = Format::from_path(path)?;
    if !matches!(
        format,
        Format::Png | Format::Tiff | Format::Npy | Format::Raw | Format::X3p | Format::Exr
    ) {
        return Err(Error::Unsupported(format!(
            "{}: surftile reads {format:?} files but does not write them; write .x3p, .npy, .tif or .png",
            path.display()
        )));
    }
    if raster.data.iter().any(|v| v.is_infinite()) {
        return Err(Error::param(
            "output samples",
            "infinite",
            "finite heights (infinite values cannot be written)",
        ));
    }
    if !format.holds_missing() && raster.data.iter().any(|v| v.is_nan()) {
        return Err(Error::param(
            "output samples",
            format!("{} missing points (NaN)", raster.count_nan()),
            "a format that holds missing points (.x3p, .npy, .tif), or --fill-missing",
        ));
    }
    write_atomically(path, |w| match format {
        Format::Png => png::write16(w, raster, meta),
        Format::Tiff => tiff::write(w, raster, meta),
        Format::Npy => npy::write(w, raster),
        Format::Exr => exr::write(w, raster, meta),
        Format::X3p => {
            // The generating command, as the X3P record's comment.
            let command: Vec<String> = std::env::args().collect();
            x3p::write(w, raster, meta, &command.join(" "))
        }
        Format::Raw => {
            for v in &raster.data {
                std::io::Write::write_all(w, &v.to_le_bytes()).map_err(|e| Error::io(path, e))?;
            }
            Ok(())
        }
        _ => Err(Error::Unsupported(format!("writing {format:?} files"))),
    })
}

/// Writes a normal map (three channels of unit-vector components) to `path`: a 16-bit
/// RGB PNG with each component v as round((v + 1)/2 · 65535), or a float RGB `.exr`
/// with the components as they are.
pub fn write_normals(path: &Path, normals: &Raster) -> Result<()> {
    match Format::from_path(path)? {
        Format::Png => write_atomically(path, |w| png::write_signed_unit16(w, normals)),
        Format::Exr => write_atomically(path, |w| exr::write(w, normals, &WriteMeta::um(None))),
        other => Err(Error::Unsupported(format!(
            "{}: a normal map as {other:?}; write .png (16-bit) or .exr (float)",
            path.display()
        ))),
    }
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

/// A 16-bit PNG of `raster` (1 or 3 channels) scaled from the range [lo, hi], which
/// must be finite, ordered and hold every sample: level = round((v − lo) / (hi − lo) ·
/// 65535), recorded in the file's `surftile` chunk, so that several files (the tiles of
/// a set) share one scale. Written atomically.
pub fn write_png16_range(
    path: &Path,
    raster: &Raster,
    meta: &WriteMeta,
    lo: f32,
    hi: f32,
) -> Result<()> {
    let inside = raster.data.iter().all(|v| (lo..=hi).contains(v));
    if !(lo.is_finite() && hi.is_finite() && lo <= hi && inside) {
        return Err(Error::param(
            "PNG range",
            format!("[{lo}, {hi}]"),
            "a finite range holding every sample",
        ));
    }
    write_atomically(path, |w| png::write16_in(w, raster, meta, lo, hi))
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
