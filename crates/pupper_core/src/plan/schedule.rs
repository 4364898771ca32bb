//! The experiment schedule: how long, where it starts, when the push comes,
//! which continuous force acts, and what is recorded. Plain data shared by the
//! CLI and the Python module.
//!
//! Timing follows MuJoCo: time before step k is the double `t += dt`
//! accumulated k times, and an event is active on a step when the time before
//! that step lies in its window. This reproduces a hand-written
//! `while data.time < T` loop exactly (at dt 2 ms a 0.25 s push at 2 s acts on
//! 126 steps, not 125).

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Where every cell starts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InitialState {
    /// A keyframe of the model, by name; its joint qpos and ctrl are the
    /// targets.
    Keyframe(String),
    /// Joint angles in actuator order (rad), used as both start and target;
    /// the base starts where the first keyframe (or the model default) puts it.
    Pose(Vec<f64>),
    /// A stand pose searched on each cell's own body (see `pose`), with the
    /// base at the height that puts the feet just above the floor; the feet
    /// aim at the chapter's depth scaled to the body's legs.
    Auto,
    /// The same search, aiming the feet this far below the hips (m).
    AutoDepth(f64),
}

impl InitialState {
    /// For a searched stand pose, the depth asked for (None: scaled to the
    /// legs); None for a keyframe or given angles.
    pub fn auto_depth(&self) -> Option<Option<f64>> {
        match self {
            InitialState::Auto => Some(None),
            InitialState::AutoDepth(d) => Some(Some(*d)),
            _ => None,
        }
    }
}

/// A force on a body, in world coordinates, over a time window.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Push {
    /// Start time (s).
    pub start: f64,
    /// Duration (s).
    pub duration: f64,
    /// Force (N), world frame.
    pub force: [f64; 3],
    /// Body name; empty means the floating base body.
    #[serde(default)]
    pub body: String,
    /// The default push, not yet scaled to the robot: resolving the run on
    /// its model sets `force` to [`default_push_n`] of the model's mass and
    /// clears this (a manifest never holds it set).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub by_weight: bool,
}

/// The chapter's push on Pupper v3 (N, world z): the default push of a
/// sweep and a lab on Pupper.
pub const PUPPER_PUSH_N: f64 = -25.0;
/// Pupper v3's mass (kg), the weight the chapter's push was chosen for.
pub const PUPPER_MASS_KG: f64 = 3.17;

/// The default push on a robot of `mass` kg: the chapter's −25 N scaled by
/// its mass over Pupper v3's 3.17 kg, rounded to 0.1 N, so that Pupper's
/// own (3.17 kg as MuJoCo sums it, 3.1699999999999995) is exactly −25 N and
/// a 15 kg robot gets −118.3 N (the same push per kilogram).
pub fn default_push_n(mass: f64) -> f64 {
    (PUPPER_PUSH_N * mass / PUPPER_MASS_KG * 10.0).round() / 10.0
}

impl Push {
    /// The push on a model of `mass` kg: the default one scaled to it
    /// (a given force stays as given).
    pub fn resolve(&mut self, mass: f64) -> Result<()> {
        if !self.by_weight {
            return Ok(());
        }
        if !(mass.is_finite() && mass > 0.0) {
            return Err(Error::Config(format!(
                "the model's mass is {mass} kg: the default push scales with the robot's mass, so give the model mass or a --push-force"
            )));
        }
        self.force = [0.0, 0.0, default_push_n(mass)];
        self.by_weight = false;
        Ok(())
    }
}

impl Default for Push {
    fn default() -> Self {
        Push {
            start: 2.0,
            duration: 0.25,
            force: [0.0, 0.0, PUPPER_PUSH_N],
            body: String::new(),
            by_weight: false,
        }
    }
}

/// A continuous sinusoidal force `amplitude * sin(2 pi f t)` along `axis`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SineForce {
    pub amplitude: f64,
    pub frequency: f64,
    #[serde(default = "z_axis")]
    pub axis: [f64; 3],
}

fn z_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// Below this fraction of its stance height, at any moment, a robot fell
/// (Pupper v3 from `home`: 0.3 x 0.132 m = 4 cm).
pub const FALL_FRACTION: f64 = 0.3;
/// Below this fraction of its stance height on average over the last
/// window, a robot has collapsed (legs folded under it): a fall too, so it
/// is never the steadiest (Pupper v3 from `home`: 7.9 cm).
pub const COLLAPSE_FRACTION: f64 = 0.6;

