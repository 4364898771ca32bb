//! Building the CPU batch: one model with per-cell fields (`expand()`)
//! where every cell has one body, else a model per distinct setting
//! (`set_models()`); the state rows' layout; every simulation reset to its
//! start state and targets.

use numpy::{PyArray2, PyArray3, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use super::{MujocoBatch, Offsets};
use crate::bridge::model::LoadedModel;
use crate::bridge::python::PyResultExt;
use crate::bridge::setup::{
    StartStates, actuator_params, colliding_geoms, prepare_model, scale_masses,
};
use pupper_core::error::{Error, Result};
use pupper_core::plan::mode::Mode;
use pupper_core::plan::schedule::InitialState;
use pupper_core::plan::setup::CellSetup;
use pupper_core::robot::model::ModelInfo;
use pupper_core::sim::physics::Physics;

impl<'a, 'py> MujocoBatch<'a, 'py> {
    /// A batch of `cells` on `threads` threads, each simulation at its
    /// start state with its targets.
    pub(super) fn new(
        owner: &'a LoadedModel<'py>,
        cells: &[CellSetup],
        mode: Mode,
        initial: &InitialState,
        threads: usize,
    ) -> Result<Self> {
        let info = &owner.info;
        let layout = Physics::layout(owner);
        let n = cells.len();
        let batch = create(owner, cells, mode, threads)?;
        let (state, warning) = state_views(&batch)?;
        let off = offsets(&batch, &state)?;
        // initial state and targets
        let starts = StartStates::new(owner, cells, initial)?;
        reset(owner, &batch, &state, off, &starts, mode)?;
        let stance = starts.stance;
        let targets: Vec<Vec<f64>> = starts.starts.into_iter().map(|(t, _)| t).collect();
        let warned = vec![0; n];
        let mut me = MujocoBatch {
            owner,
            batch,
            state,
            warning,
            warned,
            off,
            targets,
            stance,
            nsim: n,
            force_body: layout.base.body,
            nbody: info.nbody,
        };
        me.warned = me.warning_counts();
        Ok(me)
    }
}

/// The `mujoco.batch.Batch` of `cells`, each cell's gains, limits, friction
/// and body in it.
fn create<'py>(
    owner: &LoadedModel<'py>,
    cells: &[CellSetup],
    mode: Mode,
    threads: usize,
) -> Result<Bound<'py, PyAny>> {
    let mj = &owner.mj;
    let py = mj.py;
    let info = &owner.info;
    let n = cells.len();
    let dt = cells[0].timestep.unwrap_or(info.timestep);
    let same_body = cells.iter().all(|c| {
        c.leg_scale == cells[0].leg_scale
            && c.torso_mass_scale == cells[0].torso_mass_scale
            && c.nominal_masses()
    });
    let prepare = |m: &Bound<'py, PyAny>| prepare_model(mj, m, mode, dt);
    let template =
        prepare(&owner.variant(cells[0].leg_scale, cells[0].torso_mass_scale)?).internal()?;
    let batch = mj
        .batch
        .getattr("Batch")
        .and_then(|b| {
            // torque mode steps once per control step: a persistent batch
            // keeps each MjData between calls instead of rebuilding it
            let kw = PyDict::new(py);
            kw.set_item("persistent", mode == Mode::Torque)?;
            b.call((&template, n, threads), Some(&kw))
        })
        .internal()?;
    let colliding = colliding_geoms(&template).internal()?;
    if same_body {
        // one model: per-cell fields through expand()
        set_cell_fields(&batch, cells, mode, info, &colliding)?;
    } else {
        let models = cell_models(owner, cells, mode, dt, &colliding)?;
        batch.call_method1("set_models", (models,)).internal()?;
    }
    Ok(batch)
}

/// A batch's state rows and its warning counters.
type StateViews<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray3<i32>>);

/// The batch's state rows (one contiguous array, read and written in
/// place) and its warning counters.
fn state_views<'py>(batch: &Bound<'py, PyAny>) -> Result<StateViews<'py>> {
    let state: Bound<'py, PyArray2<f64>> = batch
        .getattr("state")
        .and_then(|s| s.cast_into::<PyArray2<f64>>().map_err(PyErr::from))
        .internal()?;
    if !state.is_c_contiguous() {
        return Err(Error::Internal(
            "batch state rows are not contiguous".into(),
        ));
    }
    let warning: Bound<'py, PyArray3<i32>> = batch
        .getattr("warning")
        .and_then(|s| s.cast_into::<PyArray3<i32>>().map_err(PyErr::from))
        .internal()?;
    Ok((state, warning))
}

