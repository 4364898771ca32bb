//! `response`: how each joint follows its target, as `pupper response`
//! runs it.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use pupper_core::request::response::{self as request, SignalInput};
use pupper_core::request::spec::SweepSpec;

use super::sweep::{Kind, kind_command};
use crate::convert::{given, keywords};
use crate::error::to_py;

kind_command! {
    /// `pupper_core.response`: the response experiment, as `pupper response`
    /// runs it. `options` are its own keywords (the signal, hold, joints,
    /// standing) and the sweep keywords (model, mode, kp, kd, seconds, pose,
    /// threads, replicates, ...).
    response(ResponseOptions)
    // as inspect and help() show it: ResponseOptions' defaults, kept equal
    // by a test below
    "(grid=None, *, out=None, progress=None, signal='step', amplitude=0.2, frequency=None, chirp=None, hold=0.5, joints=(), standing=False, **options)"
}

/// `response`'s own keywords: the signal (`SignalInput`'s fields), the
/// hold before it, the joints it excites, and whether the robot stands.
pub(crate) struct ResponseOptions {
    signal: String,
    amplitude: f64,
    frequency: Option<f64>,
    chirp: Option<[f64; 2]>,
    hold: f64,
    joints: Vec<String>,
    standing: bool,
}

impl Default for ResponseOptions {
    fn default() -> Self {
        let signal = SignalInput::default();
        ResponseOptions {
            signal: signal.kind,
            amplitude: signal.amplitude,
            frequency: signal.frequency,
            chirp: signal.chirp,
            hold: request::DEFAULT_HOLD,
            joints: Vec::new(),
            standing: false,
        }
    }
}

keywords!(ResponseOptions {
    signal,
    amplitude,
    frequency,
    chirp,
    hold,
    joints,
    standing
});

impl Kind for ResponseOptions {
    const COMMAND: &'static str = "python: pupper_core.response";

    fn seconds(&self) -> f64 {
        request::SECONDS
    }

    /// From its searched stand pose unless a pose or keyframe is given.
    fn spec(self, base: SweepSpec, options: Option<&Bound<'_, PyDict>>) -> PyResult<SweepSpec> {
        let signal = SignalInput {
            kind: self.signal,
            amplitude: self.amplitude,
            frequency: self.frequency,
            chirp: self.chirp,
        };
        let keyframe = given(options, "keyframe");
        request::spec(
            base,
            &signal,
            self.hold,
            &self.joints,
            self.standing,
            keyframe,
        )
        .map_err(to_py)
    }
}

#[cfg(test)]
mod tests {
    use super::ResponseOptions;
    use crate::commands::sweep::kind_signature;
    use crate::convert::shown::assert_declares;

    #[test]
    fn the_text_signature_shows_the_defaults() {
        assert_declares(
            include_str!("response.rs"),
            &kind_signature::<ResponseOptions>(),
        );
    }
}
