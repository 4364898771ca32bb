//! The stand kind's probe: base height, tilt and tracking after every
//! step, into the metrics of [`crate::sim::metrics`].

use crate::math::quat;
use crate::sim::frames::FrameRecorder;
use crate::sim::metrics::{Recorder, Status};
use crate::sim::probe::{Finish, Probe, Sample, Start};
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

/// What a kind measures besides the stand kind's recorder (hold, walk):
/// its own figures, from the same samples.
pub trait Figures {
    /// A sample, after the stand's recorder has taken it.
    fn observe(&mut self, s: &Sample<'_>);
    /// The kind's figures, in the order of its tables' columns.
    fn figures(&self) -> Vec<f64>;
}

/// A kind's probe on the stand kind's: the recorder observes every step
/// first, decides falls and divergence and finishes the cell's metrics;
/// the kind's figures are the cell's (replicate 0's) and, in a replicated
/// run, each replicate's row's.
pub struct OnStand<K> {
    stand: StandProbe,
    kind: K,
}

impl<K: Figures> OnStand<K> {
    /// `kind` on a stand recorder of the simulation `s`.
    pub fn new(s: &Start<'_>, kind: K) -> OnStand<K> {
        OnStand {
            stand: StandProbe::new(Recorder::new(s.schedule, s.dt, s.stance)),
            kind,
        }
    }
}

impl<K: Figures> Probe for OnStand<K> {
    fn observe(&mut self, s: &Sample<'_>) {
        self.stand.observe(s);
        self.kind.observe(s);
    }

    fn fallen(&self) -> bool {
        self.stand.fallen()
    }

    fn diverge(&mut self, t: f64) {
        self.stand.diverge(t);
    }

    fn finish(self: Box<Self>, cell: &mut CellResult, done: Finish<'_>) {
        let figures = self.kind.figures();
        let replicated = !done.cfg.replicates.is_plain();
        if done.replicate == 0 {
            cell.figures = figures.clone();
        }
        Box::new(self.stand).finish(cell, done);
        if replicated && let Some(r) = cell.replicates.last_mut() {
            r.figures = figures;
        }
    }
}
