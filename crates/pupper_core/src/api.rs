//! The operations the CLI and the Python module share, so the same inputs
//! give the same numbers from both.

use serde::Serialize;

use crate::bridge;
use crate::error::Result;
use crate::experiment::{self, CellResult, Defaults, Hooks, RunOptions, SweepConfig};
use crate::grid::{Cell, Grid};
use crate::metrics::Status;
use crate::model::{ModelInfo, ModelSource};
use crate::physics::{Mode, Physics};
use crate::schedule::{InitialState, Schedule};

/// What `pupper info` prints.
pub fn info(source: &ModelSource) -> Result<ModelInfo> {
    bridge::with_model(source, false, |m| Ok(m.info().clone()))
}

/// The outcome of `pupper stand`.
#[derive(Debug, Clone, Serialize)]
pub struct StandReport {
    pub model: String,
    pub mode: Mode,
    pub kp: f64,
    pub kd: f64,
    pub seconds: f64,
    pub final_z: f64,
    pub last_1s_std_mm: f64,
    pub max_tilt_deg: f64,
    pub status: Status,
}

/// Resets to `initial`, stands for `seconds` with no push, reports.
pub fn stand(
    source: &ModelSource,
    seconds: f64,
    kp: f64,
    kd: f64,
    initial: InitialState,
    mode: Mode,
) -> Result<StandReport> {
    let cfg = SweepConfig {
        model: source.clone(),
        grid: Grid::default(),
        schedule: Schedule {
            duration: seconds,
            initial,
            push: None,
            ..Schedule::default()
        },
        mode,
        defaults: Defaults {
            kp,
            kd,
            ..Defaults::default()
        },
    };
    let results = sweep(&cfg, None, RunOptions::default(), &mut experiment::NoHooks)?;
    let m = &results[0].metrics;
    Ok(StandReport {
        model: source.display(),
        mode,
        kp,
        kd,
        seconds,
        final_z: m.final_z,
        last_1s_std_mm: m.last_1s_std_mm,
        max_tilt_deg: m.max_tilt_deg,
        status: m.status,
    })
}

/// Runs a sweep's cells (all of them, or `only` these), streaming finished
/// chunks to `hooks`.
pub fn sweep(
    cfg: &SweepConfig,
    only: Option<&[Cell]>,
    opts: RunOptions,
    hooks: &mut dyn Hooks,
) -> Result<Vec<CellResult>> {
    cfg.validate()?;
    let all;
    let cells = match only {
        Some(c) => c,
        None => {
            all = cfg.grid.cells();
            &all
        }
    };
    bridge::with_model(&cfg.model, true, |model| {
        experiment::run_cells(model, cfg, cells, opts, hooks)
    })
}

/// Total cell-steps, for progress bars.
pub fn total_steps(cfg: &SweepConfig, cells: &[Cell]) -> Result<u64> {
    bridge::with_model(&cfg.model, false, |model| {
        let dt = model.info().timestep;
        Ok(cells
            .iter()
            .map(|c| cfg.schedule.steps(cfg.setup(c).timestep.unwrap_or(dt)) as u64)
            .sum())
    })
}

/// Model info through the [`Physics`] trait object, for callers that hold one.
pub fn physics_info(p: &dyn Physics) -> &ModelInfo {
    p.info()
}
