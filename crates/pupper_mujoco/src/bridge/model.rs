//! Loading models: MJCF into `MjSpec`, compiled `MjModel`s, and body
//! variants edited in memory (scaled legs, heavier torso).

use std::cell::RefCell;

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};

use super::python::{Mujoco, PyResultExt, python_message};
use pupper_core::error::{Error, Result};
use pupper_core::robot::layout::Layout;
use pupper_core::robot::model::{Builtin, ModelInfo, ModelSource};
use pupper_core::robot::pose::StandPose;

impl<'py> Mujoco<'py> {
    /// Parses the model's MJCF into an `MjSpec`.
    pub(crate) fn spec(&self, source: &ModelSource) -> Result<Bound<'py, PyAny>> {
        let spec_cls = self.module.getattr("MjSpec").internal()?;
        let res = match source.builtin() {
            Some(b) => {
                let spec = builtin_spec(&spec_cls, b).internal()?;
                return Ok(spec);
            }
            None => match source {
                // MuJoCo picks a file's reader by its extension; one without
                // prints a WARNING line (and writes MUJOCO_LOG.TXT) before it fails
                ModelSource::Path(p) if p.extension().is_none_or(|x| x.is_empty()) => {
                    return Err(Error::Model(format!(
                        "model '{}' is not valid MJCF: its name has no extension, by which MuJoCo picks the reader; give an MJCF file ending in .xml",
                        source.display()
                    )));
                }
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

    pub(crate) fn model_error(&self, source: &ModelSource, e: &PyErr) -> Error {
        Error::Model(format!(
            "model '{}' is not valid MJCF: {}; fix the file where MuJoCo points",
            source.display(),
            python_message(self.py, e)
        ))
    }

    pub(crate) fn compile(
        &self,
        source: &ModelSource,
        spec: &Bound<'py, PyAny>,
    ) -> Result<Bound<'py, PyAny>> {
        spec.call_method0("compile")
            .map_err(|e| self.model_error(source, &e))
    }

    /// Loads and compiles a model.
    pub fn load(&self, source: &ModelSource) -> Result<LoadedModel<'py>> {
        self.load_on(source, false)
    }

    /// Loads a model, `suspended` on the response test bench (base fixed,
    /// no contacts).
    pub fn load_on(&self, source: &ModelSource, suspended: bool) -> Result<LoadedModel<'py>> {
        let spec = self.spec_on(source, suspended)?;
        let model = self.compile(source, &spec)?;
        let info = self.info(source, &model)?;
        Ok(LoadedModel {
            mj: self.clone(),
            source: source.clone(),
            model,
            info,
            layout: None,
            suspended,
            integrator: None,
            variants: RefCell::new(Vec::new()),
        })
    }

    fn spec_on(&self, source: &ModelSource, suspended: bool) -> Result<Bound<'py, PyAny>> {
        let spec = self.spec(source)?;
        if suspended {
            suspend(&spec).internal()?;
        }
        Ok(spec)
    }
}

/// The spec of a built-in model: its main text with its includes given as
/// in-memory files; a fixed base loses its free joint (and the keyframes
/// their base coordinates).
fn builtin_spec<'py>(spec_cls: &Bound<'py, PyAny>, b: &Builtin) -> PyResult<Bound<'py, PyAny>> {
    let py = spec_cls.py();
    let include = PyDict::new(py);
    for (name, text) in b.includes {
        include.set_item(name, PyBytes::new(py, text.as_bytes()))?;
    }
    let kw = PyDict::new(py);
    kw.set_item("include", include)?;
    let spec = spec_cls.call_method("from_string", (b.main,), Some(&kw))?;
    spec.setattr("modelname", b.name)?;
    if b.fixed_base {
        fix_base(&spec)?;
    }
    Ok(spec)
}

