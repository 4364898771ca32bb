//! The response experiment's input: which joints are excited, by what
//! signal, on which test bench. Each excited joint is its own simulation:
//! its target follows the signal while every other joint holds its pose.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::math::response::chirp;
use crate::robot::model::ModelInfo;

/// Seconds within which a time on the runner's clock counts as the signal's
/// start: far below any timestep, far above the clock's rounding error.
pub const STEP_TOLERANCE: f64 = 1e-9;

/// What an excited joint's target does, added to its pose angle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Signal {
    /// A step of `amplitude` rad.
    Step { amplitude: f64 },
    /// `amplitude * sin(2 pi hz t)`.
    Sine { amplitude: f64, hz: f64 },
    /// A logarithmic sweep from `f0` to `f1` Hz over the window.
    Chirp { amplitude: f64, f0: f64, f1: f64 },
}

impl Signal {
    pub fn name(&self) -> &'static str {
        match self {
            Signal::Step { .. } => "step",
            Signal::Sine { .. } => "sine",
            Signal::Chirp { .. } => "chirp",
        }
    }

    pub fn amplitude(&self) -> f64 {
        match self {
            Signal::Step { amplitude }
            | Signal::Sine { amplitude, .. }
            | Signal::Chirp { amplitude, .. } => *amplitude,
        }
    }
}

/// Default step size (rad).
pub const AMPLITUDE: f64 = 0.2;
/// Default seconds the pose is held before the signal starts: the joints
/// settle their sag under gravity first.
pub const HOLD: f64 = 0.5;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Excitation {
    pub signal: Signal,
    /// Seconds holding the pose before the signal starts.
    pub hold: f64,
    /// What was asked to be excited: actuator names or joint groups
    /// (haa, hfe, kfe); empty: every actuator.
    #[serde(default)]
    pub select: Vec<String>,
    /// The floating robot standing on the floor, instead of the fixed base
    /// hung in the air.
    #[serde(default)]
    pub standing: bool,
    /// The excited actuators in ctrl order, their names and joint groups,
    /// resolved on the compiled model ([`Excitation::resolve`]).
    #[serde(default)]
    pub joints: Vec<usize>,
    #[serde(default)]
    pub names: Vec<String>,
    #[serde(default)]
    pub groups: Vec<String>,
    /// The excited joints' reflected inertia at the pose (kg·m²), for the
    /// stability margin of each cell's gains.
    #[serde(default)]
    pub inertia: Vec<f64>,
}

impl Excitation {
    /// Fills the excited actuators from `select` on a compiled model.
    pub fn resolve(&mut self, info: &ModelInfo) -> Result<()> {
        let group = |a: usize| info.actuator_group(a).unwrap_or("other");
        let mut joints = Vec::new();
        for a in 0..info.nu {
            let name = &info.actuators[a].name;
            if self.select.is_empty()
                || self
                    .select
                    .iter()
                    .any(|s| s == name || s.eq_ignore_ascii_case(group(a)))
            {
                joints.push(a);
            }
        }
        for s in &self.select {
            let known = info.actuators.iter().any(|a| &a.name == s)
                || (0..info.nu).any(|a| s.eq_ignore_ascii_case(group(a)));
            if !known {
                let names: Vec<&str> = info.actuators.iter().map(|a| a.name.as_str()).collect();
                return Err(Error::Config(format!(
                    "--joints {s}: model '{}' has no actuator or joint group of that name: give groups (haa, hfe, kfe) or actuators ({})",
                    info.name,
                    names.join(", ")
                )));
            }
        }
        self.names = joints
            .iter()
            .map(|&a| info.actuators[a].name.clone())
            .collect();
        self.groups = joints.iter().map(|&a| group(a).to_string()).collect();
        self.joints = joints;
        Ok(())
    }

