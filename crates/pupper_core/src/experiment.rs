//! The experiment runner: cells in chunks, each chunk one batch stepped to
//! the schedule, metrics streamed per cell. Pure Rust over [`Physics`].

use std::cell::RefCell;

use serde::{Deserialize, Serialize};

use crate::backend::Backend;
use crate::error::{Error, Result};
use crate::frames::{FrameRecorder, Frames, frame_count};
use crate::grid::{Axis, Cell, Grid};
use crate::layout::Layout;
use crate::metrics::{Metrics, Recorder, Status};
use crate::model::{ModelInfo, ModelSource};
use crate::pd;
use crate::physics::{CellSetup, Force, Mode, Physics};
use crate::quat;
use crate::randomize::{Draws, Noise, Replicates};
use crate::schedule::Schedule;

/// Values used for any axis the grid does not vary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Defaults {
    /// None: each actuator's own gains, as the model declares them.
    pub kp: Option<f64>,
    pub kd: Option<f64>,
    /// None: each actuator's own limit (the model's force or control range).
    #[serde(default)]
    pub max_torque: Option<f64>,
    /// The body (a named variant's scales).
    #[serde(default = "one")]
    pub leg_scale: f64,
    #[serde(default = "one")]
    pub torso_mass_scale: f64,
}

fn one() -> f64 {
    1.0
}

impl Default for Defaults {
    fn default() -> Self {
        Defaults {
            kp: None,
            kd: None,
            max_torque: None,
            leg_scale: 1.0,
            torso_mass_scale: 1.0,
        }
    }
}

/// Everything that decides a sweep's numbers. Stored in the manifest; a
/// resume must match it exactly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepConfig {
    pub model: ModelSource,
    pub grid: Grid,
    pub schedule: Schedule,
    pub mode: Mode,
    pub defaults: Defaults,
    /// Randomized replicates of every cell; a plain sweep leaves it out of
    /// the manifest (so its manifest is what it always was).
    #[serde(default, skip_serializing_if = "Replicates::is_plain")]
    pub replicates: Replicates,
    /// What steps the physics; the cpu backend is left out of the manifest.
    #[serde(default, skip_serializing_if = "Backend::is_cpu")]
    pub backend: Backend,
}

impl Default for SweepConfig {
    fn default() -> Self {
        SweepConfig {
            model: ModelSource::default(),
            grid: Grid::default(),
            schedule: Schedule::default(),
            mode: Mode::Servo,
            defaults: Defaults::default(),
            replicates: Replicates::default(),
            backend: Backend::Cpu,
        }
    }
}

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

