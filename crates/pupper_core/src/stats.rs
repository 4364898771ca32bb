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

/// Streamed settle time: the time after `from` at which the series last was
/// outside `reference ± band`. `None` if it is still outside at the end.
#[derive(Debug, Clone)]
pub struct Settle {
    from: f64,
    band: f64,
    last_out: Option<f64>,
    out_now: bool,
    seen: bool,
}

impl Settle {
    pub fn new(from: f64, band: f64) -> Settle {
        Settle {
            from,
            band,
            last_out: None,
            out_now: false,
            seen: false,
        }
    }

    #[inline]
    pub fn push(&mut self, t: f64, z: f64, reference: f64) {
        if t < self.from {
            return;
        }
        self.seen = true;
        // NaN counts as outside
        use std::cmp::Ordering::{Equal, Less};
        self.out_now = !matches!(
            (z - reference).abs().partial_cmp(&self.band),
            Some(Less | Equal)
        );
        if self.out_now {
            self.last_out = Some(t);
        }
    }

    /// Seconds from `from` until the series stayed inside the band; `None`
    /// if it ends outside, or never reached `from`.
    pub fn value(&self) -> Option<f64> {
        if self.out_now || !self.seen {
            return None;
        }
        Some(self.last_out.map_or(0.0, |t| t - self.from))
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
    fn settle_time() {
        let mut s = Settle::new(2.0, 0.001);
        for (t, z) in [
            (1.0, 0.5),
            (2.1, 0.11),
            (2.5, 0.1195),
            (2.7, 0.12),
            (3.0, 0.1201),
        ] {
            s.push(t, z, 0.12);
        }
        assert!((s.value().unwrap() - 0.1).abs() < 1e-12);
        s.push(3.1, 0.2, 0.12);
        assert_eq!(s.value(), None);
        let mut never_left = Settle::new(0.0, 0.001);
        never_left.push(0.5, 0.12, 0.12);
        assert_eq!(never_left.value(), Some(0.0));
        // a run that ends before `from` has no settle time
        let mut short = Settle::new(2.0, 0.001);
        short.push(1.0, 0.12, 0.12);
        assert_eq!(short.value(), None);
    }
}
