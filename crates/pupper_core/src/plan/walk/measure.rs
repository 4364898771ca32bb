//! What a walk measures of the compiled model: its four legs as the
//! walk's kinematics take them (each a chain of abduction, hip and knee, in
//! the base frame at the default pose, told front or back, left or right),
//! its weight, its gears, and the step height scaled to its legs.

use crate::error::{Error, Result};
use crate::plan::schedule::Schedule;
use crate::plan::walk::leg::{Leg, V3, norm, sub};
use crate::plan::walk::{STEP_HEIGHT, Walk};
use crate::robot::model::{LegInfo, ModelInfo};

impl Walk {
    /// The legs, weight and gears of the compiled model, and the step
    /// height scaled to its legs when none was given.
    pub(super) fn measure(&mut self, info: &ModelInfo, schedule: &mut Schedule) -> Result<()> {
        schedule.push = None;
        self.legs = legs_of(info)?;
        let g = info.gravity.iter().map(|v| v * v).sum::<f64>().sqrt();
        self.weight = info.total_mass * g;
        // without weight nothing holds the feet on the floor, and the cost
        // of transport divides by it: the numbers would say nothing
        if self.weight.is_nan() || self.weight <= 0.0 {
            return Err(Error::Model(format!(
                "model '{}' has no weight (mass {:.3} kg, gravity {g:.3} m/s^2): a walk needs the robot's weight on its feet; give the model gravity (<option gravity=\"0 0 -9.81\"/>) and mass",
                info.name, info.total_mass
            )));
        }
        self.gears = info.actuators.iter().map(|a| a.gear).collect();
        if self.step_height.is_none() {
            let length = crate::robot::pose::leg_length(info)
                .unwrap_or(crate::robot::pose::PUPPER_LEG_LENGTH);
            self.step_height = Some(STEP_HEIGHT * length / crate::robot::pose::PUPPER_LEG_LENGTH);
        }
        Ok(())
    }
}

/// Why a model cannot walk, in one line.
fn refuse<T>(info: &ModelInfo, why: String) -> Result<T> {
    Err(Error::Model(format!(
        "model '{}' {why}: pupper walk needs four legs of abduction, hip and knee hinges (the knee last) under a free-joint base",
        info.name
    )))
}

/// The four legs of a model, each a chain of abduction, hip and knee with
/// the knee last, in the base frame at the default pose; each told front or
/// back, left or right of the hips' centre.
fn legs_of(info: &ModelInfo) -> Result<Vec<Leg>> {
    if info.legs.len() != 4 {
        return refuse(
            info,
            format!("has {} legs pupper can measure", info.legs.len()),
        );
    }
    // a walk places each foot by its sphere's centre and radius: another
    // shape's centre (a calf capsule's) lies inside the leg, and every
    // stance would be measured centimetres into the floor
    if let Some(l) = info.legs.iter().find(|l| !l.foot_sphere) {
        return Err(Error::Model(format!(
            "model '{}' has a leg ({}) whose foot (the colliding geom of its last body furthest from the knee) is not a sphere: pupper walk stands each foot by its sphere's centre and radius; give each foot a sphere geom at the leg's tip",
            info.name, l.name
        )));
    }
    let Some(free) = info.joints.iter().find(|j| j.kind == "free") else {
        return refuse(info, "has no free-joint base".into());
    };
    let q0 = |i: usize| info.qpos0.get(free.qpos_adr + i).copied().unwrap_or(0.0);
    let origin = [q0(0), q0(1), q0(2)];
    let quat = [q0(3), q0(4), q0(5), q0(6)];
    // into the base frame: the inverse of the base's default orientation
    let to_base = |v: V3| rotate_by(conjugate(quat), v);
    let mut legs = info
        .legs
        .iter()
        .map(|l| leg_of(info, l, origin, &to_base))
        .collect::<Result<Vec<Leg>>>()?;
    // front and left of the shoulders' centre
    let centre: V3 = legs.iter().fold([0.0; 3], |c, l| {
        let s = l.shoulder();
        [c[0] + s[0] / 4.0, c[1] + s[1] / 4.0, c[2] + s[2] / 4.0]
    });
    for l in &mut legs {
        let s = l.shoulder();
        l.front = s[0] > centre[0];
        l.left = s[1] > centre[1];
    }
    let mut seen: Vec<(bool, bool)> = legs.iter().map(|l| (l.front, l.left)).collect();
    seen.sort();
    seen.dedup();
    if seen.len() != 4 {
        return refuse(
            info,
            "has legs that are not one at each corner (front/back, left/right)".into(),
        );
    }
    Ok(legs)
}

