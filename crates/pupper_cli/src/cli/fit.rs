//! `pupper excite` and `pupper fit`: the excitation to play on the robot,
//! and the model fitted to the logs it gives. Both run in Python.

use std::path::PathBuf;

use clap::Args;
use pupper_core::{Error, Result};
use serde::Serialize;

use super::args::{ModelArg, rundir_name};
use super::python::python_command;
use crate::pyargs;
use pupper_mujoco::bridge::calls;

#[derive(Args, Debug, Serialize)]
#[command(
    after_help = "The log (CSV, plain or gzip/bzip2/xz-compressed): `# key: value` lines, then a header
time,ACTUATOR.target,ACTUATOR.q[,ACTUATOR.qd][,ACTUATOR.tau],... in s, rad, rad/s, N·m, for any
subset of the actuators, time stamps as recorded. Keys: kp and kd (the gains in use: one value, or
one per actuator in column order; required, or given to fit: --kp/--kd, LOG::kp=K,kd=D,
--gains-from-name), mode (servo or torque), base (suspended), held (what the others hold), columns
(a map of the log's own names, e.g. `# columns: time=stamp,leg_front_r_3.q=fr_knee_pos:deg`; fit
--columns). Play the file's targets on the robot, hung in the air, at
its gains; log the measured angles (and velocities, torques where the servos report them) into the
same columns. The format, the fit and the motor model: docs/fit.md.

Examples:
  pupper excite -o excite.csv                      8 s per joint group at the model's own gains
  pupper excite --kd 0.3 --signal chirp -o excite_kd03.csv   a second log at another kd
  pupper excite --joints leg_front_r_3 --rate 250 -o stand.csv   one motor on a test stand"
)]
pub(super) struct ExciteArgs {
    #[command(flatten)]
    #[serde(flatten)]
    model: ModelArg,
    /// The log to write.
    #[arg(long, short = 'o', value_name = "FILE", default_value = "excite.csv")]
    #[serde(serialize_with = "pyargs::path")]
    out: PathBuf,
    /// Overwrite --out.
    #[arg(long)]
    force: bool,
    /// Kp of every actuator [default: each actuator's own]
    #[arg(long, allow_negative_numbers = true)]
    kp: Option<f64>,
    /// Kd of every actuator [default: each actuator's own]
    #[arg(long, allow_negative_numbers = true)]
    kd: Option<f64>,
    /// multisine (8 log-spaced sines with low crest factor) or chirp (logarithmic sweep).
    #[arg(long, default_value = "multisine", value_name = "NAME")]
    signal: String,
    /// The excited band (Hz), F0,F1.
    #[arg(long, default_value = "0.3,6", value_name = "F0,F1")]
    #[serde(skip)]
    band: String,
    /// Seconds of excitation per joint group.
    #[arg(long, default_value_t = 8.0, value_name = "S", allow_negative_numbers = true)]
    seconds: f64,
    /// Seconds held at the rest pose before and between groups.
    #[arg(long, default_value_t = 1.0, value_name = "S", allow_negative_numbers = true)]
    hold: f64,
    /// Largest swing of a joint from its rest angle (rad); smaller where the range, the speed
    /// limit or the torque limit at the gains asks.
    #[arg(long, default_value_t = 0.3, value_name = "RAD", allow_negative_numbers = true)]
    amplitude: f64,
    /// Fastest commanded joint speed (rad/s).
    #[arg(long, default_value_t = 8.0, value_name = "RAD_S", allow_negative_numbers = true)]
    max_velocity: f64,
    /// Seed of the multisine's phases (a whole number >= 0).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The actuators excited and logged, comma-separated (names, or joint groups haa, hfe, kfe);
    /// the others hold their rest angle and are not in the log (a test stand) [default: all]
    #[arg(long, value_name = "NAMES")]
    joints: Option<String>,
    /// The log's sample rate (Hz): the physics rate divided by a whole number, and fast enough for
    /// fit (twice the fastest joint's natural frequency at the gains, and the band's top); the
    /// targets are held between samples, as the servo holds them [default: the physics rate]
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    rate: Option<f64>,
}

/// What `pupper_core._fit._cli_excite` is given: the flags, the band as
/// the two numbers read from --band.
#[derive(Serialize)]
struct ExciteCall<'a> {
    #[serde(flatten)]
    args: &'a ExciteArgs,
    band: Vec<f64>,
}