/// Welds the base where the file puts it: the root's free joint deleted
/// (and the keyframes' base coordinates with it). Only a free joint that
/// comes first (the root's, as MJCF puts it) is removed.
fn fix_base(spec: &Bound<'_, PyAny>) -> PyResult<()> {
    let Some(first) = spec.getattr("joints")?.try_iter()?.next() else {
        return Ok(());
    };
    let joint = first?;
    if joint.getattr("type")?.getattr("value")?.extract::<i64>()? != 0 {
        return Ok(()); // mjJNT_FREE is 0
    }
    spec.call_method1("delete", (joint,))?;
    for key in spec.getattr("keys")?.try_iter()? {
        let key = key?;
        let qpos: Vec<f64> = key.getattr("qpos")?.extract()?;
        if qpos.len() >= 7 {
            key.setattr("qpos", qpos[7..].to_vec())?;
        }
    }
    Ok(())
}

/// The response test bench: the robot hung in the air, its base fixed and
/// no contacts (MuJoCo's contact pass disabled).
fn suspend(spec: &Bound<'_, PyAny>) -> PyResult<()> {
    fix_base(spec)?;
    let py = spec.py();
    let bit: i64 = PyModule::import(py, "mujoco")?
        .getattr("mjtDisableBit")?
        .getattr("mjDSBL_CONTACT")?
        .getattr("value")?
        .extract()?;
    let option = spec.getattr("option")?;
    let flags: i64 = option.getattr("disableflags")?.extract()?;
    option.setattr("disableflags", flags | bit)
}

/// A compiled body variant, keyed by the bits of (leg_scale, torso_mass_scale).
type Variant<'py> = ((u64, u64), Bound<'py, PyAny>);

/// A compiled model and what was read from it.
pub struct LoadedModel<'py> {
    pub(crate) mj: Mujoco<'py>,
    source: ModelSource,
    model: Bound<'py, PyAny>,
    pub(crate) info: ModelInfo,
    pub(crate) layout: Option<Layout>,
    /// Hung in the air: base fixed, no contacts.
    suspended: bool,
    /// MuJoCo's integrator asked for instead of the model's (`mjtIntegrator`).
    integrator: Option<i64>,
    /// Compiled body variants by (leg_scale, torso_mass_scale) bits.
    variants: RefCell<Vec<Variant<'py>>>,
}

impl<'py> LoadedModel<'py> {
    pub fn info(&self) -> &ModelInfo {
        &self.info
    }

