//! `pupper hold`: the options of the hold experiment, turned into a sweep
//! spec whose robot stands under a ramped load and is then shoved sideways.
//! Its defaults are written here once, for the CLI and Python.

use crate::error::{Error, Result};
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
/// Refuses a hold's own times by their own flags (the shove becomes the
/// sweep's push, whose checks would name `--push-at`).
pub fn spec(base: SweepSpec, h: &HoldInput) -> Result<SweepSpec> {
    for (flag, v) in [
        ("--ramp", Some(h.ramp)),
        ("--shove-at", h.shove_at),
        ("--shove-duration", Some(h.shove_duration)),
    ] {
        if let Some(v) = v
            && !(v.is_finite() && v >= 0.0)
        {
            return Err(Error::Config(format!("{flag} {v} must be a time >= 0 s")));
        }
    }
    let load = Load::new(h.load, LANDING, h.ramp, h.shove);
    Ok(SweepSpec {
        push: h.shove > 0.0,
        push_at: h.shove_at.unwrap_or_else(|| default_shove_at(h.ramp)),
        push_duration: h.shove_duration,
        experiment: Experiment::Hold(load),
        ..base
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn built(seconds: f64, h: &HoldInput) -> crate::error::Result<crate::request::spec::Sweep> {
        spec(
            SweepSpec {
                seconds,
                ..SweepSpec::default()
            },
            h,
        )?
        .build()
    }

    #[test]
    fn a_bad_time_is_named_by_holds_own_flag() {
        for (h, flag) in [
            (
                HoldInput {
                    ramp: f64::NAN,
                    ..HoldInput::default()
                },
                "--ramp NaN",
            ),
            (
                HoldInput {
                    shove_at: Some(-2.0),
                    ..HoldInput::default()
                },
                "--shove-at -2",
            ),
            (
                HoldInput {
                    shove_duration: -1.0,
                    ..HoldInput::default()
                },
                "--shove-duration -1",
            ),
        ] {
            let e = built(10.0, &h).err().unwrap().to_string();
            assert!(e.contains(flag) && !e.contains("--push"), "{e}");
        }
    }

    #[test]
    fn a_run_must_reach_the_end_of_the_shoves_dip_window() {
        let h = HoldInput::default();
        // the shove at 3.5 s for 0.25 s, its dip known 1.5 s after: 5.25 s
        let e = built(3.6, &h).err().unwrap().to_string();
        assert!(e.contains("--seconds 3.6 ends before the shove"), "{e}");
        assert!(e.contains("give --seconds 5.25 or more"), "{e}");
        assert!(built(5.25, &h).is_ok());
        // no shove: the loaded window is all it needs
        let calm = HoldInput {
            shove: 0.0,
            ..HoldInput::default()
        };
        assert!(built(3.6, &calm).is_ok());
        // a late shove asks for the seconds that reach its window's end
        let late = HoldInput {
            shove_at: Some(100.0),
            ..HoldInput::default()
        };
        let e = built(7.0, &late).err().unwrap().to_string();
        assert!(e.contains("give --seconds 101.75 or more"), "{e}");
        assert_eq!(seconds(&late), 102.75);
        assert!(built(seconds(&late), &late).is_ok());
    }
}
