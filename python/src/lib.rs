//! The `surftile` Python package's native module (`surftile._surftile`): the Rust front
//! door ([`surftile::open`], [`surftile::bake::Baker`], [`surftile::stats`]) with numpy
//! arrays in and out.
//!
//! - Fills write straight into numpy memory (a new array, or the caller's `out=`), in
//!   the bounded pieces of [`surftile::render::fill_into`], with the GIL released.
//! - Every value is the library's: the same bits as the CLI and the Rust API.
//! - Errors are the library's one-line messages, raised as `ValueError` (parameters,
//!   arrays, file contents), `FileNotFoundError` / `PermissionError` / `OSError`
//!   (files), `surftile.BankError` (a `ValueError`: a bank that fails validation).

mod dataset;

use std::path::PathBuf;

use numpy::{
    PyArray, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::create_exception;
use pyo3::exceptions::{
    PyFileNotFoundError, PyIsADirectoryError, PyOSError, PyPermissionError, PyRuntimeError,
    PyValueError,
};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyList};

use surftile::bake::quilting::QuiltingOptions;
use surftile::bake::rsgf::{RepeatWindow, RsgfOptions};
use surftile::bake::{Baker, BakerBuilder, Leveling};
use surftile::bank::Method;
use surftile::error::Error;
use surftile::imperfect::Imperfect;
use surftile::io::{ImageFile, MAX_IMAGE_PIXELS, ReadOptions, read_image};
use surftile::models::synth::SynthParams;
use surftile::raster::Raster;
use surftile::render::{MAX_IMPERFECT_SAMPLES, MAX_RENDER_SAMPLES, checked_size, fill_into};
use surftile::stream::Region;

create_exception!(
    surftile,
    BankError,
    PyValueError,
    "A bank file that fails validation (magic, version, sizes, checksum, values)."
);

/// The library's error as the Python exception its cause calls for.
fn py_err(e: Error) -> PyErr {
    let message = e.to_string();
    match &e {
        Error::Io { source, .. } => match source.kind() {
            std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
            std::io::ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
            std::io::ErrorKind::IsADirectory => PyIsADirectoryError::new_err(message),
            _ => PyOSError::new_err(message),
        },
        Error::BadBank { .. } => BankError::new_err(message),
        Error::Gpu(_) => PyRuntimeError::new_err(message),
        _ => PyValueError::new_err(message),
    }
}

/// `invalid NAME = VALUE: expected EXPECTED` as a `ValueError`.
fn bad(name: &str, value: impl std::fmt::Display, expected: impl Into<String>) -> PyErr {
    py_err(Error::param(name, value, expected))
}

trait OrPy<T> {
    fn py(self) -> PyResult<T>;
}

impl<T> OrPy<T> for surftile::Result<T> {
    fn py(self) -> PyResult<T> {
        self.map_err(py_err)
    }
}

/// A JSON value as Python objects (dicts, lists, floats, ints, strings, None).
fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    use serde_json::Value;
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(n) => {
            if let Some(i) = n.as_i64() {
                i.into_pyobject(py)?.into_any()
            } else if let Some(u) = n.as_u64() {
                u.into_pyobject(py)?.into_any()
            } else {
                n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any()
            }
        }
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(json_to_py(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, item) in map {
                dict.set_item(k, json_to_py(py, item)?)?;
            }
            dict.into_any()
        }
    })
}

