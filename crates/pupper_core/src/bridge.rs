//! The MuJoCo bridge: the only code that touches Python objects for physics.
//! It imports `mujoco` (4.x), compiles models, reads what `pupper info`
//! shows, and drives `mujoco.batch.Batch` for the runner.
//!
//! State is read and written through the batch's state rows, one contiguous
//! `(nsim, nstate)` float64 array, so the hot loop makes one borrow per step
//! and copies nothing.

use std::cell::RefCell;

use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::error::{Error, Result};
use crate::layout::Layout;
use crate::model::{ActuatorInfo, JointInfo, KeyframeInfo, ModelInfo, ModelSource, SensorInfo};
use crate::physics::{CellSetup, Controller, Force, Mode, Observer, Physics, SimBatch};
use crate::schedule::InitialState;

/// The supported `mujoco` major version.
pub const MUJOCO_MAJOR: &str = "4.";

/// How to fix a missing or wrong `mujoco`, for every message that needs it.
const MUJOCO_FIX: &str = "run `make setup` in the pupper checkout (or `pip install 'mujoco==4.0.*'` in the Python that pupper uses; `pupper doctor` shows which)";

fn py_err(e: PyErr) -> Error {
    Python::attach(|py| {
        // Ctrl-C landing inside a MuJoCo call from a notebook
        if e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py) {
            return Error::Interrupted("KeyboardInterrupt".into());
        }
        Error::Internal(python_message(py, &e))
    })
}

/// A Python exception's message on one line (MuJoCo's XML errors span
/// several: the parse error, then the element and line number).
fn python_message(py: Python<'_>, e: &PyErr) -> String {
    let text = e.value(py).to_string();
    let mut out = String::new();
    for line in text.lines().map(str::trim).filter(|l| !l.is_empty()) {
        if !out.is_empty() {
            out.push_str(if out.ends_with(':') { " " } else { "; " });
        }
        out.push_str(line);
    }
    out
}

trait PyResultExt<T> {
    fn internal(self) -> Result<T>;
}

impl<T> PyResultExt<T> for PyResult<T> {
    fn internal(self) -> Result<T> {
        self.map_err(py_err)
    }
}

/// Where the interpreter is and what it has: `pupper doctor`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PythonReport {
    pub executable: String,
    pub version: String,
    pub prefix: String,
    pub base_prefix: String,
    pub mujoco: Option<String>,
    pub mujoco_path: Option<String>,
    pub numpy: Option<String>,
    pub problem: Option<String>,
}

pub fn doctor() -> Result<PythonReport> {
    Python::attach(|py| {
        let sys = PyModule::import(py, "sys").internal()?;
        let get = |n: &str| -> Result<String> {
            sys.getattr(n)
                .internal()?
                .str()
                .internal()
                .map(|s| s.to_string())
        };
        let mut report = PythonReport {
            executable: get("executable")?,
            version: get("version")?.lines().next().unwrap_or("").to_string(),
            prefix: get("prefix")?,
            base_prefix: get("base_prefix")?,
            mujoco: None,
            mujoco_path: None,
            numpy: None,
            problem: None,
        };
        if let Ok(np) = PyModule::import(py, "numpy") {
            report.numpy = np
                .getattr("__version__")
                .and_then(|v| v.extract::<String>())
                .ok();
        }
        match Mujoco::import(py) {
            Ok(mj) => {
                report.mujoco = Some(mj.version.clone());
                report.mujoco_path = mj
                    .module
                    .getattr("__file__")
                    .and_then(|v| v.extract::<String>())
                    .ok();
            }
            Err(e) => report.problem = Some(e.to_string()),
        }
        Ok(report)
    })
}

/// The imported `mujoco` package.
#[derive(Clone)]
pub struct Mujoco<'py> {
    py: Python<'py>,
    module: Bound<'py, PyModule>,
    batch: Bound<'py, PyModule>,
    copy: Bound<'py, PyAny>,
    pub version: String,
}

