//! The warp backend: a batch's simulations as worlds of MuJoCo Warp, on a
//! CUDA device or the CPU. One Warp model per body (cells that differ only
//! in gains, torque limit or friction share it, those are per world), one
//! world per simulation; the device side lives in `pupper_core._warp`.
//! Each `advance` runs on the device and hands back qpos and actuator
//! forces of every step in one block, which the same Rust recorders turn
//! into metrics as on the cpu backend. Torque mode runs its PD inside the
//! actuators ([`ActuatorPd`]), so no call crosses to the host per step.

use numpy::{PyArray1, PyArray3, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyList;

use super::model::LoadedModel;
use super::python::{PyResultExt, exception_name, python_message};
use super::setup::{
    StartStates, actuator_params, colliding_geoms, prepare_model, scale_body_masses,
};
use pupper_core::error::{Error, Result};
use pupper_core::plan::backend::ActuatorPd;
use pupper_core::plan::mode::Mode;
use pupper_core::plan::schedule::InitialState;
use pupper_core::plan::setup::CellSetup;
use pupper_core::robot::layout::Layout;
use pupper_core::robot::model::ModelInfo;
use pupper_core::sim::physics::{Controller, Force, Observer, Physics, SimBatch};

/// The device-side module of the package.
const MODULE: &str = "pupper_core._warp";

/// MuJoCo Warp on one device, over a loaded model.
pub struct WarpPhysics<'a, 'py> {
    owner: &'a LoadedModel<'py>,
    module: Bound<'py, PyModule>,
    device: String,
    most_worlds: usize,
}

/// A Python error of the device module as a one-line user error (Warp or
/// the device missing) or an internal one.
fn warp_err(py: Python<'_>, e: PyErr) -> Error {
    let kind = exception_name(py, &e);
    let msg = python_message(py, &e);
    if kind == "WarpUnavailable" {
        Error::Mujoco(msg)
    } else {
        Error::Internal(format!("warp backend: {kind}: {msg}"))
    }
}

impl<'a, 'py> WarpPhysics<'a, 'py> {
    /// Imports MuJoCo Warp and checks the device; fails with one line
    /// saying what to install or which devices there are.
    pub fn new(owner: &'a LoadedModel<'py>, device: &str) -> Result<Self> {
        let py = owner.mj.py;
        let module = PyModule::import(py, MODULE).map_err(|e| {
            Error::Mujoco(format!(
                "cannot import {MODULE} ({}): run `make setup` to install pupper's Python package",
                python_message(py, &e)
            ))
        })?;
        let most_worlds: usize = module
            .getattr("check")
            .and_then(|f| f.call1((device,)))
            .and_then(|n| n.extract())
            .map_err(|e| warp_err(py, e))?;
        Ok(WarpPhysics {
            owner,
            module,
            device: device.to_string(),
            most_worlds,
        })
    }
}

impl Physics for WarpPhysics<'_, '_> {
    fn info(&self) -> &ModelInfo {
        &self.owner.info
    }

    fn layout(&self) -> &Layout {
        Physics::layout(self.owner)
    }

    fn start(
        &self,
        cells: &[CellSetup],
        mode: Mode,
        initial: &InitialState,
        _threads: usize,
    ) -> Result<Box<dyn SimBatch + '_>> {
        Ok(Box::new(WarpBatch::new(self, cells, mode, initial)?))
    }

    fn batch_limit(&self) -> Option<usize> {
        Some(self.most_worlds)
    }
}

/// The worlds of one body.
struct Group<'py> {
    worlds: Bound<'py, PyAny>,
    /// The batch's simulation of each world.
    sims: Vec<usize>,
    /// Most steps per device call (the record buffer's rows).
    block: usize,
}

pub struct WarpBatch<'py> {
    groups: Vec<Group<'py>>,
    /// (group, world) of each simulation.
    place: Vec<(usize, usize)>,
    targets: Vec<Vec<f64>>,
    stance: Vec<f64>,
    nq: usize,
    nu: usize,
}

