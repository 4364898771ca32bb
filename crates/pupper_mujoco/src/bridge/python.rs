//! Python and the `mujoco` package: importing it (and checking its
//! version), turning Python exceptions into typed errors, and `pupper doctor`.

use pyo3::prelude::*;

use pupper_core::error::{Error, Result};

/// The supported `mujoco` major version.
pub const MUJOCO_MAJOR: &str = "4.";

/// How to fix a missing or wrong `mujoco`, for every message that needs it.
pub(crate) const MUJOCO_FIX: &str = "run `make setup` in the pupper checkout (or `pip install 'mujoco==4.0.*'` in the Python that pupper uses; `pupper doctor` shows which)";

pub(crate) fn py_err(e: PyErr) -> Error {
    Python::attach(|py| {
        // Ctrl-C landing inside a MuJoCo call from a notebook; its words
        // kept (a stop handler's "fit stopped by SIGTERM: ...")
        if e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py) {
            let msg = python_message(py, &e);
            return Error::Interrupted(if msg.is_empty() {
                "KeyboardInterrupt".into()
            } else {
                msg
            });
        }
        Error::Internal(python_message(py, &e))
    })
}

/// A Python exception's message on one line (MuJoCo's XML errors span
/// several: the parse error, then the element and line number).
pub(crate) fn python_message(py: Python<'_>, e: &PyErr) -> String {
    let text = e.value(py).to_string();
    let mut out = String::new();
    for line in text.lines().map(str::trim).filter(|l| !l.is_empty()) {
        if !out.is_empty() {
            out.push_str(if out.ends_with(':') { " " } else { "; " });
        }
        out.push_str(line);
    }
    out
}

/// [`python_message`] in the command line's words: where the error, or one
/// it was raised from (its `__cause__` or `__context__`), came from the
/// Rust core, the module said it in Python's words (`give kp= and kd=`)
/// and kept the command line's as `cli_message`; the command-line words
/// replace them wherever the message quotes them.
pub(crate) fn cli_message(py: Python<'_>, e: &PyErr) -> String {
    let mut msg = python_message(py, e);
    let mut exc = Some(e.value(py).clone().into_any());
    // a chain is short; the bound guards against a cycle
    for _ in 0..8 {
        let Some(x) = exc.take() else { break };
        let cli = x
            .getattr("cli_message")
            .ok()
            .and_then(|c| c.extract::<String>().ok());
        if let (Some(cli), Ok(said)) = (cli, x.str().map(|s| s.to_string()))
            && !said.is_empty()
            && msg.contains(&said)
        {
            msg = msg.replace(&said, &cli);
        }
        exc = ["__cause__", "__context__"]
            .iter()
            .filter_map(|a| x.getattr(*a).ok())
            .find(|c| !c.is_none());
    }
    msg
}

/// The class name of a Python exception (`WarpUnavailable`, ...), for the
/// helpers that turn some of their own exceptions into user errors.
pub(crate) fn exception_name(py: Python<'_>, e: &PyErr) -> String {
    e.get_type(py)
        .name()
        .map(|n| n.to_string())
        .unwrap_or_default()
}

pub(crate) trait PyResultExt<T> {
    fn internal(self) -> Result<T>;
}

impl<T> PyResultExt<T> for PyResult<T> {
    fn internal(self) -> Result<T> {
        self.map_err(py_err)
    }
}

/// Where the interpreter is and what it has: `pupper doctor`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PythonReport {
    pub executable: String,
    pub version: String,
    pub prefix: String,
    pub base_prefix: String,
    pub mujoco: Option<String>,
    pub mujoco_path: Option<String>,
    pub numpy: Option<String>,
    pub problem: Option<String>,
    /// warp-lang and mujoco-warp versions, when installed (`--backend warp`).
    pub warp: Option<String>,
    /// The Warp devices seen, or why there are none.
    pub warp_devices: Vec<String>,
    pub warp_problem: Option<String>,
    /// Ray's version, when installed (`--ray`).
    pub ray: Option<String>,
}

