//! One simulation's physical setting: gains, limits, push, body.

use crate::error::Result;
use crate::plan::randomize::Draws;
use crate::robot::model::ModelInfo;

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
    /// This cell's setting for one of its replicates, with its draws.
    pub fn with_draws(&self, d: &Draws) -> CellSetup {
        let mut s = self.clone();
        s.torso_mass_factor = d.torso_mass;
        s.leg_mass_factor = d.leg_mass;
        s.motor_gain = d.motor_gain.clone();
        if d.friction.is_some() {
            s.friction = d.friction;
        }
        if let Some(f) = d.push_force {
            s.push_force[2] = f;
        }
        s.push_at = d.push_at;
        s
    }

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