/// What decides a simulation's Warp model: its leg scale (geometry). Masses
/// and inertias are per world, like gains, torque limits and friction.
fn body_key(c: &CellSetup) -> u64 {
    c.leg_scale.to_bits()
}

/// What decides a world's masses: the body's torso scale and the draws.
fn mass_key(c: &CellSetup) -> [u64; 3] {
    [
        c.torso_mass_scale.to_bits(),
        c.torso_mass_factor.to_bits(),
        c.leg_mass_factor.to_bits(),
    ]
}

/// Actuator `a`'s first three gain and bias parameters on warp: servo mode
/// as on the cpu backend; torque mode the PD as an affine actuator.
fn world_params(mode: Mode, c: &CellSetup, a: usize) -> ([f64; 3], [f64; 3]) {
    match mode {
        Mode::Servo => actuator_params(mode, c, a),
        // the targets go in as ctrl; the limit is the force range
        Mode::Torque => {
            let pd = ActuatorPd::new(c.kp(a), c.kd(a), 0.0, f64::INFINITY);
            ([pd.gain, 0.0, 0.0], pd.bias)
        }
    }
}

fn array3<'py>(py: Python<'py>, v: Vec<f64>, shape: [usize; 3]) -> Result<Bound<'py, PyAny>> {
    PyArray1::from_vec(py, v)
        .reshape(shape)
        .map(Bound::into_any)
        .internal()
}

impl<'py> WarpBatch<'py> {
    fn new(
        physics: &WarpPhysics<'_, 'py>,
        cells: &[CellSetup],
        mode: Mode,
        initial: &InitialState,
    ) -> Result<Self> {
        let owner = physics.owner;
        let mj = &owner.mj;
        let py = mj.py;
        let info = &owner.info;
        let layout = Physics::layout(owner);
        let (nq, nu) = (info.nq, info.nu);
        let dt = cells[0].timestep.unwrap_or(info.timestep);
        let starts = StartStates::new(owner, cells, initial)?;
        let reset: Vec<f64> = match starts.keyframe {
            Some(k) => info.keyframes[k].qpos.clone(),
            None => info.qpos0.clone(),
        };
        // bodies in order of first appearance, each with its simulations
        let mut bodies: Vec<(u64, Vec<usize>)> = Vec::new();
        for (i, c) in cells.iter().enumerate() {
            let key = body_key(c);
            match bodies.iter_mut().find(|(k, _)| *k == key) {
                Some((_, sims)) => sims.push(i),
                None => bodies.push((key, vec![i])),
            }
        }
        let mut place = vec![(0, 0); cells.len()];
        let mut groups = Vec::with_capacity(bodies.len());
        let mut scratch: Option<Bound<'py, PyAny>> = None;
        for (g, (_, sims)) in bodies.into_iter().enumerate() {
            let first = &cells[sims[0]];
            let model =
                prepare_model(mj, &owner.variant(first.leg_scale, 1.0)?, mode, dt).internal()?;
            let per_world = group_masses(physics, &model, cells, &sims, &mut scratch)?;
            let colliding = colliding_geoms(&model).internal()?;
            let n = sims.len();
            let (mut qpos, mut ctrl) = (Vec::with_capacity(n * nq), Vec::with_capacity(n * nu));
            let (mut gain, mut bias) = (vec![0.0; n * nu * 3], vec![0.0; n * nu * 3]);
            let mut range = vec![0.0; n * nu * 2];
            let mut friction = Vec::with_capacity(n);
            for (w, &sim) in sims.iter().enumerate() {
                place[sim] = (g, w);
                let c = &cells[sim];
                let mut q = reset.clone();
                starts.qpos(owner, sim, &mut q);
                qpos.extend_from_slice(&q);
                // servo mode: the targets are the servos' ctrl; torque mode
                // on warp: the PD's targets, its actuators' ctrl
                ctrl.extend_from_slice(&starts.starts[sim].0);
                let limits = c.torque_limits(info)?;
                for a in 0..nu {
                    let (gp, bp) = world_params(mode, c, a);
                    let at = (w * nu + a) * 3;
                    gain[at..at + 3].copy_from_slice(&gp);
                    bias[at..at + 3].copy_from_slice(&bp);
                    range[(w * nu + a) * 2] = -limits[a];
                    range[(w * nu + a) * 2 + 1] = limits[a];
                }
                friction.push(c.friction);
            }
            let friction = world_friction(py, &model, &colliding, &friction)?;
            let args = (
                &model,
                &physics.device,
                starts.keyframe.map_or(-1, |k| k as i64),
                PyArray1::from_vec(py, qpos).reshape([n, nq]).internal()?,
                PyArray1::from_vec(py, ctrl).reshape([n, nu]).internal()?,
                array3(py, gain, [n, nu, 3])?,
                array3(py, bias, [n, nu, 3])?,
                array3(py, range, [n, nu, 2])?,
                friction,
                colliding,
                layout.base.body,
                per_world,
            );
            let worlds = physics
                .module
                .getattr("Worlds")
                .and_then(|w| w.call1(args))
                .map_err(|e| warp_err(py, e))?;
            let block: usize = worlds
                .getattr("block")
                .and_then(|b| b.extract())
                .internal()?;
            groups.push(Group {
                worlds,
                sims,
                block: block.max(1),
            });
        }
        Ok(WarpBatch {
            groups,
            place,
            stance: starts.stance,
            targets: starts.starts.into_iter().map(|(t, _)| t).collect(),
            nq,
            nu,
        })
    }
}