impl ExciteArgs {
    pub(super) fn run(&self) -> Result<u8> {
        let band: Vec<f64> = self
            .band
            .split(',')
            .map(|v| v.trim().parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| {
                Error::Config(format!(
                    "--band {} is not two numbers F0,F1 (Hz): give e.g. 0.3,6",
                    self.band
                ))
            })?;
        if band.len() != 2 || band.iter().any(|f| !f.is_finite()) {
            return Err(Error::Config(format!(
                "--band {} is not two numbers F0,F1 (Hz): give e.g. 0.3,6",
                self.band
            )));
        }
        // JSON writes NaN as null, which Python would read as "not given"
        let given = [("kp", self.kp), ("kd", self.kd), ("rate", self.rate)];
        let numbers = [
            ("seconds", Some(self.seconds)),
            ("hold", Some(self.hold)),
            ("amplitude", Some(self.amplitude)),
            ("max-velocity", Some(self.max_velocity)),
        ];
        for (flag, v) in given.into_iter().chain(numbers) {
            if let Some(v) = v.filter(|v| !v.is_finite()) {
                return Err(Error::Config(format!(
                    "--{flag} {v} is not a finite number: give --{flag} a number"
                )));
            }
        }
        let call = ExciteCall { args: self, band };
        let text = pyargs::to_text(&call).map_err(|e| Error::Internal(e.to_string()))?;
        python_command(&calls::EXCITE, &text)
    }
}

#[derive(Args, Debug, Serialize)]
#[command(
    after_help = "The fit replays each log through the model hung in the air (free joint removed,
