//! The servo firmware and sensing of a torque-mode simulation: what its
//! PD reads (late, noisy) and how the motor turns the PD into torque.

use crate::math::motor;
use crate::math::pd;
use crate::plan::config::SweepConfig;
use crate::plan::mode::Mode;
use crate::plan::motor::Motor;
use crate::plan::randomize::{Draws, Noise};
use crate::robot::layout::Layout;
use crate::robot::model::ModelInfo;

/// What the torque-mode PD of one simulation reads: its joint angles and
/// velocities `delay` control steps late (the start state until then), each
/// actuator's a fitted feedback latency later still (fractional steps,
/// between two recorded states), the angles with Gaussian noise.
pub(crate) struct Sensing {
    delay: usize,
    noise: Option<Noise>,
    /// Each actuator's feedback latency beyond `delay`, in control steps
    /// (a calibrated model's `pupper:latency:ACT`, as `pupper fit`'s
    /// replay reads it); empty: none.
    latency: Vec<f64>,
    /// The last `delay + ceil(latency) + 1` (angles, velocities) of the
    /// actuated joints, oldest first.
    history: std::collections::VecDeque<(Vec<f64>, Vec<f64>)>,
    /// The servo firmware between the PD and the joint; None: the ideal
    /// motor (the PD every step on what is read, clipped at the limit).
    pub(crate) firmware: Option<Firmware>,
}

/// The firmware of a torque-mode simulation: `--motor`, or a calibrated
/// model's fitted servo (its command delay, torque lag and feedback
/// latency per actuator, where `--motor` and the draws give none); None
/// for the ideal motor.
pub(crate) fn firmware(
    cfg: &SweepConfig,
    info: &ModelInfo,
    dt: f64,
    d: &Draws,
) -> Option<Firmware> {
    // a replicate's draws over --motor
    let mut motor = cfg.motor.clone();
    motor.delay = d.motor_delay.unwrap_or(motor.delay);
    motor.filter = d.motor_filter.or(motor.filter);
    motor.noload = d.motor_noload.or(motor.noload);
    // a drawn lag of 0 is a robot without one
    motor.lag = d.motor_lag.map_or(motor.lag, |t| (t > 0.0).then_some(t));
    let torque = cfg.mode == Mode::Torque;
    let delayed = info.actuators.iter().any(|a| a.delay > 0.0);
    // the model's own lag runs where neither --motor nor a draw sets one
    let own_lag = motor.lag.is_none() && d.motor_lag.is_none();
    let lagged = own_lag && info.actuators.iter().any(|a| a.lag > 0.0);
    if motor.is_ideal() && !((delayed || lagged) && torque) {
        return None;
    }
    let mut f = Firmware::new(&motor, info.nu, dt);
    if motor.delay == 0.0 && d.motor_delay.is_none() {
        f.delays = info.actuators.iter().map(|a| a.delay).collect();
    }
    if lagged {
        f.follow = info
            .actuators
            .iter()
            .map(|a| lag_weight(a.lag, dt))
            .collect();
    }
    Some(f)
}

/// Each actuator's fitted feedback latency in control steps at physics step
/// `dt` (a calibrated model's; empty where it has none), as the firmware's
/// PD reads it: a PD without a rate of its own reads `HELD_STEPS` younger.
pub(crate) fn latency_steps(motor: &Motor, info: &ModelInfo, dt: f64) -> Vec<f64> {
    if info.actuators.iter().all(|a| a.latency <= 0.0) {
        return Vec::new();
    }
    info.actuators
        .iter()
        .map(|a| motor.late_steps(a.latency, dt))
        .collect()
}

/// The lag's weight of a new torque per physics step: the exact
/// discretisation of `T·dy/dt = x − y` over `dt`; None where it is 1 to
/// the last bit (a lag thousands of times shorter than the step), which is
/// no lag at all: `y + 1·(x − y)` may differ from `x` in its last bit, and
/// a fit's finite differences on a lag at its bound of 0 would read that
/// round-off as a slope.
fn lag_weight(t: f64, dt: f64) -> Option<f64> {
    let w = -(-dt / t).exp_m1();
    (t > 0.0 && w < 1.0).then_some(w)
}

