//! Statistics on base-height series, whole or streamed.

use std::collections::VecDeque;

/// Keeps the last `n` values of a stream.
#[derive(Debug, Clone)]
pub struct Tail {
    cap: usize,
    buf: VecDeque<f64>,
}

impl Tail {
    pub fn new(n: usize) -> Tail {
        Tail {
            cap: n.max(1),
            buf: VecDeque::with_capacity(n.max(1)),
        }
    }

    pub fn push(&mut self, x: f64) {
        if self.buf.len() == self.cap {
            self.buf.pop_front();
        }
        self.buf.push_back(x);
    }

    /// Mean of what is held (NaN when empty).
    pub fn mean(&self) -> f64 {
        let (a, b) = self.buf.as_slices();
        if self.buf.is_empty() {
            return f64::NAN;
        }
        (a.iter().sum::<f64>() + b.iter().sum::<f64>()) / self.buf.len() as f64
    }

    /// Standard deviation of what is held (fewer than `n` if the stream was short).
    pub fn std(&self) -> f64 {
        let (a, b) = self.buf.as_slices();
        let n = self.buf.len() as f64;
        if n == 0.0 {
            return f64::NAN;
        }
        let m = (a.iter().sum::<f64>() + b.iter().sum::<f64>()) / n;
        let ss: f64 = self.buf.iter().map(|x| (x - m) * (x - m)).sum();
        (ss / n).sqrt()
    }
}

/// The arithmetic mean (NaN for no values).
pub fn mean(xs: &[f64]) -> f64 {
    if xs.is_empty() {
        return f64::NAN;
    }
    xs.iter().sum::<f64>() / xs.len() as f64
}

/// The `p`-quantile (0 <= p <= 1) of ascending `sorted` values, linear
/// between order statistics (NumPy's default, Hyndman & Fan type 7); NaN
/// for no values.
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    let n = sorted.len();
    if n == 0 {
        return f64::NAN;
    }
    let h = (n - 1) as f64 * p.clamp(0.0, 1.0);
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(n - 1);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

/// The chapter's push dip, streamed over (post-step time, z) samples: mean
/// z over `[push_start - 0.5, push_start)` minus the minimum over
/// `[push_start, push_end + 1.5)`, floored at 0.
#[derive(Debug, Clone)]
pub struct PushDip {
    start: f64,
    end: f64,
    pre_sum: f64,
    pre_n: usize,
    min: f64,
}

/// Seconds before the push over which the reference height is averaged.
pub const DIP_BEFORE: f64 = 0.5;
/// Seconds after the push end within which the minimum is sought.
pub const DIP_AFTER: f64 = 1.5;

impl PushDip {
    pub fn new(push_start: f64, push_end: f64) -> PushDip {
        PushDip {
            start: push_start,
            end: push_end,
            pre_sum: 0.0,
            pre_n: 0,
            min: f64::INFINITY,
        }
    }

    #[inline]
    pub fn push(&mut self, t: f64, z: f64) {
        if self.start - DIP_BEFORE <= t && t < self.start {
            self.pre_sum += z;
            self.pre_n += 1;
        } else if self.start <= t && t < self.end + DIP_AFTER && z < self.min {
            self.min = z;
        }
    }

    /// Mean height before the push, NaN if no sample fell there.
    pub fn reference(&self) -> f64 {
        if self.pre_n == 0 {
            f64::NAN
        } else {
            self.pre_sum / self.pre_n as f64
        }
    }

    /// The dip (m), floored at 0; NaN if either window had no sample.
    pub fn value(&self) -> f64 {
        let r = self.reference();
        if r.is_nan() || !self.min.is_finite() {
            return f64::NAN;
        }
        (r - self.min).max(0.0)
    }
}

/// Settling time after a push, by the step-response convention
/// (python-control's `step_info`, MATLAB's `stepinfo`): seconds from the
/// push's start until the base stays within a band of `fraction` x the dip
/// (at least `floor`, m) around its final height (the mean of the last
/// window: where it came to rest, which after feet slipped under the push
/// is not always where it stood before). The heights from the push on are
/// held as f32 offsets from the first of them (4 bytes a step) until both
/// are known.
#[derive(Debug, Clone)]
pub struct Settle {
    start: f64,
    fraction: f64,
    floor: f64,
    /// Post-step time of the first held sample.
    first: f64,
    origin: f64,
    held: Vec<f32>,
}

impl Settle {
    pub fn new(start: f64, fraction: f64, floor: f64) -> Settle {
        Settle {
            start,
            fraction,
            floor,
            first: f64::NAN,
            origin: f64::NAN,
            held: Vec::new(),
        }
    }

    /// A sample at post-step time `t`.
    #[inline]
    pub fn push(&mut self, t: f64, z: f64) {
        if t < self.start {
            return;
        }
        if self.held.is_empty() {
            self.first = t;
            self.origin = z;
        }
        self.held.push((z - self.origin) as f32);
    }