/// A body group's masses: one carried by the model itself, or several as
/// each mass's rows of the model and the index of every world's (what
/// MuJoCo derives from a mass is set per world).
fn group_masses<'py>(
    physics: &WarpPhysics<'_, 'py>,
    model: &Bound<'py, PyAny>,
    cells: &[CellSetup],
    sims: &[usize],
    scratch: &mut Option<Bound<'py, PyAny>>,
) -> Result<Bound<'py, PyAny>> {
    let owner = physics.owner;
    let (mj, py) = (&owner.mj, owner.mj.py);
    let layout = Physics::layout(owner);
    // the group's masses, in order of first appearance
    let mut masses: Vec<([u64; 3], usize)> = Vec::new();
    let mut mass_of = Vec::with_capacity(sims.len());
    for &sim in sims {
        let key = mass_key(&cells[sim]);
        let k = match masses.iter().position(|(m, _)| *m == key) {
            Some(k) => k,
            None => {
                masses.push((key, sim));
                masses.len() - 1
            }
        };
        mass_of.push(k);
    }
    let data = match scratch {
        Some(d) => d.clone(),
        None => {
            let d = mj.module.getattr("MjData").and_then(|f| f.call1((model,)));
            scratch.insert(d.internal()?).clone()
        }
    };
    // the torso scale first, then the draws: the products the cpu
    // backend forms (a scaled body, then its draws)
    let scaled = |m: &Bound<'py, PyAny>, c: &CellSetup| -> Result<()> {
        let base = layout.base.body;
        if c.torso_mass_scale != 1.0 {
            scale_body_masses(mj, m, &data, base, c.torso_mass_scale, 1.0).internal()?;
        }
        if !c.nominal_masses() {
            scale_body_masses(mj, m, &data, base, c.torso_mass_factor, c.leg_mass_factor)
                .internal()?;
        }
        Ok(())
    };
    // one mass: the model carries it; several: one model, its mass
    // and what MuJoCo derives from it per world
    Ok(if masses.len() == 1 {
        scaled(model, &cells[masses[0].1])?;
        py.None().into_bound(py)
    } else {
        let copy = PyModule::import(py, "copy")
            .and_then(|c| c.getattr("copy"))
            .internal()?;
        let rows_of = physics.module.getattr("mass_rows").internal()?;
        // each body's rows only: a population's models would not fit
        let mut bodies = Vec::with_capacity(masses.len());
        for &(_, sim) in &masses {
            let m = copy.call1((model,)).internal()?;
            scaled(&m, &cells[sim])?;
            bodies.push(rows_of.call1((&m,)).internal()?);
        }
        let bodies = PyList::new(py, bodies).internal()?;
        let index = PyArray1::from_vec(py, mass_of.iter().map(|&k| k as i64).collect());
        (bodies, index).into_pyobject(py).internal()?.into_any()
    })
}

