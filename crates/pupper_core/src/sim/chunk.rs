//! The plan of a chunk: its simulations (replicates of cells, excited
//! joints), their settings and sensing, and the lanes they step in.

use crate::error::Result;
use crate::plan::config::SweepConfig;
use crate::plan::grid::Cell;
use crate::plan::mode::Mode;
use crate::plan::schedule::Schedule;
use crate::plan::setup::CellSetup;
use crate::robot::model::ModelInfo;
use crate::sim::firmware::{Sensing, firmware, latency_steps};

/// Torque-mode simulations stepped together per thread (see `run_chunk`):
/// measured on a 2-core EPYC (1 MB L2 per core): 32 per thread when
/// simulations share models, half that when each has its own.
const TORQUE_LANE_PER_THREAD: usize = 32;

/// A cell of a chunk and its setting, resolved once per cell: it picks the
/// cell's batch (by timestep) and is the base of its replicates' settings.
#[derive(Clone, Copy)]
pub(crate) struct Resolved<'a> {
    pub(crate) cell: &'a Cell,
    pub(crate) setup: &'a CellSetup,
}

/// One simulation of a chunk: a replicate of a cell (of one excited joint,
/// in a response run).
pub(crate) struct SimPlan {
    /// Position of its cell in the chunk.
    pub(crate) cell: usize,
    pub(crate) replicate: usize,
    pub(crate) drawn: Vec<f64>,
    /// Steps during which it is pushed.
    pub(crate) push: std::ops::Range<usize>,
    /// The actuator whose target follows the excitation.
    pub(crate) excited: Option<usize>,
}

/// Every simulation of a chunk, cell by cell (then excited joint, then
/// replicate): its plan, physical setting, schedule and sensing.
pub(crate) struct ChunkPlan {
    pub(crate) sims: Vec<SimPlan>,
    pub(crate) setups: Vec<CellSetup>,
    pub(crate) schedules: Vec<Schedule>,
    pub(crate) sensing: Vec<Sensing>,
}

impl ChunkPlan {
    pub(crate) fn new(
        cfg: &SweepConfig,
        cells: &[Resolved<'_>],
        dt: f64,
        info: &ModelInfo,
    ) -> Result<ChunkPlan> {
        let schedule = &cfg.schedule;
        let plan = schedule.plan(dt)?;
        let per_cell = cfg.sims_per_cell();
        let reps = &cfg.replicates;
        let excited = cfg.experiment.plan().excited();
        // a calibrated model's fitted feedback latency, run by torque mode's PD
        let late = if cfg.mode == Mode::Torque {
            latency_steps(&cfg.motor, info, dt)
        } else {
            Vec::new()
        };
        let n = cells.len() * per_cell;
        let mut out = ChunkPlan {
            sims: Vec::with_capacity(n),
            setups: Vec::with_capacity(n),
            schedules: Vec::with_capacity(n),
            sensing: Vec::with_capacity(n),
        };
        for (ci, c) in cells.iter().enumerate() {
            for &joint in &excited {
                for r in 0..cfg.replicate_count() {
                    let d = reps.draws(&c.cell.id, r as u32, info.nu);
                    let setup = c.setup.with_draws(&d);
                    // a replicate's own push start moves its push window;
                    // only replicate 0 keeps a trace
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
                    out.schedules.push(own);
                    let fw = firmware(cfg, info, dt, &d);
                    out.sensing.push(Sensing::new(
                        d.delay,
                        reps.noise(&c.cell.id, r as u32),
                        fw,
                        late.clone(),
                    ));
                    out.setups.push(setup);
                    out.sims.push(SimPlan {
                        cell: ci,
                        replicate: r,
                        drawn: d.values,
                        push,
                        excited: joint,
                    });
                }
            }
        }
        Ok(out)
    }

    pub(crate) fn len(&self) -> usize {
        self.sims.len()
    }
}

/// Lanes of simulations stepped one after another. Torque mode steps once
/// per control step; stepping every simulation of a large batch in turn
/// keeps none of their states in cache (measured: 512 simulations cost
/// 1.23x the physics of 32), so lanes of a few simulations per thread run
/// the whole schedule one after another. Simulations are independent, so
/// the numbers do not depend on it.
pub(crate) fn lanes(n: usize, per_step: bool, own_models: bool, threads: usize) -> Vec<Vec<usize>> {
    if !per_step {
        return vec![(0..n).collect()];
    }
    let threads = match threads {
        0 => std::thread::available_parallelism().map_or(1, |t| t.get()),
        t => t,
    };
    // a simulation with its own model (drawn masses) brings that model
    // into cache too: half as many fit
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
