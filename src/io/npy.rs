//! NumPy `.npy` reading (f32, f64, u8, u16, i16, i32; C or Fortran order; H×W or H×W×C) and
//! float32 writing, on the `npyz` crate.

use std::io::Write;

use npyz::{DType, NpyFile, Order, TypeChar, WriterBuilder};

use super::ImageFile;
use crate::error::{Error, Result};
use crate::raster::Raster;

/// Longest `.npy` header read: numpy's default `max_header_size`.
const MAX_HEADER_BYTES: usize = 10_000;

/// Deepest bracket nesting of an `.npy` header read: a plain array's is 2 (the dict and
/// its shape tuple); structured dtypes, which the reader refuses anyway, nest a little
/// deeper.
const MAX_HEADER_NESTING: usize = 6;

/// The deepest nesting of (), [] and {} in a Python literal, outside its string
/// literals (quoted with ' or ", backslash escapes skipped).
fn nesting_depth(text: &[u8]) -> usize {
    let (mut depth, mut deepest, mut quote, mut escaped) = (0usize, 0usize, None, false);
    for &b in text {
        match quote {
            Some(q) => {
                if escaped {
                    escaped = false;
                } else if b == b'\\' {
                    escaped = true;
                } else if b == q {
                    quote = None;
                }
            }
            None => match b {
                b'\'' | b'"' => quote = Some(b),
                b'(' | b'[' | b'{' => {
                    depth += 1;
                    deepest = deepest.max(depth);
                }
                b')' | b']' | b'}' => depth = depth.saturating_sub(1),
                _ => {}
            },
        }
    }
    deepest
}

/// Checks an `.npy` file's framing and declared shape before npyz reads it. npyz
/// allocates whatever header length the file states (up to 4 GiB for a 12-byte file) and
/// multiplies the dimensions unchecked (a product past 2⁶⁴ wraps in release builds and
/// panics in debug ones). The header text is parsed with `py_literal`, the parser npyz
/// itself uses; the product of the non-zero dimensions, which bounds every partial
/// product npyz forms, is then computed with checked arithmetic.
fn check_header(bytes: &[u8], what: &str) -> Result<()> {
    use py_literal::Value;
    let bad = |m: String| Err(Error::decode(what, m));
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return bad("not a .npy file (no \\x93NUMPY magic)".into());
    }
    let (text_at, len) = match bytes[6] {
        1 => (10usize, u16::from_le_bytes([bytes[8], bytes[9]]) as usize),
        2 | 3 if bytes.len() >= 12 => (
            12,
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
        ),
        v => return bad(format!(".npy format version {v}; expected 1, 2 or 3")),
    };
    let Some(text) = text_at
        .checked_add(len)
        .and_then(|end| bytes.get(text_at..end))
    else {
        return bad(format!(
            "the .npy header says {len} bytes, past the end of the {}-byte file",
            bytes.len()
        ));
    };
    let text = text.strip_suffix(b"\n").unwrap_or(text);
    // The parser backtracks exponentially on deep nesting (118 bytes of '{' ran past
    // 60 s, found by the npy fuzz target), and a plain array's header is a flat dict:
    // numpy itself refuses headers over 10,000 bytes unless told otherwise.
    if text.len() > MAX_HEADER_BYTES {
        return bad(format!(
            "the .npy header is {} bytes; expected at most {MAX_HEADER_BYTES} (numpy's own limit)",
            text.len()
        ));
    }
    let depth = nesting_depth(text);
    if depth > MAX_HEADER_NESTING {
        return bad(format!(
            "the .npy header nests {depth} brackets deep; expected a flat dict (at most {MAX_HEADER_NESTING})"
        ));
    }
    let header: Value = std::str::from_utf8(text)
        .ok()
        .and_then(|t| t.parse().ok())
        .ok_or_else(|| Error::decode(what, "the .npy header is not a Python literal"))?;
    let Value::Dict(items) = header else {
        return bad("the .npy header is not a dict".into());
    };
    let shape = items.iter().find_map(|(k, v)| match k {
        Value::String(k) if k == "shape" => Some(v),
        _ => None,
    });
    let Some(Value::Tuple(dims)) = shape else {
        return bad("the .npy header has no shape tuple".into());
    };
    // npyz multiplies the dimensions in both orders (its strides, C or Fortran), so a
    // zero among them does not save a product of the others that passes 2⁶⁴: the npy
    // fuzz target's (0, 8209644704054465877, 5) overflowed at 5 × 8.2·10¹⁸. Every
    // partial product is at most the product of the non-zero dimensions.
    let mut count = Some(1u64);
    for d in dims {
        let dim = match d {
            Value::Integer(i) => u64::try_from(i).ok(),
            _ => None,
        };
        count = count.zip(dim).and_then(|(n, d)| n.checked_mul(d.max(1)));
    }
    if count.is_none() {
        return bad(format!(
            "array shape {}: its non-zero dimensions multiply past 2⁶⁴; expected an element count below 2⁶⁴ (npyz multiplies them all)",
            Value::Tuple(dims.clone())
        ));
    }
    Ok(())
}

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let bad = |m: String| Error::decode(what, m);
    check_header(bytes, what)?;
    let npy = NpyFile::new(bytes).map_err(|e| bad(format!("not a valid .npy file ({e})")))?;
    let fortran = npy.order() == Order::Fortran;
    let shape: Vec<usize> = npy.shape().iter().map(|&d| d as usize).collect();
    let (h, w, c) = match shape[..] {
        [h, w] => (h, w, 1),
        [h, w, c] if (1..=4).contains(&c) => (h, w, c),
        _ => {
            return Err(bad(format!(
                "array shape {shape:?}; expected (rows, cols) or (rows, cols, channels ≤ 4)"
            )));
        }
    };
    let samples = super::check_shape(what, w, h, c)?;
    let DType::Plain(ts) = npy.dtype() else {
        return Err(bad(
            "structured dtype; expected a plain numeric array".into()
        ));
    };
    let read_err =
        |e: std::io::Error| Error::decode(what, format!("truncated or corrupt data ({e})"));
    let data: Vec<f32> = match (ts.type_char(), ts.size_field()) {
        (TypeChar::Float, 4) => npy.into_vec::<f32>().map_err(read_err)?,
        (TypeChar::Float, 8) => npy
            .into_vec::<f64>()
            .map_err(read_err)?
            .into_iter()
            .map(|v| v as f32)
            .collect(),
        (TypeChar::Uint, 1) => npy
            .into_vec::<u8>()
            .map_err(read_err)?
            .into_iter()
            .map(f32::from)
            .collect(),
        (TypeChar::Uint, 2) => npy
            .into_vec::<u16>()
            .map_err(read_err)?
            .into_iter()
            .map(f32::from)
            .collect(),
        (TypeChar::Int, 2) => npy
            .into_vec::<i16>()
            .map_err(read_err)?
            .into_iter()
            .map(f32::from)
            .collect(),
        (TypeChar::Int, 4) => npy
            .into_vec::<i32>()
            .map_err(read_err)?
            .into_iter()
            .map(|v| v as f32)
            .collect(),
        _ => {
            return Err(bad(format!(
                "dtype {ts}; expected float32/64, uint8/16 or int16/32"
            )));
        }
    };
    if data.len() != samples {
        return Err(bad("data length does not match the shape".into()));
    }
    // Fortran order: element (y, x, ch) sits at y + h·(x + w·ch).
    let data = if fortran {
        let mut out = vec![0.0f32; data.len()];
        for y in 0..h {
            for x in 0..w {
                for ch in 0..c {
                    out[(y * w + x) * c + ch] = data[y + h * (x + w * ch)];
                }
            }
        }
        out
    } else {
        data
    };
    let (data, c) = super::drop_alpha(data, c);
    Ok(ImageFile::new(
        Raster::from_vec(w, h, c, data)
            .map_err(|_| bad("data length does not match the shape".into()))?,
        None,
    ))
}

