//! `pupper recommend`: gains per joint group to put on the robot, searched
//! in Python (Optuna over the robots drawn from what the model does not
//! know); this side hands it the flags as JSON.

use std::path::PathBuf;

use clap::Args;
use pupper_core::{Error, Result};
use serde::Serialize;

use super::args::{ModelArg, finite, rundir_name};
use super::python::python_command;
use crate::pyargs;
use pupper_mujoco::bridge::calls;

/// The flags serialize themselves as `pupper_core.recommend`'s keywords,
/// each under its own name (the manifest keeps the same names).
#[derive(Args, Debug, Serialize)]
#[command(
    after_help = "What it answers: the kp and kd per joint group with the lowest worst-side \
(95th percentile) push dip among gains that hold on EVERY drawn robot:
  - no robot falls, diverges or lies past the stability bound of the PD;
  - no robot saturates its torque limit on more than --max-saturation of its steps;
  - no robot ends lower than --max-sag of its stance height (the base height with the lowest
    foot on the floor in the start pose) below it: a crouch barely dips, so the push alone
    would reward one;
  - each group's loop, as the firmware (--motor) closes it on measurements --sensing-delay old,
    keeps --min-phase-margin and --min-gain-margin: the joint linearised at the stand pose (its
    reflected inertia, kp + kd s, the feedback path's latency: sensing delay, half the update
    period, the derivative's filter and differencing), checked at the spread's worst corners
    (what the motors deliver of the gains, the joints' least and most inertia).
A --command-delay is not in that loop: it leaves the margins alone and shows as a later step
response. Push dips within 2 % are a tie, won by the candidate whose slowest group tracks fastest.
Exit status: 0 gains named; 3 none held every constraint (the card then names the best available,
how far short it falls and the gains in use beside it); 2 bad input; 1 an internal error.

The robots (default spread): torso mass ±15 %, leg masses ±10 %, motor gains ±10 % per joint,
floor friction 0.6-1.2, 1 mrad of encoder noise, 0 to --sensing-delay of sensing latency; every
candidate meets the same robots (common draws), so the card's numbers are reproduced by the sweep
the manifest names. With --from-fit DIR (checked against its manifest first) the robot is the fit's calibrated model
and the robots are the ones its logs allow (its robots.csv: 8 draws from its joint distribution,
each with its whole motor); the margins close the loop the fit found (its firmware, lag, latency
and damping), nothing stacked on top.
With several runs (--from-fit A B, e.g. per-joint fits of different motors) the robot is one model
of what each fitted, written to the run directory as calibrated.xml.

--task walk ranks by walking instead: each candidate walks `pupper walk`'s gait (--gait, --frequency,
--speed) on the same robots, the lowest p95 speed_error_pct wins among those that hold the same
constraints while walking and keep every robot's roll and pitch RMS under --max-tilt; the card
then runs --task stand's search too and sets both picks side by side, each scored on both tasks,
with why they differ.

Writes, in the run directory: recommend.csv (a card per group: gains, margins, predicted step
response, p95 push dip, torque headroom), trials.csv (every candidate), tradeoffs.csv (those no
other beats at once on push dip, slowest group's tracking and stand height), recommended.yaml (a ROS 2
parameter file: joint_names, kps, kds for --controller in --joint-order), recommended.xml (the
model with the gains in its actuators), report.html, manifest.json. Needs the tune extra (Optuna).

The gains are what to command. A calibrated model (`pupper fit`'s, with gain scales
pupper:kp_scale:ACT) says its motors deliver other gains: the card shows those beside them (motor
kp, motor kd), and every margin is of the delivered gains. The gains the robot runs today
(--current, default the model's own) run on the same robots and are set beside the pick.

Examples:
  pupper recommend -o runs/rec
  pupper recommend --motor rate=250,counts=16384 --sensing-delay 0.004 -o runs/rec_slow
  pupper recommend --from-fit runs/fit --joint-order leg_front_r_1,leg_front_r_2,... -o runs/rec_fit
  pupper recommend --task walk --gait trot --speed 0.25 -o runs/rec_walk"
)]
pub(super) struct RecommendArgs {
    #[command(flatten)]
    #[serde(flatten)]
    model: ModelArg,
    /// Robots drawn per candidate (every constraint must hold on each).
    #[arg(long, default_value_t = 32, value_name = "N")]
    robots: u32,
    /// Candidates run on the robots (those whose margins fail cost no simulation).
    #[arg(long, default_value_t = 48, value_name = "N")]
    trials: u32,
    /// Candidates per generation, run as one batch.
    #[arg(long, default_value_t = 16, value_name = "B")]
    batch: u32,
    /// Times the search's best may move to a better neighbour (a group's kp or kd x/÷ 1.25, or
    /// its kp with kd along its margin window); the last neighbours are scored either way, and
    /// the card says why each lost.
    #[arg(long, default_value_t = 4, value_name = "N")]
    polish: u32,
    /// Seed of the robots' draws and of the search.
    #[arg(long, default_value_t = 0, value_name = "S")]
    seed: u64,
    /// Simulated seconds per robot (the push comes at 2 s) [default: 4, or 8 with --task walk, whose
    /// steady window starts at 3.5 s]
    #[arg(long, value_name = "S", allow_negative_numbers = true, value_parser = finite)]
    seconds: Option<f64>,
    /// What the gains are ranked for: stand (the push dip) or walk (the speed error of `pupper walk`
    /// at --gait, --frequency and --speed on the same robots; the card sets the pick beside
    /// --task stand's and says why they differ).
    #[arg(long, default_value = "stand", value_name = "TASK")]
    task: String,
    #[command(flatten)]
    #[serde(flatten)]
    walk: super::walk::WalkTaskArgs,
    /// The push's vertical force (N) [default: sweep's].
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = finite)]
    push_force: Option<f64>,
    /// The servo firmware, as --motor takes it (rate=HZ,filter=HZ,counts=N,noload=RAD_S,lag=S)
    /// [default: rate=500,counts=16384; with --from-fit, or on a calibrated model, the firmware the
    /// fit replayed, the model's fitted lag and latency in it (a lag= here stands instead)]
    #[arg(long, value_name = "SPEC")]
    motor: Option<String>,
    /// Age of the measurements the firmware's PD reads (s): in the loop margins, and drawn 0 to it
    /// (whole physics steps) on the robots [default: 0.002; with --from-fit, or on a calibrated
    /// model, none on top of the fit's own feedback latency; the card says which]
    #[arg(long, value_name = "S", allow_negative_numbers = true, value_parser = finite)]
    sensing_delay: Option<f64>,
    /// Delay of the commanded target (s): the firmware's command delay; shifts the step response.
    #[arg(long, default_value_t = 0.0, value_name = "S", allow_negative_numbers = true, value_parser = finite)]
    command_delay: f64,
    /// What differs between robots, as --randomize specs; repeat. Replaces the default spread.
    #[arg(long, value_name = "QUANTITY=DIST", allow_hyphen_values = true)]
    #[serde(serialize_with = "pyargs::none_if_empty")]
    spread: Vec<String>,
    /// A `pupper fit` run directory: its calibrated model is the robot, its intervals the spread.
    /// Several (repeat the flag, or list them after it) merge into one model, each actuator's
    /// calibrated parameters from the run that fitted it; two runs that calibrate one actuator's
    /// parameter to different values are refused.
    #[arg(long, value_name = "DIR", num_args = 1..)]
    #[serde(serialize_with = "pyargs::paths_or_none")]
    from_fit: Vec<PathBuf>,
    /// Least phase margin of every group's loop on every robot (degrees).
    #[arg(long, default_value_t = 30.0, value_name = "DEG", allow_negative_numbers = true, value_parser = finite)]
    min_phase_margin: f64,
    /// Least gain margin of every group's loop on every robot (dB).
    #[arg(long, default_value_t = 6.0, value_name = "DB", allow_negative_numbers = true, value_parser = finite)]
    min_gain_margin: f64,
    /// Largest share of steps a robot may spend at its torque limit.
    #[arg(long, default_value_t = pupper_core::results::best::MAX_SATURATION, value_name = "F", allow_negative_numbers = true, value_parser = super::args::saturation)]
    max_saturation: f64,
    /// Most a robot's final base height may lie below its stance height, as a share of it.
    #[arg(long, default_value_t = 0.1, value_name = "F", allow_negative_numbers = true, value_parser = finite)]
    max_sag: f64,
    /// The motors' largest kp [default: the model's pupper:kp_max:ACT numerics, else 20x its own].
    #[arg(long, value_name = "KP", allow_negative_numbers = true, value_parser = finite)]
    kp_max: Option<f64>,
    /// The motors' largest kd [default: the model's pupper:kd_max:ACT numerics, else 50x its own].
    #[arg(long, value_name = "KD", allow_negative_numbers = true, value_parser = finite)]
    kd_max: Option<f64>,
    /// The gains the robot runs today, KP,KD for every group, run on the same robots and set beside
    /// the pick on the card [default: the model's own servo gains].
    #[arg(long, value_name = "KP,KD", allow_hyphen_values = true)]
    current: Option<String>,
    /// The robot's controller configuration, a ROS 2 parameter YAML: the --controller node's
    /// joint_names are the default --joint-order, its kps/kds (or init_kps/init_kds) the default
    /// --current.
    #[arg(long, value_name = "YAML")]
    #[serde(serialize_with = "pyargs::opt_path")]
    robot_config: Option<PathBuf>,
    /// The controller's joint order for the YAML's kps/kds, comma-separated actuator names
    /// [default: the model's actuators].
    #[arg(long, value_name = "A,B,...")]
    joint_order: Option<String>,
    /// The ROS 2 node the YAML's parameters are for.
    #[arg(long, default_value = "neural_controller", value_name = "NAME")]
    controller: String,
    /// Run directory (default runs/<time>-recommend).
    #[arg(long, short = 'o', value_name = "DIR")]
    #[serde(skip)]
    out: Option<PathBuf>,
    /// Overwrite --out.
    #[arg(long)]
    force: bool,
    /// No line per generation.
    #[arg(long, short = 'q')]
    #[serde(skip)]
    quiet: bool,
}

/// What `pupper_core._recommend._cli` is given: the flags, the run
/// directory, whether to print progress.
#[derive(Serialize)]
struct Call<'a> {
    #[serde(flatten)]
    args: &'a RecommendArgs,
    #[serde(serialize_with = "pyargs::path")]
    out: PathBuf,
    progress: bool,
}

impl RecommendArgs {
    pub(super) fn run(&self) -> Result<u8> {
        let out = self.out.clone().unwrap_or_else(|| rundir_name("recommend"));
        let call = Call {
            args: self,
            out,
            progress: !self.quiet,
        };
        let text = pyargs::to_text(&call).map_err(|e| Error::Internal(e.to_string()))?;
        python_command(&calls::RECOMMEND, &text)
    }
}