/// One simulation's servo firmware ([`Motor`]): the PD updated at its own
/// rate on the encoder's angle and a filtered derivative, towards the
/// target of `delay` ago, its torque held between updates, delivered
/// within the motor's torque–speed band and, with a `lag`, followed by the
/// current loop's first-order lag every physics step.
pub(crate) struct Firmware {
    motor: Motor,
    /// The update period (s).
    period: f64,
    /// The derivative filter's weight of a new sample.
    alpha: Option<f64>,
    updates: u64,
    /// Per actuator: the torque held since the last update, the filtered
    /// derivative and the last encoder angle (NaN before the first update).
    held: Vec<f64>,
    filtered: Vec<f64>,
    last_angle: Vec<f64>,
    /// Each actuator's command delay (s).
    pub(crate) delays: Vec<f64>,
    /// Each actuator's lag weight of a new torque per physics step
    /// ([`lag_weight`]; None: no lag), and its lagged torque (NaN before
    /// the first step: it starts at the PD's).
    follow: Vec<Option<f64>>,
    lagged: Vec<f64>,
    /// Whether the encoder rounds the angle to its counts (torque mode);
    /// `pupper fit`'s replay keeps the difference velocity but not the
    /// rounding, which would make the replay a staircase in the
    /// parameters that no finite-difference Jacobian can follow.
    quantize: bool,
}

impl Firmware {
    pub(crate) fn new(motor: &Motor, nu: usize, dt: f64) -> Firmware {
        let period = motor.period(dt);
        Firmware {
            motor: motor.clone(),
            period,
            alpha: motor.filter.map(|f| motor::lowpass_alpha(f, period)),
            updates: 0,
            held: vec![0.0; nu],
            filtered: vec![f64::NAN; nu],
            last_angle: vec![f64::NAN; nu],
            delays: vec![motor.delay; nu],
            follow: vec![motor.lag.and_then(|t| lag_weight(t, dt)); nu],
            lagged: vec![f64::NAN; nu],
            quantize: true,
        }
    }

    /// This firmware for `pupper fit`'s replay: the encoder's difference
    /// velocity without its rounding, and each actuator's own torque lag
    /// (s; 0: none) at physics step `dt`.
    pub(crate) fn smooth(mut self, lags: &[f64], dt: f64) -> Firmware {
        self.quantize = false;
        self.follow = lags.iter().map(|&t| lag_weight(t, dt)).collect();
        self
    }

    /// True when the PD updates on the step starting at time `t`.
    pub(crate) fn due(&mut self, t: f64) -> bool {
        let due = match self.motor.rate {
            None => true,
            // the k-th update falls at k / rate (a step's start time may
            // sit a rounding error below it)
            Some(r) => t * r + 1e-6 >= self.updates as f64,
        };
        self.updates += due as u64;
        due
    }

    /// A PD update of actuator `a` from the angle and velocity it reads.
    pub(crate) fn update(&mut self, a: usize, kp: f64, kd: f64, target: f64, q: f64, v: f64) {
        let (q, v) = match self.motor.counts {
            Some(c) => {
                let q = if self.quantize {
                    motor::quantize(q, c)
                } else {
                    q
                };
                let last = self.last_angle[a];
                self.last_angle[a] = q;
                // the encoder's difference; the sensor's velocity at first
                (
                    q,
                    if last.is_nan() {
                        v
                    } else {
                        (q - last) / self.period
                    },
                )
            }
            None => (q, v),
        };
        let v = match self.alpha {
            Some(alpha) => {
                let f = &mut self.filtered[a];
                *f = if f.is_nan() { v } else { *f + alpha * (v - *f) };
                *f
            }
            None => v,
        };
        self.held[a] = pd::law(kp, kd, target, q, v);
    }

    /// The torque actuator `a` delivers over this physics step at joint
    /// speed `speed`, and whether the limit (`peak` at stall) cut it.
    pub(crate) fn deliver(&mut self, a: usize, peak: f64, speed: f64) -> (f64, bool) {
        let band = match self.motor.noload {
            Some(w) => motor::speed_band(peak, w, speed),
            None => (-peak, peak),
        };
        let (tau, cut) = motor::clip(self.held[a], band);
        let Some(follow) = self.follow[a] else {
            return (tau, cut);
        };
        let y = &mut self.lagged[a];
        *y = if y.is_nan() {
            tau
        } else {
            *y + follow * (tau - *y)
        };
        (*y, cut)
    }
}

impl Sensing {
    /// Reads `delay` control steps late (and each actuator `latency[a]`
    /// steps later still; empty: none), with `noise` on the angles, through
    /// `firmware` (None: the ideal motor).
    pub(crate) fn new(
        delay: usize,
        noise: Option<Noise>,
        firmware: Option<Firmware>,
        latency: Vec<f64>,
    ) -> Sensing {
        Sensing {
            delay,
            noise,
            latency,
            history: Default::default(),
            firmware,
        }
    }

