//! Run directories read back and put together, and pupper's ranking rule
//! on any table.

use std::path::PathBuf;

use pyo3::prelude::*;

use pupper_core::results::{best, kind_manifest};

use crate::error::to_py;
use crate::result::{Parts, SweepResult};

/// Shards of one sweep put together into `out` (what `pupper merge` does);
/// the merged run, read back.
#[pyfunction]
#[pyo3(signature = (dirs, out, *, force=false))]
pub(crate) fn merge(
    py: Python<'_>,
    dirs: Vec<PathBuf>,
    out: PathBuf,
    force: bool,
) -> PyResult<SweepResult> {
    let existing = match force {
        true => pupper_core::results::rundir::Existing::Overwrite,
        false => pupper_core::results::rundir::Existing::Refuse,
    };
    let (dir, _) = pupper_core::results::merge::merge(&dirs, &out, existing).map_err(to_py)?;
    load_run(py, dir)
}

/// A run directory read back: its rows checked against its manifest.
#[pyfunction]
pub(crate) fn load_run(py: Python<'_>, run_dir: PathBuf) -> PyResult<SweepResult> {
    let run = pupper_core::results::tables::read_run(&run_dir).map_err(to_py)?;
    let cell_steps = steps_of(&run);
    SweepResult::new(
        py,
        Parts {
            header: run.header,
            rows: run.rows,
            traces: &run.traces,
            out: Some(&run_dir),
            complete: run.manifest.complete,
            // what the manifest knows (a resumed run's last part)
            wall_seconds: run.manifest.wall_seconds,
            config: &run.manifest.config,
            cell_steps,
            tables: run.details,
        },
    )
}

/// Each row's cell-steps as the manifest knows them: the schedule's steps
/// at the cell's timestep (its grid's, else the model's), times the
/// simulations per cell. None where the manifest cannot say: a manifest
/// from before it recorded the model's timestep, a cell that diverged or
/// has a replicate that failed (a simulation stops where it diverges), or,
/// with `stop_fallen`, one whose robot fell.
fn steps_of(run: &pupper_core::results::tables::RunTables) -> Vec<Option<u64>> {
    let cfg = &run.manifest.config;
    let col = |name: &str| run.header.iter().position(|h| h == name);
    let (dt_at, status_at, failed_at) = (col("timestep"), col("status"), col("failure_fraction"));
    run.rows
        .iter()
        .map(|r| {
            let status = status_at.map_or("", |i| r[i].as_str());
            let failed = failed_at.is_some_and(|i| r[i].parse::<f64>().is_ok_and(|f| f > 0.0));
            if status == "diverged" || failed || (cfg.schedule.stop_fallen && status == "fell") {
                return None;
            }
            let dt = match dt_at.and_then(|i| r[i].parse::<f64>().ok()) {
                Some(dt) => dt,
                None => run.manifest.model.timestep?,
            };
            let steps = cfg.schedule.plan(dt).ok()?.steps as u64;
            Some(steps * cfg.sims_per_cell() as u64)
        })
        .collect()
}

/// Every file an older run of any kind left in `dir` removed (`--force`),
/// and its `plots/` and `robots/` once empty: the one rule the Rust and
/// the Python kinds share (`pupper_core::results::clear`).
#[pyfunction]
pub(crate) fn clear_run(dir: PathBuf) -> PyResult<()> {
    pupper_core::results::clear::clear_run(&dir).map_err(to_py)
}

/// Refuses to resume `dir` as a run of `kind` when another kind's run is
/// there, in one line naming both.
#[pyfunction]
pub(crate) fn check_kind(dir: PathBuf, kind: &str) -> PyResult<()> {
    pupper_core::results::clear::check_kind(&dir, kind).map_err(to_py)
}

/// The manifest of a run directory of any kind, as a dict: the one reader,
/// every kind's JSON as it is (a Python kind's NaN and infinities
/// included, which Python's json reads; `load_run` checks a sweep's
/// against its struct). No manifest: `RunNotFoundError`; one that is not
/// JSON holding an object: `OutputError`, each one line.
#[pyfunction]
pub(crate) fn read_manifest(py: Python<'_>, dir: PathBuf) -> PyResult<Bound<'_, PyAny>> {
    let text = kind_manifest::read_text(&dir).map_err(to_py)?;
    let kind = kind_manifest::kind_of(&text);
    match PyModule::import(py, "json")?
        .getattr("loads")?
        .call1((text,))
    {
        Ok(m) if m.is_instance_of::<pyo3::types::PyDict>() => Ok(m),
        _ => Err(to_py(pupper_core::error::Error::Output(format!(
            "'{}': its manifest.json is not a pupper manifest (damaged?): run the {} again into a new directory",
            dir.display(),
            kind.as_deref().unwrap_or("command")
        )))),
    }
}

/// pupper's ranking rule (`best::best`) on any table: `header` and rows of
/// text as summary.csv holds them; the best row of each group of `by`, in
/// order of first appearance (None for a group with no eligible row).
/// Plots mark the cell the CLI names, through this one rule.
#[pyfunction]
#[pyo3(signature = (header, rows, metric, *, by = Vec::new(), minimize = true, max_saturation = best::MAX_SATURATION))]
pub(crate) fn best_rows(
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
