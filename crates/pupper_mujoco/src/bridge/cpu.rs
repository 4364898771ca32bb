//! The CPU backend: every cell of a chunk in one `mujoco.batch.Batch`,
//! stepped on MuJoCo's C thread pool. State is read and written through the
//! batch's state rows, one contiguous `(nsim, nstate)` float64 array, so the
//! hot loop makes one borrow per step and copies nothing.

use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use super::model::LoadedModel;
use super::python::{PyResultExt, py_err};
use super::setup::{StartStates, actuator_params, colliding_geoms, prepare_model, scale_masses};
use pupper_core::error::{Error, Result};
use pupper_core::plan::mode::Mode;
use pupper_core::plan::schedule::InitialState;
use pupper_core::plan::setup::CellSetup;
use pupper_core::robot::layout::Layout;
use pupper_core::robot::model::ModelInfo;
use pupper_core::sim::physics::{Controller, Force, Observer, Physics, SimBatch};

impl Physics for LoadedModel<'_> {
    fn info(&self) -> &ModelInfo {
        &self.info
    }

    fn layout(&self) -> &Layout {
        // start() is only reachable through floating()
        self.layout
            .as_ref()
            .unwrap_or_else(|| unreachable!("layout of a non-floating model"))
    }

    fn start(
        &self,
        cells: &[CellSetup],
        mode: Mode,
        initial: &InitialState,
        threads: usize,
    ) -> Result<Box<dyn SimBatch + '_>> {
        let batch = MujocoBatch::new(self, cells, mode, initial, threads)?;
        Ok(Box::new(batch))
    }
}

/// Offsets of state components within a state row.
#[derive(Debug, Clone, Copy)]
struct Offsets {
    qpos: usize,
    qvel: usize,
    ctrl: usize,
    xfrc: usize,
    nstate: usize,
}

pub struct MujocoBatch<'a, 'py> {
    owner: &'a LoadedModel<'py>,
    batch: Bound<'py, PyAny>,
    state: Bound<'py, PyArray2<f64>>,
    warning: Bound<'py, PyArray3<i32>>,
    /// Warning counts after the last call, per simulation.
    warned: Vec<i64>,
    off: Offsets,
    /// Joint targets per simulation, in ctrl order.
    targets: Vec<Vec<f64>>,
    /// Stance height per simulation.
    stance: Vec<f64>,
    nsim: usize,
    /// Row of the base body in xfrc_applied.
    force_body: usize,
    nbody: usize,
}

