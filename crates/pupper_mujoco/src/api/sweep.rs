//! A sweep run end to end: checks, the manifest, the run directory as
//! chunks finish, locally or on a Ray cluster, and what it leaves.

use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::bridge;
use crate::bridge::ray::RayCluster;
use pupper_core::error::{Error, Result};
use pupper_core::plan::backend::Backend;
use pupper_core::plan::config::SweepConfig;
use pupper_core::plan::grid::Cell;
use pupper_core::plan::shard::Shard;
use pupper_core::request::spec::Sweep;
use pupper_core::results::output::{Manifest, ModelRecord, ShardRecord, Trace};
use pupper_core::results::rundir::RunWriter;
use pupper_core::robot::model::ModelInfo;
use pupper_core::sim::cluster::{self, Address, Job};
use pupper_core::sim::physics::Physics;
use pupper_core::sim::runner::{self, CellResult, Hooks, RunOptions};

use super::SweepUi;
use super::bound::StabilityBound;
use super::start::{check_start, resolved, start_targets};
use pupper_core::results::tables::NamedTable;

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
    pub traces: Vec<Trace>,
    /// Every table beside summary.csv (replicates.csv; response.csv and
    /// bode.csv): file name, header, rows in cell order.
    pub details: Vec<NamedTable>,
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
        config: cfg,
        options,
        out,
        existing,
        shard,
        ray,
        ..
    } = &req.sweep;
    cfg.validate()?;
    // a shard runs its part of the grid; the manifest keeps the whole grid
    let cells = shard_cells(cfg, shard.as_ref());
    let started = std::time::Instant::now();
    bridge::with_config_model(cfg, |model| {
        let info = model.info();
        // a response run's joints, named on this compiled model
        let given = cfg;
        let cfg = &resolved(cfg, model)?;
        let push = scaled_push(given, cfg, info);
        let bound = StabilityBound::new(cfg, model);
        let unstable = bound.as_ref().and_then(StabilityBound::note);
        let mark = bound.as_ref().map(|b| move |r: &mut CellResult| b.mark(r));
        // hung in the air, a response run needs no floor
        let standing = !cfg.experiment.plan().suspended();
        let mut note = check_start(info, &cfg.schedule.initial, standing)?;
        note.extend(servo_note(cfg, info));
        cfg.check_motor(info)?;
        // Warp and its device are checked before anything is written; on
        // Ray the workers run the physics
        let physics = ray
            .is_none()
            .then(|| bridge::physics(model, &cfg.backend))
            .transpose()?;
        let manifest = manifest_of(req, cfg, model, cells.len())?;
        let mut writer = RunWriter::new(out.as_deref(), *existing, manifest)?;
        let todo = still_to_do(cells, &writer);
        // every timestep's plan is checked before anything is created
        let (steps_at, total) = planned_steps(cfg, info, &todo)?;
        let steps_of = |c: &Cell| steps_at.get(&dt_bits(cfg, info, c)).copied().unwrap_or(0);
        // the cluster last: the user's own mistakes (grid, run directory)
        // are named first, and a stop while connecting writes nothing
        let mut cluster = match ray {
            None => None,
            Some(address) => Some(connect(cfg, model, address, options, &mut writer)?),
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
            let r = run_todo(
                &mut hooks,
                physics.as_ref().map(|p| p.as_ref()),
                cluster.as_mut(),
                cfg,
                &todo,
                options,
                &steps_of,
            );
            (r, hooks.steps)
        };
        // disconnects from Ray (the tasks of a stop are cancelled already)
        drop(cluster);
        finish(&mut writer, log, result)?;
        ui.finish();
        let warned = [push, unclipped(cfg, info), unstable].into_iter().flatten();
        let notes = note.into_iter().chain(warned).chain(advice(cfg)).collect();
        Ok(outcome_of(&writer, &steps, todo.len(), started, notes))
    })
}

/// The cells of the grid a run of `shard` holds (all without one).
fn shard_cells(cfg: &SweepConfig, shard: Option<&Shard>) -> Vec<Cell> {
    cfg.grid
        .cells()
        .into_iter()
        .filter(|c| shard.is_none_or(|s| s.holds(c.index)))
        .collect()
}

