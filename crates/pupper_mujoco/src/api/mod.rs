//! The operations the CLI and the Python module share, so the same inputs
//! give the same numbers from both.

use pyo3::prelude::*;
use serde::Serialize;

use crate::bridge;
use pupper_core::error::{Error, Result};
use pupper_core::plan::config::SweepConfig;
use pupper_core::plan::grid::Cell;
use pupper_core::plan::mode::Mode;
use pupper_core::plan::setup::CellSetup;
use pupper_core::plan::stability::Damping;
use pupper_core::request::spec::{GridInput, Sweep, SweepSpec};
use pupper_core::results::best;
use pupper_core::results::output;
use pupper_core::robot::model::{ModelInfo, ModelSource};
use pupper_core::robot::pose::StandPose;
use pupper_core::robot::variant::Variant;
use pupper_core::sim::cluster::{self, Job, Outcome, Task};
use pupper_core::sim::metrics::Status;
use pupper_core::sim::runner::{self, CellResult, Hooks, RunOptions};

mod bound;
mod response;
mod start;
mod sweep;

pub use response::{StepTrace, step_traces};
use start::{check_start, resolved};
pub use sweep::{SweepOutcome, SweepRequest, run_sweep};

/// A cluster worker's part of `--ray`: runs one task's cells of a job
/// here, as one batch on `threads` threads, and encodes the [`Outcome`].
/// A worker that cannot give the driver's numbers (another pupper or
/// mujoco version, another model file) refuses; the refusal, like any
/// failure, travels back as the outcome, naming this node.
pub fn run_task(job: &[u8], task: &[u8], threads: usize) -> Result<Vec<u8>> {
    let outcome = match task_results(job, task, threads) {
        Ok(results) => Outcome::Done(results),
        Err(e) => Outcome::Failed {
            host: pupper_core::results::lock::hostname(),
            user: e.is_user_error(),
            message: e.to_string(),
        },
    };
    cluster::encode(&outcome)
}

fn task_results(job: &[u8], task: &[u8], threads: usize) -> Result<Vec<CellResult>> {
    let job: Job = cluster::decode(job)?;
    let task: Task = cluster::decode(task)?;
    let fix = "install the same pupper_core and mujoco on every node (e.g. the wheel `make wheel` builds)";
    if job.pupper_version != pupper_core::VERSION {
        return Err(Error::Cluster(format!(
            "this node has pupper_core {}, the driver {}: {fix}",
            pupper_core::VERSION,
            job.pupper_version
        )));
    }
    let cfg = &job.config;
    bridge::with_config_model(cfg, |model| {
        if model.mujoco_version() != job.mujoco_version {
            return Err(Error::Cluster(format!(
                "this node has mujoco {}, the driver {}: {fix}",
                model.mujoco_version(),
                job.mujoco_version
            )));
        }
        if model.info().sha256 != job.model_sha256 {
            return Err(Error::Cluster(format!(
                "the model '{}' here is not the driver's (SHA-256 {} here, {} there): put the same file at the same path on every node (a shared filesystem)",
                cfg.model.display(),
                pupper_core::results::output::short(&model.info().sha256),
                pupper_core::results::output::short(&job.model_sha256)
            )));
        }
        let physics = bridge::physics(model, &cfg.backend)?;
        // one batch through the node's cores (a task is the unit to lose)
        let opts = RunOptions {
            threads,
            chunk_cells: Some(task.cells.len()),
            chunk_seconds: f64::INFINITY,
            chunk_steps: job.chunk_steps,
            frame_rate: None,
        };
        runner::run_cells(
            physics.as_ref(),
            cfg,
            &task.cells,
            opts,
            &mut runner::NoHooks,
        )
    })
}

/// What `pupper info` prints.
pub fn info(source: &ModelSource, variant: &Variant) -> Result<ModelInfo> {
    let scaled = variant.leg_scale != 1.0 || variant.torso_mass_scale != 1.0;
    bridge::with_model(source, scaled, |m| {
        if !scaled {
            return Ok(m.info().clone());
        }
        let body = m.variant(variant.leg_scale, variant.torso_mass_scale)?;
        let mut info = m.mj.info(source, &body)?;
        info.name = format!("{} ({})", info.name, variant.name);
        Ok(info)
    })
}

/// `pupper pose`: the stand pose of a model's (variant's) compiled body.
pub fn pose(source: &ModelSource, variant: &Variant, depth: Option<f64>) -> Result<StandPose> {
    if let Some(d) = depth
        && !(d.is_finite() && d > 0.0)
    {
        return Err(pupper_core::error::Error::Config(format!(
            "--depth {d} is not a positive length: give the feet's depth below the hips in metres, e.g. 0.14"
        )));
    }
    let info = info(source, variant)?;
    pupper_core::robot::pose::stand_pose(&info, variant.leg_scale, depth)
}

