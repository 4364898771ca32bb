//! The experiment runner: cells in chunks, each chunk one batch stepped to
//! the schedule, metrics streamed per cell. Pure Rust over [`Physics`].

use std::cell::RefCell;

use crate::error::{Error, Result};
use crate::math::pd;
use crate::plan::config::SweepConfig;
use crate::plan::experiment::Experiment;
use crate::plan::grid::Cell;
use crate::plan::mode::Mode;
use crate::robot::layout::Layout;
use crate::sim::chunk::{ChunkPlan, lanes};
use crate::sim::firmware::Sensing;
use crate::sim::frames::{FrameRecorder, frame_count};
use crate::sim::hold::HoldProbe;
use crate::sim::metrics::{Metrics, Recorder};
use crate::sim::physics::SimBatch;
use crate::sim::physics::{Force, Physics};
use crate::sim::probe::{Finish, Probe, Sample, Start};
use crate::sim::response::JointProbe;
use crate::sim::stand::StandProbe;

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
    cfg.check_motor(physics.info())?;
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

/// The registry: the probe of a simulation of `cfg`'s experiment kind.
fn probe(cfg: &SweepConfig, s: &Start<'_>) -> Box<dyn Probe> {
    match (&cfg.experiment, s.excited) {
        (Experiment::Response(e), Some(a)) => Box::new(JointProbe::new(s, a, e.hold)),
        (Experiment::Hold(l), _) => Box::new(HoldProbe::new(
            StandProbe::new(Recorder::new(s.schedule, s.dt, s.stance)),
            l,
            s.schedule,
            s.dt,
        )),
        _ => Box::new(StandProbe::new(Recorder::new(s.schedule, s.dt, s.stance))),
    }
}

/// Per-simulation accumulators of a chunk.
struct ChunkState<'a> {
    layout: &'a Layout,
    /// Joint targets per simulation (before any excitation).
    targets: &'a [Vec<f64>],
    probes: Vec<Box<dyn Probe>>,
    frames: Vec<Option<FrameRecorder>>,
    /// Steps each simulation took (fewer than the schedule's when it
    /// diverged or, with `stop_fallen`, fell).
    steps: Vec<u64>,
}

impl ChunkState<'_> {
    /// One post-step sample of simulation `sim`, whose step ended at `t`;
    /// `act` the actuator forces, `peak`/`nsat` over all actuators.
    #[allow(clippy::too_many_arguments)]
    fn sample(
        &mut self,
        sim: usize,
        t: f64,
        pushing: bool,
        qpos: &[f64],
        act: &[f64],
        peak: f64,
        nsat: usize,
    ) {
        self.steps[sim] += 1;
        self.probes[sim].observe(&Sample {
            t,
            qpos,
            act,
            peak,
            nsat,
            targets: &self.targets[sim],
            layout: self.layout,
        });
        if let Some(f) = &mut self.frames[sim] {
            f.offer(t, qpos, pushing);
        }
    }

    /// True when simulation `sim` has fallen and may stop stepping.
    fn fallen(&self, sim: usize) -> bool {
        self.probes[sim].fallen()
    }

    fn diverge(&mut self, sim: usize, t: f64) {
        self.probes[sim].diverge(t);
    }
}

/// The peak |force| of `act` and how many are at their `limits`.
fn peak_and_saturated(act: &[f64], limits: &[f64]) -> (f64, usize) {
    let (mut peak, mut nsat) = (0.0f64, 0usize);
    for (&f, &lim) in act.iter().zip(limits) {
        peak = peak.max(f.abs());
        // the actuator clamps at its force range
        if f.abs() >= lim * (1.0 - 1e-12) {
            nsat += 1;
        }
    }
    (peak, nsat)
}

/// What stays fixed while a chunk steps.
struct Stepping<'a> {
    cfg: &'a SweepConfig,
    plan: &'a ChunkPlan,
    limits: &'a [Vec<f64>],
    targets: &'a [Vec<f64>],
    layout: &'a Layout,
    dt: f64,
    nsteps: usize,
    /// Steps at which some simulation's push starts or ends: no call
    /// crosses one.
    bounds: Vec<usize>,
    /// Control every step: torque mode's PD in Rust.
    per_step: bool,
    /// Targets that move on a schedule (the response): each call gets
    /// every step's ctrl.
    moving: bool,
    chunk_steps: usize,
}

