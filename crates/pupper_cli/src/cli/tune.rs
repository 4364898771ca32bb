//! `pupper tune`: Optuna's search over grid axes, run in Python; this
//! side hands it the flags as JSON.

use std::path::PathBuf;

use clap::Args;
use pupper_core::request::spec::SweepSpec;
use pupper_core::{Error, Result};
use serde_json::Value;

use super::args::{BackendArgs, BatchArgs, PopulationArgs, SetupArgs, rundir_name};
use super::python::python_command;
use crate::pyargs;
use pupper_mujoco::bridge::calls;

/// Tune's own flags serialize themselves as `pupper_core.tune`'s keywords;
/// the sweep's flags it shares reach Python as the sweep's spec's options.
#[derive(Args, Debug, serde::Serialize)]
#[command(
    after_help = "A trial whose robot fell, diverged or saturated is told a penalty of 1e6 (the
worst value), keeps its status in trials.csv and is never a best. The sampler of generation g is
seeded from (--seed, g) and sees only finished trials, so the same command gives the same trials in
the same order at any thread count and after --resume, even after kill -9: each told generation is
appended to DIR/journal.jsonl, a resume rebuilds the study from it and re-runs the generation a
kill cut short. One pupper at a time writes DIR. Show the study:
optuna-dashboard sqlite:///DIR/study.db. Needs the tune extra (make setup PUPPER_EXTRAS=tune).

Examples:
  pupper tune --space kp=5:200:log --space kd=0.05:10:log --trials 64 --batch 16
  pupper tune --space kp.hfe=5:100:log --space kp.kfe=5:100:log --kd 0.5 --budget 2000000
  pupper tune --space kp=5:200:log --space kd=0.05:5:log --objective last_1s_std_mm,push_dip_mm --trials 48"
)]
// the shared --out's help names sweep's default
#[command(mut_arg("out", |a| a.help("Run directory (default runs/<time>-tune)")))]
pub(super) struct TuneArgs {
    /// A searched axis: AXIS=LOW:HIGH (linear), LOW:HIGH:log, LOW:HIGH:int, or choices A|B|C;
    /// repeat for more. Any grid axis (kp, kd, kp.hfe, max_torque, variant, ...).
    #[arg(long, value_name = "AXIS=RANGE", allow_hyphen_values = true)]
    space: Vec<String>,
    /// The summary.csv column to minimize, or several comma-separated (a Pareto front).
    #[arg(long, default_value = pupper_core::results::best::DEFAULT_METRIC, value_name = "COLUMN[,COLUMN]")]
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
    /// all of them; the others are told pruned with their first value. 0 is none.
    #[arg(long, default_value_t = 0, value_name = "ETA")]
    halving: u64,
    #[command(flatten)]
    #[serde(skip)]
    setup: SetupArgs,
    /// Continue an interrupted study in DIR (the same inputs, or --resume DIR alone).
    #[arg(long, value_name = "DIR")]
    #[serde(skip)]
    resume: Option<PathBuf>,
    /// Write DIR/plots/tune_progress.png (best objective against cell-steps spent) and, for
    /// two searched axes, tune_trials.png (the trials over that plane).
    #[arg(long)]
    plot: bool,
    /// With --plot: a sweep's run directory of the same question (e.g. a grid over the same
    /// axes), drawn behind the search: its best-so-far curve and its heatmap.
    #[arg(long, value_name = "DIR", requires = "plot")]
    #[serde(serialize_with = "pyargs::opt_path")]
    compare: Option<PathBuf>,
    /// No line per generation.
    #[arg(long, short = 'q')]
    #[serde(skip)]
    quiet: bool,
    #[command(flatten)]
    #[serde(skip)]
    batching: BatchArgs,
    // last: their help headings would hold every option after them
    #[command(flatten)]
    #[serde(skip)]
    backend: BackendArgs,
    #[command(flatten)]
    #[serde(skip)]
    population: PopulationArgs,
}