/// `pupper gains`: each joint's reflected inertia on the robot hung in the
/// air at the stand pose (or the pose given), and the gains a bandwidth and
/// damping ratio ask for, or what given gains give.
///
/// The loop margins: with a firmware (`motor`, `sensing` s of feedback
/// latency), of the loop it closes; on a calibrated model (its fitted
/// servo: [`pupper_core::robot::model::ModelInfo::calibrated`]), of the loop
/// the fit found, each joint's own (its fitted torque lag and feedback
/// latency, where `motor` and `sensing` give none, and its damping).
pub fn gains(
    source: &ModelSource,
    pose: Option<Vec<f64>>,
    ask: pupper_core::robot::gains::Ask,
    integrator: Option<&str>,
    motor: Option<&str>,
    sensing: Option<f64>,
) -> Result<pupper_core::robot::gains::GainsReport> {
    let integrator = integrator
        .map(pupper_core::plan::integrator::Integrator::parse)
        .transpose()?;
    use pupper_core::robot::gains::Ask;
    let bad = |what: String| Err(Error::Config(what));
    match ask {
        Ask::Bandwidth { hz, zeta }
            if !(hz.is_finite() && hz > 0.0 && zeta.is_finite() && zeta > 0.0) =>
        {
            return bad(format!(
                "--bandwidth {hz} --damping {zeta}: give a positive bandwidth (Hz) and damping ratio, e.g. --bandwidth 8 --damping 0.7"
            ));
        }
        Ask::Gains { kp, kd } if !(kp.is_finite() && kp > 0.0 && kd.is_finite() && kd >= 0.0) => {
            return bad(format!("--kp {kp} --kd {kd}: give kp > 0 and kd >= 0"));
        }
        _ => {}
    }
    Python::attach(|py| {
        let mj = bridge::Mujoco::import(py)?;
        let model = mj.load_on(source, true)?.floating()?;
        let info = model.info();
        let targets = match pose {
            Some(p) => {
                info.check_pose(&p)?;
                p
            }
            None => pupper_core::robot::pose::stand_pose(info, 1.0, None)?.targets,
        };
        let layout = pupper_core::robot::layout::Layout::suspended(info)?;
        let mut q = info.qpos0.clone();
        for (a, &t) in targets.iter().enumerate() {
            q[layout.act_qpos[a]] = t;
        }
        let inertia = model.joint_inertia(&q)?;
        // a servo's damping as the integrator takes it (the model's own, or
        // the one asked for); torque mode's Rust PD is always explicit
        let mj_integrator = integrator.map_or(info.integrator, |i| i.mj());
        let implicit = Damping::of(Mode::Servo, mj_integrator) == Some(Damping::Implicit);
        let report =
            pupper_core::robot::gains::report(info, &inertia, info.timestep, ask, implicit);
        let calibrated = info.calibrated();
        if calibrated {
            let damping = model.joint_damping()?;
            let m = pupper_core::plan::motor::Motor::parse(motor.unwrap_or(""))?;
            pupper_core::plan::motor::feedback_of(Some(""), sensing, info.timestep)?;
            let terms: Vec<_> = info
                .actuators
                .iter()
                .zip(damping)
                .map(|(a, damping)| pupper_core::robot::gains::LoopTerms {
                    feedback: pupper_core::plan::motor::fitted_feedback(
                        &m,
                        sensing,
                        info.timestep,
                        a.lag,
                        a.latency,
                    ),
                    damping,
                })
                .collect();
            return Ok(report.with_loops(&terms, true));
        }
        Ok(
            match pupper_core::plan::motor::feedback_of(motor, sensing, info.timestep)? {
                Some(fb) => report.with_feedback(fb),
                None => report,
            },
        )
    })
}

/// The compiled `MjModel` of a model source, for Python callers.
pub fn compiled(source: &ModelSource) -> Result<Py<PyAny>> {
    bridge::with_model(source, false, |m| Ok(m.model().clone().unbind()))
}

/// The outcome of `pupper stand`.
#[derive(Debug, Clone, Serialize)]
pub struct StandReport {
    pub model: String,
    pub mode: Mode,
    /// The gains the cell ran at (the first actuator's when they differ).
    pub kp: f64,
    pub kd: f64,
    /// `given` (--kp/--kd) or `model` (each actuator's own gains).
    pub gains_from: &'static str,
    /// The gains as text: one value, or the range over the actuators.
    pub gains: String,
    pub seconds: f64,
    pub final_z: f64,
    pub last_1s_std_mm: f64,
    pub max_tilt_deg: f64,
    pub status: Status,
    /// What the user should know (e.g. the start fell back to the default pose).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
}

/// The sweep of `spec` for one cell: its grid ignored (the model's own
/// gains, or the spec's), no push, nothing written.
fn one_cell(spec: &SweepSpec) -> Result<Sweep> {
    SweepSpec {
        grid: GridInput::None,
        push: false,
        out: None,
        resume: false,
        ..spec.clone()
    }
    .build()
}

/// The stance height (m) a run of `spec` starts from (its model, body and
/// start; the grid is not read, as gains do not move it): the base height at
/// which its lowest foot touches the floor in its start pose. Falls are judged against it, and
/// `recommend` its robots' sag. NaN for a fixed base.
pub fn stance(spec: &SweepSpec) -> Result<f64> {
    let sweep = one_cell(spec)?;
    let cfg = &sweep.config;
    bridge::with_config_model(cfg, |model| {
        let cells = cfg.grid.cells();
        let setup = cfg.setup(&cells[0], model.info());
        bridge::start_stance(model, &setup, &cfg.schedule.initial)
    })
}

