//! Flag groups that several commands share, each defined once and
//! `#[command(flatten)]`ed into the commands that take it.

use std::marker::PhantomData;
use std::path::PathBuf;

use clap::{Arg, ArgAction, ArgMatches, Args, Command, FromArgMatches, ValueEnum};
use pupper_core::Result;
use pupper_core::plan::mode::Mode;
use pupper_core::request::spec::{self, GridInput, SweepSpec};
use pupper_core::robot::model::ModelSource;

/// `--grid`, repeatable.
#[derive(Args, Debug)]
pub(super) struct GridArg {
    /// A grid axis and its values, AXIS=VALUES; repeat for more axes.
    #[arg(long = "grid", short = 'g', value_name = "AXIS=VALUES", allow_hyphen_values = true)]
    pub(super) grid: Vec<String>,
}

impl GridArg {
    /// The grid as the spec takes it.
    pub(super) fn input(&self) -> GridInput {
        GridInput::Specs(self.grid.clone())
    }
}

#[derive(Args, Debug, serde::Serialize)]
pub(super) struct ModelArg {
    /// Built-in model name (pupper_v3, pupper_v3_fixed) or path to an MJCF file.
    #[arg(long, short = 'm', default_value_t = SweepSpec::default().model, value_name = "NAME|PATH")]
    pub(super) model: String,
}

impl ModelArg {
    pub(super) fn source(&self) -> Result<ModelSource> {
        ModelSource::parse(&self.model)
    }
}

/// The one parser of a number flag of a command done in Python: JSON has
/// no NaN or infinity (they would reach Python as null, the flag left out),
/// so they are refused where the flag is read.
pub(super) fn finite(text: &str) -> std::result::Result<f64, String> {
    let v: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("'{text}' is not a number: give a number"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{v} is not a finite number: give a number"))
    }
}

/// A `--max-saturation` value: the core's rule for one.
pub(super) fn saturation(text: &str) -> std::result::Result<f64, String> {
    let x = finite(text)?;
    pupper_core::results::best::saturation_problem(x).map_or(Ok(x), Err)
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub(super) enum ModeArg {
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
pub(super) struct SimArgs {
    #[command(flatten)]
    pub(super) model: ModelArg,
    /// A named body: original, long-leg (thighs and calves 1.5x), heavy (torso mass 2x) (in a
    /// sweep: where the grid has no variant, leg_scale or torso_mass_scale axis).
    #[arg(long, default_value_t = SweepSpec::default().variant, value_name = "NAME")]
    pub(super) variant: String,
    /// Who computes the PD torques.
    #[arg(long, value_enum, default_value_t = ModeArg::from(SweepSpec::default().mode))]
    pub(super) mode: ModeArg,
    /// Simulated seconds (in a sweep: of every cell) [default: 10; response: 3]
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub(super) seconds: Option<f64>,
    /// Proportional gain (N·m/rad) of every actuator (in a sweep: where the grid has no kp axis)
    /// [default: each actuator's own, as the model declares it; Pupper v3: 5]
    #[arg(long, allow_negative_numbers = true)]
    pub(super) kp: Option<f64>,
    /// Derivative gain (N·m·s/rad) of every actuator (in a sweep: where the grid has no kd axis)
    /// [default: each actuator's own, as the model declares it; Pupper v3: 0.1]
    #[arg(long, allow_negative_numbers = true)]
    pub(super) kd: Option<f64>,
    /// Torque limit (N·m) of every actuator, in both modes [default: each actuator's own
    /// force range, else its control range; Pupper v3's motors: 3]
    #[arg(long, value_name = "NM", allow_negative_numbers = true)]
    pub(super) max_torque: Option<f64>,
    /// Keyframe to reset to; its ctrl (or joint qpos) gives the joint targets.
    /// [default: home; response: the searched stand pose, as --pose auto]
    #[arg(long, value_name = "NAME", conflicts_with = "pose")]
    pub(super) keyframe: Option<String>,
    /// Start and target joint angles (rad), one per actuator in ctrl order, comma-separated;
    /// or `auto`: a stand pose searched on the body (in a sweep: on each cell's own; see `pupper pose`), the base
    /// just above the floor.
    #[arg(long, value_name = "Q1,Q2,...|auto", allow_hyphen_values = true)]
    pub(super) pose: Option<String>,
    /// With --pose auto: aim the feet this far below the hips (m) [default: the chapter's
    /// 0.14 m on Pupper v3's legs, scaled to the model's leg length]
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    pub(super) depth: Option<f64>,
    /// Torque mode's servo firmware and motor, KEY=VALUE,...: rate=HZ (the PD's update rate,
    /// torque held between updates), filter=HZ (first-order low-pass on the derivative),
    /// counts=N (encoder counts per revolution; the derivative is then the encoder's
    /// difference), delay=S (command delay: the PD tracks the target of S ago), noload=RAD_S
    /// (torque limit falling linearly to 0 at this speed), lag=S (the torque's first-order lag
    /// behind the PD: a current loop's, in seconds up to 0.05; 0: none; `pupper fit` measures
    /// it). E.g. rate=1000,filter=100,counts=16384
    /// [default: ideal, the PD every physics step on the exact state]
    #[arg(long, value_name = "SPEC")]
    pub(super) motor: Option<String>,
    /// MuJoCo's integrator for every cell: euler, implicitfast (a servo's damping integrated
    /// implicitly: stiff, well-damped gains run without chatter), implicit, rk4. Cells past the
    /// stability bound of the PD as the integrator computes it are marked past_bound and never
    /// ranked [default: the model's own; Pupper v3's: euler]
    #[arg(long, value_name = "NAME")]
    pub(super) integrator: Option<String>,
}

impl SimArgs {
    /// These arguments over the spec's defaults.
    pub(super) fn spec(&self) -> Result<SweepSpec> {
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
            integrator: self.integrator.clone(),
            ..SweepSpec::default()
        })
    }
}