/// A numpy array that is not one contiguous slice (the arrays here are made
/// contiguous first, so this is not expected).
fn slice_err(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A seed in the 32-bit range placements use.
fn seed32(seed: i64) -> PyResult<u32> {
    u32::try_from(seed).map_err(|_| bad("seed", seed, "a whole number from 0 to 2^32 − 1"))
}

/// A path from a `str` or an `os.PathLike`, or `None` for anything else.
fn as_path(obj: &Bound<'_, PyAny>) -> Option<PathBuf> {
    obj.extract::<PathBuf>().ok()
}

/// A 2-D (rows, cols) or 3-D (rows, cols, channels ≤ 4) numpy array of floats or
/// integers as a raster, converted to f32 as the `.npy` reader converts (round to
/// nearest): the same samples as the array saved with `numpy.save` and read back.
fn raster_from_array(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Raster> {
    let py = obj.py();
    let np = py.import("numpy")?;
    let arr = np.call_method1("asarray", (obj,))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    if !matches!(kind.as_str(), "f" | "i" | "u") {
        let dtype = arr.getattr("dtype")?.str()?.to_string();
        return Err(bad(
            name,
            format!("an array of dtype {dtype}"),
            "a numpy array of floats or integers, or a file path",
        ));
    }
    let shape: Vec<usize> = arr.getattr("shape")?.extract()?;
    let (h, w, c) = match shape[..] {
        [h, w] => (h, w, 1),
        [h, w, c] if (1..=4).contains(&c) => (h, w, c),
        _ => {
            return Err(bad(
                name,
                format!("an array of shape {shape:?}"),
                "(rows, cols) or (rows, cols, channels ≤ 4)",
            ));
        }
    };
    // The readers' limits, before the copy: no empty image, at most 2^25 pixels.
    match w.checked_mul(h) {
        Some(0) => {
            return Err(bad(
                name,
                format!("an empty array of shape {shape:?}"),
                "at least one row and one column",
            ));
        }
        Some(n) if n <= MAX_IMAGE_PIXELS => {}
        _ => {
            return Err(py_err(Error::Limits(format!(
                "{name}: an array of {h}×{w} pixels (at most {MAX_IMAGE_PIXELS}, as for image files)"
            ))));
        }
    }
    let arr = np.call_method1("ascontiguousarray", (arr, "float32"))?;
    let arr: PyReadonlyArrayDyn<'_, f32> = arr.extract()?;
    let data = arr
        .as_slice()
        .map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?
        .to_vec();
    Raster::from_vec(w, h, c, data).py()
}

/// An exemplar or map given as a path (read by extension) or as a numpy array, with
/// the name its errors and the bank record.
fn image_from(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<(ImageFile, String)> {
    if let Some(path) = as_path(obj) {
        let image = read_image(&path, &ReadOptions::default()).py()?;
        return Ok((image, path.display().to_string()));
    }
    let raster = raster_from_array(name, obj)?;
    let what = format!(
        "numpy array ({}×{}×{})",
        raster.height, raster.width, raster.channels
    );
    Ok((ImageFile::new(raster, None), what))
}

/// What `surftile.open` returns: a loaded source, placed by [`Source::surface`].
#[pyclass(module = "surftile", frozen)]
struct Source {
    inner: surftile::Source,
    spec: String,
}

/// `Source.surface` and `Bank.surface`: the seed checked, the GIL released.
fn place(py: Python<'_>, source: &surftile::Source, seed: i64) -> PyResult<Surface> {
    let seed = seed32(seed)?;
    py.detach(|| make_surface(source, seed)).py()
}

/// The surface of `source` placed with `seed`: its defects in it, its layer kept typed
/// for the mask.
fn make_surface(source: &surftile::Source, seed: u32) -> surftile::Result<Surface> {
    let defects = source.defects(seed).transpose()?;
    let plain = source.with_defects(source.loaded().surface(seed)?, seed)?;
    let inner = if source.imperfection().is_some() {
        let layer = source
            .imperfect_over(plain, seed)
            .expect("a source with a layer");
        Inner::Layered(Box::new(layer?))
    } else {
        Inner::Plain(plain)
    };
    Ok(Surface {
        channels: inner.get().channels(),
        inner,
        defects,
        spacing_um: source.spacing_um(),
        height_unit: source.height_unit(),
        seed,
    })
}

#[pymethods]
impl Source {
    /// The endless surface placed with `seed` (0 to 2^32 − 1): which tile goes where, a
    /// model's random draws, an imperfection layer's noise. Cheap to call again.
    #[pyo3(signature = (seed=0))]
    fn surface(&self, py: Python<'_>, seed: i64) -> PyResult<Surface> {
        place(py, &self.inner, seed)
    }

    /// What `surftile info --json SPEC` prints, as a dict: for a bank its method,
    /// tiles, spacing (µm per pixel), height unit, exemplar and bake record; for a
    /// configuration or preset its kind, spacing and height unit; an imperfection
    /// layer's pattern and age.
    #[getter]
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.inner.info_json())
    }

    /// The registry's kind: "blend" (rpn, adsn banks), "toroidal" (roller), "wang"
    /// (quilt), "rsgf", "synth", "quilting", "milling" (banks, configurations, presets) or
    /// "models".
    #[getter]
    fn kind(&self) -> &'static str {
        self.inner.kind().name()
    }

    /// Pixel spacing in µm, or None where the source has none (seed 001 models are in
    /// pixels; a bank baked without one).
    #[getter]
    fn spacing_um(&self) -> Option<f64> {
        self.inner.spacing_um()
    }

    /// Unit of the heights: "um", or "" where unknown (pixels, grey levels).
    #[getter]
    fn height_unit(&self) -> String {
        self.inner.height_unit()
    }

    fn __repr__(&self) -> String {
        format!("surftile.Source({:?}, kind={:?})", self.spec, self.kind())
    }
}

/// The surface behind a Python `Surface`: plain, or under an imperfection layer kept
/// as such so that its layer ids can be filled too.
enum Inner {
    Plain(Box<dyn surftile::Surface>),
    Layered(Box<Imperfect<Box<dyn surftile::Surface>>>),
}

impl Inner {
    fn get(&self) -> &dyn surftile::Surface {
        match self {
            Inner::Plain(s) => s.as_ref(),
            Inner::Layered(s) => s.as_ref(),
        }
    }
}

