//! One leg of three hinges (abduction, hip, knee in any chain order, the
//! knee last) as the compiled model measures it: each joint's anchor and
//! axis and the foot's centre at the default pose, in the base frame. Its
//! forward kinematics, and an inverse kinematics in closed form where the
//! first two joints' axes meet (Pupper v3, trotter-style legs, most
//! quadrupeds), polished by Newton's method where they miss by an offset.

use serde::{Deserialize, Serialize};

pub type V3 = [f64; 3];

pub(crate) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale(a: V3, k: f64) -> V3 {
    [a[0] * k, a[1] * k, a[2] * k]
}

pub(crate) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

/// `v` turned by `angle` about the unit axis `u` (Rodrigues).
pub(crate) fn rotate(v: V3, u: V3, angle: f64) -> V3 {
    let (s, c) = angle.sin_cos();
    let k = dot(u, v) * (1.0 - c);
    let x = cross(u, v);
    [
        v[0] * c + x[0] * s + u[0] * k,
        v[1] * c + x[1] * s + u[1] * k,
        v[2] * c + x[2] * s + u[2] * k,
    ]
}

/// The signed angle that turns `a` onto `b` about the unit axis `u`, both
/// projected onto the plane normal to `u`.
fn angle_about(a: V3, b: V3, u: V3) -> f64 {
    let flat = |v: V3| sub(v, scale(u, dot(v, u)));
    let (a, b) = (flat(a), flat(b));
    dot(u, cross(a, b)).atan2(dot(a, b))
}

/// `a` in (-pi, pi].
fn wrap(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    // the angles here are within a turn or two of each other: a step or two
    // is cheaper than a division
    if a.abs() > 4.0 * PI {
        let w = a.rem_euclid(TAU);
        return if w > PI { w - TAU } else { w };
    }
    let mut w = a;
    while w > PI {
        w -= TAU;
    }
    while w <= -PI {
        w += TAU;
    }
    w
}

/// The angle nearest `seed` that equals `a` modulo a turn.
fn near(a: f64, seed: f64) -> f64 {
    seed + wrap(a - seed)
}

/// How far a solved foot may lie from where it was asked to be (m) before
/// the closed form is polished: exact geometry solves to rounding.
const EXACT: f64 = 1e-10;
/// Newton steps of the polish; each squares the error near the answer.
const POLISH_STEPS: usize = 12;

/// A leg's chain at the default pose, in the base frame (m).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Leg {
    /// The leg's first body, as `pupper info` names it.
    pub name: String,
    /// Where it sits on the body: front or back, left or right of the hips' centre.
    pub front: bool,
    pub left: bool,
    /// Each joint's anchor and unit axis, in chain order (the knee last).
    pub anchors: [V3; 3],
    pub axes: [V3; 3],
    /// The foot's centre.
    pub foot: V3,
    /// The foot's radius: its centre stands this high on the floor.
    pub radius: f64,
    /// The actuator of each joint, in chain order.
    pub actuators: [usize; 3],
    /// Each joint's angle at the default pose (MuJoCo's qpos0): the angles
    /// of [`Leg::foot_at`] are measured from it.
    pub zero: [f64; 3],
    /// Each joint's range as turns from the default pose (chain order);
    /// unlimited joints span a turn each way. Where two branches reach a
    /// point (a knee bent either way from straight), the one inside wins.
    #[serde(default = "any_turn")]
    pub ranges: [[f64; 2]; 3],
}

fn any_turn() -> [[f64; 2]; 3] {
    [[-std::f64::consts::TAU, std::f64::consts::TAU]; 3]
}

/// How far `q` lies outside `range` (0 inside).
fn outside(q: f64, [lo, hi]: [f64; 2]) -> f64 {
    (lo - q).max(q - hi).max(0.0)
}

impl Leg {
    /// The foot's centre with the joints turned `q` from the default pose.
    pub fn foot_at(&self, q: [f64; 3]) -> V3 {
        let mut f = self.foot;
        // the last joint turns first: every axis is taken at the default
        // pose, where the joints before it have not turned it yet
        for i in (0..3).rev() {
            f = add(
                rotate(sub(f, self.anchors[i]), self.axes[i], q[i]),
                self.anchors[i],
            );
        }
        f
    }

    /// The point where the first two joints' axes meet (the midpoint of
    /// their common perpendicular where they miss).
    pub fn shoulder(&self) -> V3 {
        let (a, b) = self.nearest();
        scale(add(a, b), 0.5)
    }

