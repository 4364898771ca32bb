//! `pupper walk`: the options of the walk experiment, turned into a sweep
//! spec whose robot walks a gait. Its defaults are written here once, for
//! the CLI and Python.

use crate::error::{Error, Result};
use crate::plan::experiment::Experiment;
use crate::plan::grid::Axis;
use crate::plan::schedule::LANDING;
use crate::plan::walk::gait::Pattern;
use crate::plan::walk::{FREQUENCY, SECONDS, SPEED, Walk};
use crate::request::spec::SweepSpec;

/// What `pupper walk`'s own options ask for.
#[derive(Debug, Clone, PartialEq)]
pub struct WalkInput {
    /// trot, walk, pace or bound.
    pub gait: String,
    /// Gait cycles per second (Hz).
    pub frequency: f64,
    /// Commanded forward speed (m/s).
    pub speed: f64,
    /// Commanded sideways speed (m/s, to the left).
    pub sideways: f64,
    /// Commanded yaw rate (rad/s, to the left).
    pub yaw_rate: f64,
    /// None: the gait's own (0.75 for walk, 0.6 for the others).
    pub duty: Option<f64>,
    /// None: 6 cm on Pupper v3's legs, scaled to the model's.
    pub step_height: Option<f64>,
    /// The base's height above the floor while walking (m); None: the
    /// start pose's.
    pub height: Option<f64>,
}

impl Default for WalkInput {
    fn default() -> Self {
        WalkInput {
            gait: "trot".into(),
            frequency: FREQUENCY,
            speed: SPEED,
            sideways: 0.0,
            yaw_rate: 0.0,
            duty: None,
            step_height: None,
            height: None,
        }
    }
}

/// Simulated seconds unless `--seconds` says.
pub fn seconds(_w: &WalkInput) -> f64 {
    SECONDS
}

/// A sweep spec running the walk on `base` (its grid, gains, model,
/// seconds): the gait starts after the landing.
pub fn spec(base: SweepSpec, w: &WalkInput) -> Result<SweepSpec> {
    if base.variant != "original" {
        return Err(Error::Config(format!(
            "--variant {}: a walk runs the gait on the compiled model's own legs; give the other body as its own --model",
            base.variant
        )));
    }
    let mut walk = Walk::new(
        Pattern::parse(&w.gait)?,
        [w.speed, w.sideways, w.yaw_rate],
        LANDING,
    );
    walk.frequency = w.frequency;
    if let Some(d) = w.duty {
        walk.duty = d;
    }
    walk.step_height = w.step_height;
    walk.height = w.height;
    Ok(SweepSpec {
        push: false,
        experiment: Experiment::Walk(walk),
        ..base
    })
}

/// The axes whose settings each get their best walker: a grid's gait axes
/// (frequency, speed, duty, step_height), where it varies something else
/// too (the gains); a grid of gait axes alone is ranked whole.
pub fn best_by(axes: &[Axis]) -> Vec<String> {
    let gait = |a: &&Axis| a.kind() == Some("walk");
    if axes.iter().all(|a| gait(&a)) {
        return Vec::new();
    }
    axes.iter()
        .filter(gait)
        .map(|a| a.name().to_string())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_best_walker_is_picked_per_gait_setting() {
        assert_eq!(best_by(&[Axis::Kp, Axis::Speed]), ["speed"]);
        assert_eq!(
            best_by(&[Axis::Speed, Axis::Kd, Axis::Duty]),
            ["speed", "duty"]
        );
        assert!(best_by(&[Axis::Speed, Axis::Frequency]).is_empty());
        assert!(best_by(&[Axis::Kp]).is_empty());
    }

    #[test]
    fn a_walk_has_no_push_and_one_body() {
        let s = spec(SweepSpec::default(), &WalkInput::default()).unwrap();
        assert!(!s.push && s.experiment.name() == "walk");
        let long = SweepSpec {
            variant: "long-leg".into(),
            ..SweepSpec::default()
        };
        let e = spec(long, &WalkInput::default()).unwrap_err().to_string();
        assert!(e.contains("--variant long-leg"), "{e}");
        let gallop = WalkInput {
            gait: "gallop".into(),
            ..WalkInput::default()
        };
        assert!(spec(SweepSpec::default(), &gallop).is_err());
    }
}
