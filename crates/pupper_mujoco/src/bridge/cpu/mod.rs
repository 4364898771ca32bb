//! The CPU backend: every cell of a chunk in one `mujoco.batch.Batch`,
//! stepped on MuJoCo's C thread pool. State is read and written through the
//! batch's state rows, one contiguous `(nsim, nstate)` float64 array, so the
//! hot loop makes one borrow per step and copies nothing.

mod build;
mod step;

use numpy::{PyArray2, PyArray3};
use pyo3::prelude::*;

use super::model::LoadedModel;
use pupper_core::error::Result;
use pupper_core::robot::layout::Layout;
use pupper_core::robot::model::ModelInfo;
use pupper_core::sim::physics::{BatchStart, Physics, SimBatch};

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

    fn start(&self, b: &BatchStart<'_>) -> Result<Box<dyn SimBatch + '_>> {
        let batch = MujocoBatch::new(self, b.cells, b.mode, b.initial, b.threads)?;
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
