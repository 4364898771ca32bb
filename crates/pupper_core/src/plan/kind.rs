//! What an experiment kind decides of its simulations before any physics
//! ([`KindPlan`]); each kind's plan is in its own module (`plan::stand`,
//! `plan::response`, `plan::hold`). The kinds themselves are one
//! type, `plan::experiment::Experiment`; each layer has a module per kind
//! and dispatches on that type in one place, its registry.

use crate::error::Result;
use crate::plan::grid::{Cell, Grid};
use crate::plan::schedule::Schedule;
use crate::robot::model::ModelInfo;

/// The metric a standing run ranks by unless told: the base height's
/// spread over the last second.
pub const DEFAULT_METRIC: &str = "last_1s_std_mm";

/// What a kind decides of its simulations, before any physics. The
/// defaults are the stand kind's.
pub trait KindPlan {
    /// The kind's name, as a manifest and a report name it.
    fn name(&self) -> &'static str;
    /// What each simulation of a replicate excites: nothing (one
    /// simulation), or one actuator each.
    fn excited(&self) -> Vec<Option<usize>> {
        vec![None]
    }
    /// Whether the schedule's push and its figures belong to the kind.
    fn pushes(&self) -> bool {
        true
    }
    /// Whether the robot runs hung in the air: base fixed, no contacts.
    fn suspended(&self) -> bool {
        false
    }
    /// Whether targets move on a schedule, so every step's ctrl is given.
    fn moving_targets(&self) -> bool {
        false
    }
    /// How far an excited joint's target is from its pose at time `t` of a
    /// `duration` s run (rad).
    fn target_offset(&self, _t: f64, _duration: f64) -> f64 {
        0.0
    }
    /// The kind's own force on the base at time `t` (N, world frame),
    /// beside the schedule's push and sine.
    fn base_force(&self, _t: f64) -> [f64; 3] {
        [0.0; 3]
    }
    /// Whether [`KindPlan::base_force`] changes from step to step.
    fn varying_force(&self) -> bool {
        false
    }
    /// The targets' own motion in one simulation of `cell`, from the joint
    /// targets `start`, where the kind moves every target itself (a gait);
    /// None where they stay or follow [`KindPlan::target_offset`].
    fn motion(&self, _cell: &Cell, _start: &[f64]) -> Option<Box<dyn Motion>> {
        None
    }
    /// What the kind takes from the compiled model before it runs; by
    /// default the schedule's push, scaled to the robot's mass.
    fn resolve(&mut self, m: &OnModel<'_>, schedule: &mut Schedule) -> Result<()> {
        match schedule.push.as_mut() {
            Some(p) => p.resolve(m.info.total_mass),
            None => Ok(()),
        }
    }
    /// The summary column its best cell is the lowest of, unless a rule
    /// names another.
    fn default_metric(&self) -> &'static str {
        DEFAULT_METRIC
    }
    /// Refuses a run the kind cannot measure, in one line: its schedule,
    /// its grid, and whether it has replicates.
    fn check(&self, _schedule: &Schedule, _grid: &Grid, _replicated: bool) -> Result<()> {
        Ok(())
    }
}

/// Joint targets a kind moves on its own schedule, all of one
/// simulation's at once (a gait's come from the legs' kinematics together).
pub trait Motion {
    /// Each actuator's target at time `t` (s), into `out` (actuator order).
    fn targets(&self, t: f64, out: &mut [f64]);
}

/// What a kind may read of the compiled model as it resolves: the model,
/// the run's grid, and the joint targets its cells start from (worked out
/// only when asked: finding a stand pose is a search).
pub struct OnModel<'a> {
    pub info: &'a ModelInfo,
    pub grid: &'a Grid,
    /// The start pose's joint targets (None where the model gives none).
    pub start: &'a dyn Fn() -> Result<Option<Vec<f64>>>,
}
