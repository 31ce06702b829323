//! Bruker/Veeco/Digital Instruments Nanoscope files (`.spm`, `.001`…): a Latin-1 text
//! header of `\*Section` and `\Key: value` lines (its size is the first section's `Data
//! length`), then each image's little-endian i16 or i32 samples at its `Data offset`,
//! scan lines from the bottom up. The first image whose `@2:Image Data` is `Height` or
//! `ZSensor` is read (the height channel). Height = raw · Zh · S / 2^(8·bytes per
//! pixel), where `@2:Z scale` gives the soft scale's name and the hard value Zh (V), and
//! the scanner list gives the sensitivity S of that name (nm/V). The spacing comes from
//! `Scan Size` over the samples per line and the number of lines.

use super::ImageFile;
use super::bytes::Bytes;
use crate::error::Result;
use crate::raster::Raster;

/// Largest header read (the text is tens of kilobytes).
const MAX_HEADER: usize = 1 << 22;

/// One `\*Section` of the header: its name and its (key, value) lines.
struct Section<'a> {
    name: &'a str,
    keys: Vec<(&'a str, &'a str)>,
}

impl<'a> Section<'a> {
    fn get(&self, key: &str) -> Option<&'a str> {
        self.keys
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(key))
            .map(|(_, v)| *v)
    }
}

/// The header's sections, from the text before `\*File list end`.
fn sections(text: &str) -> Vec<Section<'_>> {
    let mut out: Vec<Section> = Vec::new();
    for line in text.split(['\r', '\n']) {
        let Some(rest) = line.strip_prefix('\\') else {
            continue;
        };
        if let Some(name) = rest.strip_prefix('*') {
            if name.eq_ignore_ascii_case("File list end") {
                break;
            }
            out.push(Section {
                name: name.trim(),
                keys: Vec::new(),
            });
        } else if let (Some(s), Some((k, v))) = (out.last_mut(), rest.split_once(": ")) {
            s.keys.push((k.trim(), v.trim()));
        } else if let (Some(s), Some(k)) = (out.last_mut(), rest.strip_suffix(':')) {
            s.keys.push((k.trim(), ""));
        }
    }
    out
}

/// A length unit's size in µm (`~m` is µm).
fn unit_um(unit: &str) -> Option<(f64, super::Unit)> {
    use super::Unit;
    Some(match unit {
        "m" => (1e6, Unit::M),
        "mm" => (1e3, Unit::Mm),
        "~m" | "um" | "µm" => (1.0, Unit::Um),
        "nm" => (1e-3, Unit::Nm),
        "pm" => (1e-6, Unit::Pm),
        "Å" | "A" => (1e-4, Unit::Angstrom),
        _ => return None,
    })
}

/// Volts in one of `unit` (`V`, `mV`, `~V` or `uV`, `nV`).
fn volts(unit: &str) -> Option<f64> {
    Some(match unit {
        "V" => 1.0,
        "mV" => 1e-3,
        "~V" | "uV" | "µV" => 1e-6,
        "nV" => 1e-9,
        _ => return None,
    })
}