impl<'py> Mujoco<'py> {
    pub fn import(py: Python<'py>) -> Result<Mujoco<'py>> {
        let executable = PyModule::import(py, "sys")
            .and_then(|s| s.getattr("executable"))
            .map(|e| e.to_string())
            .unwrap_or_default();
        let module = PyModule::import(py, "mujoco").map_err(|e| {
            Error::Mujoco(format!(
                "cannot import the Python package 'mujoco' in {executable} ({}): {MUJOCO_FIX}",
                python_message(py, &e)
            ))
        })?;
        let version: String = module
            .getattr("__version__")
            .and_then(|v| v.extract())
            .unwrap_or_else(|_| "unknown".into());
        if !version.starts_with(MUJOCO_MAJOR) {
            return Err(Error::Mujoco(format!(
                "pupper needs mujoco 4.x but {executable} has mujoco {version}: {MUJOCO_FIX}"
            )));
        }
        let batch = PyModule::import(py, "mujoco.batch").map_err(|e| {
            Error::Mujoco(format!(
                "mujoco {version} has no usable mujoco.batch ({}): {MUJOCO_FIX}",
                python_message(py, &e)
            ))
        })?;
        let copy = PyModule::import(py, "copy")
            .and_then(|c| c.getattr("copy"))
            .internal()?;
        Ok(Mujoco {
            py,
            module,
            batch,
            copy,
            version,
        })
    }

    /// Parses the model's MJCF into an `MjSpec`.
    fn spec(&self, source: &ModelSource) -> Result<Bound<'py, PyAny>> {
        let spec_cls = self.module.getattr("MjSpec").internal()?;
        let res = match source.builtin_xml() {
            Some(xml) => spec_cls.call_method1("from_string", (xml,)),
            None => match source {
                ModelSource::Path(p) => {
                    spec_cls.call_method1("from_file", (p.to_string_lossy().into_owned(),))
                }
                ModelSource::Builtin(n) => {
                    return Err(Error::Model(format!("unknown built-in model '{n}'")));
                }
            },
        };
        res.map_err(|e| self.model_error(source, &e))
    }

    fn model_error(&self, source: &ModelSource, e: &PyErr) -> Error {
        Error::Model(format!(
            "model '{}' is not valid MJCF: {}; fix the file where MuJoCo points",
            source.display(),
            python_message(self.py, e)
        ))
    }

    fn compile(&self, source: &ModelSource, spec: &Bound<'py, PyAny>) -> Result<Bound<'py, PyAny>> {
        spec.call_method0("compile")
            .map_err(|e| self.model_error(source, &e))
    }

    /// Loads and compiles a model.
    pub fn load(&self, source: &ModelSource) -> Result<LoadedModel<'py>> {
        let spec = self.spec(source)?;
        let model = self.compile(source, &spec)?;
        let info = self.info(source, &model)?;
        Ok(LoadedModel {
            mj: self.clone(),
            source: source.clone(),
            model,
            info,
            layout: None,
            variants: RefCell::new(Vec::new()),
        })
    }

    fn name_of(&self, model: &Bound<'py, PyAny>, obj: &str, id: usize) -> Result<String> {
        let kind = self
            .module
            .getattr("mjtObj")
            .and_then(|o| o.getattr(obj))
            .internal()?;
        let name = self
            .module
            .getattr("mj_id2name")
            .and_then(|f| f.call1((model, kind, id)))
            .internal()?;
        Ok(name
            .extract::<Option<String>>()
            .internal()?
            .unwrap_or_default())
    }

