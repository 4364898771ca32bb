//! One model, no sweep: its facts, stand pose, gains, a stand, and the
//! compiled built-in model.

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::PyDict;

use pupper_core::error::Error;
use pupper_core::robot::model::ModelSource;
use pupper_mujoco::api;

use crate::convert::{spec_from, to_dict};
use crate::error::{ModelError, to_py};

/// Model info (what `pupper info --json` prints), as a dict.
#[pyfunction]
#[pyo3(signature = (model=PathBuf::from("pupper_v3"), variant="original"))]
pub(crate) fn info<'py>(
    py: Python<'py>,
    model: PathBuf,
    variant: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let source = ModelSource::parse(&model.to_string_lossy()).map_err(to_py)?;
    let body = pupper_core::robot::variant::variant(variant).map_err(to_py)?;
    to_dict(py, &api::info(&source, body).map_err(to_py)?)
}

/// The stand pose of a body (what `pupper pose --json` prints), as a dict.
#[pyfunction]
#[pyo3(signature = (model=PathBuf::from("pupper_v3"), variant="original", depth=None))]
pub(crate) fn pose<'py>(
    py: Python<'py>,
    model: PathBuf,
    variant: &str,
    depth: Option<f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let source = ModelSource::parse(&model.to_string_lossy()).map_err(to_py)?;
    let body = pupper_core::robot::variant::variant(variant).map_err(to_py)?;
    to_dict(py, &api::pose(&source, body, depth).map_err(to_py)?)
}

/// Gains for a bandwidth, or given gains' margins per joint (what `pupper
/// gains --json` prints), as a dict.
#[pyfunction]
#[pyo3(signature = (model=PathBuf::from("pupper_v3"), *, kp=None, kd=None, bandwidth=None, damping=0.7, pose=None, integrator=None, motor=None, sensing_delay=None))]
// a keyword per option, as Python calls it
#[allow(clippy::too_many_arguments)]
pub(crate) fn gains<'py>(
    py: Python<'py>,
    model: PathBuf,
    kp: Option<f64>,
    kd: Option<f64>,
    bandwidth: Option<f64>,
    damping: f64,
    pose: Option<Vec<f64>>,
    integrator: Option<String>,
    motor: Option<String>,
    sensing_delay: Option<f64>,
) -> PyResult<Bound<'py, PyAny>> {
    use pupper_core::robot::gains::Ask;
    let ask = match (bandwidth, kp, kd) {
        (Some(hz), None, None) => Ask::Bandwidth { hz, zeta: damping },
        (None, Some(kp), Some(kd)) => Ask::Gains { kp, kd },
        _ => {
            return Err(to_py(Error::Config(
                "gains() needs bandwidth=HZ (with damping=, default 0.7) or both kp= and kd="
                    .into(),
            )));
        }
    };
    let source = ModelSource::parse(&model.to_string_lossy()).map_err(to_py)?;
    let r = api::gains(
        &source,
        pose,
        ask,
        integrator.as_deref(),
        motor.as_deref(),
        sensing_delay,
    )
    .map_err(to_py)?;
    to_dict(py, &r)
}

/// The phase (deg) and gain (dB) margins of one joint's servo loop, as
/// `gains(..., motor=, sensing_delay=)` computes them, from the joint's
/// reflected inertia alone (no model loaded): what `recommend` checks for
/// every candidate and drawn robot.
#[pyfunction]
#[pyo3(signature = (inertia, kp, kd, *, motor=None, sensing_delay=None, timestep))]
pub(crate) fn loop_margins(
    inertia: f64,
    kp: f64,
    kd: f64,
    motor: Option<String>,
    sensing_delay: Option<f64>,
    timestep: f64,
) -> PyResult<(f64, f64)> {
    if !(inertia.is_finite() && inertia > 0.0 && timestep.is_finite() && timestep > 0.0) {
        return Err(to_py(Error::Config(format!(
            "loop_margins(inertia={inertia}, timestep={timestep}): give a positive inertia (kg·m²) and timestep (s)"
        ))));
    }
    let fb = pupper_core::plan::motor::feedback_of(
        Some(motor.as_deref().unwrap_or("")),
        sensing_delay,
        timestep,
    )
    .map_err(to_py)?
    .unwrap_or_default();
    Ok(fb
        .servo(inertia, 0.0, kp, kd)
        .margins()
        .map_or((f64::NAN, f64::NAN), |m| (m.phase_deg, m.gain_db)))
}

/// Stand report (what `pupper stand --json` prints), as a dict. Keyword
/// arguments are those of `sweep`; the grid and the push are ignored.
#[pyfunction]
#[pyo3(signature = (**options))]
pub(crate) fn stand<'py>(
    py: Python<'py>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let spec = spec_from(py, options)?;
    to_dict(py, &api::stand(&spec).map_err(to_py)?)
}

/// The stance height (m) a run of these options starts from: the base
/// height with the lowest foot on the floor in the start pose, what falls
/// are judged against. Keyword arguments are those of `sweep`.
#[pyfunction]
#[pyo3(signature = (**options))]
pub(crate) fn stance<'py>(py: Python<'py>, options: Option<&Bound<'py, PyDict>>) -> PyResult<f64> {
    let spec = spec_from(py, options)?;
    api::stance(&spec).map_err(to_py)
}

/// A built-in model compiled as the CLI compiles it, as a `mujoco.MjModel`
/// (for rendering, viewers and hand-written loops).
#[pyfunction]
pub(crate) fn builtin_model(name: &str) -> PyResult<Py<PyAny>> {
    let source = ModelSource::Builtin(name.to_string());
    if source.builtin().is_none() {
        return Err(ModelError::new_err(format!(
            "no built-in model '{name}': use one of {}",
            pupper_core::robot::model::BUILTIN_NAMES.join(", ")
        )));
    }
    api::compiled(&source).map_err(to_py)
}
