//! `hold`: how firmly the gains hold the robot up under a load and against
//! a shove, as `pupper hold` runs it.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use pupper_core::request::hold::{self as request, HoldInput};
use pupper_core::request::spec::SweepSpec;
use pupper_core::results::best;

use super::sweep::{Kind, kind_command};
use crate::convert::keywords;
use crate::error::to_py;

kind_command! {
    /// `pupper_core.hold`: the hold experiment; `options` are its own
    /// keywords (load, ramp, shove, shove_at, shove_duration) and the sweep
    /// keywords (model, mode, kp, kd, seconds, pose, threads, ...). Writes
    /// best.csv (the stiffest cell) into a run directory.
    hold(HoldInput)
    // as inspect and help() show it: HoldInput's defaults, kept equal by a
    // test below
    "(grid=None, *, out=None, progress=None, load=1.0, ramp=2.0, shove=0.25, shove_at=None, shove_duration=0.25, **options)"
}

keywords!(HoldInput {
    load,
    ramp,
    shove,
    shove_at,
    shove_duration
});

impl Kind for HoldInput {
    const COMMAND: &'static str = "python: pupper_core.hold";

    fn seconds(&self) -> f64 {
        request::seconds(self)
    }

    fn spec(self, base: SweepSpec, _: Option<&Bound<'_, PyDict>>) -> PyResult<SweepSpec> {
        request::spec(base, &self).map_err(to_py)
    }

    /// The stiffest cell.
    fn rule(spec: &SweepSpec) -> Option<best::Rule> {
        Some(best::Rule::new(
            spec.experiment.plan().default_metric(),
            &[],
        ))
    }
}

#[cfg(test)]
mod tests {
    use pupper_core::request::hold::HoldInput;

    use crate::commands::sweep::kind_signature;
    use crate::convert::shown::assert_declares;

    #[test]
    fn the_text_signature_shows_the_defaults() {
        assert_declares(include_str!("hold.rs"), &kind_signature::<HoldInput>());
    }
}