    fn exact(&self) -> bool {
        self.delay == 0 && self.noise.is_none() && self.latency.is_empty()
    }

    /// How many past states the reads need: the newest and `delay` plus the
    /// longest latency's steps before it.
    fn depth(&self) -> usize {
        let late = self.latency.iter().fold(0.0_f64, |m, &l| m.max(l));
        self.delay + late.ceil() as usize + 1
    }

    /// Records the state just read, for the sensing delay; what the PD sees
    /// of an actuator is then `read`'s.
    pub(crate) fn remember(&mut self, layout: &Layout, qpos: &[f64], qvel: &[f64]) {
        self.remember_with(|q, v| {
            q.extend(layout.act_qpos.iter().map(|&i| qpos[i]));
            v.extend(layout.act_dof.iter().map(|&i| qvel[i]));
        });
    }

    /// Records the actuated joints' angles and velocities `fill` writes
    /// into the two (emptied) buffers it is given.
    pub(crate) fn remember_with(&mut self, fill: impl FnOnce(&mut Vec<f64>, &mut Vec<f64>)) {
        if self.exact() {
            return;
        }
        // the oldest entry's buffers take the newest state
        let (mut q, mut v) = if self.history.len() >= self.depth() {
            self.history.pop_front().unwrap_or_default()
        } else {
            Default::default()
        };
        q.clear();
        v.clear();
        fill(&mut q, &mut v);
        self.history.push_back((q, v));
    }

    /// Actuator `a`'s angle and velocity as the PD reads them.
    pub(crate) fn read(
        &mut self,
        layout: &Layout,
        a: usize,
        qpos: &[f64],
        qvel: &[f64],
    ) -> (f64, f64) {
        let (q, v) = self
            .late(a)
            .unwrap_or((qpos[layout.act_qpos[a]], qvel[layout.act_dof[a]]));
        match &mut self.noise {
            Some(noise) => (q + noise.sample(), v),
            None => (q, v),
        }
    }

    /// Actuator `a`'s recorded angle and velocity `delay + latency` steps
    /// before the newest state, between the two recorded states around it
    /// (the oldest before the start); None where it reads the state as it
    /// is (no delay, latency or noise).
    pub(crate) fn late(&self, a: usize) -> Option<(f64, f64)> {
        if self.exact() || self.history.is_empty() {
            return None;
        }
        let back = self.delay as f64 + self.latency.get(a).copied().unwrap_or(0.0);
        let at = (self.history.len() - 1) as f64 - back;
        if at <= 0.0 {
            let (q, v) = &self.history[0];
            return Some((q[a], v[a]));
        }
        let i = at.floor() as usize;
        let frac = at - i as f64;
        let (q0, v0) = &self.history[i];
        Some(match self.history.get(i + 1) {
            Some((q1, v1)) if frac > 0.0 => (
                q0[a] * (1.0 - frac) + q1[a] * frac,
                v0[a] * (1.0 - frac) + v1[a] * frac,
            ),
            _ => (q0[a], v0[a]),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_torque_lag_follows_a_step_as_its_first_order_law() {
        // a 1 N·m step held from the first step through a 10 ms lag on a
        // 2 ms step: 1 at the first step (the lag starts at the PD's
        // torque), then from a 0 N·m start it reaches 1 − exp(−k·dt/T)
        let dt = 0.002;
        let motor = Motor::parse("lag=0.01").unwrap();
        let mut f = Firmware::new(&motor, 1, dt);
        f.held[0] = 0.0;
        assert_eq!(f.deliver(0, 3.0, 0.0), (0.0, false));
        f.held[0] = 1.0;
        for k in 1..=25 {
            let (y, cut) = f.deliver(0, 3.0, 0.0);
            let want = 1.0 - (-(k as f64) * dt / 0.01).exp();
            assert!((y - want).abs() < 1e-12, "step {k}: {y} vs {want}");
            assert!(!cut);
        }
        // the lag follows what the limit lets through: a 5 N·m command at a
        // 3 N·m limit is cut, and the lagged torque never passes 3
        f.held[0] = 5.0;
        for _ in 0..500 {
            let (y, cut) = f.deliver(0, 3.0, 0.0);
            assert!(cut && y <= 3.0 + 1e-12);
        }
        // no lag: what the PD holds, clipped
        let mut ideal = Firmware::new(&Motor::parse("rate=500").unwrap(), 1, dt);
        ideal.held[0] = 5.0;
        assert_eq!(ideal.deliver(0, 3.0, 0.0), (3.0, true));
    }
}
