//! A gait as schedule and kinematics: each leg's phase in the cycle, and
//! where its foot is (base frame) at a phase. Stance feet move under the
//! body at the commanded velocity (forward, sideways, yaw rate); swing
//! feet lift by the step height and land where a Raibert-style rule puts
//! them: half a stance's travel ahead of their nominal place, so the stance
//! sweeps symmetrically under the hip.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::plan::walk::leg::V3;

/// The footfall pattern.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Pattern {
    /// Diagonal pairs together (front left with back right).
    Trot,
    /// A four-beat walk: left front, right back, right front, left back,
    /// a quarter cycle apart.
    Walk,
    /// Lateral pairs together (both left legs, then both right).
    Pace,
    /// Front pair, then back pair.
    Bound,
}

impl Pattern {
    pub const ALL: [Pattern; 4] = [Pattern::Trot, Pattern::Walk, Pattern::Pace, Pattern::Bound];

    pub fn name(self) -> &'static str {
        match self {
            Pattern::Trot => "trot",
            Pattern::Walk => "walk",
            Pattern::Pace => "pace",
            Pattern::Bound => "bound",
        }
    }

    pub fn parse(text: &str) -> Result<Pattern> {
        let t = text.trim().to_ascii_lowercase();
        Pattern::ALL
            .into_iter()
            .find(|p| p.name() == t)
            .ok_or_else(|| {
                Error::Config(format!(
                    "unknown gait '{}': use trot, walk, pace or bound",
                    text.trim()
                ))
            })
    }

    /// When a leg's stance starts, as a fraction of the cycle.
    pub fn offset(self, front: bool, left: bool) -> f64 {
        match (self, front, left) {
            (Pattern::Trot, true, true) | (Pattern::Trot, false, false) => 0.0,
            (Pattern::Trot, _, _) => 0.5,
            (Pattern::Pace, _, true) => 0.0,
            (Pattern::Pace, _, false) => 0.5,
            (Pattern::Bound, true, _) => 0.0,
            (Pattern::Bound, false, _) => 0.5,
            (Pattern::Walk, true, true) => 0.0,
            (Pattern::Walk, false, false) => 0.25,
            (Pattern::Walk, true, false) => 0.5,
            (Pattern::Walk, false, true) => 0.75,
        }
    }

    /// The duty factor unless told: a four-beat walk keeps three feet
    /// down (0.75); the two-beat gaits overlap their stances a little.
    pub fn default_duty(self) -> f64 {
        match self {
            Pattern::Walk => 0.75,
            _ => 0.6,
        }
    }
}

/// One cell's gait: its pattern and numbers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gait {
    pub pattern: Pattern,
    /// Cycles per second (Hz).
    pub frequency: f64,
    /// The share of a cycle each foot is down.
    pub duty: f64,
    /// How high a swing lifts the foot (m).
    pub step_height: f64,
    /// Commanded forward and sideways speed (m/s, base frame) and yaw
    /// rate (rad/s), at full ramp.
    pub velocity: [f64; 3],
}

impl Gait {
    /// Seconds a foot is down.
    pub fn stance_time(&self) -> f64 {
        self.duty / self.frequency
    }

    /// Where a foot whose nominal place is `nominal` stands, `phase` of
    /// the cycle after its stance began, at velocity `v` (forward,
    /// sideways, yaw rate); and whether it is down.
    pub fn foot(&self, nominal: V3, phase: f64, v: [f64; 3]) -> (V3, bool) {
        let stance = self.stance_time();
        // a stance s in [0, 1] from touchdown: the foot moves against the
        // body's motion, centred on its nominal place
        let at = |s: f64| -> V3 {
            let tau = (s - 0.5) * stance;
            let (sin, cos) = match v[2] {
                0.0 => (0.0, 1.0),
                w => (-w * tau).sin_cos(),
            };
            [
                nominal[0] * cos - nominal[1] * sin - v[0] * tau,
                nominal[0] * sin + nominal[1] * cos - v[1] * tau,
                nominal[2],
            ]
        };
        let phase = phase.rem_euclid(1.0);
        if phase < self.duty {
            return (at(phase / self.duty), true);
        }
        // a swing from liftoff (stance end) to touchdown (stance start):
        // across in a half cosine, up and down in a sine squared, both
        // still at liftoff and touchdown
        let s = (phase - self.duty) / (1.0 - self.duty);
        let (lo, td) = (at(1.0), at(0.0));
        let across = 0.5 * (1.0 - (std::f64::consts::PI * s).cos());
        let lift = (std::f64::consts::PI * s).sin().powi(2);
        (
            [
                lo[0] + (td[0] - lo[0]) * across,
                lo[1] + (td[1] - lo[1]) * across,
                nominal[2] + self.step_height * lift,
            ],
            false,
        )
    }

