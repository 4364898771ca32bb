//! Base orientation from MuJoCo's `(w, x, y, z)` quaternion.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// Roll, pitch, yaw (rad), intrinsic x-y-z as nalgebra defines them.
pub fn roll_pitch_yaw(wxyz: [f64; 4]) -> (f64, f64, f64) {
    let q = UnitQuaternion::from_quaternion(Quaternion::new(wxyz[0], wxyz[1], wxyz[2], wxyz[3]));
    q.euler_angles()
}

/// Angle (rad) between the body z axis and world z: how far the base leans,
/// whatever the heading.
pub fn tilt(wxyz: [f64; 4]) -> f64 {
    let q = UnitQuaternion::from_quaternion(Quaternion::new(wxyz[0], wxyz[1], wxyz[2], wxyz[3]));
    let up = q * Vector3::z();
    up.z.clamp(-1.0, 1.0).acos()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn about(axis: [f64; 3], angle: f64) -> [f64; 4] {
        let (s, c) = (angle / 2.0).sin_cos();
        [c, s * axis[0], s * axis[1], s * axis[2]]
    }

    #[test]
    fn identity() {
        assert_eq!(roll_pitch_yaw([1.0, 0.0, 0.0, 0.0]), (0.0, 0.0, 0.0));
        assert_eq!(tilt([1.0, 0.0, 0.0, 0.0]), 0.0);
    }

    #[test]
    fn single_axis_rotations() {
        let (r, p, y) = roll_pitch_yaw(about([1.0, 0.0, 0.0], 0.3));
        assert!((r - 0.3).abs() < 1e-12 && p.abs() < 1e-12 && y.abs() < 1e-12);
        let (r, p, y) = roll_pitch_yaw(about([0.0, 1.0, 0.0], -0.2));
        assert!(r.abs() < 1e-12 && (p + 0.2).abs() < 1e-12 && y.abs() < 1e-12);
        let (r, p, y) = roll_pitch_yaw(about([0.0, 0.0, 1.0], 1.0));
        assert!(r.abs() < 1e-12 && p.abs() < 1e-12 && (y - 1.0).abs() < 1e-12);
    }

    #[test]
    fn tilt_ignores_yaw() {
        assert!(tilt(about([0.0, 0.0, 1.0], 2.0)).abs() < 1e-12);
        assert!((tilt(about([1.0, 0.0, 0.0], 0.4)) - 0.4).abs() < 1e-12);
        assert!((tilt(about([0.0, 1.0, 0.0], FRAC_PI_2)) - FRAC_PI_2).abs() < 1e-12);
        // upside down
        assert!((tilt([0.0, 1.0, 0.0, 0.0]) - std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn unnormalised_input_is_normalised() {
        let q = about([1.0, 0.0, 0.0], 0.5).map(|c| c * 3.0);
        assert!((tilt(q) - 0.5).abs() < 1e-12);
    }
}