/// The cells not yet in the run directory (a resume skips the others).
fn still_to_do(cells: Vec<Cell>, writer: &RunWriter) -> Vec<Cell> {
    let done: Vec<usize> = writer.done().collect();
    cells
        .into_iter()
        .filter(|c| !done.contains(&c.index))
        .collect()
}

/// Runs the cells still to do through `hooks`: on this host's physics, or
/// as tasks of the Ray cluster (`steps_of`: a cell's steps, for progress).
fn run_todo(
    hooks: &mut WriterHooks<'_>,
    physics: Option<&(dyn Physics + '_)>,
    cluster: Option<&mut (RayCluster<'_>, Job)>,
    cfg: &SweepConfig,
    todo: &[Cell],
    options: &RunOptions,
    steps_of: &dyn Fn(&Cell) -> u64,
) -> Result<()> {
    match (physics, cluster) {
        (Some(physics), _) => runner::run_cells(physics, cfg, todo, *options, hooks).map(drop),
        (None, Some((cluster, job))) => {
            cluster::run_cells(cluster, job, todo, options.chunk_cells, steps_of, hooks)
        }
        (None, None) => Err(Error::Internal(
            "a sweep with neither physics nor cluster".into(),
        )),
    }
}

/// The manifest of a run about to start on `model` (nothing done yet).
fn manifest_of(
    req: &SweepRequest,
    cfg: &SweepConfig,
    model: &bridge::LoadedModel<'_>,
    cells: usize,
) -> Result<Manifest> {
    let (info, s) = (model.info(), &req.sweep);
    Ok(Manifest {
        kind: s.kind.clone(),
        pupper_version: pupper_core::VERSION.to_string(),
        mujoco_version: model.mujoco_version().to_string(),
        python: model.python_executable(),
        config: cfg.clone(),
        model: ModelRecord {
            name: info.name.clone(),
            source: info.source.clone(),
            sha256: info.sha256.clone(),
            timestep: Some(info.timestep),
        },
        torque_limits: match cfg.defaults.max_torque {
            Some(t) => vec![t; info.nu],
            None => info.torque_limits()?,
        },
        start_notes: start_targets(info, &cfg.schedule.initial)?.1,
        cells_total: cells,
        cells_done: 0,
        batches: 0,
        complete: false,
        threads: s.options.threads,
        started_unix: std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0),
        wall_seconds: 0.0,
        command: req.command.clone(),
        shard: s.shard.map(|shard| ShardRecord {
            shard,
            host: pupper_core::results::lock::hostname(),
        }),
        merged: Vec::new(),
        ray: None,
    })
}

/// A cell's timestep, as the bits that key its step plan.
fn dt_bits(cfg: &SweepConfig, info: &ModelInfo, c: &Cell) -> u64 {
    cfg.setup(c, info)
        .timestep
        .unwrap_or(info.timestep)
        .to_bits()
}

/// Each timestep's steps per cell (every plan checked before anything is
/// created), and the cell-steps of `todo` in all.
fn planned_steps(
    cfg: &SweepConfig,
    info: &ModelInfo,
    todo: &[Cell],
) -> Result<(BTreeMap<u64, u64>, u64)> {
    let mut steps_at: BTreeMap<u64, u64> = BTreeMap::new();
    let mut total = 0u64;
    for c in todo {
        let dt = dt_bits(cfg, info, c);
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
    Ok((steps_at, total))
}

/// The Ray cluster at `address`, with the job its tasks run; the manifest
/// records it. Connected last, so the user's own mistakes (grid, run
/// directory) are named first and a stop while connecting writes nothing.
fn connect<'py>(
    cfg: &SweepConfig,
    model: &bridge::LoadedModel<'py>,
    address: &Address,
    options: &RunOptions,
    writer: &mut RunWriter,
) -> Result<(RayCluster<'py>, Job)> {
    let job = Job {
        config: cfg.clone(),
        model_sha256: model.info().sha256.clone(),
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
    Ok((c, job))
}

/// The run directory closed after the cells ran (or stopped): MuJoCo's
/// log moved in, the manifest final; an error other than a stop is
/// returned once what finished is kept.
fn finish(writer: &mut RunWriter, log: MujocoLog, result: Result<()>) -> Result<()> {
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
    writer.finish(complete)
}

/// The default push as the run applies it, when the robot's mass made it
/// other than the chapter's −25 N (on Pupper v3 it is −25 N, unsaid).
fn scaled_push(given: &SweepConfig, run: &SweepConfig, info: &ModelInfo) -> Option<String> {
    use pupper_core::plan::schedule::{PUPPER_MASS_KG, PUPPER_PUSH_N};
    let by_weight = given.schedule.push.as_ref()?.by_weight;
    let force = run.schedule.push.as_ref()?.force[2];
    (by_weight && force != PUPPER_PUSH_N).then(|| {
        format!(
            "the push is {force} N: the chapter's {PUPPER_PUSH_N} N on Pupper v3 ({PUPPER_MASS_KG} kg) scaled to this model's {:.2} kg (give --push-force to set it)",
            info.total_mass
        )
    })
}

/// Actuators without a torque limit, when no --max-torque gives one.
fn unclipped(cfg: &SweepConfig, info: &ModelInfo) -> Option<String> {
    cfg.defaults
        .max_torque
        .is_none()
        .then(|| info.unlimited_note())
        .flatten()
}

/// What the user should know of the run's inputs: identical replicates,
/// and the standing metrics a short run cannot measure (they mean nothing
/// to a kind without a push).
fn advice(cfg: &SweepConfig) -> Vec<String> {
    let r = &cfg.replicates;
    (r.count > 1 && r.randomize.is_empty())
        .then(|| {
            format!(
                "--replicates {} without --randomize runs {} identical copies of every cell: add --randomize QUANTITY=DIST (see --help) to draw a population",
                r.count, r.count
            )
        })
        .into_iter()
        .chain(
            cfg.schedule
                .shortfalls()
                .into_iter()
                .filter(|_| cfg.experiment.plan().pushes()),
        )
        .collect()
}

/// What a finished (or stopped) run leaves, read from its writer.
fn outcome_of(
    writer: &RunWriter,
    steps: &BTreeMap<usize, u64>,
    cells_run: usize,
    started: std::time::Instant,
    notes: Vec<String>,
) -> SweepOutcome {
    SweepOutcome {
        header: writer.header().to_vec(),
        rows: writer.rows().cloned().collect(),
        traces: writer.traces().cloned().collect(),
        details: writer.detail_tables(),
        cell_steps: writer
            .rows()
            .map(|r| {
                r[0].parse::<usize>()
                    .ok()
                    .and_then(|i| steps.get(&i).copied())
            })
            .collect(),
        out: writer.dir().map(|p| p.to_path_buf()),
        cells_total: writer.manifest.cells_total,
        cells_run,
        complete: writer.manifest.complete,
        wall_seconds: started.elapsed().as_secs_f64(),
        mujoco_version: writer.manifest.mujoco_version.clone(),
        notes,
    }
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

/// A calibrated model's fitted servo (its torque lag, feedback latency)
/// that a servo-mode run does not run, said: MuJoCo's servo has none.
fn servo_note(cfg: &SweepConfig, info: &pupper_core::robot::model::ModelInfo) -> Option<String> {
    use pupper_core::plan::mode::Mode;
    if cfg.mode != Mode::Servo || !info.fitted_servo_times() {
        return None;
    }
    // in ms, to the microsecond
    let most = |f: fn(&pupper_core::robot::model::ActuatorInfo) -> f64| {
        (info.actuators.iter().map(f).fold(0.0_f64, f64::max) * 1e6).round() / 1e3
    };
    Some(format!(
        "the model carries a calibrated servo (torque lag up to {} ms, feedback latency up to {} ms, pupper fit's) that MuJoCo's servo cannot run: this servo-mode run leaves them out; --mode torque runs them",
        most(|a| a.lag),
        most(|a| a.latency)
    ))
}