impl Stepping<'_> {
    /// Simulation `sim`'s target of actuator `a` at time `t`.
    fn target(&self, sim: usize, a: usize, t: f64) -> f64 {
        let base = self.targets[sim][a];
        match self.plan.sims[sim].excited {
            Some(j) if j == a => {
                base + self
                    .cfg
                    .experiment
                    .plan()
                    .target_offset(t, self.cfg.schedule.duration)
            }
            _ => base,
        }
    }

    /// The external base force on simulation `sim` at time `t` (pushed or not).
    fn force(&self, sim: usize, pushing: bool, t: f64) -> [f64; 3] {
        let mut f = if pushing {
            self.plan.setups[sim].push_force
        } else {
            [0.0; 3]
        };
        if self.cfg.schedule.sine.is_some() {
            let s = self.cfg.schedule.sine_force(t);
            for i in 0..3 {
                f[i] += s[i];
            }
        }
        let own = self.cfg.experiment.plan().base_force(t);
        if own != [0.0; 3] {
            for i in 0..3 {
                f[i] += own[i];
            }
        }
        f
    }
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
    let info = physics.info();
    cfg.motor.check_timestep(dt)?;
    let mut plan = ChunkPlan::new(cfg, cells, dt, info)?;
    let limits: Vec<Vec<f64>> = plan
        .setups
        .iter()
        .map(|s| s.torque_limits(info))
        .collect::<Result<_>>()?;
    let mut batch = physics.start(&plan.setups, cfg.mode, &schedule.initial, opts.threads)?;
    let layout = physics.layout().clone();
    let n = plan.len();
    let probes: Vec<Box<dyn Probe>> = (0..n)
        .map(|sim| {
            probe(
                cfg,
                &Start {
                    excited: plan.sims[sim].excited,
                    replicate: plan.sims[sim].replicate,
                    schedule: &plan.schedules[sim],
                    dt,
                    stance: batch.stance(sim),
                    layout: &layout,
                    limits: &limits[sim],
                },
            )
        })
        .collect();
    let targets: Vec<Vec<f64>> = (0..n).map(|s| batch.targets(s).to_vec()).collect();
    let mut state = ChunkState {
        layout: &layout,
        targets: &targets,
        probes,
        steps: vec![0; n],
        frames: frame_recorders(cfg, batch.as_ref(), n, opts.frame_rate)?,
    };
    let mut bounds: Vec<usize> = plan
        .sims
        .iter()
        .flat_map(|s| [s.push.start, s.push.end])
        .collect();
    bounds.sort_unstable();
    bounds.dedup();
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
        bounds,
        per_step: host_pd,
        moving,
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

/// Steps one lane of simulations through the whole schedule.
fn step_lane(
    st: &Stepping<'_>,
    batch: &mut dyn SimBatch,
    state: &mut ChunkState<'_>,
    sensing: &mut [Sensing],
    lane: Vec<usize>,
    hooks: &mut dyn Hooks,
    since_check: &mut usize,
) -> Result<()> {
    let dt = st.dt;
    let mut alive = lane;
    let n = alive.len();
    let mut k = 0usize;
    let mut t_before = 0.0f64;
    // Time before each step of a call: the clock the schedule is written in.
    let mut step_time = Vec::new();
    while k < st.nsteps && !alive.is_empty() {
        let mut end = (k + st.chunk_steps.max(1)).min(st.nsteps);
        if st.per_step {
            end = k + 1;
        }
        if let Some(&b) = st.bounds.iter().find(|&&b| b > k) {
            end = end.min(b);
        }
        let pushing = |sim: usize| st.plan.sims[sim].push.contains(&k);
        let nstep = end - k;
        step_time.clear();
        let mut t = t_before;
        for _ in 0..nstep {
            step_time.push(t);
            t += dt;
        }
        let diverged: Vec<(usize, usize)> = if st.per_step {
            let forces: Vec<[f64; 3]> = alive
                .iter()
                .map(|&s| st.force(s, pushing(s), step_time[0]))
                .collect();
            let d = step_controlled(
                st,
                batch,
                state,
                sensing,
                &alive,
                &forces,
                step_time[0],
                &pushing,
            )?;
            d.into_iter().map(|p| (p, 0)).collect()
        } else {
            advance_open_loop(st, batch, state, &alive, &step_time, &pushing)?
        };
        // Diverged cells leave the batch; their clock is set to the event.
        let mut dead: Vec<usize> = Vec::new();
        for (pos, step) in diverged {
            let sim = alive[pos];
            state.diverge(sim, step_time[step] + dt);
            dead.push(sim);
        }
        alive.retain(|s| !dead.contains(s));
        let stepped = alive.len() + dead.len();
        if st.cfg.schedule.stop_fallen {
            // a robot on the floor has nothing more to say: it stops here
            alive.retain(|&s| !state.fallen(s));
        }
        hooks.progress((nstep * stepped) as u64);
        t_before = t;
        k = end;
        *since_check += nstep * n;
        if *since_check >= 2000 || !st.per_step {
            *since_check = 0;
            if hooks.should_stop() {
                return Err(Error::Interrupted("stopped by a signal".into()));
            }
        }
    }
    Ok(())
}

