//! `pupper gains`: PD gains from each joint's reflected inertia, or what
//! given gains do, with the stability bound at the model's timestep.

use clap::Args;
use pupper_core::request::spec;
use pupper_core::{Error, Result};
use pupper_mujoco::api;

use super::args::ModelArg;
use crate::print;

#[derive(Args, Debug)]
#[command(
    after_help = "Stability: MuJoCo's Euler integrator (and pupper's torque mode) applies a PD
force computed from the state at the start of each step, then steps velocity and position
semi-implicitly. With a = h^2 kp / I and b = h kd / I (h the timestep, I the joint's inertia) that
discrete system is stable exactly when a + 2b < 4 and b < 2 (Jury's test on its characteristic
polynomial z^2 - (2 - a - b) z + (1 - b)). stability_margin = max((a + 2b)/4, b/2): 1 or more is
past the bound, where the joint chatters or diverges. With --integrator implicitfast (or implicit)
a servo's damping is integrated implicitly: stable exactly when a < 4 + 2b, stability_margin =
a / (4 + 2b). A sweep marks cells past the bound past_bound and never ranks them.
Loop margins (with --motor or --sensing-delay): each joint linearised at the pose, its reflected
inertia driven by kp + kd s through the feedback path's latency (the sensing delay plus half the
PD's update period: --motor rate=HZ, else the physics step), the derivative's low-pass filter
(filter=HZ) and, with encoder counts, half a period more on the derivative (a difference over one
period); no viscous damping (the conservative case). phase_margin_deg: 180 plus the phase of
the open loop where its gain is 1 (below 0: the real joint oscillates or runs away however the
simulation looks); gain_margin_db: how much more loop gain makes it unstable (inf: none does;
-inf: the phase starts past -180°, kd/kp shorter than the lag and latency, and no gain is stable;
\"inf\" and \"-inf\" in --json, floats in pc.gains; NaN is null). A command delay
(delay=S) is not in the loop: it shifts the step response, not these margins.
On a calibrated model (gain scales pupper:kp_scale:ACT, pupper:kd_scale:ACT: `pupper fit`'s)
kp and kd are what to command; motor kp and motor kd are what each motor delivers of them, and
every other figure is of the delivered gains. A --bandwidth's gains are divided by the scales.

Examples:
  pupper gains --bandwidth 8 --damping 0.7
  pupper gains --kp 20 --kd 0.5 --json
  pupper gains --kp 10 --kd 1 --motor rate=500 --sensing-delay 0.001"
)]
pub(super) struct GainsArgs {
    #[command(flatten)]
    model: ModelArg,
    /// A `pupper fit` run directory: its calibrated model, the loop the fit found (checked
    /// against the run's manifest first). In place of --model.
    #[arg(long, value_name = "DIR", conflicts_with = "model")]
    from_fit: Option<std::path::PathBuf>,
    /// The −3 dB bandwidth (Hz) the gains should give.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true, conflicts_with_all = ["kp", "kd"])]
    bandwidth: Option<f64>,
    /// The damping ratio with --bandwidth.
    #[arg(long, default_value_t = 0.7, value_name = "ZETA", allow_negative_numbers = true)]
    damping: f64,
    /// Given gains: their natural frequency, damping ratio and stability margin per joint.
    #[arg(long, allow_negative_numbers = true, requires = "kd")]
    kp: Option<f64>,
    #[arg(long, allow_negative_numbers = true, requires = "kp")]
    kd: Option<f64>,
    /// The pose the inertias are read at, one angle per actuator [default: the stand pose].
    #[arg(long, value_name = "Q1,Q2,...", allow_hyphen_values = true)]
    pose: Option<String>,
    /// MuJoCo's integrator the bound is for: euler, implicitfast, implicit [default: the
    /// model's own]. Torque mode's PD is explicit whatever the integrator.
    #[arg(long, value_name = "NAME")]
    integrator: Option<String>,
    /// The servo firmware whose loop margins to state (see `pupper sweep --help`'s --motor:
    /// rate, filter, counts, delay, noload, lag).
    #[arg(long, value_name = "SPEC")]
    motor: Option<String>,
    /// How old the firmware's measurements are when the PD uses them (s), for the loop margins.
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    sensing_delay: Option<f64>,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

impl GainsArgs {
    pub(super) fn run(&self) -> Result<u8> {
        use pupper_core::robot::gains::Ask;
        let ask = match (self.bandwidth, self.kp, self.kd) {
            (Some(hz), _, _) => Ask::Bandwidth {
                hz,
                zeta: self.damping,
            },
            (None, Some(kp), Some(kd)) => Ask::Gains { kp, kd },
            _ => {
                return Err(Error::Config(
                    "pupper gains needs --bandwidth HZ (with --damping, default 0.7) or --kp and --kd".into(),
                ));
            }
        };
        let pose = match self.pose.as_deref().map(spec::parse_pose).transpose()? {
            Some(spec::PoseInput::Angles(p)) => Some(p),
            _ => None,
        };
        let source = match &self.from_fit {
            Some(dir) => pupper_core::robot::model::ModelSource::Path(
                pupper_core::results::fit_run::calibrated(dir)?,
            ),
            None => self.model.source()?,
        };
        let r = api::gains(
            &source,
            pose,
            ask,
            self.integrator.as_deref(),
            self.motor.as_deref(),
            self.sensing_delay,
        )?;
        if self.json {
            outln!("{}", print::json(&r)?);
        } else {
            outp!("{}", print::gains(&r));
        }
        Ok(0)
    }
}
