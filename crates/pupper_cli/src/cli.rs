//! Command-line arguments and what each command does with them.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use pupper_core::plan::config::SweepConfig;
use pupper_core::plan::mode::Mode;
use pupper_core::request::spec::{self, GridInput, SweepSpec};
use pupper_core::results::best;
use pupper_core::results::output;
use pupper_core::results::rundir::Existing;
use pupper_core::robot::model::ModelSource;
use pupper_core::sim::runner::Hooks;
use pupper_core::{Error, Result};
use pupper_mujoco::api::{self, SweepRequest, SweepUi};
use pupper_mujoco::bridge;

use crate::print;
use crate::pyargs::PyArgs;

const ABOUT: &str = "Physics experiments on the Pupper v3 quadruped in MuJoCo: inspect the robot, \
make it stand, sweep PD gains, measure how well each setting stands and rejects a push.";

const AFTER: &str = "Examples:
  pupper info                                   counts, joints, actuators of the built-in model
  pupper stand --kp 5 --kd 0.1                  settle from the home keyframe, report base height
  pupper sweep --grid kp=10,30,60,120 --grid kd=0.5,1,2,5
  pupper sweep --preset chapter-4.6 --plot      the chapter's four servo cases, with plots
  pupper sweep --resume runs/20261122-120000-kp-kd   finish an interrupted sweep
  pupper response --grid kp=5,20,60 --grid kd=0.1,0.5   how each joint follows a step
  pupper gains --bandwidth 8 --damping 0.7      gains per joint group from the reflected inertia
  pupper tune --space kp=5:200:log --space kd=0.05:10:log --trials 64   search instead of a grid
  pupper excite -o ex.csv; pupper fit robot.csv -o runs/fit   calibrate the model to joint logs

Exit status: 0 success, 2 bad input (one line on stderr says what and how to fix it),
130 interrupted (finished cells are kept), 1 internal error.";

/// Writes to standard output. A stdout that cannot take the text (a full
/// disk) is a one-line error, never a panic; a closed pipe (`| head`) just
/// ends the output.
fn out(text: &str) -> Result<()> {
    use std::io::Write;
    let mut o = std::io::stdout().lock();
    match o.write_all(text.as_bytes()).and_then(|()| o.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => r.map_err(|source| Error::Io {
            action: "write to",
            path: PathBuf::from(pupper_core::error::STDOUT),
            source,
        }),
    }
}

/// `print!` through [`out`].
macro_rules! outp {
    ($($t:tt)*) => { out(&format!($($t)*))? };
}

/// `println!` through [`out`].
macro_rules! outln {
    ($($t:tt)*) => { out(&format!("{}\n", format_args!($($t)*)))? };
}

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
        /// A run directory (sweep, lab, response, tune or fit).
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

#[derive(Args, Debug)]
struct MergeArgs {
    /// The shards' run directories (e.g. runs/study-shard-*).
    #[arg(required = true, value_name = "DIR")]
    dirs: Vec<PathBuf>,
    /// The merged run directory (default runs/<time>-merged).
    #[arg(long, short = 'o', value_name = "OUT")]
    out: Option<PathBuf>,
    /// Overwrite pupper's files in an existing OUT.
    #[arg(long)]
    force: bool,
    /// Print {"out", "shards", "cells"} as JSON instead of the "merged" line.
    #[arg(long)]
    json: bool,
}

#[derive(Args, Debug)]
#[command(
    after_help = "Step figures (python-control's step_info and MATLAB's stepinfo, for a step of
size A commanded at the end of the hold, from the angle y0 then to the final value yf, the mean
over the last tenth of the window): rise_time_s from 10 % to 90 % of yf - y0; settling_time_s
until the angle stays within 2 % of |yf - y0| of yf (empty: never settled); overshoot_pct past yf
in % of |yf - y0|; peak_time_s; ss_error_rad = y0 + A - yf and ss_error_pct in % of A.
Sine: gain_db and phase_deg of the joint against its target (a least-squares fit over the second
half of the window). Chirp (logarithmic, F0 to F1 over the window): gain and phase at 24
log-spaced frequencies inside the band (the angle's Fourier sum over the target's, on the whole
window) in bode.csv; bandwidth_hz where the gain falls 3 dB below its value at the lowest of them
(refined by bisection), phase_at_bw_deg there, resonance_db the peak above it.
peak_torque and saturation_frac are the excited joint's actuator over the window. Status: ok,
saturated (at its torque limit in 5 % of steps or more), diverged.
Joint groups: haa (abduction), hfe (hip pitch), kfe (knee), assigned by what each joint does in
its leg on the compiled model (`pupper info` lists them), not by its name.

Examples:
  pupper response --grid kp=5,20,60 --grid kd=0.1,0.5,2
  pupper response --signal chirp --chirp 0.5,30 --seconds 12 --joints hfe --kp 20 --kd 0.5
  pupper response --signal sine --frequency 3 --amplitude 0.1 --standing"
)]
struct ResponseArgs {
    #[command(flatten)]
    grid: GridArg,
    #[command(flatten)]
    sim: SimArgs,
    /// The excitation: step (the target jumps by --amplitude), sine (--frequency), chirp
    /// (a logarithmic sweep over --chirp F0,F1 for the window after the hold).
    #[arg(long, default_value = "step", value_name = "KIND")]
    signal: String,
    /// The signal's size (rad), added to the joint's pose angle.
    #[arg(long, default_value_t = pupper_core::plan::excitation::AMPLITUDE, value_name = "RAD", allow_negative_numbers = true)]
    amplitude: f64,
    /// --signal sine: its frequency (Hz).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    frequency: Option<f64>,
    /// --signal chirp: its band, F0,F1 in Hz [default: 0.5,20].
    #[arg(long, value_name = "F0,F1")]
    chirp: Option<String>,
    /// Seconds the pose is held before the signal starts (the joints settle under gravity).
    #[arg(long, default_value_t = pupper_core::request::response::DEFAULT_HOLD, value_name = "S", allow_negative_numbers = true)]
    hold: f64,
    /// The excited joints: groups (haa, hfe, kfe) or actuator names, comma-separated
    /// [default: every actuator].
    #[arg(long, value_name = "NAMES", value_delimiter = ',')]
    joints: Vec<String>,
    /// Excite the joints of the floating robot standing on the floor instead of the one hung
    /// in the air.
    #[arg(long)]
    standing: bool,
    /// Run directory (default runs/<time>-response).
    #[arg(long, short = 'o', value_name = "DIR", conflicts_with = "resume")]
    out: Option<PathBuf>,
    /// Overwrite pupper's files in an existing --out directory.
    #[arg(long)]
    force: bool,
    /// Run only shard I of N of the grid's cells (see `pupper sweep --help`).
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Continue an interrupted run in DIR (alone: with the manifest's inputs).
    #[arg(long, value_name = "DIR")]
    resume: Option<PathBuf>,
    /// Batch threads; 0 uses all cores. Never changes the numbers.
    #[arg(long, short = 'j', default_value_t = SweepSpec::default().threads, value_name = "N")]
    threads: usize,
    /// Most cells per batch. Never changes the numbers.
    #[arg(long, value_name = "N")]
    chunk_cells: Option<usize>,
    /// Keep each excited joint's angle after the hold (response_traces.csv), every
    /// --trace-every-th step.
    #[arg(long)]
    trace: bool,
    /// Decimation of the traces.
    #[arg(long, default_value_t = SweepSpec::default().trace_every, value_name = "N")]
    trace_every: usize,
    /// Write plots into DIR/plots: step responses per joint group (target dashed, the 2 %
    /// band shaded), Bode gain and phase per group (sine, chirp), heatmaps of rise time,
    /// overshoot and settling time over Kp x Kd.
    #[arg(long)]
    plot: bool,
    /// Print the rows as JSON instead of a table per joint group.
    #[arg(long)]
    json: bool,
    /// No progress bar.
    #[arg(long, short = 'q')]
    quiet: bool,
    #[command(flatten)]
    backend: BackendArgs,
    #[command(flatten)]
    population: PopulationArgs,
}

impl ResponseArgs {
    fn spec(&self) -> Result<SweepSpec> {
        let signal = pupper_core::request::response::SignalInput {
            kind: self.signal.clone(),
            amplitude: self.amplitude,
            frequency: self.frequency,
            chirp: self
                .chirp
                .as_deref()
                .map(pupper_core::request::response::parse_chirp)
                .transpose()?,
        };
        let base = SweepSpec {
            grid: GridInput::Specs(self.grid.grid.clone()),
            seconds: self
                .sim
                .seconds
                .unwrap_or(pupper_core::request::response::SECONDS),
            threads: self.threads,
            chunk_cells: self.chunk_cells,
            force: self.force,
            shard: self.shard.clone(),
            // the step plots draw the traces
            trace: self.trace || self.plot,
            trace_every: self.trace_every,
            ..self.backend.apply(self.population.apply(self.sim.spec()?))
        };
        pupper_core::request::response::spec(
            base,
            &signal,
            self.hold,
            &self.joints,
            self.standing,
            self.sim.keyframe.is_some(),
        )
    }
}

#[derive(Args, Debug)]
#[command(
    after_help = "Stability: MuJoCo's Euler integrator (and pupper's torque mode) applies a PD
force computed from the state at the start of each step, then steps velocity and position
semi-implicitly. With a = h^2 kp / I and b = h kd / I (h the timestep, I the joint's inertia) that
discrete system is stable exactly when a + 2b < 4 and b < 2 (Jury's test on its characteristic
polynomial z^2 - (2 - a - b) z + (1 - b)). stability_margin = max((a + 2b)/4, b/2): 1 or more is
past the bound, where the joint chatters or diverges.

Examples:
  pupper gains --bandwidth 8 --damping 0.7
  pupper gains --kp 20 --kd 0.5 --json"
)]
struct GainsArgs {
    #[command(flatten)]
    model: ModelArg,
    /// The −3 dB bandwidth (Hz) the gains should give.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true, conflicts_with_all = ["kp", "kd"])]
    bandwidth: Option<f64>,
    /// The damping ratio with --bandwidth.
    #[arg(
        long,
        default_value_t = 0.7,
        value_name = "ZETA",
        allow_negative_numbers = true
    )]
    damping: f64,
    /// Given gains: their natural frequency, damping ratio and stability margin per joint.
    #[arg(long, allow_negative_numbers = true, requires = "kd")]
    kp: Option<f64>,
    #[arg(long, allow_negative_numbers = true, requires = "kp")]
    kd: Option<f64>,
    /// The pose the inertias are read at, one angle per actuator [default: the stand pose].
    #[arg(long, value_name = "Q1,Q2,...", allow_hyphen_values = true)]
    pose: Option<String>,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Args, Debug)]
