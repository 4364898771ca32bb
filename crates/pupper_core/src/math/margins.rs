//! Phase and gain margins of one joint's servo loop as a firmware closes
//! it, linearised at a pose: the joint's reflected inertia `J` and viscous
//! damping `b` driven by a PD `kp + kd·s` that sees the joint late.
//!
//! Where the PD runs slower than the physics, the loop is continuous:
//! `L(s) = (kp + kd·s·F(s)·e^{-s·d}) · e^{-s·τ} / ((1 + s·T) · s·(J·s + b))`,
//! with `T` the torque's first-order lag behind the PD (a current loop's),
//! `τ` the feedback path's latency (sensing delay plus half the PD's
//! update period: a sampled controller holds its output for one period,
//! on average half a period late), `F` the derivative's first-order
//! low-pass filter and `d` the extra half period of a derivative taken as
//! an encoder's difference over one period.
//!
//! Where the PD acts every physics step (pupper's ideal motor, a firmware
//! at the physics rate, what `pupper fit` replays), the loop is the sampled
//! one the simulation steps, exactly: MuJoCo's semi-implicit Euler (the
//! velocity first, its damping implicit, then the angle by the new
//! velocity), the PD on the state `ℓ` steps old (between two steps where
//! `ℓ` is fractional), the lag and the filter as their per-step laws; its
//! frequency response is that of the simulated joint, not an approximation
//! of it (a continuous model with half a step of latency was 6° off at
//! 20 Hz on Pupper's knee).
//!
//! A command delay is not in the loop: it shifts the target, not the
//! feedback, and leaves these margins alone. The margins are the classical
//! ones: the phase margin at the gain crossover (|L| = 1), the gain margin
//! at the phase crossover (arg L = −180°).

use nalgebra::Complex;
use serde::Serialize;

/// What a firmware puts in a servo loop's feedback path.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Feedback {
    /// Latency of the whole feedback path (s).
    pub latency: f64,
    /// Cutoff of the derivative's low-pass filter (Hz); None: no filter.
    pub filter_hz: Option<f64>,
    /// Extra delay of the derivative path alone (s).
    pub derivative_delay: f64,
    /// The time constant of the torque's first-order lag behind the PD
    /// (s); 0: none.
    pub torque_lag: f64,
    /// How late the PD's output acts on the joint (s): half its update
    /// period, held over it; the target's path has it too.
    #[serde(default)]
    pub hold: f64,
    /// Where the PD acts every physics step: that step (s), and how many
    /// steps old the state it reads is (the sampled loop, exactly as the
    /// simulation steps it); None: the continuous loop of `latency`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sampled: Option<Sampled>,
}

/// A PD that acts every physics step of `step` s, on the state `late`
/// steps old.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Sampled {
    pub step: f64,
    pub late: f64,
}

impl Feedback {
    /// The loop of a joint of `inertia` and `damping` under `kp`, `kd`.
    pub fn servo(&self, inertia: f64, damping: f64, kp: f64, kd: f64) -> ServoLoop {
        ServoLoop {
            inertia,
            damping,
            kp,
            kd,
            latency: self.latency,
            filter_hz: self.filter_hz,
            derivative_delay: self.derivative_delay,
            torque_lag: self.torque_lag,
            hold: self.hold,
            sampled: self.sampled,
        }
    }
}

/// One joint's linearised servo loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoLoop {
    /// Reflected inertia (kg·m²), armature included.
    pub inertia: f64,
    /// Viscous damping of the joint (N·m·s/rad).
    pub damping: f64,
    pub kp: f64,
    pub kd: f64,
    /// Latency of the whole feedback path (s).
    pub latency: f64,
    /// Cutoff of the derivative's low-pass filter (Hz); None: no filter.
    pub filter_hz: Option<f64>,
    /// Extra delay of the derivative path alone (s): half an update period
    /// for a derivative differenced over one.
    pub derivative_delay: f64,
    /// The torque's first-order lag behind the PD (s); 0: none.
    pub torque_lag: f64,
    /// How late the PD's output acts (s), on the target's path too.
    pub hold: f64,
    /// The sampled loop of a PD acting every physics step ([`Sampled`]).
    pub sampled: Option<Sampled>,
}

