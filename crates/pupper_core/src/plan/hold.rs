//! The hold kind's plan (`pupper hold`): the robot stands, a vertical load
//! ramps onto its base up to a multiple of its own weight, is held, and a
//! lateral shove follows. What it measures is in `sim::hold`, its tables in
//! `results::kinds::hold`.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::plan::grid::{Axis, Grid};
use crate::plan::kind::{KindPlan, OnModel};
use crate::plan::schedule::Schedule;
use crate::robot::model::ModelInfo;

/// The load at full ramp, in multiples of the robot's weight.
pub const LOAD: f64 = 1.0;
/// Seconds the load takes to ramp from 0 to full.
pub const RAMP: f64 = 2.0;
/// The lateral shove, in multiples of the robot's weight.
pub const SHOVE: f64 = 0.25;
/// Seconds the shove lasts.
pub const SHOVE_DURATION: f64 = 0.25;
/// Seconds of steady load before the shove, over which the loaded height
/// and the standing torques are measured (also the unloaded window before
/// the ramp).
pub const WINDOW: f64 = 0.5;
/// Simulated seconds unless `--seconds` says: landing, ramp, steady load,
/// the shove, and the push dip's 1.5 s and a last second after it.
pub const SECONDS: f64 = 7.0;

/// A vertical load on a standing robot, then a lateral shove.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Load {
    /// Full load, in multiples of the robot's weight.
    pub weights: f64,
    /// When the ramp starts (s): the end of the landing.
    pub start: f64,
    /// Seconds from no load to full load.
    pub ramp: f64,
    /// The lateral shove (along the world's y), in multiples of the weight.
    pub shove: f64,
    /// Resolved on the compiled model: its weight (N), total mass times
    /// the magnitude of its gravity. 0 until resolved.
    #[serde(default)]
    pub weight: f64,
    /// Resolved: each actuator's joint group (haa, hfe, kfe, or other).
    #[serde(default)]
    pub groups: Vec<String>,
    /// Resolved: each actuator's torque constant (N·m/A) and winding
    /// resistance (Ω), where the model declares them; copper loss is
    /// reported when any does.
    #[serde(default)]
    pub winding: Vec<Option<[f64; 2]>>,
}

impl Load {
    pub fn new(weights: f64, start: f64, ramp: f64, shove: f64) -> Load {
        Load {
            weights,
            start,
            ramp,
            shove,
            weight: 0.0,
            groups: Vec::new(),
            winding: Vec::new(),
        }
    }

    /// The full load (N), once resolved.
    pub fn full(&self) -> f64 {
        self.weights * self.weight
    }

    /// When the load is full (s).
    pub fn loaded_at(&self) -> f64 {
        self.start + self.ramp
    }

    /// The load at time `t` (N, downwards positive).
    pub fn at(&self, t: f64) -> f64 {
        let f = if self.ramp > 0.0 {
            ((t - self.start) / self.ramp).clamp(0.0, 1.0)
        } else if t >= self.start {
            1.0
        } else {
            0.0
        };
        f * self.full()
    }

    /// The joint groups that appear, in the model's order of groups.
    pub fn group_names(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for g in crate::robot::model::JOINT_GROUPS
            .iter()
            .map(|g| g.to_string())
            .chain(std::iter::once("other".to_string()))
        {
            if self.groups.contains(&g) {
                out.push(g);
            }
        }
        out
    }

    /// Whether the model declares a winding for any actuator.
    pub fn copper(&self) -> bool {
        self.winding.iter().any(Option::is_some)
    }

    /// Weight, joint groups and windings of the compiled model; the
    /// schedule's push becomes the lateral shove at the model's own weight.
    pub fn resolve(&mut self, info: &ModelInfo, schedule: &mut Schedule) -> Result<()> {
        let g = info.gravity.iter().map(|v| v * v).sum::<f64>().sqrt();
        self.weight = info.total_mass * g;
        if !(self.weight.is_finite() && self.weight > 0.0) {
            return Err(Error::Config(format!(
                "model '{}' weighs {} N (mass {} kg, gravity {g} m/s^2): a hold needs a robot with weight; give the model mass and gravity",
                info.name, self.weight, info.total_mass
            )));
        }
        self.groups = (0..info.nu)
            .map(|a| info.actuator_group(a).unwrap_or("other").to_string())
            .collect();
        self.winding = info.actuators.iter().map(|a| a.winding).collect();
        if let Some(p) = schedule.push.as_mut() {
            p.force = [0.0, -self.shove * self.weight, 0.0];
            p.by_weight = false;
        }
        Ok(())
    }

