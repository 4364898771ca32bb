//! Index bookkeeping of a floating-base model: where the base and each
//! actuated joint live in qpos (7 base entries for a free joint) and qvel
//! (6), in actuator (ctrl) order. Taken from the model's addresses, never
//! hard-coded.

use crate::error::{Error, Result};
use crate::robot::model::ModelInfo;

/// The base: the body a free joint moves, or on a suspended robot the
/// same body fixed to the world (no free joint, no base coordinates).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Base {
    /// The body the free joint moves (pushes act on it).
    pub body: usize,
    /// qpos address of the free joint (x, y, z, then the quaternion);
    /// None when the base is fixed.
    pub qpos: Option<usize>,
}

impl Base {
    /// Index of base z in qpos.
    pub fn z(&self) -> Option<usize> {
        self.qpos.map(|q| q + 2)
    }
    /// Index of the (w, x, y, z) quaternion's first entry in qpos.
    pub fn quat(&self) -> Option<usize> {
        self.qpos.map(|q| q + 3)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    pub nu: usize,
    pub base: Base,
    /// qpos address of the joint each actuator drives, in ctrl order.
    pub act_qpos: Vec<usize>,
    /// qvel address of the same joints.
    pub act_dof: Vec<usize>,
}

impl Layout {
    /// The layout of a free-base model whose actuators all drive 1-dof joints.
    pub fn floating(info: &ModelInfo) -> Result<Layout> {
        let base = info
            .joints
            .iter()
            .find(|j| j.kind == "free")
            .ok_or_else(|| {
                Error::Model(format!(
                    "model '{}' has no free-joint base: sweeps and stand need a floating robot; add <freejoint/> to its root body (or use --model pupper_v3)",
                    info.name
                ))
            })?;
        Layout::with_base(
            info,
            Base {
                body: base.body,
                qpos: Some(base.qpos_adr),
            },
        )
    }

    /// The layout of a robot whose base is fixed to the world (a free
    /// joint removed, or none): the base is the body nearest the world
    /// that carries every actuated joint.
    pub fn suspended(info: &ModelInfo) -> Result<Layout> {
        let bodies: Vec<usize> = info
            .actuators
            .iter()
            .filter_map(|a| a.joint.and_then(|j| info.joints.get(j)).map(|j| j.body))
            .collect();
        let ancestors = |mut b: usize| {
            let mut up = vec![b];
            while b != 0 {
                b = info.body_parent.get(b).copied().unwrap_or(0);
                up.push(b);
            }
            up
        };
        // the deepest common ancestor below the world; the world itself if none
        let common = bodies
            .iter()
            .map(|&b| ancestors(b))
            .reduce(|a, b| a.into_iter().filter(|x| b.contains(x)).collect())
            .unwrap_or_default();
        let body = common
            .into_iter()
            .find(|&b| b != 0 && !bodies.contains(&b))
            .unwrap_or(0);
        Layout::with_base(info, Base { body, qpos: None })
    }

    fn with_base(info: &ModelInfo, base: Base) -> Result<Layout> {
        if info.actuators.is_empty() {
            return Err(Error::Model(format!(
                "model '{}' has no actuators: the controller needs one actuator per leg joint",
                info.name
            )));
        }
        let mut act_qpos = Vec::with_capacity(info.nu);
        let mut act_dof = Vec::with_capacity(info.nu);
        for a in &info.actuators {
            let joint = a
                .joint
                .and_then(|j| info.joints.get(j))
                .filter(|j| j.kind == "hinge" || j.kind == "slide");
            let Some(j) = joint else {
                return Err(Error::Model(format!(
                    "actuator '{}' of model '{}' does not drive a hinge or slide joint: pupper controls joint actuators only",
                    a.name, info.name
                )));
            };
            act_qpos.push(j.qpos_adr);
            act_dof.push(j.dof_adr);
        }
        Ok(Layout {
            nu: info.nu,
            base,
            act_qpos,
            act_dof,
        })
    }

