//! The `pupper` command line: [`Cli`] parses it, [`run`] hands each command
//! to its module. One file per command (or per pair that share their
//! work); the flag groups several commands take are in `args`.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use clap::{Parser, Subcommand};
use pupper_core::Result;

const ABOUT: &str = "Physics experiments on the Pupper v3 quadruped in MuJoCo: inspect the robot, \
make it stand, sweep PD gains, measure how well each setting stands and rejects a push.";

const AFTER: &str = "Examples:
  pupper info                                   counts, joints, actuators of the built-in model
  pupper stand --kp 5 --kd 0.1                  settle from the home keyframe, report base height
  pupper sweep --grid kp=10,30,60,120 --grid kd=0.5,1,2,5
  pupper sweep --preset chapter-4.6 --plot      the chapter's four servo cases, with plots
  pupper sweep --resume runs/20261122-120000-kp-kd   finish an interrupted sweep
  pupper response --grid kp=5,20,60 --grid kd=0.1,0.5   how each joint follows a step
  pupper hold --grid kp=5,10,20,40 --grid kd=0.25,0.5,1   sag under a load, sway after a shove
  pupper gains --bandwidth 8 --damping 0.7      gains per joint group from the reflected inertia
  pupper tune --space kp=5:200:log --space kd=0.05:10:log --trials 64   search instead of a grid
  pupper excite -o ex.csv; pupper fit robot.csv -o runs/fit   calibrate the model to joint logs

Exit status: 0 success, 2 bad input (one line on stderr says what and how to fix it),
130 interrupted (finished cells are kept), 1 internal error.";

// first: textual scope, so every command's module has its macros
#[macro_use]
mod console;

mod args;
mod fit;
mod gains;
mod hold;
mod lab;
mod merge;
mod model;
mod progress;
mod python;
mod recommend;
mod render;
mod response;
mod sweep;
mod tune;
mod walk;

use args::ModelArg;
use fit::{ExciteArgs, FitArgs};
use gains::GainsArgs;
use hold::HoldArgs;
use lab::LabArgs;
use merge::MergeArgs;
use model::{BodyArgs, PoseArgs, StandArgs};
use recommend::RecommendArgs;
use render::RenderArgs;
use response::ResponseArgs;
use sweep::SweepArgs;
use tune::TuneArgs;

