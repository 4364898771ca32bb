//! The stability bound of each cell's PD at the start pose: which cells
//! are marked past_bound, and the note that says why.

use crate::bridge;
use pupper_core::plan::config::SweepConfig;
use pupper_core::plan::grid::Cell;
use pupper_core::plan::mode::Mode;
use pupper_core::plan::randomize::Quantity;
use pupper_core::plan::stability::{self, Damping};
use pupper_core::sim::runner::CellResult;

use super::start::start_qpos;
/// A body by the bits of its (leg_scale, torso_mass_scale).
type BodyKey = (u64, u64);

/// What marks a run's cells past the stability bound: each body's joint
/// inertias at the start pose and how the integrator takes the damping.
pub(super) struct StabilityBound<'a, 'py> {
    cfg: &'a SweepConfig,
    model: &'a bridge::LoadedModel<'py>,
    /// The start pose's qpos, where every body's inertias are read.
    qpos: Vec<f64>,
    damping: Damping,
    /// Inertias by body, as computed.
    bodies: std::cell::RefCell<Vec<(BodyKey, Vec<f64>)>>,
}

impl<'a, 'py> StabilityBound<'a, 'py> {
    /// None where pupper states no bound: RK4, no start pose to read the
    /// inertias at, or torque mode's firmware closing another loop than the
    /// PD at the physics step (a filtered derivative, a slower update, a
    /// torque lag or a feedback latency, given or a calibrated model's).
    pub(super) fn new(
        cfg: &'a SweepConfig,
        model: &'a bridge::LoadedModel<'py>,
    ) -> Option<StabilityBound<'a, 'py>> {
        let info = model.info();
        let damping = Damping::of(cfg.mode, info.integrator)?;
        let firmware = cfg.mode == Mode::Torque
            && (cfg.motor.filter.is_some()
                || cfg.motor.lag.is_some()
                // a calibrated model's fitted lag or latency, which torque mode runs
                || info.fitted_servo_times()
                || cfg
                    .motor
                    .rate
                    .is_some_and(|r| r * info.timestep < 1.0 - 1e-9)
                || cfg
                    .replicates
                    .randomize
                    .iter()
                    .any(|r| matches!(r.quantity, Quantity::MotorFilter | Quantity::MotorLag)));
        if firmware {
            return None;
        }
        let qpos = start_qpos(model, &cfg.schedule.initial).ok().flatten()?;
        Some(StabilityBound {
            cfg,
            model,
            qpos,
            damping,
            bodies: Default::default(),
        })
    }

    /// Each actuator's margin in `cell`, on the cell's own body (a lab's
    /// long legs have other inertias than the original's).
    fn margins(&self, cell: &Cell) -> Vec<f64> {
        let info = self.model.info();
        let s = self.cfg.setup(cell, info);
        let key = (s.leg_scale.to_bits(), s.torso_mass_scale.to_bits());
        let known = self
            .bodies
            .borrow()
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(_, i)| i.clone());
        let inertia = match known {
            Some(i) => i,
            None => {
                let i = self
                    .model
                    .variant(s.leg_scale, s.torso_mass_scale)
                    .and_then(|body| self.model.body_joint_inertia(&body, &self.qpos))
                    .unwrap_or_default();
                self.bodies.borrow_mut().push((key, i.clone()));
                i
            }
        };
        stability::cell_margins(info, &inertia, &s, self.damping)
    }

    pub(super) fn mark(&self, r: &mut CellResult) {
        let margins = self.margins(&r.cell);
        r.mark_past_bound(&margins, self.damping == Damping::Explicit);
    }

    /// The note for cells past the bound: how many, the worst, why they are
    /// not ranked, and how to simulate such gains honestly.
    pub(super) fn note(&self) -> Option<String> {
        let mut past = 0usize;
        let mut worst: Option<(f64, String, String)> = None;
        for cell in self.cfg.grid.cells() {
            let (m, a) = self
                .margins(&cell)
                .into_iter()
                .enumerate()
                .map(|(a, m)| (m, a))
                .fold((0.0, 0), |x, y| if y.0 > x.0 { y } else { x });
            if m >= 1.0 {
                past += 1;
                if worst.as_ref().is_none_or(|w| m > w.0) {
                    worst = Some((
                        m,
                        cell.id.clone(),
                        self.model.info().actuators[a].name.clone(),
                    ));
                }
            }
        }
        let (m, id, joint) = worst?;
        // an absurd gain's margin in two digits, not three hundred
        let m = if m < 1e6 {
            format!("{m:.2}")
        } else {
            format!("{m:.2e}")
        };
        let how = match (self.damping, self.cfg.mode) {
            (Damping::Explicit, Mode::Servo) => {
                "a smaller timestep (--grid timestep=...) or --integrator implicitfast simulates such gains honestly"
            }
            _ => "a smaller timestep (--grid timestep=...) simulates such gains honestly",
        };
        let integrated = match self.damping {
            Damping::Explicit => "an explicitly integrated PD",
            Damping::Implicit => "the PD with its damping integrated implicitly",
        };
        Some(format!(
            "{past} cell(s) lie past the stability bound of {integrated} at the timestep (worst: {id} on {joint}, margin {m}): marked past_bound and never ranked, since their numbers describe the integrator, not a robot; {how}; `pupper gains --kp KP --kd KD` shows the bound per joint"
        ))
    }
}