/// One leg as the kinematics take it: its joints in chain order with their
/// actuators, default angles and ranges, in the base frame (its origin at
/// `origin`, world directions turned by `to_base`).
fn leg_of(info: &ModelInfo, l: &LegInfo, origin: V3, to_base: &dyn Fn(V3) -> V3) -> Result<Leg> {
    // MuJoCo numbers joints down the tree: a leg's chain in index order
    let mut chain = [
        (l.joints[0], l.abduction, l.abduction_axis),
        (l.joints[1], l.hip, l.hip_axis),
        (l.joints[2], l.knee, l.knee_axis),
    ];
    chain.sort_by_key(|(j, _, _)| *j);
    if chain[2].0 != l.joints[2] {
        return refuse(
            info,
            format!("has a leg ({}) whose knee is not its last joint", l.name),
        );
    }
    let mut actuators = [0usize; 3];
    let mut zero = [0.0; 3];
    let mut ranges = [[-std::f64::consts::TAU, std::f64::consts::TAU]; 3];
    for (i, (j, _, _)) in chain.iter().enumerate() {
        let Some(a) = info.actuators.iter().position(|a| a.joint == Some(*j)) else {
            let name = &info.joints[*j].name;
            return refuse(
                info,
                format!("has a leg joint ({name}) that no actuator drives"),
            );
        };
        actuators[i] = a;
        zero[i] = info
            .qpos0
            .get(info.joints[*j].qpos_adr)
            .copied()
            .unwrap_or(0.0);
        if let Some([lo, hi]) = info.joints[*j].range {
            ranges[i] = [lo - zero[i], hi - zero[i]];
        }
    }
    let unit = |v: V3| {
        let n = norm(v);
        if n > 0.0 { v.map(|x| x / n) } else { v }
    };
    Ok(Leg {
        name: l.name.clone(),
        front: false,
        left: false,
        anchors: chain.map(|(_, p, _)| to_base(sub(p, origin))),
        axes: chain.map(|(_, _, u)| unit(to_base(u))),
        foot: to_base(sub(l.foot, origin)),
        radius: l.foot_radius,
        actuators,
        zero,
        ranges,
    })
}

fn conjugate(q: [f64; 4]) -> [f64; 4] {
    [q[0], -q[1], -q[2], -q[3]]
}

/// `v` turned by the unit quaternion `q` (w, x, y, z).
pub(crate) fn rotate_by(q: [f64; 4], v: V3) -> V3 {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let [w, x, y, z] = if n > 0.0 {
        q.map(|c| c / n)
    } else {
        [1.0, 0.0, 0.0, 0.0]
    };
    // v + 2 u x (u x v + w v), u = (x, y, z)
    let u = [x, y, z];
    let c1 = [
        u[1] * v[2] - u[2] * v[1] + w * v[0],
        u[2] * v[0] - u[0] * v[2] + w * v[1],
        u[0] * v[1] - u[1] * v[0] + w * v[2],
    ];
    [
        v[0] + 2.0 * (u[1] * c1[2] - u[2] * c1[1]),
        v[1] + 2.0 * (u[2] * c1[0] - u[0] * c1[2]),
        v[2] + 2.0 * (u[0] * c1[1] - u[1] * c1[0]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quaternion_turns_a_vector() {
        // 90 degrees about z: x -> y
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let v = rotate_by([h, 0.0, 0.0, h], [1.0, 0.0, 0.0]);
        assert!(norm(sub(v, [0.0, 1.0, 0.0])) < 1e-15, "{v:?}");
        let back = rotate_by(conjugate([h, 0.0, 0.0, h]), v);
        assert!(norm(sub(back, [1.0, 0.0, 0.0])) < 1e-15);
    }
}
