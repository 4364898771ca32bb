//! `pupper fit`'s replay of its logs through the servo firmware: every
//! rollout of a Jacobian (each its own parameters) stepped together, the
//! firmware's arithmetic here, in the one [`Firmware`] torque mode runs
//! (its PD at its rate, the encoder's difference velocity, the derivative
//! filter, the torque–speed band, the torque's lag) and the one
//! [`Sensing`] that reads the state a fitted latency late. What the replay
//! adds of its own: each rollout's gains, command delay, latency, lag and
//! torque limit (a Jacobian's rollouts differ in them), targets sampled
//! from the log (a delay between two samples interpolated), and the
//! encoder noise as one pre-drawn series every rollout reads (common
//! random numbers, each with its sign: antithetic pairs), beside a
//! noise-free copy of the firmware whose torque is what a torque sensor
//! reports. The stepping (MuJoCo's batch) is the bridge's.

use crate::error::{Error, Result};
use crate::plan::motor::Motor;
use crate::sim::firmware::{Firmware, Sensing};

/// The firmware of a replay: `--motor`'s rate, filter, encoder difference
/// and no-load speed (the delay, lag and latency are each rollout's).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReplayMotor {
    pub rate: Option<f64>,
    pub filter: Option<f64>,
    /// The derivative is the encoder's difference over an update period.
    pub counts: bool,
    pub noload: Option<f64>,
}

/// Each rollout's servo, per actuator (rollout-major, `nb × nu`): the
/// gains it runs at, its command delay, feedback latency and torque lag
/// (s), and its torque limit (N·m; infinite: none).
#[derive(Debug, Clone, Default)]
pub struct ReplayServo {
    pub kp: Vec<f64>,
    pub kd: Vec<f64>,
    pub delay: Vec<f64>,
    pub latency: Vec<f64>,
    pub lag: Vec<f64>,
    pub peak: Vec<f64>,
}

/// The replay of `nb` rollouts of `nu` actuators at physics step `dt`.
pub struct Replay {
    nb: usize,
    nu: usize,
    dt: f64,
    servo: ReplayServo,
    /// Each rollout's command delay in steps.
    delay_steps: Vec<f64>,
    fw: Vec<Firmware>,
    /// The noise-free firmware, where the PD reads noise.
    clean: Option<Vec<Firmware>>,
    sensing: Vec<Sensing>,
    /// The encoder noise (rad) the PD reads at its k-th update, per
    /// actuator (`updates × nu`), and each rollout's sign of it.
    noise: Option<(Vec<f64>, Vec<f64>)>,
    updates: usize,
}

impl Replay {
    /// A replay of `nb` rollouts; `noise`: the pre-drawn noise (`updates ×
    /// nu`, rad) and each rollout's sign (`nb`).
    pub fn new(
        motor: &ReplayMotor,
        nb: usize,
        nu: usize,
        dt: f64,
        servo: ReplayServo,
        noise: Option<(Vec<f64>, Vec<f64>)>,
    ) -> Result<Replay> {
        let n = nb * nu;
        let fields = [
            &servo.kp,
            &servo.kd,
            &servo.delay,
            &servo.latency,
            &servo.lag,
            &servo.peak,
        ];
        if fields.iter().any(|f| f.len() != n) || !(dt.is_finite() && dt > 0.0) {
            return Err(Error::Internal(format!(
                "replay: every servo field needs {nb} x {nu} values and a positive step"
            )));
        }
        if let Some((draws, sign)) = &noise
            && (sign.len() != nb || draws.len() % nu.max(1) != 0)
        {
            return Err(Error::Internal("replay: noise of the wrong shape".into()));
        }
        let m = Motor {
            rate: motor.rate,
            filter: motor.filter,
            counts: motor.counts.then_some(1 << 14),
            noload: motor.noload,
            ..Motor::default()
        };
        let make =
            |b: usize| Firmware::new(&m, nu, dt).smooth(&servo.lag[b * nu..(b + 1) * nu], dt);
        let sensing = (0..nb)
            .map(|b| {
                let late: Vec<f64> = servo.latency[b * nu..(b + 1) * nu]
                    .iter()
                    .map(|&l| m.late_steps(l, dt))
                    .collect();
                let late = if late.iter().all(|&l| l <= 0.0) {
                    Vec::new()
                } else {
                    late
                };
                Sensing::new(0, None, None, late)
            })
            .collect();
        Ok(Replay {
            nb,
            nu,
            dt,
            delay_steps: servo.delay.iter().map(|d| d / dt).collect(),
            fw: (0..nb).map(make).collect(),
            clean: noise.as_ref().map(|_| (0..nb).map(make).collect()),
            sensing,
            noise,
            updates: 0,
            servo,
        })
    }