/// The push and the sine force, as sweep and tune take them.
#[derive(Args, Debug)]
pub(super) struct ScheduleArgs {
    /// Push force along world z (N; negative pushes down) [default: the chapter's -25 N on
    /// Pupper v3 (3.17 kg), scaled to the model's mass and rounded to 0.1 N: -25 N x mass / 3.17 kg,
    /// e.g. -118.3 N on 15 kg; the manifest records the force used].
    #[arg(long, value_name = "N", allow_hyphen_values = true)]
    pub(super) push_force: Option<f64>,
    /// Push start time (s).
    #[arg(long, default_value_t = SweepSpec::default().push_at, value_name = "S", allow_negative_numbers = true)]
    pub(super) push_at: f64,
    /// Push duration (s).
    #[arg(long, default_value_t = SweepSpec::default().push_duration, value_name = "S", allow_negative_numbers = true)]
    pub(super) push_duration: f64,
    /// No push.
    #[arg(long)]
    pub(super) no_push: bool,
    /// A continuous vertical force AMPLITUDE*sin(2π·FREQUENCY·t) on the base (N, Hz), e.g. 2,1.2.
    #[arg(long, value_name = "AMP,HZ", allow_hyphen_values = true)]
    pub(super) sine: Option<String>,
}

impl ScheduleArgs {
    /// `--sine`, parsed. Apart from [`ScheduleArgs::apply`] because sweep
    /// checks it before the simulation flags and tune after them, which
    /// decides the error a command line with two mistakes gets.
    pub(super) fn sine(&self) -> Result<Option<[f64; 2]>> {
        self.sine.as_deref().map(spec::parse_sine).transpose()
    }

    /// These flags over `spec`, with the `sine` [`ScheduleArgs::sine`] gave.
    pub(super) fn apply(&self, sine: Option<[f64; 2]>, spec: SweepSpec) -> SweepSpec {
        SweepSpec {
            push: !self.no_push,
            push_force: self.push_force,
            push_at: self.push_at,
            push_duration: self.push_duration,
            sine,
            ..spec
        }
    }
}