#[command(
    after_help = "A trial whose robot fell or diverged is told a penalty of 1e6 (the worst
value) and keeps its status in trials.csv. The sampler of generation g is seeded from (--seed, g)
and sees only finished trials, so the same command gives the same trials in the same order at any
thread count and after --resume (which re-runs the trials a kill left unfinished). Show the study:
optuna-dashboard sqlite:///DIR/study.db. Needs the tune extra (make setup PUPPER_EXTRAS=tune).

Examples:
  pupper tune --space kp=5:200:log --space kd=0.05:10:log --trials 64 --batch 16
  pupper tune --space kp.hfe=5:100:log --space kp.kfe=5:100:log --kd 0.5 --budget 2000000
  pupper tune --space kp=5:200:log --space kd=0.05:5:log --objective last_1s_std_mm,push_dip_mm --trials 48"
)]
struct TuneArgs {
    /// A searched axis: AXIS=LOW:HIGH (linear), LOW:HIGH:log, LOW:HIGH:int, or choices A|B|C;
    /// repeat for more. Any grid axis (kp, kd, kp.hfe, max_torque, variant, ...).
    #[arg(long, value_name = "AXIS=RANGE", allow_hyphen_values = true)]
    space: Vec<String>,
    /// The summary.csv column to minimize, or several comma-separated (a Pareto front).
    #[arg(long, default_value = "last_1s_std_mm", value_name = "COLUMN[,COLUMN]")]
    objective: String,
    /// Maximize the objective(s) instead.
    #[arg(long)]
    maximize: bool,
    /// Stop after this many finished trials.
    #[arg(long, value_name = "N", conflicts_with = "budget")]
    trials: Option<u64>,
    /// Spend at most this many cell-steps (the last generation may be smaller).
    #[arg(long, value_name = "CELL_STEPS")]
    budget: Option<u64>,
    /// Trials per generation, run as one batch.
    #[arg(long, default_value_t = 8, value_name = "B")]
    batch: u64,
    /// tpe (with a constant liar), cmaes (population = --batch), gp (needs torch), random.
    #[arg(long, default_value = "tpe", value_name = "NAME")]
    sampler: String,
    /// With replicates, the objective over them: mean, p95 (the worse side), worst, fail-rate.
    #[arg(long, default_value = "mean", value_name = "NAME")]
    aggregate: String,
    /// Successive halving over the replicates (an eta of 2 or more, with --replicates): each
    /// generation runs every trial on replicates/eta robots first and only its best 1/eta on
    /// all of them; the others are told pruned with their first value.
    #[arg(long, default_value_t = 0, value_name = "ETA")]
    halving: u64,
    #[command(flatten)]
    sim: SimArgs,
    /// Push force along world z (N; negative pushes down).
    #[arg(long, default_value_t = SweepSpec::default().push_force, value_name = "N", allow_hyphen_values = true)]
    push_force: f64,
    /// Push start time (s).
    #[arg(long, default_value_t = SweepSpec::default().push_at, value_name = "S", allow_negative_numbers = true)]
    push_at: f64,
    /// Push duration (s).
    #[arg(long, default_value_t = SweepSpec::default().push_duration, value_name = "S", allow_negative_numbers = true)]
    push_duration: f64,
    /// No push.
    #[arg(long)]
    no_push: bool,
    /// A continuous vertical force AMPLITUDE*sin(2π·FREQUENCY·t) on the base (N, Hz), e.g. 2,1.2.
    #[arg(long, value_name = "AMP,HZ", allow_hyphen_values = true)]
    sine: Option<String>,
    /// Most cells per batch (a generation runs in batches of at most this many). Never
    /// changes the numbers.
    #[arg(long, value_name = "N")]
    chunk_cells: Option<usize>,
    /// Run directory (default runs/<time>-tune).
    #[arg(long, short = 'o', value_name = "DIR", conflicts_with = "resume")]
    out: Option<PathBuf>,
    /// Overwrite pupper's files in an existing --out directory.
    #[arg(long)]
    force: bool,
    /// Continue an interrupted study in DIR (the same inputs, or --resume DIR alone).
    #[arg(long, value_name = "DIR")]
    resume: Option<PathBuf>,
    /// Batch threads; 0 uses all cores. Never changes the numbers.
    #[arg(long, short = 'j', default_value_t = 0, value_name = "N")]
    threads: usize,
    /// Write DIR/plots/tune_progress.png (best objective against cell-steps spent) and, for
    /// two searched axes, tune_trials.png (the trials over that plane).
    #[arg(long)]
    plot: bool,
    /// With --plot: a sweep's run directory of the same question (e.g. a grid over the same
    /// axes), drawn behind the search: its best-so-far curve and its heatmap.
    #[arg(long, value_name = "DIR", requires = "plot")]
    compare: Option<PathBuf>,
    /// No line per generation.
    #[arg(long, short = 'q')]
    quiet: bool,
    // last: their help headings would hold every option after them
    #[command(flatten)]
    backend: BackendArgs,
    #[command(flatten)]
    population: PopulationArgs,
}

impl TuneArgs {
    fn run(&self) -> Result<u8> {
        let spec = self.sim.spec()?;
        let pose = match &self.sim.pose {
            Some(p) if p.trim() == "auto" => serde_json::json!("auto"),
            Some(_) => match &spec.pose {
                Some(spec::PoseInput::Angles(a)) => serde_json::json!(a),
                _ => serde_json::Value::Null,
            },
            None => serde_json::Value::Null,
        };
        let out = match (&self.resume, &self.out) {
            (Some(d), _) | (None, Some(d)) => d.clone(),
            (None, None) => PathBuf::from("runs").join(format!(
                "{}-tune",
                chrono::Local::now().format("%Y%m%d-%H%M%S")
            )),
        };
        let mut options = serde_json::json!({
            "model": spec.model,
            "variant": spec.variant,
            "mode": spec.mode,
            "seconds": spec.seconds,
            "push": !self.no_push,
            "threads": self.threads,
            "replicates": self.population.replicates,
            "randomize": self.population.randomize,
        });
        let o = options
            .as_object_mut()
            .ok_or_else(|| Error::Internal("options".into()))?;
        for (k, v) in [
            ("kp", spec.kp),
            ("kd", spec.kd),
            ("max_torque", spec.max_torque),
            ("depth", spec.depth),
        ] {
            if let Some(v) = v {
                o.insert(k.into(), serde_json::json!(v));
            }
        }
        if let Some(m) = &spec.motor {
            o.insert("motor".into(), serde_json::json!(m));
        }
        // the schedule and backend as sweep takes them; a default stays
        // out, so a study's inputs read as they did before these flags
        let d = SweepSpec::default();
        for (k, v, default) in [
            ("push_force", self.push_force, d.push_force),
            ("push_at", self.push_at, d.push_at),
            ("push_duration", self.push_duration, d.push_duration),
        ] {
            if v != default {
                o.insert(k.into(), serde_json::json!(v));
            }
        }
        if let Some(s) = &self.sine {
            o.insert("sine".into(), serde_json::json!(spec::parse_sine(s)?));
        }
        if let Some(c) = self.chunk_cells {
            o.insert("chunk_cells".into(), serde_json::json!(c));
        }
        if self.backend.backend != "cpu" {
            o.insert("backend".into(), serde_json::json!(self.backend.backend));
        }
        for (k, v) in [("device", &self.backend.device), ("ray", &self.backend.ray)] {
            if let Some(v) = v {
                o.insert(k.into(), serde_json::json!(v));
            }
        }
        if let Some(k) = &self.sim.keyframe {
            o.insert("keyframe".into(), serde_json::json!(k));
        }
        if !pose.is_null() {
            o.insert("pose".into(), pose);
        }
        let mut py = PyArgs::new();
        let mut args = serde_json::json!({
            "space": self.space,
            "objective": self.objective,
            "maximize": self.maximize,
            "trials": self.trials,
            "budget": self.budget,
            "batch": self.batch,
            "sampler": self.sampler,
            "seed": self.population.seed,
            "aggregate": self.aggregate,
            "halving": self.halving,
            "out": py.path(&out),
            "resume": self.resume.is_some(),
            "force": self.force,
            "progress": !self.quiet,
            "plot": self.plot,
            "compare": self.compare.as_ref().map(|c| py.path(c)),
        });
        if let (Some(a), Some(o)) = (args.as_object_mut(), options.as_object()) {
            for (k, v) in o {
                a.insert(k.clone(), v.clone());
            }
        }
        python_command("pupper_core._tune", "_cli", &py.text(&args))
    }
}