impl<'a, 'py> MujocoBatch<'a, 'py> {
    fn new(
        owner: &'a LoadedModel<'py>,
        cells: &[CellSetup],
        mode: Mode,
        initial: &InitialState,
        threads: usize,
    ) -> Result<Self> {
        let mj = &owner.mj;
        let py = mj.py;
        let info = &owner.info;
        let layout = Physics::layout(owner);
        let n = cells.len();
        let dt = cells[0].timestep.unwrap_or(info.timestep);
        let same_body = cells.iter().all(|c| {
            c.leg_scale == cells[0].leg_scale
                && c.torso_mass_scale == cells[0].torso_mass_scale
                && c.nominal_masses()
        });
        let prepare = |m: &Bound<'py, PyAny>| prepare_model(mj, m, mode, dt);
        let template =
            prepare(&owner.variant(cells[0].leg_scale, cells[0].torso_mass_scale)?).internal()?;
        let batch = mj
            .batch
            .getattr("Batch")
            .and_then(|b| {
                // torque mode steps once per control step: a persistent batch
                // keeps each MjData between calls instead of rebuilding it
                let kw = PyDict::new(py);
                kw.set_item("persistent", mode == Mode::Torque)?;
                b.call((&template, n, threads), Some(&kw))
            })
            .internal()?;
        let colliding = colliding_geoms(&template).internal()?;
        if same_body {
            // one model: per-cell fields through expand()
            set_cell_fields(&batch, cells, mode, info, &colliding)?;
        } else {
            let models = cell_models(owner, cells, mode, dt, &colliding)?;
            batch.call_method1("set_models", (models,)).internal()?;
        }
        let state: Bound<'py, PyArray2<f64>> = batch
            .getattr("state")
            .and_then(|s| s.cast_into::<PyArray2<f64>>().map_err(PyErr::from))
            .internal()?;
        if !state.is_c_contiguous() {
            return Err(Error::Internal(
                "batch state rows are not contiguous".into(),
            ));
        }
        let warning: Bound<'py, PyArray3<i32>> = batch
            .getattr("warning")
            .and_then(|s| s.cast_into::<PyArray3<i32>>().map_err(PyErr::from))
            .internal()?;
        let off = offsets(&batch, &state)?;
        // initial state and targets
        let starts = StartStates::new(owner, cells, initial)?;
        let kw = PyDict::new(py);
        kw.set_item("keyframe", starts.keyframe.map_or(-1, |k| k as i64))
            .internal()?;
        kw.set_item("stage", 0).internal()?;
        batch.call_method("reset", (), Some(&kw)).internal()?;
        {
            let mut s = state.readwrite();
            let rows = s
                .as_slice_mut()
                .map_err(|e| Error::Internal(e.to_string()))?;
            for i in 0..n {
                let row = &mut rows[i * off.nstate..(i + 1) * off.nstate];
                starts.qpos(owner, i, &mut row[off.qpos..off.qpos + info.nq]);
                let targets = &starts.starts[i].0;
                let ctrl = &mut row[off.ctrl..off.ctrl + info.nu];
                match mode {
                    Mode::Servo => ctrl.copy_from_slice(targets),
                    Mode::Torque => ctrl.fill(0.0),
                }
            }
        }
        let stance = starts.stance;
        let targets: Vec<Vec<f64>> = starts.starts.into_iter().map(|(t, _)| t).collect();
        let warned = vec![0; n];
        let mut me = MujocoBatch {
            owner,
            batch,
            state,
            warning,
            warned,
            off,
            targets,
            stance,
            nsim: n,
            force_body: layout.base.body,
            nbody: info.nbody,
        };
        me.warned = me.warning_counts();
        Ok(me)
    }

    /// The rollout's control input when the force changes per step or
    /// targets move: a row per (simulation, step) of [ctrl (nu)] then
    /// [xfrc_applied (6 nbody)], in mjtState's order, and its spec bits.
    fn control_input(
        &self,
        n: usize,
        nstep: usize,
        per_step: Option<&[[f64; 3]]>,
        ctrl: Option<&[f64]>,
    ) -> Result<Option<(Bound<'py, PyAny>, i64)>> {
        if per_step.is_none() && ctrl.is_none() {
            return Ok(None);
        }
        let (py, nu) = (self.owner.mj.py, self.owner.info.nu);
        // a control row: [ctrl (nu)] then [xfrc_applied (6 nbody)], in
        // mjtState's order
        let (cw, fw) = (
            if ctrl.is_some() { nu } else { 0 },
            if per_step.is_some() {
                6 * self.nbody
            } else {
                0
            },
        );
        let width = cw + fw;
        let mut control = vec![0.0f64; n * nstep * width];
        for pos in 0..n {
            for j in 0..nstep {
                let row = (pos * nstep + j) * width;
                if let Some(c) = ctrl {
                    let from = (pos * nstep + j) * nu;
                    control[row..row + nu].copy_from_slice(&c[from..from + nu]);
                }
                if let Some(f) = per_step {
                    let at = row + cw + 6 * self.force_body;
                    control[at..at + 3].copy_from_slice(&f[pos * nstep + j]);
                }
            }
        }
        let arr = PyArray1::from_vec(py, control)
            .reshape([n, nstep, width])
            .internal()?;
        let bit = |name: &str| -> Result<i64> {
            self.owner
                .mj
                .module
                .getattr("mjtState")
                .and_then(|s| s.getattr(name))
                .and_then(|s| s.getattr("value"))
                .and_then(|v| v.extract())
                .internal()
        };
        let mut spec = 0i64;
        if ctrl.is_some() {
            spec |= bit("mjSTATE_CTRL")?;
        }
        if per_step.is_some() {
            spec |= bit("mjSTATE_XFRC_APPLIED")?;
        }
        Ok(Some((arr.into_any(), spec)))
    }

