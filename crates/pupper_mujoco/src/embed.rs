//! Starting CPython inside the `pupper` binary.
//!
//! The binary links the libpython it was built against (rpath set by the CLI's
//! build script). What it still needs is the project's virtual environment,
//! where `mujoco` lives, found with nothing activated: from any working
//! directory, in a fresh shell. CPython finds a venv from its executable
//! path (the `pyvenv.cfg` beside it), so we point `PYTHONEXECUTABLE` at the
//! venv's python before initialising. (`VIRTUAL_ENV` alone does nothing to
//! an embedded interpreter, and `PYTHONHOME` pointing at a venv breaks it.)

use std::path::{Path, PathBuf};

/// The interpreter the embedded Python should behave as, by precedence:
/// `$PUPPER_PYTHON`, an activated `$VIRTUAL_ENV`, the environment the binary
/// was built with, and `.venv` of the checkout the binary sits in.
pub fn find_python(built_with: Option<&str>) -> Option<PathBuf> {
    let exists = |p: &Path| p.is_file();
    if let Some(p) = std::env::var_os("PUPPER_PYTHON").map(PathBuf::from) {
        // explicit choice: used even if wrong, so the error names it
        return Some(p);
    }
    if let Some(v) = std::env::var_os("VIRTUAL_ENV").map(PathBuf::from) {
        let p = v.join("bin").join("python");
        if exists(&p) {
            return Some(p);
        }
    }
    if let Some(p) = built_with.map(PathBuf::from).filter(|p| exists(p)) {
        return Some(p);
    }
    let exe = std::env::current_exe().ok()?;
    exe.ancestors()
        .skip(1)
        .map(|d| d.join(".venv").join("bin").join("python"))
        .find(|p| exists(p))
}

/// Points the interpreter at `python`'s environment and starts it. Call once,
/// before any other Python use, on the main thread.
pub fn start(python: Option<&Path>) {
    if let Some(p) = python
        && std::env::var_os("PYTHONEXECUTABLE").is_none()
    {
        // SAFETY: called at the top of main, before any thread is spawned.
        unsafe { std::env::set_var("PYTHONEXECUTABLE", p) };
    }
    pyo3::Python::initialize();
}

/// Makes Python's `sys.stdout` flush at every newline, as Rust's does.
///
/// Off a terminal CPython buffers stdout in blocks while stderr goes out a
/// line at a time, so a Python-run command's table would reach a log file
/// (`2>&1 | tee`) after the warnings printed below it, and the order would
/// hang on `PYTHONUNBUFFERED` (issue 58). A command prints a few lines, so
/// flushing each costs nothing. Errors are ignored: a stdout that cannot be
/// reconfigured (replaced by the host) keeps its own behaviour.
pub fn line_buffered_stdout() {
    use pyo3::prelude::*;
    use pyo3::types::PyDict;
    Python::attach(|py| {
        let _ = (|| -> PyResult<()> {
            let stdout = py.import("sys")?.getattr("stdout")?;
            if stdout.is_none() || !stdout.hasattr("reconfigure")? {
                return Ok(());
            }
            let kw = PyDict::new(py);
            kw.set_item("line_buffering", true)?;
            stdout.call_method("reconfigure", (), Some(&kw))?;
            Ok(())
        })();
    });
}