    /// Requires a floating base with joint actuators (for stand and
    /// sweep), or on the suspended bench joint actuators alone.
    pub fn floating(mut self) -> Result<LoadedModel<'py>> {
        self.layout = Some(match self.suspended {
            false => Layout::floating(&self.info)?,
            true => Layout::suspended(&self.info)?,
        });
        Ok(self)
    }

    /// The model run with MuJoCo's integrator `integrator`
    /// (`mjtIntegrator`), its variants too; None keeps the model's own.
    pub fn with_integrator(mut self, integrator: Option<i64>) -> Result<LoadedModel<'py>> {
        if let Some(i) = integrator {
            self.model
                .getattr("opt")
                .and_then(|o| o.setattr("integrator", i))
                .internal()?;
            self.info.integrator = i;
            self.integrator = Some(i);
        }
        Ok(self)
    }

    /// The state layout, once [`LoadedModel::floating`] checked the model.
    pub fn layout(&self) -> Option<&Layout> {
        self.layout.as_ref()
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

    /// The stand pose of a body variant, searched on its compiled geometry.
    pub fn stand_pose(
        &self,
        leg_scale: f64,
        torso_mass_scale: f64,
        depth: Option<f64>,
    ) -> Result<StandPose> {
        let body = self.variant(leg_scale, torso_mass_scale)?;
        let info = self.mj.info(&self.source, &body)?;
        pupper_core::robot::pose::stand_pose(&info, leg_scale, depth)
    }

    /// The stance height of `body` with the joints of `qpos`: the base
    /// height at which its lowest foot (each leg's foot geom; a model
    /// without legs: its lowest colliding geom's bounding sphere) touches
    /// z = 0. Falls and collapses are judged against it.
    pub fn stance(&self, body: &Bound<'py, PyAny>, qpos: &[f64]) -> Result<f64> {
        let layout = self
            .layout
            .as_ref()
            .ok_or_else(|| Error::Internal("stance needs a floating model".into()))?;
        // a fixed base stands on nothing: no stance, no falls
        let Some(zi) = layout.base.z() else {
            return Ok(f64::NAN);
        };
        let lowest = (|| -> PyResult<f64> {
            let data = self.mj.module.getattr("MjData")?.call1((body,))?;
            let q = data.getattr("qpos")?;
            for (i, v) in qpos.iter().enumerate() {
                q.set_item(i, *v)?;
            }
            self.mj
                .module
                .getattr("mj_kinematics")?
                .call1((body, &data))?;
            let list = |obj: &Bound<'py, PyAny>, n: &str| -> PyResult<Bound<'py, PyAny>> {
                obj.getattr(n)?.call_method0("tolist")
            };
            let gpos: Vec<[f64; 3]> = list(&data, "geom_xpos")?.extract()?;
            let gsize: Vec<[f64; 3]> = list(body, "geom_size")?.extract()?;
            if !self.info.legs.is_empty() {
                return Ok(self
                    .info
                    .legs
                    .iter()
                    .map(|l| gpos[l.foot_geom][2] - gsize[l.foot_geom][0])
                    .fold(f64::INFINITY, f64::min));
            }
            let gbody: Vec<usize> = list(body, "geom_bodyid")?.extract()?;
            let rbound: Vec<f64> = list(body, "geom_rbound")?.extract()?;
            let ctype: Vec<i64> = list(body, "geom_contype")?.extract()?;
            let caff: Vec<i64> = list(body, "geom_conaffinity")?.extract()?;
            Ok((0..gbody.len())
                .filter(|&g| gbody[g] != 0 && (ctype[g] != 0 || caff[g] != 0))
                .map(|g| gpos[g][2] - rbound[g])
                .fold(f64::INFINITY, f64::min))
        })()
        .internal()?;
        let z = qpos[zi];
        let stance = z - lowest;
        // a robot without a foot below its base: judge it by where it starts
        Ok(if stance.is_finite() && stance > 0.0 {
            stance
        } else {
            z
        })
    }

    /// Each actuated joint's reflected inertia at `qpos`: the joint-space
    /// inertia matrix's diagonal (armature included), in ctrl order.
    pub fn joint_inertia(&self, qpos: &[f64]) -> Result<Vec<f64>> {
        self.body_joint_inertia(&self.model, qpos)
    }

    /// Each actuated joint's viscous damping (N·m·s/rad, MuJoCo's
    /// `dof_damping`), in ctrl order: a calibrated model's fitted damping.
    pub fn joint_damping(&self) -> Result<Vec<f64>> {
        let layout = self
            .layout
            .as_ref()
            .ok_or_else(|| Error::Internal("joint damping needs a floating model".into()))?;
        let all: Vec<f64> = self
            .model
            .getattr("dof_damping")
            .and_then(|d| d.call_method0("tolist"))
            .and_then(|d| d.extract())
            .internal()?;
        Ok(layout.act_dof.iter().map(|&d| all[d]).collect())
    }

    /// [`LoadedModel::joint_inertia`] on one of its bodies (a [`LoadedModel::variant`]).
    pub fn body_joint_inertia(&self, body: &Bound<'py, PyAny>, qpos: &[f64]) -> Result<Vec<f64>> {
        let layout = self
            .layout
            .as_ref()
            .ok_or_else(|| Error::Internal("joint inertia needs a floating model".into()))?;
        let nv = self.info.nv;
        let diag = (|| -> PyResult<Vec<f64>> {
            let m = &self.mj.module;
            let data = m.getattr("MjData")?.call1((body,))?;
            let q = data.getattr("qpos")?;
            for (i, v) in qpos.iter().enumerate() {
                q.set_item(i, *v)?;
            }
            m.getattr("mj_forward")?.call1((body, &data))?;
            let np = PyModule::import(self.mj.py, "numpy")?;
            let dense = np.getattr("zeros")?.call1(((nv, nv),))?;
            // mujoco 4: mj_fullM(m, d, dst) reads d's sparse inertia itself
            m.getattr("mj_fullM")?.call1((body, &data, &dense))?;
            np.getattr("diag")?
                .call1((dense,))?
                .call_method0("tolist")?
                .extract()
        })()
        .internal()?;
        Ok(layout.act_dof.iter().map(|&d| diag[d]).collect())
    }

    /// A model with scaled legs and torso, compiled from an edited spec.
    pub fn variant(&self, leg_scale: f64, torso_mass_scale: f64) -> Result<Bound<'py, PyAny>> {
        if leg_scale == 1.0 && torso_mass_scale == 1.0 {
            return Ok(self.model.clone());
        }
        let key = (leg_scale.to_bits(), torso_mass_scale.to_bits());
        if let Some((_, m)) = self.variants.borrow().iter().find(|(k, _)| *k == key) {
            return Ok(m.clone());
        }
        let spec = self.mj.spec_on(&self.source, self.suspended)?;
        let layout = self
            .layout
            .as_ref()
            .ok_or_else(|| Error::Internal("variants need a floating model".into()))?;
        let base_name = &self.info.bodies[layout.base.body];
        let torso = Torso {
            compiled: &self.model,
            id: layout.base.body,
            scale: torso_mass_scale,
        };
        scale_spec(&spec, base_name, leg_scale, &torso).internal()?;
        let model = self.mj.compile(&self.source, &spec)?;
        if let Some(i) = self.integrator {
            model
                .getattr("opt")
                .and_then(|o| o.setattr("integrator", i))
                .internal()?;
        }
        self.variants.borrow_mut().push((key, model.clone()));
        Ok(model)
    }
}

