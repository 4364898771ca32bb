//! The experiment runner: cells in chunks, each chunk one batch stepped to
//! the schedule, metrics streamed per cell. Pure Rust over [`Physics`].

use crate::error::Result;
use crate::plan::config::SweepConfig;
use crate::plan::experiment::Experiment;
use crate::plan::grid::Cell;
use crate::plan::kind::Motion;
use crate::plan::mode::Mode;
use crate::plan::setup::CellSetup;
use crate::robot::layout::Layout;
use crate::sim::chunk::{ChunkPlan, Resolved, lanes};
use crate::sim::frames::{FrameRecorder, frame_count};
use crate::sim::hold::HoldProbe;
use crate::sim::metrics::{Metrics, Recorder};
use crate::sim::physics::{BatchStart, Physics, SimBatch};
use crate::sim::probe::{Finish, Probe, Start};
use crate::sim::response::JointProbe;
use crate::sim::stand::{OnStand, StandProbe};
use crate::sim::stepping::{ChunkState, Stepping, step_lane};
use crate::sim::walk::WalkProbe;

pub use crate::sim::hooks::{Hooks, NoHooks};
pub use crate::sim::result::{CellResult, Replicate};

/// Most cells per batch on the cpu backend unless `--chunk-cells` says.
pub const DEFAULT_CHUNK_CELLS: usize = 256;

/// How to run (not what): changes speed and what is kept, never numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunOptions {
    /// Threads of the batch; 0 for all cores.
    pub threads: usize,
    /// Most cells per batch; None: [`DEFAULT_CHUNK_CELLS`], or what the
    /// physics' [`Physics::batch_limit`] holds.
    pub chunk_cells: Option<usize>,
    /// Wall seconds of work a batch aims at: the most a stop (Ctrl-C, a
    /// kill) can lose, whatever the grid. Batches grow or shrink with the
    /// measured speed; numbers never depend on it.
    pub chunk_seconds: f64,
    /// Steps per open-loop call in servo mode.
    pub chunk_steps: usize,
    /// Record qpos at this many frames per second (for drawing).
    pub frame_rate: Option<f64>,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            threads: 0,
            chunk_cells: None,
            chunk_seconds: 10.0,
            chunk_steps: 250,
            frame_rate: None,
        }
    }
}

