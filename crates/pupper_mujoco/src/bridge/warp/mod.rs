//! The warp backend: a batch's simulations as worlds of MuJoCo Warp, on a
//! CUDA device or the CPU. One Warp model per body (cells that differ only
//! in gains, torque limit or friction share it, those are per world), one
//! world per simulation; the device side lives in `pupper_core._warp`.
//! Each `advance` runs on the device and hands back qpos and actuator
//! forces of every step in one block, which the same Rust recorders turn
//! into metrics as on the cpu backend. Torque mode runs its PD inside the
//! actuators (`plan::backend::ActuatorPd`), so no call crosses to the host
//! per step. Building the worlds is `worlds`; stepping them is here.

use numpy::{PyArray3, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

mod worlds;

use worlds::array3;

use super::model::LoadedModel;
use super::python::{PyResultExt, exception_name, python_message};
use pupper_core::error::{Error, Result};
use pupper_core::robot::layout::Layout;
use pupper_core::robot::model::ModelInfo;
use pupper_core::sim::physics::{
    Advance, BatchStart, Controlled, Controller, Force, Observer, Physics, SimBatch,
};

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

    fn start(&self, b: &BatchStart<'_>) -> Result<Box<dyn SimBatch + '_>> {
        Ok(Box::new(WarpBatch::new(self, b.cells, b.mode, b.initial)?))
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

/// The qpos and actuator-force records of one `Worlds.advance` call.
type Records<'py> = (Bound<'py, PyArray3<f32>>, Bound<'py, PyArray3<f32>>);

/// The records `out` of a call of `k` steps of `n` worlds (`[k, n]`),
/// checked to hold `nq` positions and `nu` forces per world and step.
fn records<'py>(
    out: &Bound<'py, PyAny>,
    [k, n]: [usize; 2],
    nq: usize,
    nu: usize,
) -> Result<Records<'py>> {
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
    Ok((q, a))
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
        call: Advance<'_>,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<(usize, usize)>> {
        let (nq, nu, nstep) = (self.nq, self.nu, call.nstep);
        let mut diverged = Vec::new();
        // where each simulation of the call sits: its position in ids
        let mut pos_of = vec![usize::MAX; self.place.len()];
        for (pos, &sim) in call.ids.iter().enumerate() {
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
                let table = force_table(py, &call.force, &members, n, nstep, start, k)?;
                let drive = match call.ctrl {
                    None => py.None().into_bound(py),
                    Some(ctrl) => self.drive(py, group, &pos_of, ctrl, nstep, start, k)?,
                };
                let out = group
                    .worlds
                    .call_method1("advance", (k, table, drive))
                    .map_err(|e| warp_err(py, e))?;
                let (q, a) = records(&out, [k, n], nq, nu)?;
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
        _call: Controlled<'_>,
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