    /// Step `k`: from each rollout's state (`q`, `v`: `nb × nu`) and the
    /// log's targets (`control(b, i, a)`: rollout b's target of actuator a
    /// at sample i), the torque each actuator applies over the step
    /// (`ctrl`) and the one a torque sensor reports (`sensed`: the
    /// noise-free firmware's, where the PD reads noise).
    pub fn step(
        &mut self,
        k: usize,
        q: &[f64],
        v: &[f64],
        control: &dyn Fn(usize, usize, usize) -> f64,
        ctrl: &mut [f64],
        sensed: &mut [f64],
    ) {
        let (nu, t) = (self.nu, k as f64 * self.dt);
        // one update clock for every rollout: they share the firmware's rate
        // (each firmware's counter steps, so every one is asked)
        let mut due = false;
        for f in &mut self.fw {
            due |= f.due(t);
        }
        let update = self.updates;
        self.updates += due as usize;
        for b in 0..self.nb {
            let row = b * nu..(b + 1) * nu;
            self.sensing[b].remember_with(|qs, vs| {
                qs.extend_from_slice(&q[row.clone()]);
                vs.extend_from_slice(&v[row.clone()]);
            });
            for a in 0..nu {
                let i = b * nu + a;
                let (qr, vr) = self.sensing[b].late(a).unwrap_or((q[i], v[i]));
                if due {
                    let target = delayed(control, b, a, k, self.delay_steps[i]);
                    let (kp, kd) = (self.servo.kp[i], self.servo.kd[i]);
                    let seen = match &self.noise {
                        Some((draws, sign)) => qr + sign[b] * draws[update * nu + a],
                        None => qr,
                    };
                    self.fw[b].update(a, kp, kd, target, seen, vr);
                    if let Some(clean) = self.clean.as_mut() {
                        clean[b].update(a, kp, kd, target, qr, vr);
                    }
                }
                // the motor's band at the joint's own speed
                let (tau, _) = self.fw[b].deliver(a, self.servo.peak[i], v[i]);
                ctrl[i] = tau;
                sensed[i] = match self.clean.as_mut() {
                    Some(clean) => clean[b].deliver(a, self.servo.peak[i], v[i]).0,
                    None => tau,
                };
            }
        }
    }
}

/// Rollout b's target of actuator a `steps` before sample k, linearly
/// between the two samples around it (the first sample before the start).
fn delayed(
    control: &dyn Fn(usize, usize, usize) -> f64,
    b: usize,
    a: usize,
    k: usize,
    steps: f64,
) -> f64 {
    let at = (k as f64 - steps).max(0.0);
    let i0 = at.floor() as usize;
    let frac = at - i0 as f64;
    let i1 = (i0 + 1).min(k);
    control(b, i0, a) * (1.0 - frac) + control(b, i1, a) * frac
}

#[cfg(test)]
mod tests {
    use super::*;

    fn servo(nb: usize, kp: f64, kd: f64, delay: f64, latency: f64, lag: f64) -> ReplayServo {
        ReplayServo {
            kp: vec![kp; nb],
            kd: vec![kd; nb],
            delay: vec![delay; nb],
            latency: vec![latency; nb],
            lag: vec![lag; nb],
            peak: vec![3.0; nb],
        }
    }

    /// One joint of inertia `j` stepped as MuJoCo's semi-implicit Euler
    /// steps it under the replay's torques, against a target `target(i)`.
    fn run(r: &mut Replay, j: f64, dt: f64, n: usize, target: &dyn Fn(usize) -> f64) -> Vec<f64> {
        let (mut q, mut v) = (0.0, 0.0);
        let mut out = Vec::new();
        let control = |_b: usize, i: usize, _a: usize| target(i);
        for k in 0..n {
            let (mut ctrl, mut sensed) = ([0.0], [0.0]);
            r.step(k, &[q], &[v], &control, &mut ctrl, &mut sensed);
            v += dt * ctrl[0] / j;
            q += dt * v;
            out.push(q);
        }
        out
    }