#[derive(Args, Debug)]
#[command(after_help = "The log (CSV): `# key: value` lines, then a header
time,ACTUATOR.target,ACTUATOR.q[,ACTUATOR.qd][,ACTUATOR.tau],... in s, rad, rad/s, N·m.
Keys: kp and kd (the gains in use: one value, or one per actuator in column order; required),
mode (servo or torque), base (suspended). Play the file's targets on the robot, hung in the air, at
its gains; log the measured angles (and velocities, torques where the servos report them) into the
same columns. The format, the fit and the motor model: docs/fit.md.

Examples:
  pupper excite -o excite.csv                      8 s per joint group at the model's own gains
  pupper excite --kd 0.3 --signal chirp -o excite_kd03.csv   a second log at another kd")]
struct ExciteArgs {
    #[command(flatten)]
    model: ModelArg,
    /// The log to write.
    #[arg(long, short = 'o', value_name = "FILE", default_value = "excite.csv")]
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
    band: String,
    /// Seconds of excitation per joint group.
    #[arg(
        long,
        default_value_t = 8.0,
        value_name = "S",
        allow_negative_numbers = true
    )]
    seconds: f64,
    /// Seconds held at the rest pose before and between groups.
    #[arg(
        long,
        default_value_t = 1.0,
        value_name = "S",
        allow_negative_numbers = true
    )]
    hold: f64,
    /// Largest swing of a joint from its rest angle (rad); smaller where the range, the speed
    /// limit or the torque limit at the gains asks.
    #[arg(
        long,
        default_value_t = 0.3,
        value_name = "RAD",
        allow_negative_numbers = true
    )]
    amplitude: f64,
    /// Fastest commanded joint speed (rad/s).
    #[arg(
        long,
        default_value_t = 8.0,
        value_name = "RAD_S",
        allow_negative_numbers = true
    )]
    max_velocity: f64,
    /// Seed of the multisine's phases.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

impl ExciteArgs {
    fn run(&self) -> Result<u8> {
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
        if band.len() != 2 {
            return Err(Error::Config(format!(
                "--band {} is not two numbers F0,F1 (Hz): give e.g. 0.3,6",
                self.band
            )));
        }
        let mut py = PyArgs::new();
        let args = serde_json::json!({
            "model": self.model.model,
            "out": py.path(&self.out),
            "force": self.force,
            "kp": self.kp,
            "kd": self.kd,
            "signal": self.signal,
            "band": band,
            "seconds": self.seconds,
            "hold": self.hold,
            "amplitude": self.amplitude,
            "max_velocity": self.max_velocity,
            "seed": self.seed,
        });
        python_command("pupper_core._fit", "_cli_excite", &py.text(&args))
    }
}

#[derive(Args, Debug)]
#[command(
    after_help = "The fit replays each log through the model hung in the air (free joint removed,
contacts off) at the log's gains and fits the angles (and velocities and torques where
logged) by mujoco.sysid's bounded Levenberg-Marquardt. With angles only, joint damping and the
servo's kd act as one damping: fit a second log at another kd (pupper excite --kd) or log torque,
or leave one of them out of --params; fit warns when they are confounded. calibrated.xml keeps
armature, damping and friction loss in the joints, the delay in the actuators (MuJoCo's own
actuator delay) and the gain scales as custom numerics that pupper applies to every gain it
commands. Needs the fit extra (make setup PUPPER_EXTRAS=fit).

Examples:
  pupper excite -o ex1.csv && pupper excite --kd 0.3 -o ex2.csv    then play both on the robot
  pupper fit robot1.csv robot2.csv -o runs/fit --plot
  pupper fit robot1.csv --params armature,frictionloss,kp_scale,delay --per group
  pupper response --model runs/fit/calibrated.xml --grid kp=5,20 --grid kd=0.1,0.5"
)]
struct FitArgs {
    /// Joint logs (CSV; see below), fitted together.
    #[arg(required = true, value_name = "LOG")]
    logs: Vec<PathBuf>,
    #[command(flatten)]
    model: ModelArg,
    /// What to fit, comma-separated: armature, damping, frictionloss, kp_scale, kd_scale, delay.
    #[arg(
        long,
        default_value = "armature,damping,frictionloss,kp_scale,kd_scale,delay",
        value_name = "NAMES"
    )]
    params: String,
    /// One value of each parameter for all actuators, per joint group (haa, hfe, kfe) or per joint.
    #[arg(long, default_value = "all", value_name = "all|group|joint")]
    per: String,
    /// Run directory (default runs/<time>-fit).
    #[arg(long, short = 'o', value_name = "DIR")]
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
}

impl FitArgs {
    fn run(&self) -> Result<u8> {
        let out = self.out.clone().unwrap_or_else(|| {
            PathBuf::from("runs").join(format!(
                "{}-fit",
                chrono::Local::now().format("%Y%m%d-%H%M%S")
            ))
        });
        let mut py = PyArgs::new();
        let args = serde_json::json!({
            "logs": py.paths(&self.logs),
            "model": self.model.model,
            "params": self.params,
            "per": self.per,
            "out": py.path(&out),
            "force": self.force,
            "max_iters": self.max_iters,
            "plot": self.plot,
        });
        python_command("pupper_core._fit", "_cli_fit", &py.text(&args))
    }
}

/// A command whose work is in pupper's Python package: its flags as JSON
/// to `module.func`, which returns the files it wrote (said on stderr).
fn python_command(module: &str, func: &str, args_json: &str) -> Result<u8> {
    for p in bridge::call_helper(
        module,
        func,
        &[args_json.to_string()],
        &serde_json::json!({}),
    )? {
        eprintln!("wrote {p}");
    }
    Ok(0)
}

/// `--grid`, repeatable.
#[derive(Args, Debug)]
struct GridArg {
    /// A grid axis and its values, AXIS=VALUES; repeat for more axes.
    #[arg(
        long = "grid",
        short = 'g',
        value_name = "AXIS=VALUES",
        allow_hyphen_values = true
    )]
    grid: Vec<String>,
}

/// A model, one of its bodies, and how to print what is found.
#[derive(Args, Debug)]
struct BodyArgs {
    #[command(flatten)]
    model: ModelArg,
    /// A named body: original, long-leg (legs 1.5x), heavy (torso mass 2x).
    #[arg(long, default_value_t = SweepSpec::default().variant, value_name = "NAME")]
    variant: String,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Args, Debug)]
struct PoseArgs {
    #[command(flatten)]
    body: BodyArgs,
    /// Aim the feet this far below the hips (m) instead of the chapter's 0.14 m scaled to the
    /// model's legs.
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    depth: Option<f64>,
}

impl BodyArgs {
    /// Runs `find` on the body and prints its answer as text or JSON.
    fn show<T: serde::Serialize>(
        &self,
        find: impl FnOnce(&ModelSource, &pupper_core::robot::variant::Variant) -> Result<T>,
        text: impl FnOnce(&T) -> String,
    ) -> Result<()> {
        let found = find(
            &self.model.source()?,
            pupper_core::robot::variant::variant(&self.variant)?,
        )?;
        if self.json {
            outln!("{}", print::json(&found)?);
        } else {
            outp!("{}", text(&found));
        }
        Ok(())
    }
}

