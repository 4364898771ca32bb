//! Stepping `pupper fit`'s replay: every rollout of a Jacobian in one
//! `mujoco.batch.Batch`, one `step()` call per physics step on all cores,
//! the firmware between the steps in Rust
//! ([`pupper_core::sim::replay::Replay`]), each step's state rows read and
//! written in place (the batch's `state` array: its integration state,
//! ctrl in it).

use numpy::{PyArray2, PyArrayMethods};
use pyo3::prelude::*;

use super::python::PyResultExt;
use pupper_core::error::{Error, Result};
use pupper_core::sim::replay::Replay;

/// Where the replay reads and writes a state row: each actuator's angle,
/// velocity and ctrl column, and the columns of the state it records (the
/// full physics state, as `mj_getState` gives it).
pub struct RowLayout {
    pub qpos: Vec<usize>,
    pub qvel: Vec<usize>,
    pub ctrl: Vec<usize>,
    pub record: Vec<usize>,
}

/// What a replay recorded: each rollout's state after each step (rollout,
/// step, `record` column), and the torque its sensor reports at each step
/// (rollout, step, actuator).
pub struct Recorded {
    pub state: Vec<f64>,
    pub sensed: Vec<f64>,
}

/// Steps `batch` (its `rows`, `nb` rollouts, each holding its start) `n`
/// steps, the firmware `replay` turning each rollout's state and its log's
/// targets (`control`: rollout, sample, actuator) into its ctrl before
/// every step.
pub fn replay_steps<'py>(
    batch: &Bound<'py, PyAny>,
    rows: &Bound<'py, PyArray2<f64>>,
    layout: &RowLayout,
    control: &[f64],
    n: usize,
    replay: &mut Replay,
) -> Result<Recorded> {
    let nu = layout.ctrl.len();
    let (width, nb) = {
        let r = rows.readonly();
        let shape = r.as_array().shape().to_vec();
        (shape[1], shape[0])
    };
    if control.len() != nb * n * nu
        || layout.qpos.len() != nu
        || layout.qvel.len() != nu
        || layout
            .record
            .iter()
            .chain(&layout.ctrl)
            .any(|&c| c >= width)
    {
        return Err(Error::Internal(
            "replay: the control, the layout and the batch's rows disagree".into(),
        ));
    }
    let nrec = layout.record.len();
    let mut out = Recorded {
        state: vec![0.0; nb * n * nrec],
        sensed: vec![0.0; nb * n * nu],
    };
    let (mut q, mut v) = (vec![0.0; nb * nu], vec![0.0; nb * nu]);
    let (mut ctrl, mut sensed) = (vec![0.0; nb * nu], vec![0.0; nb * nu]);
    let target = |b: usize, i: usize, a: usize| control[(b * n + i) * nu + a];
    for k in 0..n {
        {
            let mut s = rows.readwrite();
            let all = s
                .as_slice_mut()
                .map_err(|e| Error::Internal(e.to_string()))?;
            for b in 0..nb {
                let row = &all[b * width..(b + 1) * width];
                for a in 0..nu {
                    q[b * nu + a] = row[layout.qpos[a]];
                    v[b * nu + a] = row[layout.qvel[a]];
                }
            }
            replay.step(k, &q, &v, &target, &mut ctrl, &mut sensed);
            for b in 0..nb {
                for a in 0..nu {
                    all[b * width + layout.ctrl[a]] = ctrl[b * nu + a];
                }
            }
        }
        batch.call_method0("step").internal()?;
        let s = rows.readonly();
        let all = s.as_slice().map_err(|e| Error::Internal(e.to_string()))?;
        for b in 0..nb {
            let row = &all[b * width..(b + 1) * width];
            let at = (b * n + k) * nrec;
            for (c, &col) in layout.record.iter().enumerate() {
                out.state[at + c] = row[col];
            }
            let at = (b * n + k) * nu;
            out.sensed[at..at + nu].copy_from_slice(&sensed[b * nu..(b + 1) * nu]);
        }
    }
    Ok(out)
}
