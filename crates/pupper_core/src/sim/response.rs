//! What the response experiment measures: each excited joint's angle
//! against its target, sampled every step after the hold, reduced to the
//! step figures or the frequency response when the simulation ends.

use crate::math::response::{self as resp, Bode};
use crate::plan::response::{Excitation, Signal};
use crate::sim::metrics::{SATURATED, Status};

pub use crate::sim::joints::{CHIRP_POINTS, JOINT_METRIC_NAMES, JointMetrics, JointResult};

/// Samples of one excited joint.
pub struct JointProbe {
    actuator: usize,
    replicate: usize,
    /// qpos address of its joint.
    qpos: usize,
    limit: f64,
    hold: f64,
    dt: f64,
    t: Vec<f64>,
    y: Vec<f64>,
    peak: f64,
    nsat: usize,
    diverged: bool,
}

impl JointProbe {
    /// The probe of actuator `a` excited in the simulation starting at `s`,
    /// its signal after `hold` s.
    pub fn new(s: &crate::sim::probe::Start<'_>, a: usize, hold: f64) -> Self {
        JointProbe {
            actuator: a,
            replicate: s.replicate,
            qpos: s.layout.act_qpos[a],
            limit: s.limits[a],
            hold,
            dt: s.dt,
            t: Vec::new(),
            y: Vec::new(),
            peak: 0.0,
            nsat: 0,
            diverged: false,
        }
    }

    /// The excited actuator.
    pub fn actuator(&self) -> usize {
        self.actuator
    }

    /// The state after a step that ended at `t`; `force` the actuator's.
    pub fn observe(&mut self, t: f64, qpos: &[f64], force: f64) {
        // the first sample kept is the angle when the signal starts
        if t < self.hold - 0.5 * self.dt {
            return;
        }
        self.t.push(t);
        self.y.push(qpos[self.qpos]);
        if self.t.len() > 1 {
            self.peak = self.peak.max(force.abs());
            if force.abs() >= self.limit * (1.0 - 1e-12) {
                self.nsat += 1;
            }
        }
    }

    pub fn diverge(&mut self) {
        self.diverged = true;
    }

    /// The signal's figures in `m` from the excited joint's angle: a
    /// step's rise and settling, a sine's gain and phase, a chirp's
    /// bandwidth; the Bode points a sine or a chirp gives.
    fn measure(&self, ex: &Excitation, duration: f64, m: &mut JointMetrics) -> Vec<Bode> {
        let mut bode = Vec::new();
        let t0 = self.t[0];
        let s: Vec<f64> = self.t.iter().map(|t| t - t0).collect();
        let amplitude = ex.signal.amplitude();
        match ex.signal {
            Signal::Step { .. } => {
                let i = resp::step_info(&s, &self.y, amplitude);
                m.rise_time_s = i.rise_time;
                m.settling_time_s = i.settling_time;
                m.overshoot_pct = i.overshoot_pct;
                m.peak_time_s = i.peak_time;
                m.ss_error_rad = i.ss_error;
                m.ss_error_pct = i.ss_error_pct;
            }
            Signal::Sine { hz, .. } => {
                // the second half of the window: past the start's transient
                let from = s.len() / 2;
                let phase: Vec<f64> = s[from..]
                    .iter()
                    .map(|t| 2.0 * std::f64::consts::PI * hz * t)
                    .collect();
                let (g, p) = resp::sine_fit(&phase, &self.y[from..], amplitude);
                m.gain_db = 20.0 * g.log10();
                m.phase_deg = p.to_degrees();
                bode.push(Bode {
                    hz,
                    gain_db: m.gain_db,
                    phase_deg: m.phase_deg,
                });
            }
            Signal::Chirp { f0, f1, .. } => {
                let window = ex.window(duration);
                let band = (f0, f1, window);
                bode = resp::chirp_response(&s, &self.y, amplitude, band, CHIRP_POINTS);
                let (bw, ph, peak) = resp::chirp_bandwidth(&s, &self.y, amplitude, band, &bode);
                m.bandwidth_hz = bw;
                m.phase_at_bw_deg = ph;
                m.resonance_db = peak;
            }
        }
        bode
    }

    pub fn finish(self, ex: &Excitation, duration: f64, trace_every: usize) -> JointResult {
        let nan = f64::NAN;
        let mut m = JointMetrics {
            rise_time_s: nan,
            settling_time_s: nan,
            overshoot_pct: nan,
            peak_time_s: nan,
            ss_error_rad: nan,
            ss_error_pct: nan,
            gain_db: nan,
            phase_deg: nan,
            bandwidth_hz: nan,
            phase_at_bw_deg: nan,
            resonance_db: nan,
            peak_torque: self.peak,
            saturation_frac: self.nsat as f64 / (self.t.len().max(2) - 1) as f64,
            stability_margin: nan,
            status: Status::Ok,
        };
        let mut bode = Vec::new();
        if self.diverged || self.t.len() < 10 {
            m.status = Status::Diverged;
        } else {
            bode = self.measure(ex, duration, &mut m);
            if m.saturation_frac >= SATURATED {
                m.status = Status::Saturated;
            }
        }
        let t0 = self.t.first().copied().unwrap_or(0.0);
        let trace = match trace_every {
            0 => Vec::new(),
            k => self
                .t
                .iter()
                .zip(&self.y)
                .step_by(k)
                .map(|(t, y)| (t - t0, *y))
                .collect(),
        };
        JointResult {
            actuator: self.actuator,
            replicate: self.replicate,
            metrics: m,
            trace,
            bode,
        }
    }
}
/// The response kind's probe: the excited joint's angle after each step,
/// its figures (with the cell's stability margin on it) added to the cell.
impl crate::sim::probe::Probe for JointProbe {
    fn observe(&mut self, s: &crate::sim::probe::Sample<'_>) {
        JointProbe::observe(
            self,
            s.t,
            s.qpos,
            s.act.get(self.actuator).copied().unwrap_or(0.0),
        );
    }

    fn diverge(&mut self, _t: f64) {
        JointProbe::diverge(self);
    }

    fn finish(
        self: Box<Self>,
        cell: &mut crate::sim::result::CellResult,
        done: crate::sim::probe::Finish<'_>,
    ) {
        let (cfg, setup) = (done.cfg, done.setup);
        if let Some(e) = cfg.experiment.excitation() {
            let a = self.actuator;
            let mut joint = (*self).finish(e, cfg.schedule.duration, cfg.schedule.trace_every);
            joint.metrics.stability_margin = crate::math::response::explicit_pd_margin(
                e.inertia_of(a),
                setup.gain(a) * setup.kp(a),
                setup.gain(a) * setup.kd(a),
                done.dt,
            );
            cell.joints.push(joint);
        }
        if done.replicate == 0 && cell.frames.is_none() {
            cell.frames = done.frames.map(crate::sim::frames::FrameRecorder::finish);
        }
    }
}