/// An endless, deterministic surface: any region or point, at any coordinate, gives
/// the same bits however it is split, on any thread.
#[pyclass(module = "surftile", frozen)]
struct Surface {
    inner: Inner,
    /// The defects in it, for their mask ids.
    defects: Option<surftile::defects::Defects>,
    channels: usize,
    spacing_um: Option<f64>,
    height_unit: String,
    seed: u32,
}

/// Shape of a fill's array: (H, W), or (H, W, C) for colour.
fn fill_shape(h: usize, w: usize, c: usize) -> Vec<usize> {
    if c == 1 { vec![h, w] } else { vec![h, w, c] }
}

/// The checked region of a fill request.
fn region_of(x: f64, y: f64, width: i64, height: i64, step: f64) -> PyResult<Region> {
    let region = Region::new(
        x,
        y,
        checked_size("width", width).py()?,
        checked_size("height", height).py()?,
    )
    .with_step(step);
    region.validate().py()?;
    Ok(region)
}

/// The caller's `out` array checked for a fill of `shape`: float32, C-contiguous,
/// writeable, of exactly that shape.
fn out_array<'py>(
    out: &Bound<'py, PyAny>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let expected = format!("a C-contiguous, writeable float32 numpy array of shape {shape:?}");
    let Ok(untyped) = out.cast::<PyUntypedArray>() else {
        let ty = out.get_type().name()?.to_string();
        return Err(bad("out", format!("a {ty}"), expected));
    };
    let Ok(arr) = untyped.cast::<PyArrayDyn<f32>>() else {
        let dtype = untyped.dtype().str()?.to_string();
        return Err(bad("out", format!("an array of dtype {dtype}"), expected));
    };
    if !arr.is_c_contiguous() {
        return Err(bad("out", "a non-contiguous array", expected));
    }
    if arr.shape() != shape {
        return Err(bad(
            "out",
            format!("an array of shape {:?}", arr.shape()),
            expected,
        ));
    }
    let writeable: bool = arr.getattr("flags")?.getattr("writeable")?.extract()?;
    if !writeable {
        return Err(bad("out", "a read-only array", expected));
    }
    Ok(arr.clone())
}