    /// Refuses a signal that takes an excited joint past its range from
    /// the pose's `targets` (in ctrl order).
    pub fn check_ranges(&self, info: &ModelInfo, targets: &[f64]) -> Result<()> {
        let a = self.signal.amplitude();
        let low = match self.signal {
            Signal::Step { .. } => 0.0,
            _ => -a,
        };
        for &j in &self.joints {
            let range = info.actuators[j].joint.and_then(|k| info.joints[k].range);
            let (Some([lo, hi]), Some(&t)) = (range, targets.get(j)) else {
                continue;
            };
            let (from, to) = (t + low, t + a);
            if from < lo || to > hi {
                return Err(Error::Config(format!(
                    "--amplitude {a} takes joint '{}' from its pose angle {t:.3} rad to {:.3} rad, outside its range [{lo:.3}, {hi:.3}]: give a smaller --amplitude, or leave the joint out with --joints",
                    info.actuators[j].name,
                    if from < lo { from } else { to }
                )));
            }
        }
        Ok(())
    }

    /// The joint group of excited actuator `a`.
    pub fn group_of(&self, a: usize) -> Option<&str> {
        let at = self.joints.iter().position(|&j| j == a)?;
        self.groups.get(at).map(String::as_str)
    }

    /// The reflected inertia of excited actuator `a` (NaN if unknown).
    pub fn inertia_of(&self, a: usize) -> f64 {
        self.joints
            .iter()
            .position(|&j| j == a)
            .and_then(|at| self.inertia.get(at))
            .copied()
            .unwrap_or(f64::NAN)
    }

    /// The name of excited actuator `a`.
    pub fn name_of(&self, a: usize) -> &str {
        self.joints
            .iter()
            .position(|&j| j == a)
            .and_then(|at| self.names.get(at))
            .map_or("", String::as_str)
    }

    /// Seconds the signal runs (the window after the hold).
    pub fn window(&self, duration: f64) -> f64 {
        duration - self.hold
    }

    /// The target offset (rad) at time `t` of the schedule.
    pub fn offset(&self, t: f64, duration: f64) -> f64 {
        // the runner's clock is a sum of timesteps, which may fall a rounding
        // error short of the hold's end (and, less the command delay, of it
        // on another step than without the delay): within STEP_TOLERANCE it
        // is the signal's start, so a delay shifts the response by exactly
        // its length
        let s = t - self.hold;
        if s < -STEP_TOLERANCE {
            return 0.0;
        }
        let s = s.max(0.0);
        match self.signal {
            Signal::Step { amplitude } => amplitude,
            Signal::Sine { amplitude, hz } => {
                amplitude * (2.0 * std::f64::consts::PI * hz * s).sin()
            }
            Signal::Chirp { amplitude, f0, f1 } => {
                amplitude * chirp(f0, f1, self.window(duration), s).0.sin()
            }
        }
    }

    /// Checks the signal against the schedule and the timestep.
    pub fn validate(&self, duration: f64, timestep: f64) -> Result<()> {
        let a = self.signal.amplitude();
        if !(a.is_finite() && a > 0.0) {
            return Err(Error::Config(format!(
                "--amplitude {a} is not positive: give the signal's size in rad (> 0)"
            )));
        }
        if !(self.hold.is_finite() && self.hold >= 0.0) {
            return Err(Error::Config(format!(
                "--hold {} is negative: give the seconds to hold the pose before the signal (>= 0)",
                self.hold
            )));
        }
        let window = self.window(duration);
        let nyquist = 0.5 / timestep;
        let top = match self.signal {
            Signal::Step { .. } => None,
            Signal::Sine { hz, .. } => Some(("the sine's frequency", hz, hz)),
            Signal::Chirp { f0, f1, .. } => Some(("--chirp F1", f1, f0)),
        };
        if let Some((what, hi, lo)) = top {
            if !(lo.is_finite() && lo > 0.0 && hi.is_finite() && hi >= lo) {
                return Err(Error::Config(format!(
                    "frequencies {lo}..{hi} Hz: give positive frequencies, the chirp's F0 below F1"
                )));
            }
            if hi >= nyquist {
                return Err(Error::Config(format!(
                    "{what} {hi} Hz is at or past the Nyquist frequency {nyquist} Hz of the {timestep} s timestep: lower it, or give --timestep"
                )));
            }
            // a few periods of the lowest frequency, to fit gain and phase
            let need = 3.0 / lo;
            if window < need {
                return Err(Error::Config(format!(
                    "the {window:.3} s window after the {} s hold holds under 3 periods of {lo} Hz: use --seconds {:.3} or more",
                    self.hold,
                    self.hold + need
                )));
            }
        }
        if matches!(self.signal, Signal::Step { .. }) && window < 0.2 {
            return Err(Error::Config(format!(
                "the {window:.3} s window after the {} s hold is too short to settle: use --seconds {} or more",
                self.hold,
                self.hold + 0.2
            )));
        }
        Ok(())
    }
}

