//! The `#[pymodule]` behind `import pupper_core` (as `pupper_core._native`):
//! a thin layer that turns Python arguments into the same Rust calls the CLI
//! makes, and Rust errors into `PupperError` subclasses. Results cross as
//! JSON text; the Python package decodes them.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt};
use pyo3::prelude::*;

use pupper_core::error::{Error, ErrorKind};
use pupper_core::experiment::{Defaults, Hooks, RunOptions, SweepConfig};
use pupper_core::grid::{Axis, AxisValues, Grid};
use pupper_core::model::ModelSource;
use pupper_core::output::{self, Existing};
use pupper_core::physics::Mode;
use pupper_core::schedule::{InitialState, Push, Schedule, SineForce};
use pupper_mujoco::api::{self, SweepRequest, SweepUi};

create_exception!(
    pupper_core,
    PupperError,
    PyException,
    "Base class of pupper's errors."
);
create_exception!(
    pupper_core,
    GridError,
    PupperError,
    "A bad grid: unknown axis, bad values, too many cells."
);
create_exception!(
    pupper_core,
    ConfigError,
    PupperError,
    "A bad schedule, pose, gain or option."
);
create_exception!(
    pupper_core,
    ModelError,
    PupperError,
    "A model that is missing, unreadable, invalid or unsuitable."
);
create_exception!(
    pupper_core,
    MujocoError,
    PupperError,
    "The mujoco package is missing or the wrong version."
);
create_exception!(
    pupper_core,
    OutputError,
    PupperError,
    "The run directory exists, or a resume does not match."
);
create_exception!(
    pupper_core,
    DisplayError,
    PupperError,
    "Rendering or a viewer is not possible here."
);
create_exception!(
    pupper_core,
    InternalError,
    PupperError,
    "A bug in pupper or MuJoCo."
);

fn to_py(e: Error) -> PyErr {
    let msg = e.to_string();
    match e.kind() {
        ErrorKind::Grid => GridError::new_err(msg),
        ErrorKind::Config => ConfigError::new_err(msg),
        ErrorKind::Model => ModelError::new_err(msg),
        ErrorKind::Mujoco => MujocoError::new_err(msg),
        ErrorKind::Output => OutputError::new_err(msg),
        ErrorKind::Interrupted => PyKeyboardInterrupt::new_err(msg),
        ErrorKind::Display => DisplayError::new_err(msg),
        ErrorKind::Internal => InternalError::new_err(msg),
    }
}

fn json<T: serde::Serialize>(v: &T) -> PyResult<String> {
    serde_json::to_string(v).map_err(|e| InternalError::new_err(e.to_string()))
}

fn mode(text: &str) -> PyResult<Mode> {
    match text {
        "servo" => Ok(Mode::Servo),
        "torque" => Ok(Mode::Torque),
        _ => Err(ConfigError::new_err(format!(
            "mode '{text}' is unknown: use 'servo' or 'torque'"
        ))),
    }
}

fn initial(keyframe: &str, pose: Option<Vec<f64>>) -> InitialState {
    match pose {
        Some(p) => InitialState::Pose(p),
        None => InitialState::Keyframe(keyframe.to_string()),
    }
}

/// Model info as JSON (what `pupper info --json` prints).
#[pyfunction]
#[pyo3(signature = (model="pupper_v3"))]
fn info(model: &str) -> PyResult<String> {
    let source = ModelSource::parse(model).map_err(to_py)?;
    json(&api::info(&source).map_err(to_py)?)
}

/// Stand report as JSON (what `pupper stand --json` prints).
#[pyfunction]
#[pyo3(signature = (model="pupper_v3", seconds=10.0, kp=5.0, kd=0.1, keyframe="home", pose=None, mode="servo"))]
fn stand(
    model: &str,
    seconds: f64,
    kp: f64,
    kd: f64,
    keyframe: &str,
    pose: Option<Vec<f64>>,
    mode: &str,
) -> PyResult<String> {
    let source = ModelSource::parse(model).map_err(to_py)?;
    for (name, v) in [("kp", kp), ("kd", kd)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(ConfigError::new_err(format!(
                "{name} {v} is negative or not finite: gains must be >= 0"
            )));
        }
    }
    let r = api::stand(
        &source,
        seconds,
        kp,
        kd,
        initial(keyframe, pose),
        self::mode(mode)?,
    )
    .map_err(to_py)?;
    json(&r)
}

