//! The `#[pymodule]` behind `import pupper_core` (as `pupper_core._native`):
//! a thin layer that turns Python arguments into the same Rust calls the CLI
//! makes, and Rust errors into `PupperError` subclasses. Results come back
//! as Python objects: a `SweepResult` with numpy columns, dicts of plain
//! values for reports, numpy arrays for recorded states.

mod result;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use numpy::{PyArray1, PyArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use pupper_core::error::{Error, ErrorKind};
use pupper_core::request::spec::{AxisInput, GridInput, SweepSpec};
use pupper_core::results::best;
use pupper_core::results::output;
use pupper_core::robot::model::ModelSource;
use pupper_core::sim::runner::Hooks;
use pupper_mujoco::api::{self, Recording, SweepRequest, SweepUi};

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
    ClusterError,
    PupperError,
    "Ray is missing, the cluster cannot be reached, or a node cannot run pupper."
);
create_exception!(
    pupper_core,
    InternalError,
    PupperError,
    "A bug in pupper or MuJoCo."
);

/// Errors that are also the builtin `OSError` subclass a user would catch
/// (the way polars raises `FileNotFoundError`): (name, family, builtin, doc).
const DUAL_ERRORS: [(&str, &str, &str, &str); 4] = [
    (
        "ModelNotFoundError",
        "ModelError",
        "FileNotFoundError",
        "A model file that does not exist.",
    ),
    (
        "RunNotFoundError",
        "OutputError",
        "FileNotFoundError",
        "A run directory, or a file in it, that does not exist.",
    ),
    (
        "RunExistsError",
        "OutputError",
        "FileExistsError",
        "The run directory exists; pass force=True or resume=True.",
    ),
    (
        "OutputPermissionError",
        "OutputError",
        "PermissionError",
        "The run directory cannot be written or read.",
    ),
];

/// The Python exception of a Rust error: the family's class (or its
/// `OSError` twin), with the stable `kind` code as an attribute.
pub(crate) fn to_py(e: Error) -> PyErr {
    let msg = pythonic(&e.to_string());
    let dual = match e.code() {
        "model_not_found" => Some("ModelNotFoundError"),
        "run_not_found" | "not_found" => Some("RunNotFoundError"),
        "run_exists" => Some("RunExistsError"),
        "permission" => Some("OutputPermissionError"),
        _ => None,
    };
    Python::attach(|py| {
        let dual = dual
            .and_then(|name| {
                PyModule::import(py, "pupper_core._native")
                    .and_then(|m| m.getattr(name))
                    .ok()
            })
            .and_then(|c| c.cast_into::<pyo3::types::PyType>().ok());
        let err = match dual {
            Some(cls) => PyErr::from_type(cls, msg),
            None => match e.kind() {
                ErrorKind::Grid => GridError::new_err(msg),
                ErrorKind::Config => ConfigError::new_err(msg),
                ErrorKind::Model => ModelError::new_err(msg),
                ErrorKind::Mujoco => MujocoError::new_err(msg),
                ErrorKind::Output => OutputError::new_err(msg),
                ErrorKind::Interrupted => PyKeyboardInterrupt::new_err(msg),
                ErrorKind::Display => DisplayError::new_err(msg),
                ErrorKind::Cluster => ClusterError::new_err(msg),
                ErrorKind::Internal => InternalError::new_err(msg),
            },
        };
        // an exception without the attribute is still raised, only plainer
        let _ = err.value(py).setattr("kind", e.code());
        err
    })
}