#[derive(Args, Debug)]
struct ModelArg {
    /// Built-in model name (pupper_v3, pupper_v3_fixed) or path to an MJCF file.
    #[arg(long, short = 'm', default_value_t = SweepSpec::default().model, value_name = "NAME|PATH")]
    model: String,
}

impl ModelArg {
    fn source(&self) -> Result<ModelSource> {
        ModelSource::parse(&self.model)
    }
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum ModeArg {
    /// MuJoCo's affine actuators do the PD (gains written into gainprm/biasprm).
    Servo,
    /// PD computed in Rust every step, clipped to --max-torque; actuators as direct torque inputs.
    Torque,
}

impl From<ModeArg> for Mode {
    fn from(m: ModeArg) -> Mode {
        match m {
            ModeArg::Servo => Mode::Servo,
            ModeArg::Torque => Mode::Torque,
        }
    }
}

impl From<Mode> for ModeArg {
    fn from(m: Mode) -> ModeArg {
        match m {
            Mode::Servo => ModeArg::Servo,
            Mode::Torque => ModeArg::Torque,
        }
    }
}

/// What every simulating command shares: the model, the controller, how
/// long, and where cells start. Defaults come from `SweepSpec::default()`.
#[derive(Args, Debug)]
struct SimArgs {
    #[command(flatten)]
    model: ModelArg,
    /// A named body: original, long-leg (thighs and calves 1.5x), heavy (torso mass 2x) (in a
    /// sweep: where the grid has no variant, leg_scale or torso_mass_scale axis).
    #[arg(long, default_value_t = SweepSpec::default().variant, value_name = "NAME")]
    variant: String,
    /// Who computes the PD torques.
    #[arg(long, value_enum, default_value_t = ModeArg::from(SweepSpec::default().mode))]
    mode: ModeArg,
    /// Simulated seconds (in a sweep: of every cell) [default: 10; response: 3]
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    seconds: Option<f64>,
    /// Proportional gain (N·m/rad) of every actuator (in a sweep: where the grid has no kp axis)
    /// [default: each actuator's own, as the model declares it; Pupper v3: 5]
    #[arg(long, allow_negative_numbers = true)]
    kp: Option<f64>,
    /// Derivative gain (N·m·s/rad) of every actuator (in a sweep: where the grid has no kd axis)
    /// [default: each actuator's own, as the model declares it; Pupper v3: 0.1]
    #[arg(long, allow_negative_numbers = true)]
    kd: Option<f64>,
    /// Torque limit (N·m) of every actuator, in both modes [default: each actuator's own
    /// force range, else its control range; Pupper v3's motors: 3]
    #[arg(long, value_name = "NM", allow_negative_numbers = true)]
    max_torque: Option<f64>,
    /// Keyframe to reset to; its ctrl (or joint qpos) gives the joint targets.
    /// [default: home; response: the searched stand pose, as --pose auto]
    #[arg(long, value_name = "NAME", conflicts_with = "pose")]
    keyframe: Option<String>,
    /// Start and target joint angles (rad), one per actuator in ctrl order, comma-separated;
    /// or `auto`: a stand pose searched on the body (in a sweep: on each cell's own; see `pupper pose`), the base
    /// just above the floor.
    #[arg(long, value_name = "Q1,Q2,...|auto", allow_hyphen_values = true)]
    pose: Option<String>,
    /// With --pose auto: aim the feet this far below the hips (m) [default: the chapter's
    /// 0.14 m on Pupper v3's legs, scaled to the model's leg length]
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    depth: Option<f64>,
    /// Torque mode's servo firmware and motor, KEY=VALUE,...: rate=HZ (the PD's update rate,
    /// torque held between updates), filter=HZ (first-order low-pass on the derivative),
    /// counts=N (encoder counts per revolution; the derivative is then the encoder's
    /// difference), delay=S (command delay: the PD tracks the target of S ago), noload=RAD_S
    /// (torque limit falling linearly to 0 at this speed). E.g. rate=1000,filter=100,counts=16384
    /// [default: ideal, the PD every physics step on the exact state]
    #[arg(long, value_name = "SPEC")]
    motor: Option<String>,
}

impl SimArgs {
    /// These arguments over the spec's defaults.
    fn spec(&self) -> Result<SweepSpec> {
        Ok(SweepSpec {
            model: self.model.model.clone(),
            variant: self.variant.clone(),
            mode: self.mode.into(),
            seconds: self.seconds.unwrap_or(SweepSpec::default().seconds),
            kp: self.kp,
            kd: self.kd,
            max_torque: self.max_torque,
            keyframe: self
                .keyframe
                .clone()
                .unwrap_or_else(|| SweepSpec::default().keyframe),
            pose: self.pose.as_deref().map(spec::parse_pose).transpose()?,
            depth: self.depth,
            motor: self.motor.clone(),
            ..SweepSpec::default()
        })
    }
}

/// Randomized replicates: a population of plausible robots per cell.
#[derive(Args, Debug)]
#[command(next_help_heading = "Randomized replicates")]
struct PopulationArgs {
    /// Runs of every cell, each on a robot drawn by --randomize. Writes replicates.csv (a row
    /// per cell and replicate, with the drawn values and its metrics); summary.csv then holds,
    /// per metric, `mean:METRIC` and `p95:METRIC` (the worst-side 95th percentile: the 5th for
    /// final_z) over the replicates that stayed up, and `failure_fraction` (fell or diverged).
    /// Replicates are more simulations in the same batches; --trace and --render show
    /// replicate 0 of each cell.
    #[arg(long, default_value_t = SweepSpec::default().replicates, value_name = "R")]
    replicates: u32,
    /// Seed of the draws. Each draw is a function of (seed, cell id, replicate, quantity)
    /// alone, so the numbers are the same whatever the threads, batches or resume points.
    #[arg(long, default_value_t = SweepSpec::default().seed, value_name = "S")]
    seed: u64,
    /// What differs between replicates, QUANTITY=DISTRIBUTION; repeat for more.
    /// Relative (a factor uniform in 1±P): torso_mass=±10%, leg_mass=±10% (thigh and calf),
    /// motor_gain=±5% (drawn per actuator). Uniform ranges: friction=0.5:1.2 (feet and floor);
    /// with a push (sweep, not lab): push_force=-35:-15 (N), push_at=1.5:3 (s). Torque mode only: q_noise=N(0,0.002) (rad,
    /// on the angles the PD reads, every step), delay=0:3 (whole control steps the PD reads
    /// late), and the --motor model's motor_delay=0:0.01 (s), motor_filter=50:200 (Hz),
    /// motor_noload=20:40 (rad/s). `+-10%` may stand for `±10%`.
    #[arg(long, value_name = "QUANTITY=DIST", allow_hyphen_values = true)]
    randomize: Vec<String>,
}

impl PopulationArgs {
    fn apply(&self, spec: SweepSpec) -> SweepSpec {
        SweepSpec {
            replicates: self.replicates,
            seed: self.seed,
            randomize: self.randomize.clone(),
            ..spec
        }
    }
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Backend")]
struct BackendArgs {
    /// What steps the physics. cpu: MuJoCo on this machine's cores, float64 (the reference).
    /// warp: MuJoCo Warp, float32, thousands of cells at once on a GPU (tens of thousands of
    /// cells a batch); needs the optional extra: pip install 'pupper_core[gpu]' (in a
    /// checkout: make setup PUPPER_EXTRAS=gpu). Results agree with cpu to about 1e-4 m in
    /// base z on the chapter's schedule; the manifest records backend, device and precision.
    /// In torque mode warp runs the PD inside MuJoCo's actuators (gain kp, bias -kp·q - kd·q̇,
    /// clipped at the torque limit), so --randomize delay, q_noise and motor_gain need cpu.
    #[arg(long, default_value = "cpu", value_name = "NAME", value_parser = ["cpu", "warp"])]
    backend: String,
    /// The Warp device for --backend warp: cuda:0 (the first GPU; cuda:1 the second) or cpu
    /// (slow: for tests on machines without a GPU) [default: cuda:0]. `pupper doctor` lists
    /// the devices Warp sees.
    #[arg(long, value_name = "DEVICE")]
    device: Option<String>,
    /// Run the cells as tasks on a Ray cluster: auto (the RAY_ADDRESS variable, or the cluster
    /// this machine is a node of), ray://HOST:PORT (Ray's client port, 10001 by default) or
    /// HOST:PORT (the head's port, from a node). Each task is a batch of neighbouring cells
    /// through one node's cores (-j sets the CPUs per task, default the smallest node's; on
    /// warp with a CUDA device a task takes one GPU instead);
    /// each finished task is written here as it arrives, so Ctrl-C, a dead driver or a lost
    /// node lose only running tasks (Ray retries those of a dead worker), and --resume
    /// continues on Ray or locally. Same summary.csv as a local run. Every node needs the same
    /// pupper_core and mujoco (checked) and model file; needs the optional extra:
    /// pip install 'pupper_core[ray]' (in a checkout: make setup PUPPER_EXTRAS=ray).
    #[arg(long, value_name = "ADDRESS")]
    ray: Option<String>,
}

impl BackendArgs {
    fn apply(&self, spec: SweepSpec) -> SweepSpec {
        SweepSpec {
            backend: self.backend.clone(),
            device: self.device.clone(),
            ray: self.ray.clone(),
            ..spec
        }
    }
}

#[derive(Args, Debug)]
#[command(
    after_help = "Without --grid the gains are kp=10,30,60,120 x kd=0.5,1,2,5; --grid replaces them \
(any sweep axis; a variant axis there replaces --variants). The best gains per body follow the \
--best-by rule of `pupper sweep`: the cell stood (with replicates: none fell or diverged), saturation \
under --max-saturation, lowest --rank, ties within 0.001 mm to the smaller dip, then the first cell."
)]
struct LabArgs {
    #[command(flatten)]
    model: ModelArg,
    /// The bodies, comma-separated: original, long-leg (legs 1.5x), heavy (torso mass 2x).
    /// (`--variant`, as sweep spells it, works too.)
    #[arg(long, alias = "variant", value_delimiter = ',', default_values_t = pupper_core::request::lab::VARIANTS.map(String::from), value_name = "NAME,...")]
    variants: Vec<String>,
    #[command(flatten)]
    grid: GridArg,
    /// Simulated seconds per cell.
    #[arg(long, default_value_t = pupper_core::request::lab::SECONDS, value_name = "S")]
    seconds: f64,
    /// The vertical disturbance AMPLITUDE*sin(2π·FREQUENCY·t) (N, Hz).
    #[arg(
        long,
        default_value = "2,1.2",
        value_name = "AMP,HZ",
        allow_hyphen_values = true
    )]
    sine: String,
    /// Aim each body's stand pose at this depth of the feet below the hips (m) [default: the
    /// chapter's 0.14 m on Pupper v3's legs, scaled to each body's leg length]
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    depth: Option<f64>,
    /// The servo firmware and motor the lab's torque-mode PD runs through, as for `sweep
    /// --motor` (rate=HZ, filter=HZ, counts=N, delay=S, noload=RAD_S) [default: ideal]
    #[arg(long, value_name = "SPEC")]
    motor: Option<String>,
    /// Cells at the torque limit in this share of actuator-steps or more are never "best".
    #[arg(long, default_value_t = pupper_core::results::best::MAX_SATURATION, value_name = "FRACTION")]
    max_saturation: f64,
    /// The metric each body's best gains are ranked by (lower is better) [default:
    /// last_1s_std_mm; with replicates p95:last_1s_std_mm].
    #[arg(long, value_name = "[STAT:]METRIC")]
    rank: Option<String>,
    /// Run directory (default runs/<time>-lab).
    #[arg(long, short = 'o', value_name = "DIR", conflicts_with = "resume")]
    out: Option<PathBuf>,
    /// Overwrite pupper's files in an existing --out directory.
    #[arg(long, requires = "out")]
    force: bool,
    /// Continue an interrupted lab in DIR (alone: with the manifest's inputs).
    #[arg(long, value_name = "DIR")]
    resume: Option<PathBuf>,
    /// Batch threads; 0 uses all cores. Never changes the numbers.
    #[arg(long, short = 'j', default_value_t = SweepSpec::default().threads, value_name = "N")]
    threads: usize,
    /// Also write the GIF of the bodies at their best gains.
    #[arg(long)]
    render: bool,
    /// Print the rows as JSON instead of a line per body.
    #[arg(long)]
    json: bool,
    /// No progress bar.
    #[arg(long, short = 'q')]
    quiet: bool,
    /// Answer the lab's question per body by a search (pupper tune; the tune extra) over
    /// kp 10-120 x kd 0.5-5 (log) instead of the 4x4 grid: a study per body in DIR/<body>/,
    /// each body's best gains in DIR/best.csv.
    #[arg(long, conflicts_with_all = ["resume", "grid"])]
    tune: bool,
    /// With --tune: finished trials per body.
    #[arg(long, default_value_t = 64, value_name = "N", requires = "tune")]
    trials: u64,
    /// With --tune: trials per generation (one batch).
    #[arg(long, default_value_t = 16, value_name = "B", requires = "tune")]
    batch: u64,
    // last: their help headings would hold every option after them
    #[command(flatten)]
    backend: BackendArgs,
    #[command(flatten)]
    population: PopulationArgs,
}