/// Friction per world only when some cell sets it; the model's own value
/// stands in for the others.
fn world_friction<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyAny>,
    colliding: &[usize],
    friction: &[Option<f64>],
) -> Result<Bound<'py, PyAny>> {
    if !friction.iter().any(Option::is_some) {
        return Ok(py.None().into_bound(py));
    }
    let own: f64 = match colliding.first() {
        Some(&gid) => model
            .getattr("geom_friction")
            .and_then(|f| f.get_item((gid, 0)))
            .and_then(|v| v.extract())
            .internal()?,
        None => 1.0,
    };
    let v: Vec<f64> = friction.iter().map(|f| f.unwrap_or(own)).collect();
    Ok(PyArray1::from_vec(py, v).into_any())
}

/// The base force of each world for a piece of `k` steps from `start`:
/// one row for a constant force, a row per step otherwise; worlds that
/// left the call are pushed by nothing.
fn force_table<'py>(
    py: Python<'py>,
    force: &Force<'_>,
    members: &[(usize, usize)],
    n: usize,
    nstep: usize,
    start: usize,
    k: usize,
) -> Result<Bound<'py, PyAny>> {
    let rows = match force {
        Force::Constant(_) => 1,
        Force::PerStep(_) => k,
    };
    let mut table = vec![0.0f64; rows * n * 3];
    for &(w, pos) in members {
        for j in 0..rows {
            let f = match force {
                Force::Constant(f) => f[pos],
                Force::PerStep(f) => f[pos * nstep + start + j],
            };
            table[(j * n + w) * 3..(j * n + w) * 3 + 3].copy_from_slice(&f);
        }
    }
    array3(py, table, [rows, n, 3])
}

impl WarpBatch<'_> {
    /// Moving targets: every world's ctrl for each step of a piece of `k`
    /// steps from `start`; worlds outside the call hold their start targets.
    #[allow(clippy::too_many_arguments)]
    fn drive<'py>(
        &self,
        py: Python<'py>,
        group: &Group<'_>,
        pos_of: &[usize],
        ctrl: &[f64],
        nstep: usize,
        start: usize,
        k: usize,
    ) -> Result<Bound<'py, PyAny>> {
        let (n, nu) = (group.sims.len(), self.nu);
        let mut rows = vec![0.0f64; k * n * nu];
        for (w, &sim) in group.sims.iter().enumerate() {
            for j in 0..k {
                let at = (j * n + w) * nu;
                let from = match pos_of[sim] {
                    usize::MAX => &self.targets[sim][..],
                    pos => {
                        let s = (pos * nstep + start + j) * nu;
                        &ctrl[s..s + nu]
                    }
                };
                rows[at..at + nu].copy_from_slice(from);
            }
        }
        array3(py, rows, [k, n, nu])
    }
}