#[pymethods]
impl Surface {
    /// Channel 0 at surface coordinates (x, y), in pixels, at full resolution. Scalars
    /// give a float; numpy arrays (or anything numpy turns into one) of matching or
    /// broadcastable shapes give a float32 array of the broadcast shape. NaN (or
    /// coordinates beyond ±2^52 px) give NaN. The GIL is released while it runs.
    fn height<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let np = py.import("numpy")?;
        let ndim =
            |o: &Bound<'py, PyAny>| -> PyResult<usize> { np.call_method1("ndim", (o,))?.extract() };
        let is_array = |o: &Bound<'py, PyAny>| o.cast::<PyUntypedArray>().is_ok();
        if !is_array(x) && !is_array(y) && ndim(x)? == 0 && ndim(y)? == 0 {
            let (xs, ys): (f64, f64) = (x.extract()?, y.extract()?);
            let s = self.inner.get();
            let h = py.detach(|| s.height(xs, ys));
            return Ok((h as f64).into_pyobject(py)?.into_any());
        }
        let as_f64 = |o: &Bound<'py, PyAny>| np.call_method1("asarray", (o, "float64"));
        let both = np.call_method1("broadcast_arrays", (as_f64(x)?, as_f64(y)?))?;
        let contiguous = |i: usize| -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
            np.call_method1("ascontiguousarray", (both.get_item(i)?,))?
                .extract()
        };
        let (xs, ys) = (contiguous(0)?, contiguous(1)?);
        let shape = xs.shape().to_vec();
        let out = PyArray::<f32, _>::zeros(py, shape.as_slice(), false);
        {
            let mut w = out.readwrite();
            let o = w.as_slice_mut().map_err(slice_err)?;
            let (xv, yv) = (
                xs.as_slice().map_err(slice_err)?,
                ys.as_slice().map_err(slice_err)?,
            );
            let s = self.inner.get();
            py.detach(|| {
                for ((o, &x), &y) in o.iter_mut().zip(xv).zip(yv) {
                    *o = s.height(x, y);
                }
            });
        }
        Ok(out.into_any())
    }
    /// The `width × height` samples whose first is at surface coordinates (x, y)
    /// (pixels), `step` pixels apart (above 1 reads prefiltered levels). Returns a
    /// float32 array of shape (height, width), or (height, width, channels) for colour,
    /// in the source's height unit. With `out` (a C-contiguous, writeable float32 array
    /// of that shape) the samples are written straight into it, with no copy, and `out`
    /// is returned. Fills on every core with the GIL released; without `out`, at most
    /// 2^28 values (1 GiB) per call.
    #[pyo3(signature = (x, y, width, height, *, step=1.0, out=None))]
    #[allow(clippy::too_many_arguments)]
    fn fill<'py>(
        &self,
        py: Python<'py>,
        x: f64,
        y: f64,
        width: i64,
        height: i64,
        step: f64,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let region = region_of(x, y, width, height, step)?;
        let c = self.channels;
        let shape = fill_shape(region.height, region.width, c);
        let arr = match out {
            Some(o) => out_array(o, &shape)?,
            None => {
                let values = region
                    .width
                    .checked_mul(region.height)
                    .and_then(|n| n.checked_mul(c))
                    .filter(|&n| n <= MAX_RENDER_SAMPLES);
                if values.is_none() {
                    return Err(py_err(Error::Limits(format!(
                        "a {}×{} region of {c} channel(s) is over the limit of {MAX_RENDER_SAMPLES} values (1 GiB of f32) a new array may hold; pass out= or fill it in tiles",
                        region.width, region.height
                    ))));
                }
                PyArray::<f32, _>::zeros(py, shape.as_slice(), false)
            }
        };
        {
            let mut w = arr.try_readwrite().map_err(|e| {
                bad(
                    "out",
                    "an array already borrowed",
                    format!("one not in use ({e})"),
                )
            })?;
            let buf = w.as_slice_mut().map_err(slice_err)?;
            let s = self.inner.get();
            py.detach(|| fill_into(s, &region, buf)).py()?;
        }
        Ok(arr.into_any())
    }
    /// As `fill`, with the mask id of every sample as a uint8 array of shape (height,
    /// width), what `surftile render --mask` writes: 0 clean; the imperfection layer's
    /// ids (dust and patina 1; peeling 1, 2, … for each layer lost); the defects' ids
    /// (scratch 16, dent 17, pits 18, or their `mask_id`) where a defect changed the
    /// sample by more than 5% of its depth. A source without layer or defects gives its
    /// heights and an all-zero mask. At most 2^25 samples per call with a layer.
    #[pyo3(signature = (x, y, width, height, *, step=1.0))]
    fn fill_with_mask<'py>(
        &self,
        py: Python<'py>,
        x: f64,
        y: f64,
        width: i64,
        height: i64,
        step: f64,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let region = region_of(x, y, width, height, step)?;
        let mask = PyArray::<u8, _>::zeros(py, [region.height, region.width], false);
        let Inner::Layered(layer) = &self.inner else {
            let heights = self.fill(py, x, y, width, height, step, None)?;
            if let Some(defects) = &self.defects {
                let mut mw = mask.readwrite();
                let ms = mw.as_slice_mut().map_err(slice_err)?;
                py.detach(|| defects.fill_ids(&region, ms)).py()?;
            }
            return Ok((heights, mask.into_any()));
        };
        let samples = region.width * region.height;
        if samples > MAX_IMPERFECT_SAMPLES {
            return Err(py_err(Error::Limits(format!(
                "a {}×{} region is over the limit of {MAX_IMPERFECT_SAMPLES} samples per fill_with_mask call (it holds four layers a sample); fill it in tiles",
                region.width, region.height
            ))));
        }
        let heights = PyArray::<f32, _>::zeros(py, [region.height, region.width], false);
        {
            let (mut hw, mut mw) = (heights.readwrite(), mask.readwrite());
            let hs = hw.as_slice_mut().map_err(slice_err)?;
            let ms = mw.as_slice_mut().map_err(slice_err)?;
            py.detach(|| -> surftile::Result<()> {
                // Strips of bounded size: a layer fills any part as it fills the whole.
                let rows = (1usize << 22).div_ceil(region.width).max(1);
                let mut row = 0;
                while row < region.height {
                    let n = rows.min(region.height - row);
                    let part = layer.fill_layers(&region.sub(0, row, region.width, n)?)?;
                    let at = row * region.width;
                    hs[at..at + part.heights.len()].copy_from_slice(&part.heights);
                    ms[at..at + part.layers.len()].copy_from_slice(&part.layers);
                    row += n;
                }
                // The defects' ids over the layer's, where they are set.
                if let Some(defects) = &self.defects {
                    let mut ids = vec![0u8; samples];
                    defects.fill_ids(&region, &mut ids)?;
                    for (m, &id) in ms.iter_mut().zip(&ids) {
                        if id != 0 {
                            *m = id;
                        }
                    }
                }
                Ok(())
            })
            .py()?;
        }
        Ok((heights.into_any(), mask.into_any()))
    }

    /// Values per sample: 1 for heights, 3 for RGB.
    #[getter]
    fn channels(&self) -> usize {
        self.channels
    }

    /// Pixel spacing in µm, or None where the source has none.
    #[getter]
    fn spacing_um(&self) -> Option<f64> {
        self.spacing_um
    }

    /// Unit of the heights: "um", or "" where unknown (pixels, grey levels).
    #[getter]
    fn height_unit(&self) -> &str {
        &self.height_unit
    }

    /// The placement seed.
    #[getter]
    fn seed(&self) -> u32 {
        self.seed
    }

    /// Whether an imperfection layer lies over the surface.
    #[getter]
    fn has_layer(&self) -> bool {
        matches!(self.inner, Inner::Layered(_))
    }

    /// Whether defects lie in the surface.
    #[getter]
    fn has_defects(&self) -> bool {
        self.defects.is_some()
    }

    fn __repr__(&self) -> String {
        format!(
            "surftile.Surface(channels={}, seed={}, spacing_um={:?}, height_unit={:?})",
            self.channels, self.seed, self.spacing_um, self.height_unit
        )
    }
}
/// Opens a bank file (recognised by its content), a milling or seed 001 model `.toml`,
/// or a preset name (models: rock, china, casting, cells-convex, cells-concave;
/// milling: e.g. parallel-d4-ae05). `spacing_um` is the pixel spacing in µm a milling
/// source is drawn at (default 6.1; banks keep their own, models are in pixels).
/// `imperfect` lays an imperfection layer over it (a `.toml` or a preset: dust, patina,
/// peeling), `age` multiplies its sources' γ. `defects` puts defects in it, under the
/// layer (a `.toml` of [[defect]] entries or a preset: scratches, dents, pits).
#[pyfunction]
#[pyo3(signature = (spec, *, spacing_um=None, imperfect=None, age=None, defects=None))]
fn open(
    py: Python<'_>,
    spec: PathBuf,
    spacing_um: Option<f64>,
    imperfect: Option<PathBuf>,
    age: Option<f64>,
    defects: Option<PathBuf>,
) -> PyResult<Source> {
    let mut open = surftile::Open::new(&spec);
    if let Some(s) = spacing_um {
        open = open.spacing_um(s);
    }
    if let Some(layer) = &imperfect {
        open = open.imperfection(layer);
    }
    if let Some(a) = age {
        open = open.age(a);
    }
    if let Some(d) = &defects {
        open = open.defects(d);
    }
    let inner = py.detach(|| open.open()).py()?;
    Ok(Source {
        inner,
        spec: spec.display().to_string(),
    })
}

