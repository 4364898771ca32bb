//! The run directory's writing, lent to the kinds Python drives (fit,
//! tune, recommend): the lock, a file put in place, the manifest. One
//! implementation, the Rust core's, so every kind's directory is written
//! the same way.

use std::path::PathBuf;

use pyo3::exceptions::{PyOSError, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use pupper_core::error::Error;
use pupper_core::results::json::Doc;
use pupper_core::results::{files, kind_manifest, lock};

use crate::error::to_py;

/// A held run-directory lock (`pupper_core::results::lock`); `release()`
/// lets it go, as dropping it does.
#[pyclass(module = "pupper_core._native")]
pub(crate) struct RunLock(Option<lock::RunLock>);

#[pymethods]
impl RunLock {
    /// Lets the lock go; the lock file stays, naming nobody.
    fn release(&mut self) {
        self.0 = None;
    }
}

/// Takes `dir`'s lock (the directory must exist): `PupperError` of kind
/// `run_busy` naming the holder while another pupper writes there.
#[pyfunction]
pub(crate) fn lock_run(dir: PathBuf) -> PyResult<RunLock> {
    lock::RunLock::take(&dir)
        .map(|l| RunLock(Some(l)))
        .map_err(os_or_py)
}

/// Puts the finished temporary file `tmp` in place as `path`, flushed
/// (`pupper_core::results::files::publish`). A failed write is the
/// `OSError` it was, naming `path`; a `path` that is not a regular file
/// is `OutputError`.
#[pyfunction]
pub(crate) fn publish(tmp: PathBuf, path: PathBuf) -> PyResult<()> {
    files::publish(&tmp, &path).map_err(os_or_py)
}

/// Writes `dir/manifest.json`: the stamp every manifest starts with (the
/// kind, pupper's, MuJoCo's and Python's versions), then `body`'s fields.
#[pyfunction]
pub(crate) fn write_manifest(
    py: Python<'_>,
    dir: PathBuf,
    kind: &str,
    body: &Bound<'_, PyDict>,
) -> PyResult<()> {
    let stamp = kind_manifest::Stamp {
        mujoco_version: PyModule::import(py, "mujoco")?
            .getattr("__version__")?
            .extract()?,
        python: PyModule::import(py, "sys")?
            .getattr("executable")?
            .extract()?,
    };
    kind_manifest::write_manifest(&dir, kind, &stamp, doc_of(body.as_any())?).map_err(os_or_py)
}

/// A JSON-able Python value as a [`Doc`]: dicts (string keys, in order),
/// lists and tuples, strings, bools, ints, floats (non-finite kept), None.
fn doc_of(v: &Bound<'_, PyAny>) -> PyResult<Doc> {
    Ok(if v.is_none() {
        Doc::Null
    } else if let Ok(b) = v.cast::<PyBool>() {
        Doc::Bool(b.is_true())
    } else if v.is_instance_of::<PyInt>() {
        match v.extract::<i64>() {
            Ok(i) => Doc::Int(i),
            Err(_) => Doc::Uint(v.extract::<u64>()?),
        }
    } else if let Ok(f) = v.cast::<PyFloat>() {
        Doc::Float(f.value())
    } else if let Ok(s) = v.cast::<PyString>() {
        Doc::Text(text_of(s))
    } else if let Ok(d) = v.cast::<PyDict>() {
        let mut m = Vec::with_capacity(d.len());
        for (k, x) in d.iter() {
            let k = k.cast::<PyString>().map_err(|_| {
                PyTypeError::new_err(format!("a manifest's keys are strings, not {k:?}"))
            })?;
            m.push((text_of(k), doc_of(&x)?));
        }
        Doc::Map(m)
    } else if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        Doc::List(
            v.try_iter()?
                .map(|x| doc_of(&x?))
                .collect::<PyResult<_>>()?,
        )
    } else {
        return Err(PyTypeError::new_err(format!(
            "a manifest holds JSON's values, not {}",
            v.get_type().name()?
        )));
    })
}

/// A string as the manifest keeps it: a path's bytes that are not UTF-8
/// (Python's surrogate escapes) shown as U+FFFD, as a sweep's manifest
/// shows them.
fn text_of(s: &Bound<'_, PyString>) -> String {
    s.to_string_lossy().into_owned()
}

/// An I/O failure as the `OSError` Python's own writes raise; the rest as
/// pupper's errors.
fn os_or_py(e: Error) -> PyErr {
    match &e {
        Error::Io { path, source, .. } => match source.raw_os_error() {
            Some(errno) => Python::attach(|py| {
                let strerror = PyModule::import(py, "os")
                    .and_then(|os| os.getattr("strerror")?.call1((errno,))?.extract::<String>())
                    .unwrap_or_else(|_| source.to_string());
                PyOSError::new_err((errno, strerror, path.display().to_string()))
            }),
            None => to_py(e),
        },
        _ => to_py(e),
    }
}