/// The text inside the first `[...]` of `value`, and the number before the last
/// whitespace-separated unit: `V [Sens. Zsens] (0.0050354 V/LSB) 329.9950 V` gives
/// ("Sens. Zsens", 329.995, "V").
fn soft_scale(value: &str) -> Option<(String, f64, String)> {
    let open = value.find('[')?;
    let close = open + value[open..].find(']')?;
    let name = value[open + 1..close].trim().to_string();
    let mut words = value[close + 1..].split_whitespace().rev();
    let unit = words.next()?.to_string();
    let hard: f64 = words.next()?.parse().ok()?;
    Some((name, hard, unit))
}

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let b = Bytes::new(bytes, what);
    if bytes.starts_with(b"?*File list") {
        return Err(b.bad(
            "it is a Nanoscope file with ASCII data ('?*File list'); only binary data is read",
        ));
    }
    if bytes.starts_with(b"\\*Force file list") {
        return Err(b.bad("it is a Nanoscope force-curve file, not an image"));
    }
    let start = if bytes.starts_with(b"\\*File list") {
        11
    } else if bytes.starts_with(b"\\*EC File list") {
        14
    } else {
        return Err(b.bad("not a Nanoscope file (it does not start with '\\*File list')"));
    };
    if bytes.get(start) == Some(&b'\n') {
        return Err(
            b.bad("its line endings are damaged (LF for CR LF): the file was transferred as text")
        );
    }
    let probe = &bytes[..bytes.len().min(MAX_HEADER)];
    let head = String::from_utf8_lossy(&probe[..probe.len().min(8192)]);
    let first = sections(&head);
    let header = first
        .first()
        .and_then(|s| s.get("Data length"))
        .and_then(|v| v.parse::<usize>().ok())
        .ok_or_else(|| b.bad("its Nanoscope file list gives no Data length (the header's size)"))?;
    if header > MAX_HEADER {
        return Err(b.bad(format!(
            "its Nanoscope header claims {header} bytes; at most {MAX_HEADER} are read"
        )));
    }
    let text = b.slice("header", 0, header)?;
    // The text ends at the first NUL or ^Z; the rest of the header is padding.
    let end = text
        .iter()
        .position(|&c| c == 0 || c == 0x1a)
        .unwrap_or(text.len());
    let text: String = text[..end].iter().map(|&c| c as char).collect();
    let all = sections(&text);
    let scanner = |key: &str| {
        all.iter()
            .filter(|s| {
                s.name.eq_ignore_ascii_case("scanner list")
                    || s.name.eq_ignore_ascii_case("microscope list")
            })
            .chain(
                all.iter()
                    .filter(|s| s.name.to_ascii_lowercase().ends_with("scan list")),
            )
            .find_map(|s| s.get(key))
    };
    let images: Vec<&Section> = all
        .iter()
        .filter(|s| s.name.to_ascii_lowercase().ends_with("image list"))
        .collect();
    if images.is_empty() {
        return Err(b.bad("its Nanoscope header lists no image"));
    }
    let channel = |s: &Section| {
        s.get("@2:Image Data")
            .and_then(|v| {
                let open = v.find('[')?;
                let close = open + v[open..].find(']')?;
                Some(v[open + 1..close].to_string())
            })
            .unwrap_or_default()
    };
    let image = images
        .iter()
        .find(|s| matches!(channel(s).as_str(), "Height" | "ZSensor"))
        .ok_or_else(|| {
            let names: Vec<String> = images.iter().map(|s| channel(s)).collect();
            b.bad(format!(
                "its Nanoscope file has no Height or ZSensor image (it holds {})",
                names.join(", ")
            ))
        })?;
    let int = |key: &str| -> Result<usize> {
        let v = image
            .get(key)
            .ok_or_else(|| b.bad(format!("its Nanoscope image has no {key}")))?;
        v.parse().map_err(|_| {
            b.bad(format!(
                "its Nanoscope {key} is '{v}'; expected a whole number"
            ))
        })
    };
    let (nx, ny) = (int("Samps/line")?, int("Number of lines")?);
    let offset = int("Data offset")?;
    let length = int("Data length")?;
    let bpp = match image.get("Bytes/pixel") {
        Some(_) => int("Bytes/pixel")?,
        None => 2,
    };
    if bpp != 2 && bpp != 4 {
        return Err(b.bad(format!(
            "its Nanoscope Bytes/pixel is {bpp}; expected 2 or 4"
        )));
    }
    let n = super::check_shape(what, nx, ny, 1)?;
    // Nanoscope 9.2 and later store 32-bit samples whatever Bytes/pixel says; the data
    // length tells which.
    let elem = if length == 4 * n {
        4
    } else if length == 2 * n {
        2
    } else if length >= bpp * n {
        bpp
    } else {
        return Err(b.bad(format!(
            "its Nanoscope image's Data length {length} is smaller than {nx}×{ny} samples of {bpp} bytes"
        )));
    };
    let z = image.get("@2:Z scale").ok_or_else(|| {
        b.bad("its Nanoscope image has no @2:Z scale (a header older than version 4.3)")
    })?;
    let (soft, hard, hard_unit) = soft_scale(z).ok_or_else(|| {
        b.bad(format!(
            "its Nanoscope @2:Z scale is '{z}'; expected 'V [name] (…) value unit'"
        ))
    })?;
    let sens = scanner(&format!("@{soft}")).ok_or_else(|| {
        b.bad(format!(
            "its Nanoscope header gives no sensitivity '@{soft}'"
        ))
    })?;
    let mut words = sens.split_whitespace().skip(1);
    let s: f64 = words.next().and_then(|v| v.parse().ok()).ok_or_else(|| {
        b.bad(format!(
            "its Nanoscope sensitivity @{soft} is '{sens}'; expected 'V number unit/V'"
        ))
    })?;
    let unit = words.next().unwrap_or("");
    let (z_unit, per) = unit.split_once('/').unwrap_or((unit, ""));
    let (z_um, file_unit) = unit_um(z_unit).ok_or_else(|| {
        b.bad(format!(
            "its Nanoscope channel's unit is '{unit}', not a length: not a height channel"
        ))
    })?;
    // The Z scale's hard value and the sensitivity's denominator are volts, each with
    // an SI prefix of its own.
    let (hv, pv) = (volts(&hard_unit), volts(per));
    let (Some(hv), Some(pv)) = (hv, pv) else {
        return Err(b.bad(format!(
            "its Nanoscope Z scale is in '{hard_unit}' and its sensitivity per '{per}'; expected volts (V, mV, ~V, nV)"
        )));
    };
    if !(hard.is_finite() && s.is_finite() && hard != 0.0 && s != 0.0) {
        return Err(b.bad(format!(
            "its Nanoscope Z scale {hard} or sensitivity {s} is not a finite, non-zero number"
        )));
    }
    let hard = hard * hv / pv;
    let scan = image
        .get("Scan Size")
        .or_else(|| scanner("Scan Size"))
        .ok_or_else(|| b.bad("its Nanoscope image has no Scan Size"))?;
    let parts: Vec<&str> = scan.split_whitespace().collect();
    let (sx, sy, lateral) = match parts[..] {
        [x, y, u] => (x.parse::<f64>().ok(), y.parse::<f64>().ok(), u),
        [x, u] => (x.parse::<f64>().ok(), x.parse::<f64>().ok(), u),
        _ => (None, None, ""),
    };
    let (lx, _) = unit_um(lateral).ok_or_else(|| {
        b.bad(format!(
            "its Nanoscope Scan Size is '{scan}'; expected 'x y unit'"
        ))
    })?;
    let (sx, sy) = match (sx, sy) {
        (Some(x), Some(y)) if x > 0.0 && y > 0.0 && x.is_finite() && y.is_finite() => (x, y),
        _ => {
            return Err(b.bad(format!(
                "its Nanoscope Scan Size is '{scan}'; expected positive sizes"
            )));
        }
    };
    let data = b.grid(offset, (nx, ny), elem, None)?;
    let k = hard * s / 2f64.powi(8 * bpp as i32) * z_um;
    let mut heights = vec![0.0f32; n];
    for (i, c) in data.chunks_exact(elem).enumerate() {
        let raw = if elem == 2 {
            i16::from_le_bytes([c[0], c[1]]) as f64
        } else {
            i32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64
        };
        let (line, x) = (i / nx, i % nx);
        heights[(ny - 1 - line) * nx + x] = (raw * k) as f32;
    }
    let mut out = ImageFile::new(
        Raster::from_vec(nx, ny, 1, heights)?,
        Some(sx * lx / nx as f64),
    );
    out.spacing_y_um = Some(sy * lx / ny as f64);
    out.unit = Some(file_unit);
    Ok(out)
}