    /// Seconds from the push's start until the series stayed within the
    /// band around `final_z`, for a push that dipped `dip` m, with samples
    /// `dt` apart; `None` without samples, with a non-finite final height,
    /// or when the last sample is still outside the band.
    pub fn value(&self, final_z: f64, dip: f64, dt: f64) -> Option<f64> {
        let band = (self.fraction * dip).max(self.floor);
        if self.held.is_empty() || !final_z.is_finite() || !band.is_finite() {
            return None;
        }
        let target = final_z - self.origin;
        // NaN counts as outside
        use std::cmp::Ordering::{Equal, Less};
        let inside = |d: f32| {
            matches!(
                (d as f64 - target).abs().partial_cmp(&band),
                Some(Less | Equal)
            )
        };
        match self.held.iter().rposition(|&d| !inside(d)) {
            None => Some(0.0),
            Some(i) if i + 1 == self.held.len() => None,
            Some(i) => Some((self.first + i as f64 * dt - self.start).max(0.0)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Known answers (NumPy: np.percentile([1, 2, 3, 4, 10], [95, 5, 50]) =
    /// [8.8, 1.2, 3.0]).
    #[test]
    fn percentiles_interpolate_like_numpy() {
        let xs = [1.0, 2.0, 3.0, 4.0, 10.0];
        assert!((percentile(&xs, 0.95) - 8.8).abs() < 1e-12);
        assert!((percentile(&xs, 0.05) - 1.2).abs() < 1e-12);
        assert_eq!(percentile(&xs, 0.5), 3.0);
        assert_eq!(percentile(&xs, 1.0), 10.0);
        assert_eq!(percentile(&[7.0], 0.95), 7.0);
        assert!(percentile(&[], 0.5).is_nan());
        assert_eq!(mean(&xs), 4.0);
        assert!(mean(&[]).is_nan());
    }

    /// The streamed dip over (post-step time, z) samples.
    fn push_dip(times: &[f64], z: &[f64], push_start: f64, push_end: f64) -> f64 {
        let mut dip = PushDip::new(push_start, push_end);
        for (t, v) in times.iter().zip(z) {
            dip.push(*t, *v);
        }
        dip.value()
    }

    #[test]
    fn tail_std_known_answer() {
        // population std (numpy's ddof 0) of this textbook series is 2
        let mut t = Tail::new(8);
        for x in [2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0] {
            t.push(x);
        }
        assert_eq!(t.std(), 2.0);
    }

    #[test]
    fn tail_keeps_last_n() {
        let mut t = Tail::new(4);
        for x in [100.0, 1.0, 2.0, 3.0, 4.0] {
            t.push(x);
        }
        // std of 1,2,3,4 = sqrt(1.25)
        assert!((t.std() - 1.25f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn dip_on_hand_made_series() {
        // 0.1 s samples; flat 0.12 before, a dip to 0.1 at t = 2.3, back after.
        let times: Vec<f64> = (1..=60).map(|k| k as f64 * 0.1).collect();
        let z: Vec<f64> = times
            .iter()
            .map(|&t| if (t - 2.3).abs() < 1e-9 { 0.10 } else { 0.12 })
            .collect();
        let d = push_dip(&times, &z, 2.0, 2.25);
        assert!((d - 0.02).abs() < 1e-12, "{d}");
    }

    #[test]
    fn dip_ignores_minimum_outside_window() {
        // The minimum at t = 4.0 is after push end + 1.5 = 3.75.
        let times = [1.6, 1.9, 2.1, 4.0];
        let z = [0.12, 0.12, 0.119, 0.05];
        assert!((push_dip(&times, &z, 2.0, 2.25) - 0.001).abs() < 1e-12);
    }

    #[test]
    fn dip_floors_at_zero() {
        let times = [1.6, 2.1];
        let z = [0.12, 0.13];
        assert_eq!(push_dip(&times, &z, 2.0, 2.25), 0.0);
    }

    #[test]
    fn settle_time_is_from_the_push_within_a_band_of_the_dip_around_the_final_height() {
        // push at 2 s, samples 0.1 s apart; a 2 % band
        let settle = |zs: &[f64], final_z: f64, dip: f64| {
            let mut s = Settle::new(2.0, 0.02, 1e-6);
            s.push(1.9, 0.5); // before the push: ignored
            for (i, &z) in zs.iter().enumerate() {
                s.push(2.0 + 0.1 * i as f64, z);
            }
            s.value(final_z, dip, 0.1)
        };
        // dips 10 mm, comes back to rest 0.5 mm lower than it stood
        let zs = [0.12, 0.11, 0.1150, 0.1192, 0.1196, 0.1195, 0.1195];
        // band 0.2 mm around 0.1195: 0.1192 (at 2.3 s) is the last one out
        let v = settle(&zs, 0.1195, 0.01).unwrap();
        assert!((v - 0.3).abs() < 1e-6, "{v}");
        // a 1 mm dip: band 0.02 mm, 0.1196 (2.4 s) is out too
        let v = settle(&zs, 0.1195, 0.001).unwrap();
        assert!((v - 0.4).abs() < 1e-6, "{v}");
        // still out at the end: never settled
        assert_eq!(settle(&[0.12, 0.11, 0.13], 0.12, 0.01), None);
        // no dip: the floor is the band, and a still series settled at once
        assert_eq!(settle(&[0.12, 0.1200001], 0.12, 0.0), Some(0.0));
        // no sample from the push on, or no final height: none
        assert_eq!(Settle::new(2.0, 0.02, 1e-6).value(0.12, 0.01, 0.1), None);
        assert_eq!(settle(&zs, f64::NAN, 0.01), None);
    }
}
