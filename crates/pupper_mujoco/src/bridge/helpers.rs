//! Entry points that hold the interpreter: run a closure on a loaded model,
//! and call the Python package's helpers (plots, rendering, the viewer).

use crate::bridge::calls::PyCall;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use super::model::LoadedModel;
use super::python::{Mujoco, PyResultExt, cli_message, exception_name, python_message};
use super::warp::WarpPhysics;
use pupper_core::error::{Error, Result};
use pupper_core::plan::backend::Backend;
use pupper_core::plan::config::SweepConfig;
use pupper_core::robot::model::ModelSource;
use pupper_core::sim::physics::Physics;

/// Runs `f` with the imported `mujoco` and the model, floating-checked.
pub fn with_model<T>(
    source: &ModelSource,
    floating: bool,
    f: impl for<'py> FnOnce(&LoadedModel<'py>) -> Result<T>,
) -> Result<T> {
    Python::attach(|py| {
        let mj = Mujoco::import(py)?;
        let model = mj.load(source)?;
        let model = if floating { model.floating()? } else { model };
        f(&model)
    })
}

/// Runs `f` with the model a config runs on: floating, or for a response
/// run not `standing` hung in the air (base fixed, no contacts).
pub fn with_config_model<T>(
    cfg: &SweepConfig,
    f: impl for<'py> FnOnce(&LoadedModel<'py>) -> Result<T>,
) -> Result<T> {
    let suspended = cfg.experiment.plan().suspended();
    Python::attach(|py| {
        let mj = Mujoco::import(py)?;
        let model = mj
            .load_on(&cfg.model, suspended)?
            .with_integrator(cfg.integrator.map(|i| i.mj()))?
            .floating()?;
        f(&model)
    })
}

/// What steps a model's physics, as a backend picked at run time:
/// `as_ref` gives either as a [`Physics`].
pub enum Picked<'a, 'py> {
    /// MuJoCo's CPU batch: the model itself.
    Cpu(&'a LoadedModel<'py>),
    /// MuJoCo Warp over the model.
    Warp(WarpPhysics<'a, 'py>),
}

impl<'a> AsRef<dyn Physics + 'a> for Picked<'a, '_> {
    fn as_ref(&self) -> &(dyn Physics + 'a) {
        match self {
            Picked::Cpu(model) => *model,
            Picked::Warp(warp) => warp,
        }
    }
}

/// What steps `model`'s physics on `backend`: the model itself (MuJoCo's
/// CPU batch), or MuJoCo Warp over it (checked: installed, device there).
pub fn physics<'a, 'py>(model: &'a LoadedModel<'py>, backend: &Backend) -> Result<Picked<'a, 'py>> {
    Ok(match backend {
        Backend::Cpu => Picked::Cpu(model),
        Backend::Warp { device, .. } => Picked::Warp(WarpPhysics::new(model, device)?),
    })
}

/// Calls a function of our Python package (plots, rendering, the viewer)
/// with string arguments and keyword arguments (a JSON object, so numbers,
/// text and lists cross as themselves); returns its result as
/// strings (a path or a list of paths). `RenderUnavailable` and
/// `DisplayUnavailable` become one-line [`Error::Display`]s.
pub fn call_helper(
    call: &PyCall,
    args: &[String],
    kwargs: &serde_json::Value,
) -> Result<Vec<String>> {
    let (module, func) = (call.module, call.function);
    if !call.accepts(args.len(), kwargs) {
        return Err(Error::Internal(format!(
            "{} is called with {} arguments and keywords {kwargs}, not as bridge::calls says",
            call.name(),
            args.len()
        )));
    }
    Python::attach(|py| {
        Mujoco::import(py)?;
        let m = PyModule::import(py, module).map_err(|e| {
            Error::Mujoco(format!(
                "cannot import {module} ({}): run `make setup` to install pupper's Python package into the project venv",
                python_message(py, &e)
            ))
        })?;
        let kw: Bound<'_, PyDict> = PyModule::import(py, "json")
            .and_then(|j| j.getattr("loads"))
            .and_then(|loads| loads.call1((kwargs.to_string(),)))
            .and_then(|d| d.cast_into::<PyDict>().map_err(PyErr::from))
            .internal()?;
        let out = m
            .getattr(func)
            .and_then(|f| f.call(pyo3::types::PyTuple::new(py, args)?, Some(&kw)))
            .map_err(|e| {
                let kind = exception_name(py, &e);
                // the CLI's words where the core said it (`--kp`, not `kp=`)
                let msg = cli_message(py, &e);
                // Ctrl-C or SIGTERM inside the helper: what the CLI's own
                // stop gives, exit 130 and one line
                if e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py) {
                    return Error::Interrupted(msg);
                }
                if kind.ends_with("Unavailable") {
                    Error::Display(msg)
                } else if [
                    "TuneError",
                    "FitError",
                    "RecommendError",
                    "LogError",
                    "ConfigError",
                    "OutputError",
                    "GridError",
                    "ModelError",
                    "ModelNotFoundError",
                ]
                .contains(&kind.as_str())
                {
                    // bad input said by our Python package: one line, exit 2
                    Error::Config(msg)
                } else if e.is_instance_of::<pyo3::exceptions::PyOSError>(py) {
                    // a file or stream the helper could not use (a read-only
                    // folder, a full disk): the user's to fix, not a bug
                    Error::Output(os_error_line(py, &e))
                } else {
                    Error::Internal(format!("{module}.{func}: {kind}: {msg}"))
                }
            })?;
        if out.is_none() {
            return Ok(vec![]);
        }
        if !(out.is_instance_of::<PyList>() || out.is_instance_of::<pyo3::types::PyTuple>()) {
            return Ok(vec![shown(&out)]);
        }
        let items: Vec<Bound<'_, PyAny>> = out
            .try_iter()
            .internal()?
            .collect::<PyResult<_>>()
            .internal()?;
        Ok(items.iter().map(shown).collect())
    })
}

/// An `OSError` in one line: the file it names, the system's words, and
/// what to do where the cause says it (room on the disk, a place to write).
fn os_error_line(py: Python<'_>, e: &PyErr) -> String {
    let v = e.value(py);
    let get = |a: &str| v.getattr(a).ok().filter(|x| !x.is_none());
    let text = get("strerror")
        .and_then(|x| x.extract::<String>().ok())
        .unwrap_or_else(|| python_message(py, e));
    let file = get("filename").map(|f| shown(&f));
    let kind = get("errno")
        .and_then(|x| x.extract::<i32>().ok())
        .map(|n| std::io::Error::from_raw_os_error(n).kind());
    let fix = match kind {
        Some(std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded) => {
            "; free some space, or write elsewhere"
        }
        Some(std::io::ErrorKind::PermissionDenied | std::io::ErrorKind::ReadOnlyFilesystem) => {
            "; choose a place you can write to"
        }
        _ => "",
    };
    match file {
        Some(f) => format!("'{f}': {text}{fix}"),
        None => format!("{text}{fix}"),
    }
}

/// A helper's returned path as text: a path that is not UTF-8 (a str with
/// surrogate escapes) through its bytes, shown lossily, never an error.
fn shown(item: &Bound<'_, PyAny>) -> String {
    match item.extract::<std::path::PathBuf>() {
        Ok(p) => p.display().to_string(),
        Err(_) => item.to_string(),
    }
}
