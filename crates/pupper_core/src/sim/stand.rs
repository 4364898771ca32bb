//! The stand kind's probe: base height, tilt and tracking after every
//! step, into the metrics of [`crate::sim::metrics`].

use crate::math::quat;
use crate::sim::frames::FrameRecorder;
use crate::sim::metrics::{Recorder, Status};
use crate::sim::probe::{Finish, Probe, Sample};
use crate::sim::result::{CellResult, Replicate};

/// A standing robot's recorder.
pub struct StandProbe(Box<Recorder>);

impl StandProbe {
    pub fn new(r: Recorder) -> StandProbe {
        StandProbe(Box::new(r))
    }
}

impl Probe for StandProbe {
    fn observe(&mut self, s: &Sample<'_>) {
        let layout = s.layout;
        let (Some(zi), Some(qi)) = (layout.base.z(), layout.base.quat()) else {
            return;
        };
        let qpos = s.qpos;
        let z = qpos[zi];
        let tilt = quat::tilt([qpos[qi], qpos[qi + 1], qpos[qi + 2], qpos[qi + 3]]).to_degrees();
        let track: f64 = layout
            .act_qpos
            .iter()
            .zip(s.targets)
            .map(|(&i, &q)| (q - qpos[i]) * (q - qpos[i]))
            .sum();
        let nu = layout.nu;
        self.0.observe(z, tilt, track, nu, s.peak, s.nsat, nu);
    }

    fn fallen(&self) -> bool {
        self.0.fell()
    }

    fn diverge(&mut self, t: f64) {
        self.0.diverge(t);
    }

    /// Replicate 0 carries the cell's metrics, trace and frames; every
    /// replicate of a replicated run its own row.
    fn finish(self: Box<Self>, cell: &mut CellResult, done: Finish<'_>) {
        let (metrics, trace) = (*self.0).finish();
        debug_assert!(metrics.status != Status::Diverged || metrics.event_time.is_finite());
        if done.replicate == 0 {
            cell.metrics = metrics.clone();
            cell.trace = trace;
            cell.frames = done.frames.map(FrameRecorder::finish);
        }
        if !done.cfg.replicates.is_plain() {
            cell.replicates.push(Replicate {
                drawn: done.drawn,
                metrics,
                figures: Vec::new(),
            });
        }
    }
}
