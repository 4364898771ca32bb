//! A response run's figures per excited joint: what the response kind's
//! probe (`sim::response`) finishes into and its tables write.

use serde::{Deserialize, Serialize};

use crate::math::response::Bode;
use crate::sim::metrics::Status;

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
