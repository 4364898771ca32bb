//! `pupper fit`'s replay through the servo firmware (its `_fit.replay`
//! calls this): the Rust core's firmware between the steps of a MuJoCo
//! batch the caller set up.

use numpy::{
    PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
};
use pyo3::prelude::*;

use pupper_core::error::Error;
use pupper_core::sim::replay::{Replay, ReplayMotor, ReplayServo};
use pupper_mujoco::bridge::replay::{RowLayout, replay_steps};

use crate::error::to_py;

fn flat(a: &PyReadonlyArray2<'_, f64>) -> Vec<f64> {
    a.as_array().iter().copied().collect()
}

fn cols(a: &PyReadonlyArray1<'_, i64>) -> PyResult<Vec<usize>> {
    a.as_array()
        .iter()
        .map(|&c| {
            usize::try_from(c)
                .map_err(|_| to_py(Error::Internal("replay: a negative column".into())))
        })
        .collect()
}

/// Steps `batch` (a `mujoco.batch.Batch`; `rows`, its state array, holds
/// each rollout's start) through the log's targets `control` (rollout,
/// sample, actuator), the firmware between the steps: each rollout's
/// `kp`, `kd`, command `delay`, feedback `latency`, torque `lag` (s) and
/// torque limit `peak` (rollout, actuator), the firmware's `rate`,
/// `filter`, encoder difference (`counts`) and `noload`, and the encoder
/// `noise` (rad, update × actuator) each rollout reads times its `sign`.
/// Returns each rollout's state after each step at the `record` columns
/// (rollout, step, column) and its sensed torque (rollout, step, actuator).
#[pyfunction]
#[pyo3(signature = (batch, rows, control, *, qpos, qvel, ctrl, record, kp, kd, delay, latency, lag, peak, timestep, rate=None, filter=None, counts=false, noload=None, noise=None, sign=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn firmware_replay<'py>(
    py: Python<'py>,
    batch: &Bound<'py, PyAny>,
    rows: &Bound<'py, PyArray2<f64>>,
    control: PyReadonlyArray3<'py, f64>,
    qpos: PyReadonlyArray1<'py, i64>,
    qvel: PyReadonlyArray1<'py, i64>,
    ctrl: PyReadonlyArray1<'py, i64>,
    record: PyReadonlyArray1<'py, i64>,
    kp: PyReadonlyArray2<'py, f64>,
    kd: PyReadonlyArray2<'py, f64>,
    delay: PyReadonlyArray2<'py, f64>,
    latency: PyReadonlyArray2<'py, f64>,
    lag: PyReadonlyArray2<'py, f64>,
    peak: PyReadonlyArray2<'py, f64>,
    timestep: f64,
    rate: Option<f64>,
    filter: Option<f64>,
    counts: bool,
    noload: Option<f64>,
    noise: Option<PyReadonlyArray2<'py, f64>>,
    sign: Option<PyReadonlyArray1<'py, f64>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let shape = control.as_array().shape().to_vec();
    let (nb, n, nu) = (shape[0], shape[1], shape[2]);
    let layout = RowLayout {
        qpos: cols(&qpos)?,
        qvel: cols(&qvel)?,
        ctrl: cols(&ctrl)?,
        record: cols(&record)?,
    };
    let servo = ReplayServo {
        kp: flat(&kp),
        kd: flat(&kd),
        delay: flat(&delay),
        latency: flat(&latency),
        lag: flat(&lag),
        peak: flat(&peak),
    };
    let noise = match (noise, sign) {
        (Some(d), Some(s)) => Some((flat(&d), s.as_array().to_vec())),
        (None, None) => None,
        _ => {
            return Err(to_py(Error::Internal(
                "replay: noise and sign go together".into(),
            )));
        }
    };
    let motor = ReplayMotor {
        rate,
        filter,
        counts,
        noload,
    };
    let mut replay = Replay::new(&motor, nb, nu, timestep, servo, noise).map_err(to_py)?;
    let targets: Vec<f64> = control.as_array().iter().copied().collect();
    let out = replay_steps(batch, rows, &layout, &targets, n, &mut replay).map_err(to_py)?;
    let nrec = layout.record.len();
    let state = PyArray1::from_vec(py, out.state).reshape([nb, n, nrec])?;
    let sensed = PyArray1::from_vec(py, out.sensed).reshape([nb, n, nu])?;
    Ok((state.into_any(), sensed.into_any()))
}
