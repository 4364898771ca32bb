//! `response`: how each joint follows its target, as `pupper response`
//! runs it.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use pupper_core::request::response::{self as request, SignalInput};

use super::sweep::{kind_spec, run_spec};
use crate::convert::given;
use crate::error::to_py;
use crate::result::SweepResult;

/// `pupper_core.response`: the response experiment, as `pupper response`
/// runs it. `options` are the sweep keywords (model, mode, kp, kd, seconds,
/// pose, threads, replicates, ...); the signal comes in its own keywords.
#[pyfunction]
#[pyo3(signature = (grid=None, *, out=None, progress=None, signal="step".to_string(), amplitude=pupper_core::plan::excitation::AMPLITUDE, frequency=None, chirp=None, hold=request::DEFAULT_HOLD, joints=Vec::new(), standing=false, **options))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn response(
    py: Python<'_>,
    grid: Option<&Bound<'_, PyAny>>,
    out: Option<&Bound<'_, PyAny>>,
    progress: Option<Bound<'_, PyAny>>,
    signal: String,
    amplitude: f64,
    frequency: Option<f64>,
    chirp: Option<[f64; 2]>,
    hold: f64,
    joints: Vec<String>,
    standing: bool,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<SweepResult> {
    let base = kind_spec(py, grid, out, options, request::SECONDS)?;
    let input = SignalInput {
        kind: signal,
        amplitude,
        frequency,
        chirp,
    };
    let spec = request::spec(
        base,
        &input,
        hold,
        &joints,
        standing,
        given(options, "keyframe"),
    )
    .map_err(to_py)?;
    run_spec(py, spec, progress, "python: pupper_core.response", None)
}
