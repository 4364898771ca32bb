//! The operations the CLI and the Python module share, so the same inputs
//! give the same numbers from both.

use std::path::PathBuf;

use pyo3::prelude::*;
use serde::Serialize;

use crate::bridge;
use crate::bridge::ray::RayCluster;
use pupper_core::error::{Error, Result};
use pupper_core::plan::backend::Backend;
use pupper_core::plan::config::SweepConfig;
use pupper_core::plan::grid::Cell;
use pupper_core::plan::mode::Mode;
use pupper_core::plan::randomize::Quantity;
use pupper_core::plan::schedule::InitialState;
use pupper_core::plan::setup::CellSetup;
use pupper_core::plan::stability::{self, Damping};
use pupper_core::request::spec::{GridInput, Sweep, SweepSpec};
use pupper_core::results::best;
use pupper_core::results::output::{self, Manifest, ModelRecord, ShardRecord};
use pupper_core::results::rundir::RunWriter;
use pupper_core::robot::model::{ModelInfo, ModelSource};
use pupper_core::robot::pose::StandPose;
use pupper_core::robot::variant::Variant;
use pupper_core::sim::cluster::{self, Job, Outcome, Task};
use pupper_core::sim::metrics::Status;
use pupper_core::sim::runner::{self, CellResult, Hooks, RunOptions};

