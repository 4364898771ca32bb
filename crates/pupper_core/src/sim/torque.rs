//! Torque mode's controller: each control step, the PD in Rust (or the
//! motor's firmware, where the model has one) turns a simulation's sensed
//! state into ctrl, and says what the motors deliver of it.

use crate::math::pd;
use crate::plan::setup::CellSetup;
use crate::robot::layout::Layout;
use crate::sim::firmware::Sensing;

/// What the controller of one simulation worked out for its step: the
/// largest delivered force, how many actuators were at their limit, and
/// each actuator's delivered force.
#[derive(Default)]
pub(crate) struct Delivered {
    pub(crate) peak: f64,
    pub(crate) nsat: usize,
    pub(crate) forces: Vec<f64>,
}

/// One simulation's motors: its gains and limits, and where its targets
/// are at a time (`target(actuator, t)`, moving or not).
pub(crate) struct Motors<'a, F: Fn(usize, f64) -> f64> {
    pub(crate) setup: &'a CellSetup,
    pub(crate) limits: &'a [f64],
    pub(crate) layout: &'a Layout,
    pub(crate) target: F,
}

impl<F: Fn(usize, f64) -> f64> Motors<'_, F> {
    /// The control step at time `t` from the state (`qpos`, `qvel`): every
    /// actuator's command written to `ctrl`, what it delivers to `out`.
    pub(crate) fn control(
        &self,
        sense: &mut Sensing,
        t: f64,
        qpos: &[f64],
        qvel: &[f64],
        ctrl: &mut [f64],
        out: &mut Delivered,
    ) {
        let (s, lim, layout) = (self.setup, self.limits, self.layout);
        out.peak = 0.0;
        out.nsat = 0;
        sense.remember(layout, qpos, qvel);
        out.forces.clear();
        let due = sense.firmware.as_mut().map(|f| f.due(t));
        for a in 0..layout.nu {
            let (tau, sat) = match due {
                None => {
                    let (q, v) = sense.read(layout, a, qpos, qvel);
                    pd::torque(s.kp(a), s.kd(a), (self.target)(a, t), q, v, lim[a])
                }
                Some(due) => {
                    if due {
                        let (q, v) = sense.read(layout, a, qpos, qvel);
                        if let Some(f) = sense.firmware.as_mut() {
                            let target = (self.target)(a, t - f.delays[a]);
                            f.update(a, s.kp(a), s.kd(a), target, q, v);
                        }
                    }
                    match sense.firmware.as_mut() {
                        Some(f) => f.deliver(a, lim[a], qvel[layout.act_dof[a]]),
                        None => (0.0, false),
                    }
                }
            };
            ctrl[a] = tau;
            // what the motor delivers: its gain times the command,
            // clamped at its force range
            let signed = s.gain(a) * tau;
            out.forces.push(signed.clamp(-lim[a], lim[a]));
            let delivered = signed.abs();
            out.peak = out.peak.max(if delivered > lim[a] {
                lim[a]
            } else {
                delivered
            });
            out.nsat += (sat || delivered >= lim[a] * (1.0 + 1e-12)) as usize;
        }
    }
}