    fn info(&self, source: &ModelSource, model: &Bound<'py, PyAny>) -> Result<ModelInfo> {
        let int =
            |n: &str| -> Result<usize> { model.getattr(n).and_then(|v| v.extract()).internal() };
        let list = |n: &str| -> Result<Bound<'py, PyAny>> {
            model
                .getattr(n)
                .and_then(|v| v.call_method0("tolist"))
                .internal()
        };
        let ints = |n: &str| -> Result<Vec<i64>> { list(n)?.extract().internal() };
        let floats2 = |n: &str| -> Result<Vec<Vec<f64>>> { list(n)?.extract().internal() };
        let (nq, nv, nu, nbody) = (int("nq")?, int("nv")?, int("nu")?, int("nbody")?);
        let njnt = int("njnt")?;
        let timestep: f64 = model
            .getattr("opt")
            .and_then(|o| o.getattr("timestep"))
            .and_then(|t| t.extract())
            .internal()?;
        let masses: Vec<f64> = list("body_mass")?.extract().internal()?;
        let bodies = (0..nbody)
            .map(|i| self.name_of(model, "mjOBJ_BODY", i))
            .collect::<Result<Vec<_>>>()?;
        let (jtype, jq, jd, jlim, jbody) = (
            ints("jnt_type")?,
            ints("jnt_qposadr")?,
            ints("jnt_dofadr")?,
            ints("jnt_limited")?,
            ints("jnt_bodyid")?,
        );
        let jrange = floats2("jnt_range")?;
        let mut joints = Vec::with_capacity(njnt);
        for i in 0..njnt {
            joints.push(JointInfo {
                name: self.name_of(model, "mjOBJ_JOINT", i)?,
                kind: ["free", "ball", "slide", "hinge"]
                    .get(jtype[i] as usize)
                    .unwrap_or(&"unknown")
                    .to_string(),
                qpos_adr: jq[i] as usize,
                dof_adr: jd[i] as usize,
                range: (jlim[i] != 0).then(|| [jrange[i][0], jrange[i][1]]),
                body: jbody[i] as usize,
            });
        }
        let (trntype, trnid, flim) = (
            ints("actuator_trntype")?,
            floats2("actuator_trnid")?,
            ints("actuator_forcelimited")?,
        );
        let (gain, bias, frange) = (
            floats2("actuator_gainprm")?,
            floats2("actuator_biasprm")?,
            floats2("actuator_forcerange")?,
        );
        let mut actuators = Vec::with_capacity(nu);
        for i in 0..nu {
            // trntype 0 is mjTRN_JOINT
            let joint = (trntype[i] == 0).then_some(trnid[i][0] as usize);
            actuators.push(ActuatorInfo {
                name: self.name_of(model, "mjOBJ_ACTUATOR", i)?,
                joint,
                gainprm: [gain[i][0], gain[i][1], gain[i][2]],
                biasprm: [bias[i][0], bias[i][1], bias[i][2]],
                forcerange: (flim[i] != 0).then(|| [frange[i][0], frange[i][1]]),
            });
        }
        let nkey = int("nkey")?;
        let (kq, kc) = (floats2("key_qpos")?, floats2("key_ctrl")?);
        let keyframes = (0..nkey)
            .map(|i| {
                Ok(KeyframeInfo {
                    name: self.name_of(model, "mjOBJ_KEY", i)?,
                    qpos: kq[i].clone(),
                    ctrl: kc.get(i).cloned().unwrap_or_default(),
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let nsensor = int("nsensor")?;
        let (stype, sdim) = (ints("sensor_type")?, ints("sensor_dim")?);
        let sensor_enum = self.module.getattr("mjtSensor").internal()?;
        let sensors = (0..nsensor)
            .map(|i| {
                let kind = sensor_enum
                    .call1((stype[i],))
                    .and_then(|e| e.getattr("name"))
                    .map(|n| n.to_string().trim_start_matches("mjSENS_").to_lowercase())
                    .unwrap_or_else(|_| stype[i].to_string());
                Ok(SensorInfo {
                    name: self.name_of(model, "mjOBJ_SENSOR", i)?,
                    kind,
                    dim: sdim[i] as usize,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let name = match self.name_of(model, "mjOBJ_MODEL", 0) {
            Ok(n) if !n.is_empty() => n,
            _ => source.display(),
        };
        Ok(ModelInfo {
            name,
            source: source.display(),
            sha256: source.sha256()?,
            nq,
            nv,
            nu,
            nbody,
            timestep,
            total_mass: masses.iter().sum(),
            bodies,
            joints,
            actuators,
            keyframes,
            sensors,
        })
    }
}

/// A compiled body variant, keyed by the bits of (leg_scale, torso_mass_scale).
type Variant<'py> = ((u64, u64), Bound<'py, PyAny>);

/// A compiled model and what was read from it.
pub struct LoadedModel<'py> {
    mj: Mujoco<'py>,
    source: ModelSource,
    model: Bound<'py, PyAny>,
    info: ModelInfo,
    layout: Option<Layout>,
    /// Compiled body variants by (leg_scale, torso_mass_scale) bits.
    variants: RefCell<Vec<Variant<'py>>>,
}

impl<'py> LoadedModel<'py> {
    pub fn info(&self) -> &ModelInfo {
        &self.info
    }

    /// Requires a floating base with joint actuators (for stand and sweep).
    pub fn floating(mut self) -> Result<LoadedModel<'py>> {
        self.layout = Some(Layout::floating(&self.info)?);
        Ok(self)
    }

    pub fn mujoco_version(&self) -> &str {
        &self.mj.version
    }

    pub fn python_executable(&self) -> String {
        PyModule::import(self.mj.py, "sys")
            .and_then(|s| s.getattr("executable"))
            .map(|e| e.to_string())
            .unwrap_or_default()
    }

    /// The `MjModel` object, for Python callers (rendering, viewers).
    pub fn model(&self) -> &Bound<'py, PyAny> {
        &self.model
    }

    /// A model with scaled legs and torso, compiled from an edited spec.
    fn variant(&self, leg_scale: f64, torso_mass_scale: f64) -> Result<Bound<'py, PyAny>> {
        if leg_scale == 1.0 && torso_mass_scale == 1.0 {
            return Ok(self.model.clone());
        }
        let key = (leg_scale.to_bits(), torso_mass_scale.to_bits());
        if let Some((_, m)) = self.variants.borrow().iter().find(|(k, _)| *k == key) {
            return Ok(m.clone());
        }
        let spec = self.mj.spec(&self.source)?;
        let layout = self
            .layout
            .as_ref()
            .ok_or_else(|| Error::Internal("variants need a floating model".into()))?;
        let base_name = &self.info.bodies[layout.base.body];
        scale_spec(&spec, base_name, leg_scale, torso_mass_scale).internal()?;
        let model = self.mj.compile(&self.source, &spec)?;
        self.variants.borrow_mut().push((key, model.clone()));
        Ok(model)
    }
}

/// Scales the spec in memory: bodies two or more levels below the base (the
/// thigh and calf segments of each leg) get their offsets, geoms, sites and
/// inertial positions scaled by `leg`, their masses by `leg` and inertias by
/// `leg^3` (a uniform rod); the base body's mass and inertia by `torso`.
fn scale_spec(spec: &Bound<'_, PyAny>, base: &str, leg: f64, torso: f64) -> PyResult<()> {
    let py = spec.py();
    let scale3 = |obj: &Bound<'_, PyAny>, attr: &str, s: f64| -> PyResult<()> {
        let v: Vec<f64> = obj.getattr(attr)?.call_method0("tolist")?.extract()?;
        let scaled: Vec<f64> = v.iter().map(|x| x * s).collect();
        obj.setattr(attr, PyList::new(py, scaled)?)
    };
    let base_body = spec.call_method1("body", (base,))?;
    if torso != 1.0 {
        let m: f64 = base_body.getattr("mass")?.extract()?;
        base_body.setattr("mass", m * torso)?;
        scale3(&base_body, "inertia", torso)?;
    }
    if leg == 1.0 {
        return Ok(());
    }
    // depth-first over the base's descendants, tracking depth
    let mut stack: Vec<(Bound<'_, PyAny>, usize)> = Vec::new();
    for c in children(&base_body)? {
        stack.push((c, 1));
    }
    while let Some((body, depth)) = stack.pop() {
        for c in children(&body)? {
            stack.push((c, depth + 1));
        }
        if depth < 2 {
            continue;
        }
        if depth >= 3 {
            // its offset from the parent is the parent segment's length
            scale3(&body, "pos", leg)?;
        }
        scale3(&body, "ipos", leg)?;
        let m: f64 = body.getattr("mass")?.extract()?;
        body.setattr("mass", m * leg)?;
        scale3(&body, "inertia", leg * leg * leg)?;
        for g in body.getattr("geoms")?.try_iter()? {
            let g = g?;
            let fromto: Vec<f64> = g.getattr("fromto")?.call_method0("tolist")?.extract()?;
            if fromto.iter().all(|x| x.is_finite()) {
                scale3(&g, "fromto", leg)?;
            } else {
                scale3(&g, "pos", leg)?;
            }
        }
        for s in body.getattr("sites")?.try_iter()? {
            scale3(&s?, "pos", leg)?;
        }
    }
    Ok(())
}

/// The direct child bodies of a spec body.
fn children<'py>(b: &Bound<'py, PyAny>) -> PyResult<Vec<Bound<'py, PyAny>>> {
    b.getattr("bodies")?.extract()
}