/// Where sweep and tune write. Tune says its own default name in its
/// `--out` help.
#[derive(Args, Debug)]
pub(super) struct OutputArgs {
    /// Run directory (default runs/<time>-<what ran: the grid's axes, or the command>).
    #[arg(long, short = 'o', value_name = "DIR", conflicts_with = "resume")]
    pub(super) out: Option<PathBuf>,
    /// Overwrite pupper's files in an existing --out directory.
    #[arg(long)]
    pub(super) force: bool,
}

/// What a run command keeps, draws and ranks by: `--trace`, `--plot`,
/// `--render` and `--rank` (in that order in `--help`), each in the words of
/// the command `S` flattens it into ([`Shows`]); a flag that command does
/// not take is not there, and false (or None) here.
#[derive(Debug)]
pub(super) struct ShowArgs<S> {
    pub(super) trace: bool,
    pub(super) plot: bool,
    pub(super) render: bool,
    pub(super) rank: Option<String>,
    shows: PhantomData<S>,
}

impl<S> ShowArgs<S> {
    /// Whether the run keeps its traces: asked for, or drawn by the plots.
    pub(super) fn traces(&self) -> bool {
        self.trace || self.plot
    }
}

/// A command's help for each flag of [`ShowArgs`] (`None`: the command
/// does not take the flag).
pub(super) struct Shown {
    pub(super) trace: Option<&'static str>,
    pub(super) plot: Option<&'static str>,
    pub(super) render: Option<&'static str>,
    pub(super) rank: Option<RankHelp>,
}

/// `--rank`'s help, its value's name, and an older name it answers to.
pub(super) struct RankHelp {
    pub(super) help: &'static str,
    pub(super) value_name: &'static str,
    pub(super) alias: Option<&'static str>,
}

/// The command a [`ShowArgs`] is flattened into, by its words.
pub(super) trait Shows {
    const SHOWN: Shown;
}

/// `--trace` of the kinds whose traces are the base height (hold, walk).
pub(super) const TRACE_HEIGHT: &str =
    "Record each cell's base height every --trace-every steps (traces.csv)";

impl<S: Shows> Args for ShowArgs<S> {
    fn augment_args(cmd: Command) -> Command {
        let shown = S::SHOWN;
        let flag = |id: &'static str, help: Option<&'static str>| {
            help.map(|h| Arg::new(id).long(id).action(ArgAction::SetTrue).help(h))
        };
        let rank = shown.rank.map(|r| {
            let arg = Arg::new("rank")
                .long("rank")
                .value_name(r.value_name)
                .value_parser(clap::value_parser!(String))
                .action(ArgAction::Set)
                .help(r.help);
            match r.alias {
                Some(alias) => arg.alias(alias),
                None => arg,
            }
        });
        let flags = [
            flag("trace", shown.trace),
            flag("plot", shown.plot),
            flag("render", shown.render),
            rank,
        ];
        cmd.args(flags.into_iter().flatten())
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}

impl<S: Shows> FromArgMatches for ShowArgs<S> {
    fn from_arg_matches(m: &ArgMatches) -> std::result::Result<Self, clap::Error> {
        Self::from_arg_matches_mut(&mut m.clone())
    }