    /// Hands each simulation's recorded steps to `observe`, up to the step
    /// it warned or went non-finite at; returns those (position, step).
    fn observe_rollout(
        &mut self,
        out: &Bound<'py, PyAny>,
        ids: &[usize],
        nstep: usize,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<(usize, usize)>> {
        let (nq, nu) = (self.owner.info.nq, self.owner.info.nu);
        let qpos = out
            .get_item("qpos")
            .and_then(|a| a.cast_into::<PyArray3<f64>>().map_err(PyErr::from))
            .internal()?;
        let act = out
            .get_item("actuator_force")
            .and_then(|a| a.cast_into::<PyArray3<f64>>().map_err(PyErr::from))
            .internal()?;
        let warned = self.newly_warned(ids);
        let qpos = qpos.readonly();
        let act = act.readonly();
        let qs = qpos
            .as_slice()
            .map_err(|e| Error::Internal(e.to_string()))?;
        let acts = act.as_slice().map_err(|e| Error::Internal(e.to_string()))?;
        let mut diverged = Vec::new();
        for pos in 0..ids.len() {
            let rec = |j: usize| &qs[(pos * nstep + j) * nq..(pos * nstep + j + 1) * nq];
            // A warned simulation stopped stepping and repeats its last
            // record; the step that warned is the one before the repeats.
            let mut valid = nstep;
            if warned.contains(&pos) {
                let stop = (1..nstep).find(|&j| rec(j) == rec(j - 1)).unwrap_or(nstep);
                valid = stop.saturating_sub(1);
            }
            for j in 0..valid {
                let q = rec(j);
                if q.iter().any(|x| !x.is_finite()) {
                    valid = j;
                    break;
                }
                let a = &acts[(pos * nstep + j) * nu..(pos * nstep + j + 1) * nu];
                observe(pos, j, q, a);
            }
            if valid < nstep {
                diverged.push((pos, valid));
            }
        }
        Ok(diverged)
    }

    /// Total warnings so far, per simulation.
    fn warning_counts(&self) -> Vec<i64> {
        let w = self.warning.readonly();
        let w = w.as_array();
        (0..self.nsim)
            .map(|i| {
                w.slice(numpy::ndarray::s![i, .., 1])
                    .iter()
                    .map(|&c| c as i64)
                    .sum()
            })
            .collect()
    }

    /// Simulations among `ids` whose warning counts rose since the last call.
    fn newly_warned(&mut self, ids: &[usize]) -> Vec<usize> {
        let now = self.warning_counts();
        let mut out = Vec::new();
        for (pos, &sim) in ids.iter().enumerate() {
            if now[sim] > self.warned[sim] {
                out.push(pos);
            }
        }
        self.warned = now;
        out
    }

    fn ids_arg(&self, ids: &[usize]) -> Result<Bound<'py, PyAny>> {
        let py = self.owner.mj.py;
        if ids.len() == self.nsim {
            return Ok(py.None().into_bound(py));
        }
        let v: Vec<i32> = ids.iter().map(|&i| i as i32).collect();
        Ok(PyArray1::from_vec(py, v).into_any())
    }

    fn write_force(&self, rows: &mut [f64], sim: usize, f: [f64; 3]) {
        let at = sim * self.off.nstate + self.off.xfrc + 6 * self.force_body;
        rows[at..at + 3].copy_from_slice(&f);
        rows[at + 3..at + 6].fill(0.0);
    }
}