impl Physics for LoadedModel<'_> {
    fn info(&self) -> &ModelInfo {
        &self.info
    }

    fn layout(&self) -> &Layout {
        // start() is only reachable through floating()
        self.layout
            .as_ref()
            .unwrap_or_else(|| unreachable!("layout of a non-floating model"))
    }

    fn start(
        &self,
        cells: &[CellSetup],
        mode: Mode,
        initial: &InitialState,
        threads: usize,
    ) -> Result<Box<dyn SimBatch + '_>> {
        let batch = MujocoBatch::new(self, cells, mode, initial, threads)?;
        Ok(Box::new(batch))
    }
}

/// Offsets of state components within a state row.
#[derive(Debug, Clone, Copy)]
struct Offsets {
    qpos: usize,
    qvel: usize,
    ctrl: usize,
    xfrc: usize,
    nstate: usize,
}

pub struct MujocoBatch<'a, 'py> {
    owner: &'a LoadedModel<'py>,
    batch: Bound<'py, PyAny>,
    state: Bound<'py, PyArray2<f64>>,
    warning: Bound<'py, PyArray3<i32>>,
    /// Warning counts after the last call, per simulation.
    warned: Vec<i64>,
    off: Offsets,
    targets: Vec<f64>,
    nsim: usize,
    /// Row of the base body in xfrc_applied.
    force_body: usize,
    nbody: usize,
}