/// A message written for the command line, in Python's words: `--kp -1`
/// becomes `kp=-1`, `add --force` `add force=True`, `--no-push`
/// `push=False`, `--max-torque` `max_torque=`. Command lines quoted in it
/// (from `pupper` to the next `:` `;` or `,`) stay as they are.
pub(crate) fn pythonic(msg: &str) -> String {
    const SWITCHES: [(&str, &str); 4] = [
        ("force", "force=True"),
        ("resume", "resume=True"),
        ("trace", "trace=True"),
        ("no-push", "push=False"),
    ];
    const NAMED: [&str; 3] = ["model", "preset", "keyframe"];
    let words: Vec<&str> = msg.split(' ').collect();
    let mut out: Vec<String> = Vec::with_capacity(words.len());
    let mut quoted = false;
    let mut i = 0;
    while i < words.len() {
        let w = words[i];
        if w.trim_start_matches('`') == "pupper" {
            quoted = true;
        }
        let flag = w
            .strip_prefix("--")
            .filter(|f| f.chars().next().is_some_and(|c| c.is_ascii_lowercase()));
        match flag {
            Some(f) if !quoted => {
                let name: String = f
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                    .collect();
                let rest = &f[name.len()..];
                let key = name.replace('-', "_");
                // a flag that names a thing takes it as a string: `model="pupper_v3"`
                let named = words.get(i + 1).filter(|v| {
                    rest.is_empty()
                        && NAMED.contains(&name.as_str())
                        && v.trim_end_matches([',', ':', ';', ')']).chars().all(|c| {
                            c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '/')
                        })
                });
                if let Some(v) = named {
                    let bare = v.trim_end_matches([',', ':', ';', ')']);
                    out.push(format!("{key}=\"{bare}\"{}", &v[bare.len()..]));
                    i += 2;
                    continue;
                }
                let value = words.get(i + 1).filter(|v| {
                    rest.is_empty()
                        && v.trim_end_matches([',', ':', ';', ')'])
                            .parse::<f64>()
                            .is_ok()
                });
                match (SWITCHES.iter().find(|(s, _)| *s == name), value) {
                    (Some((_, py)), _) => out.push(format!("{py}{rest}")),
                    (None, Some(v)) => {
                        out.push(format!("{key}={v}"));
                        i += 1;
                    }
                    (None, None) => out.push(format!("{key}={rest}")),
                }
            }
            _ => out.push(w.to_string()),
        }
        if w.ends_with([':', ';', ',']) {
            quoted = false;
        }
        i += 1;
    }
    out.join(" ")
}

/// A serializable report as a dict of plain Python values.
fn to_dict<'py, T: serde::Serialize>(py: Python<'py>, v: &T) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(v).map_err(|e| InternalError::new_err(e.to_string()))?;
    PyModule::import(py, "json")?
        .getattr("loads")?
        .call1((text,))
}

/// The spec from Python keyword arguments: their names are the fields of
/// [`SweepSpec`] and what is not given keeps the spec's default. They cross
/// as JSON (floats round-trip exactly), so a wrong type names its keyword.
fn spec_from(py: Python<'_>, options: Option<&Bound<'_, PyDict>>) -> PyResult<SweepSpec> {
    let Some(options) = options else {
        return Ok(SweepSpec::default());
    };
    // a float that is not finite, named by its keyword (JSON cannot say which)
    for (k, v) in options.iter() {
        let bad = |x: f64| !x.is_finite();
        let nonfinite = match v.extract::<f64>() {
            Ok(x) => bad(x),
            Err(_) => v
                .extract::<Vec<f64>>()
                .is_ok_and(|xs| xs.iter().copied().any(bad)),
        };
        if nonfinite && !v.is_instance_of::<pyo3::types::PyBool>() {
            return Err(ConfigError::new_err(format!(
                "{k}={} is not a finite number: give {k} a finite value",
                v.repr()?
            )));
        }
    }
    let kw = PyDict::new(py);
    kw.set_item("allow_nan", false)?;
    // numpy's numbers and arrays (np.float32(60), np.array([...])) are the
    // plain values their tolist() gives
    let tolist = PyModule::import(py, "operator")?
        .getattr("methodcaller")?
        .call1(("tolist",))?;
    kw.set_item("default", tolist)?;
    let dumps = PyModule::import(py, "json")?.getattr("dumps")?;
    let mut fields = Vec::with_capacity(options.len());
    for (k, v) in options.iter() {
        let value: String = dumps
            .call((&v,), Some(&kw))
            .map_err(|_| {
                ConfigError::new_err(format!(
                    "{k}={} is not a plain value: give {k} a number, a string or a list of them",
                    v.repr().map(|r| r.to_string()).unwrap_or_default()
                ))
            })?
            .extract()?;
        let key: String = dumps.call1((k.str()?,))?.extract()?;
        fields.push(format!("{key}:{value}"));
    }
    let text = format!("{{{}}}", fields.join(","));
    let mut de = serde_json::Deserializer::from_str(&text);
    serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let what = e.inner().to_string();
        let what = what.split(" at line").next().unwrap_or_default();
        if what.contains("integer `-") && what.contains("expected u") {
            // a negative count: name the keyword and what it takes
            let got = what.split('`').nth(1).unwrap_or("it");
            return pyo3::exceptions::PyValueError::new_err(format!(
                "{} must be a whole number >= 0, not {got}",
                e.path()
            ));
        }
        PyTypeError::new_err(format!("{}: {what}", e.path()))
    })
}