contacts off) at the log's gains and fits the angles (and velocities and torques where
logged) by mujoco.sysid's bounded Levenberg-Marquardt. With angles only, joint damping and the
servo's kd act as one damping: fit a second log at another kd (pupper excite --kd) or log torque,
or leave one of them out of --params; fit warns when they are confounded. calibrated.xml keeps
armature, damping and friction loss in the joints, the delay and the torque limit in the
actuators (MuJoCo's own actuator delay and force range), the gain scales as custom numerics
that pupper applies to every gain it commands, and the torque lag and feedback latency as
custom numerics torque mode runs (and gains and recommend close the loop through). A logged
joint's armature and damping go to the same joint of the legs no log covers. robots.csv holds
the robots the logs allow: 8 draws from the fit's joint distribution, each within 1.25x the
fit's RMS error on the logs (what recommend --from-fit stands its candidates on).
A real Pupper v3 log (the real2sim logger's header: motor_idx, command (rad), ...) is read
with no column map; a map's motor=COLUMN names the log's motor by a column for any other.
Needs the fit extra (make setup PUPPER_EXTRAS=fit).

Examples:
  pupper excite -o ex1.csv && pupper excite --kd 0.3 -o ex2.csv    then play both on the robot
  pupper fit robot1.csv robot2.csv -o runs/fit --plot
  pupper fit robot1.csv --params armature,frictionloss,kp_scale,delay --per group
  pupper fit stand_kd01.csv stand_kd03.csv --columns stand.map --validate stand_kp25.csv stand_kp75.csv
  pupper fit a_kp_5_kd_0.25.csv.gz b_kp_5_kd_0.5.csv.gz --gains-from-name 'kp_{kp}_kd_{kd}'
  pupper fit 'knee.csv.gz::kp=5,kd=0.25' 'hip.csv.gz::kp=5,kd=0.25,columns=hip.map' --held 0
  pupper fit @bench.logs --validate @check.logs     lists: one LOG[::kp=K,kd=D,...] per line
  pupper response --model runs/fit/calibrated.xml --grid kp=5,20 --grid kd=0.1,0.5"
)]
pub(super) struct FitArgs {
    /// Joint logs (CSV, plain or gzip/bzip2/xz-compressed: told by the bytes), fitted together.
    /// LOG::kp=K,kd=D gives one log its own gains (also held=..., columns=MAP|FILE, in place of
    /// --held and --columns for it); @FILE reads such logs from a file, one per line (# comments;
    /// paths relative to the file's folder).
    #[arg(required = true, value_name = "LOG")]
    #[serde(serialize_with = "pyargs::paths")]
    logs: Vec<PathBuf>,
    #[command(flatten)]
    #[serde(flatten)]
    model: ModelArg,
    /// What to fit, comma-separated: armature, damping, frictionloss, kp_scale, kd_scale, delay,
    /// lag (the servo's torque lag), torque_limit, latency (the PD's feedback latency). The lag and
    /// latency replay each log through the servo firmware.
    #[arg(
        long,
        default_value = "armature,damping,frictionloss,kp_scale,kd_scale,delay,lag,torque_limit",
        value_name = "NAMES"
    )]
    params: String,
    /// One value of each parameter for all actuators, per joint group (haa, hfe, kfe) or per joint.
    #[arg(long, default_value = "all", value_name = "all|group|joint")]
    per: String,
    /// Run directory (default runs/<time>-fit).
    #[arg(long, short = 'o', value_name = "DIR")]
    #[serde(skip)]
    out: Option<PathBuf>,
    /// Overwrite pupper's files in an existing --out directory.
    #[arg(long)]
    force: bool,
    /// Most Levenberg-Marquardt iterations.
    #[arg(long, default_value_t = 50, value_name = "N")]
    max_iters: u64,
    /// Write DIR/plots/fit_<log>.png: measured against simulated angle per joint, before and after.
    #[arg(long)]
    plot: bool,
    /// The logs' own column names and units: KEY=COLUMN[:UNIT],... (KEY: time or ACTUATOR.FIELD),
    /// or a file holding the map; over a log's own `# columns:` line (a log's own columns= in
    /// place of it). Its columns name the actuators the log covers.
    #[arg(long, value_name = "MAP|FILE")]
    columns: Option<String>,
    /// Kp in use in the fitted logs that do not say it (one value, or one per logged actuator); a
    /// log that says another (a header line, columns, LOG::kp=, its name) is refused. A --validate
    /// log states its own.
    #[arg(long, value_name = "KP", allow_hyphen_values = true)]
    kp: Option<String>,
    /// Kd in use, as --kp.
    #[arg(long, value_name = "KD", allow_hyphen_values = true)]
    kd: Option<String>,
    /// Read each log's gains from its file name: a pattern with {kp} and {kd} where the name holds
    /// them, the rest as written, e.g. 'kp_{kp}_kd_{kd}' reads kp 5, kd 0.25 from
    /// freq_sweep_motor_3_kp_5_kd_0.25.csv.gz (0p25 reads as 0.25).
    #[arg(long, value_name = "PATTERN")]
    gains_from_name: Option<String>,
    /// What the actuators a log does not cover hold (rad, inside each joint's range): one angle,
    /// or ACTUATOR=RAD,... [default: the model's rest pose]
    #[arg(long, value_name = "RAD|ACT=RAD,...", allow_hyphen_values = true)]
    held: Option<String>,
    /// Logs not fitted, replayed through the nominal and the calibrated model: RMS angle error and
    /// frequency response (stepped sines, chirps) beside the log's own; validation.csv,
    /// validation_bode.csv and plots/validate_<log>.png. Each at its own gains (its header,
    /// LOG::kp=K,kd=D, or --gains-from-name; not --kp/--kd); @FILE as for LOG.
    #[arg(long, value_name = "LOG", num_args = 1..)]
    #[serde(serialize_with = "pyargs::paths")]
    validate: Vec<PathBuf>,
    /// Replay through the servo firmware, KEY=VALUE,...: rate (Hz), filter (Hz), counts (the
    /// encoder's difference velocity), noload (rad/s), noise (the encoder noise the PD reads, rad)
    /// [default: MuJoCo's ideal servo]
    #[arg(long, value_name = "KEY=VALUE,...")]
    motor: Option<String>,
    /// Where the fit starts a kind of parameter, KIND=VALUE,... (e.g. delay=0.015); the delay is
    /// also estimated from the logs, and the lowest cost of every start is kept
    /// [default: the model's values]
    #[arg(long, value_name = "KIND=VALUE,...")]
    start: Option<String>,
}

/// What `pupper_core._fit._cli_fit` is given: the flags and the run
/// directory.
#[derive(Serialize)]
struct FitCall<'a> {
    #[serde(flatten)]
    args: &'a FitArgs,
    #[serde(serialize_with = "pyargs::path")]
    out: PathBuf,
}

impl FitArgs {
    pub(super) fn run(&self) -> Result<u8> {
        let out = self.out.clone().unwrap_or_else(|| rundir_name("fit"));
        let call = FitCall { args: self, out };
        let text = pyargs::to_text(&call).map_err(|e| Error::Internal(e.to_string()))?;
        python_command(&calls::FIT, &text)
    }
}