/// Where the loop crosses over, and by how much it is stable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Margins {
    /// Gain crossover (Hz): |L| = 1.
    pub crossover_hz: f64,
    /// 180° plus the phase of L there (deg); below 0: unstable.
    pub phase_deg: f64,
    /// Phase crossover (Hz): arg L = −180°; infinite when the phase never
    /// gets there (no latency, and no torque lag as long as kd/kp); 0 when
    /// it starts past it (an undamped joint whose kd/kp is shorter than the
    /// lag and latency together).
    pub phase_crossover_hz: f64,
    /// −20·log10 |L| at the phase crossover (dB): +∞ without one, −∞ when
    /// the phase starts past −180° (no loop gain makes it stable: scaling
    /// kp and kd together keeps kd/kp).
    pub gain_db: f64,
}

/// Frequencies searched (rad/s): far below and above any joint's loop,
/// 100 a decade, each crossing then refined by bisection (a PD loop's gain
/// and phase move by far less than a crossing's worth in 2.3 %).
const LOW: f64 = 1e-2;
const HIGH: f64 = 1e6;
const STEPS: usize = 800;

impl ServoLoop {
    /// The controller's transfer at `w` rad/s (derivative filtered and
    /// delayed), without the common latency: `kp + kd·s·F(s)·e^{-s·d}`, or
    /// in the sampled loop `kp + kd·F(z)·(z − 1)/(h·z)` (the velocity of
    /// semi-implicit Euler is the angle's difference over a step).
    fn controller(&self, w: f64) -> Complex<f64> {
        let one = Complex::new(1.0, 0.0);
        if let Some(Sampled { step: h, .. }) = self.sampled {
            let zi = Complex::from_polar(1.0, -w * h);
            let filter = match self.filter_hz {
                Some(f) => {
                    let a = crate::math::motor::lowpass_alpha(f, h);
                    a / (one - zi * (1.0 - a))
                }
                None => one,
            };
            return (one - zi) / h * self.kd * filter + self.kp;
        }
        let s = Complex::new(0.0, w);
        let filter = match self.filter_hz {
            Some(f) => one / (s / (2.0 * std::f64::consts::PI * f) + 1.0),
            None => one,
        };
        let delay = Complex::from_polar(1.0, -w * self.derivative_delay);
        s * self.kd * filter * delay + self.kp
    }

    /// The loop's parts at `w` rad/s besides the controller: the joint
    /// (from torque to angle), the torque's lag and the feedback latency,
    /// each as (magnitude, unwrapped phase in radians).
    fn parts(&self, w: f64) -> [(f64, f64); 3] {
        use std::f64::consts::FRAC_PI_2;
        match self.sampled {
            Some(Sampled { step: h, late }) => {
                let z = Complex::from_polar(1.0, w * h);
                // semi-implicit Euler: v' = (v + h·u/J) / (1 + h·b/J),
                // q' = q + h·v', so Q/U = h²·z / (J·(z − 1)·((1 + β)·z − 1));
                // arg(z − 1) = 90° + w·h/2 on the unit circle
                let beta = h * self.damping / self.inertia;
                let pole = z * (1.0 + beta) - 1.0;
                let joint = (
                    h * h / (self.inertia * 2.0 * (w * h / 2.0).sin() * pole.norm()),
                    w * h - (FRAC_PI_2 + w * h / 2.0) - pole.im.atan2(pole.re),
                );
                // the lag's step law y' = y + α·(u − y): α / (1 − (1 − α)·z⁻¹)
                let lag = if self.torque_lag > 0.0 {
                    let a = -(-h / self.torque_lag).exp_m1();
                    let den = Complex::new(1.0, 0.0) - Complex::from_polar(1.0 - a, -w * h);
                    (a / den.norm(), -den.im.atan2(den.re))
                } else {
                    (1.0, 0.0)
                };
                // the state `late` steps old, between two steps
                let whole = late.floor();
                let frac = late - whole;
                let between = Complex::new(1.0 - frac, 0.0) + Complex::from_polar(frac, -w * h);
                let latency = (
                    between.norm(),
                    -w * h * whole + between.im.atan2(between.re),
                );
                [joint, lag, latency]
            }
            None => {
                let plant = Complex::new(-self.inertia * w * w, self.damping * w);
                [
                    (
                        1.0 / plant.norm(),
                        -(FRAC_PI_2 + (self.inertia * w).atan2(self.damping)),
                    ),
                    (
                        1.0 / (w * self.torque_lag).hypot(1.0),
                        -(w * self.torque_lag).atan(),
                    ),
                    (1.0, -w * self.latency),
                ]
            }
        }
    }

