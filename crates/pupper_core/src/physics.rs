//! The runner's whole contact with physics: start a batch of cells, advance
//! it, read what is recorded. `pupper_mujoco` implements it twice: MuJoCo's
//! CPU batch and MuJoCo Warp (see [`crate::backend`]).

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::layout::Layout;
use crate::model::ModelInfo;
use crate::schedule::InitialState;

/// Who computes the joint torques.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// MuJoCo's affine actuators are the PD: gains written once per cell.
    #[default]
    Servo,
    /// PD computed in Rust every step; actuators are direct torque inputs.
    Torque,
}

impl Mode {
    pub fn as_str(self) -> &'static str {
        match self {
            Mode::Servo => "servo",
            Mode::Torque => "torque",
        }
    }
}

/// One cell's physical setting, resolved from the grid and the defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct CellSetup {
    /// Each actuator's Kp and Kd, in actuator order: the grid's or the
    /// defaults' value, else the actuator's own gains from the model.
    pub kp: Vec<f64>,
    pub kd: Vec<f64>,
    /// One torque limit (N·m) for every actuator; None: each actuator's own.
    pub max_torque: Option<f64>,
    /// Push force (N) along the push direction's z, i.e. the push's world z.
    pub push_force: [f64; 3],
    /// Sliding friction of every colliding geom; None keeps the model's.
    pub friction: Option<f64>,
    /// Physics timestep; None keeps the model's.
    pub timestep: Option<f64>,
    pub leg_scale: f64,
    pub torso_mass_scale: f64,
    /// Factors on the compiled body's torso mass and on its thigh and calf
    /// masses (inertias alike): a replicate's draws, 1 when nominal.
    pub torso_mass_factor: f64,
    pub leg_mass_factor: f64,
    /// Factor on each actuator's gain, in actuator order; empty: all 1.
    pub motor_gain: Vec<f64>,
    /// When this simulation's push starts; None: the schedule's.
    pub push_at: Option<f64>,
}

impl CellSetup {
    /// Actuator `a`'s Kp.
    pub fn kp(&self, a: usize) -> f64 {
        self.kp.get(a).copied().unwrap_or(0.0)
    }

    /// Actuator `a`'s Kd.
    pub fn kd(&self, a: usize) -> f64 {
        self.kd.get(a).copied().unwrap_or(0.0)
    }

    /// The gain factor of actuator `a`.
    pub fn gain(&self, a: usize) -> f64 {
        self.motor_gain.get(a).copied().unwrap_or(1.0)
    }

    /// True when the masses are the compiled body's own.
    pub fn nominal_masses(&self) -> bool {
        self.torso_mass_factor == 1.0 && self.leg_mass_factor == 1.0
    }

    /// The torque limit of each actuator in this cell.
    pub fn torque_limits(&self, info: &ModelInfo) -> Result<Vec<f64>> {
        match self.max_torque {
            Some(t) => Ok(vec![t; info.nu]),
            None => info.torque_limits(),
        }
    }
}

/// The external base force over one advance call.
pub enum Force<'a> {
    /// One force per simulation of the call, held for every step.
    Constant(&'a [[f64; 3]]),
    /// `nstep` forces per simulation, simulation-major.
    PerStep(&'a [[f64; 3]]),
}

/// Rows handed to an observer after each step: the simulation's position in
/// the call's ids, the step within the call, qpos, and actuator forces.
pub type Observer<'a> = dyn FnMut(usize, usize, &[f64], &[f64]) + 'a;

/// A controller: simulation's position in the ids, qpos, qvel, ctrl to write.
pub type Controller<'a> = dyn FnMut(usize, &[f64], &[f64], &mut [f64]) + 'a;

pub trait Physics {
    fn info(&self) -> &ModelInfo;
    fn layout(&self) -> &Layout;
    /// Starts simulations for `cells` (which share a timestep) at `initial`.
    fn start(
        &self,
        cells: &[CellSetup],
        mode: Mode,
        initial: &InitialState,
        threads: usize,
    ) -> Result<Box<dyn SimBatch + '_>>;
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
    /// ([`crate::backend::ActuatorPd`]): the runner then advances
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
    /// Open-loop advance of simulations `ids` (sorted) by `nstep` steps,
    /// observing after each. Returns `(position in ids, step)` of simulations
    /// that diverged; they are not observed from that step on.
    fn advance(
        &mut self,
        ids: &[usize],
        nstep: usize,
        force: Force<'_>,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<(usize, usize)>>;
    /// One closed-loop step: `control` writes each simulation's ctrl from its
    /// state, then all step once, then `observe` sees the new state. Returns
    /// the positions in ids of simulations that diverged.
    fn step_controlled(
        &mut self,
        ids: &[usize],
        force: &[[f64; 3]],
        control: &mut Controller<'_>,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<usize>>;
}