/// Progress to a Python callable, throttled; Ctrl-C through check_signals.
struct PyUi<'py> {
    py: Python<'py>,
    callback: Option<Bound<'py, PyAny>>,
    done: u64,
    total: u64,
    last: Instant,
    interrupt: Option<PyErr>,
    failed: Option<PyErr>,
}

impl SweepUi for PyUi<'_> {
    fn start(&mut self, _cells: usize, steps: u64) {
        self.total = steps;
        self.report();
    }
    fn finish(&mut self) {
        self.done = self.total;
        self.report();
    }
    fn hooks(&mut self) -> &mut dyn Hooks {
        self
    }
}

impl PyUi<'_> {
    fn report(&mut self) {
        if let Some(cb) = &self.callback
            && let Err(e) = cb.call1((self.done, self.total))
        {
            self.failed.get_or_insert(e);
        }
        self.last = Instant::now();
    }
}

impl Hooks for PyUi<'_> {
    fn progress(&mut self, steps: u64) {
        self.done += steps;
        if self.last.elapsed() > Duration::from_millis(200) {
            self.report();
        }
    }
    fn should_stop(&mut self) -> bool {
        if self.failed.is_some() {
            return true;
        }
        if let Err(e) = self.py.check_signals() {
            self.interrupt = Some(e);
            return true;
        }
        false
    }
}

