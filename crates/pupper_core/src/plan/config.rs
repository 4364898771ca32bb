//! Everything that decides a sweep's numbers (the manifest's `config`),
//! and each cell's physical setting resolved from it.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::plan::backend::Backend;
use crate::plan::experiment::Experiment;
use crate::plan::grid::{Axis, Cell, Grid};
use crate::plan::integrator::Integrator;
use crate::plan::mode::Mode;
use crate::plan::motor::Motor;
use crate::plan::randomize::Replicates;
use crate::plan::schedule::Schedule;
use crate::plan::setup::CellSetup;
use crate::robot::model::{ModelInfo, ModelSource};

/// Values used for any axis the grid does not vary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Defaults {
    /// None: each actuator's own gains, as the model declares them.
    pub kp: Option<f64>,
    pub kd: Option<f64>,
    /// None: each actuator's own limit (the model's force or control range).
    #[serde(default)]
    pub max_torque: Option<f64>,
    /// The body (a named variant's scales).
    #[serde(default = "one")]
    pub leg_scale: f64,
    #[serde(default = "one")]
    pub torso_mass_scale: f64,
}

fn one() -> f64 {
    1.0
}

impl Default for Defaults {
    fn default() -> Self {
        Defaults {
            kp: None,
            kd: None,
            max_torque: None,
            leg_scale: 1.0,
            torso_mass_scale: 1.0,
        }
    }
}

/// Everything that decides a sweep's numbers. Stored in the manifest; a
/// resume must match it exactly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepConfig {
    pub model: ModelSource,
    pub grid: Grid,
    pub schedule: Schedule,
    pub mode: Mode,
    pub defaults: Defaults,
    /// Randomized replicates of every cell; a plain sweep leaves it out of
    /// the manifest (so its manifest is what it always was).
    #[serde(default, skip_serializing_if = "Replicates::is_plain")]
    pub replicates: Replicates,
    /// What steps the physics; the cpu backend is left out of the manifest.
    #[serde(default, skip_serializing_if = "Backend::is_cpu")]
    pub backend: Backend,
    /// What the simulations do (the stand kind is left out of the
    /// manifest; a response writes its excitation under `response`).
    #[serde(flatten)]
    pub experiment: Experiment,
    /// MuJoCo's integrator for every cell; None (the model's own) is left
    /// out of the manifest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub integrator: Option<Integrator>,
    /// The servo firmware and motor of torque mode's PD; the ideal motor
    /// is left out of the manifest.
    #[serde(default, skip_serializing_if = "Motor::is_ideal")]
    pub motor: Motor,
}

impl Default for SweepConfig {
    fn default() -> Self {
        SweepConfig {
            model: ModelSource::default(),
            grid: Grid::default(),
            schedule: Schedule::default(),
            mode: Mode::Servo,
            defaults: Defaults::default(),
            replicates: Replicates::default(),
            backend: Backend::Cpu,
            experiment: Experiment::Stand,
            integrator: None,
            motor: Motor::default(),
        }
    }
}

