//! A stand pose for any leg geometry: the chapter's planar two-link grid
//! search, run on the hip, knee and foot positions measured on the compiled
//! body (so a long-leg variant gets its own pose).
//!
//! Abduction stays at 0; hip flexion (HFE) and knee (KFE) are searched on a
//! grid inside every leg's joint range, rotating the leg's measured thigh
//! and calf vectors about the joints' real axes. The score is the chapter's:
//! `(z - target)^2 + 0.25 x^2 + 0.002 (phi - 0.70)^2`, with the foot at
//! `(x, z)` from the hip. Its last term is, in the chapter's words, "only a
//! slight preference for a naturally bent leg, so that no odd folded
//! solution is picked": it chooses among the poses that reach the target
//! (within 0.5 mm), and never pulls the feet off it (on Pupper v3's legs the
//! plain weighted sum settles 2.2 mm behind the hips, farther at other
//! depths). The chapter writes its last term on a skeleton
//! whose thigh hangs straight down at HFE = 0, so there HFE *is* `phi`, the
//! thigh's angle from the downward vertical, positive towards the side the
//! knee juts when it bends: the term prefers a symmetric bend. On another
//! geometry the joint's zero means something else (Pupper v3's zero is
//! already a crouch), so `phi` is measured on the compiled legs, never read
//! off the joint value.
//!
//! The depth aimed at is the chapter's 0.14 m on Pupper v3's legs, scaled to
//! a model's own leg length (thigh + calf) and, as the chapter does for its
//! variants, by `clamp(leg_scale, 1, 1.5)`; `--depth` sets it outright.
//! Angles are searched in the first leg's convention (Pupper: the right
//! legs', as the chapter's table is written) and mirrored onto each leg by
//! the direction of its own joint axes.

use serde::Serialize;

use crate::error::{Error, Result};
use crate::robot::model::{LegInfo, ModelInfo};

/// Grid spacing of the coarse search, and of the fine one around its best
/// point (rad): the score is smooth, so this finds the fine grid's optimum
/// at a tenth of the cost of searching the fine grid everywhere.
const COARSE: f64 = 0.02;
const FINE: f64 = 0.001;
/// How far from the grid's closest reach a pose may be and still count as
/// reaching the target (the square of a foot error, m^2): 4 mm on the
/// coarse grid (its spacing moves a Pupper foot by about 3 mm), 0.5 mm on
/// the fine one. Among those, the chapter's bend term picks.
const COARSE_REACH: f64 = 4e-3 * 4e-3;
const FINE_REACH: f64 = 0.5e-3 * 0.5e-3;
/// Gap left between the lowest foot and the floor at the start (m).
pub const CLEARANCE: f64 = 0.002;
/// The chapter's stand depth of the feet below the hips (m), on Pupper v3.
pub const CHAPTER_DEPTH: f64 = 0.14;
/// Thigh + calf of Pupper v3 (hip flexion axis to knee axis, knee axis to
/// the foot's centre), measured on models/pupper_v3: the legs the chapter's
/// depth was chosen for.
pub const PUPPER_LEG_LENGTH: f64 = 0.174_290_195_309_120_43;
/// The thigh angle the chapter's last score term prefers (rad).
const PREFERRED_THIGH: f64 = 0.70;

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StandPose {
    /// Joint targets in actuator order (also the start pose).
    pub targets: Vec<f64>,
    /// Base height that puts the lowest foot `CLEARANCE` above z = 0 (m).
    pub base_z: f64,
    /// HFE and KFE in the first leg's convention (rad).
    pub hfe: f64,
    pub kfe: f64,
    /// The first leg's thigh angle from the downward vertical, positive
    /// towards the side the knee juts (rad): the angle the score prefers
    /// near 0.70.
    pub thigh_angle: f64,
    /// Foot height below the hip that was aimed at (m, negative).
    pub target_z: f64,
    /// Where the depth came from: `scaled` (the chapter's, to this leg
    /// length) or `given`.
    pub depth_from: &'static str,
    /// The first leg's thigh + calf length (m).
    pub leg_length: f64,
    /// Each leg's foot position relative to its hip at the pose: (x, z) m.
    pub feet: Vec<(String, f64, f64)>,
}

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `v` rotated by `angle` about the unit axis `u` (Rodrigues).
fn rotate(v: V3, u: V3, angle: f64) -> V3 {
    let (s, c) = angle.sin_cos();
    let cross = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let k = dot(u, v) * (1.0 - c);
    [
        v[0] * c + cross[0] * s + u[0] * k,
        v[1] * c + cross[1] * s + u[1] * k,
        v[2] * c + cross[2] * s + u[2] * k,
    ]
}

