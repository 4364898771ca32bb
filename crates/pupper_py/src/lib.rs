//! The `#[pymodule]` behind `import pupper_core` (as `pupper_core._native`):
//! a thin layer that turns Python arguments into the same Rust calls the CLI
//! makes, and Rust errors into `PupperError` subclasses. Results come back
//! as Python objects: a `SweepResult` with numpy columns, dicts of plain
//! values for reports, numpy arrays for recorded states.
//!
//! Where things are: `error` (the exceptions), `convert` (Python values
//! into the Rust request), `progress` (callbacks, Ctrl-C, the exit),
//! `result` (`SweepResult`), `commands` (the functions).

mod commands;
mod convert;
mod error;
mod progress;
mod result;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use commands::{cli, hold, lab, model, record, replay, response, runs, sweep};
use error::{
    ClusterError, ConfigError, DisplayError, GridError, InternalError, ModelError, MujocoError,
    OutputError, PupperError,
};

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", pupper_core::VERSION)?;
    m.add("METRICS", pupper_core::sim::metrics::METRIC_NAMES.to_vec())?;
    m.add("VARIANTS", pupper_core::request::lab::VARIANTS.to_vec())?;
    m.add("DEFAULT_METRIC", pupper_core::results::best::DEFAULT_METRIC)?;
    m.add("DIP_AFTER", pupper_core::math::stats::DIP_AFTER)?;
    m.add("MAX_SATURATION", pupper_core::results::best::MAX_SATURATION)?;
    m.add("PupperError", py.get_type::<PupperError>())?;
    m.add("GridError", py.get_type::<GridError>())?;
    m.add("ConfigError", py.get_type::<ConfigError>())?;
    m.add("ModelError", py.get_type::<ModelError>())?;
    m.add("MujocoError", py.get_type::<MujocoError>())?;
    m.add("OutputError", py.get_type::<OutputError>())?;
    m.add("DisplayError", py.get_type::<DisplayError>())?;
    m.add("ClusterError", py.get_type::<ClusterError>())?;
    m.add("InternalError", py.get_type::<InternalError>())?;
    let builtins = PyModule::import(py, "builtins")?;
    for (name, family, builtin, doc) in error::DUAL_ERRORS {
        let bases = PyTuple::new(py, [m.getattr(family)?, builtins.getattr(builtin)?])?;
        let ns = PyDict::new(py);
        ns.set_item("__doc__", doc)?;
        ns.set_item("__module__", "pupper_core")?;
        m.add(name, builtins.getattr("type")?.call1((name, bases, ns))?)?;
    }
    m.add_function(wrap_pyfunction!(model::info, m)?)?;
    m.add_function(wrap_pyfunction!(model::stand, m)?)?;
    m.add_function(wrap_pyfunction!(model::stance, m)?)?;
    m.add_function(wrap_pyfunction!(model::pose, m)?)?;
    m.add_function(wrap_pyfunction!(model::gains, m)?)?;
    m.add_function(wrap_pyfunction!(model::loop_margins, m)?)?;
    m.add_function(wrap_pyfunction!(model::loop_response, m)?)?;
    m.add_function(wrap_pyfunction!(model::fit_run, m)?)?;
    m.add_function(wrap_pyfunction!(replay::firmware_replay, m)?)?;
    m.add_function(wrap_pyfunction!(progress::_shutdown, m)?)?;
    m.add_function(wrap_pyfunction!(runs::best_rows, m)?)?;
    m.add_function(wrap_pyfunction!(result::_result_from_state, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::sweep, m)?)?;
    m.add_function(wrap_pyfunction!(runs::read_manifest, m)?)?;
    m.add_function(wrap_pyfunction!(commands::rundir::lock_run, m)?)?;
    m.add_function(wrap_pyfunction!(commands::rundir::publish, m)?)?;
    m.add_function(wrap_pyfunction!(commands::rundir::write_manifest, m)?)?;
    m.add_class::<commands::rundir::RunLock>()?;
    m.add_function(wrap_pyfunction!(runs::clear_run, m)?)?;
    m.add_function(wrap_pyfunction!(runs::check_kind, m)?)?;
    m.add_function(wrap_pyfunction!(runs::load_run, m)?)?;
    m.add_function(wrap_pyfunction!(runs::merge, m)?)?;
    m.add_function(wrap_pyfunction!(lab::lab, m)?)?;
    m.add_function(wrap_pyfunction!(response::response, m)?)?;
    m.add_function(wrap_pyfunction!(hold::hold, m)?)?;
    m.add_function(wrap_pyfunction!(commands::walk::walk, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::check_axes, m)?)?;
    m.add_class::<result::SweepResult>()?;
    m.add_function(wrap_pyfunction!(record::record, m)?)?;
    m.add_function(wrap_pyfunction!(record::record_run, m)?)?;
    m.add_function(wrap_pyfunction!(record::step_traces, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::sweep_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(commands::kind_defaults, m)?)?;
    m.add(
        "KINDS",
        pupper_core::plan::experiment::Experiment::KINDS.to_vec(),
    )?;
    m.add_function(wrap_pyfunction!(model::builtin_model, m)?)?;
    m.add_function(wrap_pyfunction!(cli::cli_main, m)?)?;
    m.add_function(wrap_pyfunction!(cli::_run_task, m)?)?;
    Ok(())
}
