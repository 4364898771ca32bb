//! How a joint follows its target: step-response figures (the conventions
//! of python-control's `step_info` and MATLAB's `stepinfo`), gain and phase
//! of a sinusoid, the frequency response along a chirp, and what a
//! second-order system and an explicitly integrated PD predict.
//!
//! Conventions, for a step of size `A` from `y0` (the angle when the step
//! is commanded) with final value `yf` (mean over the last tenth of the
//! window) and change `D = yf - y0`:
//! - rise time: from the first crossing of `y0 + 0.1 D` to the first of
//!   `y0 + 0.9 D`;
//! - settling time: from the step to the last moment `|y - yf|` exceeds
//!   2 % of `|D|` (NaN if it still does in the last tenth: never settled);
//! - overshoot: the largest excursion past `yf` in the step's direction,
//!   in % of `|D|` (0 if none);
//! - peak time: when that largest excursion (or, without overshoot, the
//!   largest value in the step's direction) happens;
//! - steady-state error: `y0 + A - yf` in rad and in % of `|A|`.
//!
//! Times are measured from the step. Samples are `(t, y)` with `t`
//! increasing.

use std::f64::consts::PI;

/// Step-response figures; NaN where a figure does not exist.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepInfo {
    pub rise_time: f64,
    pub settling_time: f64,
    pub overshoot_pct: f64,
    pub peak_time: f64,
    pub ss_error: f64,
    pub ss_error_pct: f64,
}

/// The settling band, as a fraction of the change.
pub const SETTLING_BAND: f64 = 0.02;
/// The share of the window, at its end, whose mean is the final value.
pub const FINAL_SHARE: f64 = 0.1;

/// Linear interpolation of the first time `y` crosses `level` going in
/// `sign`'s direction.
fn first_crossing(t: &[f64], y: &[f64], level: f64, sign: f64) -> f64 {
    for i in 0..y.len() {
        if sign * (y[i] - level) >= 0.0 {
            if i == 0 {
                return t[0];
            }
            let (a, b) = (y[i - 1] - level, y[i] - level);
            let f = if a == b { 1.0 } else { a / (a - b) };
            return t[i - 1] + f * (t[i] - t[i - 1]);
        }
    }
    f64::NAN
}

