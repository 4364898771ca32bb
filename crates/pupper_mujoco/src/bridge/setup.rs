//! What both backends build from a batch's cells: the compiled model each
//! simulation runs (actuators made fixed-gain with an affine bias, masses
//! edited) and each simulation's start (joint targets, base height).

use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;

use super::model::LoadedModel;
use super::python::Mujoco;
use pupper_core::error::Result;
use pupper_core::plan::mode::Mode;
use pupper_core::plan::schedule::InitialState;
use pupper_core::plan::setup::CellSetup;
use pupper_core::sim::physics::Physics;

/// A copy of `m` with timestep `dt` whose actuators, whatever the file
/// declares (a position servo, a motor), are fixed-gain with an affine bias
/// (the PD of servo mode; zero bias in torque mode), no activation
/// dynamics, clipped at the cell's torque limit.
pub(crate) fn prepare_model<'py>(
    mj: &Mujoco<'py>,
    m: &Bound<'py, PyAny>,
    mode: Mode,
    dt: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let m = mj.copy.call1((m,))?;
    m.getattr("opt")?.setattr("timestep", dt)?;
    let fill = |field: &str, v: i64| -> PyResult<()> {
        m.getattr(field)?.call_method1("fill", (v,)).map(|_| ())
    };
    fill("actuator_gaintype", 0)?; // mjGAIN_FIXED
    fill("actuator_biastype", 1)?; // mjBIAS_AFFINE
    fill("actuator_dyntype", 0)?; // mjDYN_NONE
    fill("actuator_forcelimited", 1)?;
    if mode == Mode::Torque {
        // torques (or, on warp, the PD's targets) must not be clamped to
        // a position range
        fill("actuator_ctrllimited", 0)?;
        // ctrl is now a torque: a calibrated model's command delay is the
        // Rust firmware's (on its targets), not MuJoCo's (on the torque)
        if m.hasattr("actuator_delay")? {
            m.getattr("actuator_delay")?.call_method1("fill", (0.0,))?;
        }
    }
    Ok(m)
}

/// A simulation's start: its joint targets (also its start angles when a
/// pose is given) and, for a searched pose, its base height.
pub(crate) type Start = (Vec<f64>, Option<f64>);

/// The starts of a batch's simulations.
pub(crate) struct StartStates {
    /// The keyframe every simulation is reset to first; None: qpos0.
    pub keyframe: Option<usize>,
    /// True when the start angles are the targets (a pose), not the keyframe's.
    pub set_joints: bool,
    pub starts: Vec<Start>,
    /// Each simulation's stance height (see [`LoadedModel::stance`]).
    pub stance: Vec<f64>,
}

/// The stance height (m) of one cell's start: the base height at which its
/// lowest foot touches the floor in its start pose, what falls are judged
/// against (NaN for a fixed base).
pub fn start_stance(
    owner: &LoadedModel<'_>,
    cell: &CellSetup,
    initial: &InitialState,
) -> Result<f64> {
    Ok(StartStates::new(owner, std::slice::from_ref(cell), initial)?.stance[0])
}

/// Each cell's start from the stand pose searched on its body (`depth`
/// below the hips, or its scaled default): one search per body, not per
/// cell.
fn searched_starts(
    owner: &LoadedModel<'_>,
    cells: &[CellSetup],
    depth: Option<f64>,
) -> Result<Vec<Start>> {
    let mut poses: Vec<((u64, u64), Start)> = Vec::new();
    let mut starts = Vec::with_capacity(cells.len());
    for c in cells {
        let key = (c.leg_scale.to_bits(), c.torso_mass_scale.to_bits());
        let start = match poses.iter().find(|(k, _)| *k == key) {
            Some((_, s)) => s.clone(),
            None => {
                let p = owner.stand_pose(c.leg_scale, c.torso_mass_scale, depth)?;
                poses.push((key, (p.targets, Some(p.base_z))));
                poses[poses.len() - 1].1.clone()
            }
        };
        starts.push(start);
    }
    Ok(starts)
}

impl StartStates {
    pub fn new(
        owner: &LoadedModel<'_>,
        cells: &[CellSetup],
        initial: &InitialState,
    ) -> Result<StartStates> {
        let info = &owner.info;
        let layout = Physics::layout(owner);
        let n = cells.len();
        let (key, pose) = match initial {
            InitialState::Keyframe(name) => (info.start_keyframe(name)?.0, None),
            // base x, y and orientation as the first keyframe (or qpos0) has them
            InitialState::Auto | InitialState::AutoDepth(_) => {
                (info.keyframes.first().map(|_| 0), None)
            }
            InitialState::Pose(p) => {
                info.check_pose(p)?;
                (info.keyframes.first().map(|_| 0), Some(p.clone()))
            }
        };
        // each simulation's start: joint angles (also its targets), base height
        let starts: Vec<Start> = match (initial.auto_depth(), &pose, key) {
            (Some(depth), _, _) => searched_starts(owner, cells, depth)?,
            (_, Some(p), _) => vec![(p.clone(), None); n],
            (_, None, Some(k)) => {
                let kf = &info.keyframes[k];
                let t = if kf.ctrl.len() == info.nu {
                    kf.ctrl.clone()
                } else {
                    layout.joint_targets(&kf.qpos)
                };
                vec![(t, None); n]
            }
            (_, None, None) => vec![(layout.joint_targets(&info.qpos0), None); n],
        };
        let mut states = StartStates {
            keyframe: key,
            set_joints: pose.is_some() || initial.auto_depth().is_some(),
            starts,
            stance: Vec::with_capacity(n),
        };
        // one forward-kinematics pass per body and start, not per cell
        let reset = match key {
            Some(k) => info.keyframes[k].qpos.clone(),
            None => info.qpos0.clone(),
        };
        let mut seen: Vec<((u64, u64), usize, f64)> = Vec::new();
        for (i, c) in cells.iter().enumerate() {
            let body = (c.leg_scale.to_bits(), c.torso_mass_scale.to_bits());
            let same = |&(b, j, _): &((u64, u64), usize, f64)| {
                b == body && states.starts[j] == states.starts[i]
            };
            let stance = match seen.iter().find(|s| same(s)) {
                Some(&(_, _, s)) => s,
                None => {
                    let mut q = reset.clone();
                    states.qpos(owner, i, &mut q);
                    let model = owner.variant(c.leg_scale, c.torso_mass_scale)?;
                    let s = owner.stance(&model, &q)?;
                    seen.push((body, i, s));
                    s
                }
            };
            states.stance.push(stance);
        }
        Ok(states)
    }

