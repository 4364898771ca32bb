//! `pupper hold`: the options of the hold experiment, turned into a sweep
//! spec whose robot stands under a ramped load and is then shoved sideways.
//! Its defaults are written here once, for the CLI and Python.

use crate::plan::experiment::Experiment;
use crate::plan::hold::{LOAD, Load, RAMP, SHOVE, SHOVE_DURATION, WINDOW};
use crate::plan::schedule::LANDING;
use crate::request::spec::SweepSpec;

/// What `pupper hold`'s own options ask for.
#[derive(Debug, Clone, PartialEq)]
pub struct HoldInput {
    /// Full load in multiples of the robot's weight.
    pub load: f64,
    /// Seconds of ramp.
    pub ramp: f64,
    /// The lateral shove in multiples of the weight (0: none).
    pub shove: f64,
    /// When the shove starts (s); None: after the ramp and the loaded
    /// window.
    pub shove_at: Option<f64>,
    pub shove_duration: f64,
}

impl Default for HoldInput {
    fn default() -> Self {
        HoldInput {
            load: LOAD,
            ramp: RAMP,
            shove: SHOVE,
            shove_at: None,
            shove_duration: SHOVE_DURATION,
        }
    }
}

/// When the shove comes unless `--shove-at` says: the end of the ramp
/// plus one loaded window, after a landing of [`LANDING`] s.
pub fn default_shove_at(ramp: f64) -> f64 {
    LANDING + ramp + WINDOW
}

/// Simulated seconds unless `--seconds` says: to the shove's end, its dip
/// window and a last second.
pub fn seconds(h: &HoldInput) -> f64 {
    match h.shove_at {
        None => crate::plan::hold::SECONDS,
        Some(at) => at + h.shove_duration + crate::math::stats::DIP_AFTER + 1.0,
    }
}

/// A sweep spec running the hold experiment on `base` (its grid, gains,
/// model, seconds): the load starts when the landing ends.
pub fn spec(base: SweepSpec, h: &HoldInput) -> SweepSpec {
    let load = Load::new(h.load, LANDING, h.ramp, h.shove);
    SweepSpec {
        push: h.shove > 0.0,
        push_at: h.shove_at.unwrap_or_else(|| default_shove_at(h.ramp)),
        push_duration: h.shove_duration,
        experiment: Experiment::Hold(load),
        ..base
    }
}
