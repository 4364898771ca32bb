//! What one simulation measures as it steps, and what it adds to its cell
//! when it is done: a probe per experiment kind (the stand kind's in
//! `sim::stand`, the response's in `sim::response`), chosen in one place,
//! the runner's registry.

use crate::plan::config::SweepConfig;
use crate::plan::grid::Cell;
use crate::plan::schedule::Schedule;
use crate::plan::setup::CellSetup;
use crate::robot::layout::Layout;
use crate::sim::frames::FrameRecorder;
use crate::sim::result::CellResult;

/// One simulation's state after a step.
pub struct Sample<'a> {
    /// Time at the end of the step (s).
    pub t: f64,
    pub qpos: &'a [f64],
    /// Each actuator's force.
    pub act: &'a [f64],
    /// The largest force over all actuators, and how many were at their limit.
    pub peak: f64,
    pub nsat: usize,
    /// The simulation's joint targets, before any excitation; the step's
    /// own where the kind moves them all ([`crate::plan::kind::Motion`]).
    pub targets: &'a [f64],
    pub layout: &'a Layout,
}

/// Where a simulation starts: what its probe needs to know of it.
pub struct Start<'a> {
    /// The actuator it excites, if its kind excites one.
    pub excited: Option<usize>,
    pub replicate: usize,
    /// Its cell.
    pub cell: &'a Cell,
    /// Its own schedule (a replicate may push at its own time).
    pub schedule: &'a Schedule,
    pub dt: f64,
    /// Base height at which its lowest foot touches the floor (m).
    pub stance: f64,
    pub layout: &'a Layout,
    /// Its actuators' torque limits (N·m).
    pub limits: &'a [f64],
}

/// A finished simulation, as its cell takes it.
pub struct Finish<'a> {
    pub cfg: &'a SweepConfig,
    pub replicate: usize,
    /// Its drawn values (a replicated run).
    pub drawn: Vec<f64>,
    pub setup: &'a CellSetup,
    pub dt: f64,
    pub frames: Option<FrameRecorder>,
}

pub trait Probe {
    fn observe(&mut self, s: &Sample<'_>);
    /// True once the robot has fallen and may stop stepping.
    fn fallen(&self) -> bool {
        false
    }
    /// The simulation diverged at time `t`: it is not stepped again.
    fn diverge(&mut self, t: f64);
    /// Adds what was measured to its cell's result.
    fn finish(self: Box<Self>, cell: &mut CellResult, done: Finish<'_>);
}
