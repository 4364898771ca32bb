//! The joint-space PD law of torque mode: `tau = kp (q* - q) - kd qdot`,
//! clipped to `[-max, max]`.

/// The law before any limit.
#[inline]
pub fn law(kp: f64, kd: f64, target: f64, q: f64, qdot: f64) -> f64 {
    kp * (target - q) - kd * qdot
}

/// One joint's torque, and whether the limit cut it.
#[inline]
pub fn torque(kp: f64, kd: f64, target: f64, q: f64, qdot: f64, max: f64) -> (f64, bool) {
    let raw = law(kp, kd, target, q, qdot);
    let clipped = raw.clamp(-max, max);
    (clipped, raw.abs() > max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_answers() {
        // 10 * (0.5 - 0.2) - 2 * 0.1 = 2.8
        let (t, sat) = torque(10.0, 2.0, 0.5, 0.2, 0.1, 3.0);
        assert!((t - 2.8).abs() < 1e-12);
        assert!(!sat);
        let (t, sat) = torque(100.0, 0.0, 1.0, 0.0, 0.0, 3.0);
        assert_eq!(t, 3.0);
        assert!(sat);
        let (t, sat) = torque(100.0, 0.0, -1.0, 0.0, 0.0, 3.0);
        assert_eq!(t, -3.0);
        assert!(sat);
        // pure damping opposes velocity
        let (t, _) = torque(0.0, 0.5, 0.0, 0.0, 2.0, 3.0);
        assert_eq!(t, -1.0);
    }

    #[test]
    fn exactly_at_limit_is_not_saturated() {
        let (t, sat) = torque(3.0, 0.0, 1.0, 0.0, 0.0, 3.0);
        assert_eq!(t, 3.0);
        assert!(!sat);
    }
}