pub fn doctor() -> Result<PythonReport> {
    Python::attach(|py| {
        let sys = PyModule::import(py, "sys").internal()?;
        let get = |n: &str| -> Result<String> {
            sys.getattr(n)
                .internal()?
                .str()
                .internal()
                .map(|s| s.to_string())
        };
        let mut report = PythonReport {
            executable: get("executable")?,
            version: get("version")?.lines().next().unwrap_or("").to_string(),
            prefix: get("prefix")?,
            base_prefix: get("base_prefix")?,
            mujoco: None,
            mujoco_path: None,
            numpy: None,
            problem: None,
            warp: None,
            warp_devices: Vec::new(),
            warp_problem: None,
            ray: None,
        };
        if let Ok(np) = PyModule::import(py, "numpy") {
            report.numpy = np
                .getattr("__version__")
                .and_then(|v| v.extract::<String>())
                .ok();
        }
        match Mujoco::import(py) {
            Ok(mj) => {
                report.mujoco = Some(mj.version.clone());
                report.mujoco_path = mj
                    .module
                    .getattr("__file__")
                    .and_then(|v| v.extract::<String>())
                    .ok();
            }
            Err(e) => report.problem = Some(e.to_string()),
        }
        if report.problem.is_none() {
            // the optional warp backend: versions and devices, or why not
            let warp = PyModule::import(py, "pupper_core._warp").and_then(|w| {
                let v = w.getattr("versions")?.call0()?;
                let text = format!(
                    "warp-lang {}, mujoco-warp {}",
                    v.get_item("warp")?,
                    v.get_item("mujoco_warp")?
                );
                let devices: Vec<String> = w.getattr("devices")?.call0()?.extract()?;
                Ok((text, devices))
            });
            match warp {
                Ok((v, d)) => {
                    report.warp = Some(v);
                    report.warp_devices = d;
                }
                Err(e) => report.warp_problem = Some(python_message(py, &e)),
            }
            report.ray = PyModule::import(py, "pupper_core._ray")
                .and_then(|r| r.getattr("version")?.call0()?.extract())
                .ok()
                .flatten();
        }
        Ok(report)
    })
}

/// The imported `mujoco` package.
#[derive(Clone)]
pub struct Mujoco<'py> {
    pub(crate) py: Python<'py>,
    pub(crate) module: Bound<'py, PyModule>,
    pub(crate) batch: Bound<'py, PyModule>,
    pub(crate) copy: Bound<'py, PyAny>,
    pub version: String,
}

impl<'py> Mujoco<'py> {
    pub fn import(py: Python<'py>) -> Result<Mujoco<'py>> {
        let executable = PyModule::import(py, "sys")
            .and_then(|s| s.getattr("executable"))
            .map(|e| e.to_string())
            .unwrap_or_default();
        let module = PyModule::import(py, "mujoco").map_err(|e| {
            Error::Mujoco(format!(
                "cannot import the Python package 'mujoco' in {executable} ({}): {MUJOCO_FIX}",
                python_message(py, &e)
            ))
        })?;
        let version: String = module
            .getattr("__version__")
            .and_then(|v| v.extract())
            .unwrap_or_else(|_| "unknown".into());
        if !version.starts_with(MUJOCO_MAJOR) {
            return Err(Error::Mujoco(format!(
                "pupper needs mujoco 4.x but {executable} has mujoco {version}: {MUJOCO_FIX}"
            )));
        }
        let batch = PyModule::import(py, "mujoco.batch").map_err(|e| {
            Error::Mujoco(format!(
                "mujoco {version} has no usable mujoco.batch ({}): {MUJOCO_FIX}",
                python_message(py, &e)
            ))
        })?;
        let copy = PyModule::import(py, "copy")
            .and_then(|c| c.getattr("copy"))
            .internal()?;
        Ok(Mujoco {
            py,
            module,
            batch,
            copy,
            version,
        })
    }
}