/// A bank made by `surftile.bake`: save it, or place it as a surface.
#[pyclass(module = "surftile", frozen)]
struct Bank {
    source: surftile::Source,
    log: Vec<String>,
}

#[pymethods]
impl Bank {
    /// Writes the bank file (checked in full, written to a temporary name and renamed,
    /// so `path` is either complete or untouched).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let bank = self.source.bank().expect("a baked bank");
        py.detach(|| surftile::kinds::write_bank(bank, &path)).py()
    }
    /// The bank's endless surface placed with `seed`.
    #[pyo3(signature = (seed=0))]
    fn surface(&self, py: Python<'_>, seed: i64) -> PyResult<Surface> {
        place(py, &self.source, seed)
    }

    /// What `surftile info --json` prints for the saved file (without its size).
    #[getter]
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.source.info_json())
    }

    /// The bake's progress lines (for `method="auto"`, the first says what it picked
    /// and why).
    #[getter]
    fn log(&self) -> Vec<String> {
        self.log.clone()
    }

    fn __repr__(&self) -> String {
        let h = &self.source.bank().expect("a baked bank").header;
        format!(
            "surftile.Bank(method={:?}, tiles={}, channels={})",
            h.method.to_string(),
            h.tiles,
            h.channels
        )
    }
}

/// The error for a keyword whose value is not of the type it takes.
fn wrong_type(name: &str, value: &Bound<'_, PyAny>, expected: &str) -> PyErr {
    let shown = value.repr().map(|r| r.to_string()).unwrap_or_default();
    bad(name, shown, expected)
}

/// The enum value serde (and the CLI) call `text`; `names` lists them for the error.
fn named<T: serde::de::DeserializeOwned>(name: &str, text: &str, names: &str) -> PyResult<T> {
    serde_json::from_value(serde_json::Value::String(text.into()))
        .map_err(|_| bad(name, format!("{text:?}"), format!("one of {names}")))
}

/// A keyword's value as a string naming one of an enum's values.
fn enum_param<T: serde::de::DeserializeOwned>(
    name: &str,
    value: &Bound<'_, PyAny>,
    names: &str,
) -> PyResult<T> {
    let text: String = value
        .extract()
        .map_err(|_| wrong_type(name, value, &format!("one of {names}")))?;
    named(name, &text, names)
}

/// A keyword's value as a count (a whole number ≥ 0).
fn count_param(name: &str, value: &Bound<'_, PyAny>) -> PyResult<usize> {
    let v: i64 = value
        .extract()
        .map_err(|_| wrong_type(name, value, "a whole number"))?;
    usize::try_from(v).map_err(|_| bad(name, v, "a whole number ≥ 0"))
}

