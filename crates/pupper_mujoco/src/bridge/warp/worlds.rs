//! Building a warp batch: the cells grouped by body, one Warp model per
//! body and a world per simulation, each world's start state, gains,
//! limits, friction and masses.

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyList;

use super::{Group, WarpBatch, WarpPhysics, warp_err};
use crate::bridge::model::LoadedModel;
use crate::bridge::python::PyResultExt;
use crate::bridge::setup::{
    StartStates, actuator_params, colliding_geoms, prepare_model, scale_body_masses,
};
use pupper_core::error::Result;
use pupper_core::plan::backend::ActuatorPd;
use pupper_core::plan::mode::Mode;
use pupper_core::plan::schedule::InitialState;
use pupper_core::plan::setup::CellSetup;
use pupper_core::sim::physics::Physics;

/// What decides a simulation's Warp model: its leg scale (geometry). Masses
/// and inertias are per world, like gains, torque limits and friction.
fn body_key(c: &CellSetup) -> u64 {
    c.leg_scale.to_bits()
}

/// What decides a world's masses: the body's torso scale and the draws.
fn mass_key(c: &CellSetup) -> [u64; 3] {
    [
        c.torso_mass_scale.to_bits(),
        c.torso_mass_factor.to_bits(),
        c.leg_mass_factor.to_bits(),
    ]
}

/// Actuator `a`'s first three gain and bias parameters on warp: servo mode
/// as on the cpu backend; torque mode the PD as an affine actuator.
fn world_params(mode: Mode, c: &CellSetup, a: usize) -> ([f64; 3], [f64; 3]) {
    match mode {
        Mode::Servo => actuator_params(mode, c, a),
        // the targets go in as ctrl; the limit is the force range
        Mode::Torque => {
            let pd = ActuatorPd::new(c.kp(a), c.kd(a), 0.0, f64::INFINITY);
            ([pd.gain, 0.0, 0.0], pd.bias)
        }
    }
}

pub(super) fn array3<'py>(
    py: Python<'py>,
    v: Vec<f64>,
    shape: [usize; 3],
) -> Result<Bound<'py, PyAny>> {
    PyArray1::from_vec(py, v)
        .reshape(shape)
        .map(Bound::into_any)
        .internal()
}

impl<'py> WarpBatch<'py> {
    /// The worlds of `cells` on `physics`'s device, each at its start.
    pub(super) fn new(
        physics: &WarpPhysics<'_, 'py>,
        cells: &[CellSetup],
        mode: Mode,
        initial: &InitialState,
    ) -> Result<Self> {
        let owner = physics.owner;
        let mj = &owner.mj;
        let py = mj.py;
        let info = &owner.info;
        let layout = Physics::layout(owner);
        let (nq, nu) = (info.nq, info.nu);
        let dt = cells[0].timestep.unwrap_or(info.timestep);
        let starts = StartStates::new(owner, cells, initial)?;
        let reset: Vec<f64> = match starts.keyframe {
            Some(k) => info.keyframes[k].qpos.clone(),
            None => info.qpos0.clone(),
        };
        let bodies = by_body(cells);
        let mut place = vec![(0, 0); cells.len()];
        let mut groups = Vec::with_capacity(bodies.len());
        let mut scratch: Option<Bound<'py, PyAny>> = None;
        for (g, (_, sims)) in bodies.into_iter().enumerate() {
            let first = &cells[sims[0]];
            let model =
                prepare_model(mj, &owner.variant(first.leg_scale, 1.0)?, mode, dt).internal()?;
            let per_world = group_masses(physics, &model, cells, &sims, &mut scratch)?;
            let colliding = colliding_geoms(&model).internal()?;
            let n = sims.len();
            for (w, &sim) in sims.iter().enumerate() {
                place[sim] = (g, w);
            }
            let arrays = world_arrays(owner, &starts, &reset, cells, &sims, mode)?;
            let friction = world_friction(py, &model, &colliding, &arrays.friction)?;
            let args = (
                &model,
                &physics.device,
                starts.keyframe.map_or(-1, |k| k as i64),
                PyArray1::from_vec(py, arrays.qpos)
                    .reshape([n, nq])
                    .internal()?,
                PyArray1::from_vec(py, arrays.ctrl)
                    .reshape([n, nu])
                    .internal()?,
                array3(py, arrays.gain, [n, nu, 3])?,
                array3(py, arrays.bias, [n, nu, 3])?,
                array3(py, arrays.range, [n, nu, 2])?,
                friction,
                colliding,
                layout.base.body,
                per_world,
            );
            let worlds = physics
                .module
                .getattr("Worlds")
                .and_then(|w| w.call1(args))
                .map_err(|e| warp_err(py, e))?;
            let block: usize = worlds
                .getattr("block")
                .and_then(|b| b.extract())
                .internal()?;
            groups.push(Group {
                worlds,
                sims,
                block: block.max(1),
            });
        }
        Ok(WarpBatch {
            groups,
            place,
            stance: starts.stance,
            targets: starts.starts.into_iter().map(|(t, _)| t).collect(),
            nq,
            nu,
        })
    }
}

/// The simulations of each body, bodies in order of first appearance.
fn by_body(cells: &[CellSetup]) -> Vec<(u64, Vec<usize>)> {
    let mut bodies: Vec<(u64, Vec<usize>)> = Vec::new();
    for (i, c) in cells.iter().enumerate() {
        let key = body_key(c);
        match bodies.iter_mut().find(|(k, _)| *k == key) {
            Some((_, sims)) => sims.push(i),
            None => bodies.push((key, vec![i])),
        }
    }
    bodies
}