#[derive(Args, Debug)]
struct StandArgs {
    #[command(flatten)]
    sim: SimArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Args, Debug)]
#[command(
    after_help = "Grid values: a list 10,30,60 | a linear range start:stop:count (10:120:12) | \
a log range start:stop:count:log (1:100:5:log).
Axes: kp, kd, push_force (N, world z), max_torque (N·m), friction (feet and floor), timestep (s),
leg_scale, torso_mass_scale, variant (body names: original, long-leg, heavy; numeric scale axes
multiply a body's scales). Cells are the product of the axes, the last axis varying fastest.
Metrics per cell: final_z (m), last_1s_std_mm (the last 1 s, which must lie after the landing at
1 s), push_dip_mm (mean z 0.5 s before the push minus the minimum from push start to push end +
1.5 s), settle_time_s (from the push's start until base z stays within 2 % of the dip of its final
height), max_tilt_deg and peak_torque (N·m) after the landing (from 1 s, or the push if earlier),
saturation_frac (share of actuator-steps at the torque limit), tracking_rms (rad), status, and
event_time (s, when it fell or diverged). A metric the run is too short for is left empty, with a
note. Status: ok; saturated (stood, at the torque limit in 5 % or more of actuator-steps); fell (the
base below 30 % of the robot's stance height, i.e. its base height with the lowest foot on the
floor in the start pose, or tilted past 60 deg, at any moment; or collapsed: mean height over the
last 1 s below 60 % of the stance, or mean tilt there past 30 deg); diverged (the physics blew up).
Ties: cells within 0.001 mm on a *_mm metric are tied, and the smaller push dip decides."
)]
struct SweepArgs {
    #[command(flatten)]
    grid: GridArg,
    /// A named grid: chapter-4.6 (the chapter's soft/default/stiff/underD servo cases) or lab-grid (the lab's
    /// kp 10,30,60,120 x kd 0.5,1,2,5 only, in this command's mode and push; the lab itself is `pupper lab`).
    #[arg(long, value_name = "NAME", conflicts_with = "grid")]
    preset: Option<String>,
    #[command(flatten)]
    sim: SimArgs,
    /// Push force along world z (N; negative pushes down).
    #[arg(long, default_value_t = SweepSpec::default().push_force, value_name = "N", allow_hyphen_values = true)]
    push_force: f64,
    /// Push start time (s).
    #[arg(long, default_value_t = SweepSpec::default().push_at, value_name = "S", allow_negative_numbers = true)]
    push_at: f64,
    /// Push duration (s).
    #[arg(long, default_value_t = SweepSpec::default().push_duration, value_name = "S", allow_negative_numbers = true)]
    push_duration: f64,
    /// No push.
    #[arg(long)]
    no_push: bool,
    /// A continuous vertical force AMPLITUDE*sin(2π·FREQUENCY·t) on the base (N, Hz), e.g. 2,1.2.
    #[arg(long, value_name = "AMP,HZ", allow_hyphen_values = true)]
    sine: Option<String>,
    /// Run directory (default runs/<time>-<grid>).
    #[arg(long, short = 'o', value_name = "DIR", conflicts_with = "resume")]
    out: Option<PathBuf>,
    /// Overwrite pupper's files in an existing --out directory.
    #[arg(long)]
    force: bool,
    /// Run only shard I of N of the grid's cells (1 <= I <= N; cell k belongs to shard
    /// k mod N + 1, so costly and cheap cells spread evenly), into its own run directory
    /// whose manifest records the whole grid, the shard and the host. Resume, Ctrl-C and
    /// checks work per shard; `pupper merge` puts the shards together. In a Slurm array:
    /// --shard $SLURM_ARRAY_TASK_ID/N with --array=1-N.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Continue an interrupted run in DIR: checks the inputs match its manifest, runs only missing cells. Alone, it reuses the manifest's inputs.
    #[arg(long, value_name = "DIR")]
    resume: Option<PathBuf>,
    /// Keep base-z traces (traces.csv), every --trace-every-th step.
    #[arg(long)]
    trace: bool,
    /// Decimation of the traces.
    #[arg(long, default_value_t = SweepSpec::default().trace_every, value_name = "N")]
    trace_every: usize,
    /// Batch threads; 0 uses all cores. Never changes the numbers.
    #[arg(long, short = 'j', default_value_t = SweepSpec::default().threads, value_name = "N")]
    threads: usize,
    /// Most cells per batch [default: 256 on the cpu backend, whose batches
    /// hold about 10 s of work so a stop loses little; on warp, as many as
    /// the device's memory holds]. Fewer cells bound memory. Never changes
    /// the numbers.
    #[arg(long, value_name = "N")]
    chunk_cells: Option<usize>,
    /// Refuse grids with more cells than this.
    #[arg(long, default_value_t = SweepSpec::default().max_cells, value_name = "N")]
    max_cells: usize,
    /// Write plots (base-z curves, heatmaps or bars) into DIR/plots.
    #[arg(long)]
    plot: bool,
    /// Stop stepping a robot once it has fallen (base below 30 % of its stance height or
    /// tilted past 60 deg) or diverged, within one batch call (0.5 s at most in servo mode, at
    /// once in torque mode): its row keeps its status (fell) and the metrics up to the stop;
    /// every other row is unchanged. Saves the cell-steps of robots on the floor. (A slow
    /// collapse is judged on the last second, so it runs to the end.)
    #[arg(long)]
    stop_fallen: bool,
    /// Render the effects GIF and final-frame PNG of the cells (up to 6) into DIR/plots.
    #[arg(long)]
    render: bool,
    /// Pick the best cell of each group of these axes (e.g. kd, or leg_scale,torso_mass_scale):
    /// printed a line per group and written to DIR/best.csv. Rule: among cells that stood
    /// (status ok or saturated; with replicates: none fell or diverged), whose metric is a number
    /// and whose saturation_frac (with replicates: p95:saturation_frac) is under
    /// --max-saturation, the lowest --rank wins; cells within 0.001 mm of it on a *_mm metric
    /// are tied and the smaller push dip decides, then the first cell in grid order.
    #[arg(long, value_name = "AXIS[,AXIS]", value_delimiter = ',')]
    best_by: Option<Vec<String>>,
    /// The metric --best-by ranks by (lower is better): a summary.csv column. With replicates,
    /// a statistic over them: mean:METRIC or p95:METRIC (worst side), e.g.
    /// p95:last_1s_std_mm [default: last_1s_std_mm; with replicates p95:last_1s_std_mm].
    #[arg(long, alias = "best-metric", value_name = "[STAT:]METRIC")]
    rank: Option<String>,
    /// Cells at the torque limit in this share of actuator-steps or more are never "best".
    #[arg(long, default_value_t = pupper_core::results::best::MAX_SATURATION, value_name = "FRACTION")]
    max_saturation: f64,
    /// Print the rows as JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// No progress bar.
    #[arg(long, short = 'q')]
    quiet: bool,
    // last: their help headings would hold every option after them
    #[command(flatten)]
    backend: BackendArgs,
    #[command(flatten)]
    population: PopulationArgs,
}