impl SweepConfig {
    pub fn validate(&self) -> Result<()> {
        self.schedule.validate()?;
        let d = &self.defaults;
        for (flag, v) in [("kp", d.kp), ("kd", d.kd)] {
            let Some(v) = v else { continue };
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::Config(format!(
                    "--{flag} {v} is negative or not finite: gains must be >= 0"
                )));
            }
        }
        if self.grid.has_axis(Axis::Variant) && (d.leg_scale, d.torso_mass_scale) != (1.0, 1.0) {
            return Err(Error::Config(
                "both --variant and a variant grid axis name the body: drop one of them".into(),
            ));
        }
        if self.schedule.push.is_none() && self.grid.has_axis(Axis::PushForce) {
            return Err(Error::Config(
                "the grid varies push_force but the push is off: drop --no-push or the push_force axis"
                    .into(),
            ));
        }
        if let Some(t) = d.max_torque
            && !(t.is_finite() && t > 0.0)
        {
            return Err(Error::Config(format!(
                "max torque {t} is not positive: give --max-torque a value > 0"
            )));
        }
        let axes: Vec<&str> = self.grid.axes.iter().map(|a| a.axis.name()).collect();
        self.replicates
            .check(self.mode, self.schedule.push.is_some(), &axes)?;
        self.backend.check(self.mode, &self.replicates)
    }

    /// The simulations each cell runs.
    pub fn replicate_count(&self) -> usize {
        self.replicates.count.max(1) as usize
    }

    /// The physical setting of one replicate of a cell, with its draws.
    pub fn setup_replicate(&self, cell: &Cell, d: &Draws, info: &ModelInfo) -> CellSetup {
        let mut s = self.setup(cell, info);
        s.torso_mass_factor = d.torso_mass;
        s.leg_mass_factor = d.leg_mass;
        s.motor_gain = d.motor_gain.clone();
        if d.friction.is_some() {
            s.friction = d.friction;
        }
        if let Some(f) = d.push_force {
            s.push_force[2] = f;
        }
        s.push_at = d.push_at;
        s
    }

    /// Checks that every gain a cell may need has a value: the model's own
    /// gains stand in for a gain neither the grid nor the defaults give.
    pub fn check_gains(&self, info: &ModelInfo) -> Result<()> {
        let given = |axis: Axis, d: Option<f64>| d.is_some() || self.grid.has_axis(axis);
        if given(Axis::Kp, self.defaults.kp) && given(Axis::Kd, self.defaults.kd) {
            return Ok(());
        }
        match info.actuators.iter().find(|a| a.own_gains().is_none()) {
            Some(a) => Err(Error::Config(format!(
                "actuator '{}' of model '{}' has no PD gains of its own (it is not a position servo), so there is no default to run it at: give --kp and --kd",
                a.name, info.name
            ))),
            None => Ok(()),
        }
    }

    /// The physical setting of one cell on a model (whose actuators give
    /// the gains the grid and the defaults leave open).
    pub fn setup(&self, cell: &Cell, info: &ModelInfo) -> CellSetup {
        let get = |a: Axis, d: f64| cell.get(a).unwrap_or(d);
        let body = match cell.get(Axis::Variant) {
            Some(i) => {
                let b =
                    crate::variant::VARIANTS[(i as usize).min(crate::variant::VARIANTS.len() - 1)];
                (b.leg_scale, b.torso_mass_scale)
            }
            None => (self.defaults.leg_scale, self.defaults.torso_mass_scale),
        };
        let body = crate::variant::Scales {
            leg_scale: body.0,
            torso_mass_scale: body.1,
        };
        let base_push = self.schedule.push.as_ref().map(|p| p.force);
        // The push_force axis sets the push's world-z component (N).
        let push_force = match (cell.get(Axis::PushForce), base_push) {
            (Some(f), Some(p)) => [p[0], p[1], f],
            (Some(f), None) => [0.0, 0.0, f],
            (None, Some(p)) => p,
            (None, None) => [0.0; 3],
        };
        let own = |i: usize| -> Vec<f64> {
            info.actuators
                .iter()
                .map(|a| a.own_gains().map_or(0.0, |g| g[i]))
                .collect()
        };
        let gain = |axis: Axis, default: Option<f64>, i: usize| match cell.get(axis).or(default) {
            Some(v) => vec![v; info.nu],
            None => own(i),
        };
        CellSetup {
            kp: gain(Axis::Kp, self.defaults.kp, 0),
            kd: gain(Axis::Kd, self.defaults.kd, 1),
            max_torque: cell.get(Axis::MaxTorque).or(self.defaults.max_torque),
            push_force,
            friction: cell.get(Axis::Friction),
            timestep: cell.get(Axis::Timestep),
            // a named body sets the scales; numeric scale axes multiply them
            leg_scale: body.leg_scale * get(Axis::LegScale, 1.0),
            torso_mass_scale: body.torso_mass_scale * get(Axis::TorsoMassScale, 1.0),
            torso_mass_factor: 1.0,
            leg_mass_factor: 1.0,
            motor_gain: Vec::new(),
            push_at: None,
        }
    }
}

/// One replicate of a cell: its drawn values (in the order of
/// [`Replicates::columns`]) and its metrics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Replicate {
    pub drawn: Vec<f64>,
    pub metrics: Metrics,
}

/// One finished cell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellResult {
    pub cell: Cell,
    /// The cell's metrics (of replicate 0 in a replicated sweep).
    pub metrics: Metrics,
    /// Every replicate, in a replicated sweep; empty in a plain one.
    #[serde(default)]
    pub replicates: Vec<Replicate>,
    /// Decimated (time, base z) samples when a trace was asked for (of
    /// replicate 0 in a replicated sweep, as are the frames).
    pub trace: Vec<(f64, f64)>,
    /// States at the frame rate, when [`RunOptions::frame_rate`] is set.
    pub frames: Option<Frames>,
}