/// The per-world arrays of a body group's worlds, world by world: start
/// qpos and ctrl, each actuator's gain, bias and force range, friction.
struct WorldArrays {
    qpos: Vec<f64>,
    ctrl: Vec<f64>,
    gain: Vec<f64>,
    bias: Vec<f64>,
    range: Vec<f64>,
    friction: Vec<Option<f64>>,
}

/// The [`WorldArrays`] of the simulations `sims` of `cells`, each started
/// from `reset` as `starts` says.
fn world_arrays(
    owner: &LoadedModel<'_>,
    starts: &StartStates,
    reset: &[f64],
    cells: &[CellSetup],
    sims: &[usize],
    mode: Mode,
) -> Result<WorldArrays> {
    let info = &owner.info;
    let (n, nq, nu) = (sims.len(), info.nq, info.nu);
    let (mut qpos, mut ctrl) = (Vec::with_capacity(n * nq), Vec::with_capacity(n * nu));
    let (mut gain, mut bias) = (vec![0.0; n * nu * 3], vec![0.0; n * nu * 3]);
    let mut range = vec![0.0; n * nu * 2];
    let mut friction = Vec::with_capacity(n);
    for (w, &sim) in sims.iter().enumerate() {
        let c = &cells[sim];
        let mut q = reset.to_vec();
        starts.qpos(owner, sim, &mut q);
        qpos.extend_from_slice(&q);
        // servo mode: the targets are the servos' ctrl; torque mode
        // on warp: the PD's targets, its actuators' ctrl
        ctrl.extend_from_slice(&starts.starts[sim].0);
        let limits = c.torque_limits(info)?;
        for a in 0..nu {
            let (gp, bp) = world_params(mode, c, a);
            let at = (w * nu + a) * 3;
            gain[at..at + 3].copy_from_slice(&gp);
            bias[at..at + 3].copy_from_slice(&bp);
            range[(w * nu + a) * 2] = -limits[a];
            range[(w * nu + a) * 2 + 1] = limits[a];
        }
        friction.push(c.friction);
    }
    Ok(WorldArrays {
        qpos,
        ctrl,
        gain,
        bias,
        range,
        friction,
    })
}

/// A body group's masses: one carried by the model itself, or several as
/// each mass's rows of the model and the index of every world's (what
/// MuJoCo derives from a mass is set per world).
fn group_masses<'py>(
    physics: &WarpPhysics<'_, 'py>,
    model: &Bound<'py, PyAny>,
    cells: &[CellSetup],
    sims: &[usize],
    scratch: &mut Option<Bound<'py, PyAny>>,
) -> Result<Bound<'py, PyAny>> {
    let owner = physics.owner;
    let (mj, py) = (&owner.mj, owner.mj.py);
    let layout = Physics::layout(owner);
    // the group's masses, in order of first appearance
    let mut masses: Vec<([u64; 3], usize)> = Vec::new();
    let mut mass_of = Vec::with_capacity(sims.len());
    for &sim in sims {
        let key = mass_key(&cells[sim]);
        let k = match masses.iter().position(|(m, _)| *m == key) {
            Some(k) => k,
            None => {
                masses.push((key, sim));
                masses.len() - 1
            }
        };
        mass_of.push(k);
    }
    let data = match scratch {
        Some(d) => d.clone(),
        None => {
            let d = mj.module.getattr("MjData").and_then(|f| f.call1((model,)));
            scratch.insert(d.internal()?).clone()
        }
    };
    // the torso scale first, then the draws: the products the cpu
    // backend forms (a scaled body, then its draws)
    let scaled = |m: &Bound<'py, PyAny>, c: &CellSetup| -> Result<()> {
        let base = layout.base.body;
        if c.torso_mass_scale != 1.0 {
            scale_body_masses(mj, m, &data, base, c.torso_mass_scale, 1.0).internal()?;
        }
        if !c.nominal_masses() {
            scale_body_masses(mj, m, &data, base, c.torso_mass_factor, c.leg_mass_factor)
                .internal()?;
        }
        Ok(())
    };
    // one mass: the model carries it; several: one model, its mass
    // and what MuJoCo derives from it per world
    Ok(if masses.len() == 1 {
        scaled(model, &cells[masses[0].1])?;
        py.None().into_bound(py)
    } else {
        let copy = PyModule::import(py, "copy")
            .and_then(|c| c.getattr("copy"))
            .internal()?;
        let rows_of = physics.module.getattr("mass_rows").internal()?;
        // each body's rows only: a population's models would not fit
        let mut bodies = Vec::with_capacity(masses.len());
        for &(_, sim) in &masses {
            let m = copy.call1((model,)).internal()?;
            scaled(&m, &cells[sim])?;
            bodies.push(rows_of.call1((&m,)).internal()?);
        }
        let bodies = PyList::new(py, bodies).internal()?;
        let index = PyArray1::from_vec(py, mass_of.iter().map(|&k| k as i64).collect());
        (bodies, index).into_pyobject(py).internal()?.into_any()
    })
}

/// Friction per world only when some cell sets it; the model's own value
/// stands in for the others.
fn world_friction<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyAny>,
    colliding: &[usize],
    friction: &[Option<f64>],
) -> Result<Bound<'py, PyAny>> {
    if !friction.iter().any(Option::is_some) {
        return Ok(py.None().into_bound(py));
    }
    let own: f64 = match colliding.first() {
        Some(&gid) => model
            .getattr("geom_friction")
            .and_then(|f| f.get_item((gid, 0)))
            .and_then(|v| v.extract())
            .internal()?,
        None => 1.0,
    };
    let v: Vec<f64> = friction.iter().map(|f| f.unwrap_or(own)).collect();
    Ok(PyArray1::from_vec(py, v).into_any())
}
