//! Per-cell metrics, streamed sample by sample so memory stays flat in the
//! number of steps (the optional trace aside).

use serde::{Deserialize, Serialize};

use crate::math::stats::{PushDip, Settle, Tail};
use crate::plan::schedule::Schedule;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Ok,
    /// Stood, but with its actuators at their torque limit in a share of
    /// actuator-steps of at least [`SATURATED`] (a chattering PD): never
    /// ranked best at the default `--max-saturation`.
    Saturated,
    /// Stood, with gains past the stability bound of the PD as the
    /// integrator computes it at the timestep on some joint: its numbers
    /// describe the integrator, not a robot, so it is never ranked.
    PastBound,
    Fell,
    Diverged,
}

/// The share of actuator-steps at the torque limit from which a cell that
/// stood is `saturated` (the ranking's default bound, `--max-saturation`).
pub const SATURATED: f64 = 0.05;

impl Status {
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Saturated => "saturated",
            Status::PastBound => "past_bound",
            Status::Fell => "fell",
            Status::Diverged => "diverged",
        }
    }

    /// True when the robot stayed up (ok, saturated or past the bound).
    pub fn stood(self) -> bool {
        matches!(self, Status::Ok | Status::Saturated | Status::PastBound)
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
    /// No measurement (every number NaN): a response run's cell, whose
    /// figures are its joints'.
    pub fn empty() -> Metrics {
        let nan = f64::NAN;
        Metrics {
            final_z: nan,
            last_1s_std_mm: nan,
            push_dip_mm: nan,
            settle_time_s: nan,
            max_tilt_deg: nan,
            peak_torque: nan,
            saturation_frac: nan,
            tracking_rms: nan,
            status: Status::Ok,
            event_time: nan,
        }
    }

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
    /// When the dip is known (NaN without a push): a run that ends sooner
    /// has no dip.
    dip_end: f64,
    /// Tilt and torque are taken from here on (post-step time, s).
    measure_from: f64,
    /// The last window counts only once it holds no sample of the landing.
    landing: f64,
    /// Samples after the landing.
    landed: usize,
    window: usize,
    /// Below this base height (m) at any moment the robot fell.
    fall_height: f64,
    /// Below this mean height (m) over the last window it collapsed.
    collapse_height: f64,
    /// When the base last went below `collapse_height` and stayed there.
    below_since: Option<f64>,
    fall_tilt: f64,
    /// Tilt (deg) over the last window: leaning past half the fall tilt on
    /// average there, the robot has tipped over onto its side.
    tilt_tail: Tail,
    /// When the tilt last went past half the fall tilt and stayed there.
    leaning_since: Option<f64>,
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
    /// A recorder for a robot whose stance height (the base height with its
    /// lowest foot on the floor, in its start pose) is `stance` m: falls are
    /// judged against it.
    pub fn new(schedule: &Schedule, dt: f64, stance: f64) -> Recorder {
        let dip_end = schedule.dip_end().unwrap_or(f64::NAN);
        let (dip, settle) = match &schedule.push {
            Some(p) => (
                Some(PushDip::new(p.start, p.start + p.duration)),
                Some(Settle::new(
                    p.start,
                    schedule.settle_fraction,
                    crate::plan::schedule::SETTLE_FLOOR,
                )),
            ),
            None => (None, None),
        };
        Recorder {
            dt,
            t: 0.0,
            tail: Tail::new(schedule.window_samples(dt)),
            dip,
            settle,
            dip_end,
            measure_from: schedule.measure_from(),
            landing: schedule.landing,
            landed: 0,
            window: schedule.window_samples(dt),
            fall_height: schedule.fall_fraction * stance,
            collapse_height: schedule.collapse_fraction * stance,
            below_since: None,
            fall_tilt: schedule.fall_tilt_deg,
            tilt_tail: Tail::new(schedule.window_samples(dt)),
            leaning_since: None,
            last_z: f64::NAN,
            max_tilt: f64::NAN,
            peak_torque: f64::NAN,
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
        if t > self.landing {
            self.landed += 1;
        }
        if let Some(d) = &mut self.dip {
            d.push(t, z);
        }
        if let Some(s) = &mut self.settle {
            s.push(t, z);
        }
        if t > self.measure_from {
            // f64::max takes the number over the NaN it starts from
            self.max_tilt = self.max_tilt.max(tilt_deg);
            self.peak_torque = self.peak_torque.max(peak_tau);
        }
        self.saturated += nsat as u64;
        self.actuator_steps += nu as u64;
        self.track_sq += track_sq;
        self.track_n += njoint as u64;
        if z < self.collapse_height {
            self.below_since.get_or_insert(t);
        } else {
            self.below_since = None;
        }
        self.tilt_tail.push(tilt_deg);
        if tilt_deg > 0.5 * self.fall_tilt {
            self.leaning_since.get_or_insert(t);
        } else {
            self.leaning_since = None;
        }
        if self.status == Status::Ok && (z < self.fall_height || tilt_deg > self.fall_tilt) {
            self.status = Status::Fell;
            self.event_time = t;
        }
        if self.trace_every > 0 && (self.samples - 1).is_multiple_of(self.trace_every) {
            self.trace.push((t, z));
        }
    }

    /// True once the robot has fallen (below the fall line or past the
    /// fall tilt at some moment).
    pub fn fell(&self) -> bool {
        self.status == Status::Fell
    }

    /// Marks the cell diverged at post-step time `t`.
    pub fn diverge(&mut self, t: f64) {
        self.status = Status::Diverged;
        self.event_time = t;
    }

    pub fn finish(mut self) -> (Metrics, Vec<(f64, f64)>) {
        // lying low at the end, legs folded under it: a fall, dated from
        // when it went below the line for good
        if self.status == Status::Ok && self.tail.mean() < self.collapse_height {
            self.status = Status::Fell;
            self.event_time = self.below_since.unwrap_or(self.t);
        }
        if self.status == Status::Ok && self.tilt_tail.mean() > 0.5 * self.fall_tilt {
            self.status = Status::Fell;
            self.event_time = self.leaning_since.unwrap_or(self.t);
        }
        let saturation = if self.actuator_steps == 0 {
            0.0
        } else {
            self.saturated as f64 / self.actuator_steps as f64
        };
        if self.status == Status::Ok && saturation >= SATURATED {
            self.status = Status::Saturated;
        }
        let diverged = self.status == Status::Diverged;
        let nan_if = |x: f64| if diverged { f64::NAN } else { x };
        // a window that holds part of the landing, a dip window the run
        // ends inside: not measured
        let std = if self.landed >= self.window {
            self.tail.std() * 1e3
        } else {
            f64::NAN
        };
        let dip_m = match &self.dip {
            Some(d) if self.t >= self.dip_end - 0.5 * self.dt => d.value(),
            _ => f64::NAN,
        };
        let dip = dip_m * 1e3;
        let settle = match &self.settle {
            Some(s) if dip_m.is_finite() => s
                .value(self.tail.mean(), dip_m, self.dt)
                .unwrap_or(f64::NAN),
            _ => f64::NAN,
        };
        let metrics = Metrics {
            final_z: nan_if(self.last_z),
            last_1s_std_mm: nan_if(std),
            push_dip_mm: nan_if(dip),
            settle_time_s: nan_if(settle),
            max_tilt_deg: nan_if(self.max_tilt),
            peak_torque: nan_if(self.peak_torque),
            saturation_frac: nan_if(saturation),
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

    /// A robot standing 0.13 m tall: falls below 3.9 cm, collapsed below 7.8.
    const STANCE: f64 = 0.13;

    #[test]
    fn steady_series() {
        let s = Schedule {
            duration: 4.0,
            ..Schedule::default()
        };
        let mut r = Recorder::new(&s, 0.002, STANCE);
        for k in 0..2000 {
            let t = (k + 1) as f64 * 0.002;
            // flat at 0.12 with a 5 mm dip right after the push starts
            let z = if (2.0..2.1).contains(&t) { 0.115 } else { 0.12 };
            r.observe(z, 1.0, 0.01 * 12.0, 12, 2.0, 3, 12);
        }
        let (m, trace) = r.finish();
        assert!(trace.is_empty());
        // 3 of 12 actuators at the limit every step: it stood, saturated
        assert_eq!(m.status, Status::Saturated);
        assert_eq!(m.final_z, 0.12);
        assert!(m.last_1s_std_mm < 1e-9);
        assert!((m.push_dip_mm - 5.0).abs() < 1e-9, "{}", m.push_dip_mm);
        // from the push's start until back within 2 % of the 5 mm dip: the
        // last sample of the dip is at 2.098 s
        assert!(
            (m.settle_time_s - 0.098).abs() < 1e-9,
            "{}",
            m.settle_time_s
        );
        assert_eq!(m.max_tilt_deg, 1.0);
        assert_eq!(m.peak_torque, 2.0);
        assert!((m.saturation_frac - 0.25).abs() < 1e-15);
        assert!((m.tracking_rms - 0.1).abs() < 1e-12);
    }

    #[test]
    fn the_landing_is_not_the_response_and_a_short_run_measures_only_what_it_can() {
        // a landing (tilt 17 deg, 3 N.m) in the first 0.3 s, then calm
        let record = |seconds: f64| {
            let s = Schedule {
                duration: seconds,
                ..Schedule::default()
            };
            let mut r = Recorder::new(&s, 0.002, STANCE);
            let n = (seconds / 0.002).round() as usize;
            for k in 0..n {
                let t = (k + 1) as f64 * 0.002;
                let (tilt, tau) = if t < 0.3 { (17.0, 3.0) } else { (2.0, 0.8) };
                r.observe(0.12, tilt, 0.0, 12, tau, 0, 12);
            }
            r.finish().0
        };
        let full = record(4.0);
        assert_eq!((full.max_tilt_deg, full.peak_torque), (2.0, 0.8));
        assert!(full.last_1s_std_mm.is_finite() && full.push_dip_mm.is_finite());
        // 0.3 s: no window after the landing, no dip, no calm
        let short = record(0.3);
        assert!(short.last_1s_std_mm.is_nan() && short.push_dip_mm.is_nan());
        assert!(short.max_tilt_deg.is_nan() && short.peak_torque.is_nan());
        assert!(short.settle_time_s.is_nan());
        assert_eq!(short.final_z, 0.12);
        // 2.1 s: a whole window after the landing, but the push (2 s) and
        // the 1.5 s after it are cut short
        let cut = record(2.1);
        assert!(cut.last_1s_std_mm.is_finite() && cut.push_dip_mm.is_nan());
        assert_eq!(cut.max_tilt_deg, 2.0);
        // the schedule says so, one line per metric family
        let s = |d: f64| Schedule {
            duration: d,
            ..Schedule::default()
        };
        assert_eq!(s(10.0).shortfalls(), Vec::<String>::new());
        assert_eq!(s(2.1).shortfalls().len(), 1);
        assert_eq!(s(0.5).shortfalls().len(), 3);
        assert!(s(0.5).shortfalls()[0].contains("--seconds 2 or more"));
    }

    #[test]
    fn fall_is_flagged_once() {
        let s = Schedule::default();
        let mut r = Recorder::new(&s, 0.5, STANCE);
        r.observe(0.12, 0.0, 0.0, 1, 0.0, 0, 1);
        r.observe(0.02, 0.0, 0.0, 1, 0.0, 0, 1);
        r.observe(0.01, 80.0, 0.0, 1, 0.0, 0, 1);
        let (m, _) = r.finish();
        assert_eq!(m.status, Status::Fell);
        assert_eq!(m.event_time, 1.0);
    }

    /// 3 s without a push, sampled every 10 ms: (base z, tilt) at each
    /// post-step time, for a robot `stance` m tall.
    fn three_seconds(stance: f64, sample: &dyn Fn(f64) -> (f64, f64)) -> Metrics {
        let s = Schedule {
            duration: 3.0,
            push: None,
            ..Schedule::default()
        };
        let mut r = Recorder::new(&s, 0.01, stance);
        for k in 0..300 {
            let (z, tilt) = sample((k + 1) as f64 * 0.01);
            r.observe(z, tilt, 0.0, 1, 0.0, 0, 1);
        }
        r.finish().0
    }

    #[test]
    fn falls_are_judged_against_the_robots_own_stance() {
        // the same 0.05 m is a fall for a robot 0.27 m tall, not for one
        // 0.13 m tall (0.3 x 0.27 = 0.081 m)
        let run = |stance: f64, z: &dyn Fn(f64) -> f64| three_seconds(stance, &|t| (z(t), 0.0));
        let low = |_: f64| 0.05;
        let (tall, short) = (run(0.27, &low), run(0.13, &low));
        assert_eq!(tall.status, Status::Fell);
        assert!((tall.event_time - 0.01).abs() < 1e-12);
        // 0.05 m for a 0.13 m robot: collapsed (below 0.6 x 0.13 on
        // average over the last second), dated from the first sample
        assert_eq!(short.status, Status::Fell);
        assert!((short.event_time - 0.01).abs() < 1e-12);
        // sinking to 0.142 m of 0.27 (legs folded, perfectly still) is a
        // collapse, dated from when it went below 0.162 m for good
        let sink = |t: f64| if t < 1.0 { 0.27 - 0.128 * t } else { 0.142 };
        let m = run(0.27, &sink);
        assert_eq!(m.status, Status::Fell, "{m:?}");
        assert!((m.event_time - 0.85).abs() < 0.011, "{}", m.event_time);
        // dipping below the line and standing back up is no collapse
        let dip = |t: f64| if (1.0..1.5).contains(&t) { 0.15 } else { 0.26 };
        assert_eq!(run(0.27, &dip).status, Status::Ok);
        // the line is the mean of the last window, not one sample
        let last = |t: f64| if t > 2.9 { 0.10 } else { 0.26 };
        assert_eq!(run(0.27, &last).status, Status::Ok);
    }

    #[test]
    fn ending_on_its_side_is_a_fall_a_passing_lean_is_not() {
        let run = |tilt: &dyn Fn(f64) -> f64| three_seconds(0.13, &|t| (0.12, tilt(t)));
        // tipping over to 38 degrees at 1.5 s and staying there
        let m = run(&|t| if t < 1.5 { 2.0 } else { 38.0 });
        assert_eq!(m.status, Status::Fell);
        assert!((m.event_time - 1.5).abs() < 0.011, "{}", m.event_time);
        // a 50-degree wobble that comes back up
        assert_eq!(
            run(&|t| if (1.0..1.3).contains(&t) { 50.0 } else { 3.0 }).status,
            Status::Ok
        );
    }

    #[test]
    fn trace_decimation() {
        let s = Schedule {
            trace_every: 10,
            ..Schedule::default()
        };
        let mut r = Recorder::new(&s, 0.002, STANCE);
        for _ in 0..25 {
            r.observe(0.1, 0.0, 0.0, 1, 0.0, 0, 1);
        }
        let (_, trace) = r.finish();
        assert_eq!(trace.len(), 3);
        assert!((trace[1].0 - 0.022).abs() < 1e-12);
    }
}