    /// |L(jw)|.
    pub fn magnitude(&self, w: f64) -> f64 {
        self.controller(w).norm() * self.parts(w).iter().map(|p| p.0).product::<f64>()
    }

    /// arg L(jw) in radians, unwrapped: the controller's angle (its real
    /// part stays positive, so it lies in (−90°, 90°)), the joint's
    /// (`−(90° + atan2(J·w, b))` continuous), the torque lag's and the
    /// latency's.
    pub fn phase(&self, w: f64) -> f64 {
        let c = self.controller(w);
        c.im.atan2(c.re) + self.parts(w).iter().map(|p| p.1).sum::<f64>()
    }

    /// The closed loop from target to angle at `w` rad/s, the target
    /// `command_delay` s late: `kp·e^{-s·delay}·P / (1 + L)` (the firmware's
    /// PD law, `kp·(target − q) − kd·q̇`, puts only kp on the target), P the
    /// joint and its lag (and in the continuous loop the PD's hold). What a
    /// sine on the simulated joint measures, where the joint is linear.
    pub fn closed_loop(&self, w: f64, command_delay: f64) -> Complex<f64> {
        let [joint, lag, _] = self.parts(w);
        let hold = if self.sampled.is_some() {
            0.0
        } else {
            self.hold
        };
        let forward = Complex::from_polar(
            self.kp * joint.0 * lag.0,
            joint.1 + lag.1 - w * (command_delay + hold),
        );
        let open = Complex::from_polar(self.magnitude(w), self.phase(w));
        forward / (open + 1.0)
    }

    /// The highest frequency the loop is searched to (rad/s): a sampled
    /// loop's Nyquist frequency.
    fn top(&self) -> f64 {
        match self.sampled {
            Some(Sampled { step, .. }) => std::f64::consts::PI / step * (1.0 - 1e-9),
            None => HIGH,
        }
    }

    /// The margins; None for a loop without a gain crossover (no gains).
    pub fn margins(&self) -> Option<Margins> {
        let top = self.top();
        let ws: Vec<f64> = (0..=STEPS)
            .map(|i| LOW * (top / LOW).powf(i as f64 / STEPS as f64))
            .collect();
        let gain = |w: f64| self.magnitude(w).ln();
        let turn = |w: f64| self.phase(w) + std::f64::consts::PI;
        let hz = |w: f64| w / (2.0 * std::f64::consts::PI);
        let Some(wc) = first_root(&ws, &gain) else {
            // a sampled loop whose gain is still above 1 at the Nyquist
            // frequency, where its phase is −180° or past it: past the
            // explicit PD's stability bound, no phase margin at all
            if self.sampled.is_some() && gain(top) > 0.0 && turn(top) <= 1e-6 {
                return Some(Margins {
                    crossover_hz: hz(top),
                    phase_deg: f64::NEG_INFINITY,
                    phase_crossover_hz: hz(top),
                    gain_db: -20.0 * self.magnitude(top).log10(),
                });
            }
            return None;
        };
        // past −180° from the band's start, the crossover is at 0 Hz, where
        // |L| of the undamped joint is infinite (a gain margin of −∞, not +∞)
        // a sampled loop's phase reaches −180° at the Nyquist frequency at
        // the latest (there the joint's is −180° and the rest are real):
        // its gain there is the explicit PD's stability bound
        let w180 = if turn(ws[0]) <= 0.0 {
            Some(0.0)
        } else {
            first_root(&ws, &turn)
                .or_else(|| (self.sampled.is_some() && turn(top) <= 1e-6).then_some(top))
        };
        Some(Margins {
            crossover_hz: hz(wc),
            phase_deg: turn(wc).to_degrees(),
            phase_crossover_hz: w180.map_or(f64::INFINITY, hz),
            gain_db: w180.map_or(f64::INFINITY, |w| -20.0 * self.magnitude(w).log10()),
        })
    }
}