    /// Joint targets in ctrl order from a full qpos vector.
    pub fn joint_targets(&self, qpos: &[f64]) -> Vec<f64> {
        self.act_qpos.iter().map(|&i| qpos[i]).collect()
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::robot::model::{ActuatorInfo, JointInfo};

    /// A free base plus `legs` three-joint legs, actuated in an order that
    /// differs from the joint order, like a user model might.
    pub fn quadruped_info(legs: usize) -> ModelInfo {
        let mut joints = vec![JointInfo::free_base()];
        for i in 0..legs * 3 {
            joints.push(JointInfo {
                name: format!("j{i}"),
                kind: "hinge".into(),
                qpos_adr: 7 + i,
                dof_adr: 6 + i,
                range: Some([-1.0, 1.0]),
                body: 2 + i,
            });
        }
        // actuators in reverse joint order
        let actuators = (0..legs * 3)
            .rev()
            .map(|i| {
                ActuatorInfo::for_test(
                    format!("a{i}"),
                    Some(1 + i),
                    [5.0, 0.0, 0.0],
                    [0.0, -5.0, -0.1],
                )
            })
            .collect();
        ModelInfo::for_test("test", joints, actuators)
    }

    #[test]
    fn free_joint_bookkeeping() {
        let l = Layout::floating(&quadruped_info(4)).unwrap();
        assert_eq!(l.nu, 12);
        assert_eq!(
            (l.base.body, l.base.z(), l.base.quat()),
            (1, Some(2), Some(3))
        );
        // actuator 0 drives the last joint: qpos 18, qvel 17
        assert_eq!(l.act_qpos[0], 18);
        assert_eq!(l.act_dof[0], 17);
        assert_eq!(l.act_qpos[11], 7);
        assert_eq!(l.act_dof[11], 6);
        let qpos: Vec<f64> = (0..19).map(|i| i as f64).collect();
        assert_eq!(l.joint_targets(&qpos)[0], 18.0);
    }

    #[test]
    fn free_joint_not_first() {
        // a model whose free joint comes after a hinge (e.g. a prop on the floor first)
        let mut info = quadruped_info(1);
        info.joints[0].qpos_adr = 3;
        info.joints[0].dof_adr = 3;
        let l = Layout::floating(&info).unwrap();
        assert_eq!(l.base.z(), Some(5));
        assert_eq!(l.base.quat(), Some(6));
    }

    #[test]
    fn no_free_joint_is_a_model_error() {
        let mut info = quadruped_info(4);
        info.joints.remove(0);
        for a in &mut info.actuators {
            a.joint = a.joint.map(|j| j - 1);
        }
        let e = Layout::floating(&info).unwrap_err().to_string();
        assert!(e.contains("no free-joint base"), "{e}");
    }

    #[test]
    fn actuator_without_joint_is_rejected() {
        let mut info = quadruped_info(1);
        info.actuators[0].joint = None;
        let e = Layout::floating(&info).unwrap_err();
        assert_eq!(e.kind(), crate::ErrorKind::Model);
        assert!(
            e.to_string()
                .contains("does not drive a hinge or slide joint"),
            "{e}"
        );
    }

    #[test]
    fn actuator_on_a_ball_joint_is_rejected() {
        let mut info = quadruped_info(1);
        info.joints[1].kind = "ball".into();
        let e = Layout::floating(&info).unwrap_err().to_string();
        assert!(e.contains("does not drive a hinge or slide joint"), "{e}");
    }

    #[test]
    fn torque_limits_come_from_force_then_control_ranges() {
        let mut info = quadruped_info(1);
        assert_eq!(info.torque_limits().unwrap(), vec![3.0; 3]);
        info.actuators[0].forcerange = None;
        info.actuators[0].ctrlrange = Some([-2.0, 2.5]);
        info.actuators[1].forcerange = Some([-4.0, 1.0]);
        assert_eq!(info.torque_limits().unwrap(), vec![2.5, 4.0, 3.0]);
        info.actuators[2].forcerange = None;
        let l = info.torque_limits().unwrap();
        assert_eq!(l[2], crate::robot::model::UNLIMITED);
        let note = info.unlimited_note().unwrap();
        assert!(
            note.contains("actuators a0 ") && note.contains("--max-torque"),
            "{note}"
        );
    }

    #[test]
    fn no_actuators_is_rejected() {
        let mut info = quadruped_info(1);
        info.actuators.clear();
        info.nu = 0;
        let e = Layout::floating(&info).unwrap_err().to_string();
        assert!(e.contains("has no actuators"), "{e}");
    }
}