/// A grid value: a number, never a bool (Python's `True` is an int 1, and
/// `kp=[True, False]` is a mistake, not kp 1 and 0).
fn number(x: &Bound<'_, PyAny>) -> Option<f64> {
    if x.is_instance_of::<pyo3::types::PyBool>() {
        return None;
    }
    x.extract::<f64>().ok()
}

/// A grid as Python gives it: a dict of axis -> values (numbers, or text
/// parsed as the CLI parses it), a list of `AXIS=VALUES` strings, or one.
fn grid_from(grid: Option<&Bound<'_, PyAny>>, preset: Option<String>) -> PyResult<GridInput> {
    let grid = match (grid, preset) {
        (Some(g), _) if g.is_none() => None,
        (g, None) => g,
        (None, Some(p)) => return Ok(GridInput::Preset(p)),
        (Some(_), Some(_)) => {
            return Err(GridError::new_err(
                "give a grid or a preset, not both: drop one of them",
            ));
        }
    };
    let Some(grid) = grid else {
        return Ok(GridInput::None);
    };
    if let Ok(text) = grid.extract::<String>() {
        return Ok(GridInput::Specs(vec![text]));
    }
    // a list of cells: [{"kp": 10, "kd": 0.5}, ...] (a "name" key names one)
    if let Ok(cells) = grid.extract::<Vec<Bound<'_, PyDict>>>()
        && !cells.is_empty()
    {
        let mut axes: Vec<String> = Vec::new();
        for (k, _) in cells[0].iter() {
            let k: String = k.str()?.to_string();
            if k != "name" {
                axes.push(k);
            }
        }
        let mut rows = Vec::with_capacity(cells.len());
        let mut names = Vec::new();
        for (i, c) in cells.iter().enumerate() {
            let mut row = Vec::with_capacity(axes.len());
            for a in &axes {
                let v = c.get_item(a)?.ok_or_else(|| {
                    GridError::new_err(format!(
                        "cell {i} has no '{a}': give every cell the same axes"
                    ))
                })?;
                row.push(number(&v).ok_or_else(|| {
                    GridError::new_err(format!("cell {i}'s '{a}' is not a number"))
                })?);
            }
            if c.len() != axes.len() + usize::from(c.contains("name")?) {
                return Err(GridError::new_err(format!(
                    "cell {i} has other axes than the first cell ({}): give every cell the same axes",
                    axes.join(", ")
                )));
            }
            if let Some(n) = c.get_item("name")? {
                names.push(n.str()?.to_string());
            }
            rows.push(row);
        }
        return Ok(GridInput::Cells { axes, rows, names });
    }
    if let Ok(dict) = grid.cast::<PyDict>() {
        let mut axes = Vec::with_capacity(dict.len());
        for (name, values) in dict.iter() {
            let name: String = name.str()?.to_string();
            let input = if let Ok(text) = values.extract::<String>() {
                AxisInput::Text(text)
            } else if let Ok(names) = values.extract::<Vec<String>>() {
                // names (the variant axis), parsed as the CLI parses them
                AxisInput::Text(names.join(","))
            } else if let Some(v) = number(&values) {
                AxisInput::Values(vec![v])
            } else {
                let items: Vec<Bound<'_, PyAny>> = values
                    .try_iter()
                    .and_then(|it| it.collect::<PyResult<_>>())
                    .map_err(|_| {
                        GridError::new_err(format!(
                            "grid axis '{name}' has values of type {}: give numbers, a list of numbers, or text like '10,30' or '1:120:16:log'",
                            values.get_type().name().map(|n| n.to_string()).unwrap_or_default()
                        ))
                    })?;
                let v = items
                    .iter()
                    .map(|x| {
                        number(x).ok_or_else(|| {
                            GridError::new_err(format!(
                                "grid axis '{name}' has a non-numeric value {}: use numbers like 10 or 0.5",
                                x.repr().map(|r| r.to_string()).unwrap_or_default()
                            ))
                        })
                    })
                    .collect::<PyResult<Vec<f64>>>()?;
                AxisInput::Values(v)
            };
            axes.push((name, input));
        }
        return Ok(GridInput::Axes(axes));
    }
    let specs: Vec<String> = grid.extract().map_err(|_| {
        GridError::new_err(
            "grid must be a dict {axis: values}, a list of 'AXIS=VALUES' strings, or one such string",
        )
    })?;
    Ok(GridInput::Specs(specs))
}