/// Runs `cells` (any subset of the grid, e.g. the ones a resume still
/// needs). Results come back in the order of `cells`. On interrupt returns
/// `Error::Interrupted` after the finished chunks were passed to `hooks`.
pub fn run_cells(
    physics: &dyn Physics,
    cfg: &SweepConfig,
    cells: &[Cell],
    opts: RunOptions,
    hooks: &mut dyn Hooks,
) -> Result<Vec<CellResult>> {
    cfg.validate()?;
    cfg.check_gains(physics.info())?;
    cfg.check_motor(physics.info())?;
    if let Some(fps) = opts.frame_rate {
        frame_count(cfg.schedule.duration, fps)?;
    }
    // each cell's setting, resolved once: its timestep picks its batch, its
    // replicates' settings start from it
    let setups: Vec<CellSetup> = cells.iter().map(|c| cfg.setup(c, physics.info())).collect();
    let groups = by_timestep(cells, &setups, physics.info().timestep);
    let mut plans = Vec::with_capacity(groups.len());
    for (bits, _) in &groups {
        plans.push(cfg.schedule.plan(f64::from_bits(*bits))?.steps);
    }
    let mut pace = Pace::new(opts);
    let per_cell = cfg.sims_per_cell();
    let limit = physics.batch_limit();
    let most_cells = opts
        .chunk_cells
        .or(limit.map(|l| l / per_cell))
        .unwrap_or(DEFAULT_CHUNK_CELLS)
        .max(1);
    let mut out: Vec<CellResult> = Vec::with_capacity(cells.len());
    for ((bits, group), steps) in groups.iter().zip(plans) {
        let dt = f64::from_bits(*bits);
        let mut rest: &[Resolved<'_>] = group;
        while !rest.is_empty() {
            // a cell's replicates always share its batch
            let fit = match limit {
                Some(most) => most / per_cell,
                None => pace.sims(steps).div_ceil(per_cell),
            }
            .max(1);
            let (chunk, more) = rest.split_at(fit.min(most_cells).min(rest.len()));
            let started = std::time::Instant::now();
            let results = run_chunk(physics, cfg, chunk, dt, opts, hooks)?;
            pace.measured(
                chunk.len() * per_cell,
                steps,
                started.elapsed().as_secs_f64(),
            );
            hooks.chunk_done(&results)?;
            out.extend(results);
            rest = more;
        }
    }
    // back to the caller's order
    let pos = |c: &Cell| {
        cells
            .iter()
            .position(|x| x.index == c.index)
            .unwrap_or(usize::MAX)
    };
    out.sort_by_key(|r| pos(&r.cell));
    Ok(out)
}

/// The cells by timestep, as the bits of it (the cells of one batch share
/// one), keeping grid order within each.
fn by_timestep<'a>(
    cells: &'a [Cell],
    setups: &'a [CellSetup],
    model_dt: f64,
) -> Vec<(u64, Vec<Resolved<'a>>)> {
    let mut groups: Vec<(u64, Vec<Resolved<'a>>)> = Vec::new();
    for (cell, setup) in cells.iter().zip(setups) {
        let bits = setup.timestep.unwrap_or(model_dt).to_bits();
        let c = Resolved { cell, setup };
        match groups.iter_mut().find(|(b, _)| *b == bits) {
            Some((_, g)) => g.push(c),
            None => groups.push((bits, vec![c])),
        }
    }
    groups
}

/// Sizes batches to about `chunk_seconds` of work from the speed measured
/// so far (a cautious guess before the first batch). Up to one simulation
/// per thread costs the same wall time, so a batch is never smaller than
/// that. `--chunk-cells` caps the cells of a batch separately.
struct Pace {
    seconds: f64,
    threads: usize,
    /// Steps per wall second of one thread.
    lane_rate: f64,
    /// Whether a batch has been timed: before one, the guess is taken as
    /// the rate of the whole batch, not of each thread, since a kind whose
    /// every step runs Rust per simulation (a walk's targets and feet, torque
    /// mode's PD) does not get faster with threads (a 256-cell first walk
    /// batch on 16 threads took 45 s).
    measured: bool,
}

impl Pace {
    fn new(opts: RunOptions) -> Pace {
        let threads = match opts.threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            n => n,
        };
        Pace {
            seconds: opts.chunk_seconds,
            threads,
            // 40 µs per step: Pupper on a slow core (measured again after
            // the first batch)
            lane_rate: 2.5e4,
            measured: false,
        }
    }

    /// Simulations of `steps` steps for the next batch.
    fn sims(&self, steps: usize) -> usize {
        let lanes = if self.measured { self.threads } else { 1 };
        let fit = self.seconds * self.lane_rate * lanes as f64 / steps.max(1) as f64;
        (fit.floor() as usize).max(self.threads).max(1)
    }

    /// A batch of `sims` simulations of `steps` steps took `seconds`.
    fn measured(&mut self, sims: usize, steps: usize, seconds: f64) {
        if seconds > 0.05 {
            let lanes = sims.min(self.threads).max(1);
            self.lane_rate = (sims * steps) as f64 / seconds / lanes as f64;
            self.measured = true;
        }
    }
}

/// The registry: the probe of a simulation of `cfg`'s experiment kind.
fn probe(cfg: &SweepConfig, s: &Start<'_>) -> Box<dyn Probe> {
    match (&cfg.experiment, s.excited) {
        (Experiment::Response(e), Some(a)) => Box::new(JointProbe::new(s, a, e.hold)),
        (Experiment::Hold(l), _) => Box::new(OnStand::new(s, HoldProbe::new(l, s.schedule, s.dt))),
        (Experiment::Walk(w), _) => Box::new(OnStand::new(s, WalkProbe::new(s, w))),
        _ => Box::new(StandProbe::new(Recorder::new(s.schedule, s.dt, s.stance))),
    }
}