/// Callbacks from a running sweep.
pub trait Hooks {
    /// `steps` more cell-steps are done.
    fn progress(&mut self, _steps: u64) {}
    /// True to stop now; checked about every 50 ms of simulation work.
    fn should_stop(&mut self) -> bool {
        false
    }
    /// A chunk of cells finished (in grid order within the chunk).
    fn chunk_done(&mut self, _results: &[CellResult]) -> Result<()> {
        Ok(())
    }
}

/// Hooks that do nothing.
pub struct NoHooks;
impl Hooks for NoHooks {}

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
    if let Some(fps) = opts.frame_rate {
        frame_count(cfg.schedule.duration, fps)?;
    }
    // Cells of one batch must share a timestep: group, keeping grid order within.
    let model_dt = physics.info().timestep;
    let mut groups: Vec<(u64, Vec<&Cell>)> = Vec::new();
    for c in cells {
        let dt = cfg.setup(c, physics.info()).timestep.unwrap_or(model_dt);
        match groups.iter_mut().find(|(b, _)| *b == dt.to_bits()) {
            Some((_, g)) => g.push(c),
            None => groups.push((dt.to_bits(), vec![c])),
        }
    }
    let mut plans = Vec::with_capacity(groups.len());
    for (bits, _) in &groups {
        plans.push(cfg.schedule.plan(f64::from_bits(*bits))?.steps);
    }
    let mut pace = Pace::new(opts);
    let per_cell = cfg.replicate_count();
    let limit = physics.batch_limit();
    let most_cells = opts
        .chunk_cells
        .or(limit.map(|l| l / per_cell))
        .unwrap_or(DEFAULT_CHUNK_CELLS)
        .max(1);
    let mut out: Vec<CellResult> = Vec::with_capacity(cells.len());
    for ((bits, group), steps) in groups.iter().zip(plans) {
        let dt = f64::from_bits(*bits);
        let mut rest: &[&Cell] = group;
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

/// Sizes batches to about `chunk_seconds` of work from the speed measured
/// so far (a cautious guess before the first batch). Up to one simulation
/// per thread costs the same wall time, so a batch is never smaller than
/// that. `--chunk-cells` caps the cells of a batch separately.
struct Pace {
    seconds: f64,
    threads: usize,
    /// Steps per wall second of one thread.
    lane_rate: f64,
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
        }
    }

    /// Simulations of `steps` steps for the next batch.
    fn sims(&self, steps: usize) -> usize {
        let fit = self.seconds * self.lane_rate * self.threads as f64 / steps.max(1) as f64;
        (fit.floor() as usize).max(self.threads).max(1)
    }

    /// A batch of `sims` simulations of `steps` steps took `seconds`.
    fn measured(&mut self, sims: usize, steps: usize, seconds: f64) {
        if seconds > 0.05 {
            let lanes = sims.min(self.threads).max(1);
            self.lane_rate = (sims * steps) as f64 / seconds / lanes as f64;
        }
    }
}

/// Per-cell accumulators of a chunk.
struct ChunkState<'a> {
    layout: &'a Layout,
    /// Joint targets per simulation.
    targets: &'a [Vec<f64>],
    recorders: Vec<Recorder>,
    frames: Vec<Option<FrameRecorder>>,
}

impl ChunkState<'_> {
    /// One post-step sample of simulation `sim`, whose step ended at `t`.
    fn sample(&mut self, sim: usize, t: f64, pushing: bool, qpos: &[f64], peak: f64, nsat: usize) {
        let layout = self.layout;
        let z = qpos[layout.base.z()];
        let qi = layout.base.quat();
        let tilt = quat::tilt([qpos[qi], qpos[qi + 1], qpos[qi + 2], qpos[qi + 3]]).to_degrees();
        let track: f64 = layout
            .act_qpos
            .iter()
            .zip(&self.targets[sim])
            .map(|(&i, &q)| (q - qpos[i]) * (q - qpos[i]))
            .sum();
        let nu = layout.nu;
        self.recorders[sim].observe(z, tilt, track, nu, peak, nsat, nu);
        if let Some(f) = &mut self.frames[sim] {
            f.offer(t, qpos, pushing);
        }
    }
}