    /// The points of the first two joints' axes nearest each other (the
    /// first anchor twice for parallel axes).
    fn nearest(&self) -> (V3, V3) {
        let [p1, p2, _] = self.anchors;
        let [u1, u2, _] = self.axes;
        let w = sub(p1, p2);
        let b = dot(u1, u2);
        let (d, e) = (dot(u1, w), dot(u2, w));
        let den = 1.0 - b * b;
        if den.abs() < 1e-12 {
            return (p1, p1);
        }
        let t1 = (b * e - d) / den;
        let t2 = (e - b * d) / den;
        (add(p1, scale(u1, t1)), add(p2, scale(u2, t2)))
    }

    /// The farthest the foot's centre gets from the shoulder (m): the
    /// knee turned to stretch the leg most.
    pub fn reach(&self) -> f64 {
        let (base, a, b) = self.knee_terms();
        (base + 2.0 * a.hypot(b)).max(0.0).sqrt()
    }

    /// The squared distance of the foot from the shoulder as the knee
    /// turns by q is `base + 2 (a cos q + b sin q)`: (base, a, b).
    fn knee_terms(&self) -> (f64, f64, f64) {
        let (p3, u3) = (self.anchors[2], self.axes[2]);
        let c = sub(p3, self.shoulder());
        let v = sub(self.foot, p3);
        let (cu, uv) = (dot(c, u3), dot(u3, v));
        (
            dot(c, c) + dot(v, v) + 2.0 * cu * uv,
            dot(c, v) - cu * uv,
            dot(c, cross(u3, v)),
        )
    }

    /// The turns from the default pose that put the foot's centre at `p`,
    /// on the branch nearest `seed` (the knee bent the way it is there).
    /// A point out of reach gets the nearest pose the leg has.
    pub fn solve(&self, p: V3, seed: [f64; 3]) -> [f64; 3] {
        let s = self.shoulder();
        let (p3, u3) = (self.anchors[2], self.axes[2]);
        // the knee: the rotations about axes through the shoulder keep the
        // foot's distance to it, which only the knee changes:
        // |c + R(u3, q) v|^2 = |p - s|^2
        let c = sub(p3, s);
        let v = sub(self.foot, p3);
        let (base, a, b) = self.knee_terms();
        let want = dot(sub(p, s), sub(p, s));
        let r = a.hypot(b);
        let phase = b.atan2(a);
        let half = if r > 0.0 {
            (((want - base) / 2.0) / r).clamp(-1.0, 1.0).acos()
        } else {
            0.0
        };
        // inside the knee's range first, then nearest the seed
        let cost = |k: f64| (outside(k, self.ranges[2]), (k - seed[2]).abs());
        let knee = [phase + half, phase - half]
            .map(|k| near(k, seed[2]))
            .into_iter()
            .min_by(|x, y| {
                cost(*x)
                    .partial_cmp(&cost(*y))
                    .unwrap_or(std::cmp::Ordering::Equal)
            })
            .unwrap_or(seed[2]);
        // the first two: turn w (the foot from the shoulder, knee set) onto
        // t about u2 then u1 (two rotations about meeting axes)
        let w = add(rotate(v, u3, knee), c);
        let t = sub(p, s);
        let [u1, u2, _] = self.axes;
        let k = dot(u1, u2);
        let den = k * k - 1.0;
        let n = cross(u1, u2);
        let (alpha, beta) = if den.abs() > 1e-12 {
            (
                (k * dot(u2, w) - dot(u1, t)) / den,
                (k * dot(u1, t) - dot(u2, w)) / den,
            )
        } else {
            (0.0, 0.0)
        };
        let g2 = (dot(w, w) - alpha * alpha - beta * beta - 2.0 * alpha * beta * k) / dot(n, n);
        let g = g2.max(0.0).sqrt();
        let mut best = ((f64::INFINITY, f64::INFINITY), seed[0], seed[1]);
        for gamma in [g, -g] {
            let z = add(add(scale(u1, alpha), scale(u2, beta)), scale(n, gamma));
            let q2 = near(angle_about(w, z, u2), seed[1]);
            let q1 = near(angle_about(z, t, u1), seed[0]);
            // inside the ranges first, then nearest the seed
            let cost = (
                outside(q1, self.ranges[0]) + outside(q2, self.ranges[1]),
                (q1 - seed[0]).abs() + (q2 - seed[1]).abs(),
            );
            if cost < best.0 {
                best = (cost, q1, q2);
            }
        }
        let q = [best.1, best.2, knee];
        // axes that meet: the closed form is exact (to rounding)
        let (a, b) = self.nearest();
        if norm(sub(a, b)) < 1e-12 {
            return q;
        }
        self.polish(p, q)
    }