/// A run directory argument: `str` or `os.PathLike`, not empty.
fn out_from(out: Option<&Bound<'_, PyAny>>) -> PyResult<Option<PathBuf>> {
    let Some(out) = out.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    let is_path =
        out.is_instance_of::<pyo3::types::PyString>() || out.hasattr("__fspath__").unwrap_or(false);
    let path: Option<PathBuf> = if is_path { out.extract().ok() } else { None };
    match path {
        Some(p) if p.as_os_str().is_empty() => Err(OutputError::new_err(
            "out is an empty path: give a directory name, e.g. out='runs/my-sweep'",
        )),
        Some(p) => Ok(Some(p)),
        None => Err(PyTypeError::new_err(format!(
            "out must be a str or os.PathLike, not {}",
            out.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))),
    }
}

/// Model info (what `pupper info --json` prints), as a dict.
#[pyfunction]
#[pyo3(signature = (model=PathBuf::from("pupper_v3"), variant="original"))]
fn info<'py>(py: Python<'py>, model: PathBuf, variant: &str) -> PyResult<Bound<'py, PyAny>> {
    let source = ModelSource::parse(&model.to_string_lossy()).map_err(to_py)?;
    let body = pupper_core::robot::variant::variant(variant).map_err(to_py)?;
    to_dict(py, &api::info(&source, body).map_err(to_py)?)
}

/// The stand pose of a body (what `pupper pose --json` prints), as a dict.
#[pyfunction]
#[pyo3(signature = (model=PathBuf::from("pupper_v3"), variant="original", depth=None))]
fn pose<'py>(
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
#[pyo3(signature = (model=PathBuf::from("pupper_v3"), *, kp=None, kd=None, bandwidth=None, damping=0.7, pose=None))]
fn gains<'py>(
    py: Python<'py>,
    model: PathBuf,
    kp: Option<f64>,
    kd: Option<f64>,
    bandwidth: Option<f64>,
    damping: f64,
    pose: Option<Vec<f64>>,
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
    to_dict(py, &api::gains(&source, pose, ask).map_err(to_py)?)
}

/// Stand report (what `pupper stand --json` prints), as a dict. Keyword
/// arguments are those of `sweep`; the grid and the push are ignored.
#[pyfunction]
#[pyo3(signature = (**options))]
fn stand<'py>(
    py: Python<'py>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let spec = spec_from(py, options)?;
    to_dict(py, &api::stand(&spec).map_err(to_py)?)
}

/// Set when the interpreter exits (`_shutdown`, from an `atexit` hook): a
/// sweep still running in another thread then stops at its next check,
/// keeps what it finished, and leaves Rust before Python finalizes (a
/// daemon thread woken inside Rust after that would be torn down mid-call).
static SHUTDOWN: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);
/// Sweeps running now, in any thread.
static ACTIVE: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
/// The longest the exit waits for running sweeps to stop (s).
const SHUTDOWN_WAIT: f64 = 30.0;