fn float_param(name: &str, value: &Bound<'_, PyAny>) -> PyResult<f64> {
    value
        .extract()
        .map_err(|_| wrong_type(name, value, "a number"))
}

fn bool_param(name: &str, value: &Bound<'_, PyAny>) -> PyResult<bool> {
    value
        .cast::<PyBool>()
        .map(|b| b.is_true())
        .map_err(|_| wrong_type(name, value, "True or False"))
}

/// Two integers, from a tuple/list or a string "a,b" (or "aXb" with `sep` = 'x').
fn pair_param(name: &str, value: &Bound<'_, PyAny>, sep: char) -> PyResult<(i64, i64)> {
    if let Ok(p) = value.extract::<(i64, i64)>() {
        return Ok(p);
    }
    let wrong = || wrong_type(name, value, "two whole numbers");
    let text: String = value.extract().map_err(|_| wrong())?;
    let (a, b) = text
        .split_once([sep, sep.to_ascii_uppercase()])
        .ok_or_else(wrong)?;
    Ok((
        a.trim().parse().map_err(|_| wrong())?,
        b.trim().parse().map_err(|_| wrong())?,
    ))
}

/// The keywords `bake` takes besides method, spacing_um and seed: the CLI's flags.
const BAKE_KEYWORDS: &str = "patch, bank_size, level, downsample, downsample_filter, fill_missing, triangle_edge, taper, tiles, lattice, tile, overlap, block, border, tolerance, metric, join, feather, stochastic, match_histogram, edges, repeat_window, colours, levels, k, passes, fine_passes, jitter, appearance_dims, coherence, jitter_levels, ragged, penalty";

