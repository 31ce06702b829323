//! Checked reads from an instrument file's bytes: every field and every data block is
//! checked against the file's length before it is read or anything of its size is
//! allocated, so a truncated or lying file gets a one-line error naming the file, the
//! field and the sizes.

use crate::error::{Error, Result};

/// A file's bytes and its name for errors.
#[derive(Clone, Copy)]
pub(super) struct Bytes<'a> {
    pub bytes: &'a [u8],
    pub what: &'a str,
}

/// Byte order of a field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Order {
    Little,
    Big,
}

impl<'a> Bytes<'a> {
    pub fn new(bytes: &'a [u8], what: &'a str) -> Bytes<'a> {
        Bytes { bytes, what }
    }

    /// A decode error naming the file, on one line: control characters a message
    /// quotes from the file (a damaged name or value) become '?'.
    pub fn bad(&self, message: impl Into<String>) -> Error {
        let message: String = message
            .into()
            .chars()
            .map(|c| if c.is_control() { '?' } else { c })
            .collect();
        Error::decode(self.what, message)
    }

    /// The `len` bytes of `field` at `offset`, or an error saying the file is too short.
    pub fn slice(&self, field: &str, offset: usize, len: usize) -> Result<&'a [u8]> {
        match offset.checked_add(len) {
            Some(end) if end <= self.bytes.len() => Ok(&self.bytes[offset..end]),
            _ => Err(self.bad(format!(
                "truncated: its {field} needs {len} bytes at offset {offset}, the file holds {}",
                self.bytes.len()
            ))),
        }
    }

    fn array<const N: usize>(&self, field: &str, offset: usize) -> Result<[u8; N]> {
        let s = self.slice(field, offset, N)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }

    pub fn u16(&self, field: &str, offset: usize, order: Order) -> Result<u16> {
        let a = self.array::<2>(field, offset)?;
        Ok(match order {
            Order::Little => u16::from_le_bytes(a),
            Order::Big => u16::from_be_bytes(a),
        })
    }

    pub fn i16(&self, field: &str, offset: usize, order: Order) -> Result<i16> {
        Ok(self.u16(field, offset, order)? as i16)
    }

    pub fn u32(&self, field: &str, offset: usize, order: Order) -> Result<u32> {
        let a = self.array::<4>(field, offset)?;
        Ok(match order {
            Order::Little => u32::from_le_bytes(a),
            Order::Big => u32::from_be_bytes(a),
        })
    }

    pub fn i32(&self, field: &str, offset: usize, order: Order) -> Result<i32> {
        Ok(self.u32(field, offset, order)? as i32)
    }

    pub fn f32(&self, field: &str, offset: usize, order: Order) -> Result<f32> {
        Ok(f32::from_bits(self.u32(field, offset, order)?))
    }

    pub fn f64(&self, field: &str, offset: usize, order: Order) -> Result<f64> {
        let a = self.array::<8>(field, offset)?;
        Ok(match order {
            Order::Little => f64::from_le_bytes(a),
            Order::Big => f64::from_be_bytes(a),
        })
    }

    /// A fixed-size text field: bytes up to the first NUL, trimmed, lossily decoded.
    pub fn text(&self, field: &str, offset: usize, len: usize) -> Result<String> {
        let s = self.slice(field, offset, len)?;
        let end = s.iter().position(|&b| b == 0).unwrap_or(s.len());
        Ok(String::from_utf8_lossy(&s[..end]).trim().to_string())
    }

    /// The data block of a `w × h` grid of `elem`-byte samples at `offset`: the grid is
    /// checked against [`super::MAX_IMAGE_PIXELS`] and the block against the file's
    /// length before anything is allocated.
    pub fn grid(
        &self,
        offset: usize,
        (w, h): (usize, usize),
        elem: usize,
        row_stride: Option<usize>,
    ) -> Result<&'a [u8]> {
        super::check_shape(self.what, w, h, 1)?;
        let stride = row_stride.unwrap_or(w);
        let len = stride
            .checked_mul(h)
            .and_then(|v| v.checked_mul(elem))
            .filter(|_| stride >= w)
            .ok_or_else(|| self.bad(format!("a {w}×{h} grid of row length {stride}")))?;
        match offset.checked_add(len) {
            Some(end) if end <= self.bytes.len() => Ok(&self.bytes[offset..end]),
            _ => Err(self.bad(format!(
                "truncated: its {w}×{h} grid of {elem}-byte samples needs {len} bytes at offset {offset}, the file holds {}",
                self.bytes.len()
            ))),
        }
    }
}

/// `value` checked positive and finite (`field` names it in the error).
pub(super) fn positive(b: &Bytes, field: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(b.bad(format!(
            "its {field} is {value}; expected a positive, finite number"
        )))
    }
}