/// Runs a sweep; returns the summary table (and traces) as JSON.
///
/// `axes` is a list of (axis, values); `specs` the CLI's `AXIS=VALUES`
/// strings. On Ctrl-C the finished chunks are kept (and written when `out`
/// is given) and KeyboardInterrupt is raised.
#[pyfunction]
#[pyo3(signature = (
    axes=None, specs=None, preset=None, model="pupper_v3", mode="servo", seconds=10.0,
    kp=5.0, kd=0.1, max_torque=3.0, push=true, push_force=-25.0, push_at=2.0,
    push_duration=0.25, sine=None, keyframe="home", pose=None, trace_every=0,
    threads=0, chunk_cells=256, max_cells=pupper_core::grid::DEFAULT_MAX_CELLS,
    out=None, force=false, resume=false, progress=None,
))]
#[allow(clippy::too_many_arguments)]
fn sweep(
    py: Python<'_>,
    axes: Option<Vec<(String, Vec<f64>)>>,
    specs: Option<Vec<String>>,
    preset: Option<String>,
    model: &str,
    mode: &str,
    seconds: f64,
    kp: f64,
    kd: f64,
    max_torque: f64,
    push: bool,
    push_force: f64,
    push_at: f64,
    push_duration: f64,
    sine: Option<(f64, f64)>,
    keyframe: &str,
    pose: Option<Vec<f64>>,
    trace_every: usize,
    threads: usize,
    chunk_cells: usize,
    max_cells: usize,
    out: Option<PathBuf>,
    force: bool,
    resume: bool,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<String> {
    let grid = match (preset, axes, specs) {
        (Some(p), None, None) => Grid::preset(&p),
        (None, Some(a), None) => a
            .into_iter()
            .map(|(name, values)| AxisValues::new(Axis::parse(&name)?, values))
            .collect::<pupper_core::Result<Vec<_>>>()
            .and_then(Grid::from_axes),
        (None, None, Some(s)) => Grid::parse(&s),
        (None, None, None) => Ok(Grid::default()),
        _ => Err(Error::Grid(
            "give one of a grid dict, grid strings or a preset, not several".into(),
        )),
    }
    .map_err(to_py)?;
    let config = SweepConfig {
        model: ModelSource::parse(model).map_err(to_py)?,
        grid,
        schedule: Schedule {
            duration: seconds,
            initial: initial(keyframe, pose),
            push: push.then(|| Push {
                start: push_at,
                duration: push_duration,
                force: [0.0, 0.0, push_force],
                body: String::new(),
            }),
            sine: sine.map(|(amplitude, frequency)| SineForce {
                amplitude,
                frequency,
                axis: [0.0, 0.0, 1.0],
            }),
            trace_every,
            ..Schedule::default()
        },
        mode: self::mode(mode)?,
        defaults: Defaults { kp, kd, max_torque },
    };
    let existing = match (resume, force) {
        (true, _) => Existing::Resume,
        (false, true) => Existing::Overwrite,
        (false, false) => Existing::Refuse,
    };
    let req = SweepRequest {
        config,
        options: RunOptions {
            threads,
            chunk_cells: chunk_cells.max(1),
            ..RunOptions::default()
        },
        out,
        existing,
        max_cells,
        command: vec!["python: pupper_core.sweep".into()],
    };
    let mut ui = PyUi {
        py,
        callback: progress,
        done: 0,
        total: 0,
        last: Instant::now(),
        interrupt: None,
        failed: None,
    };
    let outcome = api::run_sweep(&req, &mut ui).map_err(to_py)?;
    if let Some(e) = ui.failed {
        return Err(e);
    }
    if let Some(e) = ui.interrupt {
        return Err(e);
    }
    if !outcome.complete {
        // interrupted inside a MuJoCo call: finished chunks are kept
        return Err(PyKeyboardInterrupt::new_err(
            "sweep interrupted; finished cells are kept (resume=True continues a run directory)",
        ));
    }
    json(&serde_json::json!({
        "header": outcome.header,
        "rows": outcome.rows,
        "traces": outcome.traces,
        "out": outcome.out,
        "complete": outcome.complete,
        "cells_total": outcome.cells_total,
        "cells_run": outcome.cells_run,
        "wall_seconds": outcome.wall_seconds,
        "mujoco_version": outcome.mujoco_version,
        "config": req.config,
    }))
}

/// The manifest of a run directory, as JSON.
#[pyfunction]
fn read_manifest(dir: PathBuf) -> PyResult<String> {
    json(&output::read_manifest(&dir).map_err(to_py)?)
}

/// Parses grid specs the CLI way; returns (axis, values) pairs.
#[pyfunction]
fn parse_grid(specs: Vec<String>) -> PyResult<Vec<(String, Vec<f64>)>> {
    let g = Grid::parse(&specs).map_err(to_py)?;
    Ok(g.axes
        .into_iter()
        .map(|a| (a.axis.name().to_string(), a.values))
        .collect())
}

/// The MJCF text of a built-in model (for rendering and viewers).
#[pyfunction]
fn builtin_xml(name: &str) -> PyResult<String> {
    ModelSource::Builtin(name.to_string())
        .builtin_xml()
        .map(String::from)
        .ok_or_else(|| {
            ModelError::new_err(format!(
                "no built-in model '{name}': use one of {}",
                pupper_core::model::BUILTIN_NAMES.join(", ")
            ))
        })
}

/// The `pupper` command inside this interpreter (the wheel's console
/// script): `argv` as `sys.argv`; returns the exit status.
#[pyfunction]
fn cli_main(py: Python<'_>, argv: Vec<std::ffi::OsString>) -> u8 {
    // The CLI attaches to the interpreter itself; let it run its long calls
    // without holding this frame's attachment.
    let _ = py;
    pupper_cli::main(argv, pupper_cli::Host::Interpreter)
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", pupper_core::VERSION)?;
    m.add("METRICS", pupper_core::metrics::METRIC_NAMES.to_vec())?;
    m.add("PupperError", py.get_type::<PupperError>())?;
    m.add("GridError", py.get_type::<GridError>())?;
    m.add("ConfigError", py.get_type::<ConfigError>())?;
    m.add("ModelError", py.get_type::<ModelError>())?;
    m.add("MujocoError", py.get_type::<MujocoError>())?;
    m.add("OutputError", py.get_type::<OutputError>())?;
    m.add("DisplayError", py.get_type::<DisplayError>())?;
    m.add("InternalError", py.get_type::<InternalError>())?;
    m.add_function(wrap_pyfunction!(info, m)?)?;
    m.add_function(wrap_pyfunction!(stand, m)?)?;
    m.add_function(wrap_pyfunction!(sweep, m)?)?;
    m.add_function(wrap_pyfunction!(read_manifest, m)?)?;
    m.add_function(wrap_pyfunction!(parse_grid, m)?)?;
    m.add_function(wrap_pyfunction!(builtin_xml, m)?)?;
    m.add_function(wrap_pyfunction!(cli_main, m)?)?;
    Ok(())
}