/// The builder with the keywords applied, in the order given.
fn apply_params(
    mut b: BakerBuilder,
    method: Method,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<BakerBuilder> {
    let mut rsgf = RsgfOptions::default();
    // Quilting takes `block` and `overlap` as its own, as the CLI does.
    let quilts = method == Method::Quilting;
    let mut quilting = QuiltingOptions::default();
    let mut synth = SynthParams::default();
    let (mut downsample, mut filter) = (1, surftile::prep::resample::DownsampleFilter::Nearest);
    for (key, v) in params.into_iter().flatten() {
        let key: String = key.extract()?;
        let k = key.as_str();
        b = match k {
            "patch" => b.patch(count_param(k, &v)?),
            "bank_size" => b.bank_size(count_param(k, &v)?),
            "level" => b.leveling(enum_param::<Leveling>(k, &v, "auto, plane, poly:N, none")?),
            "downsample" => {
                downsample = count_param(k, &v)?;
                b
            }
            "downsample_filter" => {
                filter = enum_param(k, &v, "nearest, area")?;
                b
            }
            "fill_missing" => b.fill_missing(bool_param(k, &v)?),
            "triangle_edge" => b.triangle_edge(float_param(k, &v)?),
            "taper" => b.taper(enum_param(k, &v, "hann, main-lobe, periodic")?),
            "tiles" => b.tiles(count_param(k, &v)?),
            "lattice" => {
                let list: Vec<Bound<'_, PyAny>> = if let Ok(s) = v.extract::<String>() {
                    let (u, w) = s.split_once(';').ok_or_else(|| {
                        bad(
                            k,
                            format!("{s:?}"),
                            "two vectors ((ux, uy), (vx, vy)) or \"ux,uy;vx,vy\" in pixels",
                        )
                    })?;
                    vec![
                        u.into_pyobject(v.py())?.into_any(),
                        w.into_pyobject(v.py())?.into_any(),
                    ]
                } else {
                    v.extract().map_err(|_| {
                        bad(
                            k,
                            "not a pair",
                            "two vectors ((ux, uy), (vx, vy)) in pixels",
                        )
                    })?
                };
                if list.len() != 2 {
                    return Err(bad(
                        k,
                        format!("{} vectors", list.len()),
                        "two vectors ((ux, uy), (vx, vy)) in pixels",
                    ));
                }
                b.lattice(pair_param(k, &list[0], ',')?, pair_param(k, &list[1], ',')?)
            }
            "tile" => {
                let (w, h) = pair_param(k, &v, 'x')?;
                let size = |s: i64| usize::try_from(s).map_err(|_| bad(k, s, "a size ≥ 0"));
                b.tile(size(w)?, size(h)?)
            }
            "overlap" if quilts => {
                quilting.overlap_px = Some(count_param(k, &v)?);
                b
            }
            "overlap" => b.overlap(count_param(k, &v)?),
            "block" if quilts => {
                quilting.block_px = Some(count_param(k, &v)?);
                b
            }
            "block" => {
                rsgf.block_px = Some(count_param(k, &v)?);
                b
            }
            "penalty" => {
                quilting.penalty = Some(float_param(k, &v)? as f32);
                b
            }
            "repeat_window" => {
                rsgf.repeat_window = match v.extract::<String>() {
                    Ok(text) => text.parse().map_err(|_: String| {
                        bad(
                            k,
                            format!("{text:?}"),
                            "auto, off or the window's side in pixels",
                        )
                    })?,
                    Err(_) => RepeatWindow::Side(count_param(k, &v)?),
                };
                b
            }
            "border" => {
                rsgf.border_px = Some(count_param(k, &v)?);
                b
            }
            "tolerance" => {
                rsgf.tolerance_px = count_param(k, &v)?;
                b
            }
            "metric" => {
                rsgf.metric = Some(enum_param(k, &v, "ssd, ncc")?);
                b
            }
            "join" => {
                rsgf.join = enum_param(k, &v, "blend, cut")?;
                b
            }
            "feather" => {
                rsgf.feather_px = Some(count_param(k, &v)?);
                b
            }
            "stochastic" => {
                rsgf.stochastic = bool_param(k, &v)?;
                b
            }
            "match_histogram" => {
                rsgf.histogram = bool_param(k, &v)?;
                b
            }
            "edges" if quilts => {
                quilting.wrap = match enum_param::<surftile::models::rsgf::Edges>(
                    k,
                    &v,
                    "auto, reflect, wrap",
                )? {
                    surftile::models::rsgf::Edges::Auto => None,
                    surftile::models::rsgf::Edges::Wrap => Some(true),
                    surftile::models::rsgf::Edges::Reflect => Some(false),
                };
                b
            }
            "edges" => {
                rsgf.edges = enum_param(k, &v, "auto, reflect, wrap")?;
                b
            }
            "colours" => b.colours(count_param(k, &v)?),
            "levels" => {
                synth.levels = count_param(k, &v)?;
                if synth.levels == 0 {
                    return Err(bad("levels", 0, "1 to 12 synthesis levels"));
                }
                b
            }
            "k" => {
                synth.k = count_param(k, &v)?;
                b
            }
            "passes" => {
                synth.passes = count_param(k, &v)?;
                b
            }
            "fine_passes" => {
                synth.fine_passes = count_param(k, &v)?;
                b
            }
            "jitter" => {
                synth.jitter = float_param(k, &v)?;
                b
            }
            "appearance_dims" => {
                synth.appearance_dims = count_param(k, &v)?;
                b
            }
            "coherence" => {
                synth.coherence = float_param(k, &v)?;
                b
            }
            "jitter_levels" => {
                synth.jitter_levels = count_param(k, &v)?;
                b
            }
            "ragged" => {
                synth.ragged = float_param(k, &v)?;
                b
            }
            other => {
                return Err(bad(
                    "keyword",
                    other,
                    format!("one of method, spacing_um, seed, {BAKE_KEYWORDS}"),
                ));
            }
        };
    }
    Ok(b.downsample(downsample, filter)
        .rsgf(rsgf)
        .synth(synth)
        .quilting(quilting))
}
/// Analyses an exemplar once into a bank. `exemplar` is a file path (.png, .jpg, .tif,
/// .npy, instrument files; a milling .toml for method="milling") or a numpy array (rows, cols) or
/// (rows, cols, channels ≤ 4) of floats or integers. `method`: auto (picks one and
/// says why in `Bank.log`), rpn, adsn, roller, rsgf, quilt, synth, quilting or milling.
/// `spacing_um`: pixel spacing in µm (overrides the file's; required for milling).
/// `seed`: the bake's random draws. Other keywords are the CLI's `bake` flags with
/// underscores (patch, bank_size, level, stochastic, block, k, …), with the same
/// defaults. The GIL is released while it runs.
#[pyfunction]
#[pyo3(signature = (exemplar, *, method="auto", spacing_um=None, seed=0, **params))]
fn bake(
    py: Python<'_>,
    exemplar: &Bound<'_, PyAny>,
    method: &str,
    spacing_um: Option<f64>,
    seed: i64,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<Bank> {
    let method: Method = named(
        "method",
        method,
        "auto, rpn, adsn, roller, rsgf, quilt, synth, quilting, milling",
    )?;
    let seed = u64::try_from(seed).map_err(|_| bad("seed", seed, "a whole number ≥ 0"))?;
    let mut log = Vec::new();
    let bank = if method == Method::Milling {
        if params.is_some_and(|p| !p.is_empty()) {
            return Err(bad(
                "keywords",
                "given with method=\"milling\"",
                "none: a milling bank is its TOML configuration at spacing_um",
            ));
        }
        let Some(config) = as_path(exemplar) else {
            return Err(bad(
                "exemplar",
                "not a path",
                "a milling .toml file (or preset name) for method=\"milling\"",
            ));
        };
        let spacing = spacing_um.ok_or_else(|| {
            bad(
                "spacing_um",
                "None",
                "the pixel spacing in µm of the surface the bank renders, e.g. 6.1",
            )
        })?;
        py.detach(|| -> surftile::Result<surftile::bank::Bank> {
            let (c, base) = surftile::models::milling::MillingConfig::load(&config)?;
            surftile::models::milling::MillingSurface::new(&c, spacing, seed as u32)?
                .adapt_from_config(base.as_deref())?
                .to_bank(&config.display().to_string())
        })
        .py()?
    } else {
        let mut builder = Baker::builder().method(method).seed(seed);
        builder = apply_params(builder, method, params)?;
        if let Some(s) = spacing_um {
            builder = builder.spacing_um(s);
        }
        let baker = builder.build().py()?;
        let (image, what) = image_from("exemplar", exemplar)?;
        py.detach(|| baker.bake(&image, &what, &mut |line| log.push(line.to_string())))
            .py()?
    };
    let source = surftile::Source::from_bank(bank).py()?;
    Ok(Bank { source, log })
}
/// Reads a height file the CLI reads (instrument formats — X3P, AL3D, PLU, SUR, OPD,
/// Nanoscope, MetroPro, SDF — and npy, TIFF, PNG; recognised by content) as a dict:
/// `heights` (float32 array, rows × cols, in µm, NaN where missing), `spacing_um`
/// ((x, y), or None where the file records none), `unit_in_file` (the unit the file
/// stored heights in, or None) and `missing` (the count of missing points).
#[pyfunction]
fn read<'py>(py: Python<'py>, path: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
    let Some(path) = as_path(path) else {
        return Err(wrong_type("path", path, "a file path (str or os.PathLike)"));
    };
    let image = py
        .detach(|| read_image(&path, &ReadOptions::default()))
        .py()?;
    let r = &image.raster;
    let d = PyDict::new(py);
    let missing = r.count_nan();
    let (h, w, c) = (r.height, r.width, r.channels);
    let heights = PyArray::from_vec(py, image.raster.data.clone());
    if c == 1 {
        d.set_item("heights", heights.reshape([h, w])?)?;
    } else {
        d.set_item("heights", heights.reshape([h, w, c])?)?;
    }
    d.set_item("spacing_um", image.spacing_um.zip(image.spacing_y()))?;
    d.set_item("unit_in_file", image.unit.map(|u| u.symbol()))?;
    d.set_item("missing", missing)?;
    Ok(d)
}