impl<'a, 'py> MujocoBatch<'a, 'py> {
    fn new(
        owner: &'a LoadedModel<'py>,
        cells: &[CellSetup],
        mode: Mode,
        initial: &InitialState,
        threads: usize,
    ) -> Result<Self> {
        let mj = &owner.mj;
        let py = mj.py;
        let info = &owner.info;
        let layout = Physics::layout(owner);
        let n = cells.len();
        let dt = cells[0].timestep.unwrap_or(info.timestep);
        let same_body = cells.iter().all(|c| {
            c.leg_scale == cells[0].leg_scale && c.torso_mass_scale == cells[0].torso_mass_scale
        });
        let prepare = |m: &Bound<'py, PyAny>| -> PyResult<Bound<'py, PyAny>> {
            let m = mj.copy.call1((m,))?;
            m.getattr("opt")?.setattr("timestep", dt)?;
            if mode == Mode::Torque {
                // direct torque inputs must not be clamped to a position range
                m.getattr("actuator_ctrllimited")?
                    .call_method1("fill", (0,))?;
            }
            Ok(m)
        };
        let template =
            prepare(&owner.variant(cells[0].leg_scale, cells[0].torso_mass_scale)?).internal()?;
        let batch = mj
            .batch
            .getattr("Batch")
            .and_then(|b| b.call1((&template, n, threads)))
            .internal()?;
        let colliding = colliding_geoms(&template).internal()?;
        if same_body {
            // one model: per-cell fields through expand()
            let gain = expand3(&batch, "actuator_gainprm")?;
            let bias = expand3(&batch, "actuator_biasprm")?;
            let range = expand3(&batch, "actuator_forcerange")?;
            let friction = if cells.iter().any(|c| c.friction.is_some()) {
                Some(expand3(&batch, "geom_friction")?)
            } else {
                None
            };
            let mut g = gain.readwrite();
            let mut b = bias.readwrite();
            let mut r = range.readwrite();
            let (mut g, mut b, mut r) = (g.as_array_mut(), b.as_array_mut(), r.as_array_mut());
            for (i, c) in cells.iter().enumerate() {
                for a in 0..info.nu {
                    let (gp, bp) = actuator_params(mode, c);
                    for j in 0..gp.len().min(g.shape()[2]) {
                        g[[i, a, j]] = gp[j];
                        b[[i, a, j]] = bp[j];
                    }
                    r[[i, a, 0]] = -c.max_torque;
                    r[[i, a, 1]] = c.max_torque;
                }
            }
            if let Some(f) = friction {
                let mut f = f.readwrite();
                let mut f = f.as_array_mut();
                for (i, c) in cells.iter().enumerate() {
                    if let Some(mu) = c.friction {
                        for &gid in &colliding {
                            f[[i, gid, 0]] = mu;
                        }
                    }
                }
            }
        } else {
            // bodies differ: a model per cell, from the compiled variants
            let models = PyList::empty(py);
            for c in cells {
                let m = prepare(&owner.variant(c.leg_scale, c.torso_mass_scale)?).internal()?;
                set_model_params(&m, mode, c, &colliding).internal()?;
                models.append(m).internal()?;
            }
            batch.call_method1("set_models", (models,)).internal()?;
        }
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
        let off = Offsets {
            qpos: offset_of("qpos")?,
            qvel: offset_of("qvel")?,
            ctrl: offset_of("ctrl")?,
            xfrc: offset_of("xfrc_applied")?,
            nstate: state.shape()[1],
        };
        // initial state and targets
        let (key, pose) = match initial {
            InitialState::Keyframe(name) => (Some(info.keyframe(name)?.0), None),
            InitialState::Pose(p) => {
                if p.len() != info.nu {
                    return Err(Error::Config(format!(
                        "the pose has {} angles but model '{}' has {} actuated joints: give one angle per actuator, in actuator order",
                        p.len(),
                        info.name,
                        info.nu
                    )));
                }
                (info.keyframes.first().map(|_| 0), Some(p.clone()))
            }
        };
        let kw = PyDict::new(py);
        kw.set_item("keyframe", key.map_or(-1, |k| k as i64))
            .internal()?;
        kw.set_item("stage", 0).internal()?;
        batch.call_method("reset", (), Some(&kw)).internal()?;
        let targets = match (&pose, key) {
            (Some(p), _) => p.clone(),
            (None, Some(k)) => {
                let kf = &info.keyframes[k];
                if kf.ctrl.len() == info.nu {
                    kf.ctrl.clone()
                } else {
                    layout.joint_targets(&kf.qpos)
                }
            }
            (None, None) => vec![0.0; info.nu],
        };
        {
            let mut s = state.readwrite();
            let rows = s
                .as_slice_mut()
                .map_err(|e| Error::Internal(e.to_string()))?;
            for i in 0..n {
                let row = &mut rows[i * off.nstate..(i + 1) * off.nstate];
                if let Some(p) = &pose {
                    for (a, &q) in p.iter().enumerate() {
                        row[off.qpos + layout.act_qpos[a]] = q;
                    }
                }
                let ctrl = &mut row[off.ctrl..off.ctrl + info.nu];
                match mode {
                    Mode::Servo => ctrl.copy_from_slice(&targets),
                    Mode::Torque => ctrl.fill(0.0),
                }
            }
        }
        let warned = vec![0; n];
        let mut me = MujocoBatch {
            owner,
            batch,
            state,
            warning,
            warned,
            off,
            targets,
            nsim: n,
            force_body: layout.base.body,
            nbody: info.nbody,
        };
        me.warned = me.warning_counts();
        Ok(me)
    }