    /// Simulation `i`'s qpos, given the qpos it was reset to.
    pub fn qpos(&self, owner: &LoadedModel<'_>, i: usize, reset: &mut [f64]) {
        let layout = Physics::layout(owner);
        let (targets, base_z) = &self.starts[i];
        if self.set_joints {
            for (a, &q) in targets.iter().enumerate() {
                reset[layout.act_qpos[a]] = q;
            }
        }
        if let (Some(z), Some(zi)) = (base_z, layout.base.z()) {
            reset[zi] = *z;
        }
    }
}

/// Actuator `a`'s gain and bias parameters: the PD of servo mode, a direct
/// torque input in torque mode, both times the motor's gain factor.
pub(crate) fn actuator_params(mode: Mode, c: &CellSetup, a: usize) -> ([f64; 3], [f64; 3]) {
    let g = c.gain(a);
    match mode {
        // g = 1 gives the nominal values exactly (1 * x == x)
        Mode::Servo => (
            [g * c.kp(a), 0.0, 0.0],
            [0.0, -(g * c.kp(a)), -(g * c.kd(a))],
        ),
        Mode::Torque => ([g, 0.0, 0.0], [0.0, 0.0, 0.0]),
    }
}

/// Scales a compiled body's torso mass and inertia, and its thigh and calf
/// ones (bodies two or more levels below the base), then recomputes what
/// the compiler derives from masses (`mj_setConst`, and the mean inertia
/// and mass as the compiler sums them), so the model equals one compiled
/// with those masses.
pub(crate) fn scale_masses(
    mj: &super::python::Mujoco<'_>,
    m: &Bound<'_, PyAny>,
    data: &Bound<'_, PyAny>,
    base: usize,
    c: &CellSetup,
) -> PyResult<()> {
    scale_body_masses(mj, m, data, base, c.torso_mass_factor, c.leg_mass_factor)
}

/// Multiplies the base's mass and inertia by `torso`, and those of the
/// bodies two or more levels below it (thighs, calves, feet) by `legs`,
/// then recomputes what MuJoCo derives from them.
pub(crate) fn scale_body_masses(
    mj: &super::python::Mujoco<'_>,
    m: &Bound<'_, PyAny>,
    data: &Bound<'_, PyAny>,
    base: usize,
    torso: f64,
    legs: f64,
) -> PyResult<()> {
    let parent: Vec<usize> = m
        .getattr("body_parentid")?
        .call_method0("tolist")?
        .extract()?;
    let mass = m.getattr("body_mass")?.cast_into::<PyArray1<f64>>()?;
    let inertia = m.getattr("body_inertia")?.cast_into::<PyArray2<f64>>()?;
    {
        let (mut mass, mut inertia) = (mass.readwrite(), inertia.readwrite());
        let (mut mass, mut inertia) = (mass.as_array_mut(), inertia.as_array_mut());
        for b in 0..parent.len() {
            // levels below the base, if b is the base or under it
            let (mut at, mut depth) = (b, 0usize);
            while at != base && at != 0 {
                at = parent[at];
                depth += 1;
            }
            let f = match (at == base, depth) {
                (true, 0) => torso,
                (true, d) if d >= 2 => legs,
                _ => continue,
            };
            mass[b] *= f;
            for j in 0..3 {
                inertia[[b, j]] *= f;
            }
        }
    }
    mj.module.getattr("mj_setConst")?.call1((m, data))?;
    let m0: Vec<f64> = m.getattr("dof_M0")?.call_method0("tolist")?.extract()?;
    let masses: Vec<f64> = mass.call_method0("tolist")?.extract()?;
    let stat = m.getattr("stat")?;
    let sum = |xs: &[f64]| xs.iter().fold(0.0, |acc, x| acc + x);
    stat.setattr("meaninertia", sum(&m0) / m0.len().max(1) as f64)?;
    stat.setattr(
        "meanmass",
        sum(&masses[1..]) / (masses.len() - 1).max(1) as f64,
    )?;
    Ok(())
}

/// Geoms that take part in contacts (the feet and the floor, in Pupper).
pub(crate) fn colliding_geoms(model: &Bound<'_, PyAny>) -> PyResult<Vec<usize>> {
    let ct: Vec<i64> = model
        .getattr("geom_contype")?
        .call_method0("tolist")?
        .extract()?;
    let ca: Vec<i64> = model
        .getattr("geom_conaffinity")?
        .call_method0("tolist")?
        .extract()?;
    Ok((0..ct.len())
        .filter(|&g| ct[g] != 0 || ca[g] != 0)
        .collect())
}