/// Every simulation reset (to the keyframe, if any) and put at its start:
/// its qpos, and its ctrl at its targets (servo mode) or 0 (torque mode).
fn reset(
    owner: &LoadedModel<'_>,
    batch: &Bound<'_, PyAny>,
    state: &Bound<'_, PyArray2<f64>>,
    off: Offsets,
    starts: &StartStates,
    mode: Mode,
) -> Result<()> {
    let info = &owner.info;
    let kw = PyDict::new(owner.mj.py);
    kw.set_item("keyframe", starts.keyframe.map_or(-1, |k| k as i64))
        .internal()?;
    kw.set_item("stage", 0).internal()?;
    batch.call_method("reset", (), Some(&kw)).internal()?;
    let mut s = state.readwrite();
    let rows = s
        .as_slice_mut()
        .map_err(|e| Error::Internal(e.to_string()))?;
    for i in 0..starts.starts.len() {
        let row = &mut rows[i * off.nstate..(i + 1) * off.nstate];
        starts.qpos(owner, i, &mut row[off.qpos..off.qpos + info.nq]);
        let targets = &starts.starts[i].0;
        let ctrl = &mut row[off.ctrl..off.ctrl + info.nu];
        match mode {
            Mode::Servo => ctrl.copy_from_slice(targets),
            Mode::Torque => ctrl.fill(0.0),
        }
    }
    Ok(())
}

/// Where qpos, qvel, ctrl and xfrc_applied sit in a batch's state rows
/// (from its field views' addresses) and a row's length.
fn offsets(batch: &Bound<'_, PyAny>, state: &Bound<'_, PyArray2<f64>>) -> Result<Offsets> {
    let base_ptr = state.data() as usize;
    let offset_of = |field: &str| -> Result<usize> {
        let view = batch.call_method1("bind", (field,)).internal()?;
        let ptr: usize = view
            .getattr("__array_interface__")
            .and_then(|d| d.get_item("data"))
            .and_then(|d| d.get_item(0))
            .and_then(|p| p.extract())
            .internal()?;
        Ok((ptr - base_ptr) / std::mem::size_of::<f64>())
    };
    Ok(Offsets {
        qpos: offset_of("qpos")?,
        qvel: offset_of("qvel")?,
        ctrl: offset_of("ctrl")?,
        xfrc: offset_of("xfrc_applied")?,
        nstate: state.shape()[1],
    })
}

/// One model for every cell: each cell's gains, torque limits and friction
/// written into the batch's per-cell fields (`expand()`).
fn set_cell_fields(
    batch: &Bound<'_, PyAny>,
    cells: &[CellSetup],
    mode: Mode,
    info: &ModelInfo,
    colliding: &[usize],
) -> Result<()> {
    let gain = expand3(batch, "actuator_gainprm")?;
    let bias = expand3(batch, "actuator_biasprm")?;
    let range = expand3(batch, "actuator_forcerange")?;
    let friction = if cells.iter().any(|c| c.friction.is_some()) {
        Some(expand3(batch, "geom_friction")?)
    } else {
        None
    };
    let mut g = gain.readwrite();
    let mut b = bias.readwrite();
    let mut r = range.readwrite();
    let (mut g, mut b, mut r) = (g.as_array_mut(), b.as_array_mut(), r.as_array_mut());
    for (i, c) in cells.iter().enumerate() {
        let limits = c.torque_limits(info)?;
        for a in 0..info.nu {
            let (gp, bp) = actuator_params(mode, c, a);
            for j in 0..gp.len().min(g.shape()[2]) {
                g[[i, a, j]] = gp[j];
                b[[i, a, j]] = bp[j];
            }
            r[[i, a, 0]] = -limits[a];
            r[[i, a, 1]] = limits[a];
        }
    }
    if let Some(f) = friction {
        let mut f = f.readwrite();
        let mut f = f.as_array_mut();
        for (i, c) in cells.iter().enumerate() {
            if let Some(mu) = c.friction {
                for &gid in colliding {
                    f[[i, gid, 0]] = mu;
                }
            }
        }
    }
    Ok(())
}