    /// Total warnings so far, per simulation.
    fn warning_counts(&self) -> Vec<i64> {
        let w = self.warning.readonly();
        let w = w.as_array();
        (0..self.nsim)
            .map(|i| {
                w.slice(numpy::ndarray::s![i, .., 1])
                    .iter()
                    .map(|&c| c as i64)
                    .sum()
            })
            .collect()
    }

    /// Simulations among `ids` whose warning counts rose since the last call.
    fn newly_warned(&mut self, ids: &[usize]) -> Vec<usize> {
        let now = self.warning_counts();
        let mut out = Vec::new();
        for (pos, &sim) in ids.iter().enumerate() {
            if now[sim] > self.warned[sim] {
                out.push(pos);
            }
        }
        self.warned = now;
        out
    }

    fn ids_arg(&self, ids: &[usize]) -> Result<Bound<'py, PyAny>> {
        let py = self.owner.mj.py;
        if ids.len() == self.nsim {
            return Ok(py.None().into_bound(py));
        }
        let v: Vec<i32> = ids.iter().map(|&i| i as i32).collect();
        Ok(PyArray1::from_vec(py, v).into_any())
    }

    fn write_force(&self, rows: &mut [f64], sim: usize, f: [f64; 3]) {
        let at = sim * self.off.nstate + self.off.xfrc + 6 * self.force_body;
        rows[at..at + 3].copy_from_slice(&f);
        rows[at + 3..at + 6].fill(0.0);
    }
}

/// The simulations a `mujoco.batch.SimulationError` names; any other
/// exception is an internal error.
fn failed_ids(py: Python<'_>, e: PyErr) -> Result<Vec<i64>> {
    e.value(py)
        .getattr("ids")
        .and_then(|i| i.call_method0("tolist"))
        .and_then(|i| i.extract())
        .map_err(|_| py_err(e))
}

fn actuator_params(mode: Mode, c: &CellSetup) -> ([f64; 3], [f64; 3]) {
    match mode {
        Mode::Servo => ([c.kp, 0.0, 0.0], [0.0, -c.kp, -c.kd]),
        Mode::Torque => ([1.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
    }
}

fn expand3<'py>(batch: &Bound<'py, PyAny>, field: &str) -> Result<Bound<'py, PyArray3<f64>>> {
    batch
        .call_method1("expand", (field,))
        .and_then(|a| a.cast_into::<PyArray3<f64>>().map_err(PyErr::from))
        .internal()
}