/// The figures of a step of size `amplitude` commanded at `t[0]`, from the
/// samples `(t, y)` (y[0]: the angle when the step is commanded).
pub fn step_info(t: &[f64], y: &[f64], amplitude: f64) -> StepInfo {
    let nan = StepInfo {
        rise_time: f64::NAN,
        settling_time: f64::NAN,
        overshoot_pct: f64::NAN,
        peak_time: f64::NAN,
        ss_error: f64::NAN,
        ss_error_pct: f64::NAN,
    };
    let n = t.len().min(y.len());
    if n < 10 || y[..n].iter().any(|v| !v.is_finite()) {
        return nan;
    }
    let (t, y) = (&t[..n], &y[..n]);
    let t0 = t[0];
    let tail = ((n as f64 * FINAL_SHARE).ceil() as usize).clamp(1, n);
    let yf = y[n - tail..].iter().sum::<f64>() / tail as f64;
    let y0 = y[0];
    let d = yf - y0;
    let ss_error = y0 + amplitude - yf;
    let ss_error_pct = 100.0 * ss_error / amplitude.abs();
    if d == 0.0 {
        return StepInfo {
            ss_error,
            ss_error_pct,
            ..nan
        };
    }
    let sign = d.signum();
    let rise = first_crossing(t, y, y0 + 0.9 * d, sign) - first_crossing(t, y, y0 + 0.1 * d, sign);
    let band = SETTLING_BAND * d.abs();
    let last_out = (0..n).rev().find(|&i| (y[i] - yf).abs() > band);
    let settling_time = match last_out {
        None => 0.0,
        Some(i) if i >= n - tail => f64::NAN,
        Some(i) => t[i + 1] - t0,
    };
    let (peak_i, peak) = y
        .iter()
        .enumerate()
        .map(|(i, v)| (i, sign * v))
        .fold((0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
    let over = (peak - sign * yf).max(0.0) / d.abs();
    StepInfo {
        rise_time: rise,
        settling_time,
        overshoot_pct: 100.0 * over,
        peak_time: t[peak_i] - t0,
        ss_error,
        ss_error_pct,
    }
}

/// Gain (ratio) and phase (rad, negative = lag) of `y` against the input
/// `amplitude * sin(phase(t))`, by least squares of `y` on
/// `sin(phase)`, `cos(phase)` and a constant over the samples given.
pub fn sine_fit(phase: &[f64], y: &[f64], amplitude: f64) -> (f64, f64) {
    // normal equations of [sin, cos, 1]
    let mut m = nalgebra::Matrix3::<f64>::zeros();
    let mut r = nalgebra::Vector3::<f64>::zeros();
    for (&p, &v) in phase.iter().zip(y) {
        let b = nalgebra::Vector3::new(p.sin(), p.cos(), 1.0);
        m += b * b.transpose();
        r += b * v;
    }
    let Some(x) = m.lu().solve(&r) else {
        return (f64::NAN, f64::NAN);
    };
    // y ~ a sin(p) + b cos(p) = |.| sin(p + atan2(b, a))
    let (a, b) = (x[0], x[1]);
    ((a * a + b * b).sqrt() / amplitude.abs(), b.atan2(a))
}

/// A logarithmic chirp from `f0` to `f1` Hz over `duration` s: its phase
/// (rad) and instantaneous frequency (Hz) at `t` s from its start.
pub fn chirp(f0: f64, f1: f64, duration: f64, t: f64) -> (f64, f64) {
    if (f1 - f0).abs() < 1e-12 {
        return (2.0 * PI * f0 * t, f0);
    }
    let k = (f1 / f0).ln() / duration;
    let f = f0 * (k * t).exp();
    (2.0 * PI * f0 * ((k * t).exp() - 1.0) / k, f)
}

/// One point of a frequency response.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Bode {
    pub hz: f64,
    pub gain_db: f64,
    pub phase_deg: f64,
}

/// The empirical transfer function of `y` against the chirp input
/// `amplitude * sin(phase(t))` at `hz`: the ratio of their Fourier sums
/// over the whole window (`y` less its value when the chirp starts).
fn etfe(t: &[f64], y: &[f64], amplitude: f64, band: (f64, f64, f64), hz: f64) -> (f64, f64) {
    let (f0, f1, duration) = band;
    let w = 2.0 * PI * hz;
    let y0 = y.first().copied().unwrap_or(0.0);
    let (mut ur, mut ui, mut yr, mut yi) = (0.0, 0.0, 0.0, 0.0);
    for (&ti, &yv) in t.iter().zip(y) {
        let u = amplitude * chirp(f0, f1, duration, ti).0.sin();
        let (c, s) = ((w * ti).cos(), (w * ti).sin());
        ur += u * c;
        ui -= u * s;
        yr += (yv - y0) * c;
        yi -= (yv - y0) * s;
    }
    // H = Y / U
    let d = ur * ur + ui * ui;
    let (hr, hi) = ((yr * ur + yi * ui) / d, (yi * ur - yr * ui) / d);
    ((hr * hr + hi * hi).sqrt(), hi.atan2(hr))
}

/// The frequency response along a chirp from `f0` to `f1` Hz over
/// `duration` s, at `points` log-spaced frequencies inside the band: the
/// empirical transfer function (the output's Fourier sum over the input's)
/// at each. Phases are unwrapped from 0 downwards.
pub fn chirp_response(
    t: &[f64],
    y: &[f64],
    amplitude: f64,
    band: (f64, f64, f64),
    points: usize,
) -> Vec<Bode> {
    let (f0, f1, _) = band;
    let span = (f1 / f0).ln();
    let mut out: Vec<Bode> = Vec::with_capacity(points);
    let mut prev = 0.0f64;
    for i in 0..points {
        // inside the band: its edges hold half the input's energy
        let hz = f0 * (span * (i as f64 + 0.5) / points as f64).exp();
        let (g, p) = etfe(t, y, amplitude, band, hz);
        let mut deg = p.to_degrees();
        while deg - prev > 180.0 {
            deg -= 360.0;
        }
        while deg - prev < -180.0 {
            deg += 360.0;
        }
        prev = deg;
        out.push(Bode {
            hz,
            gain_db: 20.0 * g.log10(),
            phase_deg: deg,
        });
    }
    out
}

/// The −3 dB bandwidth along a chirp, refined between the points of
/// `coarse` (from [`chirp_response`]) that bracket it by bisection in log
/// frequency on the empirical transfer function; with the phase there and
/// the resonance peak (see [`bandwidth`]).
pub fn chirp_bandwidth(
    t: &[f64],
    y: &[f64],
    amplitude: f64,
    band: (f64, f64, f64),
    coarse: &[Bode],
) -> (f64, f64, f64) {
    let (hz, phase, peak) = bandwidth(coarse);
    let Some(first) = coarse.iter().find(|b| b.gain_db.is_finite()) else {
        return (hz, phase, peak);
    };
    let gain_at = |f: f64| 20.0 * etfe(t, y, amplitude, band, f).0.log10();
    // the resonance peak, refined between the coarse points beside the largest
    let top = (0..coarse.len())
        .max_by(|&i, &j| coarse[i].gain_db.total_cmp(&coarse[j].gain_db))
        .unwrap_or(0);
    let peak = if peak > 0.0 && top > 0 && top + 1 < coarse.len() {
        // golden-section search in log frequency
        let (mut a, mut b) = (coarse[top - 1].hz.ln(), coarse[top + 1].hz.ln());
        let r = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..40 {
            let (c, d) = (b - r * (b - a), a + r * (b - a));
            if gain_at(c.exp()) > gain_at(d.exp()) {
                b = d;
            } else {
                a = c;
            }
        }
        (gain_at((0.5 * (a + b)).exp()) - first.gain_db).max(peak)
    } else {
        peak
    };
    let Some(at) = coarse.iter().position(|b| b.hz >= hz) else {
        return (hz, phase, peak);
    };
    if !hz.is_finite() || at == 0 {
        return (hz, phase, peak);
    }
    let dc = first.gain_db;
    let (mut lo, mut hi) = (coarse[at - 1].hz.ln(), coarse[at].hz.ln());
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if gain_at(mid.exp()) - dc > -3.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let f = (0.5 * (lo + hi)).exp();
    let (_, p) = etfe(t, y, amplitude, band, f);
    // the phase continued from the coarse point below
    let mut deg = p.to_degrees();
    let prev = coarse[at - 1].phase_deg;
    while deg - prev > 180.0 {
        deg -= 360.0;
    }
    while deg - prev < -180.0 {
        deg += 360.0;
    }
    (f, deg, peak)
}

/// Figures of a frequency response: the −3 dB bandwidth (the first
/// frequency, interpolated in log f, where the gain falls 3 dB below its
/// low-frequency value; NaN if it never does), the phase there, and the
/// resonance peak (the largest gain above the low-frequency value, dB).
pub fn bandwidth(points: &[Bode]) -> (f64, f64, f64) {
    let points: Vec<Bode> = points
        .iter()
        .copied()
        .filter(|b| b.gain_db.is_finite())
        .collect();
    let Some(first) = points.first() else {
        return (f64::NAN, f64::NAN, f64::NAN);
    };
    let dc = first.gain_db;
    let peak = points.iter().map(|b| b.gain_db - dc).fold(0.0f64, f64::max);
    for w in points.windows(2) {
        let (a, b) = (w[0], w[1]);
        if b.gain_db - dc <= -3.0 {
            let (ga, gb) = (a.gain_db - dc + 3.0, b.gain_db - dc + 3.0);
            let s = if ga == gb { 1.0 } else { ga / (ga - gb) };
            let hz = (a.hz.ln() + s * (b.hz.ln() - a.hz.ln())).exp();
            let phase = a.phase_deg + s * (b.phase_deg - a.phase_deg);
            return (hz, phase, peak);
        }
    }
    (f64::NAN, f64::NAN, peak)
}

/// What a unit-step second-order system `wn, zeta` predicts.
pub mod second_order {
    /// Overshoot (%) of an underdamped system; 0 from critical damping up.
    pub fn overshoot_pct(zeta: f64) -> f64 {
        if zeta >= 1.0 {
            return 0.0;
        }
        100.0 * (-zeta * std::f64::consts::PI / (1.0 - zeta * zeta).sqrt()).exp()
    }

    /// The −3 dB bandwidth (rad/s) of `wn^2 / (s^2 + 2 zeta wn s + wn^2)`.
    pub fn bandwidth(wn: f64, zeta: f64) -> f64 {
        let z2 = zeta * zeta;
        wn * (1.0 - 2.0 * z2 + (4.0 * z2 * z2 - 4.0 * z2 + 2.0).sqrt()).sqrt()
    }

    /// The unit-step response at `t`.
    pub fn step(wn: f64, zeta: f64, t: f64) -> f64 {
        if zeta < 1.0 {
            let wd = wn * (1.0 - zeta * zeta).sqrt();
            let phi = (zeta / (1.0 - zeta * zeta).sqrt()).atan();
            1.0 - (-zeta * wn * t).exp() * (wd * t - phi).cos() / phi.cos()
        } else if zeta == 1.0 {
            1.0 - (1.0 + wn * t) * (-wn * t).exp()
        } else {
            let r = (zeta * zeta - 1.0).sqrt();
            let (s1, s2) = (-wn * (zeta - r), -wn * (zeta + r));
            1.0 + (s2 * (s1 * t).exp() - s1 * (s2 * t).exp()) / (s1 - s2)
        }
    }
}

/// PD gains for a joint of inertia `inertia` (kg·m²) to reach a −3 dB
/// bandwidth of `hz` with damping ratio `zeta`: `kp = I wn^2`,
/// `kd = 2 zeta I wn`, with `wn` the natural frequency that bandwidth
/// takes at that damping.
pub fn gains_for(inertia: f64, hz: f64, zeta: f64) -> (f64, f64) {
    let wb = 2.0 * PI * hz;
    let wn = wb / second_order::bandwidth(1.0, zeta);
    (inertia * wn * wn, 2.0 * zeta * inertia * wn)
}

/// Natural frequency (Hz) and damping ratio of gains `kp, kd` on inertia `I`.
pub fn natural(inertia: f64, kp: f64, kd: f64) -> (f64, f64) {
    let wn = (kp / inertia).sqrt();
    (wn / (2.0 * PI), kd / (2.0 * (kp * inertia).sqrt()))
}

/// The stability margin of a PD integrated explicitly (semi-implicit Euler,
/// MuJoCo's `Euler` without implicit actuator damping, and pupper's torque
/// mode): with `a = h^2 kp / I` and `b = h kd / I`, the discrete system
/// `z^2 - (2 - a - b) z + (1 - b)` is stable exactly when `a + 2b < 4`
/// and `b < 2` (Jury's test). Returns `max((a + 2b) / 4, b / 2)`: below 1
/// stable, at or above 1 past the bound.
pub fn explicit_pd_margin(inertia: f64, kp: f64, kd: f64, timestep: f64) -> f64 {
    let a = timestep * timestep * kp / inertia;
    let b = timestep * kd / inertia;
    ((a + 2.0 * b) / 4.0).max(b / 2.0)
}

/// [`explicit_pd_margin`], or with `implicit_damping`
/// [`implicit_damping_pd_margin`].
pub fn pd_margin(inertia: f64, kp: f64, kd: f64, timestep: f64, implicit_damping: bool) -> f64 {
    if implicit_damping {
        implicit_damping_pd_margin(inertia, kp, kd, timestep)
    } else {
        explicit_pd_margin(inertia, kp, kd, timestep)
    }
}

/// The same margin when the integrator takes the damping implicitly
/// (MuJoCo's `implicitfast` and `implicit` on a servo's velocity gain):
/// `I (v' - v) / h = -kp q - kd v'`, `q' = q + h v'` has the characteristic
/// polynomial `z^2 - (2 + b - a) z / (1 + b) + 1 / (1 + b)`, stable exactly
/// when `a < 4 + 2b` (Jury's test). Returns `a / (4 + 2b)`: any damping is
/// stable, and damping widens the stiffness bound.
pub fn implicit_damping_pd_margin(inertia: f64, kp: f64, kd: f64, timestep: f64) -> f64 {
    let a = timestep * timestep * kp / inertia;
    let b = timestep * kd / inertia;
    a / (4.0 + 2.0 * b)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sampled(mut f: impl FnMut(f64) -> f64, dt: f64, end: f64) -> (Vec<f64>, Vec<f64>) {
        let n = (end / dt).round() as usize;
        let t: Vec<f64> = (0..=n).map(|i| i as f64 * dt).collect();
        let y = t.iter().map(|&t| f(t)).collect();
        (t, y)
    }

    #[test]
    fn first_order_step() {
        // y = 1 - exp(-t/tau): rise ln 9 tau, settles (2 %) at ln 50 tau, no overshoot
        let tau = 0.1;
        let (t, y) = sampled(|t| 1.0 - (-t / tau).exp(), 1e-5, 3.0);
        let s = step_info(&t, &y, 1.0);
        assert!((s.rise_time - 9f64.ln() * tau).abs() < 1e-4, "{s:?}");
        assert!((s.settling_time - 50f64.ln() * tau).abs() < 1e-3, "{s:?}");
        assert!(s.overshoot_pct < 1e-6, "{s:?}");
        assert!(s.ss_error.abs() < 1e-9);
    }

    #[test]
    fn underdamped_second_order_step() {
        let (wn, zeta) = (20.0, 0.3);
        let (t, y) = sampled(|t| second_order::step(wn, zeta, t), 1e-5, 4.0);
        let s = step_info(&t, &y, 1.0);
        assert!(
            (s.overshoot_pct - second_order::overshoot_pct(zeta)).abs() < 0.01,
            "{s:?}"
        );
        let tp = PI / (wn * (1.0 - zeta * zeta).sqrt());
        assert!((s.peak_time - tp).abs() < 1e-4, "{s:?}");
        // settling within the classic 4 / (zeta wn) envelope estimate
        assert!(
            s.settling_time > 0.4 && s.settling_time < 4.0 / (zeta * wn) * 1.1,
            "{s:?}"
        );
    }

    #[test]
    fn a_step_that_never_settles() {
        let (t, y) = sampled(
            |t| 1.0 + 0.5 * (30.0 * t).sin() * (t > 0.01) as i32 as f64,
            1e-3,
            2.0,
        );
        let s = step_info(&t, &y, 1.0);
        assert!(s.settling_time.is_nan(), "{s:?}");
    }

    #[test]
    fn a_noisy_step_keeps_its_figures() {
        // deterministic noise of 0.2 % of the step
        let tau = 0.05;
        let mut seed = 7u64;
        let (t, y) = sampled(
            |t| {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                let u = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                1.0 - (-t / tau).exp() + 0.004 * u
            },
            1e-4,
            1.0,
        );
        let s = step_info(&t, &y, 1.0);
        assert!((s.rise_time - 9f64.ln() * tau).abs() < 0.003, "{s:?}");
        assert!(s.overshoot_pct < 0.5 && s.ss_error.abs() < 0.002, "{s:?}");
    }

    #[test]
    fn a_negative_step_mirrors_a_positive_one() {
        let (wn, zeta) = (15.0, 0.5);
        let (t, up) = sampled(|t| 0.3 + 0.2 * second_order::step(wn, zeta, t), 1e-5, 3.0);
        let down: Vec<f64> = up.iter().map(|v| 0.6 - v).collect();
        let (a, b) = (step_info(&t, &up, 0.2), step_info(&t, &down, -0.2));
        assert!((a.rise_time - b.rise_time).abs() < 1e-9);
        assert!((a.overshoot_pct - b.overshoot_pct).abs() < 1e-9);
        assert!((a.overshoot_pct - second_order::overshoot_pct(zeta)).abs() < 0.01);
        assert!((a.ss_error + b.ss_error).abs() < 1e-9);
        // a steady-state error: 10 % short of the step
        let short: Vec<f64> = up.iter().map(|v| 0.3 + 0.9 * (v - 0.3)).collect();
        let s = step_info(&t, &short, 0.2);
        assert!((s.ss_error_pct - 10.0).abs() < 1e-6, "{s:?}");
    }

    #[test]
    fn a_sine_of_known_gain_and_phase() {
        let (f, a) = (3.0, 0.1);
        let (t, y) = sampled(
            |t| 0.05 + 0.7 * a * (2.0 * PI * f * t - 0.6).sin(),
            1e-4,
            2.0,
        );
        let phase: Vec<f64> = t.iter().map(|t| 2.0 * PI * f * t).collect();
        let (g, p) = sine_fit(&phase, &y, a);
        assert!((g - 0.7).abs() < 1e-9 && (p + 0.6).abs() < 1e-9, "{g} {p}");
    }

    #[test]
    fn a_chirp_through_a_known_system_gives_its_bandwidth() {
        // first-order lag: bandwidth at the corner, phase -45 deg there
        let fc = 4.0;
        let (f0, f1, dur, dt) = (0.1, 30.0, 60.0, 1e-4);
        let w = 2.0 * PI * fc;
        let n = (dur / dt) as usize;
        let (mut y, mut ts, mut ys) = (0.0, Vec::with_capacity(n), Vec::with_capacity(n));
        for i in 0..n {
            let t = i as f64 * dt;
            let u = chirp(f0, f1, dur, t).0.sin();
            y += dt * w * (u - y); // exact enough at dt w = 0.0025
            ts.push(t + dt);
            ys.push(y);
        }
        let b = chirp_response(&ts, &ys, 1.0, (f0, f1, dur), 40);
        let (hz, phase, peak) = chirp_bandwidth(&ts, &ys, 1.0, (f0, f1, dur), &b);
        assert!((hz / fc - 1.0).abs() < 0.02, "{hz}");
        assert!((phase + 45.0).abs() < 3.0, "{phase}");
        assert!(peak < 0.1);
    }

    #[test]
    fn second_order_predictions() {
        assert!((second_order::overshoot_pct(0.7) - 4.598).abs() < 0.01);
        // at zeta = 1/sqrt(2) the bandwidth is wn
        assert!((second_order::bandwidth(10.0, 0.5f64.sqrt()) - 10.0).abs() < 1e-9);
        let (kp, kd) = gains_for(0.01, 8.0, 0.5f64.sqrt());
        let (hz, z) = natural(0.01, kp, kd);
        assert!((hz - 8.0).abs() < 1e-9 && (z - 0.5f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn the_explicit_pd_bound() {
        // undamped: stable below h^2 kp / I = 4
        assert!(explicit_pd_margin(1.0, 3.9, 0.0, 1.0) < 1.0);
        assert!(explicit_pd_margin(1.0, 4.1, 0.0, 1.0) > 1.0);
        // damping alone: b < 2
        assert!(explicit_pd_margin(1.0, 0.0, 2.1, 1.0) > 1.0);
        // iterate the discrete system on both sides of the bound
        let grows = |kp: f64, kd: f64| {
            let (h, i) = (0.002, 1e-3);
            let (mut x, mut v) = (1.0f64, 0.0f64);
            for _ in 0..2_000 {
                v += h * (-kp * x - kd * v) / i;
                x += h * v;
            }
            // NaN (overflow) counts as grown
            x.is_nan() || x.abs() >= 1.0
        };
        for (kp, kd) in [
            (450.0, 0.5),
            (550.0, 0.5),
            (900.0, 0.2),
            (1100.0, 0.2),
            (100.0, 0.8),
            (100.0, 1.0),
        ] {
            let m = explicit_pd_margin(1e-3, kp, kd, 0.002);
            assert_eq!(grows(kp, kd), m >= 1.0, "kp {kp} kd {kd} margin {m}");
        }
    }

    #[test]
    fn the_pd_bound_with_implicit_damping() {
        // undamped it is the explicit bound: h^2 kp / I < 4
        assert!(implicit_damping_pd_margin(1.0, 3.9, 0.0, 1.0) < 1.0);
        assert!(implicit_damping_pd_margin(1.0, 4.1, 0.0, 1.0) > 1.0);
        // damping alone never diverges, and widens the stiffness bound
        assert_eq!(implicit_damping_pd_margin(1.0, 0.0, 100.0, 1.0), 0.0);
        assert!(implicit_damping_pd_margin(1.0, 5.0, 1.0, 1.0) < 1.0);
        // iterate I (v' - v) / h = -kp x - kd v' on both sides of the bound
        let grows = |kp: f64, kd: f64| {
            let (h, i) = (0.002, 1e-3);
            let (mut x, mut v) = (1.0f64, 0.0f64);
            for _ in 0..2_000 {
                v = (i * v - h * kp * x) / (i + h * kd);
                x += h * v;
            }
            // a stable system stays near its start; past the bound it grows
            x.is_nan() || x.abs() >= 10.0
        };
        for (kp, kd) in [
            (950.0, 0.01),
            (1070.0, 0.01),
            (1900.0, 1.0),
            (2100.0, 1.0),
            (100.0, 5.0),
            (120.0, 2.0),
        ] {
            let m = implicit_damping_pd_margin(1e-3, kp, kd, 0.002);
            assert_eq!(grows(kp, kd), m >= 1.0, "kp {kp} kd {kd} margin {m}");
        }
    }
}