/// The first `w` of the log grid `ws` where `f` falls through zero,
/// refined by bisection. Each grid point is evaluated once, and none past
/// the crossing (the margins' search is most of `recommend`'s margin maps).
fn first_root(ws: &[f64], f: &dyn Fn(f64) -> f64) -> Option<f64> {
    let mut prev = f(*ws.first()?);
    let k = ws.windows(2).position(|p| {
        let next = f(p[1]);
        let crossed = prev > 0.0 && next <= 0.0;
        prev = next;
        crossed
    })?;
    let (mut a, mut b) = (ws[k], ws[k + 1]);
    // 60 halvings of a 2.3 % step: to the float's precision
    for _ in 0..60 {
        let m = (a * b).sqrt();
        if f(m) > 0.0 {
            a = m;
        } else {
            b = m;
        }
    }
    Some((a * b).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pupper's knee (reflected inertia 1.816e-3 kg·m²) under a PD updated
    /// at 500 Hz on 1 ms old measurements: 1 ms + half of 2 ms of latency.
    fn knee(kp: f64, kd: f64) -> ServoLoop {
        ServoLoop {
            inertia: 1.816e-3,
            damping: 0.0,
            kp,
            kd,
            latency: 0.002,
            filter_hz: None,
            derivative_delay: 0.0,
            torque_lag: 0.0,
            hold: 0.001,
            sampled: None,
        }
    }

    #[test]
    fn a_pd_on_a_delayed_double_integrator_has_its_known_margins() {
        // the closed forms: |L| = sqrt(kp² + (kd w)²) / (J w²) and
        // arg L = atan(kd w / kp) − 180° − w τ
        for (kp, kd) in [(5.0, 0.25), (10.0, 1.0), (120.0, 2.0)] {
            let l = knee(kp, kd);
            let m = l.margins().unwrap();
            let w = 2.0 * std::f64::consts::PI * m.crossover_hz;
            let mag = (kp * kp + (kd * w).powi(2)).sqrt() / (1.816e-3 * w * w);
            assert!((mag - 1.0).abs() < 1e-9, "{mag}");
            let pm = (kd * w / kp).atan().to_degrees() - (w * 0.002).to_degrees();
            assert!((m.phase_deg - pm).abs() < 1e-6, "{} vs {pm}", m.phase_deg);
        }
        // the figures the issue quotes for this loop: about 68°, 27°, −39°
        let pm = |kp, kd| knee(kp, kd).margins().unwrap().phase_deg;
        assert!((pm(5.0, 0.25) - 66.0).abs() < 3.0, "{}", pm(5.0, 0.25));
        assert!((pm(10.0, 1.0) - 27.0).abs() < 2.0, "{}", pm(10.0, 1.0));
        assert!((pm(120.0, 2.0) + 39.0).abs() < 2.0, "{}", pm(120.0, 2.0));
    }

    #[test]
    fn latency_filter_and_differencing_each_cost_phase_and_none_costs_nothing() {
        let base = knee(10.0, 0.5);
        let ideal = ServoLoop {
            latency: 0.0,
            ..base
        };
        let mi = ideal.margins().unwrap();
        // no latency: the phase never reaches −180°, the gain margin is infinite
        assert!(mi.gain_db.is_infinite() && mi.phase_deg > 0.0);
        let m = base.margins().unwrap();
        assert!(m.phase_deg < mi.phase_deg && m.gain_db.is_finite() && m.gain_db > 0.0);
        let filtered = ServoLoop {
            filter_hz: Some(100.0),
            ..base
        };
        assert!(filtered.margins().unwrap().phase_deg < m.phase_deg);
        let differenced = ServoLoop {
            derivative_delay: 0.001,
            ..base
        };
        assert!(differenced.margins().unwrap().phase_deg < m.phase_deg);
        // at the phase crossover the phase is −180° and |L| is the gain margin
        let w = 2.0 * std::f64::consts::PI * m.phase_crossover_hz;
        assert!((base.phase(w) + std::f64::consts::PI).abs() < 1e-9);
        assert!((-20.0 * base.magnitude(w).log10() - m.gain_db).abs() < 1e-9);
    }

    #[test]
    fn a_torque_lag_has_its_closed_form_and_costs_phase() {
        // |L| = sqrt(kp² + (kd w)²) / (J w² sqrt(1 + (w T)²)) and
        // arg L = atan(kd w / kp) − atan(w T) − 180° − w τ: a 7 ms lag (a
        // real Pupper v3 motor's, fitted) on kp 5, kd 0.25
        let t = 0.007;
        let l = ServoLoop {
            torque_lag: t,
            ..knee(5.0, 0.25)
        };
        let m = l.margins().unwrap();
        let w = 2.0 * std::f64::consts::PI * m.crossover_hz;
        let mag = (25.0 + (0.25 * w).powi(2)).sqrt()
            / (1.816e-3 * w * w * (1.0 + (w * t).powi(2)).sqrt());
        assert!((mag - 1.0).abs() < 1e-9, "{mag}");
        let pm = (0.25 * w / 5.0).atan().to_degrees()
            - (w * t).atan().to_degrees()
            - (w * 0.002).to_degrees();
        assert!((m.phase_deg - pm).abs() < 1e-6, "{} vs {pm}", m.phase_deg);
        let without = knee(5.0, 0.25).margins().unwrap();
        assert!(
            m.phase_deg < without.phase_deg - 10.0,
            "{} vs {}",
            m.phase_deg,
            without.phase_deg
        );
    }

    #[test]
    fn a_phase_past_180_from_the_start_has_no_gain_margin() {
        // kd/kp = 12.5 ms under a 16 ms lag and 2 ms of latency: the phase
        // starts at −180° − w (T + τ − kd/kp), below −180°, and the loop
        // I T s³ + I s² + kd s + kp is unstable at any common gain
        let l = ServoLoop {
            torque_lag: 0.016,
            ..knee(40.0, 0.5)
        };
        let m = l.margins().unwrap();
        assert!(m.phase_deg < 0.0, "{}", m.phase_deg);
        assert_eq!((m.phase_crossover_hz, m.gain_db), (0.0, f64::NEG_INFINITY));
        // kd/kp of 25 ms keeps the low frequencies above −180°: a finite margin
        let kept = ServoLoop {
            torque_lag: 0.016,
            ..knee(40.0, 1.0)
        };
        let k = kept.margins().unwrap();
        assert!(k.phase_crossover_hz > 0.0 && k.gain_db.is_finite(), "{k:?}");
    }

    /// One joint stepped as torque mode steps it (semi-implicit Euler,
    /// damping implicit; the PD every step on the state `late` steps old,
    /// between two steps; its torque through the lag's step law), driven by
    /// a sine target `delay` s late: the angle's gain and phase (rad) at
    /// `hz`, from whole periods after the start has died away.
    fn stepped(l: &ServoLoop, hz: f64, delay: f64) -> Complex<f64> {
        let Some(Sampled { step: h, late }) = l.sampled else {
            panic!("a sampled loop")
        };
        let w = 2.0 * std::f64::consts::PI * hz;
        let per = (1.0 / (hz * h)).round() as usize;
        let n = per * ((20.0 * hz).ceil() as usize);
        let (mut q, mut v, mut y) = (0.0_f64, 0.0_f64, 0.0_f64);
        let mut past: Vec<(f64, f64)> = Vec::with_capacity(n);
        let alpha = if l.torque_lag > 0.0 {
            -(-h / l.torque_lag).exp_m1()
        } else {
            1.0
        };
        let mut acc = Complex::new(0.0, 0.0);
        for k in 0..n {
            let t = k as f64 * h;
            past.push((q, v));
            let at = k as f64 - late;
            let (rq, rv) = if at <= 0.0 {
                past[0]
            } else {
                let i = at.floor() as usize;
                let f = at - i as f64;
                let (a, b) = (past[i], past[(i + 1).min(k)]);
                (a.0 * (1.0 - f) + b.0 * f, a.1 * (1.0 - f) + b.1 * f)
            };
            let target = (w * (t - delay)).sin();
            let u = l.kp * (target - rq) - l.kd * rv;
            y += alpha * (u - y);
            if k >= n - 10 * per {
                // the angle at the step's start, against the target's phasor
                acc += Complex::from_polar(q, -w * t);
            }
            v = (v + h * y / l.inertia) / (1.0 + h * l.damping / l.inertia);
            q += h * v;
        }
        // sin(wt) = Im e^{jwt}: the response's phasor is 2j/N·Σ q e^{-jwt}
        acc * Complex::new(0.0, 2.0 / (10 * per) as f64)
    }

    #[test]
    fn the_sampled_loop_is_the_stepped_joint() {
        // a real Pupper v3 knee as fitted (armature 1.1e-3 on its link, the
        // motor delivering 0.86 of kp 5 and 0.91 of kd 0.25, a 7.4 ms
        // torque lag), at the 2 ms physics step, with 1.4 steps of latency
        // and a 13.6 ms command delay; and the ideal motor on the nominal knee
        let fitted = ServoLoop {
            inertia: 1.3193e-3,
            damping: 0.002,
            kp: 4.306,
            kd: 0.2265,
            latency: 0.0,
            filter_hz: None,
            derivative_delay: 0.0,
            torque_lag: 0.00739,
            hold: 0.001,
            sampled: Some(Sampled {
                step: 0.002,
                late: 1.4,
            }),
        };
        let ideal = ServoLoop {
            sampled: Some(Sampled {
                step: 0.002,
                late: 0.0,
            }),
            damping: 0.01,
            ..knee(5.0, 0.25)
        };
        for (l, delay) in [(fitted, 0.0136), (ideal, 0.0)] {
            for hz in [1.0, 2.5, 5.0, 10.0, 20.0] {
                let sim = stepped(&l, hz, delay);
                let lin = l.closed_loop(2.0 * std::f64::consts::PI * hz, delay);
                let db = 20.0 * (sim.norm() / lin.norm()).log10();
                let deg = (sim / lin).arg().to_degrees();
                assert!(
                    db.abs() < 1e-3 && deg.abs() < 1e-2,
                    "{hz} Hz: {db} dB, {deg}°"
                );
            }
        }
        // and its margins are where the loop's gain is 1 and its phase −180°
        let m = fitted.margins().unwrap();
        let wc = 2.0 * std::f64::consts::PI * m.crossover_hz;
        assert!((fitted.magnitude(wc) - 1.0).abs() < 1e-9);
        assert!(m.phase_deg > 0.0 && m.gain_db > 0.0, "{m:?}");
        let w = 2.0 * std::f64::consts::PI * m.phase_crossover_hz;
        assert!((fitted.phase(w) + std::f64::consts::PI).abs() < 1e-9);
        // 3.4 steps of latency on top of the lag: the margins say unstable,
        // and the stepped joint runs away
        let late = ServoLoop {
            sampled: Some(Sampled {
                step: 0.002,
                late: 3.4,
            }),
            ..fitted
        };
        assert!(late.margins().unwrap().phase_deg < 0.0);
        assert!(stepped(&late, 1.0, 0.0).norm() > 1e3);
    }

    #[test]
    fn a_sampled_loop_past_the_explicit_bound_has_no_phase_margin() {
        // kd 4 on the knee at 2 ms: h·kd/J = 4.4, past the bound's 2; the
        // loop's gain is above 1 up to the Nyquist frequency
        let l = ServoLoop {
            sampled: Some(Sampled {
                step: 0.002,
                late: 0.0,
            }),
            ..knee(5.0, 4.0)
        };
        let m = l.margins().unwrap();
        assert_eq!(m.phase_deg, f64::NEG_INFINITY);
        assert!(
            m.gain_db < 0.0 && (m.crossover_hz - 250.0).abs() < 1e-3,
            "{m:?}"
        );
    }

    #[test]
    fn no_gains_no_crossover() {
        assert_eq!(knee(0.0, 0.0).margins(), None);
    }
}