/// Stands one cell of `spec` (its grid is ignored, no push) and reports.
pub fn stand(spec: &SweepSpec) -> Result<StandReport> {
    let sweep = one_cell(spec)?;
    let cfg = &sweep.config;
    let (results, note, setup) = bridge::with_config_model(cfg, |model| {
        let note = check_start(model.info(), &cfg.schedule.initial, true)?;
        let cells = cfg.grid.cells();
        let physics = bridge::physics(model, &cfg.backend)?;
        let r = runner::run_cells(
            physics.as_ref(),
            cfg,
            &cells,
            sweep.options,
            &mut runner::NoHooks,
        )?;
        let setup = cfg.setup(&cells[0], model.info());
        Ok((r, note, setup))
    })?;
    let m = &results[0].metrics;
    let span = |v: &[f64]| {
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if lo == hi {
            format!("{lo}")
        } else {
            format!("{lo}..{hi}")
        }
    };
    let gains_from = match (cfg.defaults.kp, cfg.defaults.kd) {
        (Some(_), Some(_)) => "given",
        _ => "model",
    };
    Ok(StandReport {
        model: match spec.variant.as_str() {
            "original" => cfg.model.display(),
            body => format!("{} ({body})", cfg.model.display()),
        },
        mode: cfg.mode,
        kp: setup.kp(0),
        kd: setup.kd(0),
        gains_from,
        gains: format!("kp {} kd {}", span(&setup.kp), span(&setup.kd)),
        seconds: cfg.schedule.duration,
        final_z: m.final_z,
        last_1s_std_mm: m.last_1s_std_mm,
        max_tilt_deg: m.max_tilt_deg,
        status: m.status,
        notes: note.into_iter().chain(cfg.schedule.shortfalls()).collect(),
    })
}

/// One cell simulated for drawing: its result with frames, its physical
/// setting, and the compiled body it ran on (an `MjModel`).
pub struct Recording {
    pub result: CellResult,
    pub setup: CellSetup,
    pub model: Py<PyAny>,
}

/// Runs `cells` of `cfg` with the sweep's runner, recording qpos at `fps`:
/// what rendering draws, so a picture shows the simulation that was measured.
pub fn record(cfg: &SweepConfig, cells: &[Cell], fps: f64) -> Result<Vec<Recording>> {
    let opts = RunOptions {
        frame_rate: Some(fps),
        ..RunOptions::default()
    };
    bridge::with_config_model(cfg, |model| {
        let cfg = &resolved(cfg, model)?;
        check_start(model.info(), &cfg.schedule.initial, false)?;
        let physics = bridge::physics(model, &cfg.backend)?;
        let results = runner::run_cells(physics.as_ref(), cfg, cells, opts, &mut runner::NoHooks)?;
        results
            .into_iter()
            .map(|result| {
                let setup = cfg.setup(&result.cell, model.info());
                let body = model.variant(setup.leg_scale, setup.torso_mass_scale)?;
                Ok(Recording {
                    result,
                    setup,
                    model: body.unbind(),
                })
            })
            .collect()
    })
}

/// The cells of a run directory's grid at these indices.
pub(super) fn cells_of(
    dir: &std::path::Path,
    cfg: &SweepConfig,
    indices: &[usize],
) -> Result<Vec<Cell>> {
    let all = cfg.grid.cells();
    indices
        .iter()
        .map(|&i| {
            all.get(i).cloned().ok_or_else(|| {
                Error::Config(format!(
                    "cell {i} is not in {}'s grid of {} cells: give indices from its summary.csv",
                    dir.display(),
                    all.len()
                ))
            })
        })
        .collect()
}

/// [`record`] for cells of a run directory, by their index in its grid.
pub fn record_run(dir: &std::path::Path, indices: &[usize], fps: f64) -> Result<Vec<Recording>> {
    let cfg = output::read_manifest(dir)?.config;
    let cells = cells_of(dir, &cfg, indices)?;
    record(&cfg, &cells, fps)
}

/// The best cell of each group by `rule`, written to `best.csv` when the
/// sweep has a run directory.
pub fn write_best(outcome: &SweepOutcome, rule: &best::Rule) -> Result<Vec<best::Group>> {
    let groups = best::best(&outcome.header, &outcome.rows, rule)?;
    if let Some(dir) = &outcome.out {
        let (h, rows) = best::table(&outcome.header, &outcome.rows, rule, &groups);
        pupper_core::results::files::write_atomic(
            &dir.join(output::BEST),
            &output::csv_bytes(&h, &rows)?,
        )?;
    }
    Ok(groups)
}

/// A front end's view of a running sweep.
pub trait SweepUi {
    /// The run starts: `cells` to do, `steps` cell-steps in all.
    fn start(&mut self, _cells: usize, _steps: u64) {}
    fn finish(&mut self) {}
    /// Progress and interrupt hooks.
    fn hooks(&mut self) -> &mut dyn Hooks;
}
