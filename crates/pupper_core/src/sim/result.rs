//! What a finished cell carries out of the runner: its metrics (or each
//! replicate's), its trace and frames, a response's joints, its cost.

use serde::{Deserialize, Serialize};

use crate::plan::grid::Cell;
use crate::sim::frames::Frames;
use crate::sim::joints::JointResult;
use crate::sim::metrics::{Metrics, Status};

/// One replicate of a cell: its drawn values (in the order of
/// [`crate::plan::randomize::Replicates::columns`]) and its metrics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Replicate {
    pub drawn: Vec<f64>,
    pub metrics: Metrics,
    /// The kind's own figures of this replicate, in the order its tables
    /// name them; empty for the kinds without any.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub figures: Vec<f64>,
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
    /// States at the frame rate, when the runner's `RunOptions::frame_rate` is set.
    pub frames: Option<Frames>,
    /// A response run's excited joints (by joint, then replicate); empty
    /// in a sweep.
    #[serde(default)]
    pub joints: Vec<JointResult>,
    /// The kind's own figures (a hold's sag, sway and torques), in the
    /// order its tables name them; empty for the kinds without any.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub figures: Vec<f64>,
    /// Steps its simulations took in all: the cell-steps it cost.
    #[serde(default)]
    pub steps: u64,
}

impl CellResult {
    /// Marks what lies past the stability bound (`margins`: each
    /// actuator's, see `plan::stability`): a robot that stood becomes
    /// `past_bound` (every replicate with it), and so does an excited joint
    /// whose own margin is 1 or more (`explicit`: the probe's margin, with
    /// each replicate's drawn gains, is the one to read; otherwise the
    /// joint's margin becomes `margins`' own).
    pub fn mark_past_bound(&mut self, margins: &[f64], explicit: bool) {
        let past = |s: &mut Status| {
            if matches!(*s, Status::Ok | Status::Saturated) {
                *s = Status::PastBound;
            }
        };
        if margins.iter().any(|&m| m >= 1.0) {
            past(&mut self.metrics.status);
            for r in &mut self.replicates {
                past(&mut r.metrics.status);
            }
        }
        for j in &mut self.joints {
            if !explicit {
                // the probe wrote the explicit margin: the joint's is this one
                j.metrics.stability_margin = margins.get(j.actuator).copied().unwrap_or(0.0);
            }
            if j.metrics.stability_margin >= 1.0 {
                past(&mut j.metrics.status);
            }
        }
    }
}