/// Runs one chunk of cells sharing the timestep `dt` as one batch.
fn run_chunk(
    physics: &dyn Physics,
    cfg: &SweepConfig,
    cells: &[Resolved<'_>],
    dt: f64,
    opts: RunOptions,
    hooks: &mut dyn Hooks,
) -> Result<Vec<CellResult>> {
    let schedule = &cfg.schedule;
    let info = physics.info();
    cfg.motor.check_timestep(dt)?;
    let mut plan = ChunkPlan::new(cfg, cells, dt, info)?;
    let limits: Vec<Vec<f64>> = plan
        .setups
        .iter()
        .map(|s| s.torque_limits(info))
        .collect::<Result<_>>()?;
    let mut batch = physics.start(&BatchStart {
        cells: &plan.setups,
        mode: cfg.mode,
        initial: &schedule.initial,
        threads: opts.threads,
    })?;
    let layout = physics.layout().clone();
    let n = plan.len();
    let probes = probes(cfg, cells, &plan, batch.as_ref(), &layout, &limits, dt);
    let targets: Vec<Vec<f64>> = (0..n).map(|s| batch.targets(s).to_vec()).collect();
    // each simulation's targets where its kind moves them all (a gait)
    let motions: Vec<Option<Box<dyn Motion>>> = (0..n)
        .map(|s| {
            let cell = cells[plan.sims[s].cell].cell;
            cfg.experiment.plan().motion(cell, &targets[s])
        })
        .collect();
    let mut state = ChunkState {
        layout: &layout,
        targets: &targets,
        probes,
        steps: vec![0; n],
        frames: frame_recorders(cfg, batch.as_ref(), n, opts.frame_rate)?,
    };
    // torque mode's PD in Rust, one control step per call; otherwise the
    // actuators hold the PD and calls advance open-loop (unless targets move)
    let host_pd = cfg.mode == Mode::Torque && !batch.actuator_pd();
    // moving targets are the ctrl of every step: the servos' (servo mode)
    // or the actuator PD's (torque mode on warp)
    let moving = cfg.experiment.plan().moving_targets();
    let own_models = plan.setups.iter().any(|s| !s.nominal_masses());
    // the sensing changes as it steps; the rest of the plan stays
    let mut sensing = std::mem::take(&mut plan.sensing);
    let stepping = Stepping {
        cfg,
        plan: &plan,
        limits: &limits,
        targets: &targets,
        layout: &layout,
        dt,
        nsteps: schedule.plan(dt)?.steps,
        bounds: push_bounds(&plan),
        per_step: host_pd,
        moving,
        motions: &motions,
        chunk_steps: opts.chunk_steps,
    };
    let mut since_check = 0usize;
    for lane in lanes(n, stepping.per_step, own_models, opts.threads) {
        step_lane(
            &stepping,
            batch.as_mut(),
            &mut state,
            &mut sensing,
            lane,
            hooks,
            &mut since_check,
        )?;
    }
    finish_chunk(cfg, cells, dt, plan, state)
}

/// Each simulation's probe, of the chunk's experiment kind.
fn probes(
    cfg: &SweepConfig,
    cells: &[Resolved<'_>],
    plan: &ChunkPlan,
    batch: &dyn SimBatch,
    layout: &Layout,
    limits: &[Vec<f64>],
    dt: f64,
) -> Vec<Box<dyn Probe>> {
    (0..plan.len())
        .map(|sim| {
            probe(
                cfg,
                &Start {
                    excited: plan.sims[sim].excited,
                    replicate: plan.sims[sim].replicate,
                    cell: cells[plan.sims[sim].cell].cell,
                    schedule: &plan.schedules[sim],
                    dt,
                    stance: batch.stance(sim),
                    layout,
                    limits: &limits[sim],
                },
            )
        })
        .collect()
}

/// The steps at which some simulation's push starts or ends: no call
/// crosses one.
fn push_bounds(plan: &ChunkPlan) -> Vec<usize> {
    let mut bounds: Vec<usize> = plan
        .sims
        .iter()
        .flat_map(|s| [s.push.start, s.push.end])
        .collect();
    bounds.sort_unstable();
    bounds.dedup();
    bounds
}

/// The frame recorders of a chunk's `n` simulations at `fps` (None: no
/// frames): replicate 0 of each cell records, the others draw nothing.
fn frame_recorders(
    cfg: &SweepConfig,
    batch: &dyn SimBatch,
    n: usize,
    fps: Option<f64>,
) -> Result<Vec<Option<FrameRecorder>>> {
    let Some(fps) = fps else {
        return Ok((0..n).map(|_| None).collect());
    };
    let count = frame_count(cfg.schedule.duration, fps)?;
    let per_cell = cfg.sims_per_cell();
    (0..n)
        .map(|sim| {
            if sim % per_cell != 0 {
                return Ok(None);
            }
            Ok(Some(FrameRecorder::new(fps, count, &batch.qpos(sim)?)))
        })
        .collect()
}

/// Back to cells: replicate 0 carries the trace and frames; a response
/// run's cells carry each excited joint's result.
fn finish_chunk(
    cfg: &SweepConfig,
    cells: &[Resolved<'_>],
    dt: f64,
    plan: ChunkPlan,
    state: ChunkState<'_>,
) -> Result<Vec<CellResult>> {
    let mut out: Vec<CellResult> = Vec::with_capacity(cells.len());
    for ((((sim, probe), f), setup), steps) in plan
        .sims
        .into_iter()
        .zip(state.probes)
        .zip(state.frames)
        .zip(&plan.setups)
        .zip(state.steps)
    {
        if out.len() == sim.cell {
            out.push(CellResult {
                cell: cells[sim.cell].cell.clone(),
                metrics: Metrics::empty(),
                replicates: Vec::new(),
                trace: Vec::new(),
                frames: None,
                joints: Vec::new(),
                figures: Vec::new(),
                steps: 0,
            });
        }
        let cell = &mut out[sim.cell];
        cell.steps += steps;
        probe.finish(
            cell,
            Finish {
                cfg,
                replicate: sim.replicate,
                drawn: sim.drawn,
                setup,
                dt,
                frames: f,
            },
        );
    }
    Ok(out)
}