/// Geoms that take part in contacts (the feet and the floor, in Pupper).
fn colliding_geoms(model: &Bound<'_, PyAny>) -> PyResult<Vec<usize>> {
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

fn set_model_params(
    m: &Bound<'_, PyAny>,
    mode: Mode,
    c: &CellSetup,
    colliding: &[usize],
) -> PyResult<()> {
    let (gp, bp) = actuator_params(mode, c);
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
        for j in 0..3 {
            g[[a, j]] = gp[j];
            b[[a, j]] = bp[j];
        }
        for j in 3..g.shape()[1] {
            g[[a, j]] = 0.0;
            b[[a, j]] = 0.0;
        }
        r[[a, 0]] = -c.max_torque;
        r[[a, 1]] = c.max_torque;
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

impl SimBatch for MujocoBatch<'_, '_> {
    fn len(&self) -> usize {
        self.nsim
    }

    fn targets(&self) -> &[f64] {
        &self.targets
    }

    fn advance(
        &mut self,
        ids: &[usize],
        nstep: usize,
        force: Force<'_>,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<(usize, usize)>> {
        let py = self.owner.mj.py;
        let nq = self.owner.info.nq;
        let nu = self.owner.info.nu;
        let kw = PyDict::new(py);
        match force {
            Force::Constant(f) => {
                let mut s = self.state.readwrite();
                let rows = s
                    .as_slice_mut()
                    .map_err(|e| Error::Internal(e.to_string()))?;
                for (pos, &sim) in ids.iter().enumerate() {
                    self.write_force(rows, sim, f[pos]);
                }
            }
            Force::PerStep(f) => {
                let width = 6 * self.nbody;
                let mut control = vec![0.0f64; ids.len() * nstep * width];
                for pos in 0..ids.len() {
                    for j in 0..nstep {
                        let at = (pos * nstep + j) * width + 6 * self.force_body;
                        control[at..at + 3].copy_from_slice(&f[pos * nstep + j]);
                    }
                }
                let arr = PyArray1::from_vec(py, control)
                    .reshape([ids.len(), nstep, width])
                    .internal()?;
                let spec = self
                    .owner
                    .mj
                    .module
                    .getattr("mjtState")
                    .and_then(|s| s.getattr("mjSTATE_XFRC_APPLIED"))
                    .and_then(|s| s.getattr("value"))
                    .internal()?;
                kw.set_item("control", arr).internal()?;
                kw.set_item("control_spec", spec).internal()?;
            }
        }
        kw.set_item("record", ("qpos", "actuator_force"))
            .internal()?;
        kw.set_item("ids", self.ids_arg(ids)?).internal()?;
        let out = match self.batch.call_method("rollout", (nstep,), Some(&kw)) {
            Ok(out) => out,
            Err(e) => {
                // MuJoCo raised in some simulations: they diverged at this call
                let failed = failed_ids(py, e)?;
                return Ok(ids
                    .iter()
                    .enumerate()
                    .filter(|(_, s)| failed.contains(&(**s as i64)))
                    .map(|(p, _)| (p, 0))
                    .collect());
            }
        };
        let qpos = out
            .get_item("qpos")
            .and_then(|a| a.cast_into::<PyArray3<f64>>().map_err(PyErr::from))
            .internal()?;
        let act = out
            .get_item("actuator_force")
            .and_then(|a| a.cast_into::<PyArray3<f64>>().map_err(PyErr::from))
            .internal()?;
        let warned = self.newly_warned(ids);
        let qpos = qpos.readonly();
        let act = act.readonly();
        let qs = qpos
            .as_slice()
            .map_err(|e| Error::Internal(e.to_string()))?;
        let acts = act.as_slice().map_err(|e| Error::Internal(e.to_string()))?;
        let mut diverged = Vec::new();
        for pos in 0..ids.len() {
            let rec = |j: usize| &qs[(pos * nstep + j) * nq..(pos * nstep + j + 1) * nq];
            // A warned simulation stopped stepping and repeats its last
            // record; the step that warned is the one before the repeats.
            let mut valid = nstep;
            if warned.contains(&pos) {
                let stop = (1..nstep).find(|&j| rec(j) == rec(j - 1)).unwrap_or(nstep);
                valid = stop.saturating_sub(1);
            }
            for j in 0..valid {
                let q = rec(j);
                if q.iter().any(|x| !x.is_finite()) {
                    valid = j;
                    break;
                }
                let a = &acts[(pos * nstep + j) * nu..(pos * nstep + j + 1) * nu];
                observe(pos, j, q, a);
            }
            if valid < nstep {
                diverged.push((pos, valid));
            }
        }
        Ok(diverged)
    }

    fn step_controlled(
        &mut self,
        ids: &[usize],
        force: &[[f64; 3]],
        control: &mut Controller<'_>,
        observe: &mut Observer<'_>,
    ) -> Result<Vec<usize>> {
        let (nq, nv, nu) = (self.owner.info.nq, self.owner.info.nv, self.owner.info.nu);
        let off = self.off;
        let mut ctrl = vec![0.0f64; nu];
        {
            let mut s = self.state.readwrite();
            let rows = s
                .as_slice_mut()
                .map_err(|e| Error::Internal(e.to_string()))?;
            for (pos, &sim) in ids.iter().enumerate() {
                let row = &rows[sim * off.nstate..(sim + 1) * off.nstate];
                control(
                    pos,
                    &row[off.qpos..off.qpos + nq],
                    &row[off.qvel..off.qvel + nv],
                    &mut ctrl,
                );
                let at = sim * off.nstate + off.ctrl;
                rows[at..at + nu].copy_from_slice(&ctrl);
                self.write_force(rows, sim, force[pos]);
            }
        }
        let ids_arg = self.ids_arg(ids)?;
        if let Err(e) = self.batch.call_method1("step", (ids_arg,)) {
            let failed = failed_ids(self.owner.mj.py, e)?;
            let _ = self.newly_warned(ids);
            return Ok(ids
                .iter()
                .enumerate()
                .filter(|(_, s)| failed.contains(&(**s as i64)))
                .map(|(p, _)| p)
                .collect());
        }
        let mut diverged = self.newly_warned(ids);
        let s = self.state.readonly();
        let rows = s.as_slice().map_err(|e| Error::Internal(e.to_string()))?;
        for (pos, &sim) in ids.iter().enumerate() {
            if diverged.contains(&pos) {
                continue;
            }
            let q = &rows[sim * off.nstate + off.qpos..sim * off.nstate + off.qpos + nq];
            if q.iter().any(|x| !x.is_finite()) {
                diverged.push(pos);
                continue;
            }
            observe(pos, 0, q, &[]);
        }
        Ok(diverged)
    }
}

/// Runs `f` with the imported `mujoco` and the model, floating-checked.
pub fn with_model<T>(
    source: &ModelSource,
    floating: bool,
    f: impl for<'py> FnOnce(&LoadedModel<'py>) -> Result<T>,
) -> Result<T> {
    Python::attach(|py| {
        let mj = Mujoco::import(py)?;
        let model = mj.load(source)?;
        let model = if floating { model.floating()? } else { model };
        f(&model)
    })
}

/// Calls a function of our Python package (plots, rendering, the viewer)
/// with string arguments and keyword arguments; returns its result as
/// strings (a path or a list of paths). `RenderUnavailable` and
/// `DisplayUnavailable` become one-line [`Error::Display`]s.
pub fn call_helper(
    module: &str,
    func: &str,
    args: &[String],
    kwargs: &[(&str, f64)],
) -> Result<Vec<String>> {
    Python::attach(|py| {
        Mujoco::import(py)?;
        let m = PyModule::import(py, module).map_err(|e| {
            Error::Mujoco(format!(
                "cannot import {module} ({}): run `make setup` to install pupper's Python package into the project venv",
                python_message(py, &e)
            ))
        })?;
        let kw = PyDict::new(py);
        for (k, v) in kwargs {
            kw.set_item(k, v).internal()?;
        }
        let out = m
            .getattr(func)
            .and_then(|f| f.call(pyo3::types::PyTuple::new(py, args)?, Some(&kw)))
            .map_err(|e| {
                let kind = e
                    .get_type(py)
                    .name()
                    .map(|n| n.to_string())
                    .unwrap_or_default();
                let msg = python_message(py, &e);
                if kind.ends_with("Unavailable") {
                    Error::Display(msg)
                } else {
                    Error::Internal(format!("{module}.{func}: {kind}: {msg}"))
                }
            })?;
        if out.is_none() {
            return Ok(vec![]);
        }
        if !(out.is_instance_of::<PyList>() || out.is_instance_of::<pyo3::types::PyTuple>()) {
            return Ok(vec![out.to_string()]);
        }
        let items: Vec<Bound<'_, PyAny>> = out
            .try_iter()
            .internal()?
            .collect::<PyResult<_>>()
            .internal()?;
        Ok(items.iter().map(|i| i.to_string()).collect())
    })
}