/// Where qpos, qvel, ctrl and xfrc_applied sit in a batch's state rows
/// (from its field views' addresses) and a row's length.
fn offsets(batch: &Bound<'_, PyAny>, state: &Bound<'_, PyArray2<f64>>) -> Result<Offsets> {
    let base_ptr = state.data() as usize;
    let offset_of = |field: &str| -> Result<usize> {
        let view = batch.call_method1("bind", (field,)).internal()?;
        let ptr: usize = view
            .getattr("__array_interface__")
            .and_then(|d| d.get_item("data"))
            .and_then(|d| d.get_item(0))
            .and_then(|p| p.extract())
            .internal()?;
        Ok((ptr - base_ptr) / std::mem::size_of::<f64>())
    };
    Ok(Offsets {
        qpos: offset_of("qpos")?,
        qvel: offset_of("qvel")?,
        ctrl: offset_of("ctrl")?,
        xfrc: offset_of("xfrc_applied")?,
        nstate: state.shape()[1],
    })
}

/// One model for every cell: each cell's gains, torque limits and friction
/// written into the batch's per-cell fields (`expand()`).
fn set_cell_fields(
    batch: &Bound<'_, PyAny>,
    cells: &[CellSetup],
    mode: Mode,
    info: &ModelInfo,
    colliding: &[usize],
) -> Result<()> {
    let gain = expand3(batch, "actuator_gainprm")?;
    let bias = expand3(batch, "actuator_biasprm")?;
    let range = expand3(batch, "actuator_forcerange")?;
    let friction = if cells.iter().any(|c| c.friction.is_some()) {
        Some(expand3(batch, "geom_friction")?)
    } else {
        None
    };
    let mut g = gain.readwrite();
    let mut b = bias.readwrite();
    let mut r = range.readwrite();
    let (mut g, mut b, mut r) = (g.as_array_mut(), b.as_array_mut(), r.as_array_mut());
    for (i, c) in cells.iter().enumerate() {
        let limits = c.torque_limits(info)?;
        for a in 0..info.nu {
            let (gp, bp) = actuator_params(mode, c, a);
            for j in 0..gp.len().min(g.shape()[2]) {
                g[[i, a, j]] = gp[j];
                b[[i, a, j]] = bp[j];
            }
            r[[i, a, 0]] = -limits[a];
            r[[i, a, 1]] = limits[a];
        }
    }
    if let Some(f) = friction {
        let mut f = f.readwrite();
        let mut f = f.as_array_mut();
        for (i, c) in cells.iter().enumerate() {
            if let Some(mu) = c.friction {
                for &gid in colliding {
                    f[[i, gid, 0]] = mu;
                }
            }
        }
    }
    Ok(())
}

/// Bodies differ: a model per distinct setting, shared by the cells that
/// have it (torque mode writes no gains into the model, so a lab's cells of
/// one body share one; fewer copies stay in cache).
fn cell_models<'py>(
    owner: &LoadedModel<'py>,
    cells: &[CellSetup],
    mode: Mode,
    dt: f64,
    colliding: &[usize],
) -> Result<Bound<'py, PyList>> {
    let (mj, info) = (&owner.mj, &owner.info);
    let layout = Physics::layout(owner);
    let prepare = |m: &Bound<'py, PyAny>| prepare_model(mj, m, mode, dt);
    let models = PyList::empty(mj.py);
    let mut made: Vec<(Vec<u64>, Bound<'py, PyAny>)> = Vec::new();
    // one scratch MjData for every mass edit's mj_setConst: the
    // models differ in values, not sizes (an MjData per model cost
    // seconds of page faults for 512 of them)
    let mut scratch: Option<Bound<'py, PyAny>> = None;
    for c in cells {
        let key = model_key(mode, c, info.nu);
        let m = match made.iter().find(|(k, _)| *k == key) {
            Some((_, m)) => m.clone(),
            None => {
                let m = prepare(&owner.variant(c.leg_scale, c.torso_mass_scale)?).internal()?;
                if !c.nominal_masses() {
                    let data = match &scratch {
                        Some(d) => d.clone(),
                        None => {
                            let d = mj.module.getattr("MjData").and_then(|f| f.call1((&m,)));
                            scratch.insert(d.internal()?).clone()
                        }
                    };
                    scale_masses(mj, &m, &data, layout.base.body, c).internal()?;
                }
                let limits = c.torque_limits(info)?;
                set_model_params(&m, mode, c, &limits, colliding).internal()?;
                made.push((key, m.clone()));
                m
            }
        };
        models.append(m).internal()?;
    }
    Ok(models)
}

