//! `pupper lab`: the chapter's lab, every body from its own stand pose
//! under a sine force, as one sweep (or with --tune a study per body).

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use clap::Args;
use pupper_core::request::spec::{self, SweepSpec};
use pupper_core::results::best;
use pupper_core::{Error, Result};

use super::args::{
    BackendArgs, GridArg, ModelArg, PopulationArgs, RankHelp, ShowArgs, Shown, Shows, rundir_name,
};
use super::python::python_command;
use super::sweep::{Job, run_job};
use crate::pyargs;
use pupper_mujoco::bridge::calls;

#[derive(Args, Debug)]
#[command(
    after_help = "Without --grid the gains are kp=10,30,60,120 x kd=0.5,1,2,5; --grid replaces them \
(any sweep axis; a variant axis there replaces --variants). The best gains per body follow the \
--best-by rule of `pupper sweep`: the cell stood (with replicates: none fell or diverged), saturation \
under --max-saturation, lowest --rank, ties within 0.001 mm to the smaller dip, then the first cell."
)]
pub(super) struct LabArgs {
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
    #[arg(long, default_value = "2,1.2", value_name = "AMP,HZ", allow_hyphen_values = true)]
    sine: String,
    /// Aim each body's stand pose at this depth of the feet below the hips (m) [default: the
    /// chapter's 0.14 m on Pupper v3's legs, scaled to each body's leg length]
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    depth: Option<f64>,
    /// The servo firmware and motor the lab's torque-mode PD runs through, as for `sweep
    /// --motor` (rate=HZ, filter=HZ, counts=N, delay=S, noload=RAD_S, lag=S) [default: ideal]
    #[arg(long, value_name = "SPEC")]
    motor: Option<String>,
    /// Cells at the torque limit in this share of actuator-steps or more are never "best".
    #[arg(long, default_value_t = pupper_core::results::best::MAX_SATURATION, value_name = "FRACTION", value_parser = super::args::saturation)]
    max_saturation: f64,
    #[command(flatten)]
    show: ShowArgs<LabArgs>,
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
    /// Print the rows as JSON instead of a line per body.
    #[arg(long)]
    json: bool,
    /// No progress bar.
    #[arg(long, short = 'q')]
    quiet: bool,
    /// Refuse grids with more cells (times bodies and replicates) than this.
    #[arg(long, default_value_t = SweepSpec::default().max_cells, value_name = "N")]
    max_cells: usize,
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

impl Shows for LabArgs {
    const SHOWN: Shown = Shown {
        trace: None,
        plot: None,
        render: Some("Also write the GIF of the bodies at their best gains"),
        rank: Some(RankHelp {
            help: "The metric each body's best gains are ranked by (lower is better) [default: \
                   last_1s_std_mm; with replicates p95:last_1s_std_mm]",
            value_name: "[STAT:]METRIC",
            alias: None,
        }),
    };
}

/// `pupper lab`.
pub(super) fn run(a: LabArgs, stop: &'static AtomicBool) -> Result<u8> {
    let sine = spec::parse_sine(&a.sine)?;
    if a.tune {
        return tune(&a, sine);
    }
    let spec = SweepSpec {
        model: a.model.model.clone(),
        threads: a.threads,
        depth: a.depth,
        motor: a.motor.clone(),
        force: a.force,
        max_cells: a.max_cells,
        ..a.backend
            .apply(a.population.apply(pupper_core::request::lab::spec(
                &a.variants,
                &a.grid.grid,
                a.seconds,
                sine,
            )))
    };
    let metric = a.show.rank.clone().unwrap_or_default();
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
            render: a.show.render,
            rule: Some(best::Rule {
                max_saturation: a.max_saturation,
                ..best::Rule::new(&metric, &["variant".to_string()])
            }),
            lab: true,
        },
        stop,
    )
}

/// `pupper lab --tune`: a study per body, in Python.
fn tune(a: &LabArgs, sine: [f64; 2]) -> Result<u8> {
    let call = TuneCall {
        variants: &a.variants,
        objective: a
            .show
            .rank
            .clone()
            .unwrap_or_else(|| pupper_core::results::best::DEFAULT_METRIC.into()),
        trials: a.trials,
        batch: a.batch,
        seed: a.population.seed,
        out: a.out.clone().unwrap_or_else(|| rundir_name("lab-tune")),
        force: a.force,
        progress: !a.quiet,
        seconds: a.seconds,
        sine,
        model: &a.model.model,
        threads: a.threads,
        replicates: a.population.replicates,
        randomize: &a.population.randomize,
        depth: a.depth,
    };
    let text = pyargs::to_text(&call).map_err(|e| Error::Internal(e.to_string()))?;
    python_command(&calls::LAB_TUNE, &text)
}

/// What `pupper_core._tune._lab_cli` is given: `lab_tune`'s keywords.
#[derive(serde::Serialize)]
struct TuneCall<'a> {
    variants: &'a [String],
    objective: String,
    trials: u64,
    batch: u64,
    seed: u64,
    #[serde(serialize_with = "pyargs::path")]
    out: PathBuf,
    force: bool,
    progress: bool,
    seconds: f64,
    sine: [f64; 2],
    model: &'a str,
    threads: usize,
    replicates: u32,
    randomize: &'a [String],
    /// left out when not given: lab_tune's own default
    #[serde(skip_serializing_if = "Option::is_none")]
    depth: Option<f64>,
}