/// The foot relative to the hip with HFE `h` and KFE `k` on this leg's joints.
fn foot(leg: &LegInfo, h: f64, k: f64) -> V3 {
    let thigh = sub(leg.knee, leg.hip);
    let calf = sub(leg.foot, leg.knee);
    // the knee joint turns with the thigh: rotate the calf about the knee
    // axis first, then both about the hip axis
    let calf = rotate(calf, leg.knee_axis, k);
    rotate(add(thigh, calf), leg.hip_axis, h)
}

/// +1 or -1: whether `leg`'s joint turns the same way as the reference's.
fn sense(axis: V3, reference: V3) -> f64 {
    if dot(axis, reference) >= 0.0 {
        1.0
    } else {
        -1.0
    }
}

/// A range in the reference convention, given a joint's range and sense.
fn in_reference(range: Option<[f64; 2]>, s: f64) -> [f64; 2] {
    let [lo, hi] = range.unwrap_or([-std::f64::consts::PI, std::f64::consts::PI]);
    if s > 0.0 { [lo, hi] } else { [-hi, -lo] }
}

fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The signed angle (rad) from `a` to `b` about the unit axis `u`, both
/// projected onto the plane normal to `u`.
fn angle_about(a: V3, b: V3, u: V3) -> f64 {
    let along = |v: V3| {
        let k = dot(v, u);
        [v[0] - k * u[0], v[1] - k * u[1], v[2] - k * u[2]]
    };
    let (a, b) = (along(a), along(b));
    dot(u, cross(a, b)).atan2(dot(a, b))
}

/// The depth (m, positive) of the feet below the hips a body aims at: the
/// chapter's 0.14 m scaled from Pupper v3's legs to the model's own (its
/// unscaled length, `leg_length / leg_scale`), times the chapter's
/// `clamp(leg_scale, 1, 1.5)` for longer-legged variants.
pub fn scaled_depth(leg_length: f64, leg_scale: f64) -> f64 {
    let own = leg_length / leg_scale;
    CHAPTER_DEPTH * (own / PUPPER_LEG_LENGTH) * leg_scale.clamp(1.0, 1.5)
}

/// The first leg's thigh + calf length (m).
pub fn leg_length(info: &ModelInfo) -> Option<f64> {
    info.legs
        .first()
        .map(|l| norm(sub(l.knee, l.hip)) + norm(sub(l.foot, l.knee)))
}

/// The hip and knee angles inside every leg's joint ranges, in the
/// convention of the first leg (whose axes are `ref_hip`, `ref_knee`).
fn shared_ranges(
    info: &ModelInfo,
    ref_hip: [f64; 3],
    ref_knee: [f64; 3],
) -> Result<([f64; 2], [f64; 2])> {
    let mut hr = [f64::NEG_INFINITY, f64::INFINITY];
    let mut kr = hr;
    for leg in &info.legs {
        let h = in_reference(
            info.joints[leg.joints[1]].range,
            sense(leg.hip_axis, ref_hip),
        );
        let k = in_reference(
            info.joints[leg.joints[2]].range,
            sense(leg.knee_axis, ref_knee),
        );
        hr = [hr[0].max(h[0]), hr[1].min(h[1])];
        kr = [kr[0].max(k[0]), kr[1].min(k[1])];
    }
    if !(hr[0] <= hr[1] && kr[0] <= kr[1]) {
        return Err(Error::Model(format!(
            "the legs of model '{}' share no hip or knee angle inside all their joint ranges: give --pose angles instead of auto",
            info.name
        )));
    }
    Ok((hr, kr))
}

