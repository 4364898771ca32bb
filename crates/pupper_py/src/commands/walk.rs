//! `walk`: how well each gain cell walks a gait, as `pupper walk` runs it.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use pupper_core::request::spec::SweepSpec;
use pupper_core::request::walk::{self as request, WalkInput};
use pupper_core::results::best;

use super::sweep::{Kind, kind_command};
use crate::convert::keywords;
use crate::error::to_py;

kind_command! {
    /// `pupper_core.walk`: the walk experiment; `options` are its own
    /// keywords (gait, frequency, speed, sideways, yaw_rate, duty,
    /// step_height, height) and the sweep keywords (model, mode, kp, kd,
    /// seconds, pose, replicates, randomize, threads, ...). Writes best.csv
    /// (the best walker of each gait setting) into a run directory.
    walk(WalkInput)
    // as inspect and help() show it: WalkInput's defaults, kept equal by a
    // test below
    "(grid=None, *, out=None, progress=None, gait='trot', frequency=2.0, speed=0.25, sideways=0.0, yaw_rate=0.0, duty=None, step_height=None, height=None, **options)"
}

keywords!(WalkInput {
    gait,
    frequency,
    speed,
    sideways,
    yaw_rate,
    duty,
    step_height,
    height
});

impl Kind for WalkInput {
    const COMMAND: &'static str = "python: pupper_core.walk";

    fn seconds(&self) -> f64 {
        request::seconds(self)
    }

    fn spec(self, base: SweepSpec, _: Option<&Bound<'_, PyDict>>) -> PyResult<SweepSpec> {
        request::spec(base, &self).map_err(to_py)
    }

    /// The best walker of each gait setting: the lowest speed error (over
    /// the replicates, its worst side).
    fn rule(spec: &SweepSpec) -> Option<best::Rule> {
        let sweep = spec.build().ok()?;
        let metric = spec.experiment.plan().default_metric();
        let metric = match sweep.config.replicates.is_plain() {
            true => metric.to_string(),
            false => best::robust(metric),
        };
        let axes: Vec<_> = sweep.config.grid.axes.iter().map(|a| a.axis).collect();
        Some(best::Rule::new(&metric, &request::best_by(&axes)))
    }
}

#[cfg(test)]
mod tests {
    use pupper_core::request::walk::WalkInput;

    use crate::commands::sweep::kind_signature;
    use crate::convert::shown::assert_declares;

    #[test]
    fn the_text_signature_shows_the_defaults() {
        assert_declares(include_str!("walk.rs"), &kind_signature::<WalkInput>());
    }
}
