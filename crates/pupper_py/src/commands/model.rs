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

/// The servo loop of one joint from its reflected inertia alone (no model
/// loaded): the firmware `motor` with `sensing_delay` s of feedback latency
/// (the continuous loop), or with `fitted` a calibrated joint's (`gains`
/// on a calibrated model): its fitted servo (`lag`, `latency`: read as
/// torque mode and `pupper fit` read them, where `motor`'s lag= and
/// `sensing_delay` give none) as the sampled loop the simulation steps.
/// `damping`: the joint's viscous damping in the loop.
#[allow(clippy::too_many_arguments)]
fn servo_loop(
    inertia: f64,
    kp: f64,
    kd: f64,
    motor: Option<&str>,
    sensing_delay: Option<f64>,
    timestep: f64,
    damping: f64,
    lag: f64,
    latency: f64,
    fitted: bool,
) -> PyResult<pupper_core::math::margins::ServoLoop> {
    let good = |v: f64| v.is_finite() && v >= 0.0;
    if !(inertia.is_finite() && inertia > 0.0 && timestep.is_finite() && timestep > 0.0)
        || !(good(damping) && good(lag) && good(latency))
    {
        return Err(to_py(Error::Config(format!(
            "loop_margins(inertia={inertia}, timestep={timestep}, damping={damping}, lag={lag}, latency={latency}): give a positive inertia (kg·m²) and timestep (s), and a damping, lag and latency >= 0"
        ))));
    }
    // the spec and the sensing delay checked as `gains` checks them
    let plain =
        pupper_core::plan::motor::feedback_of(Some(motor.unwrap_or("")), sensing_delay, timestep)
            .map_err(to_py)?
            .unwrap_or_default();
    let m = pupper_core::plan::motor::Motor::parse(motor.unwrap_or("")).map_err(to_py)?;
    let fb = if fitted {
        pupper_core::plan::motor::fitted_feedback(&m, sensing_delay, timestep, lag, latency)
    } else {
        plain
    };
    Ok(fb.servo(inertia, damping, kp, kd))
}

/// The phase (deg) and gain (dB) margins of one joint's servo loop, as
/// `gains(..., motor=, sensing_delay=)` computes them, from the joint's
/// reflected inertia alone (no model loaded): what `recommend` checks for
/// every candidate and drawn robot. `damping`, `lag` and `latency`: a
/// calibrated joint's fitted damping and servo times; `fitted`: its loop is
/// a calibrated servo's (the sampled loop, as `gains` closes it on a
/// calibrated model).
#[pyfunction]
#[pyo3(signature = (inertia, kp, kd, *, motor=None, sensing_delay=None, timestep, damping=0.0, lag=0.0, latency=0.0, fitted=false))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn loop_margins(
    inertia: f64,
    kp: f64,
    kd: f64,
    motor: Option<String>,
    sensing_delay: Option<f64>,
    timestep: f64,
    damping: f64,
    lag: f64,
    latency: f64,
    fitted: bool,
) -> PyResult<(f64, f64)> {
    let l = servo_loop(
        inertia,
        kp,
        kd,
        motor.as_deref(),
        sensing_delay,
        timestep,
        damping,
        lag,
        latency,
        fitted,
    )?;
    Ok(l.margins()
        .map_or((f64::NAN, f64::NAN), |m| (m.phase_deg, m.gain_db)))
}

/// The closed loop of the same joint (`loop_margins`' keywords) from its
/// target, the target `command_delay` s late: per frequency in `hz`, its
/// gain (dB) and phase (deg, continuous from 0 at low frequency), what a
/// sine through the simulated joint measures where the joint is linear.
#[pyfunction]
#[pyo3(signature = (inertia, kp, kd, hz, *, motor=None, sensing_delay=None, timestep, damping=0.0, lag=0.0, latency=0.0, command_delay=0.0, fitted=false))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn loop_response(
    inertia: f64,
    kp: f64,
    kd: f64,
    hz: Vec<f64>,
    motor: Option<String>,
    sensing_delay: Option<f64>,
    timestep: f64,
    damping: f64,
    lag: f64,
    latency: f64,
    command_delay: f64,
    fitted: bool,
) -> PyResult<Vec<(f64, f64)>> {
    let l = servo_loop(
        inertia,
        kp,
        kd,
        motor.as_deref(),
        sensing_delay,
        timestep,
        damping,
        lag,
        latency,
        fitted,
    )?;
    let mut last = 0.0_f64;
    Ok(hz
        .iter()
        .map(|&f| {
            let h = l.closed_loop(2.0 * std::f64::consts::PI * f, command_delay);
            // unwrapped: each phase within half a turn of the previous one
            let mut p = h.arg().to_degrees();
            p -= 360.0 * ((p - last) / 360.0).round();
            last = p;
            (20.0 * h.norm().log10(), p)
        })
        .collect())
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

/// The calibrated model of a `pupper fit` run directory, the run checked
/// against its manifest first (kind, files, their SHA-256): what
/// `recommend --from-fit` and `gains --from-fit` read.
#[pyfunction]
pub(crate) fn fit_run(dir: PathBuf) -> PyResult<PathBuf> {
    pupper_core::results::fit_run::calibrated(&dir).map_err(to_py)
}
