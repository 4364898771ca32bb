//! `hold`: how firmly the gains hold the robot up under a load and against
//! a shove, as `pupper hold` runs it.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use pupper_core::plan::hold::{LOAD, RAMP, SHOVE, SHOVE_DURATION};
use pupper_core::request::hold::{self as request, HoldInput};
use pupper_core::results::best;

use super::sweep::{kind_spec, run_spec};
use crate::result::SweepResult;

/// `pupper_core.hold`: the hold experiment; `options` are the sweep
/// keywords (model, mode, kp, kd, seconds, pose, threads, ...). Writes
/// best.csv (the stiffest cell) into a run directory.
#[pyfunction]
#[pyo3(signature = (grid=None, *, out=None, progress=None, load=LOAD, ramp=RAMP, shove=SHOVE, shove_at=None, shove_duration=SHOVE_DURATION, **options))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn hold(
    py: Python<'_>,
    grid: Option<&Bound<'_, PyAny>>,
    out: Option<&Bound<'_, PyAny>>,
    progress: Option<Bound<'_, PyAny>>,
    load: f64,
    ramp: f64,
    shove: f64,
    shove_at: Option<f64>,
    shove_duration: f64,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<SweepResult> {
    let input = HoldInput {
        load,
        ramp,
        shove,
        shove_at,
        shove_duration,
    };
    let base = kind_spec(py, grid, out, options, request::seconds(&input))?;
    let spec = request::spec(base, &input);
    let rule = best::Rule::new(spec.experiment.plan().default_metric(), &[]);
    run_spec(py, spec, progress, "python: pupper_core.hold", Some(&rule))
}
