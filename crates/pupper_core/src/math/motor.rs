//! What a servo's firmware and its motor do between the PD law and the
//! joint, as pure functions with known answers: the encoder's
//! quantisation, a first-order low-pass filter on the derivative, and the
//! torque–speed limit of a DC motor (peak torque falling linearly to zero
//! at the no-load speed, as Isaac Lab's DC-motor actuator models it).

use std::f64::consts::TAU;

/// `q` read by an encoder of `counts` counts per revolution: rounded to
/// the nearest count.
#[inline]
pub fn quantize(q: f64, counts: u32) -> f64 {
    let step = TAU / counts as f64;
    (q / step).round() * step
}

/// The weight of a new sample in a first-order low-pass filter of cutoff
/// `cutoff_hz` updated every `period` seconds: the exact discretisation of
/// `dy/dt = 2π f (x - y)` with `x` held between samples.
#[inline]
pub fn lowpass_alpha(cutoff_hz: f64, period: f64) -> f64 {
    1.0 - (-TAU * cutoff_hz * period).exp()
}

/// The torque band a DC motor can deliver at joint speed `speed`: `peak`
/// at stall, falling linearly to zero at `noload` in the direction of
/// motion, while braking against the motion may use up to `peak`.
#[inline]
pub fn speed_band(peak: f64, noload: f64, speed: f64) -> (f64, f64) {
    let hi = (peak * (1.0 - speed / noload)).clamp(-peak, peak);
    let lo = (peak * (-1.0 - speed / noload)).clamp(-peak, peak);
    (lo, hi)
}

/// `tau` clipped into `band`, and whether the clip cut it.
#[inline]
pub fn clip(tau: f64, band: (f64, f64)) -> (f64, bool) {
    let clipped = tau.clamp(band.0, band.1);
    (clipped, tau < band.0 || tau > band.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantisation_rounds_to_the_nearest_count() {
        // 4096 counts: one count is 2π/4096 = 1.5339808e-3 rad
        let c = TAU / 4096.0;
        assert_eq!(quantize(0.0, 4096), 0.0);
        assert!((quantize(0.4 * c, 4096) - 0.0).abs() < 1e-15);
        assert!((quantize(0.6 * c, 4096) - c).abs() < 1e-15);
        assert!((quantize(-2.4 * c, 4096) + 2.0 * c).abs() < 1e-15);
        // 1 rad is 651.899 counts: 652 counts
        assert!((quantize(1.0, 4096) - 652.0 * c).abs() < 1e-12);
        // the error never exceeds half a count
        for i in 0..1000 {
            let q = -3.0 + 0.006_1 * i as f64;
            assert!((quantize(q, 16384) - q).abs() <= TAU / 16384.0 / 2.0 + 1e-15);
        }
    }

    #[test]
    fn lowpass_has_the_analytic_step_response() {
        // a unit step through the filter reaches 1 - exp(-2π f t)
        let (f, h) = (10.0, 0.002);
        let a = lowpass_alpha(f, h);
        let mut y = 0.0;
        for _ in 0..25 {
            y += a * (1.0 - y);
        }
        let t = 25.0 * h;
        assert!((y - (1.0 - (-TAU * f * t).exp())).abs() < 1e-12);
        // time constant: 1/(2π·10 Hz) = 15.9 ms reaches 63.2 %
        assert!((lowpass_alpha(1.0 / TAU, 1.0) - (1.0 - (-1.0f64).exp())).abs() < 1e-15);
    }

    #[test]
    fn torque_speed_limit_known_answers() {
        // 3 N·m peak, no-load 30 rad/s
        let (lo, hi) = speed_band(3.0, 30.0, 0.0);
        assert_eq!((lo, hi), (-3.0, 3.0));
        // half the no-load speed forwards: half the peak forwards, full braking
        let (lo, hi) = speed_band(3.0, 30.0, 15.0);
        assert!((hi - 1.5).abs() < 1e-15);
        assert_eq!(lo, -3.0);
        // backwards: mirrored
        let (lo, hi) = speed_band(3.0, 30.0, -15.0);
        assert!((lo + 1.5).abs() < 1e-15);
        assert_eq!(hi, 3.0);
        // at and past the no-load speed the motor cannot push forwards
        assert_eq!(speed_band(3.0, 30.0, 30.0).1, 0.0);
        let (lo, hi) = speed_band(3.0, 30.0, 45.0);
        assert!((hi + 1.5).abs() < 1e-15);
        assert_eq!(lo, -3.0);
        assert_eq!(clip(2.0, (-3.0, 1.5)), (1.5, true));
        assert_eq!(clip(1.5, (-3.0, 1.5)), (1.5, false));
        assert_eq!(clip(-2.0, (-3.0, 1.5)), (-2.0, false));
    }
}
