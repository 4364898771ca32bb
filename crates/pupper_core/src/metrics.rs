//! Per-cell metrics, streamed sample by sample so memory stays flat in the
//! number of steps (the optional trace aside).

use serde::{Deserialize, Serialize};

use crate::schedule::Schedule;
use crate::stats::{PushDip, Settle, Tail};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Ok,
    Fell,
    Diverged,
}

impl Status {
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Fell => "fell",
            Status::Diverged => "diverged",
        }
    }
}

/// The numbers a cell ends with. Lengths in the names' units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Last base height (m).
    pub final_z: f64,
    /// Std of base height over the last window (mm).
    pub last_1s_std_mm: f64,
    /// Push dip (mm), floored at 0; NaN without a push.
    pub push_dip_mm: f64,
    /// Seconds from push end until the base stays within the settle band of
    /// its pre-push height; NaN if it never does.
    pub settle_time_s: f64,
    /// Largest tilt of the base from upright (deg).
    pub max_tilt_deg: f64,
    /// Largest |actuator torque| (N·m).
    pub peak_torque: f64,
    /// Fraction of actuator-steps at the torque limit.
    pub saturation_frac: f64,
    /// RMS joint tracking error (rad).
    pub tracking_rms: f64,
    pub status: Status,
    /// Time (s) the cell fell or diverged; NaN if it did not.
    pub event_time: f64,
}

/// Names and units of the metric columns, in CSV order.
pub const METRIC_NAMES: [&str; 10] = [
    "final_z",
    "last_1s_std_mm",
    "push_dip_mm",
    "settle_time_s",
    "max_tilt_deg",
    "peak_torque",
    "saturation_frac",
    "tracking_rms",
    "status",
    "event_time",
];

impl Metrics {
    /// A numeric metric by name (`status` is not numeric).
    pub fn get(&self, name: &str) -> Option<f64> {
        Some(match name {
            "final_z" => self.final_z,
            "last_1s_std_mm" => self.last_1s_std_mm,
            "push_dip_mm" => self.push_dip_mm,
            "settle_time_s" => self.settle_time_s,
            "max_tilt_deg" => self.max_tilt_deg,
            "peak_torque" => self.peak_torque,
            "saturation_frac" => self.saturation_frac,
            "tracking_rms" => self.tracking_rms,
            "event_time" => self.event_time,
            _ => return None,
        })
    }
}

/// Accumulates one cell's samples. Feed it the state after each step.
#[derive(Debug, Clone)]
pub struct Recorder {
    dt: f64,
    /// Post-step time, accumulated like MuJoCo's.
    t: f64,
    tail: Tail,
    dip: Option<PushDip>,
    settle: Option<Settle>,
    push_end: f64,
    fall_height: f64,
    fall_tilt: f64,
    last_z: f64,
    max_tilt: f64,
    peak_torque: f64,
    saturated: u64,
    actuator_steps: u64,
    track_sq: f64,
    track_n: u64,
    status: Status,
    event_time: f64,
    trace_every: usize,
    samples: usize,
    trace: Vec<(f64, f64)>,
}

impl Recorder {
    pub fn new(schedule: &Schedule, dt: f64) -> Recorder {
        let (dip, settle, push_end) = match &schedule.push {
            Some(p) => (
                Some(PushDip::new(p.start, p.start + p.duration)),
                Some(Settle::new(p.start + p.duration, schedule.settle_band)),
                p.start + p.duration,
            ),
            None => (None, None, f64::NAN),
        };
        Recorder {
            dt,
            t: 0.0,
            tail: Tail::new(schedule.window_samples(dt)),
            dip,
            settle,
            push_end,
            fall_height: schedule.fall_height,
            fall_tilt: schedule.fall_tilt_deg,
            last_z: f64::NAN,
            max_tilt: 0.0,
            peak_torque: 0.0,
            saturated: 0,
            actuator_steps: 0,
            track_sq: 0.0,
            track_n: 0,
            status: Status::Ok,
            event_time: f64::NAN,
            trace_every: schedule.trace_every,
            samples: 0,
            trace: Vec::new(),
        }
    }

