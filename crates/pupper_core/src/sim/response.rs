//! What the response experiment measures: each excited joint's angle
//! against its target, sampled every step after the hold, reduced to the
//! step figures or the frequency response when the simulation ends.

use serde::{Deserialize, Serialize};

use crate::math::response::{self as resp, Bode};
use crate::plan::excitation::{Excitation, Signal};
use crate::sim::metrics::{SATURATED, Status};

/// Frequencies of a chirp's response, log-spaced over its band.
pub const CHIRP_POINTS: usize = 24;

/// One excited joint's figures; NaN where the signal has none (no rise
/// time for a sine, no bandwidth for a step).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointMetrics {
    pub rise_time_s: f64,
    pub settling_time_s: f64,
    pub overshoot_pct: f64,
    pub peak_time_s: f64,
    pub ss_error_rad: f64,
    pub ss_error_pct: f64,
    /// Gain (dB) and phase (deg) at the sine's frequency (sine only).
    pub gain_db: f64,
    pub phase_deg: f64,
    /// −3 dB bandwidth (Hz), the phase there (deg) and the resonance peak
    /// (dB above the low-frequency gain) (chirp).
    pub bandwidth_hz: f64,
    pub phase_at_bw_deg: f64,
    pub resonance_db: f64,
    /// Largest |torque| of the excited joint's actuator (N·m) and its share
    /// of steps at the limit, over the window after the hold.
    pub peak_torque: f64,
    pub saturation_frac: f64,
    /// The cell's gains on this joint against the explicit PD's stability
    /// bound at the timestep ([`crate::math::response::explicit_pd_margin`]):
    /// 1 or more is past it.
    pub stability_margin: f64,
    pub status: Status,
}

/// Column names of [`JointMetrics`], in CSV order.
pub const JOINT_METRIC_NAMES: [&str; 15] = [
    "rise_time_s",
    "settling_time_s",
    "overshoot_pct",
    "peak_time_s",
    "ss_error_rad",
    "ss_error_pct",
    "gain_db",
    "phase_deg",
    "bandwidth_hz",
    "phase_at_bw_deg",
    "resonance_db",
    "peak_torque",
    "saturation_frac",
    "stability_margin",
    "status",
];

impl JointMetrics {
    /// The numbers in the order of [`JOINT_METRIC_NAMES`] (status aside).
    pub fn values(&self) -> [f64; 14] {
        [
            self.rise_time_s,
            self.settling_time_s,
            self.overshoot_pct,
            self.peak_time_s,
            self.ss_error_rad,
            self.ss_error_pct,
            self.gain_db,
            self.phase_deg,
            self.bandwidth_hz,
            self.phase_at_bw_deg,
            self.resonance_db,
            self.peak_torque,
            self.saturation_frac,
            self.stability_margin,
        ]
    }
}

/// One excited joint of one replicate of a cell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointResult {
    /// The excited actuator, in ctrl order.
    pub actuator: usize,
    pub replicate: usize,
    pub metrics: JointMetrics,
    /// (seconds after the hold, angle) every `trace_every`-th step, when a
    /// trace was asked for.
    #[serde(default)]
    pub trace: Vec<(f64, f64)>,
    /// The frequency response (sine: one point; chirp: [`CHIRP_POINTS`]).
    pub bode: Vec<Bode>,
}

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
    pub fn new(
        actuator: usize,
        replicate: usize,
        qpos: usize,
        limit: f64,
        hold: f64,
        dt: f64,
    ) -> Self {
        JointProbe {
            actuator,
            replicate,
            qpos,
            limit,
            hold,
            dt,
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
