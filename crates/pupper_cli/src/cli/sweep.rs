//! `pupper sweep`, and the job runner that sweep, lab and response share:
//! the run, what it prints and writes after, and its progress bar.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use clap::Args;
use pupper_core::plan::config::SweepConfig;
use pupper_core::request::spec::{GridInput, Sweep, SweepSpec};
use pupper_core::results::best;
use pupper_core::results::output;
use pupper_core::results::rundir::Existing;
use pupper_core::{Error, Result};
use pupper_mujoco::api::{self, SweepOutcome, SweepRequest};
use pupper_mujoco::bridge;

use super::args::{
    GridArg, PopulationArgs, RankHelp, RunArgs, RunnerArgs, SetupArgs, ShowArgs, Shown, Shows,
    rundir_name,
};
use super::progress::Progress;
use super::python::{write_files, write_report};
use crate::print;
use pupper_mujoco::bridge::calls;

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
pub(super) struct SweepArgs {
    #[command(flatten)]
    grid: GridArg,
    /// A named grid: chapter-4.6 (the chapter's soft/default/stiff/underD servo cases) or lab-grid (the lab's
    /// kp 10,30,60,120 x kd 0.5,1,2,5 only, in this command's mode and push; the lab itself is `pupper lab`).
    #[arg(long, value_name = "NAME", conflicts_with = "grid")]
    preset: Option<String>,
    #[command(flatten)]
    setup: SetupArgs,
    /// Stop stepping a robot once it has fallen (base below 30 % of its stance height or
    /// tilted past 60 deg) or diverged, within one batch call (0.5 s at most in servo mode, at
    /// once in torque mode): its row keeps its status (fell) and the metrics up to the stop;
    /// every other row is unchanged. Saves the cell-steps of robots on the floor. (A slow
    /// collapse is judged on the last second, so it runs to the end.)
    #[arg(long)]
    stop_fallen: bool,
    /// Pick the best cell of each group of these axes (e.g. kd, or leg_scale,torso_mass_scale):
    /// printed a line per group and written to DIR/best.csv. Rule: among cells that stood
    /// (status ok or saturated; with replicates: none fell or diverged), whose metric is a number
    /// and whose saturation_frac (with replicates: p95:saturation_frac) is under
    /// --max-saturation, the lowest --rank wins; cells within 0.001 mm of it on a *_mm metric
    /// are tied and the smaller push dip decides, then the first cell in grid order.
    #[arg(long, value_name = "AXIS[,AXIS]", value_delimiter = ',')]
    best_by: Option<Vec<String>>,
    #[command(flatten)]
    show: ShowArgs<SweepArgs>,
    /// Cells at the torque limit in this share of actuator-steps or more are never "best".
    #[arg(long, default_value_t = pupper_core::results::best::MAX_SATURATION, value_name = "FRACTION", value_parser = super::args::saturation)]
    max_saturation: f64,
    // last: their help headings would hold every option after them
    #[command(flatten)]
    runner: RunnerArgs,
    #[command(flatten)]
    population: PopulationArgs,
}

impl Shows for SweepArgs {
    const SHOWN: Shown = Shown {
        trace: Some("Keep base-z traces (traces.csv), every --trace-every-th step"),
        plot: Some("Write plots (base-z curves, heatmaps or bars) into DIR/plots"),
        render: Some(
            "Render the effects GIF and final-frame PNG of the cells (up to 6) into DIR/plots",
        ),
        rank: Some(RankHelp {
            help: "The metric --best-by ranks by (lower is better): a summary.csv column. With \
                   replicates, a statistic over them: mean:METRIC or p95:METRIC (worst side), \
                   e.g. p95:last_1s_std_mm [default: last_1s_std_mm; with replicates \
                   p95:last_1s_std_mm]",
            value_name: "[STAT:]METRIC",
            alias: Some("best-metric"),
        }),
    };
}

impl SweepArgs {
    /// These arguments over the spec's defaults.
    fn spec(&self) -> Result<SweepSpec> {
        let sine = self.setup.schedule.sine()?;
        let sim = self
            .setup
            .schedule
            .apply(sine, self.population.apply(self.setup.sim.spec()?));
        Ok(SweepSpec {
            grid: match &self.preset {
                Some(p) => GridInput::Preset(p.clone()),
                None => self.grid.input(),
            },
            stop_fallen: self.stop_fallen,
            force: self.setup.output.force,
            // plots draw the base-z curves from the traces
            ..self.runner.apply(self.show.traces(), sim)
        })
    }
}

