//! `sweep` and what every sweep-like command runs through: the spec built,
//! run with Python progress and Ctrl-C, its table a `SweepResult`.

use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use pupper_core::request::spec::SweepSpec;
use pupper_core::results::best;
use pupper_mujoco::api::{self, SweepRequest};

use crate::convert::{Keywords, Options, given, grid_from, out_from, spec_from, to_dict};
use crate::error::{pythonic, to_py};
use crate::progress::{Active, PyUi};
use crate::result::{Parts, SweepResult};

/// Runs a sweep; returns its table as a `SweepResult`.
///
/// `grid`: a dict, `AXIS=VALUES` strings or one string; other keyword
/// arguments are the fields of the Rust `SweepSpec`. On Ctrl-C the finished
/// chunks are kept (and written when `out` is given) and KeyboardInterrupt
/// is raised.
#[pyfunction]
#[pyo3(signature = (grid=None, *, preset=None, out=None, progress=None, **options))]
pub(crate) fn sweep(
    py: Python<'_>,
    grid: Option<&Bound<'_, PyAny>>,
    preset: Option<String>,
    out: Option<&Bound<'_, PyAny>>,
    progress: Option<Bound<'_, PyAny>>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<SweepResult> {
    let spec = spec_of(py, grid, preset, out, options)?;
    run_spec(py, spec, progress, "python: pupper_core.sweep", None)
}

/// The spec of a sweep-like command: its grid (or preset) and `out`, the
/// other sweep keywords from `options`.
fn spec_of(
    py: Python<'_>,
    grid: Option<&Bound<'_, PyAny>>,
    preset: Option<String>,
    out: Option<&Bound<'_, PyAny>>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<SweepSpec> {
    Ok(SweepSpec {
        grid: grid_from(grid, preset)?,
        out: out_from(out)?,
        ..spec_from(py, options)?
    })
}

/// An experiment kind run as its own command (response, hold): its own
/// keywords, and the sweep it makes of the sweep keywords' spec.
pub(crate) trait Kind: Options {
    /// The command as the run's manifest records it.
    const COMMAND: &'static str;

    /// Simulated seconds unless the keywords give `seconds`.
    fn seconds(&self) -> f64;

    /// The kind's sweep on `base`; `options` are every keyword given.
    fn spec(self, base: SweepSpec, options: Option<&Bound<'_, PyDict>>) -> PyResult<SweepSpec>;

    /// The rule of the best.csv it writes, if it writes one.
    fn rule(_spec: &SweepSpec) -> Option<best::Rule> {
        None
    }
}

/// Runs kind `K`'s command: its own keywords taken out of `options` (as
/// [`Keywords`] take them), the rest the sweep keywords, as [`sweep`]'s.
pub(crate) fn run_kind<K: Kind>(
    py: Python<'_>,
    grid: Option<&Bound<'_, PyAny>>,
    out: Option<&Bound<'_, PyAny>>,
    progress: Option<Bound<'_, PyAny>>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<SweepResult> {
    let (keywords, rest) = Keywords::split(options, K::KEYWORDS)?;
    let own = K::read(&keywords)?;
    let mut base = spec_of(py, grid, None, out, rest.as_ref())?;
    if !given(options, "seconds") {
        base.seconds = own.seconds();
    }
    let spec = own.spec(base, options)?;
    let rule = K::rule(&spec);
    run_spec(py, spec, progress, K::COMMAND, rule.as_ref())
}

/// `kind_command! { /// doc  name(Kind) "text_signature" }`: the pyfunction
/// `name(grid=None, *, out=None, progress=None, **options)` running
/// [`Kind`] `Kind`, shown to inspect and help() with the text signature.
macro_rules! kind_command {
    ($(#[$doc:meta])* $name:ident($kind:ty) $text:literal) => {
        $(#[$doc])*
        #[pyfunction]
        #[pyo3(signature = (grid=None, *, out=None, progress=None, **options), text_signature = $text)]
        pub(crate) fn $name(
            py: Python<'_>,
            grid: Option<&Bound<'_, PyAny>>,
            out: Option<&Bound<'_, PyAny>>,
            progress: Option<Bound<'_, PyAny>>,
            options: Option<&Bound<'_, PyDict>>,
        ) -> PyResult<$crate::result::SweepResult> {
            $crate::commands::sweep::run_kind::<$kind>(py, grid, out, progress, options)
        }
    };
}
pub(crate) use kind_command;

/// The `text_signature` of a kind's command whose own keywords are `K`.
#[cfg(test)]
pub(crate) fn kind_signature<K: Options>() -> String {
    format!(
        "(grid=None, *, out=None, progress=None, {}, **options)",
        K::shown()
    )
}

/// Checks grid axis names as `--grid` does (GridError naming the known
/// axes); what a search checks before it writes anything.
#[pyfunction]
pub(crate) fn check_axes(names: Vec<String>) -> PyResult<()> {
    for n in names {
        pupper_core::plan::grid::Axis::parse(&n).map_err(to_py)?;
    }
    Ok(())
}

/// The defaults of every sweep keyword argument, as `SweepSpec::default()`
/// holds them (the Python signature takes its defaults from here).
#[pyfunction]
pub(crate) fn sweep_defaults(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    to_dict(py, &SweepSpec::defaults_json())
}

/// Runs a spec with Python progress and Ctrl-C; writes best.csv by `rule`.
pub(crate) fn run_spec(
    py: Python<'_>,
    spec: SweepSpec,
    progress: Option<Bound<'_, PyAny>>,
    command: &str,
    rule: Option<&best::Rule>,
) -> PyResult<SweepResult> {
    let sweep = spec.build().map_err(to_py)?;
    if let Some(rule) = rule {
        best::best(
            &pupper_core::results::tables::header_of(&sweep.config),
            &[],
            rule,
        )
        .map_err(to_py)?;
    }
    let _active = Active::start()?;
    let req = SweepRequest {
        sweep,
        command: vec![command.into()],
    };
    let mut ui = PyUi::new(py, progress);
    let outcome = api::run_sweep(&req, &mut ui).map_err(to_py)?;
    for n in &outcome.notes {
        PyErr::warn(
            py,
            &py.get_type::<pyo3::exceptions::PyUserWarning>(),
            &std::ffi::CString::new(pythonic(n)).unwrap_or_default(),
            1,
        )?;
    }
    ui.stopped()?;
    if !outcome.complete {
        // interrupted inside a MuJoCo call: finished chunks are kept
        return Err(PyKeyboardInterrupt::new_err(
            "sweep interrupted; finished cells are kept (resume=True continues a run directory)",
        ));
    }
    if let Some(rule) = rule {
        api::write_best(&outcome, rule).map_err(to_py)?;
    }
    SweepResult::new(
        py,
        Parts {
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
