//! The runner's whole contact with physics: start a batch of cells, advance
//! it, read what is recorded. `pupper_mujoco` implements it twice: MuJoCo's
//! CPU batch and MuJoCo Warp (see [`crate::plan::backend`]).

use crate::error::Result;
use crate::plan::mode::Mode;
use crate::plan::schedule::InitialState;
use crate::plan::setup::CellSetup;
use crate::robot::layout::Layout;
use crate::robot::model::ModelInfo;

/// The external base force over one advance call.
pub enum Force<'a> {
    /// One force per simulation of the call, held for every step.
    Constant(&'a [[f64; 3]]),
    /// `nstep` forces per simulation, simulation-major.
    PerStep(&'a [[f64; 3]]),
}

/// A batch to start: the cells (which share a timestep), their mode, where
/// they start, and the threads that step them.
pub struct BatchStart<'a> {
    pub cells: &'a [CellSetup],
    pub mode: Mode,
    pub initial: &'a InitialState,
    pub threads: usize,
}

/// One open-loop advance: simulations `ids` (sorted) by `nstep` steps, the
/// base force, and with `ctrl` each simulation's ctrl for every step
/// (`nstep` rows of `nu` per simulation, simulation-major): servo targets
/// that move on a schedule known in advance.
pub struct Advance<'a> {
    pub ids: &'a [usize],
    pub nstep: usize,
    pub force: Force<'a>,
    pub ctrl: Option<&'a [f64]>,
}

/// One closed-loop step: simulations `ids` (sorted) and the base force on
/// each.
pub struct Controlled<'a> {
    pub ids: &'a [usize],
    pub force: &'a [[f64; 3]],
}

/// Rows handed to an observer after each step: the simulation's position in
/// the call's ids, the step within the call, qpos, and actuator forces.
pub type Observer<'a> = dyn FnMut(usize, usize, &[f64], &[f64]) + 'a;

/// A controller: simulation's position in the ids, qpos, qvel, ctrl to write.
pub type Controller<'a> = dyn FnMut(usize, &[f64], &[f64], &mut [f64]) + 'a;

pub trait Physics {
    fn info(&self) -> &ModelInfo;
    fn layout(&self) -> &Layout;
    /// Starts the simulations of `batch`'s cells at its initial state.
    fn start(&self, batch: &BatchStart<'_>) -> Result<Box<dyn SimBatch + '_>>;
    /// The most simulations one batch should hold (a device's memory);
    /// None: batches are sized by measured speed.
    fn batch_limit(&self) -> Option<usize> {
        None
    }
}

pub trait SimBatch {
    fn len(&self) -> usize;
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// True when the actuators themselves compute torque mode's PD
    /// ([`crate::plan::backend::ActuatorPd`]): the runner then advances
    /// open-loop, as in servo mode, instead of stepping the Rust PD.
    fn actuator_pd(&self) -> bool {
        false
    }
    /// Simulation `sim`'s joint targets, in ctrl order.
    fn targets(&self, sim: usize) -> &[f64];
    /// Simulation `sim`'s stance height: the base height at which its
    /// lowest foot touches the floor in its start pose (m).
    fn stance(&self, sim: usize) -> f64;
    /// The current qpos of simulation `sim`.
    fn qpos(&self, sim: usize) -> Result<Vec<f64>>;
    /// The open-loop advance `call`, observing after each step. Returns
    /// `(position in ids, step)` of simulations that diverged; they are not
    /// observed from that step on.
    fn advance(
        &mut self,
        call: Advance<'_>,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<(usize, usize)>>;
    /// One closed-loop step of `call`'s simulations: `control` writes each
    /// simulation's ctrl from its state, then all step once, then `observe`
    /// sees the new state. Returns the positions in ids of simulations that
    /// diverged.
    fn step_controlled(
        &mut self,
        call: Controlled<'_>,
        control: &mut Controller<'_>,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<usize>>;
}