/// The stand pose of a compiled body; `leg_scale` scales the target depth,
/// unless `depth` (m below the hips) is given.
pub fn stand_pose(info: &ModelInfo, leg_scale: f64, depth: Option<f64>) -> Result<StandPose> {
    let Some(first) = info.legs.first() else {
        return Err(Error::Model(format!(
            "model '{}' has no legs pupper can pose (a chain of abduction, hip and knee hinges under the base ending in a colliding foot): give --pose angles instead of auto",
            info.name
        )));
    };
    let (ref_hip, ref_knee) = (first.hip_axis, first.knee_axis);
    let (hr, kr) = shared_ranges(info, ref_hip, ref_knee)?;
    let leg_length = norm(sub(first.knee, first.hip)) + norm(sub(first.foot, first.knee));
    let (target_z, depth_from) = match depth {
        Some(d) => (-d, "given"),
        None => (-scaled_depth(leg_length, leg_scale), "scaled"),
    };
    let thigh_angle = thigh_angle_of(first, kr);
    let reach = |h: f64, k: f64| {
        let p = foot(first, h, k);
        (p[2] - target_z).powi(2) + 0.25 * p[0] * p[0]
    };
    let bend = |h: f64| 0.002 * (thigh_angle(h) - PREFERRED_THIGH).powi(2);
    let (h0, k0) = grid_min(hr, kr, COARSE, COARSE_REACH, &reach, &bend);
    let near = |r: [f64; 2], c: f64| [(c - 2.0 * COARSE).max(r[0]), (c + 2.0 * COARSE).min(r[1])];
    let (hfe, kfe) = grid_min(near(hr, h0), near(kr, k0), FINE, FINE_REACH, &reach, &bend);
    let mut targets: Vec<f64> = info
        .actuators
        .iter()
        .map(|a| a.joint.map_or(0.0, |j| qpos0_of(info, j)))
        .collect();
    let mut feet = Vec::with_capacity(info.legs.len());
    let mut lowest = f64::INFINITY;
    for leg in &info.legs {
        let (sh, sk) = (sense(leg.hip_axis, ref_hip), sense(leg.knee_axis, ref_knee));
        for (a, act) in info.actuators.iter().enumerate() {
            match act.joint {
                Some(j) if j == leg.joints[0] => targets[a] = 0.0,
                Some(j) if j == leg.joints[1] => targets[a] = sh * hfe,
                Some(j) if j == leg.joints[2] => targets[a] = sk * kfe,
                _ => {}
            }
        }
        let p = foot(leg, sh * hfe, sk * kfe);
        lowest = lowest.min(leg.hip[2] + p[2] - leg.foot_radius);
        feet.push((leg.name.clone(), p[0], p[2]));
    }
    let base_z0 = info
        .joints
        .iter()
        .find(|j| j.kind == "free")
        .map_or(0.0, |j| {
            info.qpos0.get(j.qpos_adr + 2).copied().unwrap_or(0.0)
        });
    Ok(StandPose {
        targets,
        base_z: base_z0 + CLEARANCE - lowest,
        hfe,
        kfe,
        thigh_angle: thigh_angle(hfe),
        target_z,
        depth_from,
        leg_length,
        feet,
    })
}

/// The thigh's angle from the downward vertical as a function of HFE (in
/// the first leg's convention), signed so that it is positive towards the
/// side the knee juts: opposite to the way the calf turns from the thigh's
/// line when the knee bends. Which way the knee bends is read from its
/// range `kr`: the end that folds the calf furthest from straight.
fn thigh_angle_of(leg: &LegInfo, kr: [f64; 2]) -> impl Fn(f64) -> f64 + use<> {
    let u = leg.hip_axis;
    let thigh = sub(leg.knee, leg.hip);
    let calf = sub(leg.foot, leg.knee);
    let fold = |k: f64| angle_about(thigh, rotate(calf, leg.knee_axis, k), u);
    let (lo, hi) = (fold(kr[0]), fold(kr[1]));
    let bend = if hi.abs() >= lo.abs() { hi } else { lo };
    let sign = if bend > 0.0 { -1.0 } else { 1.0 };
    // HFE turns the thigh about the hip axis: the angle grows with it
    let at_zero = angle_about([0.0, 0.0, -1.0], thigh, u);
    move |h: f64| sign * (at_zero + h)
}