    /// One sample after a step: base height, tilt (deg), the sum of squared
    /// joint tracking errors over `njoint` joints, and the step's torques as
    /// (peak |tau|, number saturated, number of actuators).
    #[allow(clippy::too_many_arguments)]
    pub fn observe(
        &mut self,
        z: f64,
        tilt_deg: f64,
        track_sq: f64,
        njoint: usize,
        peak_tau: f64,
        nsat: usize,
        nu: usize,
    ) {
        self.t += self.dt;
        let t = self.t;
        self.samples += 1;
        self.last_z = z;
        self.tail.push(z);
        if let Some(d) = &mut self.dip {
            d.push(t, z);
            if let Some(s) = &mut self.settle {
                let r = d.reference();
                if t >= self.push_end && r.is_finite() {
                    s.push(t, z, r);
                }
            }
        }
        self.max_tilt = self.max_tilt.max(tilt_deg);
        self.peak_torque = self.peak_torque.max(peak_tau);
        self.saturated += nsat as u64;
        self.actuator_steps += nu as u64;
        self.track_sq += track_sq;
        self.track_n += njoint as u64;
        if self.status == Status::Ok && (z < self.fall_height || tilt_deg > self.fall_tilt) {
            self.status = Status::Fell;
            self.event_time = t;
        }
        if self.trace_every > 0 && (self.samples - 1).is_multiple_of(self.trace_every) {
            self.trace.push((t, z));
        }
    }

    /// Marks the cell diverged at post-step time `t`.
    pub fn diverge(&mut self, t: f64) {
        self.status = Status::Diverged;
        self.event_time = t;
    }

    pub fn finish(self) -> (Metrics, Vec<(f64, f64)>) {
        let diverged = self.status == Status::Diverged;
        let nan_if = |x: f64| if diverged { f64::NAN } else { x };
        let settle = self
            .settle
            .as_ref()
            .and_then(|s| s.value())
            .unwrap_or(f64::NAN);
        let metrics = Metrics {
            final_z: nan_if(self.last_z),
            last_1s_std_mm: nan_if(self.tail.std() * 1e3),
            push_dip_mm: nan_if(self.dip.as_ref().map_or(f64::NAN, |d| d.value() * 1e3)),
            settle_time_s: nan_if(settle),
            max_tilt_deg: nan_if(self.max_tilt),
            peak_torque: nan_if(self.peak_torque),
            saturation_frac: nan_if(if self.actuator_steps == 0 {
                0.0
            } else {
                self.saturated as f64 / self.actuator_steps as f64
            }),
            tracking_rms: nan_if(if self.track_n == 0 {
                f64::NAN
            } else {
                (self.track_sq / self.track_n as f64).sqrt()
            }),
            status: self.status,
            event_time: self.event_time,
        };
        (metrics, self.trace)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steady_series() {
        let s = Schedule {
            duration: 4.0,
            ..Schedule::default()
        };
        let mut r = Recorder::new(&s, 0.002);
        for k in 0..2000 {
            let t = (k + 1) as f64 * 0.002;
            // flat at 0.12 with a 5 mm dip right after the push starts
            let z = if (2.0..2.1).contains(&t) { 0.115 } else { 0.12 };
            r.observe(z, 1.0, 0.01 * 12.0, 12, 2.0, 3, 12);
        }
        let (m, trace) = r.finish();
        assert!(trace.is_empty());
        assert_eq!(m.status, Status::Ok);
        assert_eq!(m.final_z, 0.12);
        assert!(m.last_1s_std_mm < 1e-9);
        assert!((m.push_dip_mm - 5.0).abs() < 1e-9, "{}", m.push_dip_mm);
        assert_eq!(m.settle_time_s, 0.0);
        assert_eq!(m.max_tilt_deg, 1.0);
        assert_eq!(m.peak_torque, 2.0);
        assert!((m.saturation_frac - 0.25).abs() < 1e-15);
        assert!((m.tracking_rms - 0.1).abs() < 1e-12);
    }

    #[test]
    fn fall_is_flagged_once() {
        let s = Schedule::default();
        let mut r = Recorder::new(&s, 0.5);
        r.observe(0.12, 0.0, 0.0, 1, 0.0, 0, 1);
        r.observe(0.02, 0.0, 0.0, 1, 0.0, 0, 1);
        r.observe(0.01, 80.0, 0.0, 1, 0.0, 0, 1);
        let (m, _) = r.finish();
        assert_eq!(m.status, Status::Fell);
        assert_eq!(m.event_time, 1.0);
    }

    #[test]
    fn trace_decimation() {
        let s = Schedule {
            trace_every: 10,
            ..Schedule::default()
        };
        let mut r = Recorder::new(&s, 0.002);
        for _ in 0..25 {
            r.observe(0.1, 0.0, 0.0, 1, 0.0, 0, 1);
        }
        let (_, trace) = r.finish();
        assert_eq!(trace.len(), 3);
        assert!((trace[1].0 - 0.022).abs() < 1e-12);
    }
}