/// The quality figures of `b` (a synthesis) against `a` (an exemplar), as `surftile
/// stats` prints them: W1 of the standardised height histograms, PSD error, standard
/// deviation ratio, seam score of `b` at `cell` px, and (with `structure`) the patch
/// figures: coherence, completeness, self-repetition, copy score and seams at any
/// phase. Each map is a file path or a numpy array.
#[pyfunction]
#[pyo3(signature = (a, b, *, cell=None, level="plane", fill_missing=false, structure=true))]
fn stats<'py>(
    py: Python<'py>,
    a: &Bound<'py, PyAny>,
    b: &Bound<'py, PyAny>,
    cell: Option<i64>,
    level: &str,
    fill_missing: bool,
    structure: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let cell = cell
        .map(|c| usize::try_from(c).map_err(|_| bad("cell", c, "a size in pixels ≥ 0")))
        .transpose()?;
    let leveling: Leveling = named("level", level, "auto, plane, poly:N, none")?;
    let (ia, wa) = image_from("a", a)?;
    let (ib, wb) = image_from("b", b)?;
    let options = surftile::stats::CompareOptions {
        cell,
        leveling,
        fill_missing,
        lfilter_px: None,
        structure,
    };
    let figures = py
        .detach(|| surftile::stats::compare_maps((&ia.raster, &wa), (&ib.raster, &wb), &options))
        .py()?;
    let mut value =
        serde_json::to_value(&figures).map_err(|e| PyValueError::new_err(format!("stats: {e}")))?;
    // The operators, as the CLI names them.
    value["operators"] = serde_json::to_value(surftile::stats::Operators::new(leveling, None))
        .map_err(|e| PyValueError::new_err(format!("stats: {e}")))?;
    json_to_py(py, &value)
}

/// The native module; `surftile/__init__.py` re-exports it.
#[pymodule]
fn _surftile(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("BankError", m.py().get_type::<BankError>())?;
    m.add_class::<Source>()?;
    m.add_class::<Surface>()?;
    m.add_class::<Bank>()?;
    m.add_class::<dataset::Dataset>()?;
    m.add_function(wrap_pyfunction!(open, m)?)?;
    m.add_function(wrap_pyfunction!(bake, m)?)?;
    m.add_function(wrap_pyfunction!(stats, m)?)?;
    m.add_function(wrap_pyfunction!(read, m)?)?;
    Ok(())
}