impl TuneArgs {
    pub(super) fn run(&self) -> Result<u8> {
        let options = self.options()?;
        let out = match (&self.resume, &self.setup.output.out) {
            (Some(d), _) | (None, Some(d)) => d.clone(),
            (None, None) => rundir_name("tune"),
        };
        let call = Call {
            args: self,
            seed: self.population.seed,
            out,
            resume: self.resume.is_some(),
            force: self.setup.output.force,
            progress: !self.quiet,
            options,
        };
        let text = pyargs::to_text(&call).map_err(|e| Error::Internal(e.to_string()))?;
        python_command(&calls::TUNE, &text)
    }

    /// The study's simulation inputs, each one's JSON as the spec serializes
    /// it. A study's manifest records them and --resume compares them, so
    /// the keys and their order are fixed: the first eight always, the rest
    /// only when given (the schedule and backend only away from their
    /// defaults, as before tune took those flags; a keyframe whenever named,
    /// even `home`).
    fn options(&self) -> Result<serde_json::Map<String, Value>> {
        let sim = self.setup.sim.spec()?;
        let sine = self.setup.schedule.sine()?;
        let spec = self.batching.apply(
            self.setup
                .schedule
                .apply(sine, self.backend.apply(self.population.apply(sim))),
        );
        let d = SweepSpec::default();
        // JSON has no NaN: a non-finite number would reach Python as null,
        // which is the flag left out (the model's gains, the default push)
        for (flag, v) in [
            ("--kp", spec.kp),
            ("--kd", spec.kd),
            ("--max-torque", spec.max_torque),
            ("--depth", spec.depth),
            ("--push-force", spec.push_force),
        ] {
            if let Some(v) = v.filter(|v| !v.is_finite()) {
                return Err(Error::Config(format!(
                    "{flag} {v} is not a finite number: give a number"
                )));
            }
        }
        let keep = [
            ("model", true),
            ("variant", true),
            ("mode", true),
            ("seconds", true),
            ("push", true),
            ("threads", true),
            ("replicates", true),
            ("randomize", true),
            // decided on the flags, not on their JSON: a NaN is JSON null
            ("kp", spec.kp.is_some()),
            ("kd", spec.kd.is_some()),
            ("max_torque", spec.max_torque.is_some()),
            ("depth", spec.depth.is_some()),
            ("motor", spec.motor.is_some()),
            ("push_force", spec.push_force.is_some()),
            ("push_at", spec.push_at != d.push_at),
            ("push_duration", spec.push_duration != d.push_duration),
            ("sine", spec.sine.is_some()),
            ("chunk_cells", spec.chunk_cells.is_some()),
            ("backend", spec.backend != d.backend),
            ("device", spec.device.is_some()),
            ("ray", spec.ray.is_some()),
            ("keyframe", self.setup.sim.keyframe.is_some()),
            ("pose", spec.pose.is_some()),
            ("integrator", spec.integrator.is_some()),
        ];
        let Value::Object(mut all) =
            serde_json::to_value(&spec).map_err(|e| Error::Internal(format!("options: {e}")))?
        else {
            return Err(Error::Internal("options".into()));
        };
        let mut o = serde_json::Map::new();
        for (key, given) in keep {
            if given {
                let v = all
                    .remove(key)
                    .ok_or_else(|| Error::Internal(format!("options: {key}")))?;
                o.insert(key.into(), v);
            }
        }
        Ok(o)
    }
}

/// What `pupper_core._tune._cli` is given: tune's flags, those of the
/// shared groups it reads itself, and the sweep's options.
#[derive(serde::Serialize)]
struct Call<'a> {
    #[serde(flatten)]
    args: &'a TuneArgs,
    seed: u64,
    #[serde(serialize_with = "pyargs::path")]
    out: PathBuf,
    resume: bool,
    force: bool,
    progress: bool,
    #[serde(flatten)]
    options: serde_json::Map<String, Value>,
}