#[derive(Parser, Debug)]
#[command(name = "pupper", version, about = ABOUT, after_help = AFTER)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Show a model (or one of its bodies): sizes, mass, joints with their qpos/qvel addresses,
    /// actuators in ctrl order, keyframes, sensors, and each leg measured on the compiled body.
    Info(BodyArgs),
    /// Reset to a keyframe (or a pose), stand with PD gains and no push; report final base height, last-second steadiness and tilt.
    Stand(StandArgs),
    /// Find a stand pose for a body by the chapter's rule: abduction 0, hip and knee on a grid
    /// inside the joint ranges, the feet under the hips at a depth of 0.14 m on Pupper v3's legs
    /// (scaled to another model's leg length, and by the leg scale up to 1.5 for longer variants),
    /// with a slight preference for a thigh 0.70 rad from vertical; measured on the compiled model.
    /// Prints the depth aimed at and where each foot ended.
    Pose(PoseArgs),
    /// Run a grid of settings as one batched simulation; write summary.csv and manifest.json into a run directory.
    Sweep(Box<SweepArgs>),
    /// The chapter's lab: every body variant from its own stand pose, a Kp x Kd grid in torque
    /// mode under a 2 N, 1.2 Hz vertical sine force, 6 s, no push, all in one batch; the
    /// steadiest gains per body (best.csv), heatmaps, base-z curves and the bodies rendered.
    Lab(Box<LabArgs>),
    /// How each joint follows its target: every joint excited alone (its target steps or
    /// oscillates around the stand pose while the others hold), on the robot hung in the air
    /// (base fixed, no contact) or --standing, for every gain cell of the grid in one batch.
    /// Writes response.csv (a row per cell and joint), summary.csv (per joint group) and, for
    /// sine and chirp, bode.csv.
    Response(Box<ResponseArgs>),
    /// How firmly the gains hold the robot up: it stands, a vertical load ramps onto its base
    /// up to its own weight (or --load times it) and is held, then a sideways shove follows;
    /// per gain cell the sag per newton, the sway and recovery, and the torque each joint
    /// group spends holding the load (and the copper loss, where the model declares its motors).
    Hold(Box<HoldArgs>),
    Walk(Box<walk::WalkArgs>),
    /// PD gains from each joint's reflected inertia (the joint-space inertia diagonal with
    /// armature, on the robot hung in the air at its stand pose): the gains per joint group
    /// that give --bandwidth HZ at --damping ZETA (kp = I wn^2, kd = 2 zeta I wn), or what
    /// --kp/--kd give (natural frequency, damping ratio); and whether each lies past the
    /// stability bound of an explicitly integrated PD at the model's timestep.
    Gains(GainsArgs),
    /// Search gains (or any grid axis) for the best objective with less simulation than a
    /// grid: each generation asks --batch trials of Optuna's sampler, runs them as one batch
    /// of cells and tells the results, until --trials or --budget. The study lives in the run
    /// directory (study.db, trials.csv, best.json, pareto.csv for several objectives).
    Tune(Box<TuneArgs>),
    /// Gains per joint group to put on the robot: the lowest worst-side push dip among gains
    /// that hold on every robot drawn from what the model does not know (none falls or
    /// saturates, each group's loop keeps its phase and gain margins as the firmware closes it),
    /// searched with Optuna; a card per group, and the gains as a ROS 2 parameter file and MJCF.
    Recommend(Box<RecommendArgs>),
    /// Write an excitation to play on the robot, hung in the air: per joint group a multisine
    /// or chirp around the rest pose (inside the joint ranges, under --max-velocity and the
    /// torque limit at the gains), with holds between; and the nominal model's response to it,
    /// in the joint-log format that `pupper fit` reads.
    Excite(Box<ExciteArgs>),
    /// Calibrate the model to joint logs with mujoco.sysid: each log's targets replayed at its
    /// gains through the robot hung in the air; joint armature, damping and friction loss, the
    /// servo's kp and kd scales and its command delay fitted (bounded least squares, every
    /// rollout of a Jacobian in one batch), with 95 % intervals. Writes fit.csv, residuals.csv,
    /// calibrated.xml (load it with --model in any command) and manifest.json.
    Fit(Box<FitArgs>),
    /// Write DIR/report.html: one self-contained page (no network) with the run's inputs, its
    /// table (sortable, status coloured), the plots of its kind, the best cells and the rule that
    /// picked them, warnings, and links to the files beside it. Every run writes one when it ends.
    Report {
        /// A run directory (sweep, lab, response, hold, tune or fit).
        #[arg(value_name = "DIR")]
        dir: PathBuf,
    },
    /// Put the shards of one sweep (each run with --shard I/N) together into one run directory,
    /// whose summary.csv is the one the unsharded sweep writes. Checks that the shards share
    /// inputs and model and that together they hold every cell once; says which shard to
    /// rerun otherwise. The manifest lists the shards, their hosts and wall times.
    Merge(MergeArgs),
    /// Show which Python, prefix and mujoco pupper found, and how to fix it if it found none.
    Doctor {
        #[arg(long)]
        json: bool,
    },
    /// Render one model or cell from the tracking camera to a PNG (offscreen; needs EGL or OSMesa).
    Render(RenderArgs),
    /// Open MuJoCo's interactive viewer on a model (needs a display).
    View {
        #[command(flatten)]
        model: ModelArg,
    },
}

/// Runs the parsed command; `Ok` holds its exit status.
pub fn run(cli: Cli, stop: &'static AtomicBool) -> Result<u8> {
    match cli.command {
        Command::Info(a) => model::info(&a),
        Command::Pose(a) => model::pose(&a),
        Command::Stand(a) => model::stand(&a),
        Command::Sweep(a) => sweep::run(*a, stop),
        Command::Lab(a) => lab::run(*a, stop),
        Command::Response(a) => response::run(*a, stop),
        Command::Hold(a) => hold::run(*a, stop),
        Command::Walk(a) => walk::run(*a, stop),
        Command::Tune(a) => a.run(),
        Command::Recommend(a) => a.run(),
        Command::Excite(a) => a.run(),
        Command::Report { dir } => {
            python::write_report(&dir)?;
            errln!("wrote {}", dir.join("report.html").display());
            Ok(0)
        }
        Command::Fit(a) => a.run(),
        Command::Gains(a) => a.run(),
        Command::Merge(a) => a.run(),
        Command::Doctor { json } => model::doctor(json),
        Command::Render(a) => a.run(),
        Command::View { model } => model::view(&model),
    }
}