/// A cluster worker's part of `--ray`: runs one task's cells of a job
/// here, as one batch on `threads` threads, and encodes the [`Outcome`].
/// A worker that cannot give the driver's numbers (another pupper or
/// mujoco version, another model file) refuses; the refusal, like any
/// failure, travels back as the outcome, naming this node.
pub fn run_task(job: &[u8], task: &[u8], threads: usize) -> Result<Vec<u8>> {
    let outcome = match task_results(job, task, threads) {
        Ok(results) => Outcome::Done(results),
        Err(e) => Outcome::Failed {
            host: pupper_core::results::rundir::hostname(),
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
                pupper_core::results::rundir::short(&model.info().sha256),
                pupper_core::results::rundir::short(&job.model_sha256)
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
pub fn gains(
    source: &ModelSource,
    pose: Option<Vec<f64>>,
    ask: pupper_core::robot::gains::Ask,
    integrator: Option<&str>,
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
        Ok(pupper_core::robot::gains::report(
            info,
            &inertia,
            info.timestep,
            ask,
            implicit,
        ))
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

/// Stands one cell of `spec` (its grid is ignored, no push) and reports.
pub fn stand(spec: &SweepSpec) -> Result<StandReport> {
    let spec = SweepSpec {
        grid: GridInput::None,
        push: false,
        out: None,
        resume: false,
        ..spec.clone()
    };
    let sweep = spec.build()?;
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

/// [`record`] for cells of a run directory, by their index in its grid.
pub fn record_run(dir: &std::path::Path, indices: &[usize], fps: f64) -> Result<Vec<Recording>> {
    let cfg = output::read_manifest(dir)?.config;
    let all = cfg.grid.cells();
    let cells = indices
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
        .collect::<Result<Vec<Cell>>>()?;
    record(&cfg, &cells, fps)
}

/// The checks of where cells start that need the model; notes when the
/// start is a fallback (no `home` keyframe) or asks a joint to go past its
/// range.
fn check_start(info: &ModelInfo, initial: &InitialState, standing: bool) -> Result<Vec<String>> {
    let (targets, notes) = start_targets(info, initial)?;
    let mut notes = notes;
    if standing {
        notes.extend(info.ground_note());
    }
    // the stand-pose search keeps inside the ranges
    if !matches!(initial, InitialState::Auto | InitialState::AutoDepth(_))
        && let Some(t) = targets
    {
        notes.extend(info.targets_outside_ranges(&t));
    }
    Ok(notes)
}

/// The joint targets cells start from on the nominal body (None where the
/// model gives none), and what the user should know about them. A body
/// pupper cannot pose is refused here, before anything is written.
fn start_targets(
    info: &ModelInfo,
    initial: &InitialState,
) -> Result<(Option<Vec<f64>>, Vec<String>)> {
    let mut notes = Vec::new();
    let targets = match initial {
        InitialState::Pose(p) => {
            info.check_pose(p)?;
            Some(p.clone())
        }
        InitialState::Keyframe(k) => {
            let (key, note) = info.start_keyframe(k)?;
            notes.extend(note);
            let layout = pupper_core::robot::layout::Layout::floating(info)
                .or_else(|_| pupper_core::robot::layout::Layout::suspended(info))
                .ok();
            match (key, layout) {
                (Some(k), _) if info.keyframes[k].ctrl.len() == info.nu => {
                    Some(info.keyframes[k].ctrl.clone())
                }
                (Some(k), Some(l)) => Some(l.joint_targets(&info.keyframes[k].qpos)),
                (None, Some(l)) => Some(l.joint_targets(&info.qpos0)),
                _ => None,
            }
        }
        InitialState::Auto | InitialState::AutoDepth(_) => Some(
            pupper_core::robot::pose::stand_pose(info, 1.0, initial.auto_depth().flatten())?
                .targets,
        ),
    };
    Ok((targets, notes))
}

/// Each actuated joint's reflected inertia at the cells' start pose on
/// the nominal body (None where the model gives no start targets).
fn start_inertia(
    model: &bridge::LoadedModel<'_>,
    initial: &InitialState,
) -> Result<Option<Vec<f64>>> {
    match start_qpos(model, initial)? {
        Some(q) => Ok(Some(model.joint_inertia(&q)?)),
        None => Ok(None),
    }
}

/// The qpos of the cells' start pose on the nominal body: the keyframe (or
/// the model's default) with the start targets in the joints.
fn start_qpos(model: &bridge::LoadedModel<'_>, initial: &InitialState) -> Result<Option<Vec<f64>>> {
    let info = model.info();
    let Some(layout) = model.layout() else {
        return Ok(None);
    };
    let (Some(targets), _) = start_targets(info, initial)? else {
        return Ok(None);
    };
    let mut q = match initial {
        InitialState::Keyframe(k) => match info.start_keyframe(k)?.0 {
            Some(key) => info.keyframes[key].qpos.clone(),
            None => info.qpos0.clone(),
        },
        _ => info.qpos0.clone(),
    };
    for (a, &t) in targets.iter().enumerate() {
        q[layout.act_qpos[a]] = t;
    }
    Ok(Some(q))
}

/// A body by the bits of its (leg_scale, torso_mass_scale).
type BodyKey = (u64, u64);

/// What marks a run's cells past the stability bound: each body's joint
/// inertias at the start pose and how the integrator takes the damping.
struct Bound<'a, 'py> {
    cfg: &'a SweepConfig,
    model: &'a bridge::LoadedModel<'py>,
    /// The start pose's qpos, where every body's inertias are read.
    qpos: Vec<f64>,
    damping: Damping,
    /// Inertias by body, as computed.
    bodies: std::cell::RefCell<Vec<(BodyKey, Vec<f64>)>>,
}

impl<'a, 'py> Bound<'a, 'py> {
    /// None where pupper states no bound: RK4, no start pose to read the
    /// inertias at, or torque mode's firmware closing another loop than the
    /// PD at the physics step (a filtered derivative, a slower update).
    fn new(cfg: &'a SweepConfig, model: &'a bridge::LoadedModel<'py>) -> Option<Bound<'a, 'py>> {
        let info = model.info();
        let damping = Damping::of(cfg.mode, info.integrator)?;
        let firmware = cfg.mode == Mode::Torque
            && (cfg.motor.filter.is_some()
                || cfg
                    .motor
                    .rate
                    .is_some_and(|r| r * info.timestep < 1.0 - 1e-9)
                || cfg
                    .replicates
                    .randomize
                    .iter()
                    .any(|r| r.quantity == Quantity::MotorFilter));
        if firmware {
            return None;
        }
        let qpos = start_qpos(model, &cfg.schedule.initial).ok().flatten()?;
        Some(Bound {
            cfg,
            model,
            qpos,
            damping,
            bodies: Default::default(),
        })
    }

    /// Each actuator's margin in `cell`, on the cell's own body (a lab's
    /// long legs have other inertias than the original's).
    fn margins(&self, cell: &Cell) -> Vec<f64> {
        let info = self.model.info();
        let s = self.cfg.setup(cell, info);
        let key = (s.leg_scale.to_bits(), s.torso_mass_scale.to_bits());
        let known = self
            .bodies
            .borrow()
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(_, i)| i.clone());
        let inertia = match known {
            Some(i) => i,
            None => {
                let i = self
                    .model
                    .variant(s.leg_scale, s.torso_mass_scale)
                    .and_then(|body| self.model.body_joint_inertia(&body, &self.qpos))
                    .unwrap_or_default();
                self.bodies.borrow_mut().push((key, i.clone()));
                i
            }
        };
        stability::cell_margins(self.cfg, info, &inertia, cell, self.damping)
    }

    fn mark(&self, r: &mut CellResult) {
        let margins = self.margins(&r.cell);
        r.mark_past_bound(&margins, self.damping == Damping::Explicit);
    }

    /// The note for cells past the bound: how many, the worst, why they are
    /// not ranked, and how to simulate such gains honestly.
    fn note(&self) -> Option<String> {
        let mut past = 0usize;
        let mut worst: Option<(f64, String, String)> = None;
        for cell in self.cfg.grid.cells() {
            let (m, a) = self
                .margins(&cell)
                .into_iter()
                .enumerate()
                .map(|(a, m)| (m, a))
                .fold((0.0, 0), |x, y| if y.0 > x.0 { y } else { x });
            if m >= 1.0 {
                past += 1;
                if worst.as_ref().is_none_or(|w| m > w.0) {
                    worst = Some((
                        m,
                        cell.id.clone(),
                        self.model.info().actuators[a].name.clone(),
                    ));
                }
            }
        }
        let (m, id, joint) = worst?;
        // an absurd gain's margin in two digits, not three hundred
        let m = if m < 1e6 {
            format!("{m:.2}")
        } else {
            format!("{m:.2e}")
        };
        let how = match (self.damping, self.cfg.mode) {
            (Damping::Explicit, Mode::Servo) => {
                "a smaller timestep (--grid timestep=...) or --integrator implicitfast simulates such gains honestly"
            }
            _ => "a smaller timestep (--grid timestep=...) simulates such gains honestly",
        };
        let integrated = match self.damping {
            Damping::Explicit => "an explicitly integrated PD",
            Damping::Implicit => "the PD with its damping integrated implicitly",
        };
        Some(format!(
            "{past} cell(s) lie past the stability bound of {integrated} at the timestep (worst: {id} on {joint}, margin {m}): marked past_bound and never ranked, since their numbers describe the integrator, not a robot; {how}; `pupper gains --kp KP --kd KD` shows the bound per joint"
        ))
    }
}

/// `cfg` with what its kind takes from the model resolved on `info` (a
/// hold's weight; a response run's excited joints, its signal checked
/// against every timestep of its grid).
fn resolved(cfg: &SweepConfig, model: &bridge::LoadedModel<'_>) -> Result<SweepConfig> {
    let info = model.info();
    let mut c = cfg.clone();
    c.experiment.resolve(info, &mut c.schedule)?;
    if let Some(e) = c.experiment.excitation_mut() {
        if e.joints.is_empty() {
            e.resolve(info)?;
            if let Some(all) = start_inertia(model, &cfg.schedule.initial)? {
                e.inertia = e.joints.iter().map(|&a| all[a]).collect();
            }
        }
        if let (Some(t), _) = start_targets(info, &cfg.schedule.initial)? {
            e.check_ranges(info, &t)?;
        }
        let mut seen: Vec<u64> = Vec::new();
        for cell in cfg.grid.cells() {
            let setup = cfg.setup(&cell, info);
            // without a spring the joint never follows: every figure would be
            // a 100 % error printed as `ok`
            if let Some(&a) = e.joints.iter().find(|&&a| setup.kp(a) <= 0.0) {
                return Err(Error::Config(format!(
                    "cell {} gives {} kp 0: a joint without a servo spring does not follow its target, so there is no response to measure; give kp > 0 (--kp or a kp grid starting above 0)",
                    cell.id, info.actuators[a].name
                )));
            }
            let dt = setup.timestep.unwrap_or(info.timestep);
            if !seen.contains(&dt.to_bits()) {
                seen.push(dt.to_bits());
                e.validate(cfg.schedule.duration, dt)?;
            }
        }
    }
    Ok(c)
}

/// A validated sweep and the command line that asked for it (for the manifest).
#[derive(Debug, Clone)]
pub struct SweepRequest {
    pub sweep: Sweep,
    pub command: Vec<String>,
}

/// What a finished (or interrupted) sweep leaves.
#[derive(Debug, Clone)]
pub struct SweepOutcome {
    /// summary.csv's header and rows, in cell order (resumed rows included).
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
    /// Traces of the cells run now (id, samples), when asked for.
    pub traces: Vec<(String, Vec<(f64, f64)>)>,
    /// replicates.csv's header and rows, for a replicated sweep.
    pub replicate_header: Vec<String>,
    pub replicate_rows: Vec<Vec<String>>,
    /// Every table beside summary.csv (replicates.csv; response.csv and
    /// bode.csv): file name, header, rows in cell order.
    pub details: Vec<(String, Vec<String>, Vec<Vec<String>>)>,
    /// Cell-steps each row's cell took, in row order (None for a row a
    /// resume kept from before).
    pub cell_steps: Vec<Option<u64>>,
    pub out: Option<PathBuf>,
    pub cells_total: usize,
    /// Cells this call ran (a resume skips finished ones).
    pub cells_run: usize,
    pub complete: bool,
    pub wall_seconds: f64,
    pub mujoco_version: String,
    /// What the user should know (e.g. the start fell back to the default pose).
    pub notes: Vec<String>,
}

/// Hooks of the caller (progress, interrupt) plus the run writer.
struct WriterHooks<'a> {
    ui: &'a mut dyn Hooks,
    writer: &'a mut RunWriter,
    /// Cell-steps each cell run now took, by cell index.
    steps: std::collections::BTreeMap<usize, u64>,
    /// Marks cells past the stability bound before they are written (here,
    /// where a local run's cells and a cluster's meet).
    bound: Option<&'a dyn Fn(&mut CellResult)>,
}

impl Hooks for WriterHooks<'_> {
    fn progress(&mut self, steps: u64) {
        self.ui.progress(steps)
    }
    fn should_stop(&mut self) -> bool {
        self.ui.should_stop()
    }
    fn chunk_done(&mut self, results: &[CellResult]) -> Result<()> {
        let marked: Vec<CellResult>;
        let results = match self.bound {
            Some(b) => {
                marked = results
                    .iter()
                    .cloned()
                    .map(|mut r| {
                        b(&mut r);
                        r
                    })
                    .collect();
                &marked[..]
            }
            None => results,
        };
        self.writer.add(results)?;
        for r in results {
            self.steps.insert(r.cell.index, r.steps);
        }
        self.ui.chunk_done(results)
    }
}

/// Validates everything, loads the model, then runs the cells still to do,
/// writing the run directory as chunks finish. Bad input fails before any
/// file is created. An interrupt returns `Ok` with `complete == false`.
pub fn run_sweep(req: &SweepRequest, ui: &mut dyn SweepUi) -> Result<SweepOutcome> {
    let Sweep {
        kind,
        config: cfg,
        options,
        out,
        existing,
        shard,
        ray,
    } = &req.sweep;
    cfg.validate()?;
    // a shard runs its part of the grid; the manifest keeps the whole grid
    let cells: Vec<Cell> = cfg
        .grid
        .cells()
        .into_iter()
        .filter(|c| shard.is_none_or(|s| s.holds(c.index)))
        .collect();
    let started = std::time::Instant::now();
    bridge::with_config_model(cfg, |model| {
        let info = model.info();
        // a response run's joints, named on this compiled model
        let cfg = &resolved(cfg, model)?;
        let bound = Bound::new(cfg, model);
        let unstable = bound.as_ref().and_then(Bound::note);
        let mark = bound.as_ref().map(|b| move |r: &mut CellResult| b.mark(r));
        // hung in the air, a response run needs no floor
        let standing = !cfg.experiment.plan().suspended();
        let note = check_start(info, &cfg.schedule.initial, standing)?;
        cfg.check_motor(info)?;
        // Warp and its device are checked before anything is written; on
        // Ray the workers run the physics
        let physics = match ray {
            None => Some(bridge::physics(model, &cfg.backend)?),
            Some(_) => None,
        };
        let torque_limits = match cfg.defaults.max_torque {
            Some(t) => vec![t; info.nu],
            None => info.torque_limits()?,
        };
        let unclipped = cfg
            .defaults
            .max_torque
            .is_none()
            .then(|| info.unlimited_note())
            .flatten();
        let manifest = Manifest {
            kind: kind.clone(),
            pupper_version: pupper_core::VERSION.to_string(),
            mujoco_version: model.mujoco_version().to_string(),
            python: model.python_executable(),
            config: cfg.clone(),
            model: ModelRecord {
                name: info.name.clone(),
                source: info.source.clone(),
                sha256: info.sha256.clone(),
            },
            torque_limits,
            cells_total: cells.len(),
            cells_done: 0,
            batches: 0,
            complete: false,
            threads: options.threads,
            started_unix: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_secs())
                .unwrap_or(0),
            wall_seconds: 0.0,
            command: req.command.clone(),
            shard: shard.map(|shard| ShardRecord {
                shard,
                host: pupper_core::results::rundir::hostname(),
            }),
            merged: Vec::new(),
            ray: None,
        };
        let mut writer = RunWriter::new(out.as_deref(), *existing, manifest)?;
        let done: Vec<usize> = writer.done().collect();
        let todo: Vec<Cell> = cells
            .into_iter()
            .filter(|c| !done.contains(&c.index))
            .collect();
        // every timestep's plan is checked before anything is created
        let mut steps_at: std::collections::BTreeMap<u64, u64> = Default::default();
        let dt_of = |c: &Cell| {
            cfg.setup(c, info)
                .timestep
                .unwrap_or(info.timestep)
                .to_bits()
        };
        let mut total = 0u64;
        for c in &todo {
            let dt = dt_of(c);
            let steps = match steps_at.get(&dt) {
                Some(&s) => s,
                None => {
                    let s = cfg.schedule.plan(f64::from_bits(dt))?.steps as u64;
                    steps_at.insert(dt, s);
                    s
                }
            };
            total += steps * cfg.sims_per_cell() as u64;
        }
        // the cluster last: the user's own mistakes (grid, run directory)
        // are named first, and a stop while connecting writes nothing
        let mut cluster = match ray {
            None => None,
            Some(address) => {
                let job = Job {
                    config: cfg.clone(),
                    model_sha256: info.sha256.clone(),
                    pupper_version: pupper_core::VERSION.to_string(),
                    mujoco_version: model.mujoco_version().to_string(),
                    chunk_steps: options.chunk_steps,
                };
                let gpus = match &cfg.backend {
                    Backend::Warp { device, .. } if device.starts_with("cuda") => 1.0,
                    _ => 0.0,
                };
                let c = RayCluster::connect(model.mj.py, address, &job, options.threads, gpus)?;
                writer.manifest.threads = c.record.threads_per_task;
                writer.manifest.ray = Some(c.record.clone());
                Some((c, job))
            }
        };
        if ui.hooks().should_stop() {
            return Err(Error::Interrupted("before the run started".into()));
        }
        ui.start(todo.len(), total);
        writer.create()?;
        let log = MujocoLog::watch();
        let (result, steps) = {
            let mut hooks = WriterHooks {
                ui: ui.hooks(),
                writer: &mut writer,
                steps: Default::default(),
                bound: mark.as_ref().map(|m| m as &dyn Fn(&mut CellResult)),
            };
            let r = match (&physics, &mut cluster) {
                (Some(physics), _) => {
                    runner::run_cells(physics.as_ref(), cfg, &todo, *options, &mut hooks).map(drop)
                }
                (None, Some((cluster, job))) => cluster::run_cells(
                    cluster,
                    job,
                    &todo,
                    options.chunk_cells,
                    &|c| steps_at.get(&dt_of(c)).copied().unwrap_or(0),
                    &mut hooks,
                ),
                (None, None) => Err(Error::Internal(
                    "a sweep with neither physics nor cluster".into(),
                )),
            };
            (r, hooks.steps)
        };
        // disconnects from Ray (the tasks of a stop are cancelled already)
        drop(cluster);
        if let Some(dir) = writer.dir() {
            log.move_into(dir);
        }
        let complete = match result {
            Ok(_) => true,
            Err(Error::Interrupted(_)) => false,
            Err(e) => {
                let _ = writer.finish(false);
                return Err(e);
            }
        };
        writer.finish(complete)?;
        ui.finish();
        Ok(SweepOutcome {
            header: writer.header().to_vec(),
            rows: writer.rows().cloned().collect(),
            traces: writer.traces().cloned().collect(),
            replicate_header: writer.replicate_header().to_vec(),
            replicate_rows: writer.replicate_rows(),
            details: writer.detail_tables(),
            cell_steps: writer
                .rows()
                .map(|r| r[0].parse::<usize>().ok().and_then(|i| steps.get(&i).copied()))
                .collect(),
            out: writer.dir().map(|p| p.to_path_buf()),
            cells_total: writer.manifest.cells_total,
            cells_run: todo.len(),
            complete: writer.manifest.complete,
            wall_seconds: started.elapsed().as_secs_f64(),
            mujoco_version: writer.manifest.mujoco_version.clone(),
            notes: note
                .into_iter()
                .chain(unclipped)
                .chain(unstable)
                .chain(
                    (cfg.replicates.count > 1 && cfg.replicates.randomize.is_empty()).then(|| {
                        format!(
                            "--replicates {} without --randomize runs {} identical copies of every cell: add --randomize QUANTITY=DIST (see --help) to draw a population",
                            cfg.replicates.count, cfg.replicates.count
                        )
                    }),
                )
                // the standing metrics' windows mean nothing to a response run
                .chain(cfg.schedule.shortfalls().into_iter().filter(|_| cfg.experiment.plan().pushes()))
                .collect(),
        })
    })
}

/// MuJoCo writes its warnings (a diverging cell) to `MUJOCO_LOG.TXT` in the
/// working directory; what a run adds there is moved into its run directory.
struct MujocoLog {
    path: PathBuf,
    before: Option<u64>,
}

impl MujocoLog {
    const NAME: &'static str = "MUJOCO_LOG.TXT";

    fn watch() -> MujocoLog {
        let path = PathBuf::from(Self::NAME);
        let before = std::fs::metadata(&path).ok().map(|m| m.len());
        MujocoLog { path, before }
    }

    /// Moves the lines this run added into `dir` (best effort: a log must
    /// never fail a sweep).
    fn move_into(self, dir: &std::path::Path) {
        use std::io::{Read, Seek, SeekFrom, Write};
        let start = self.before.unwrap_or(0);
        let Ok(mut f) = std::fs::File::open(&self.path) else {
            return;
        };
        if f.metadata().map_or(0, |m| m.len()) <= start {
            return;
        }
        let mut added = Vec::new();
        if f.seek(SeekFrom::Start(start)).is_err() || f.read_to_end(&mut added).is_err() {
            return;
        }
        let appended = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(dir.join(Self::NAME))
            .and_then(|mut out| out.write_all(&added));
        if appended.is_ok() {
            let _ = match self.before {
                None => std::fs::remove_file(&self.path),
                Some(n) => std::fs::OpenOptions::new()
                    .write(true)
                    .open(&self.path)
                    .and_then(|f| f.set_len(n)),
            };
        }
    }
}

/// The best cell of each group by `rule`, written to `best.csv` when the
/// sweep has a run directory.
pub fn write_best(outcome: &SweepOutcome, rule: &best::Rule) -> Result<Vec<best::Group>> {
    let groups = best::best(&outcome.header, &outcome.rows, rule)?;
    if let Some(dir) = &outcome.out {
        let (h, rows) = best::table(&outcome.header, &outcome.rows, rule, &groups);
        pupper_core::results::rundir::write_atomic(
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