/// The simulations a `mujoco.batch.SimulationError` names; any other
/// exception is an internal error.
fn failed_ids(py: Python<'_>, e: PyErr) -> Result<Vec<i64>> {
    e.value(py)
        .getattr("ids")
        .and_then(|i| i.call_method0("tolist"))
        .and_then(|i| i.extract())
        .map_err(|_| py_err(e))
}

/// What makes two cells' models differ: body and its masses, the gains
/// written into the actuators, torque limit, friction.
fn model_key(mode: Mode, c: &CellSetup, nu: usize) -> Vec<u64> {
    let opt = |v: Option<f64>| v.map_or(u64::MAX, f64::to_bits);
    let mut key = vec![
        c.leg_scale.to_bits(),
        c.torso_mass_scale.to_bits(),
        c.torso_mass_factor.to_bits(),
        c.leg_mass_factor.to_bits(),
        opt(c.max_torque),
        opt(c.friction),
    ];
    for a in 0..nu {
        let (gains, bias) = actuator_params(mode, c, a);
        key.extend(gains.iter().chain(&bias).map(|v| v.to_bits()));
    }
    key
}

fn expand3<'py>(batch: &Bound<'py, PyAny>, field: &str) -> Result<Bound<'py, PyArray3<f64>>> {
    batch
        .call_method1("expand", (field,))
        .and_then(|a| a.cast_into::<PyArray3<f64>>().map_err(PyErr::from))
        .internal()
}

fn set_model_params(
    m: &Bound<'_, PyAny>,
    mode: Mode,
    c: &CellSetup,
    limits: &[f64],
    colliding: &[usize],
) -> PyResult<()> {
    let g = m
        .getattr("actuator_gainprm")?
        .cast_into::<PyArray2<f64>>()?;
    let b = m
        .getattr("actuator_biasprm")?
        .cast_into::<PyArray2<f64>>()?;
    let r = m
        .getattr("actuator_forcerange")?
        .cast_into::<PyArray2<f64>>()?;
    let (mut g, mut b, mut r) = (g.readwrite(), b.readwrite(), r.readwrite());
    let (mut g, mut b, mut r) = (g.as_array_mut(), b.as_array_mut(), r.as_array_mut());
    for a in 0..g.shape()[0] {
        let (gp, bp) = actuator_params(mode, c, a);
        for j in 0..3 {
            g[[a, j]] = gp[j];
            b[[a, j]] = bp[j];
        }
        for j in 3..g.shape()[1] {
            g[[a, j]] = 0.0;
            b[[a, j]] = 0.0;
        }
        r[[a, 0]] = -limits[a];
        r[[a, 1]] = limits[a];
    }
    if let Some(mu) = c.friction {
        let f = m.getattr("geom_friction")?.cast_into::<PyArray2<f64>>()?;
        let mut f = f.readwrite();
        let mut f = f.as_array_mut();
        for &gid in colliding {
            f[[gid, 0]] = mu;
        }
    }
    Ok(())
}

impl SimBatch for MujocoBatch<'_, '_> {
    fn len(&self) -> usize {
        self.nsim
    }

    fn targets(&self, sim: usize) -> &[f64] {
        &self.targets[sim]
    }

    fn stance(&self, sim: usize) -> f64 {
        self.stance[sim]
    }

    fn qpos(&self, sim: usize) -> Result<Vec<f64>> {
        let s = self.state.readonly();
        let rows = s.as_slice().map_err(|e| Error::Internal(e.to_string()))?;
        let at = sim * self.off.nstate + self.off.qpos;
        Ok(rows[at..at + self.owner.info.nq].to_vec())
    }