impl SweepConfig {
    pub fn validate(&self) -> Result<()> {
        self.schedule.validate()?;
        // a kind's own axis (a walk's gait) is no other kind's to vary
        let kind = self.experiment.name();
        if let Some((a, own)) = self
            .grid
            .axes
            .iter()
            .find_map(|a| a.axis.kind().filter(|&k| k != kind).map(|k| (a.axis, k)))
        {
            return Err(Error::Config(format!(
                "grid axis '{a}' is a {own}'s own axis: run it with `pupper {own}`"
            )));
        }
        self.experiment
            .plan()
            .check(&self.schedule, &self.grid, !self.replicates.is_plain())?;
        let d = &self.defaults;
        for (flag, v) in [("kp", d.kp), ("kd", d.kd)] {
            let Some(v) = v else { continue };
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::Config(format!(
                    "--{flag} {v} is negative or not finite: gains must be >= 0"
                )));
            }
        }
        if self.grid.has_axis(Axis::Variant) && (d.leg_scale, d.torso_mass_scale) != (1.0, 1.0) {
            return Err(Error::Config(
                "both --variant and a variant grid axis name the body: drop one of them".into(),
            ));
        }
        if self.schedule.push.is_none() && self.grid.has_axis(Axis::PushForce) {
            return Err(Error::Config(
                "the grid varies push_force but the push is off: drop --no-push or the push_force axis"
                    .into(),
            ));
        }
        if let Some(t) = d.max_torque
            && !(t.is_finite() && t > 0.0)
        {
            return Err(Error::Config(format!(
                "max torque {t} is not positive: give --max-torque a value > 0"
            )));
        }
        let axes: Vec<&str> = self.grid.axes.iter().map(|a| a.axis.name()).collect();
        self.replicates
            .check(self.mode, self.schedule.push.is_some(), &axes)?;
        if !self.motor.is_ideal() {
            if self.mode != Mode::Torque {
                return Err(Error::Config(format!(
                    "--motor {} models the firmware of torque mode's PD (servo mode's PD is MuJoCo's actuator): add --mode torque",
                    self.motor.spec()
                )));
            }
            if !self.backend.is_cpu() {
                return Err(Error::Config(
                    "--motor needs the Rust PD of --backend cpu (the warp backend runs the PD inside MuJoCo's actuators): use --backend cpu".into(),
                ));
            }
        }
        self.check_motor_draws()?;
        if self.integrator.is_some() && !self.backend.is_cpu() {
            return Err(Error::Config(
                "--integrator runs on --backend cpu (the warp backend keeps the model's own integrator): drop one of them".into(),
            ));
        }
        self.backend.check(self.mode, &self.replicates)
    }

    /// Refuses a --motor key that a --randomize quantity also sets: the
    /// draw would replace the given value without a word.
    fn check_motor_draws(&self) -> Result<()> {
        use crate::plan::randomize::Quantity;
        let m = &self.motor;
        let given = [
            ("delay", m.delay != 0.0, Quantity::MotorDelay),
            ("filter", m.filter.is_some(), Quantity::MotorFilter),
            ("noload", m.noload.is_some(), Quantity::MotorNoload),
            ("lag", m.lag.is_some(), Quantity::MotorLag),
        ];
        for (key, set, q) in given {
            if set && self.replicates.randomize.iter().any(|r| r.quantity == q) {
                let name = q.name();
                return Err(Error::Config(format!(
                    "--motor {key}= and --randomize {name}= both set the motor's {key} (each replicate's draw would replace the given value): keep one of them"
                )));
            }
        }
        Ok(())
    }

    /// The replicates of each cell.
    pub fn replicate_count(&self) -> usize {
        self.replicates.count.max(1) as usize
    }

    /// The simulations each cell runs: its replicates, times the excited
    /// joints in a response run.
    pub fn sims_per_cell(&self) -> usize {
        self.replicate_count() * self.experiment.sims_per_replicate()
    }

    /// Refuses a motor firmware faster than the physics of any cell (the
    /// model's timestep, or a timestep axis's values), and a model's command
    /// delay in torque mode where the backend has no host firmware.
    pub fn check_motor(&self, info: &ModelInfo) -> Result<()> {
        // torque mode runs a model's command delay in the Rust firmware,
        // which warp (the PD in its actuators) does not have
        if self.mode == Mode::Torque
            && !self.backend.is_cpu()
            && let Some(a) = info.actuators.iter().find(|a| a.delay > 0.0)
        {
            return Err(Error::Config(format!(
                "actuator '{}' of this model has a command delay of {} s (a calibrated model?), which torque mode runs on the host: use --backend cpu, or --mode servo (MuJoCo's own delay)",
                a.name, a.delay
            )));
        }
        let model_dt = info.timestep;
        let axis = self
            .grid
            .axes
            .iter()
            .filter(|a| a.axis == Axis::Timestep)
            .flat_map(|a| a.values.iter().copied());
        for dt in std::iter::once(model_dt).chain(axis) {
            self.motor.check_timestep(dt)?;
        }
        Ok(())
    }

    /// Checks that every gain a cell may need has a value: the model's own
    /// gains stand in for a gain neither the grid nor the defaults give.
    pub fn check_gains(&self, info: &ModelInfo) -> Result<()> {
        // a gain of actuator `a`: a default, the common axis, or its group's
        let given = |a: usize, kd: bool| {
            let (axis, d) = match kd {
                false => (Axis::Kp, self.defaults.kp),
                true => (Axis::Kd, self.defaults.kd),
            };
            d.is_some()
                || self.grid.has_axis(axis)
                || info
                    .actuator_group(a)
                    .and_then(|g| Axis::group_gain(kd, g))
                    .is_some_and(|x| self.grid.has_axis(x))
        };
        let open = info
            .actuators
            .iter()
            .enumerate()
            .find(|(i, a)| a.own_gains().is_none() && !(given(*i, false) && given(*i, true)));
        match open.map(|(_, a)| a) {
            Some(a) => Err(Error::Config(format!(
                "actuator '{}' of model '{}' has no PD gains of its own (it is not a position servo), so there is no default to run it at: give --kp and --kd",
                a.name, info.name
            ))),
            None => Ok(()),
        }
    }

    /// The physical setting of one cell on a model (whose actuators give
    /// the gains the grid and the defaults leave open).
    pub fn setup(&self, cell: &Cell, info: &ModelInfo) -> CellSetup {
        let get = |a: Axis, d: f64| cell.get(a).unwrap_or(d);
        let body = match cell.get(Axis::Variant) {
            Some(i) => {
                let b = crate::robot::variant::VARIANTS
                    [(i as usize).min(crate::robot::variant::VARIANTS.len() - 1)];
                (b.leg_scale, b.torso_mass_scale)
            }
            None => (self.defaults.leg_scale, self.defaults.torso_mass_scale),
        };
        let body = crate::robot::variant::Scales {
            leg_scale: body.0,
            torso_mass_scale: body.1,
        };
        let base_push = self.schedule.push.as_ref().map(|p| p.force);
        // The push_force axis sets the push's world-z component (N).
        let push_force = match (cell.get(Axis::PushForce), base_push) {
            (Some(f), Some(p)) => [p[0], p[1], f],
            (Some(f), None) => [0.0, 0.0, f],
            (None, Some(p)) => p,
            (None, None) => [0.0; 3],
        };
        let own = |i: usize| -> Vec<f64> {
            info.actuators
                .iter()
                .map(|a| a.own_gains().map_or(0.0, |g| g[i]))
                .collect()
        };
        // a joint group's axis over the common axis over the default, else
        // the actuator's own gain
        let gain = |axis: Axis, default: Option<f64>, i: usize| -> Vec<f64> {
            let own = own(i);
            (0..info.nu)
                .map(|a| {
                    let group = info
                        .actuator_group(a)
                        .and_then(|g| Axis::group_gain(i == 1, g))
                        .and_then(|g| cell.get(g));
                    // what the servo delivers of the commanded gain (1 but
                    // on a calibrated model)
                    let scale = info.actuators.get(a).map_or(1.0, |x| x.gain_scale[i]);
                    let g = group.or(cell.get(axis)).or(default).unwrap_or(own[a]);
                    if scale == 1.0 { g } else { g * scale }
                })
                .collect()
        };
        CellSetup {
            kp: gain(Axis::Kp, self.defaults.kp, 0),
            kd: gain(Axis::Kd, self.defaults.kd, 1),
            max_torque: cell.get(Axis::MaxTorque).or(self.defaults.max_torque),
            push_force,
            friction: cell.get(Axis::Friction),
            timestep: cell.get(Axis::Timestep),
            // a named body sets the scales; numeric scale axes multiply them
            leg_scale: body.leg_scale * get(Axis::LegScale, 1.0),
            torso_mass_scale: body.torso_mass_scale * get(Axis::TorsoMassScale, 1.0),
            torso_mass_factor: 1.0,
            leg_mass_factor: 1.0,
            motor_gain: Vec::new(),
            push_at: None,
        }
    }
}