/// Counts a running sweep while it lives.
struct Active;

impl Active {
    fn new() -> Active {
        ACTIVE.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        Active
    }
}

impl Drop for Active {
    fn drop(&mut self) {
        ACTIVE.fetch_sub(1, std::sync::atomic::Ordering::SeqCst);
    }
}

/// The interpreter is exiting: asks running sweeps to stop and waits (the
/// GIL released) until they have left Rust, at most `SHUTDOWN_WAIT` s.
#[pyfunction]
fn _shutdown(py: Python<'_>) {
    use std::sync::atomic::Ordering;
    SHUTDOWN.store(true, Ordering::SeqCst);
    let started = Instant::now();
    while ACTIVE.load(Ordering::SeqCst) > 0 && started.elapsed().as_secs_f64() < SHUTDOWN_WAIT {
        py.detach(|| std::thread::sleep(Duration::from_millis(10)));
    }
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
        if SHUTDOWN.load(std::sync::atomic::Ordering::SeqCst) {
            self.interrupt.get_or_insert_with(|| {
                PyKeyboardInterrupt::new_err(
                    "the interpreter is exiting: sweep stopped; finished cells are kept (resume=True continues a run directory)",
                )
            });
            return true;
        }
        if let Err(e) = self.py.check_signals() {
            self.interrupt = Some(e);
            return true;
        }
        false
    }
}

/// Runs a sweep; returns its table as a `SweepResult`.
///
/// `grid`: a dict, `AXIS=VALUES` strings or one string; other keyword
/// arguments are the fields of the Rust `SweepSpec`. On Ctrl-C the finished
/// chunks are kept (and written when `out` is given) and KeyboardInterrupt
/// is raised.
#[pyfunction]
#[pyo3(signature = (grid=None, *, preset=None, out=None, progress=None, **options))]
fn sweep(
    py: Python<'_>,
    grid: Option<&Bound<'_, PyAny>>,
    preset: Option<String>,
    out: Option<&Bound<'_, PyAny>>,
    progress: Option<Bound<'_, PyAny>>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<result::SweepResult> {
    let spec = SweepSpec {
        grid: grid_from(grid, preset)?,
        out: out_from(out)?,
        ..spec_from(py, options)?
    };
    run_spec(py, spec, progress, "python: pupper_core.sweep", None)
}

/// Checks grid axis names as `--grid` does (GridError naming the known
/// axes); what a search checks before it writes anything.
#[pyfunction]
fn check_axes(names: Vec<String>) -> PyResult<()> {
    for n in names {
        pupper_core::plan::grid::Axis::parse(&n).map_err(to_py)?;
    }
    Ok(())
}

/// `pupper_core.response`: the response experiment, as `pupper response`
/// runs it. `options` are the sweep keywords (model, mode, kp, kd, seconds,
/// pose, threads, replicates, ...); the signal comes in its own keywords.
#[pyfunction]
#[pyo3(signature = (grid=None, *, out=None, progress=None, signal="step".to_string(), amplitude=pupper_core::plan::excitation::AMPLITUDE, frequency=None, chirp=None, hold=pupper_core::request::response::DEFAULT_HOLD, joints=Vec::new(), standing=false, **options))]
#[allow(clippy::too_many_arguments)]
fn response(
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
) -> PyResult<result::SweepResult> {
    let given = |k: &str| options.is_some_and(|o| o.contains(k).unwrap_or(false));
    let mut base = SweepSpec {
        grid: grid_from(grid, None)?,
        out: out_from(out)?,
        ..spec_from(py, options)?
    };
    if !given("seconds") {
        base.seconds = pupper_core::request::response::SECONDS;
    }
    let input = pupper_core::request::response::SignalInput {
        kind: signal,
        amplitude,
        frequency,
        chirp,
    };
    let spec = pupper_core::request::response::spec(
        base,
        &input,
        hold,
        &joints,
        standing,
        given("keyframe"),
    )
    .map_err(to_py)?;
    run_spec(py, spec, progress, "python: pupper_core.response", None)
}