/// Most steps one cell may take (about an hour of MuJoCo time per cell).
pub const MAX_STEPS: usize = 100_000_000;

/// The steps of one cell: see [`Schedule::plan`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StepPlan {
    pub steps: usize,
    /// Steps `[first, last)` on which the push acts (empty without a push).
    pub push: std::ops::Range<usize>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Schedule {
    /// Simulated seconds per cell.
    pub duration: f64,
    pub initial: InitialState,
    pub push: Option<Push>,
    pub sine: Option<SineForce>,
    /// Length of the "last second" window for the steadiness statistic (s).
    pub window: f64,
    /// Keep every n-th sample of the base-z trace (0: no trace).
    pub trace_every: usize,
    /// A base lower than this fraction of the robot's stance height, at
    /// any moment, counts as a fall.
    #[serde(default = "fall_fraction")]
    pub fall_fraction: f64,
    /// A base whose mean height over the last window is below this
    /// fraction of the stance height has collapsed: it counts as a fall.
    #[serde(default = "collapse_fraction")]
    pub collapse_fraction: f64,
    /// A tilt larger than this (deg) counts as a fall.
    pub fall_tilt_deg: f64,
    /// Seconds by which a robot dropped from its start has landed: max
    /// tilt and peak torque are measured from here (or from the push, if
    /// it comes first), and the last window must lie after it.
    #[serde(default = "landing")]
    pub landing: f64,
    /// The settle band, as a fraction of the push dip (the step-response
    /// convention's 2 %).
    #[serde(default = "settle_fraction")]
    pub settle_fraction: f64,
    /// Stop stepping a robot once it has fallen (base below the fall line
    /// or tilted past the fall tilt) or diverged: its row keeps its status
    /// and the metrics up to the stop. Off in a sweep unless asked (left
    /// out of its manifest then), on in a search.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub stop_fallen: bool,
}

fn fall_fraction() -> f64 {
    FALL_FRACTION
}

fn collapse_fraction() -> f64 {
    COLLAPSE_FRACTION
}

fn landing() -> f64 {
    LANDING
}

fn settle_fraction() -> f64 {
    SETTLE_FRACTION
}

/// Seconds a robot dropped from its keyframe needs to land (Pupper v3 from
/// `home`, 16 cm: about 0.3 s, and still by 1 s).
pub const LANDING: f64 = 1.0;
/// The settle band: 2 % of the push dip, as a step response's settling
/// time uses 2 % of the step.
pub const SETTLE_FRACTION: f64 = 0.02;
/// The narrowest settle band (m): a dip of a few nanometres is no dip.
pub const SETTLE_FLOOR: f64 = 1e-6;

impl Default for Schedule {
    fn default() -> Self {
        Schedule {
            duration: 10.0,
            initial: InitialState::Keyframe("home".into()),
            push: Some(Push::default()),
            sine: None,
            window: 1.0,
            trace_every: 0,
            fall_fraction: FALL_FRACTION,
            collapse_fraction: COLLAPSE_FRACTION,
            fall_tilt_deg: 60.0,
            landing: LANDING,
            settle_fraction: SETTLE_FRACTION,
            stop_fallen: false,
        }
    }
}