    /// Newton's method on the foot's position from `q`, for axes that miss
    /// each other by an offset (none of it where they meet).
    fn polish(&self, p: V3, mut q: [f64; 3]) -> [f64; 3] {
        for _ in 0..POLISH_STEPS {
            let e = sub(p, self.foot_at(q));
            if norm(e) <= EXACT {
                break;
            }
            // each column: the foot's velocity for a unit turn of a joint,
            // that joint's axis and anchor carried by the joints before it
            let mut cols = [[0.0; 3]; 3];
            let f = self.foot_at(q);
            for (i, col) in cols.iter_mut().enumerate() {
                let mut u = self.axes[i];
                let mut a = self.anchors[i];
                for j in (0..i).rev() {
                    u = rotate(u, self.axes[j], q[j]);
                    a = add(
                        rotate(sub(a, self.anchors[j]), self.axes[j], q[j]),
                        self.anchors[j],
                    );
                }
                *col = cross(u, sub(f, a));
            }
            let Some(dq) = solve3(cols, e) else { break };
            for i in 0..3 {
                q[i] += dq[i];
            }
        }
        q
    }
}

/// `x` with `sum_i x_i cols[i] = e` (Cramer's rule); None when the columns
/// are (nearly) dependent: a straight knee.
fn solve3(cols: [V3; 3], e: V3) -> Option<V3> {
    let det = dot(cols[0], cross(cols[1], cols[2]));
    if det.abs() < 1e-15 {
        return None;
    }
    Some([
        dot(e, cross(cols[1], cols[2])) / det,
        dot(cols[0], cross(e, cols[2])) / det,
        dot(cols[0], cross(cols[1], e)) / det,
    ])
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Pupper v3's front right leg as the compiled model measures it (base
    /// frame): hip flexion first, abduction second on the same anchor, the
    /// knee; the foot 2 cm in radius.
    pub fn pupper_front_right() -> Leg {
        Leg {
            name: "leg_front_r_1".into(),
            front: true,
            left: false,
            anchors: [
                [0.075, -0.0835, 0.0],
                [0.075, -0.0835, 0.0],
                [0.0065, -0.0835, -0.0494],
            ],
            axes: [[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]],
            foot: [0.06881, -0.1015, -0.11156],
            radius: 0.02,
            actuators: [0, 1, 2],
            zero: [0.0; 3],
            ranges: super::any_turn(),
        }
    }

    /// A textbook leg: abduction about x at the hip, a 0.07 m offset out
    /// along y to the hip pitch, thigh and calf 0.21 m straight down.
    pub fn textbook() -> Leg {
        Leg {
            name: "fl_hip".into(),
            front: true,
            left: true,
            anchors: [[0.19, 0.06, 0.0], [0.19, 0.13, 0.0], [0.19, 0.13, -0.21]],
            axes: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
            foot: [0.19, 0.13, -0.42],
            radius: 0.022,
            actuators: [0, 4, 8],
            zero: [0.0; 3],
            ranges: super::any_turn(),
        }
    }

    fn close(a: V3, b: V3, tol: f64) -> bool {
        norm(sub(a, b)) <= tol
    }

    #[test]
    fn forward_kinematics_has_known_answers() {
        let l = textbook();
        assert!(close(l.foot_at([0.0; 3]), l.foot, 1e-15));
        // the knee at -90 degrees (about +y: the calf turns forward, +x)
        let f = l.foot_at([0.0, 0.0, -std::f64::consts::FRAC_PI_2]);
        assert!(close(f, [0.19 + 0.21, 0.13, -0.21], 1e-12), "{f:?}");
        // abduction by 90 degrees about +x swings the leg out to +y... from
        // below the hip: (y, z) = (0.07, -0.42) -> (0.42, 0.07) about (0.06, 0)
        let f = l.foot_at([std::f64::consts::FRAC_PI_2, 0.0, 0.0]);
        assert!(close(f, [0.19, 0.06 + 0.42, 0.07], 1e-12), "{f:?}");
    }

    #[test]
    fn the_closed_form_matches_the_law_of_cosines() {
        // a planar two-link leg (no abduction): thigh and calf 0.21 m; the
        // foot 0.3 m below the hip pitch: the knee bends by
        // acos((0.21^2 + 0.21^2 - 0.3^2) / (2 0.21 0.21)) from straight
        let l = textbook();
        let p = [0.19, 0.13, -0.3];
        let q = l.solve(p, [0.0, 0.5, -1.0]);
        let inner = ((0.21f64.powi(2) * 2.0 - 0.09) / (2.0 * 0.21 * 0.21)).acos();
        let knee = -(std::f64::consts::PI - inner);
        assert!((q[2] - knee).abs() < 1e-12, "{q:?} {knee}");
        // the hip splits the bend: the thigh leans half of it forward
        assert!((q[1] + knee / 2.0).abs() < 1e-12, "{q:?}");
        assert!(q[0].abs() < 1e-12, "{q:?}");
        assert!(close(l.foot_at(q), p, 1e-12));
    }

    #[test]
    fn inverse_then_forward_returns_the_point() {
        // points the legs reach, from poses around their stance
        for leg in [textbook(), pupper_front_right()] {
            let mut worst = 0.0f64;
            for i in 0..9 {
                for j in 0..9 {
                    for k in 0..5 {
                        let q = [
                            -0.4 + 0.1 * i as f64,
                            -0.4 + 0.1 * j as f64,
                            if leg.name == "fl_hip" { -0.4 } else { 0.4 } * (0.5 + 0.25 * k as f64),
                        ];
                        let p = leg.foot_at(q);
                        let back = leg.solve(p, q.map(|x| x * 0.5));
                        worst = worst.max(norm(sub(leg.foot_at(back), p)));
                    }
                }
            }
            assert!(worst < 1e-12, "{}: {worst}", leg.name);
        }
    }

    #[test]
    fn the_branch_is_the_seeds() {
        // a bent knee either way reaches the same point: the seed decides
        let l = textbook();
        let p = [0.19, 0.13, -0.3];
        let back = l.solve(p, [0.0, 0.5, -1.0]);
        let fore = l.solve(p, [0.0, -0.5, 1.0]);
        assert!(back[2] < 0.0 && fore[2] > 0.0, "{back:?} {fore:?}");
        assert!(close(l.foot_at(back), p, 1e-12) && close(l.foot_at(fore), p, 1e-12));
    }

    #[test]
    fn from_a_straight_knee_the_range_picks_the_branch() {
        // the knee straight at the seed: bent either way reaches the point
        let mut l = textbook();
        let p = [0.19, 0.13, -0.3];
        l.ranges[2] = [-2.7, 0.0];
        assert!(l.solve(p, [0.0; 3])[2] < 0.0);
        l.ranges[2] = [0.0, 2.7];
        let q = l.solve(p, [0.0; 3]);
        assert!(q[2] > 0.0 && close(l.foot_at(q), p, 1e-12), "{q:?}");
    }

    #[test]
    fn axes_that_miss_are_polished_to_the_point() {
        // the hip pitch 1 cm below the abduction axis: the axes miss
        let mut l = textbook();
        l.anchors[1][2] = -0.01;
        l.anchors[2][2] = -0.22;
        for q in [[0.2, 0.3, -0.9], [-0.3, -0.2, -1.2], [0.0, 0.6, -0.5]] {
            let p = l.foot_at(q);
            let back = l.solve(p, [0.0, 0.4, -1.0]);
            assert!(close(l.foot_at(back), p, 1e-10), "{q:?} -> {back:?}");
        }
    }

    #[test]
    fn a_point_out_of_reach_gets_the_nearest_pose() {
        let l = textbook();
        // the knee straight: 0.42 m below the hip pitch, 0.07 m out of the
        // abduction axis
        let reach = 0.07f64.hypot(0.42);
        assert!((l.reach() - reach).abs() < 1e-12, "{}", l.reach());
        let q = l.solve([0.19, 0.06, -0.9], [0.0, 0.5, -1.0]);
        assert!(q.iter().all(|x| x.is_finite()));
        let f = l.foot_at(q);
        assert!((norm(sub(f, l.shoulder())) - reach).abs() < 1e-9, "{f:?}");
    }
}
