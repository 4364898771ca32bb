//! The `pupper` command and a Ray task's work, inside this interpreter.

use pyo3::prelude::*;

use pupper_mujoco::api;

use crate::error::to_py;

/// The `pupper` command inside this interpreter (the wheel's console
/// script): `argv` as `sys.argv`; returns the exit status.
#[pyfunction]
pub(crate) fn cli_main(py: Python<'_>, argv: Vec<std::ffi::OsString>) -> u8 {
    // The CLI attaches to the interpreter itself; let it run its long calls
    // without holding this frame's attachment.
    let _ = py;
    pupper_cli::main(argv, pupper_cli::Host::Interpreter)
}

/// A Ray task's work on a worker node (`pupper_core._ray.run_task`): the
/// task's cells of the job run here, on `threads` threads; the encoded
/// outcome (results, or why this node refused) goes back to the driver.
#[pyfunction]
pub(crate) fn _run_task<'py>(
    py: Python<'py>,
    job: &[u8],
    task: &[u8],
    threads: usize,
) -> PyResult<Bound<'py, pyo3::types::PyBytes>> {
    let out = api::run_task(job, task, threads).map_err(to_py)?;
    Ok(pyo3::types::PyBytes::new(py, &out))
}