impl Schedule {
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str, fix: &str| Err(Error::Config(format!("{what}: {fix}")));
        if !(self.duration.is_finite() && self.duration > 0.0) {
            return bad(
                &format!("duration {} s is not positive", self.duration),
                "give --seconds a positive number",
            );
        }
        if self.duration > 1.0e5 {
            return bad("duration over 100000 s", "give --seconds a smaller number");
        }
        if !(self.window.is_finite() && self.window > 0.0) {
            return bad(
                "the statistics window is not positive",
                "use a window > 0 s",
            );
        }
        if let Some(p) = &self.push {
            if !(p.start.is_finite() && p.start >= 0.0) {
                return bad(
                    &format!("push start {} s is negative or not finite", p.start),
                    "give --push-at a time >= 0",
                );
            }
            if !(p.duration.is_finite() && p.duration >= 0.0) {
                return bad(
                    &format!("push duration {} s is negative or not finite", p.duration),
                    "give --push-duration a time >= 0",
                );
            }
            if p.force.iter().any(|f| !f.is_finite()) {
                return bad("push force is not finite", "use finite newtons");
            }
        }
        if let Some(s) = &self.sine
            && !(s.amplitude.is_finite()
                && s.frequency.is_finite()
                && s.frequency >= 0.0
                && s.axis.iter().all(|a| a.is_finite()))
        {
            return bad(
                "sinusoidal force has a non-finite amplitude or a negative frequency",
                "give --sine AMPLITUDE,FREQUENCY with finite numbers",
            );
        }
        if let InitialState::Pose(p) = &self.initial
            && p.iter().any(|v| !v.is_finite())
        {
            return bad("the pose has a non-finite angle", "use finite radians");
        }
        if let InitialState::AutoDepth(d) = self.initial
            && !(d.is_finite() && d > 0.0)
        {
            return bad(
                &format!("stand depth {d} m is not positive"),
                "give --depth the feet's depth below the hips in metres, e.g. 0.14",
            );
        }
        if !(self.fall_fraction.is_finite()
            && self.collapse_fraction.is_finite()
            && self.fall_tilt_deg.is_finite()
            && self.landing.is_finite()
            && self.settle_fraction.is_finite())
        {
            return bad("fall thresholds are not finite", "use finite numbers");
        }
        Ok(())
    }

    /// When tilt and torque start being measured: after the landing, or
    /// from the push if it comes first.
    pub fn measure_from(&self) -> f64 {
        match &self.push {
            Some(p) => self.landing.min(p.start),
            None => self.landing,
        }
    }

    /// When the push dip is known: the push's end plus the 1.5 s in which
    /// its minimum is sought.
    pub fn dip_end(&self) -> Option<f64> {
        self.push
            .as_ref()
            .map(|p| p.start + p.duration + crate::math::stats::DIP_AFTER)
    }

    /// What a run of this length cannot measure, one line each (empty for
    /// a long enough run): those metrics are left empty and its cells are
    /// never ranked by them.
    pub fn shortfalls(&self) -> Vec<String> {
        let mut out = Vec::new();
        let need = self.landing + self.window;
        if self.duration < need - 1e-9 {
            out.push(format!(
                "--seconds {} leaves no {} s window after the landing ({} s): last_1s_std_mm is left empty and no cell is ranked steadiest; use --seconds {need} or more",
                self.duration, self.window, self.landing
            ));
        }
        if let (Some(end), Some(p)) = (self.dip_end(), &self.push)
            && self.duration < end - 1e-9
        {
            out.push(format!(
                "--seconds {} ends before the push at {} s and the {} s after it are over: push_dip_mm and settle_time_s are left empty; use --seconds {end} or more, or --push-at earlier",
                self.duration,
                p.start,
                crate::math::stats::DIP_AFTER + p.duration
            ));
        }
        if self.duration <= self.measure_from() {
            out.push(format!(
                "--seconds {} ends before the landing is over ({} s): max_tilt_deg and peak_torque are left empty",
                self.duration,
                self.measure_from()
            ));
        }
        out
    }

    /// The steps of one cell at `dt`: how many a `while time < duration`
    /// loop makes, and those on which the push acts. Refused (before any
    /// stepping) when a cell would need more than [`MAX_STEPS`] steps.
    pub fn plan(&self, dt: f64) -> Result<StepPlan> {
        let estimate = self.duration / dt;
        let plannable = dt.is_finite() && dt > 0.0 && estimate <= MAX_STEPS as f64;
        if !plannable {
            return Err(Error::Config(format!(
                "timestep {dt:e} s makes {estimate:.3e} steps per {} s cell, over the limit of {MAX_STEPS:.0e}: use a larger timestep or fewer --seconds",
                self.duration
            )));
        }
        // The clock is the double `t += dt`, as MuJoCo keeps it: bounded
        // above, so this walk is short next to the stepping it plans.
        let push = self.push.as_ref().map(|p| (p.start, p.start + p.duration));
        let (mut first, mut last) = (None, 0);
        let mut t = 0.0f64;
        let mut n = 0usize;
        while t < self.duration {
            if let Some((a, b)) = push
                && a <= t
                && t < b
            {
                first.get_or_insert(n);
                last = n + 1;
            }
            t += dt;
            n += 1;
        }
        Ok(StepPlan {
            steps: n,
            push: first.map_or(0..0, |f| f..last),
        })
    }

    /// Number of samples in the statistics window at `dt`.
    pub fn window_samples(&self, dt: f64) -> usize {
        ((self.window / dt).round() as usize).max(1)
    }

    /// The continuous force at time `t` (before the step), world frame.
    pub fn sine_force(&self, t: f64) -> [f64; 3] {
        match &self.sine {
            Some(s) => {
                let f = s.amplitude * (2.0 * std::f64::consts::PI * s.frequency * t).sin();
                [f * s.axis[0], f * s.axis[1], f * s.axis[2]]
            }
            None => [0.0; 3],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chapter_push_acts_on_126_steps() {
        let s = Schedule::default();
        let plan = s.plan(0.002).unwrap();
        assert_eq!(plan.steps, 5000);
        assert_eq!(plan.push, 1000..1126);
        assert_eq!(s.window_samples(0.002), 500);
    }

    #[test]
    fn the_default_push_scales_with_mass_and_is_the_chapters_on_pupper() {
        // Pupper v3 as MuJoCo sums its bodies, and as written: exactly -25 N
        assert_eq!(default_push_n(3.1699999999999995), -25.0);
        assert_eq!(default_push_n(PUPPER_MASS_KG), PUPPER_PUSH_N);
        // the same newtons per kilogram, to 0.1 N
        assert_eq!(default_push_n(15.2), -119.9);
        assert_eq!(default_push_n(7.999999999999999), -63.1);
        assert_eq!(default_push_n(2.0 * PUPPER_MASS_KG), -50.0);
        let mut p = Push {
            by_weight: true,
            ..Push::default()
        };
        p.resolve(15.2).unwrap();
        assert_eq!((p.force, p.by_weight), ([0.0, 0.0, -119.9], false));
        // resolved once: a second model does not scale it again
        p.resolve(3.17).unwrap();
        assert_eq!(p.force[2], -119.9);
        // a given force is the user's
        let mut given = Push {
            force: [0.0, 0.0, -40.0],
            ..Push::default()
        };
        given.resolve(15.2).unwrap();
        assert_eq!(given.force[2], -40.0);
        let mut massless = Push {
            by_weight: true,
            ..Push::default()
        };
        let e = massless.resolve(0.0).unwrap_err().to_string();
        assert!(e.contains("--push-force"), "{e}");
    }

    #[test]
    fn no_push() {
        let s = Schedule {
            push: None,
            ..Schedule::default()
        };
        assert!(s.plan(0.002).unwrap().push.is_empty());
    }

    #[test]
    fn tiny_timesteps_are_refused_not_walked() {
        let s = Schedule::default();
        let e = s.plan(1e-17).unwrap_err().to_string();
        assert!(
            e.contains("timestep 1e-17") && e.contains("larger timestep"),
            "{e}"
        );
        assert!(s.plan(0.0).is_err() && s.plan(f64::NAN).is_err());
        // the largest allowed walk still plans
        let n = s.plan(10.0 / 1.0e6).unwrap().steps;
        assert!(n.abs_diff(1_000_000) <= 1, "{n}"); // the accumulated clock may round once
    }

    #[test]
    fn sine_force_values() {
        let s = Schedule {
            sine: Some(SineForce {
                amplitude: 2.0,
                frequency: 1.2,
                axis: [0.0, 0.0, 1.0],
            }),
            ..Schedule::default()
        };
        let f = s.sine_force(1.0 / (4.0 * 1.2));
        assert!((f[2] - 2.0).abs() < 1e-12);
        assert_eq!(f[0], 0.0);
    }

    #[test]
    fn validation() {
        let mut s = Schedule {
            duration: -1.0,
            ..Schedule::default()
        };
        assert!(s.validate().unwrap_err().to_string().contains("--seconds"));
        s.duration = 1.0;
        assert!(s.validate().is_ok());
        s.push.as_mut().unwrap().start = f64::NAN;
        assert!(s.validate().is_err());
    }
}
