//! [`Raster`]: a width × height grid of f32 samples with interleaved channels.

use crate::error::{Error, Result};

/// A row-major image of `f32` samples, `channels` values per pixel, interleaved.
///
/// Heights are in the unit of the source (µm for measured maps); colours in the
/// source's integer levels (0–255 or 0–65535) unless said otherwise.
#[derive(Clone, Debug, PartialEq)]
pub struct Raster {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Values per pixel (1 for height maps, 3 for RGB).
    pub channels: usize,
    /// `height * width * channels` samples, row-major, channels interleaved.
    pub data: Vec<f32>,
}

impl Raster {
    /// A raster of zeros.
    pub fn zeros(width: usize, height: usize, channels: usize) -> Self {
        Raster {
            width,
            height,
            channels,
            data: vec![0.0; width * height * channels],
        }
    }

    /// Wraps `data`, checking that its length is `width * height * channels`.
    pub fn from_vec(width: usize, height: usize, channels: usize, data: Vec<f32>) -> Result<Self> {
        let expected = width
            .checked_mul(height)
            .and_then(|n| n.checked_mul(channels))
            .ok_or_else(|| Error::Limits(format!("raster {width}×{height}×{channels}")))?;
        if data.len() != expected {
            return Err(Error::param(
                "raster data length",
                data.len(),
                format!("{expected} = {width}×{height}×{channels}"),
            ));
        }
        Ok(Raster {
            width,
            height,
            channels,
            data,
        })
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// Sample of channel `c` at pixel (x, y).
    #[inline]
    pub fn get(&self, x: usize, y: usize, c: usize) -> f32 {
        self.data[(y * self.width + x) * self.channels + c]
    }

    /// Sets channel `c` at pixel (x, y).
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, c: usize, v: f32) {
        self.data[(y * self.width + x) * self.channels + c] = v;
    }

    /// One channel as a single-channel raster.
    pub fn channel(&self, c: usize) -> Raster {
        let data = self
            .data
            .iter()
            .skip(c)
            .step_by(self.channels)
            .copied()
            .collect();
        Raster {
            width: self.width,
            height: self.height,
            channels: 1,
            data,
        }
    }

    /// Values of channel `c` as f64, row-major.
    pub fn channel_f64(&self, c: usize) -> Vec<f64> {
        self.data
            .iter()
            .skip(c)
            .step_by(self.channels)
            .map(|&v| v as f64)
            .collect()
    }

    /// Writes a row-major f64 plane into channel `c`.
    pub fn set_channel_f64(&mut self, c: usize, plane: &[f64]) {
        for (dst, &v) in self
            .data
            .iter_mut()
            .skip(c)
            .step_by(self.channels)
            .zip(plane)
        {
            *dst = v as f32;
        }
    }

    /// The rectangle [x, x+w) × [y, y+h), which must lie inside the raster.
    pub fn crop(&self, x: usize, y: usize, w: usize, h: usize) -> Result<Raster> {
        if x + w > self.width || y + h > self.height {
            return Err(Error::param(
                "crop",
                format!("{w}×{h} at ({x}, {y})"),
                format!("a rectangle inside {}×{}", self.width, self.height),
            ));
        }
        let c = self.channels;
        let mut data = Vec::with_capacity(w * h * c);
        for row in y..y + h {
            let start = (row * self.width + x) * c;
            data.extend_from_slice(&self.data[start..start + w * c]);
        }
        Ok(Raster {
            width: w,
            height: h,
            channels: c,
            data,
        })
    }

    /// The raster read as a torus over `width × height` pixels: pixel (x, y) is this
    /// raster's (x mod its width, y mod its height). Itself where it is empty.
    pub fn torus(&self, width: usize, height: usize) -> Raster {
        let (w, h, c) = (self.width, self.height, self.channels);
        if w * h * c == 0 {
            return self.clone();
        }
        let mut data = Vec::with_capacity(width * height * c);
        for y in 0..height {
            let row = &self.data[(y % h) * w * c..(y % h + 1) * w * c];
            for x0 in (0..width).step_by(w) {
                data.extend_from_slice(&row[..(width - x0).min(w) * c]);
            }
        }
        Raster {
            width,
            height,
            channels: c,
            data,
        }
    }

    /// Number of NaN samples.
    pub fn count_nan(&self) -> usize {
        self.data.iter().filter(|v| v.is_nan()).count()
    }
}