/// The response kind's plan: one simulation per excited joint, its target
/// moving on the signal, no push, hung in the air unless `standing`.
impl crate::plan::kind::KindPlan for Excitation {
    fn name(&self) -> &'static str {
        "response"
    }

    fn excited(&self) -> Vec<Option<usize>> {
        self.joints.iter().map(|&j| Some(j)).collect()
    }

    fn pushes(&self) -> bool {
        false
    }

    fn suspended(&self) -> bool {
        !self.standing
    }

    fn moving_targets(&self) -> bool {
        true
    }

    fn target_offset(&self, t: f64, duration: f64) -> f64 {
        self.offset(t, duration)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ex(signal: Signal) -> Excitation {
        Excitation {
            signal,
            hold: 0.5,
            select: vec![],
            standing: false,
            joints: vec![0],
            names: vec!["a".into()],
            groups: vec!["hfe".into()],
            inertia: vec![],
        }
    }

    #[test]
    fn a_clock_summed_from_steps_starts_the_step_on_time_with_or_without_a_delay() {
        // 1000 steps of 2 ms sum to a hair under 2 s: the step at hold 2 s
        // starts on that step, and 20 ms of delay moves it by 10 steps exactly
        let e = Excitation {
            hold: 2.0,
            ..ex(Signal::Step { amplitude: 0.2 })
        };
        let (dt, delay) = (0.002, 0.02);
        let mut t = 0.0;
        let (mut now, mut late) = (None, None);
        for k in 0..3000 {
            if now.is_none() && e.offset(t, 5.0) > 0.0 {
                now = Some(k);
            }
            if late.is_none() && e.offset(t - delay, 5.0) > 0.0 {
                late = Some(k);
            }
            t += dt;
        }
        assert_eq!((now, late), (Some(1000), Some(1010)));
        // a sine starts at zero, as before
        let s = ex(Signal::Sine {
            amplitude: 0.1,
            hz: 2.0,
        });
        assert_eq!(s.offset(0.5 - 1e-12, 2.0), 0.0);
        assert_eq!(s.offset(0.5 - 1e-6, 2.0), 0.0);
    }

    #[test]
    fn offsets_start_after_the_hold() {
        let e = ex(Signal::Step { amplitude: 0.2 });
        assert_eq!(e.offset(0.49, 2.0), 0.0);
        assert_eq!(e.offset(0.5, 2.0), 0.2);
        let s = ex(Signal::Sine {
            amplitude: 0.1,
            hz: 2.0,
        });
        assert!((s.offset(0.5 + 0.125, 2.0) - 0.1).abs() < 1e-12);
    }

    #[test]
    fn bad_signals_are_refused() {
        assert!(
            ex(Signal::Step { amplitude: -0.1 })
                .validate(2.0, 0.002)
                .is_err()
        );
        let past = ex(Signal::Chirp {
            amplitude: 0.1,
            f0: 1.0,
            f1: 250.0,
        });
        assert!(
            past.validate(10.0, 0.002)
                .unwrap_err()
                .to_string()
                .contains("Nyquist")
        );
        let short = ex(Signal::Sine {
            amplitude: 0.1,
            hz: 1.0,
        });
        assert!(
            short
                .validate(2.0, 0.002)
                .unwrap_err()
                .to_string()
                .contains("periods")
        );
        assert!(
            ex(Signal::Step { amplitude: 0.1 })
                .validate(0.6, 0.002)
                .is_err()
        );
        assert!(
            ex(Signal::Step { amplitude: 0.1 })
                .validate(2.0, 0.002)
                .is_ok()
        );
    }
}