impl SimBatch for WarpBatch<'_> {
    fn len(&self) -> usize {
        self.place.len()
    }

    fn actuator_pd(&self) -> bool {
        true
    }

    fn targets(&self, sim: usize) -> &[f64] {
        &self.targets[sim]
    }

    fn stance(&self, sim: usize) -> f64 {
        self.stance[sim]
    }

    fn qpos(&self, sim: usize) -> Result<Vec<f64>> {
        let (g, w) = self.place[sim];
        let q = self.groups[g]
            .worlds
            .call_method0("qpos")
            .and_then(|a| a.cast_into::<numpy::PyArray2<f32>>().map_err(PyErr::from))
            .internal()?;
        let q = q.readonly();
        let q = q.as_array();
        Ok(q.row(w).iter().map(|&x| f64::from(x)).collect())
    }

    /// Steps `ids` for `nstep` steps; `ctrl`, when given, is each
    /// simulation's ctrl for every step (`nstep` rows of `nu`,
    /// simulation-major), written on the device before each step.
    fn advance(
        &mut self,
        ids: &[usize],
        nstep: usize,
        force: Force<'_>,
        ctrl: Option<&[f64]>,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<(usize, usize)>> {
        let (nq, nu) = (self.nq, self.nu);
        let mut diverged = Vec::new();
        // where each simulation of the call sits: its position in ids
        let mut pos_of = vec![usize::MAX; self.place.len()];
        for (pos, &sim) in ids.iter().enumerate() {
            pos_of[sim] = pos;
        }
        let (mut qbuf, mut abuf) = (vec![0.0f64; nq], vec![0.0f64; nu]);
        for group in &self.groups {
            // a body whose simulations all ended needs no more steps
            let members: Vec<(usize, usize)> = group
                .sims
                .iter()
                .enumerate()
                .filter(|(_, s)| pos_of[**s] != usize::MAX)
                .map(|(w, s)| (w, pos_of[*s]))
                .collect();
            if members.is_empty() {
                continue;
            }
            let n = group.sims.len();
            let py = group.worlds.py();
            // simulations that ended in an earlier piece of this call
            let mut ended = vec![false; members.len()];
            let mut start = 0;
            while start < nstep {
                let k = group.block.min(nstep - start);
                let table = force_table(py, &force, &members, n, nstep, start, k)?;
                let drive = match ctrl {
                    None => py.None().into_bound(py),
                    Some(ctrl) => self.drive(py, group, &pos_of, ctrl, nstep, start, k)?,
                };
                let out = group
                    .worlds
                    .call_method1("advance", (k, table, drive))
                    .map_err(|e| warp_err(py, e))?;
                let q = out
                    .get_item(0)
                    .and_then(|a| a.cast_into::<PyArray3<f32>>().map_err(PyErr::from))
                    .internal()?;
                let a = out
                    .get_item(1)
                    .and_then(|a| a.cast_into::<PyArray3<f32>>().map_err(PyErr::from))
                    .internal()?;
                if q.shape() != [k, n, nq] || a.shape() != [k, n, nu] {
                    return Err(Error::Internal(format!(
                        "warp records have shapes {:?} and {:?}, not ({k}, {n}, {nq}) and ({k}, {n}, {nu})",
                        q.shape(),
                        a.shape()
                    )));
                }
                let (q, a) = (q.readonly(), a.readonly());
                let qs = q.as_slice().map_err(|e| Error::Internal(e.to_string()))?;
                let acts = a.as_slice().map_err(|e| Error::Internal(e.to_string()))?;
                for (m, &(w, pos)) in members.iter().enumerate() {
                    if ended[m] {
                        continue;
                    }
                    for j in 0..k {
                        let row = &qs[(j * n + w) * nq..(j * n + w + 1) * nq];
                        // a diverged world's rows are NaN from that step on
                        if row.iter().any(|x| !x.is_finite()) {
                            ended[m] = true;
                            diverged.push((pos, start + j));
                            break;
                        }
                        for (d, &x) in qbuf.iter_mut().zip(row) {
                            *d = f64::from(x);
                        }
                        let arow = &acts[(j * n + w) * nu..(j * n + w + 1) * nu];
                        for (d, &x) in abuf.iter_mut().zip(arow) {
                            *d = f64::from(x);
                        }
                        observe(pos, start + j, &qbuf, &abuf);
                    }
                }
                start += k;
            }
        }
        Ok(diverged)
    }

    fn step_controlled(
        &mut self,
        _ids: &[usize],
        _force: &[[f64; 3]],
        _control: &mut Controller<'_>,
        _observe: &mut Observer<'_>,
    ) -> Result<Vec<usize>> {
        // actuator_pd() is true: the runner never steps a host PD here
        Err(Error::Internal(
            "the warp backend runs torque mode's PD in its actuators, not per step on the host"
                .into(),
        ))
    }
}