/// A sweep as the CLI runs it (`sweep` and `lab` differ only in how they
/// fill it): the spec, where it goes, and what to show after.
pub(super) struct Job {
    pub(super) spec: SweepSpec,
    /// The spec of the same command with no option given: what a `--resume
    /// DIR` alone compares against to find the inputs the user set.
    pub(super) baseline: SweepSpec,
    pub(super) out: Option<PathBuf>,
    pub(super) resume: Option<PathBuf>,
    /// `--resume DIR` without grid flags: the manifest's inputs.
    pub(super) resume_alone: bool,
    pub(super) preset: Option<String>,
    pub(super) quiet: bool,
    pub(super) json: bool,
    pub(super) plot: bool,
    pub(super) render: bool,
    pub(super) rule: Option<best::Rule>,
    pub(super) lab: bool,
}

impl Job {
    /// A job with the flags every run command shares (`-o`, `--resume`,
    /// `-q`, `--json`) and nothing else asked for.
    pub(super) fn new(
        spec: SweepSpec,
        baseline: SweepSpec,
        out: Option<PathBuf>,
        run: &RunArgs,
    ) -> Job {
        Job {
            spec,
            baseline,
            resume_alone: false,
            out,
            resume: run.resume.clone(),
            preset: None,
            quiet: run.quiet,
            json: run.json,
            plot: false,
            render: false,
            rule: None,
            lab: false,
        }
    }
}

/// `pupper sweep`.
pub(super) fn run(a: SweepArgs, stop: &'static AtomicBool) -> Result<u8> {
    // a sweep ranks only what --best-by picks: a --rank alone would be
    // neither used nor checked
    if let (Some(rank), None) = (&a.show.rank, &a.best_by) {
        return Err(pupper_core::error::Error::Config(format!(
            "--rank {rank} ranks the cells --best-by picks from: give --best-by too (e.g. --best-by kd), or leave --rank out"
        )));
    }
    // no --rank: chosen in run_job, once the run's config is known
    let metric = a.show.rank.clone().unwrap_or_default();
    let rule = a.best_by.as_ref().map(|by| best::Rule {
        max_saturation: a.max_saturation,
        ..best::Rule::new(&metric, by)
    });
    run_job(
        Job {
            spec: a.spec()?,
            baseline: SweepSpec::default(),
            resume_alone: a.grid.grid.is_empty() && a.preset.is_none(),
            out: a.setup.output.out,
            resume: a.runner.run.resume,
            preset: a.preset,
            quiet: a.runner.run.quiet,
            json: a.runner.run.json,
            plot: a.show.plot,
            render: a.show.render,
            rule,
            lab: false,
        },
        stop,
    )
}

/// Runs a job: the sweep, then what it prints and writes.
pub(super) fn run_job(mut a: Job, stop: &'static AtomicBool) -> Result<u8> {
    // as text for the manifest: a path that is not UTF-8 keeps its other bytes
    let command: Vec<String> = std::env::args_os()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    let sweep = build(&a)?;
    // without --rank: the kind's own metric (a stand's steadiest), over
    // the replicates when there are some (a `--resume DIR` alone learns
    // that from the manifest)
    if let Some(rule) = a.rule.as_mut().filter(|r| r.metric.is_empty()) {
        let metric = sweep.config.experiment.plan().default_metric();
        rule.metric = match sweep.config.replicates.is_plain() {
            true => metric.into(),
            false => best::robust(metric),
        };
    }
    // the ranking rule is checked against the grid before anything runs
    if let Some(rule) = &a.rule {
        best::best(
            &pupper_core::results::tables::header_of(&sweep.config),
            &[],
            rule,
        )?;
    }
    let req = SweepRequest { sweep, command };
    let what = if a.lab {
        "lab"
    } else {
        a.spec.experiment.name()
    };
    let mut ui = Progress::new(what, a.quiet || a.json, stop);
    let outcome = api::run_sweep(&req, &mut ui)?;
    for n in &outcome.notes {
        errln!("note: {n}");
    }
    let dir = outcome.out.clone().unwrap_or_default();
    if !outcome.complete {
        say_interrupted(&a, &outcome, &dir);
        return Ok(130);
    }
    let unprinted = show(&a, &outcome, &dir)?;
    write_after(&a, &dir)?;
    // said after the files: a stdout that cannot take the table (a full
    // disk) leaves a whole run, its best.csv and report.html written
    match unprinted {
        Some(e) => Err(e),
        None => Ok(0),
    }
}