    /// The window of steady load before the shove (s), or before the end
    /// of the run when there is no shove.
    pub fn loaded_window(&self, schedule: &Schedule) -> (f64, f64) {
        let end = schedule
            .push
            .as_ref()
            .map_or(schedule.duration, |p| p.start);
        (end - WINDOW, end)
    }

    /// The unloaded window: the `WINDOW` s before the ramp starts.
    pub fn free_window(&self) -> (f64, f64) {
        (self.start - WINDOW, self.start)
    }
}

impl KindPlan for Load {
    fn name(&self) -> &'static str {
        "hold"
    }

    fn resolve(&mut self, m: &OnModel<'_>, schedule: &mut Schedule) -> Result<()> {
        Load::resolve(self, m.info, schedule)
    }

    fn base_force(&self, t: f64) -> [f64; 3] {
        [0.0, 0.0, -self.at(t)]
    }

    fn varying_force(&self) -> bool {
        true
    }

    /// The stiffest cell: the least sag per newton of load.
    fn default_metric(&self) -> &'static str {
        "compliance_mm_per_n"
    }

    /// The load needs a standing window before it and a steady one before
    /// the shove; a push_force axis would replace the shove's direction.
    fn check(&self, s: &Schedule, grid: &Grid, replicated: bool) -> Result<()> {
        let bad = |what: String| Err(Error::Config(what));
        for (flag, v) in [
            ("--load", self.weights),
            ("--ramp", self.ramp),
            ("--shove", self.shove),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{flag} {v} must be a finite number >= 0"));
            }
        }
        if self.weights > 10.0 {
            return bad(format!(
                "--load {} asks for {} times the robot's weight: give at most 10",
                self.weights, self.weights
            ));
        }
        if self.free_window().0 < 0.0 {
            return bad(format!(
                "the load starts at {} s, leaving no {WINDOW} s of standing before it to measure the unloaded height: start it at {WINDOW} s or later",
                self.start
            ));
        }
        let (from, to) = self.loaded_window(s);
        if from < self.loaded_at() - 1e-9 {
            return bad(format!(
                "the load is full at {} s but the shove comes at {to} s: leave {WINDOW} s of steady load before it (--shove-at {} or later, or a shorter --ramp)",
                self.loaded_at(),
                self.loaded_at() + WINDOW
            ));
        }
        // with a shove, its sway and recovery are measured until its dip is
        // known (its end and 1.5 s): a run must reach that too
        let need = s.dip_end().filter(|_| s.push.is_some()).unwrap_or(to);
        if s.duration < to - 1e-9 {
            return bad(format!(
                "--seconds {} ends before the load has been steady for {WINDOW} s ({to} s): give --seconds {need} or more",
                s.duration
            ));
        }
        if let Some(p) = &s.push
            && s.duration < need - 1e-9
        {
            return bad(format!(
                "--seconds {} ends before the shove at {} s and the {} s after it are over, which sway_mm and recovery_s are measured over: give --seconds {need} or more, or --shove 0 for none",
                s.duration,
                p.start,
                p.duration + crate::math::stats::DIP_AFTER
            ));
        }
        if replicated {
            return bad(
                "pupper hold runs one robot per cell: drop --replicates and --randomize (a robust hold is not built yet)"
                    .into(),
            );
        }
        if grid.has_axis(Axis::PushForce) {
            return bad(
                "a hold's shove is --shove, in multiples of the robot's weight: drop the push_force grid axis"
                    .into(),
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_load_ramps_linearly_to_its_weight_and_stays() {
        let mut l = Load::new(1.5, 1.0, 2.0, 0.25);
        l.weight = 20.0;
        assert_eq!(l.at(0.5), 0.0);
        assert_eq!(l.at(1.0), 0.0);
        assert_eq!(l.at(2.0), 15.0);
        assert_eq!(l.at(3.0), 30.0);
        assert_eq!(l.at(9.0), 30.0);
        assert_eq!(l.base_force(2.0), [0.0, 0.0, -15.0]);
        let step = Load::new(1.0, 1.0, 0.0, 0.0);
        let mut s = step.clone();
        s.weight = 10.0;
        assert_eq!((s.at(0.99), s.at(1.0)), (0.0, 10.0));
    }

    #[test]
    fn groups_are_listed_once_in_the_models_order() {
        let mut l = Load::new(1.0, 1.0, 2.0, 0.25);
        l.groups = ["kfe", "haa", "kfe", "other", "hfe"]
            .map(String::from)
            .to_vec();
        assert_eq!(l.group_names(), ["haa", "hfe", "kfe", "other"]);
        assert!(!l.copper());
        l.winding = vec![None, Some([0.1, 0.5])];
        assert!(l.copper());
    }
}
