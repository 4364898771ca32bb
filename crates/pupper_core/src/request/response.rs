//! `pupper response`: the options of the response experiment, turned into
//! a sweep spec whose config excites joints instead of pushing the robot.

use crate::error::{Error, Result};
use crate::plan::response::{AMPLITUDE, Excitation, HOLD, Signal};
use crate::request::spec::{AutoPose, PoseInput, SweepSpec};

/// Simulated seconds per cell unless `--seconds` says.
pub const SECONDS: f64 = 3.0;
/// The chirp's band unless `--chirp` says (Hz).
pub const CHIRP: [f64; 2] = [0.5, 20.0];

/// What `--signal` and its companions ask for.
#[derive(Debug, Clone, PartialEq)]
pub struct SignalInput {
    pub kind: String,
    pub amplitude: f64,
    pub frequency: Option<f64>,
    pub chirp: Option<[f64; 2]>,
}

impl Default for SignalInput {
    fn default() -> Self {
        SignalInput {
            kind: "step".into(),
            amplitude: AMPLITUDE,
            frequency: None,
            chirp: None,
        }
    }
}

impl SignalInput {
    pub fn signal(&self) -> Result<Signal> {
        let amplitude = self.amplitude;
        match (self.kind.as_str(), self.frequency, self.chirp) {
            ("step", None, None) => Ok(Signal::Step { amplitude }),
            ("sine", Some(hz), None) => Ok(Signal::Sine { amplitude, hz }),
            ("sine", None, _) => Err(Error::Config(
                "--signal sine needs --frequency HZ (e.g. 2)".into(),
            )),
            ("chirp", None, c) => {
                let [f0, f1] = c.unwrap_or(CHIRP);
                Ok(Signal::Chirp { amplitude, f0, f1 })
            }
            ("step" | "sine" | "chirp", _, _) => Err(Error::Config(format!(
                "--frequency goes with --signal sine and --chirp with --signal chirp; this is --signal {}",
                self.kind
            ))),
            (other, _, _) => Err(Error::Config(format!(
                "--signal {other} is unknown: use step, sine or chirp"
            ))),
        }
    }
}

/// A sweep spec running the response experiment: the robot from its
/// searched stand pose (unless a pose or keyframe is given), no push.
pub fn spec(
    base: SweepSpec,
    signal: &SignalInput,
    hold: f64,
    joints: &[String],
    standing: bool,
    keyframe_given: bool,
) -> Result<SweepSpec> {
    let excitation = Excitation {
        signal: signal.signal()?,
        hold,
        select: joints.to_vec(),
        standing,
        joints: Vec::new(),
        names: Vec::new(),
        groups: Vec::new(),
        inertia: Vec::new(),
    };
    let pose = match (&base.pose, keyframe_given) {
        (None, false) => Some(PoseInput::Auto(AutoPose::Auto)),
        (p, _) => p.clone(),
    };
    Ok(SweepSpec {
        push: false,
        pose,
        experiment: crate::plan::experiment::Experiment::Response(excitation),
        ..base
    })
}

/// `--chirp F0,F1`.
pub fn parse_chirp(text: &str) -> Result<[f64; 2]> {
    let parts: Vec<f64> = text
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| Error::Config(format!("--chirp '{text}': write F0,F1 in Hz, e.g. 0.5,20")))?;
    match parts[..] {
        [f0, f1] => Ok([f0, f1]),
        _ => Err(Error::Config(format!(
            "--chirp '{text}': write two frequencies F0,F1 in Hz, e.g. 0.5,20"
        ))),
    }
}

/// Default hold before the signal (s).
pub const DEFAULT_HOLD: f64 = HOLD;