    /// The points a foot whose nominal place is `nominal` passes through
    /// at full speed: touchdown, liftoff and the top of the swing (for a
    /// check of reach before anything runs).
    pub fn extremes(&self, nominal: V3) -> [V3; 3] {
        let v = self.velocity;
        let swing_top = self.duty + 0.5 * (1.0 - self.duty);
        [
            self.foot(nominal, 0.0, v).0,
            self.foot(nominal, self.duty - 1e-12, v).0,
            self.foot(nominal, swing_top, v).0,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trot() -> Gait {
        Gait {
            pattern: Pattern::Trot,
            frequency: 2.0,
            duty: 0.5,
            step_height: 0.04,
            velocity: [0.2, 0.0, 0.0],
        }
    }

    #[test]
    fn patterns_pair_their_legs() {
        let o = |p: Pattern| {
            [(true, true), (true, false), (false, true), (false, false)]
                .map(|(f, l)| p.offset(f, l))
        };
        // front left, front right, back left, back right
        assert_eq!(o(Pattern::Trot), [0.0, 0.5, 0.5, 0.0]);
        assert_eq!(o(Pattern::Pace), [0.0, 0.5, 0.0, 0.5]);
        assert_eq!(o(Pattern::Bound), [0.0, 0.0, 0.5, 0.5]);
        assert_eq!(o(Pattern::Walk), [0.0, 0.5, 0.75, 0.25]);
        assert_eq!(Pattern::parse(" Bound").unwrap(), Pattern::Bound);
        let e = Pattern::parse("gallop").unwrap_err().to_string();
        assert!(e.contains("trot, walk, pace or bound"), "{e}");
    }

    #[test]
    fn a_stance_sweeps_its_travel_centred_on_the_nominal_place() {
        let g = trot();
        let nominal = [0.1, -0.08, -0.11];
        // 0.25 s of stance at 0.2 m/s: 5 cm, from 2.5 cm ahead to 2.5 cm behind
        let (td, down) = g.foot(nominal, 0.0, g.velocity);
        assert!(down);
        assert!((td[0] - 0.125).abs() < 1e-12 && (td[1] + 0.08).abs() < 1e-15);
        let (mid, _) = g.foot(nominal, 0.25, g.velocity);
        assert!((mid[0] - 0.1).abs() < 1e-12 && mid[2] == -0.11);
        let (lo, _) = g.foot(nominal, 0.5 - 1e-12, g.velocity);
        assert!((lo[0] - 0.075).abs() < 1e-9);
    }

    #[test]
    fn a_swing_lifts_by_the_step_height_and_lands_at_touchdown() {
        let g = trot();
        let nominal = [0.1, -0.08, -0.11];
        let (top, down) = g.foot(nominal, 0.75, g.velocity);
        assert!(!down);
        // half-way across at the top, the step height above the stance
        assert!((top[0] - 0.1).abs() < 1e-12, "{top:?}");
        assert!((top[2] - (-0.11 + 0.04)).abs() < 1e-15);
        // the swing ends where the next stance begins, on the floor
        let (end, _) = g.foot(nominal, 1.0 - 1e-12, g.velocity);
        assert!((end[0] - 0.125).abs() < 1e-9 && (end[2] + 0.11).abs() < 1e-9);
        assert_eq!(
            g.foot(nominal, 1.0, g.velocity),
            g.foot(nominal, 0.0, g.velocity)
        );
    }

    #[test]
    fn a_turn_rotates_the_stance_about_the_body() {
        let g = Gait {
            velocity: [0.0, 0.0, 1.0],
            ..trot()
        };
        let nominal = [0.1, 0.0, -0.1];
        // at touchdown the foot is turned +0.125 rad ahead of the turn
        let (td, _) = g.foot(nominal, 0.0, g.velocity);
        let a: f64 = 0.125;
        assert!((td[0] - 0.1 * a.cos()).abs() < 1e-12 && (td[1] - 0.1 * a.sin()).abs() < 1e-12);
        let (side, _) = Gait {
            velocity: [0.0, 0.2, 0.0],
            ..trot()
        }
        .foot(nominal, 0.0, [0.0, 0.2, 0.0]);
        assert!((side[1] - 0.025).abs() < 1e-12 && (side[0] - 0.1).abs() < 1e-15);
    }

    #[test]
    fn standing_still_the_feet_step_in_place() {
        let g = trot();
        let nominal = [0.1, -0.08, -0.11];
        for k in 0..20 {
            let (p, _) = g.foot(nominal, k as f64 / 20.0, [0.0; 3]);
            assert!((p[0] - 0.1).abs() < 1e-15 && (p[1] + 0.08).abs() < 1e-15);
        }
        let [td, lo, top] = g.extremes(nominal);
        assert!(td[0] > lo[0] && (top[2] - (-0.07)).abs() < 1e-12);
    }
}