/// The job's sweep: the spec as given, continued from its run directory
/// (with `--resume DIR` alone, the manifest's inputs), or a new run.
fn build(a: &Job) -> Result<Sweep> {
    Ok(match &a.resume {
        // `--resume DIR` alone: the manifest's inputs
        Some(dir) if a.resume_alone => {
            let mut s = SweepSpec {
                out: Some(dir.clone()),
                resume: true,
                ..a.spec.clone()
            }
            .build()?;
            // another kind's run: refused before its inputs are taken
            pupper_core::results::clear::check_kind(dir, &s.kind)?;
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
    })
}

/// `--resume DIR` alone runs with the manifest's inputs: an input the
/// command line also sets (away from its default) to another value is
/// refused, never silently dropped.
fn refuse_other_inputs(
    dir: &Path,
    baseline: &SweepSpec,
    given: &SweepConfig,
    run: &SweepConfig,
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

/// What was kept of a stopped run, and the command that continues it.
fn say_interrupted(a: &Job, outcome: &SweepOutcome, dir: &Path) {
    errln!(
        "interrupted: kept {} of {} cells in {}; continue with: pupper {} --resume {}{}",
        outcome.rows.len(),
        outcome.cells_total,
        dir.display(),
        if a.lab {
            "lab"
        } else {
            a.spec.experiment.name()
        },
        dir.display(),
        a.spec
            .ray
            .as_ref()
            .map(|r| format!(" --ray {r}"))
            .unwrap_or_default()
    );
}

/// Prints a finished run: its table (a lab's is a line per body), its
/// best cells, or all of it as JSON; writes best.csv. A failure to print is
/// returned beside (`Ok(Some(..))`), not at once, so the files still follow.
fn show(a: &Job, outcome: &SweepOutcome, dir: &Path) -> Result<Option<Error>> {
    let mut printed: Result<()> = Ok(());
    let mut put = |text: &str| {
        if printed.is_ok() {
            printed = super::console::out(text);
        }
    };
    if !a.json && !a.lab {
        put(&print::run_table(outcome, &a.spec.experiment));
    }
    let mut best = None;
    if let Some(rule) = &a.rule {
        let groups = api::write_best(outcome, rule)?;
        if a.json {
            best = Some(print::best_json(outcome, rule, &groups));
        } else if a.lab {
            put(&print::lab(outcome, rule, &groups));
        } else {
            put(&print::best(outcome, rule, &groups));
        }
        errln!("wrote {}", dir.join(output::BEST).display());
    }
    if a.json {
        let mut doc = print::rows_json(outcome);
        if let (Some(b), Some(m)) = (best, doc.as_object_mut()) {
            m.insert("best".into(), b);
        }
        put(&format!("{}\n", print::json(&doc)?));
    }
    Ok(printed.err())
}

/// Writes what a finished run asked for beside its tables: plots,
/// renderings, and last the report.
fn write_after(a: &Job, dir: &Path) -> Result<()> {
    let dir_s = dir.display().to_string();
    if a.plot {
        // the plots of the run's kind, as its manifest names it
        write_files(&calls::WRITE_PLOTS, &dir_s)?;
    }
    if a.lab {
        // the bodies at their best gains, side by side: a PNG, and a GIF with --render
        match bridge::call_helper(
            &calls::WRITE_LAB_EFFECTS,
            std::slice::from_ref(&dir_s),
            &serde_json::json!({ "gif": a.render }),
        ) {
            Ok(paths) if paths.is_empty() => {
                errln!("note: no body has best gains (see best.csv): nothing to draw")
            }
            Ok(paths) => paths.iter().for_each(|p| errln!("wrote {p}")),
            Err(Error::Display(why)) if !a.render => errln!("note: no rendering here ({why})"),
            Err(e) => return Err(e),
        }
    } else if a.render {
        write_files(&calls::WRITE_RUN_EFFECTS, &dir_s)?;
    }
    // the page a person opens: its path last (-q: written, not said)
    write_report(dir)?;
    if !a.quiet {
        errln!("wrote {}", dir.join("report.html").display());
    }
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
    rundir_name(&name)
}
