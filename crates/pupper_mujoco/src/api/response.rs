//! The response kind's own operation: the excited joints' angles at the
//! physics rate, for the figures of a response run.

use crate::bridge;
use pupper_core::error::{Error, Result};
use pupper_core::results::output;
use pupper_core::sim::runner::{self, RunOptions};

use super::cells_of;
use super::start::resolved;

/// One excited joint's angle after every physics step of a response
/// cell's replicate 0 (time from the excitation's start, rad).
pub struct StepTrace {
    pub index: usize,
    pub id: String,
    pub joint: String,
    pub t: Vec<f64>,
    pub angle: Vec<f64>,
}

/// The excited joints' angles of cells of a response run at the physics
/// rate: the cells run again as the manifest says (the same simulation
/// that wrote response_traces.csv, which keeps every `trace_every`-th of
/// these samples), for figures that draw a 10 ms rise without the steps
/// of a 20 ms sampling.
pub fn step_traces(dir: &std::path::Path, indices: &[usize]) -> Result<Vec<StepTrace>> {
    let mut cfg = output::read_manifest(dir)?.config;
    if cfg.experiment.excitation().is_none() {
        return Err(Error::Config(format!(
            "{} is not a response run: step traces are a response's",
            dir.display()
        )));
    }
    cfg.schedule.trace_every = 1;
    let cells = cells_of(dir, &cfg, indices)?;
    bridge::with_config_model(&cfg, |model| {
        let cfg = &resolved(&cfg, model)?;
        let physics = bridge::physics(model, &cfg.backend)?;
        let results = runner::run_cells(
            physics.as_ref(),
            cfg,
            &cells,
            RunOptions::default(),
            &mut runner::NoHooks,
        )?;
        let Some(e) = cfg.experiment.excitation() else {
            return Ok(vec![]);
        };
        Ok(results
            .into_iter()
            .flat_map(|r| {
                let (index, id) = (r.cell.index, r.cell.id.clone());
                r.joints
                    .into_iter()
                    .filter(|j| j.replicate == 0)
                    .map(move |j| StepTrace {
                        index,
                        id: id.clone(),
                        joint: e.name_of(j.actuator).to_string(),
                        t: j.trace.iter().map(|p| p.0).collect(),
                        angle: j.trace.iter().map(|p| p.1).collect(),
                    })
            })
            .collect())
    })
}
