//! Cells simulated for pictures: qpos recorded at a frame rate, nothing
//! written.

use std::path::PathBuf;

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use pupper_core::request::spec::SweepSpec;
use pupper_mujoco::api::{self, Recording};

use crate::convert::{grid_from, spec_from};
use crate::error::{InternalError, to_py};

/// A recording as a dict of Python objects (the stub's `Recording`).
fn recording_dict<'py>(py: Python<'py>, r: Recording, fps: f64) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("fps", fps)?;
    let cell = &r.result.cell;
    d.set_item("index", cell.index)?;
    d.set_item("id", &cell.id)?;
    d.set_item("name", &cell.name)?;
    let values = PyDict::new(py);
    for (axis, v) in &cell.values {
        if *axis == pupper_core::plan::grid::Axis::Variant {
            values.set_item(axis.name(), axis.text(*v))?;
        } else {
            values.set_item(axis.name(), v)?;
        }
    }
    d.set_item("values", values)?;
    let s = &r.setup;
    let setup = PyDict::new(py);
    setup.set_item("kp", s.kp.clone())?;
    setup.set_item("kd", s.kd.clone())?;
    setup.set_item("max_torque", s.max_torque)?;
    setup.set_item("push_force", s.push_force.to_vec())?;
    setup.set_item("friction", s.friction)?;
    setup.set_item("timestep", s.timestep)?;
    setup.set_item("leg_scale", s.leg_scale)?;
    setup.set_item("torso_mass_scale", s.torso_mass_scale)?;
    d.set_item("setup", setup)?;
    let m = &r.result.metrics;
    d.set_item("status", m.status.as_str())?;
    d.set_item("event_time", m.event_time)?;
    d.set_item("model", r.model)?;
    let frames = r
        .result
        .frames
        .ok_or_else(|| InternalError::new_err("a recording came back without frames"))?;
    let n = frames.len();
    d.set_item("times", PyArray1::from_vec(py, frames.times))?;
    d.set_item(
        "qpos",
        PyArray1::from_vec(py, frames.qpos).reshape([n, frames.nq])?,
    )?;
    d.set_item("pushing", PyArray1::from_vec(py, frames.pushing))?;
    Ok(d)
}

/// Simulates every cell of a sweep (same keywords as `sweep`, nothing
/// written) recording qpos at `fps`; returns one `Recording` per cell.
#[pyfunction]
#[pyo3(signature = (grid=None, *, preset=None, fps=25.0, **options))]
pub(crate) fn record<'py>(
    py: Python<'py>,
    grid: Option<&Bound<'py, PyAny>>,
    preset: Option<String>,
    fps: f64,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let spec = SweepSpec {
        grid: grid_from(grid, preset)?,
        ..spec_from(py, options)?
    };
    let sweep = spec.build().map_err(to_py)?;
    let cells = sweep.config.grid.cells();
    api::record(&sweep.config, &cells, fps)
        .map_err(to_py)?
        .into_iter()
        .map(|r| recording_dict(py, r, fps))
        .collect()
}

/// [`record`] for cells of a run directory, by their `index` column.
#[pyfunction]
#[pyo3(signature = (run_dir, cells, fps=25.0))]
pub(crate) fn record_run(
    py: Python<'_>,
    run_dir: PathBuf,
    cells: Vec<usize>,
    fps: f64,
) -> PyResult<Vec<Bound<'_, PyDict>>> {
    api::record_run(&run_dir, &cells, fps)
        .map_err(to_py)?
        .into_iter()
        .map(|r| recording_dict(py, r, fps))
        .collect()
}

/// A response run's excited joints at every physics step for cells of its
/// directory, by their `index` column: a dict per (cell, joint) of replicate
/// 0 with `index`, `id`, `joint`, `t` (s after the excitation starts) and
/// `angle` (rad) as arrays.
#[pyfunction]
#[pyo3(signature = (run_dir, cells))]
pub(crate) fn step_traces(
    py: Python<'_>,
    run_dir: PathBuf,
    cells: Vec<usize>,
) -> PyResult<Vec<Bound<'_, PyDict>>> {
    api::step_traces(&run_dir, &cells)
        .map_err(to_py)?
        .into_iter()
        .map(|s| {
            let d = PyDict::new(py);
            d.set_item("index", s.index)?;
            d.set_item("id", s.id)?;
            d.set_item("joint", s.joint)?;
            d.set_item("t", PyArray1::from_vec(py, s.t))?;
            d.set_item("angle", PyArray1::from_vec(py, s.angle))?;
            Ok(d)
        })
        .collect()
}