/// Scales the spec in memory: bodies two or more levels below the base (the
/// thigh and calf segments of each leg) get their offsets, geoms, sites and
/// inertial positions scaled by `leg`, their masses by `leg` and inertias by
/// `leg^3` (a uniform rod); the base body's mass and inertia by `torso`.
/// A base whose inertia the compiler derives from its geoms (no
/// `<inertial>`) gets the compiled inertial, scaled, as an explicit one: a
/// heavier torso must never be the same torso.
fn scale_spec(
    spec: &Bound<'_, PyAny>,
    base: &str,
    leg: f64,
    torso: &Torso<'_, '_>,
) -> PyResult<()> {
    let py = spec.py();
    let scale3 = |obj: &Bound<'_, PyAny>, attr: &str, s: f64| -> PyResult<()> {
        let v: Vec<f64> = obj.getattr(attr)?.call_method0("tolist")?.extract()?;
        let scaled: Vec<f64> = v.iter().map(|x| x * s).collect();
        obj.setattr(attr, PyList::new(py, scaled)?)
    };
    let base_body = spec.call_method1("body", (base,))?;
    if torso.scale != 1.0 {
        if !base_body.getattr("explicitinertial")?.extract::<bool>()? {
            let row = |field: &str| -> PyResult<Bound<'_, PyAny>> {
                torso
                    .compiled
                    .getattr(field)?
                    .get_item(torso.id)?
                    .call_method0("tolist")
            };
            base_body.setattr("mass", row("body_mass")?)?;
            base_body.setattr("inertia", row("body_inertia")?)?;
            base_body.setattr("ipos", row("body_ipos")?)?;
            base_body.setattr("iquat", row("body_iquat")?)?;
            base_body.setattr("explicitinertial", true)?;
        }
        let m: f64 = base_body.getattr("mass")?.extract()?;
        base_body.setattr("mass", m * torso.scale)?;
        scale3(&base_body, "inertia", torso.scale)?;
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

/// The base body of a compiled model, and the factor on its mass.
struct Torso<'a, 'py> {
    compiled: &'a Bound<'py, PyAny>,
    id: usize,
    scale: f64,
}

/// The direct child bodies of a spec body.
fn children<'py>(b: &Bound<'py, PyAny>) -> PyResult<Vec<Bound<'py, PyAny>>> {
    b.getattr("bodies")?.extract()
}
