//! NumPy `.npy` reading (f32, f64, u8, u16, i16, i32; C or Fortran order; H×W or H×W×C) and
//! float32 writing, on the `npyz` crate.

use std::io::Write;

use npyz::{DType, NpyFile, Order, TypeChar, WriterBuilder};

use super::ImageFile;
use crate::error::{Error, Result};
use crate::raster::Raster;

pub(super) fn read(bytes: &[u8], what: &str) -> Result<ImageFile> {
    let bad = |m: String| Error::decode(what, m);
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
    Ok(ImageFile {
        raster: Raster::from_vec(w, h, c, data)
            .map_err(|_| bad("data length does not match the shape".into()))?,
        spacing_um: None,
    })
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
    let mut writer = npyz::WriteOptions::<f32>::new()
        .default_dtype()
        .shape(&shape)
        .writer(w)
        .begin_nd()
        .map_err(err)?;
    writer.extend(raster.data.iter().copied()).map_err(err)?;
    writer.finish().map_err(err)
}
