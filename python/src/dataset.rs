//! `surftile._surftile.Dataset`: a checked dataset spec, its shards written with the
//! GIL released (what `surftile.dataset.write_shard` and `generate` call, on this
//! machine or in a Ray task). The bytes are the CLI's: both call
//! [`surftile::dataset::Dataset::write_shard`].

use std::path::PathBuf;

use numpy::{PyArray, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::{OrPy, bad, fill_shape, json_to_py};

/// A dataset spec, checked and opened (sources, layers, defects).
#[pyclass(module = "surftile", frozen)]
pub(crate) struct Dataset {
    inner: surftile::dataset::Dataset,
    spec: PathBuf,
}

/// A thread count from Python: None for every core, else 1 to 1024.
fn threads(value: Option<i64>) -> PyResult<usize> {
    match value {
        None => Ok(surftile::stream::default_threads()),
        Some(n) if (1..=1024).contains(&n) => Ok(n as usize),
        Some(n) => Err(bad(
            "threads",
            n,
            "1 to 1024 threads, or None for every core",
        )),
    }
}

/// A shard number from Python.
fn shard(value: i64) -> PyResult<u64> {
    u64::try_from(value).map_err(|_| bad("shard", value, "a shard number ≥ 0"))
}

#[pymethods]
impl Dataset {
    /// Reads and checks the spec at `spec` (a `.toml`); relative paths in it start from
    /// its folder.
    #[new]
    fn new(py: Python<'_>, spec: PathBuf) -> PyResult<Dataset> {
        let inner = py.detach(|| surftile::dataset::Dataset::load(&spec)).py()?;
        Ok(Dataset { inner, spec })
    }

    /// The spec file.
    #[getter]
    fn spec(&self) -> PathBuf {
        self.spec.clone()
    }

    /// Samples in all.
    #[getter]
    fn samples(&self) -> u64 {
        self.inner.samples()
    }

    /// Shards in all.
    #[getter]
    fn shards(&self) -> u64 {
        self.inner.shards()
    }

    /// The spec hash `dataset.json` records ("sha256:…").
    #[getter]
    fn hash(&self) -> String {
        self.inner.hash().to_string()
    }

    /// What `dataset.json` holds, as a dict.
    #[getter]
    fn index<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, self.inner.index())
    }

    /// The samples of shard `s` as (first, end), end excluded.
    fn shard_samples(&self, s: i64) -> PyResult<(u64, u64)> {
        let r = self.inner.shard_samples(shard(s)?);
        Ok((r.start, r.end))
    }

    /// Readies `out` for shards [start, end): refuses a file, or a dataset of another
    /// spec unless `force`; writes `dataset.json`; removes interrupted writes' temporary
    /// files; returns {"todo": [...], "complete": [...], "broken": [...]}.
    #[pyo3(signature = (out, start, end, force=false))]
    fn prepare<'py>(
        &self,
        py: Python<'py>,
        out: PathBuf,
        start: i64,
        end: i64,
        force: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let range = shard(start)?..shard(end)?;
        let p = py.detach(|| self.inner.prepare(&out, range, force)).py()?;
        let d = PyDict::new(py);
        d.set_item("todo", p.todo)?;
        d.set_item("complete", p.complete)?;
        d.set_item("broken", p.broken)?;
        Ok(d)
    }

    /// Removes the temporary files interrupted writes of shards [start, end) left in
    /// `out`.
    fn remove_temporaries(
        &self,
        py: Python<'_>,
        out: PathBuf,
        start: i64,
        end: i64,
    ) -> PyResult<()> {
        let range = shard(start)?..shard(end)?;
        py.detach(|| self.inner.remove_temporaries(&out, range))
            .py()
    }

    /// Writes shard `s` into the folder `out` (a temporary name, then a rename), its
    /// samples rendered on `threads` threads (None: every core; the bytes do not
    /// depend on it). Returns {"shard", "samples", "bytes"}.
    #[pyo3(signature = (s, out, threads=None))]
    fn write_shard<'py>(
        &self,
        py: Python<'py>,
        s: i64,
        out: PathBuf,
        threads: Option<i64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (s, threads) = (shard(s)?, self::threads(threads)?);
        let w = py
            .detach(|| self.inner.write_shard(s, &out, threads, &mut |_| {}))
            .py()?;
        let d = PyDict::new(py);
        d.set_item("shard", w.shard)?;
        d.set_item("samples", w.samples)?;
        d.set_item("bytes", w.bytes)?;
        Ok(d)
    }

    /// Writes `shards` (in order) into the folder `out` as one stream: the samples
    /// render on across shard boundaries while completed shards are synced and renamed
    /// (what `surftile dataset` does). `progress`, if given, is called with
    /// (samples written, shards complete) as they change. Returns a list of
    /// {"shard", "samples", "bytes"}.
    #[pyo3(signature = (shards, out, threads=None, progress=None))]
    fn write_shards<'py>(
        &self,
        py: Python<'py>,
        shards: Vec<i64>,
        out: PathBuf,
        threads: Option<i64>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let shards = shards
            .into_iter()
            .map(shard)
            .collect::<PyResult<Vec<_>>>()?;
        let threads = self::threads(threads)?;
        let mut last_shards = 0u64;
        let mut failure: Option<PyErr> = None;
        let written = py
            .detach(|| {
                self.inner.write_shards(&shards, &out, threads, &mut |p| {
                    let Some(callback) = &progress else {
                        return;
                    };
                    if failure.is_some() || p.shards == last_shards {
                        return;
                    }
                    last_shards = p.shards;
                    Python::attach(|py| {
                        if let Err(e) = callback.call1(py, (p.samples, p.shards)) {
                            failure = Some(e);
                        }
                    });
                })
            })
            .py()?;
        if let Some(e) = failure {
            return Err(e);
        }
        written
            .into_iter()
            .map(|w| {
                let d = PyDict::new(py);
                d.set_item("shard", w.shard)?;
                d.set_item("samples", w.samples)?;
                d.set_item("bytes", w.bytes)?;
                Ok(d)
            })
            .collect()
    }

    /// Sample `k` in memory: {"height": float32 array, "mask": uint8 array or None,
    /// "shaded": uint8 array or None, "meta": dict (its JSON member)}.
    fn sample<'py>(&self, py: Python<'py>, k: i64) -> PyResult<Bound<'py, PyDict>> {
        let k = u64::try_from(k).map_err(|_| bad("sample", k, "a sample index ≥ 0"))?;
        let s = py.detach(|| self.inner.sample(k)).py()?;
        let (w, h, c) = (s.heights.width, s.heights.height, s.heights.channels);
        let d = PyDict::new(py);
        let heights = PyArray::from_vec(py, s.heights.data).reshape(fill_shape(h, w, c))?;
        d.set_item("height", heights)?;
        for (name, bytes) in [("mask", s.mask), ("shaded", s.shaded)] {
            match bytes {
                Some(b) => d.set_item(name, PyArray::from_vec(py, b).reshape([h, w])?)?,
                None => d.set_item(name, py.None())?,
            }
        }
        d.set_item("meta", json_to_py(py, &s.meta)?)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "surftile.Dataset({:?}, samples={}, shards={})",
            self.spec.display().to_string(),
            self.inner.samples(),
            self.inner.shards()
        )
    }
}