    /// One `rollout` call of simulations `ids` for `nstep` steps: the
    /// base force constant or per step, and with `ctrl` each step's ctrl
    /// (servo targets that move), both as the rollout's control input.
    fn advance(
        &mut self,
        ids: &[usize],
        nstep: usize,
        force: Force<'_>,
        ctrl: Option<&[f64]>,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<(usize, usize)>> {
        let py = self.owner.mj.py;
        let kw = PyDict::new(py);
        let per_step = match force {
            Force::Constant(f) => {
                let mut s = self.state.readwrite();
                let rows = s
                    .as_slice_mut()
                    .map_err(|e| Error::Internal(e.to_string()))?;
                for (pos, &sim) in ids.iter().enumerate() {
                    self.write_force(rows, sim, f[pos]);
                }
                None
            }
            Force::PerStep(f) => Some(f),
        };
        if let Some((arr, spec)) = self.control_input(ids.len(), nstep, per_step, ctrl)? {
            kw.set_item("control", arr).internal()?;
            kw.set_item("control_spec", spec).internal()?;
        }
        kw.set_item("record", ("qpos", "actuator_force"))
            .internal()?;
        kw.set_item("ids", self.ids_arg(ids)?).internal()?;
        let out = match self.batch.call_method("rollout", (nstep,), Some(&kw)) {
            Ok(out) => out,
            Err(e) => {
                // MuJoCo raised in some simulations: they diverged at this call
                let failed = failed_ids(py, e)?;
                return Ok(ids
                    .iter()
                    .enumerate()
                    .filter(|(_, s)| failed.contains(&(**s as i64)))
                    .map(|(p, _)| (p, 0))
                    .collect());
            }
        };
        self.observe_rollout(&out, ids, nstep, observe)
    }

    fn step_controlled(
        &mut self,
        ids: &[usize],
        force: &[[f64; 3]],
        control: &mut Controller<'_>,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<usize>> {
        let (nq, nv, nu) = (self.owner.info.nq, self.owner.info.nv, self.owner.info.nu);
        let off = self.off;
        let mut ctrl = vec![0.0f64; nu];
        {
            let mut s = self.state.readwrite();
            let rows = s
                .as_slice_mut()
                .map_err(|e| Error::Internal(e.to_string()))?;
            for (pos, &sim) in ids.iter().enumerate() {
                let row = &rows[sim * off.nstate..(sim + 1) * off.nstate];
                control(
                    pos,
                    &row[off.qpos..off.qpos + nq],
                    &row[off.qvel..off.qvel + nv],
                    &mut ctrl,
                );
                let at = sim * off.nstate + off.ctrl;
                rows[at..at + nu].copy_from_slice(&ctrl);
                self.write_force(rows, sim, force[pos]);
            }
        }
        let ids_arg = self.ids_arg(ids)?;
        // MuJoCo raising in some simulations leaves them unstepped; the
        // others stepped, and are observed as usual (so a simulation's
        // samples never depend on which others share its call)
        let failed: Vec<usize> = match self.batch.call_method1("step", (ids_arg,)) {
            Ok(_) => Vec::new(),
            Err(e) => {
                let failed = failed_ids(self.owner.mj.py, e)?;
                ids.iter()
                    .enumerate()
                    .filter(|(_, s)| failed.contains(&(**s as i64)))
                    .map(|(p, _)| p)
                    .collect()
            }
        };
        let mut diverged = self.newly_warned(ids);
        for p in failed {
            if !diverged.contains(&p) {
                diverged.push(p);
            }
        }
        let s = self.state.readonly();
        let rows = s.as_slice().map_err(|e| Error::Internal(e.to_string()))?;
        for (pos, &sim) in ids.iter().enumerate() {
            if diverged.contains(&pos) {
                continue;
            }
            let q = &rows[sim * off.nstate + off.qpos..sim * off.nstate + off.qpos + nq];
            if q.iter().any(|x| !x.is_finite()) {
                diverged.push(pos);
                continue;
            }
            observe(pos, 0, q, &[]);
        }
        Ok(diverged)
    }
}