/// Runs a spec with Python progress and Ctrl-C; writes best.csv by `rule`.
fn run_spec(
    py: Python<'_>,
    spec: SweepSpec,
    progress: Option<Bound<'_, PyAny>>,
    command: &str,
    rule: Option<&best::Rule>,
) -> PyResult<result::SweepResult> {
    let sweep = spec.build().map_err(to_py)?;
    if let Some(rule) = rule {
        best::best(&output::header_of(&sweep.config), &[], rule).map_err(to_py)?;
    }
    let _active = Active::new();
    if SHUTDOWN.load(std::sync::atomic::Ordering::SeqCst) {
        return Err(PyKeyboardInterrupt::new_err(
            "the interpreter is exiting: no new sweep starts",
        ));
    }
    let req = SweepRequest {
        sweep,
        command: vec![command.into()],
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
    for n in &outcome.notes {
        PyErr::warn(
            py,
            &py.get_type::<pyo3::exceptions::PyUserWarning>(),
            &std::ffi::CString::new(pythonic(n)).unwrap_or_default(),
            1,
        )?;
    }
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
    if let Some(rule) = rule {
        api::write_best(&outcome, rule).map_err(to_py)?;
    }
    result::SweepResult::new(
        py,
        result::Parts {
            header: outcome.header,
            rows: outcome.rows,
            traces: &outcome.traces,
            out: outcome.out.as_deref(),
            complete: outcome.complete,
            wall_seconds: outcome.wall_seconds,
            config: &req.sweep.config,
            tables: outcome.details,
            cell_steps: outcome.cell_steps,
        },
    )
}

/// The chapter's lab (what `pupper lab` runs): every body from its own
/// stand pose, the grid in torque mode under the sine force, no push;
/// best.csv (the best gains per body) in `out`. Plots and rendering are the
/// Python wrapper's.
#[pyfunction]
#[pyo3(signature = (variants=None, grid=None, *, seconds=pupper_core::request::lab::SECONDS, sine=pupper_core::request::lab::SINE, model="pupper_v3".to_string(), out=None, force=false, resume=false, threads=0, max_saturation=best::MAX_SATURATION, rank=None, replicates=1, seed=0, randomize=Vec::new(), backend="cpu".to_string(), device=None, ray=None, depth=None, motor=None, progress=None),
    text_signature = "(variants=None, grid=None, *, seconds=6.0, sine=(2.0, 1.2), model='pupper_v3', out=None, force=False, resume=False, threads=0, max_saturation=0.05, rank=None, replicates=1, seed=0, randomize=(), backend='cpu', device=None, ray=None, depth=None, motor=None, progress=None)")]