pub(super) fn write(w: &mut impl Write, raster: &Raster) -> Result<()> {
    let err = |e: std::io::Error| Error::decode("NPY output", e.to_string());
    let shape: Vec<u64> = if raster.channels == 1 {
        vec![raster.height as u64, raster.width as u64]
    } else {
        vec![
            raster.height as u64,
            raster.width as u64,
            raster.channels as u64,
        ]
    };
    // The header by npyz, the samples as one block of little-endian bytes (a call per
    // sample through npyz's typed writer took 1.5 ms per 512² sample).
    let dtype = DType::new_scalar(
        "<f4"
            .parse()
            .map_err(|e| Error::decode("NPY output", format!("{e}")))?,
    );
    npyz::WriteOptions::new_header_only()
        .dtype(dtype)
        .shape(&shape)
        .writer(&mut *w)
        .write_header_only()
        .map_err(err)?;
    let mut block = Vec::with_capacity(raster.data.len().min(1 << 16) * 4);
    for chunk in raster.data.chunks(1 << 16) {
        block.clear();
        block.extend(chunk.iter().flat_map(|v| v.to_le_bytes()));
        w.write_all(&block).map_err(err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::nesting_depth;

    #[test]
    fn nesting_is_counted_outside_strings() {
        let plain = b"{'descr': '<f4', 'fortran_order': False, 'shape': (3, 4), }";
        assert_eq!(nesting_depth(plain), 2);
        // Brackets and an escaped quote inside strings do not count.
        assert_eq!(
            nesting_depth(br"{'a': '((([{', 'b': 'it\'s ((', 'c': [(1,)]}"),
            3
        );
        assert_eq!(nesting_depth(b"{{{{{{{{"), 8);
        assert_eq!(nesting_depth(b"))){"), 1);
    }
}