/// Bodies differ: a model per distinct setting, shared by the cells that
/// have it (torque mode writes no gains into the model, so a lab's cells of
/// one body share one; fewer copies stay in cache).
fn cell_models<'py>(
    owner: &LoadedModel<'py>,
    cells: &[CellSetup],
    mode: Mode,
    dt: f64,
    colliding: &[usize],
) -> Result<Bound<'py, PyList>> {
    let (mj, info) = (&owner.mj, &owner.info);
    let layout = Physics::layout(owner);
    let prepare = |m: &Bound<'py, PyAny>| prepare_model(mj, m, mode, dt);
    let models = PyList::empty(mj.py);
    let mut made: Vec<(Vec<u64>, Bound<'py, PyAny>)> = Vec::new();
    // one scratch MjData for every mass edit's mj_setConst: the
    // models differ in values, not sizes (an MjData per model cost
    // seconds of page faults for 512 of them)
    let mut scratch: Option<Bound<'py, PyAny>> = None;
    for c in cells {
        let key = model_key(mode, c, info.nu);
        let m = match made.iter().find(|(k, _)| *k == key) {
            Some((_, m)) => m.clone(),
            None => {
                let m = prepare(&owner.variant(c.leg_scale, c.torso_mass_scale)?).internal()?;
                if !c.nominal_masses() {
                    let data = match &scratch {
                        Some(d) => d.clone(),
                        None => {
                            let d = mj.module.getattr("MjData").and_then(|f| f.call1((&m,)));
                            scratch.insert(d.internal()?).clone()
                        }
                    };
                    scale_masses(mj, &m, &data, layout.base.body, c).internal()?;
                }
                let limits = c.torque_limits(info)?;
                set_model_params(&m, mode, c, &limits, colliding).internal()?;
                made.push((key, m.clone()));
                m
            }
        };
        models.append(m).internal()?;
    }
    Ok(models)
}

/// What makes two cells' models differ: body and its masses, the gains
/// written into the actuators, torque limit, friction.
fn model_key(mode: Mode, c: &CellSetup, nu: usize) -> Vec<u64> {
    let opt = |v: Option<f64>| v.map_or(u64::MAX, f64::to_bits);
    let mut key = vec![
        c.leg_scale.to_bits(),
        c.torso_mass_scale.to_bits(),
        c.torso_mass_factor.to_bits(),
        c.leg_mass_factor.to_bits(),
        opt(c.max_torque),
        opt(c.friction),
    ];
    for a in 0..nu {
        let (gains, bias) = actuator_params(mode, c, a);
        key.extend(gains.iter().chain(&bias).map(|v| v.to_bits()));
    }
    key
}

fn expand3<'py>(batch: &Bound<'py, PyAny>, field: &str) -> Result<Bound<'py, PyArray3<f64>>> {
    batch
        .call_method1("expand", (field,))
        .and_then(|a| a.cast_into::<PyArray3<f64>>().map_err(PyErr::from))
        .internal()
}

fn set_model_params(
    m: &Bound<'_, PyAny>,
    mode: Mode,
    c: &CellSetup,
    limits: &[f64],
    colliding: &[usize],
) -> PyResult<()> {
    let g = m
        .getattr("actuator_gainprm")?
        .cast_into::<PyArray2<f64>>()?;
    let b = m
        .getattr("actuator_biasprm")?
        .cast_into::<PyArray2<f64>>()?;
    let r = m
        .getattr("actuator_forcerange")?
        .cast_into::<PyArray2<f64>>()?;
    let (mut g, mut b, mut r) = (g.readwrite(), b.readwrite(), r.readwrite());
    let (mut g, mut b, mut r) = (g.as_array_mut(), b.as_array_mut(), r.as_array_mut());
    for a in 0..g.shape()[0] {
        let (gp, bp) = actuator_params(mode, c, a);
        for j in 0..3 {
            g[[a, j]] = gp[j];
            b[[a, j]] = bp[j];
        }
        for j in 3..g.shape()[1] {
            g[[a, j]] = 0.0;
            b[[a, j]] = 0.0;
        }
        r[[a, 0]] = -limits[a];
        r[[a, 1]] = limits[a];
    }
    if let Some(mu) = c.friction {
        let f = m.getattr("geom_friction")?.cast_into::<PyArray2<f64>>()?;
        let mut f = f.readwrite();
        let mut f = f.as_array_mut();
        for &gid in colliding {
            f[[gid, 0]] = mu;
        }
    }
    Ok(())
}