impl SweepArgs {
    /// These arguments over the spec's defaults.
    fn spec(&self) -> Result<SweepSpec> {
        Ok(SweepSpec {
            grid: match &self.preset {
                Some(p) => GridInput::Preset(p.clone()),
                None => GridInput::Specs(self.grid.grid.clone()),
            },
            push: !self.no_push,
            push_force: self.push_force,
            push_at: self.push_at,
            push_duration: self.push_duration,
            sine: self.sine.as_deref().map(spec::parse_sine).transpose()?,
            // plots draw the base-z curves from the traces
            trace: self.trace || self.plot,
            trace_every: self.trace_every,
            stop_fallen: self.stop_fallen,
            threads: self.threads,
            chunk_cells: self.chunk_cells,
            max_cells: self.max_cells,
            force: self.force,
            shard: self.shard.clone(),
            ..self.backend.apply(self.population.apply(self.sim.spec()?))
        })
    }
}

#[derive(Args, Debug)]
#[command(after_help = "Examples:
  pupper render --kp 5 --kd 0.1 -o stand.png          the robot after 10 s standing
  pupper render --run runs/X --cell 5 --time 2.5     cell 5 of a finished sweep at 2.5 s")]
struct RenderArgs {
    #[command(flatten)]
    sim: SimArgs,
    /// A finished run directory: draw one of its cells (--cell), re-simulated with the run's
    /// own inputs (its push too); the model and controller flags are then not given.
    #[arg(long, value_name = "DIR")]
    run: Option<PathBuf>,
    /// With --run: the cell, by its id or index in summary.csv [default: the first].
    #[arg(long, value_name = "ID", requires = "run")]
    cell: Option<String>,
    /// The moment drawn, in simulated seconds from the start [default: the end of the run].
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    time: Option<f64>,
    /// Output PNG; an existing directory gets a file named for what is drawn
    /// [default: pupper.png, or with --run DIR/plots/render-<ID>-t<T>.png]
    #[arg(long, short = 'o', value_name = "FILE")]
    out: Option<PathBuf>,
    /// Overwrite FILE if it exists (only ever a PNG: any other file is refused).
    #[arg(long)]
    force: bool,
    /// Image width in pixels.
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Print {"path": ...} as JSON instead of the "wrote" line.
    #[arg(long)]
    json: bool,
}

impl RenderArgs {
    /// The PNG to write: `-o` as given, inside it when it is a directory,
    /// else the default for what is drawn.
    fn target(&self, default_name: &str, default_dir: Option<&std::path::Path>) -> PathBuf {
        match &self.out {
            Some(o) if o.is_dir() => o.join(default_name),
            Some(o) => o.clone(),
            None => default_dir
                .map(|d| d.join(default_name))
                .unwrap_or_else(|| PathBuf::from(default_name)),
        }
    }

    fn run(&self) -> Result<()> {
        let written = match &self.run {
            Some(dir) => self.render_cell(dir)?,
            None => self.render_stand()?,
        };
        if self.json {
            outln!("{}", serde_json::json!({ "path": written }));
        } else {
            outln!("wrote {written}");
        }
        Ok(())
    }

    fn check_time(&self, seconds: f64) -> Result<()> {
        match self.time {
            Some(t) if !(0.0..=seconds).contains(&t) => Err(Error::Config(format!(
                "--time {t} is outside the run's 0..{seconds} s: give a time in that range"
            ))),
            _ => Ok(()),
        }
    }

    fn render_stand(&self) -> Result<String> {
        // the spec checks the values; the runner simulates, Python draws
        let spec = self.sim.spec()?;
        spec.build()?;
        self.check_time(spec.seconds)?;
        let out = self.target("pupper.png", None);
        check_png_target(&out, self.force)?;
        let written = bridge::call_helper(
            "pupper_core.render",
            "render_png",
            &[out.display().to_string()],
            &serde_json::json!({
                "width": self.width,
                "height": self.height,
                "time": self.time,
                "model": spec.model,
                "variant": spec.variant,
                "mode": spec.mode,
                "seconds": spec.seconds,
                "kp": spec.kp,
                "kd": spec.kd,
                "max_torque": spec.max_torque,
                "keyframe": spec.keyframe,
                "pose": spec.pose,
            }),
        )?;
        Ok(written.first().cloned().unwrap_or_default())
    }

    fn render_cell(&self, dir: &std::path::Path) -> Result<String> {
        if self.sim.spec()? != SweepSpec::default() {
            return Err(Error::Config(format!(
                "--run {} draws a cell with the run's own inputs: drop the model and controller options, or render without --run",
                dir.display()
            )));
        }
        let cfg = output::read_manifest(dir)?.config;
        let cells = cfg.grid.cells();
        let cell = match &self.cell {
            None => cells.first(),
            Some(want) => cells
                .iter()
                .find(|c| &c.id == want || want.parse::<usize>().ok() == Some(c.index)),
        }
        .ok_or_else(|| {
            let ids: Vec<&str> = cells.iter().take(6).map(|c| c.id.as_str()).collect();
            Error::Config(format!(
                "--cell {} is not a cell of {}: give an id or index from its summary.csv (e.g. {}{})",
                self.cell.as_deref().unwrap_or(""),
                dir.display(),
                ids.join(", "),
                if cells.len() > ids.len() { ", ..." } else { "" }
            ))
        })?;
        let seconds = cfg.schedule.duration;
        self.check_time(seconds)?;
        let at = self.time.unwrap_or(seconds);
        let out = self.target(
            &format!("render-{}-t{}.png", cell.id, output::fmt_f64(at)),
            Some(&dir.join("plots")),
        );
        check_png_target(&out, self.force)?;
        let written = bridge::call_helper(
            "pupper_core.render",
            "render_cell_png",
            &[out.display().to_string(), dir.display().to_string()],
            &serde_json::json!({
                "cell": cell.index,
                "time": at,
                "width": self.width,
                "height": self.height,
            }),
        )?;
        Ok(written.first().cloned().unwrap_or_default())
    }
}