    fn from_arg_matches_mut(m: &mut ArgMatches) -> std::result::Result<Self, clap::Error> {
        let shown = S::SHOWN;
        // only a flag the command takes is asked for: another is unknown
        let mut flag = |id: &str, help: Option<&str>| {
            help.is_some() && m.remove_one::<bool>(id).unwrap_or(false)
        };
        Ok(ShowArgs {
            trace: flag("trace", shown.trace),
            plot: flag("plot", shown.plot),
            render: flag("render", shown.render),
            rank: match shown.rank {
                Some(_) => m.remove_one::<String>("rank"),
                None => None,
            },
            shows: PhantomData,
        })
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> std::result::Result<(), clap::Error> {
        *self = Self::from_arg_matches(m)?;
        Ok(())
    }
}

/// The run directory a command writes to without `-o`:
/// `runs/<local time>-<suffix>`.
pub(super) fn rundir_name(suffix: &str) -> PathBuf {
    let stamp = chrono::Local::now().format("%Y%m%d-%H%M%S");
    PathBuf::from("runs").join(format!("{stamp}-{suffix}"))
}

/// What sweep and tune both take after their own flags: the simulation,
/// its push and sine, and where the run goes (in that order in `--help`).
#[derive(Args, Debug)]
pub(super) struct SetupArgs {
    #[command(flatten)]
    pub(super) sim: SimArgs,
    #[command(flatten)]
    pub(super) schedule: ScheduleArgs,
    #[command(flatten)]
    pub(super) output: OutputArgs,
}

/// Randomized replicates: a population of plausible robots per cell.
#[derive(Args, Debug)]
#[command(next_help_heading = "Randomized replicates")]
pub(super) struct PopulationArgs {
    /// Runs of every cell, each on a robot drawn by --randomize. Writes replicates.csv (a row
    /// per cell and replicate, with the drawn values and its metrics); summary.csv then holds,
    /// per metric, `mean:METRIC` and `p95:METRIC` (the worst-side 95th percentile: the 5th for
    /// final_z) over the replicates that stayed up, and `failure_fraction` (fell or diverged).
    /// Replicates are more simulations in the same batches; --trace and --render show
    /// replicate 0 of each cell.
    #[arg(long, default_value_t = SweepSpec::default().replicates, value_name = "R")]
    pub(super) replicates: u32,
    /// Seed of the draws. Each draw is a function of (seed, cell id, replicate, quantity)
    /// alone, so the numbers are the same whatever the threads, batches or resume points.
    #[arg(long, default_value_t = SweepSpec::default().seed, value_name = "S")]
    pub(super) seed: u64,
    /// What differs between replicates, QUANTITY=DISTRIBUTION; repeat for more.
    /// Relative (a factor uniform in 1±P): torso_mass=±10%, leg_mass=±10% (thigh and calf),
    /// motor_gain=±5% (drawn per actuator). Uniform ranges: friction=0.5:1.2 (feet and floor);
    /// with a push (sweep, not lab): push_force=-35:-15 (N), push_at=1.5:3 (s). Torque mode only: q_noise=N(0,0.002) (rad,
    /// on the angles the PD reads, every step), delay=0:3 (whole control steps the PD reads
    /// late), and the --motor model's motor_delay=0:0.01 (s), motor_filter=50:200 (Hz),
    /// motor_noload=20:40 (rad/s), motor_lag=0.004:0.01 (s, up to 0.05; not beside --motor
    /// lag=). `+-10%` may stand for `±10%`.
    #[arg(long, value_name = "QUANTITY=DIST", allow_hyphen_values = true)]
    pub(super) randomize: Vec<String>,
    /// Every cell's replicate r is the same robot (its draws keyed without the cell id):
    /// common random numbers, so cells differ only by their settings. What `pupper
    /// recommend` runs, so its card's numbers can be reproduced by a sweep.
    #[arg(long)]
    pub(super) common_draws: bool,
}

impl PopulationArgs {
    pub(super) fn apply(&self, spec: SweepSpec) -> SweepSpec {
        SweepSpec {
            replicates: self.replicates,
            seed: self.seed,
            randomize: self.randomize.clone(),
            common_draws: self.common_draws,
            ..spec
        }
    }
}

/// A run directory's life: a shard of the grid, resuming, the traces'
/// decimation, what is printed.
#[derive(Args, Debug)]
pub(super) struct RunArgs {
    /// Run only shard I of N of the grid's cells (1 <= I <= N; cell k belongs to shard
    /// k mod N + 1, so costly and cheap cells spread evenly), into its own run directory
    /// whose manifest records the whole grid, the shard and the host. Resume, Ctrl-C and
    /// checks work per shard; `pupper merge` puts the shards together. In a Slurm array:
    /// --shard $SLURM_ARRAY_TASK_ID/N with --array=1-N.
    #[arg(long, value_name = "I/N")]
    pub(super) shard: Option<String>,
    /// Continue an interrupted run in DIR: checks the inputs match its manifest, runs only missing cells. Alone, it reuses the manifest's inputs.
    #[arg(long, value_name = "DIR")]
    pub(super) resume: Option<PathBuf>,
    /// Decimation of the traces (--trace).
    #[arg(long, default_value_t = SweepSpec::default().trace_every, value_name = "N")]
    pub(super) trace_every: usize,
    /// Print the rows (and the best cells) as JSON instead of a table.
    #[arg(long)]
    pub(super) json: bool,
    /// No progress bar.
    #[arg(long, short = 'q')]
    pub(super) quiet: bool,
    /// Refuse grids with more cells (times replicates) than this.
    #[arg(long, default_value_t = SweepSpec::default().max_cells, value_name = "N")]
    pub(super) max_cells: usize,
}

impl RunArgs {
    /// These flags over `spec`, with `trace`: the command's --trace, or its
    /// plots, which draw the traces.
    pub(super) fn apply(&self, trace: bool, spec: SweepSpec) -> SweepSpec {
        SweepSpec {
            trace,
            trace_every: self.trace_every,
            shard: self.shard.clone(),
            max_cells: self.max_cells,
            ..spec
        }
    }
}

/// How a run's cells are batched: speed only, never the numbers.
#[derive(Args, Debug)]
pub(super) struct BatchArgs {
    /// Batch threads; 0 uses all cores. Never changes the numbers.
    #[arg(long, short = 'j', default_value_t = SweepSpec::default().threads, value_name = "N")]
    pub(super) threads: usize,
    /// Most cells per batch [default: 256 on the cpu backend, whose batches
    /// aim at about 10 s of work (sized from the speed measured so far, the
    /// first from a cautious guess), so a stop loses about that much; on
    /// warp, as many as the device's memory holds]. Fewer cells bound
    /// memory. Never changes the numbers.
    #[arg(long, value_name = "N")]
    pub(super) chunk_cells: Option<usize>,
}

impl BatchArgs {
    pub(super) fn apply(&self, spec: SweepSpec) -> SweepSpec {
        SweepSpec {
            threads: self.threads,
            chunk_cells: self.chunk_cells,
            ..spec
        }
    }
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Backend")]
pub(super) struct BackendArgs {
    /// What steps the physics. cpu: MuJoCo on this machine's cores, float64 (the reference).
    /// warp: MuJoCo Warp, float32, thousands of cells at once on a GPU (tens of thousands of
    /// cells a batch); needs the optional extra: pip install 'pupper_core[gpu]' (in a
    /// checkout: make setup PUPPER_EXTRAS=gpu). Results agree with cpu to about 1e-4 m in
    /// base z on the chapter's schedule; the manifest records backend, device and precision.
    /// In torque mode warp runs the PD inside MuJoCo's actuators (gain kp, bias -kp·q - kd·q̇,
    /// clipped at the torque limit), so --randomize delay, q_noise and motor_gain need cpu.
    #[arg(long, default_value = "cpu", value_name = "NAME", value_parser = ["cpu", "warp"])]
    pub(super) backend: String,
    /// The Warp device for --backend warp: cuda:0 (the first GPU; cuda:1 the second) or cpu
    /// (slow: for tests on machines without a GPU) [default: cuda:0]. `pupper doctor` lists
    /// the devices Warp sees.
    #[arg(long, value_name = "DEVICE")]
    pub(super) device: Option<String>,
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
    pub(super) ray: Option<String>,
}

impl BackendArgs {
    pub(super) fn apply(&self, spec: SweepSpec) -> SweepSpec {
        SweepSpec {
            backend: self.backend.clone(),
            device: self.device.clone(),
            ray: self.ray.clone(),
            ..spec
        }
    }
}

/// How a run command's cells run, after its own flags: the run
/// directory's life, the batches, the backend (last: the backend's help
/// heading holds every option after it).
#[derive(Args, Debug)]
pub(super) struct RunnerArgs {
    #[command(flatten)]
    pub(super) run: RunArgs,
    #[command(flatten)]
    pub(super) batch: BatchArgs,
    #[command(flatten)]
    pub(super) backend: BackendArgs,
}

impl RunnerArgs {
    /// These flags over `spec`, with `trace` as [`RunArgs::apply`] takes it.
    pub(super) fn apply(&self, trace: bool, spec: SweepSpec) -> SweepSpec {
        self.run
            .apply(trace, self.batch.apply(self.backend.apply(spec)))
    }
}
