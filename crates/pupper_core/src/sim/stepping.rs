//! Stepping a chunk: its simulations in lanes through the schedule, open
//! loop (the actuators hold the PD) or a control step at a time (torque
//! mode's PD in Rust, `sim::torque`), each step sampled into its probe.

use std::cell::RefCell;

use crate::error::{Error, Result};
use crate::plan::config::SweepConfig;
use crate::plan::kind::Motion;
use crate::robot::layout::Layout;
use crate::sim::chunk::ChunkPlan;
use crate::sim::firmware::Sensing;
use crate::sim::frames::FrameRecorder;
use crate::sim::hooks::Hooks;
use crate::sim::physics::{Advance, Controlled, Force, SimBatch};
use crate::sim::probe::{Probe, Sample};
use crate::sim::torque::{Delivered, Motors};

/// Per-simulation accumulators of a chunk.
pub(crate) struct ChunkState<'a> {
    pub(crate) layout: &'a Layout,
    /// Joint targets per simulation (before any excitation).
    pub(crate) targets: &'a [Vec<f64>],
    pub(crate) probes: Vec<Box<dyn Probe>>,
    pub(crate) frames: Vec<Option<FrameRecorder>>,
    /// Steps each simulation took (fewer than the schedule's when it
    /// diverged or, with `stop_fallen`, fell).
    pub(crate) steps: Vec<u64>,
}

impl ChunkState<'_> {
    /// One post-step sample of simulation `sim`, whose step ended at `t`;
    /// `act` the actuator forces, `peak`/`nsat` over all actuators;
    /// `moved` the step's targets where its kind moves them all.
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
        moved: Option<&[f64]>,
    ) {
        self.steps[sim] += 1;
        self.probes[sim].observe(&Sample {
            t,
            qpos,
            act,
            peak,
            nsat,
            targets: moved.unwrap_or(&self.targets[sim]),
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
pub(crate) struct Stepping<'a> {
    pub(crate) cfg: &'a SweepConfig,
    pub(crate) plan: &'a ChunkPlan,
    pub(crate) limits: &'a [Vec<f64>],
    pub(crate) targets: &'a [Vec<f64>],
    pub(crate) layout: &'a Layout,
    pub(crate) dt: f64,
    pub(crate) nsteps: usize,
    /// Steps at which some simulation's push starts or ends: no call
    /// crosses one.
    pub(crate) bounds: Vec<usize>,
    /// Control every step: torque mode's PD in Rust.
    pub(crate) per_step: bool,
    /// Targets that move on a schedule (the response): each call gets
    /// every step's ctrl.
    pub(crate) moving: bool,
    /// Each simulation's targets where its kind moves them all (a gait).
    pub(crate) motions: &'a [Option<Box<dyn Motion>>],
    pub(crate) chunk_steps: usize,
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

    /// Every target of simulation `sim` at time `t`, into `out`.
    fn fill(&self, sim: usize, t: f64, out: &mut [f64]) {
        match &self.motions[sim] {
            Some(m) => m.targets(t, out),
            None => {
                for (a, o) in out.iter_mut().enumerate() {
                    *o = self.target(sim, a, t);
                }
            }
        }
    }

    /// Actuator `a`'s target of simulation `sim` at time `t`; where a
    /// motion moves every target at once, from `row` (all of them at
    /// `row.0`, filled again when `t` differs: the firmware asks at its
    /// own delays).
    fn target_from(&self, sim: usize, a: usize, t: f64, row: &mut (f64, Vec<f64>)) -> f64 {
        if self.motions[sim].is_none() {
            return self.target(sim, a, t);
        }
        if row.0.to_bits() != t.to_bits() || row.1.len() != self.layout.nu {
            row.1.resize(self.layout.nu, 0.0);
            self.fill(sim, t, &mut row.1);
            row.0 = t;
        }
        row.1[a]
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

/// Steps one lane of simulations through the whole schedule.
pub(crate) fn step_lane(
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
    // moving targets: the servos' targets of every step, known in advance
    let nu = st.layout.nu;
    let mut ctrl = Vec::new();
    if st.moving {
        ctrl.resize(alive.len() * nstep * nu, 0.0);
        let at = alive
            .iter()
            .flat_map(|&s| step_time.iter().map(move |&t| (s, t)));
        for (row, (sim, t)) in ctrl.chunks_mut(nu.max(1)).zip(at) {
            st.fill(sim, t, row);
        }
    }
    let ctrl = ctrl;
    let mut observe = |pos: usize, step: usize, qpos: &[f64], act: &[f64]| {
        let sim = alive[pos];
        let (peak, nsat) = peak_and_saturated(act, &st.limits[sim]);
        let at = (pos * nstep + step) * nu;
        let moved = st.motions[sim].as_ref().and(ctrl.get(at..at + nu));
        state.sample(
            sim,
            step_time[step] + dt,
            pushing(sim),
            qpos,
            act,
            peak,
            nsat,
            moved,
        );
    };
    let given = st.moving.then_some(&ctrl[..]);
    let call = Advance {
        ids: alive,
        nstep,
        force,
        ctrl: given,
    };
    batch.advance(call, &mut observe)
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
    let delivered: RefCell<Vec<Delivered>> =
        RefCell::new((0..alive.len()).map(|_| Delivered::default()).collect());
    // where a motion moves every target: all of them at a time, per simulation
    let rows: RefCell<Vec<(f64, Vec<f64>)>> =
        RefCell::new((0..alive.len()).map(|_| (f64::NAN, Vec::new())).collect());
    batch.step_controlled(
        Controlled {
            ids: alive,
            force: forces,
        },
        &mut |pos, qpos, qvel, ctrl| {
            let sim = alive[pos];
            let motors = Motors {
                setup: &st.plan.setups[sim],
                limits: &st.limits[sim],
                layout: st.layout,
                target: |a, t| st.target_from(sim, a, t, &mut rows.borrow_mut()[pos]),
            };
            let mut delivered = delivered.borrow_mut();
            motors.control(&mut sensing[sim], t, qpos, qvel, ctrl, &mut delivered[pos]);
        },
        &mut |pos, _step, qpos, act| {
            let sim = alive[pos];
            let delivered = delivered.borrow();
            let d = &delivered[pos];
            // the cpu batch reports no forces here: the controller's own
            let forces = if act.is_empty() { &d.forces[..] } else { act };
            let mut rows = rows.borrow_mut();
            let row = &mut rows[pos];
            if st.motions[sim].is_some() {
                st.target_from(sim, 0, t, row);
            }
            let moved = st.motions[sim].as_ref().map(|_| &row.1[..]);
            let (peak, nsat) = (d.peak, d.nsat);
            state.sample(
                sim,
                t + st.dt,
                pushing(sim),
                qpos,
                forces,
                peak,
                nsat,
                moved,
            );
        },
    )
}