/// `render -o FILE`: a new file, or with `force` an existing PNG; never
/// anything else (a directory, a file that is not a PNG).
fn check_png_target(path: &std::path::Path, force: bool) -> Result<()> {
    let shown = path.display();
    let Ok(meta) = std::fs::symlink_metadata(path) else {
        return Ok(());
    };
    if !meta.is_file() {
        return Err(Error::Output(format!(
            "'{shown}' exists and is not a file: give -o a new .png path"
        )));
    }
    let mut head = [0u8; 8];
    let is_png = std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
        .is_ok()
        && head == *b"\x89PNG\r\n\x1a\n";
    match (is_png, force) {
        (false, _) => Err(Error::Output(format!(
            "'{shown}' exists and is not a PNG: pupper never writes over it; give -o a new .png path"
        ))),
        (true, false) => Err(Error::RunExists(format!(
            "'{shown}' exists: add --force to overwrite it, or give -o a new path"
        ))),
        (true, true) => Ok(()),
    }
}

pub fn run(cli: Cli, stop: &'static AtomicBool) -> Result<u8> {
    match cli.command {
        Command::Info(a) => a.show(api::info, print::info)?,
        Command::Pose(a) => a.body.show(|m, v| api::pose(m, v, a.depth), print::pose)?,
        Command::Stand(a) => {
            let r = api::stand(&a.sim.spec()?)?;
            for n in &r.notes {
                eprintln!("note: {n}");
            }
            if a.json {
                outln!("{}", print::json(&r)?);
            } else {
                outp!("{}", print::stand(&r));
            }
        }
        Command::Sweep(a) => return sweep(*a, stop),
        Command::Lab(a) => return lab(*a, stop),
        Command::Response(a) => return response(*a, stop),
        Command::Tune(a) => return a.run(),
        Command::Excite(a) => return a.run(),
        Command::Report { dir } => {
            write_report(&dir)?;
            eprintln!("wrote {}", dir.join("report.html").display());
            return Ok(0);
        }
        Command::Fit(a) => return a.run(),
        Command::Gains(a) => {
            use pupper_core::robot::gains::Ask;
            let ask = match (a.bandwidth, a.kp, a.kd) {
                (Some(hz), _, _) => Ask::Bandwidth {
                    hz,
                    zeta: a.damping,
                },
                (None, Some(kp), Some(kd)) => Ask::Gains { kp, kd },
                _ => {
                    return Err(Error::Config(
                        "pupper gains needs --bandwidth HZ (with --damping, default 0.7) or --kp and --kd".into(),
                    ));
                }
            };
            let pose = match a.pose.as_deref().map(spec::parse_pose).transpose()? {
                Some(spec::PoseInput::Angles(p)) => Some(p),
                _ => None,
            };
            let r = api::gains(&a.model.source()?, pose, ask)?;
            if a.json {
                outln!("{}", print::json(&r)?);
            } else {
                outp!("{}", print::gains(&r));
            }
        }
        Command::Merge(a) => {
            let (out, existing) = match (a.out, a.force) {
                (Some(o), true) => (o, Existing::Overwrite),
                (Some(o), false) => (o, Existing::Refuse),
                (None, _) => (
                    PathBuf::from("runs").join(format!(
                        "{}-merged",
                        chrono::Local::now().format("%Y%m%d-%H%M%S")
                    )),
                    Existing::Unique,
                ),
            };
            let (dir, m) = pupper_core::results::rundir::merge(&a.dirs, &out, existing)?;
            if a.json {
                outln!(
                    "{}",
                    serde_json::json!({"out": dir, "shards": m.merged.len(), "cells": m.cells_total})
                );
                return Ok(0);
            }
            outln!(
                "merged {} shards ({} cells) into {}",
                m.merged.len(),
                m.cells_total,
                dir.join("summary.csv").display()
            );
        }
        Command::Doctor { json } => {
            let r = bridge::doctor()?;
            if json {
                outln!("{}", print::json(&r)?);
            } else {
                outp!("{}", print::doctor(&r));
            }
            if let Some(p) = r.problem {
                return Err(Error::Mujoco(p));
            }
        }
        Command::Render(a) => a.run()?,
        Command::View { model } => {
            let source = model.source()?;
            if std::env::var_os("DISPLAY").is_none()
                && std::env::var_os("WAYLAND_DISPLAY").is_none()
            {
                return Err(Error::Display(
                    "no display found (DISPLAY and WAYLAND_DISPLAY are unset): run pupper view in a desktop session, or use `pupper render` for a PNG".into(),
                ));
            }
            let name = match &source {
                ModelSource::Path(p) => p.display().to_string(),
                ModelSource::Builtin(n) => n.clone(),
            };
            bridge::call_helper(
                "pupper_core.render",
                "view",
                &[name],
                &serde_json::json!({}),
            )?;
        }
    }
    Ok(0)
}

/// A sweep as the CLI runs it (`sweep` and `lab` differ only in how they
/// fill it): the spec, where it goes, and what to show after.
struct Job {
    spec: SweepSpec,
    /// The spec of the same command with no option given: what a `--resume
    /// DIR` alone compares against to find the inputs the user set.
    baseline: SweepSpec,
    out: Option<PathBuf>,
    resume: Option<PathBuf>,
    /// `--resume DIR` without grid flags: the manifest's inputs.
    resume_alone: bool,
    preset: Option<String>,
    quiet: bool,
    json: bool,
    plot: bool,
    render: bool,
    rule: Option<best::Rule>,
    lab: bool,
}

fn sweep(a: SweepArgs, stop: &'static AtomicBool) -> Result<u8> {
    // no --rank: chosen in run_job, once the run's config is known
    let metric = a.rank.clone().unwrap_or_default();
    let rule = a.best_by.as_ref().map(|by| best::Rule {
        max_saturation: a.max_saturation,
        ..best::Rule::new(&metric, by)
    });
    run_job(
        Job {
            spec: a.spec()?,
            baseline: SweepSpec::default(),
            resume_alone: a.grid.grid.is_empty() && a.preset.is_none(),
            out: a.out,
            resume: a.resume,
            preset: a.preset,
            quiet: a.quiet,
            json: a.json,
            plot: a.plot,
            render: a.render,
            rule,
            lab: false,
        },
        stop,
    )
}

fn response(a: ResponseArgs, stop: &'static AtomicBool) -> Result<u8> {
    let baseline = pupper_core::request::response::spec(
        SweepSpec {
            seconds: pupper_core::request::response::SECONDS,
            ..SweepSpec::default()
        },
        &Default::default(),
        pupper_core::request::response::DEFAULT_HOLD,
        &[],
        false,
        false,
    )?;
    run_job(
        Job {
            spec: a.spec()?,
            baseline,
            resume_alone: a.grid.grid.is_empty(),
            out: a.out,
            resume: a.resume,
            preset: Some("response".into()),
            quiet: a.quiet,
            json: a.json,
            plot: a.plot,
            render: false,
            rule: None,
            lab: false,
        },
        stop,
    )
}

fn lab(a: LabArgs, stop: &'static AtomicBool) -> Result<u8> {
    let sine = spec::parse_sine(&a.sine)?;
    if a.tune {
        let out = a.out.clone().unwrap_or_else(|| {
            PathBuf::from("runs").join(format!(
                "{}-lab-tune",
                chrono::Local::now().format("%Y%m%d-%H%M%S")
            ))
        });
        let mut py = PyArgs::new();
        let mut args = serde_json::json!({
            "variants": a.variants,
            "objective": a.rank.clone().unwrap_or_else(|| "last_1s_std_mm".into()),
            "trials": a.trials,
            "batch": a.batch,
            "seed": a.population.seed,
            "out": py.path(&out),
            "force": a.force,
            "progress": !a.quiet,
            "seconds": a.seconds,
            "sine": sine,
            "model": a.model.model,
            "threads": a.threads,
            "replicates": a.population.replicates,
            "randomize": a.population.randomize,
        });
        if let (Some(d), Some(m)) = (a.depth, args.as_object_mut()) {
            m.insert("depth".into(), serde_json::json!(d));
        }
        return python_command("pupper_core._tune", "_lab_cli", &py.text(&args));
    }
    let spec = SweepSpec {
        model: a.model.model.clone(),
        threads: a.threads,
        depth: a.depth,
        motor: a.motor.clone(),
        force: a.force,
        ..a.backend
            .apply(a.population.apply(pupper_core::request::lab::spec(
                &a.variants,
                &a.grid.grid,
                a.seconds,
                sine,
            )))
    };
    let metric = a.rank.clone().unwrap_or_default();
    run_job(
        Job {
            spec,
            baseline: pupper_core::request::lab::spec(
                &pupper_core::request::lab::VARIANTS.map(String::from),
                &[],
                pupper_core::request::lab::SECONDS,
                pupper_core::request::lab::SINE,
            ),
            resume_alone: a.grid.grid.is_empty(),
            out: a.out,
            resume: a.resume,
            preset: Some("lab".into()),
            quiet: a.quiet,
            json: a.json,
            plot: true,
            render: a.render,
            rule: Some(best::Rule {
                max_saturation: a.max_saturation,
                ..best::Rule::new(&metric, &["variant".to_string()])
            }),
            lab: true,
        },
        stop,
    )
}

