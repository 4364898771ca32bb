//! Stepping the CPU batch: open-loop rollouts between schedule events
//! (forces and moving targets as a control input), or one controlled step
//! at a time with the controller writing ctrl into the state rows; the
//! simulations MuJoCo warns about leave as diverged.

use numpy::{PyArray1, PyArray3, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::MujocoBatch;
use crate::bridge::python::{PyResultExt, py_err};
use pupper_core::error::{Error, Result};
use pupper_core::sim::physics::{Advance, Controlled, Controller, Force, Observer, SimBatch};

impl<'py> MujocoBatch<'_, 'py> {
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
    pub(super) fn warning_counts(&self) -> Vec<i64> {
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

/// The simulations a `mujoco.batch.SimulationError` names; any other
/// exception is an internal error.
fn failed_ids(py: Python<'_>, e: PyErr) -> Result<Vec<i64>> {
    e.value(py)
        .getattr("ids")
        .and_then(|i| i.call_method0("tolist"))
        .and_then(|i| i.extract())
        .map_err(|_| py_err(e))
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
        call: Advance<'_>,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<(usize, usize)>> {
        let (ids, nstep) = (call.ids, call.nstep);
        let py = self.owner.mj.py;
        let kw = PyDict::new(py);
        let per_step = match call.force {
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
        if let Some((arr, spec)) = self.control_input(ids.len(), nstep, per_step, call.ctrl)? {
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
        call: Controlled<'_>,
        control: &mut Controller<'_>,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<usize>> {
        let (ids, force) = (call.ids, call.force);
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