#[allow(clippy::too_many_arguments)]
fn lab(
    py: Python<'_>,
    variants: Option<Vec<String>>,
    grid: Option<Vec<String>>,
    seconds: f64,
    sine: [f64; 2],
    model: String,
    out: Option<&Bound<'_, PyAny>>,
    force: bool,
    resume: bool,
    threads: usize,
    max_saturation: f64,
    rank: Option<String>,
    replicates: i128,
    seed: i128,
    randomize: Vec<String>,
    backend: String,
    device: Option<String>,
    ray: Option<String>,
    depth: Option<f64>,
    motor: Option<String>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<result::SweepResult> {
    // the ranges `sweep` takes, with its messages
    let whole = |name: &str, v: i128, most: u64| -> PyResult<u64> {
        match u64::try_from(v) {
            Ok(v) if v <= most => Ok(v),
            Ok(_) => Err(pyo3::exceptions::PyValueError::new_err(format!(
                "{name} {v} is too large: use at most {most}"
            ))),
            Err(_) => Err(pyo3::exceptions::PyValueError::new_err(format!(
                "{name} must be a whole number >= 0, not {v}"
            ))),
        }
    };
    let replicates = whole("replicates", replicates, u32::MAX as u64)? as u32;
    let seed = whole("seed", seed, u64::MAX)?;
    let variants = variants.unwrap_or_else(|| {
        pupper_core::request::lab::VARIANTS
            .map(String::from)
            .to_vec()
    });
    let spec = SweepSpec {
        model,
        out: out_from(out)?,
        force,
        resume,
        threads,
        replicates,
        seed,
        randomize: randomize.clone(),
        backend,
        device,
        ray,
        depth,
        motor,
        ..pupper_core::request::lab::spec(&variants, &grid.unwrap_or_default(), seconds, sine)
    };
    let metric = rank.unwrap_or_else(|| {
        if replicates > 1 || !randomize.is_empty() {
            "p95:last_1s_std_mm".into()
        } else {
            "last_1s_std_mm".into()
        }
    });
    let rule = best::Rule {
        max_saturation,
        ..best::Rule::new(&metric, &["variant".to_string()])
    };
    run_spec(py, spec, progress, "python: pupper_core.lab", Some(&rule))
}

/// Shards of one sweep put together into `out` (what `pupper merge` does);
/// the merged run, read back.
#[pyfunction]
#[pyo3(signature = (dirs, out, *, force=false))]
fn merge(
    py: Python<'_>,
    dirs: Vec<PathBuf>,
    out: PathBuf,
    force: bool,
) -> PyResult<result::SweepResult> {
    let existing = match force {
        true => pupper_core::results::rundir::Existing::Overwrite,
        false => pupper_core::results::rundir::Existing::Refuse,
    };
    let (dir, _) = pupper_core::results::rundir::merge(&dirs, &out, existing).map_err(to_py)?;
    load_run(py, dir)
}

/// A run directory read back: its rows checked against its manifest.
#[pyfunction]
fn load_run(py: Python<'_>, run_dir: PathBuf) -> PyResult<result::SweepResult> {
    let run = pupper_core::results::tables::read_run(&run_dir).map_err(to_py)?;
    let cell_steps = vec![None; run.rows.len()];
    result::SweepResult::new(
        py,
        result::Parts {
            header: run.header,
            rows: run.rows,
            traces: &run.traces,
            out: Some(&run_dir),
            complete: run.manifest.complete,
            wall_seconds: f64::NAN,
            config: &run.manifest.config,
            cell_steps,
            tables: run.details,
        },
    )
}

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
fn record<'py>(
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
fn record_run(
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

/// The manifest of a run directory, as a dict.
#[pyfunction]
fn read_manifest(py: Python<'_>, dir: PathBuf) -> PyResult<Bound<'_, PyAny>> {
    to_dict(py, &output::read_manifest(&dir).map_err(to_py)?)
}

/// The defaults of every sweep keyword argument, as `SweepSpec::default()`
/// holds them (the Python signature takes its defaults from here).
#[pyfunction]
fn sweep_defaults(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    to_dict(py, &SweepSpec::defaults_json())
}

/// A built-in model compiled as the CLI compiles it, as a `mujoco.MjModel`
/// (for rendering, viewers and hand-written loops).
#[pyfunction]
fn builtin_model(name: &str) -> PyResult<Py<PyAny>> {
    let source = ModelSource::Builtin(name.to_string());
    if source.builtin().is_none() {
        return Err(ModelError::new_err(format!(
            "no built-in model '{name}': use one of {}",
            pupper_core::robot::model::BUILTIN_NAMES.join(", ")
        )));
    }
    api::compiled(&source).map_err(to_py)
}

/// pupper's ranking rule (`best::best`) on any table: `header` and rows of
/// text as summary.csv holds them; the best row of each group of `by`, in
/// order of first appearance (None for a group with no eligible row).
/// Plots mark the cell the CLI names, through this one rule.
#[pyfunction]
#[pyo3(signature = (header, rows, metric, *, by = Vec::new(), minimize = true, max_saturation = best::MAX_SATURATION))]
fn best_rows(
    header: Vec<String>,
    rows: Vec<Vec<String>>,
    metric: String,
    by: Vec<String>,
    minimize: bool,
    max_saturation: f64,
) -> PyResult<Vec<Option<usize>>> {
    let rule = best::Rule {
        max_saturation,
        minimize,
        ..best::Rule::new(&metric, &by)
    };
    if let Some(r) = rows.iter().find(|r| r.len() != header.len()) {
        return Err(pyo3::exceptions::PyValueError::new_err(format!(
            "a row has {} fields for {} columns",
            r.len(),
            header.len()
        )));
    }
    best::best(&header, &rows, &rule)
        .map(|groups| groups.into_iter().map(|g| g.best).collect())
        .map_err(to_py)
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

/// A Ray task's work on a worker node (`pupper_core._ray.run_task`): the
/// task's cells of the job run here, on `threads` threads; the encoded
/// outcome (results, or why this node refused) goes back to the driver.
#[pyfunction]
fn _run_task<'py>(
    py: Python<'py>,
    job: &[u8],
    task: &[u8],
    threads: usize,
) -> PyResult<Bound<'py, pyo3::types::PyBytes>> {
    let out = api::run_task(job, task, threads).map_err(to_py)?;
    Ok(pyo3::types::PyBytes::new(py, &out))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", pupper_core::VERSION)?;
    m.add("METRICS", pupper_core::sim::metrics::METRIC_NAMES.to_vec())?;
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
    for (name, family, builtin, doc) in DUAL_ERRORS {
        let bases =
            pyo3::types::PyTuple::new(py, [m.getattr(family)?, builtins.getattr(builtin)?])?;
        let ns = PyDict::new(py);
        ns.set_item("__doc__", doc)?;
        ns.set_item("__module__", "pupper_core")?;
        m.add(name, builtins.getattr("type")?.call1((name, bases, ns))?)?;
    }
    m.add_function(wrap_pyfunction!(info, m)?)?;
    m.add_function(wrap_pyfunction!(stand, m)?)?;
    m.add_function(wrap_pyfunction!(pose, m)?)?;
    m.add_function(wrap_pyfunction!(gains, m)?)?;
    m.add_function(wrap_pyfunction!(_shutdown, m)?)?;
    m.add_function(wrap_pyfunction!(best_rows, m)?)?;
    m.add_function(wrap_pyfunction!(result::_result_from_state, m)?)?;
    m.add_function(wrap_pyfunction!(sweep, m)?)?;
    m.add_function(wrap_pyfunction!(read_manifest, m)?)?;
    m.add_function(wrap_pyfunction!(load_run, m)?)?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    m.add_function(wrap_pyfunction!(lab, m)?)?;
    m.add_function(wrap_pyfunction!(response, m)?)?;
    m.add_function(wrap_pyfunction!(check_axes, m)?)?;
    m.add_class::<result::SweepResult>()?;
    m.add_function(wrap_pyfunction!(record, m)?)?;
    m.add_function(wrap_pyfunction!(record_run, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(builtin_model, m)?)?;
    m.add_function(wrap_pyfunction!(cli_main, m)?)?;
    m.add_function(wrap_pyfunction!(_run_task, m)?)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::pythonic;

    #[test]
    fn cli_words_become_keywords() {
        assert_eq!(
            pythonic("--kp -1 is negative or not finite: gains must be >= 0"),
            "kp=-1 is negative or not finite: gains must be >= 0"
        );
        assert_eq!(
            pythonic(
                "output directory 'x' already exists: choose another --out, add --force to overwrite it, or --resume it"
            ),
            "output directory 'x' already exists: choose another out=, add force=True to overwrite it, or resume=True it"
        );
        assert_eq!(
            pythonic("give --max-torque a value > 0"),
            "give max_torque= a value > 0"
        );
        assert_eq!(
            pythonic("drop --no-push or the axis"),
            "drop push=False or the axis"
        );
        assert_eq!(
            pythonic(
                "model file 'nope.xml' does not exist: check the path, or use --model pupper_v3"
            ),
            "model file 'nope.xml' does not exist: check the path, or use model=\"pupper_v3\""
        );
        // a quoted command line stays one
        assert_eq!(
            pythonic("finish it with pupper sweep --resume d, then merge"),
            "finish it with pupper sweep --resume d, then merge"
        );
    }
}