/// `--resume DIR` alone runs with the manifest's inputs: an input the
/// command line also sets (away from its default) to another value is
/// refused, never silently dropped.
fn refuse_other_inputs(
    dir: &std::path::Path,
    baseline: &SweepSpec,
    given: &pupper_core::plan::config::SweepConfig,
    run: &pupper_core::plan::config::SweepConfig,
) -> Result<()> {
    let Ok(base) = baseline.build() else {
        return Ok(());
    };
    let set: Vec<String> = output::config_diff(&base.config, given)
        .into_iter()
        .filter_map(|d| d.split(':').next().map(String::from))
        .collect();
    let clash: Vec<String> = output::config_diff(run, given)
        .into_iter()
        .filter(|d| {
            d.split(':')
                .next()
                .is_some_and(|p| set.iter().any(|s| s == p))
        })
        .collect();
    if clash.is_empty() {
        return Ok(());
    }
    Err(Error::ResumeMismatch(format!(
        "--resume {} continues the run with its own inputs, but this command sets others ({}): drop those options, or start a new run with -o",
        dir.display(),
        clash.join(", ")
    )))
}

fn run_job(a: Job, stop: &'static AtomicBool) -> Result<u8> {
    // as text for the manifest: a path that is not UTF-8 keeps its other bytes
    let command: Vec<String> = std::env::args_os()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    let sweep = match &a.resume {
        // `--resume DIR` alone: the manifest's inputs
        Some(dir) if a.resume_alone => {
            let mut s = SweepSpec {
                out: Some(dir.clone()),
                resume: true,
                ..a.spec.clone()
            }
            .build()?;
            let m = output::read_manifest(dir)?;
            refuse_other_inputs(dir, &a.baseline, &s.config, &m.config)?;
            s.config = m.config;
            s.shard = m.shard.map(|r| r.shard);
            s
        }
        Some(dir) => SweepSpec {
            out: Some(dir.clone()),
            resume: true,
            ..a.spec.clone()
        }
        .build()?,
        None => {
            let mut s = SweepSpec {
                force: a.spec.force,
                ..a.spec.clone()
            }
            .build()?;
            s.out = a.out.clone();
            if s.out.is_none() {
                // created when the run starts, the first free name in one step
                s.out = Some(default_out(&a.preset, &s.config));
                s.existing = Existing::Unique;
            }
            s
        }
    };
    // without --rank: the steadiest, over the replicates when there are
    // some (a `--resume DIR` alone learns that from the manifest)
    let mut a = a;
    if let Some(rule) = a.rule.as_mut().filter(|r| r.metric.is_empty()) {
        rule.metric = match sweep.config.replicates.is_plain() {
            true => "last_1s_std_mm".into(),
            false => "p95:last_1s_std_mm".into(),
        };
    }
    // the ranking rule is checked against the grid before anything runs
    if let Some(rule) = &a.rule {
        best::best(&output::header_of(&sweep.config), &[], rule)?;
    }
    let req = SweepRequest { sweep, command };
    let mut ui = Progress {
        bar: None,
        quiet: a.quiet || a.json,
        stop,
    };
    let outcome = api::run_sweep(&req, &mut ui)?;
    for n in &outcome.notes {
        eprintln!("note: {n}");
    }
    let dir = outcome.out.clone().unwrap_or_default();
    if !outcome.complete {
        eprintln!(
            "interrupted: kept {} of {} cells in {}; continue with: pupper {} --resume {}{}",
            outcome.rows.len(),
            outcome.cells_total,
            dir.display(),
            if a.lab {
                "lab"
            } else if a.spec.response.is_some() {
                "response"
            } else {
                "sweep"
            },
            dir.display(),
            a.spec
                .ray
                .as_ref()
                .map(|r| format!(" --ray {r}"))
                .unwrap_or_default()
        );
        return Ok(130);
    }
    if !a.json && !a.lab {
        match a.spec.response.is_some() {
            true => outp!("{}", print::response(&outcome)),
            false => outp!("{}", print::sweep(&outcome)),
        }
    }
    let mut best = None;
    if let Some(rule) = &a.rule {
        let groups = api::write_best(&outcome, rule)?;
        if a.json {
            best = Some(print::best_json(&outcome, rule, &groups));
        } else if a.lab {
            outp!("{}", print::lab(&outcome, rule, &groups));
        } else {
            outp!("{}", print::best(&outcome, rule, &groups));
        }
        eprintln!("wrote {}", dir.join(output::BEST).display());
    }
    if a.json {
        let mut doc = print::rows_json(&outcome);
        if let (Some(b), Some(m)) = (best, doc.as_object_mut()) {
            m.insert("best".into(), b);
        }
        outln!("{}", print::json(&doc)?);
    }
    let dir_s = dir.display().to_string();
    if a.plot {
        let helper = if a.lab {
            "write_lab_plots"
        } else if a.spec.response.is_some() {
            "write_response_plots"
        } else {
            "write_run_plots"
        };
        for p in bridge::call_helper(
            "pupper_core.plots",
            helper,
            std::slice::from_ref(&dir_s),
            &serde_json::json!({}),
        )? {
            eprintln!("wrote {p}");
        }
    }
    if a.lab {
        // the bodies at their best gains, side by side: a PNG, and a GIF with --render
        match bridge::call_helper(
            "pupper_core.render",
            "write_lab_effects",
            std::slice::from_ref(&dir_s),
            &serde_json::json!({ "gif": a.render }),
        ) {
            Ok(paths) if paths.is_empty() => {
                eprintln!("note: no body has best gains (see best.csv): nothing to draw")
            }
            Ok(paths) => paths.iter().for_each(|p| eprintln!("wrote {p}")),
            Err(Error::Display(why)) if !a.render => eprintln!("note: no rendering here ({why})"),
            Err(e) => return Err(e),
        }
    } else if a.render {
        for p in bridge::call_helper(
            "pupper_core.render",
            "write_run_effects",
            std::slice::from_ref(&dir_s),
            &serde_json::json!({}),
        )? {
            eprintln!("wrote {p}");
        }
    }
    // the page a person opens: its path last (-q: written, not said)
    write_report(&dir)?;
    if !a.quiet {
        eprintln!("wrote {}", dir.join("report.html").display());
    }
    Ok(0)
}

/// Writes DIR/report.html. The path crosses as its bytes (hex), so a
/// directory whose name is not UTF-8 is the same directory in Python.
fn write_report(dir: &std::path::Path) -> Result<()> {
    use std::os::unix::ffi::OsStrExt;
    let hex: String = dir
        .as_os_str()
        .as_bytes()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    bridge::call_helper(
        "pupper_core._report",
        "_cli_hex",
        &[hex],
        &serde_json::json!({}),
    )?;
    Ok(())
}

/// The name a run without --out starts from (`-1`, `-2`, ... when taken).
fn default_out(preset: &Option<String>, cfg: &SweepConfig) -> PathBuf {
    let name = match preset {
        Some(p) => p.clone(),
        None if cfg.grid.axes.is_empty() => "single".into(),
        None => cfg
            .grid
            .axes
            .iter()
            .map(|a| a.axis.name())
            .collect::<Vec<_>>()
            .join("-"),
    };
    let stamp = chrono::Local::now().format("%Y%m%d-%H%M%S");
    PathBuf::from("runs").join(format!("{stamp}-{name}"))
}

/// Progress bar on stderr (hidden when stderr is not a terminal) and the
/// Ctrl-C flag.
struct Progress {
    bar: Option<ProgressBar>,
    quiet: bool,
    stop: &'static AtomicBool,
}

impl SweepUi for Progress {
    fn start(&mut self, cells: usize, steps: u64) {
        if self.quiet {
            return;
        }
        let bar = ProgressBar::new(steps);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} {msg} [{bar:30}] {percent:>3}% {elapsed} (eta {eta})",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        bar.set_message(format!("{cells} cells"));
        self.bar = Some(bar);
    }

    fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
    }

    fn hooks(&mut self) -> &mut dyn Hooks {
        self
    }
}

impl Hooks for Progress {
    fn progress(&mut self, steps: u64) {
        if let Some(b) = &self.bar {
            b.inc(steps);
        }
    }

    fn should_stop(&mut self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }
}
