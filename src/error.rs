//! The one error type of the library.
//!
//! Variants say whose fault it was (as image-rs does): a broken or unreadable file
//! ([`Error::Io`], [`Error::Decode`], [`Error::BadBank`]), a parameter out of range
//! ([`Error::InvalidParameter`]), data the method cannot use ([`Error::MissingData`],
//! [`Error::TooSmall`]), a request over a size limit ([`Error::Limits`]) or a format
//! feature we do not read ([`Error::Unsupported`]) or a missing or failing GPU
//! ([`Error::Gpu`]). Every message is one line naming
//! what is wrong and what is expected.

use std::path::Path;

/// Result with the library's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in surftile.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused a read or write.
    #[error("{what}: {source}")]
    Io {
        /// The file (or stream) concerned.
        what: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A file could be read but its content is not a valid image of its format.
    #[error("{what}: {message}")]
    Decode {
        /// The file concerned.
        what: String,
        /// What is wrong with it.
        message: String,
    },
    /// A bank file failed validation (magic, version, sizes, checksum, values).
    #[error("bank {what}: {message}")]
    BadBank {
        /// The bank file concerned.
        what: String,
        /// What failed.
        message: String,
    },
    /// A parameter is outside the range the operation accepts.
    #[error("invalid {name} = {value}: expected {expected}")]
    InvalidParameter {
        /// Parameter name, as the CLI flag or builder method calls it.
        name: String,
        /// The value given.
        value: String,
        /// What would have been accepted.
        expected: String,
    },
    /// The exemplar has undefined (NaN) points and filling was not requested.
    #[error(
        "{what}: {count} of {total} height points are missing (NaN); pass `fill_missing` to fill them smoothly before analysis"
    )]
    MissingData {
        /// The file concerned.
        what: String,
        /// Number of NaN points.
        count: usize,
        /// Number of points in the map.
        total: usize,
    },
    /// The input is too small for the operation.
    #[error("{what}: {message}")]
    TooSmall {
        /// The input concerned.
        what: String,
        /// What size was found and what is needed.
        message: String,
    },
    /// The input was read, but the analysis found nothing it could use (no lattice in a
    /// texture, …).
    #[error("{what}: {message}")]
    Analysis {
        /// The input concerned.
        what: String,
        /// What was not found, the figure that decided it, and what to do instead.
        message: String,
    },
    /// A request exceeds a size limit (memory, dimensions).
    #[error("too large: {0}")]
    Limits(String),
    /// A format feature that surftile does not read or write.
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// No usable GPU adapter, or the GPU refused or lost the work: the machine's fault,
    /// not the input's (callers may fall back to the CPU).
    #[error("GPU: {0}")]
    Gpu(String),
}

impl Error {
    /// An I/O error on the given path.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Error::Io {
            what: path.display().to_string(),
            source,
        }
    }

    /// A decoding error on the given file.
    pub fn decode(what: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Decode {
            what: what.into(),
            message: message.into(),
        }
    }

    /// A parameter error. Give numbers that may be huge through [`short`].
    pub fn param(
        name: impl Into<String>,
        value: impl std::fmt::Display,
        expected: impl Into<String>,
    ) -> Self {
        Error::InvalidParameter {
            name: name.into(),
            value: value.to_string(),
            expected: expected.into(),
        }
    }

    /// A bank validation error.
    pub fn bank(what: impl Into<String>, message: impl Into<String>) -> Self {
        Error::BadBank {
            what: what.into(),
            message: message.into(),
        }
    }
}

/// Largest magnitude any real-valued parameter of a configuration or bank may have
/// (10³⁰, like [`crate::prep::MAX_VALUE`] for a map's values): far beyond any length,
/// height or weight a surface needs, and far enough below f64's and f32's limits that
/// the products and squares a model forms stay finite. Every real parameter read from a
/// file goes through [`finite_param`], [`positive_param`] or [`non_negative_param`], so a
/// checksum-correct file with 10³⁰⁰ in it is refused by name instead of rendering ±inf.
pub const MAX_PARAMETER: f64 = 1e30;

/// `v` if it is finite and at most [`MAX_PARAMETER`] in magnitude; otherwise the error
/// naming `key`, with `expected` saying what it should be.
pub fn finite_param(key: &str, v: f64, expected: &str) -> Result<f64> {
    if v.is_finite() && v.abs() <= MAX_PARAMETER {
        Ok(v)
    } else {
        Err(Error::param(key, short(v), bounded(expected)))
    }
}

/// `v` if it is positive, finite and within [1/MAX_PARAMETER, MAX_PARAMETER].
pub fn positive_param(key: &str, v: f64, expected: &str) -> Result<f64> {
    if v.is_finite() && (1.0 / MAX_PARAMETER..=MAX_PARAMETER).contains(&v) {
        Ok(v)
    } else {
        Err(Error::param(key, short(v), bounded(expected)))
    }
}

/// `v` if it is 0, or within [1/MAX_PARAMETER, MAX_PARAMETER].
pub fn non_negative_param(key: &str, v: f64, expected: &str) -> Result<f64> {
    if v == 0.0 {
        Ok(0.0)
    } else {
        positive_param(key, v, expected)
    }
}

fn bounded(expected: &str) -> String {
    format!("{expected}, within 1e-30 to 1e30 in magnitude")
}

/// A number for an error message: as typed for everyday magnitudes, in exponent form
/// from 10¹⁵ up and under 10⁻⁶ (where `{}` would print every digit of 1e300).
pub fn short(v: f64) -> String {
    if v.is_finite() && v != 0.0 && !(1e-6..1e15).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod tests {
    use super::short;

    #[test]
    fn huge_and_tiny_numbers_are_written_short() {
        assert_eq!(short(1e300), "1e300");
        assert_eq!(short(-9e18), "-9e18");
        assert_eq!(short(2.5e-9), "2.5e-9");
        assert_eq!(short(12.5), "12.5");
        assert_eq!(short(0.0), "0");
        assert_eq!(short(f64::NAN), "NaN");
        assert_eq!(short(f64::INFINITY), "inf");
    }
}