/// The chapter's pick on a grid of spacing `step` over two ranges: among
/// the points whose `reach` (the target terms of its score) is within
/// `slack` of the grid's best reach, the one whose whole score (`reach` +
/// `bend`) is lowest (ties: the first point in order).
fn grid_min(
    hr: [f64; 2],
    kr: [f64; 2],
    step: f64,
    slack: f64,
    reach: &dyn Fn(f64, f64) -> f64,
    bend: &dyn Fn(f64) -> f64,
) -> (f64, f64) {
    let steps = |r: [f64; 2]| ((r[1] - r[0]) / step + 1e-9).floor() as usize + 1;
    let points = || {
        (0..steps(hr)).flat_map(move |i| {
            let h = hr[0] + i as f64 * step;
            (0..steps(kr)).map(move |j| (h, kr[0] + j as f64 * step))
        })
    };
    let closest = points()
        .map(|(h, k)| reach(h, k))
        .fold(f64::INFINITY, f64::min);
    let mut best = (f64::INFINITY, hr[0], kr[0]);
    for (h, k) in points() {
        let r = reach(h, k);
        if r <= closest + slack {
            let s = r + bend(h);
            if s < best.0 {
                best = (s, h, k);
            }
        }
    }
    (best.1, best.2)
}

fn qpos0_of(info: &ModelInfo, joint: usize) -> f64 {
    info.qpos0
        .get(info.joints[joint].qpos_adr)
        .copied()
        .unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::model::{ActuatorInfo, JointInfo};

    /// Two mirrored legs: thigh 0.1 m straight down, calf 0.1 m straight
    /// down, right leg axes -y, left +y; hip 0.2 m above the base origin.
    fn biped() -> ModelInfo {
        let mut joints = vec![JointInfo::free_base()];
        let mut actuators = Vec::new();
        let mut legs = Vec::new();
        for (side, y) in [("r", -1.0), ("l", 1.0)] {
            let base = joints.len();
            for (n, range) in [
                ("haa", [-1.0, 1.0]),
                ("hfe", [-3.0, 3.0]),
                ("kfe", [-3.0, 3.0]),
            ] {
                let adr = 7 + joints.len() - 1;
                joints.push(JointInfo {
                    name: format!("{n}_{side}"),
                    kind: "hinge".into(),
                    qpos_adr: adr,
                    dof_adr: adr - 1,
                    range: Some(range),
                    body: joints.len() + 1,
                });
                actuators.push(ActuatorInfo::for_test(
                    format!("{n}_{side}"),
                    Some(joints.len() - 1),
                    [1.0, 0.0, 0.0],
                    [0.0; 3],
                ));
            }
            legs.push(LegInfo {
                name: format!("leg_{side}"),
                joints: [base, base + 1, base + 2],
                hip: [0.0, 0.1 * y, 0.3],
                knee: [0.0, 0.1 * y, 0.2],
                foot: [0.0, 0.1 * y, 0.1],
                hip_axis: [0.0, y, 0.0],
                knee_axis: [0.0, y, 0.0],
                hip_to_foot: 0.2,
                foot_radius: 0.01,
                foot_sphere: true,
                foot_geom: 0,
                abduction: [0.0, 0.1 * y, 0.3],
                abduction_axis: [1.0, 0.0, 0.0],
            });
        }
        let mut info = ModelInfo::for_test("biped", joints, actuators);
        info.qpos0[2] = 0.1;
        info.legs = legs;
        info
    }

    #[test]
    fn feet_reach_the_target_and_left_mirrors_right() {
        let info = biped();
        let p = stand_pose(&info, 1.0, Some(0.14)).unwrap();
        assert_eq!(p.target_z, -0.14);
        assert_eq!(p.depth_from, "given");
        // the bend preference (0.70 rad, where these legs need 0.80 rad)
        // picks among the poses that reach the target, and pulls no foot off
        for (_, x, z) in &p.feet {
            assert!((z - -0.14).abs() < 0.5e-3, "{z}");
            assert!(x.abs() < 1e-3, "{x}");
        }
        assert!(
            (p.thigh_angle - (0.07f64 / 0.1).acos()).abs() < 0.01,
            "{p:?}"
        );
        // right (axes -y) and left (+y) get opposite angles, abduction 0
        assert_eq!(p.targets[0], 0.0);
        assert_eq!(p.targets[1], -p.targets[4]);
        assert_eq!(p.targets[2], -p.targets[5]);
        assert!(p.kfe.abs() > 0.5, "the knee bends: {p:?}");
        // lowest foot 2 mm above the floor: hip at 0.3 - 0.1 + base_z
        let foot_bottom = 0.3 - 0.1 + p.base_z - 0.14 - 0.01;
        assert!((foot_bottom - CLEARANCE).abs() < 0.006, "{foot_bottom}");
    }

    #[test]
    fn the_depth_scales_with_the_legs_and_longer_variants_aim_lower_up_to_one_and_a_half() {
        // Pupper's own legs aim at the chapter's 0.14 m
        assert!((scaled_depth(PUPPER_LEG_LENGTH, 1.0) - 0.14).abs() < 1e-15);
        // legs twice as long: twice as deep
        assert!((scaled_depth(2.0 * PUPPER_LEG_LENGTH, 1.0) - 0.28).abs() < 1e-12);
        // a variant's legs are measured scaled: the chapter's clamp applies
        let l = PUPPER_LEG_LENGTH;
        assert!((scaled_depth(1.5 * l, 1.5) - 0.21).abs() < 1e-12);
        assert!((scaled_depth(3.0 * l, 3.0) - 0.21).abs() < 1e-12);
        assert!((scaled_depth(0.5 * l, 0.5) - 0.14).abs() < 1e-12);
        // the biped's legs are 0.2 m
        let info = biped();
        let p = stand_pose(&info, 1.0, None).unwrap();
        assert_eq!(p.depth_from, "scaled");
        assert!((p.leg_length - 0.2).abs() < 1e-12);
        assert!((p.target_z + 0.14 * 0.2 / PUPPER_LEG_LENGTH).abs() < 1e-12);
    }

    #[test]
    fn the_preferred_bend_is_the_thighs_angle_from_vertical_not_the_joint_value() {
        // the same biped with its thighs already pitched 0.5 rad forward at
        // joint zero (knee and foot moved by the rotation): the pose found
        // must be the same leg shape, 0.5 rad less on the hip joint
        let straight = biped();
        let mut tilted = biped();
        // pitched the same way in the world (the right leg's +0.5)
        for leg in &mut tilted.legs {
            let hip = leg.hip;
            let turn = |p: V3| add(hip, rotate(sub(p, hip), [0.0, -1.0, 0.0], 0.5));
            leg.knee = turn(leg.knee);
            leg.foot = turn(leg.foot);
        }
        let a = stand_pose(&straight, 1.0, Some(0.14)).unwrap();
        let b = stand_pose(&tilted, 1.0, Some(0.14)).unwrap();
        assert!((a.thigh_angle - b.thigh_angle).abs() < 2e-3, "{a:?} {b:?}");
        assert!((a.hfe - (b.hfe + 0.5)).abs() < 2e-3, "{a:?} {b:?}");
        for ((_, xa, za), (_, xb, zb)) in a.feet.iter().zip(&b.feet) {
            assert!(
                (xa - xb).abs() < 1e-3 && (za - zb).abs() < 1e-3,
                "{a:?} {b:?}"
            );
        }
    }

    #[test]
    fn the_thigh_angle_is_positive_towards_the_knee() {
        // the chapter's skeleton: thigh and calf hang down at zero and the
        // knee bends to negative angles (range [-2.3, -0.25]); a symmetric
        // bend of the chapter (0.70, -1.40) has thigh angle +0.70
        let leg = &biped().legs[0];
        let f = thigh_angle_of(leg, [-2.3, -0.25]);
        let p = foot(leg, 0.7, -1.4);
        let knee_x = rotate(sub(leg.knee, leg.hip), leg.hip_axis, 0.7)[0];
        assert!(
            p[0].abs() < 1e-12,
            "a symmetric bend ends under the hip: {p:?}"
        );
        assert!((f(0.7).abs() - 0.7).abs() < 1e-12);
        assert!(f(0.7) > 0.0 && knee_x.abs() > 0.05);
        // a knee that bends the other way flips the sign
        let g = thigh_angle_of(leg, [0.25, 2.3]);
        assert!((g(0.7) + f(0.7)).abs() < 1e-12);
    }

    #[test]
    fn a_model_without_legs_is_named() {
        let mut info = biped();
        info.legs.clear();
        let e = stand_pose(&info, 1.0, None).unwrap_err().to_string();
        assert!(e.contains("no legs") && e.contains("--pose"), "{e}");
    }

    #[test]
    fn rotation_about_an_axis() {
        let v = rotate(
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            std::f64::consts::FRAC_PI_2,
        );
        assert!((v[0]).abs() < 1e-12 && (v[2] + 1.0).abs() < 1e-12, "{v:?}");
    }
}