    #[test]
    fn a_command_delay_shifts_the_response_by_whole_and_part_steps() {
        // an ideal servo: delayed by 3.5 steps, the response to a ramp is the
        // undelayed one's 3.5 steps later (the ramp interpolates exactly)
        let dt = 0.002;
        let ramp = |i: usize| 0.001 * i as f64;
        let motor = ReplayMotor::default();
        let mut now =
            Replay::new(&motor, 1, 1, dt, servo(1, 5.0, 0.2, 0.0, 0.0, 0.0), None).unwrap();
        let mut late =
            Replay::new(&motor, 1, 1, dt, servo(1, 5.0, 0.2, 0.007, 0.0, 0.0), None).unwrap();
        let a = run(&mut now, 0.002, dt, 400, &|i| ramp(i));
        let b = run(&mut late, 0.002, dt, 400, &|i| ramp(i));
        // after the start, the delayed ramp is the ramp less 3.5 samples
        let shifted = run(
            &mut Replay::new(&motor, 1, 1, dt, servo(1, 5.0, 0.2, 0.0, 0.0, 0.0), None).unwrap(),
            0.002,
            dt,
            400,
            &|i| (0.001 * (i as f64 - 3.5)).max(0.0),
        );
        assert!(
            (b[399] - shifted[399]).abs() < 1e-12,
            "{} vs {}",
            b[399],
            shifted[399]
        );
        assert!(a[399] > b[399]);
    }

    #[test]
    fn the_lag_and_the_latency_are_the_torque_mode_firmwares() {
        // a 10 ms lag: the first torque is the PD's, then it follows the
        // PD's step as 1 − exp(−k dt / T), as torque mode's firmware does
        let dt = 0.002;
        let motor = ReplayMotor::default();
        let mut r =
            Replay::new(&motor, 1, 1, dt, servo(1, 1.0, 0.0, 0.0, 0.0, 0.01), None).unwrap();
        let target = |_b: usize, i: usize, _a: usize| if i == 0 { 0.0 } else { 1.0 };
        let mut got = Vec::new();
        for k in 0..5 {
            let (mut c, mut s) = ([0.0], [0.0]);
            r.step(k, &[0.0], &[0.0], &target, &mut c, &mut s);
            got.push(c[0]);
        }
        assert_eq!(got[0], 0.0);
        for (k, y) in got.iter().enumerate().skip(1) {
            let want = 1.0 - (-(k as f64) * dt / 0.01).exp();
            assert!((y - want).abs() < 1e-12, "{k}: {y} vs {want}");
        }
        // a 4.5 ms latency on an ideal servo reads the state 2 steps old
        // (4.5 ms less the quarter step a PD every step already acts late)
        let mut r =
            Replay::new(&motor, 1, 1, dt, servo(1, 1.0, 0.0, 0.0, 0.0045, 0.0), None).unwrap();
        let zero = |_b: usize, _i: usize, _a: usize| 0.0;
        let mut torques = Vec::new();
        for k in 0..6 {
            let (mut c, mut s) = ([0.0], [0.0]);
            r.step(k, &[k as f64], &[0.0], &zero, &mut c, &mut s);
            torques.push(c[0]);
        }
        // the PD (kp 1, target 0) reads q = k − 2 from step 2 on, 0 before
        assert_eq!(torques, vec![-0.0, -0.0, -0.0, -1.0, -2.0, -3.0]);
    }

    #[test]
    fn the_noise_is_read_with_each_rollouts_sign_and_the_sensor_is_clean() {
        let dt = 0.002;
        let motor = ReplayMotor::default();
        let noise = (vec![0.01, -0.02, 0.03], vec![1.0, -1.0]);
        let mut r = Replay::new(
            &motor,
            2,
            1,
            dt,
            servo(2, 10.0, 0.0, 0.0, 0.0, 0.0),
            Some(noise),
        )
        .unwrap();
        let zero = |_b: usize, _i: usize, _a: usize| 0.0;
        let (mut c, mut s) = ([0.0; 2], [0.0; 2]);
        r.step(0, &[0.0, 0.0], &[0.0, 0.0], &zero, &mut c, &mut s);
        // the PD reads +0.01 on the first rollout, −0.01 on its mirror
        assert_eq!(c, [-0.1, 0.1]);
        assert_eq!(s, [0.0, 0.0]);
        r.step(1, &[0.0, 0.0], &[0.0, 0.0], &zero, &mut c, &mut s);
        assert_eq!(c, [0.2, -0.2]);
    }
}