/// One open-loop call over the steps starting at `step_time`: the
/// actuators hold the PD (servo mode, or torque mode's actuator PD), so the
/// batch advances without the runner; moving targets are handed over as
/// every step's ctrl. Returns the diverged (position in `alive`, step).
fn advance_open_loop(
    st: &Stepping<'_>,
    batch: &mut dyn SimBatch,
    state: &mut ChunkState<'_>,
    alive: &[usize],
    step_time: &[f64],
    pushing: &dyn Fn(usize) -> bool,
) -> Result<Vec<(usize, usize)>> {
    let dt = st.dt;
    let nstep = step_time.len();
    // a force that changes every step: one per step of the call
    let sine = st.cfg.schedule.sine.is_some() || st.cfg.experiment.plan().varying_force();
    let forces: Vec<[f64; 3]>;
    let force = if sine {
        forces = alive
            .iter()
            .flat_map(|&s| (0..nstep).map(move |j| (s, j)))
            .map(|(s, j)| st.force(s, pushing(s), step_time[j]))
            .collect();
        Force::PerStep(&forces)
    } else {
        forces = alive
            .iter()
            .map(|&s| st.force(s, pushing(s), step_time[0]))
            .collect();
        Force::Constant(&forces)
    };
    let mut observe = |pos: usize, step: usize, qpos: &[f64], act: &[f64]| {
        let sim = alive[pos];
        let (peak, nsat) = peak_and_saturated(act, &st.limits[sim]);
        state.sample(
            sim,
            step_time[step] + dt,
            pushing(sim),
            qpos,
            act,
            peak,
            nsat,
        );
    };
    Ok(match st.moving {
        false => batch.advance(alive, nstep, force, None, &mut observe)?,
        true => {
            // the servos' targets of every step, known in advance
            let nu = st.layout.nu;
            let mut ctrl = Vec::with_capacity(alive.len() * nstep * nu);
            for &sim in alive {
                for &t in step_time {
                    ctrl.extend((0..nu).map(|a| st.target(sim, a, t)));
                }
            }
            batch.advance(alive, nstep, force, Some(&ctrl), &mut observe)?
        }
    })
}

/// What the controller of one simulation worked out for its step: the
/// largest delivered force, how many actuators were at their limit, and
/// (servo mode) each actuator's force.
struct TorqueScratch {
    peak: f64,
    nsat: usize,
    forces: Vec<f64>,
}

/// One controlled step of the simulations `alive` at time `t`: torque
/// mode's PD in Rust writes ctrl from each state (towards targets that may
/// move), then all step once and are sampled.
#[allow(clippy::too_many_arguments)]
fn step_controlled(
    st: &Stepping<'_>,
    batch: &mut dyn SimBatch,
    state: &mut ChunkState<'_>,
    sensing: &mut [Sensing],
    alive: &[usize],
    forces: &[[f64; 3]],
    t: f64,
    pushing: &dyn Fn(usize) -> bool,
) -> Result<Vec<usize>> {
    let layout = st.layout;
    let nu = layout.nu;
    let scratch: RefCell<Vec<TorqueScratch>> = RefCell::new(
        (0..alive.len())
            .map(|_| TorqueScratch {
                peak: 0.0,
                nsat: 0,
                forces: Vec::new(),
            })
            .collect(),
    );
    batch.step_controlled(
        alive,
        forces,
        &mut |pos, qpos, qvel, ctrl| {
            let sim = alive[pos];
            let s = &st.plan.setups[sim];
            let lim = &st.limits[sim];
            let mut scratch = scratch.borrow_mut();
            let sc = &mut scratch[pos];
            sc.peak = 0.0;
            sc.nsat = 0;
            let sense = &mut sensing[sim];
            sense.remember(layout, qpos, qvel);
            sc.forces.clear();
            let due = sense.firmware.as_mut().map(|f| f.due(t));
            for a in 0..nu {
                let (tau, sat) = match due {
                    None => {
                        let (q, v) = sense.read(layout, a, qpos, qvel);
                        pd::torque(s.kp(a), s.kd(a), st.target(sim, a, t), q, v, lim[a])
                    }
                    Some(due) => {
                        if due {
                            let (q, v) = sense.read(layout, a, qpos, qvel);
                            if let Some(f) = sense.firmware.as_mut() {
                                let target = st.target(sim, a, t - f.delays[a]);
                                f.update(a, s.kp(a), s.kd(a), target, q, v);
                            }
                        }
                        match &sense.firmware {
                            Some(f) => f.deliver(a, lim[a], qvel[layout.act_dof[a]]),
                            None => (0.0, false),
                        }
                    }
                };
                ctrl[a] = tau;
                // what the motor delivers: its gain times the command,
                // clamped at its force range
                let signed = s.gain(a) * tau;
                sc.forces.push(signed.clamp(-lim[a], lim[a]));
                let delivered = signed.abs();
                sc.peak = sc.peak.max(if delivered > lim[a] {
                    lim[a]
                } else {
                    delivered
                });
                sc.nsat += (sat || delivered >= lim[a] * (1.0 + 1e-12)) as usize;
            }
        },
        &mut |pos, _step, qpos, act| {
            let sim = alive[pos];
            let scratch = scratch.borrow();
            let sc = &scratch[pos];
            // the cpu batch reports no forces here: the controller's own
            let forces = if act.is_empty() { &sc.forces[..] } else { act };
            state.sample(sim, t + st.dt, pushing(sim), qpos, forces, sc.peak, sc.nsat);
        },
    )
}

/// Back to cells: replicate 0 carries the trace and frames; a response
/// run's cells carry each excited joint's result.
fn finish_chunk(
    cfg: &SweepConfig,
    cells: &[&Cell],
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
                cell: cells[sim.cell].clone(),
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