/// Torque-mode simulations stepped together per thread (see `run_chunk`):
/// measured on a 2-core EPYC (1 MB L2 per core): 32 per thread when
/// simulations share models, half that when each has its own.
const TORQUE_LANE_PER_THREAD: usize = 32;

struct TorqueScratch {
    peak: f64,
    nsat: usize,
}

/// What the torque-mode PD of one simulation reads: its joint angles and
/// velocities `delay` control steps late (the start state until then), the
/// angles with Gaussian noise.
struct Sensing {
    delay: usize,
    noise: Option<Noise>,
    /// The last `delay + 1` (angles, velocities) of the actuated joints,
    /// oldest first.
    history: std::collections::VecDeque<(Vec<f64>, Vec<f64>)>,
}

impl Sensing {
    fn exact(&self) -> bool {
        self.delay == 0 && self.noise.is_none()
    }
}

/// One simulation of a chunk: a replicate of a cell.
struct SimPlan {
    /// Position of its cell in the chunk.
    cell: usize,
    drawn: Vec<f64>,
    /// Steps during which it is pushed.
    push: std::ops::Range<usize>,
}

fn run_chunk(
    physics: &dyn Physics,
    cfg: &SweepConfig,
    cells: &[&Cell],
    dt: f64,
    opts: RunOptions,
    hooks: &mut dyn Hooks,
) -> Result<Vec<CellResult>> {
    let schedule = &cfg.schedule;
    let plan = schedule.plan(dt)?;
    let nsteps = plan.steps;
    let info = physics.info();
    let per_cell = cfg.replicate_count();
    let reps = &cfg.replicates;
    // every replicate of every cell, cell by cell
    let mut sims: Vec<SimPlan> = Vec::with_capacity(cells.len() * per_cell);
    let mut sensing: Vec<Sensing> = Vec::with_capacity(cells.len() * per_cell);
    // each simulation's own schedule (its push window, its trace)
    let mut schedules: Vec<Schedule> = Vec::with_capacity(cells.len() * per_cell);
    let mut setups: Vec<CellSetup> = Vec::with_capacity(cells.len() * per_cell);
    for (ci, c) in cells.iter().enumerate() {
        for r in 0..per_cell {
            let d = reps.draws(&c.id, r as u32, info.nu);
            let setup = cfg.setup_replicate(c, &d, info);
            // a replicate's own push start moves its push window; only
            // replicate 0 keeps a trace
            let mut own = schedule.clone();
            if let (Some(at), Some(p)) = (setup.push_at, own.push.as_mut()) {
                p.start = at;
            }
            if r > 0 {
                own.trace_every = 0;
            }
            let push = match setup.push_at {
                Some(_) => own.plan(dt)?.push,
                None => plan.push.clone(),
            };
            schedules.push(own);
            sensing.push(Sensing {
                delay: d.delay,
                noise: reps.noise(&c.id, r as u32),
                history: Default::default(),
            });
            setups.push(setup);
            sims.push(SimPlan {
                cell: ci,
                drawn: d.values,
                push,
            });
        }
    }
    let limits: Vec<Vec<f64>> = setups
        .iter()
        .map(|s| s.torque_limits(info))
        .collect::<Result<_>>()?;
    let mut batch = physics.start(&setups, cfg.mode, &schedule.initial, opts.threads)?;
    let recorders: Vec<Recorder> = schedules
        .iter()
        .enumerate()
        .map(|(sim, own)| Recorder::new(own, dt, batch.stance(sim)))
        .collect();
    // torque mode's PD in Rust, one control step per call; otherwise the
    // actuators hold the PD and calls advance open-loop
    let host_pd = cfg.mode == Mode::Torque && !batch.actuator_pd();
    let layout = physics.layout().clone();
    let n = sims.len();
    let targets: Vec<Vec<f64>> = (0..n).map(|s| batch.targets(s).to_vec()).collect();
    let mut state = ChunkState {
        layout: &layout,
        targets: &targets,
        recorders,
        frames: match opts.frame_rate {
            Some(fps) => {
                let count = frame_count(schedule.duration, fps)?;
                (0..n)
                    .map(|sim| {
                        if sim % per_cell != 0 {
                            return Ok(None);
                        }
                        Ok(Some(FrameRecorder::new(fps, count, &batch.qpos(sim)?)))
                    })
                    .collect::<Result<_>>()?
            }
            None => (0..n).map(|_| None).collect(),
        },
    };
    // steps at which some simulation's push starts or ends: no call crosses one
    let mut bounds: Vec<usize> = sims
        .iter()
        .flat_map(|s| [s.push.start, s.push.end])
        .collect();
    bounds.sort_unstable();
    bounds.dedup();
    let nu = layout.nu;
    // Torque mode steps once per control step. Stepping every simulation of
    // a large batch in turn keeps none of their states in cache (measured:
    // 512 simulations cost 1.23x the physics of 32): so lanes of a few
    // simulations per thread run the whole schedule one after another.
    // Simulations are independent, so the numbers do not depend on it.
    let lanes: Vec<Vec<usize>> = match host_pd {
        false => vec![(0..n).collect()],
        true => {
            let threads = match opts.threads {
                0 => std::thread::available_parallelism().map_or(1, |t| t.get()),
                t => t,
            };
            // a simulation with its own model (drawn masses) brings that
            // model into cache too: half as many fit
            let own_models = setups.iter().any(|s| !s.nominal_masses());
            let per_thread = TORQUE_LANE_PER_THREAD / if own_models { 2 } else { 1 };
            // lanes of equal size (48 simulations: 24 + 24, not 32 + 16)
            let most = (per_thread * threads).max(1);
            let width = n.div_ceil(n.div_ceil(most).max(1)).max(1);
            (0..n)
                .collect::<Vec<usize>>()
                .chunks(width)
                .map(<[usize]>::to_vec)
                .collect()
        }
    };
    // Time before each step of a call: the clock the schedule is written in.
    let mut step_time = Vec::new();
    let sine = schedule.sine.is_some();
    let mut since_check = 0usize;
    for lane in lanes {
        let mut alive = lane;
        let n = alive.len();
        let mut k = 0usize;
        let mut t_before = 0.0f64;
        while k < nsteps && !alive.is_empty() {
            let mut end = (k + opts.chunk_steps.max(1)).min(nsteps);
            if host_pd {
                end = k + 1;
            }
            if let Some(&b) = bounds.iter().find(|&&b| b > k) {
                end = end.min(b);
            }
            let pushing = |sim: usize| sims[sim].push.contains(&k);
            let nstep = end - k;
            step_time.clear();
            let mut t = t_before;
            for _ in 0..nstep {
                step_time.push(t);
                t += dt;
            }
            let force_of = |sim: usize, step: usize| -> [f64; 3] {
                let mut f = if pushing(sim) {
                    setups[sim].push_force
                } else {
                    [0.0; 3]
                };
                if sine {
                    let s = schedule.sine_force(step_time[step]);
                    for i in 0..3 {
                        f[i] += s[i];
                    }
                }
                f
            };
            let diverged: Vec<(usize, usize)> = match host_pd {
                false => {
                    let forces: Vec<[f64; 3]>;
                    let force = if sine {
                        forces = alive
                            .iter()
                            .flat_map(|&s| (0..nstep).map(move |j| (s, j)))
                            .map(|(s, j)| force_of(s, j))
                            .collect();
                        Force::PerStep(&forces)
                    } else {
                        forces = alive.iter().map(|&s| force_of(s, 0)).collect();
                        Force::Constant(&forces)
                    };
                    batch.advance(&alive, nstep, force, &mut |pos, step, qpos, act| {
                        let sim = alive[pos];
                        let (mut peak, mut nsat) = (0.0f64, 0usize);
                        for (&f, &lim) in act.iter().zip(&limits[sim]) {
                            peak = peak.max(f.abs());
                            // the actuator clamps at its force range
                            if f.abs() >= lim * (1.0 - 1e-12) {
                                nsat += 1;
                            }
                        }
                        state.sample(sim, step_time[step] + dt, pushing(sim), qpos, peak, nsat);
                    })?
                }
                true => {
                    let forces: Vec<[f64; 3]> = alive.iter().map(|&s| force_of(s, 0)).collect();
                    let scratch: RefCell<Vec<TorqueScratch>> = RefCell::new(
                        (0..alive.len())
                            .map(|_| TorqueScratch { peak: 0.0, nsat: 0 })
                            .collect(),
                    );
                    let d = batch.step_controlled(
                        &alive,
                        &forces,
                        &mut |pos, qpos, qvel, ctrl| {
                            let sim = alive[pos];
                            let s = &setups[sim];
                            let lim = &limits[sim];
                            let mut scratch = scratch.borrow_mut();
                            let sc = &mut scratch[pos];
                            sc.peak = 0.0;
                            sc.nsat = 0;
                            let sense = &mut sensing[sim];
                            let exact = sense.exact();
                            if !exact {
                                // the oldest entry's buffers take the newest state
                                let (mut q, mut v) = if sense.history.len() > sense.delay {
                                    sense.history.pop_front().unwrap_or_default()
                                } else {
                                    Default::default()
                                };
                                q.clear();
                                q.extend(layout.act_qpos.iter().map(|&i| qpos[i]));
                                v.clear();
                                v.extend(layout.act_dof.iter().map(|&i| qvel[i]));
                                sense.history.push_back((q, v));
                            }
                            for a in 0..nu {
                                let (q, v) = match sense.history.front() {
                                    Some((q, v)) if !exact => (q[a], v[a]),
                                    _ => (qpos[layout.act_qpos[a]], qvel[layout.act_dof[a]]),
                                };
                                let q = match &mut sense.noise {
                                    Some(noise) => q + noise.sample(),
                                    None => q,
                                };
                                let (tau, sat) =
                                    pd::torque(s.kp(a), s.kd(a), targets[sim][a], q, v, lim[a]);
                                ctrl[a] = tau;
                                // what the motor delivers: its gain times the
                                // command, clamped at its force range
                                let delivered = (s.gain(a) * tau).abs();
                                sc.peak = sc.peak.max(if delivered > lim[a] {
                                    lim[a]
                                } else {
                                    delivered
                                });
                                sc.nsat += (sat || delivered >= lim[a] * (1.0 + 1e-12)) as usize;
                            }
                        },
                        &mut |pos, _step, qpos, _act| {
                            let scratch = scratch.borrow();
                            let sc = &scratch[pos];
                            let sim = alive[pos];
                            state.sample(
                                sim,
                                step_time[0] + dt,
                                pushing(sim),
                                qpos,
                                sc.peak,
                                sc.nsat,
                            );
                        },
                    )?;
                    d.into_iter().map(|p| (p, 0)).collect()
                }
            };
            // Diverged cells leave the batch; their clock is set to the event.
            let mut dead: Vec<usize> = Vec::new();
            for (pos, step) in diverged {
                let sim = alive[pos];
                state.recorders[sim].diverge(step_time[step] + dt);
                dead.push(sim);
            }
            alive.retain(|s| !dead.contains(s));
            hooks.progress((nstep * (alive.len() + dead.len())) as u64);
            t_before = t;
            k = end;
            since_check += nstep * n;
            if since_check >= 2000 || !host_pd {
                since_check = 0;
                if hooks.should_stop() {
                    return Err(Error::Interrupted("stopped by a signal".into()));
                }
            }
        }
    }
    // back to cells: replicate 0 carries the trace and frames
    let replicated = !reps.is_plain();
    let mut out: Vec<CellResult> = Vec::with_capacity(cells.len());
    for ((sim, r), f) in sims.into_iter().zip(state.recorders).zip(state.frames) {
        let (metrics, trace) = r.finish();
        debug_assert!(metrics.status != Status::Diverged || metrics.event_time.is_finite());
        if out.len() == sim.cell {
            out.push(CellResult {
                cell: cells[sim.cell].clone(),
                metrics: metrics.clone(),
                replicates: Vec::new(),
                trace,
                frames: f.map(FrameRecorder::finish),
            });
        }
        if replicated {
            out[sim.cell].replicates.push(Replicate {
                drawn: sim.drawn,
                metrics,
            });
        }
    }
    Ok(out)
}
