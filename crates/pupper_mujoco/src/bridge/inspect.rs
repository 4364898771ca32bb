//! Reading a compiled `MjModel` into plain data ([`ModelInfo`]): what
//! `pupper info` prints and what the runner's layout is built from.

use pyo3::prelude::*;

use super::python::{Mujoco, PyResultExt};
use pupper_core::error::{Error, Result};
use pupper_core::robot::model::{
    ActuatorInfo, GAIN_SCALE, JointInfo, KeyframeInfo, LegInfo, MOTOR_CONSTANT, ModelInfo,
    ModelSource, SERVO_TIMES, SensorInfo,
};

impl<'py> Mujoco<'py> {
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

    pub(crate) fn info(
        &self,
        source: &ModelSource,
        model: &Bound<'py, PyAny>,
    ) -> Result<ModelInfo> {
        let f = Fields(model);
        let (nq, nv, nu, nbody) = (f.int("nq")?, f.int("nv")?, f.int("nu")?, f.int("nbody")?);
        let opt = |n: &str| model.getattr("opt").and_then(|o| o.getattr(n));
        let masses: Vec<f64> = f.list("body_mass")?.extract().internal()?;
        let bodies = (0..nbody)
            .map(|i| self.name_of(model, "mjOBJ_BODY", i))
            .collect::<Result<Vec<_>>>()?;
        let mut actuators = self.actuators(model, &f, nu)?;
        self.numerics(model, &f, source, &mut actuators)?;
        let name = match self.name_of(model, "mjOBJ_MODEL", 0) {
            Ok(n) if !n.is_empty() => n,
            _ => source.display(),
        };
        let legs = self.legs(model, &bodies, &f.ints("jnt_type")?).internal()?;
        let ground = self.ground(model, &legs).internal()?;
        Ok(ModelInfo {
            name,
            source: source.display(),
            sha256: self.fingerprint(model).internal()?,
            nq,
            nv,
            nu,
            nbody,
            timestep: opt("timestep").and_then(|t| t.extract()).internal()?,
            integrator: opt("integrator").and_then(|i| i.extract()).internal()?,
            total_mass: masses.iter().sum(),
            gravity: opt("gravity")
                .and_then(|g| g.call_method0("tolist"))
                .and_then(|g| g.extract())
                .internal()?,
            bodies,
            body_parent: f
                .ints("body_parentid")?
                .into_iter()
                .map(|p| p as usize)
                .collect(),
            joints: self.joints(model, &f)?,
            actuators,
            keyframes: self.keyframes(model, &f)?,
            sensors: self.sensors(model, &f)?,
            qpos0: f.list("qpos0")?.extract().internal()?,
            legs,
            ground,
        })
    }

    fn joints(&self, model: &Bound<'py, PyAny>, f: &Fields<'_, 'py>) -> Result<Vec<JointInfo>> {
        let (jtype, jq, jd, jlim, jbody) = (
            f.ints("jnt_type")?,
            f.ints("jnt_qposadr")?,
            f.ints("jnt_dofadr")?,
            f.ints("jnt_limited")?,
            f.ints("jnt_bodyid")?,
        );
        let jrange = f.floats2("jnt_range")?;
        (0..f.int("njnt")?)
            .map(|i| {
                Ok(JointInfo {
                    name: self.name_of(model, "mjOBJ_JOINT", i)?,
                    kind: ["free", "ball", "slide", "hinge"]
                        .get(jtype[i] as usize)
                        .unwrap_or(&"unknown")
                        .to_string(),
                    qpos_adr: jq[i] as usize,
                    dof_adr: jd[i] as usize,
                    range: (jlim[i] != 0).then(|| [jrange[i][0], jrange[i][1]]),
                    body: jbody[i] as usize,
                })
            })
            .collect()
    }

    fn actuators(
        &self,
        model: &Bound<'py, PyAny>,
        f: &Fields<'_, 'py>,
        nu: usize,
    ) -> Result<Vec<ActuatorInfo>> {
        let (trntype, trnid, flim, clim) = (
            f.ints("actuator_trntype")?,
            f.floats2("actuator_trnid")?,
            f.ints("actuator_forcelimited")?,
            f.ints("actuator_ctrllimited")?,
        );
        let (crange, gear) = (
            f.floats2("actuator_ctrlrange")?,
            f.floats2("actuator_gear")?,
        );
        let (gain, bias, frange) = (
            f.floats2("actuator_gainprm")?,
            f.floats2("actuator_biasprm")?,
            f.floats2("actuator_forcerange")?,
        );
        let delays: Vec<f64> = f
            .list("actuator_delay")
            .and_then(|l| l.extract().internal())
            .unwrap_or_default();
        (0..nu)
            .map(|i| {
                Ok(ActuatorInfo {
                    name: self.name_of(model, "mjOBJ_ACTUATOR", i)?,
                    // trntype 0 is mjTRN_JOINT
                    joint: (trntype[i] == 0).then_some(trnid[i][0] as usize),
                    gainprm: [gain[i][0], gain[i][1], gain[i][2]],
                    biasprm: [bias[i][0], bias[i][1], bias[i][2]],
                    forcerange: (flim[i] != 0).then(|| [frange[i][0], frange[i][1]]),
                    ctrlrange: (clim[i] != 0).then(|| [crange[i][0], crange[i][1]]),
                    gear: gear[i][0],
                    delay: delays.get(i).copied().unwrap_or(0.0),
                    gain_scale: [1.0, 1.0],
                    winding: None,
                    lag: 0.0,
                    latency: 0.0,
                })
            })
            .collect()
    }

    /// What the model's custom numerics declare of its actuators: a
    /// calibrated model's gain scales (`pupper fit`), a motor's torque
    /// constant and resistance (for copper loss).
    fn numerics(
        &self,
        model: &Bound<'py, PyAny>,
        f: &Fields<'_, 'py>,
        source: &ModelSource,
        actuators: &mut [ActuatorInfo],
    ) -> Result<()> {
        let nnumeric = f.int("nnumeric")?;
        if nnumeric == 0 {
            return Ok(());
        }
        let (adr, size) = (f.ints("numeric_adr")?, f.ints("numeric_size")?);
        let data: Vec<f64> = f.list("numeric_data")?.extract().internal()?;
        let mut motor: Vec<[Option<f64>; 2]> = vec![[None; 2]; actuators.len()];
        for n in 0..nnumeric {
            let name = self.name_of(model, "mjOBJ_NUMERIC", n)?;
            let values = &data[adr[n] as usize..(adr[n] + size[n]) as usize];
            if let Some((k, actuator, scale)) =
                GAIN_SCALE.read(&name, values, actuators, &source.display())?
            {
                actuators[actuator].gain_scale[k] = scale;
            }
            if let Some((k, actuator, v)) =
                SERVO_TIMES.read(&name, values, actuators, &source.display())?
            {
                let a = &mut actuators[actuator];
                *(if k == 0 { &mut a.lag } else { &mut a.latency }) = v;
            }
            if let Some((k, actuator, v)) =
                MOTOR_CONSTANT.read(&name, values, actuators, &source.display())?
            {
                motor[actuator][k] = Some(v);
            }
        }
        for (a, m) in actuators.iter_mut().zip(motor) {
            a.winding = match m {
                [Some(kt), Some(r)] => Some([kt, r]),
                [None, None] => None,
                [kt, _] => {
                    let (has, lacks) = match kt {
                        Some(_) => ("a torque constant", "its resistance"),
                        None => ("a resistance", "its torque constant"),
                    };
                    return Err(Error::Model(format!(
                        "{}: actuator {} declares {has} but not {lacks}: copper loss needs both pupper:kt:{} (N·m/A) and pupper:resistance:{} (Ω)",
                        source.display(),
                        a.name,
                        a.name,
                        a.name
                    )));
                }
            };
        }
        Ok(())
    }

    fn keyframes(
        &self,
        model: &Bound<'py, PyAny>,
        f: &Fields<'_, 'py>,
    ) -> Result<Vec<KeyframeInfo>> {
        let (kq, kc) = (f.floats2("key_qpos")?, f.floats2("key_ctrl")?);
        (0..f.int("nkey")?)
            .map(|i| {
                Ok(KeyframeInfo {
                    name: self.name_of(model, "mjOBJ_KEY", i)?,
                    qpos: kq[i].clone(),
                    ctrl: kc.get(i).cloned().unwrap_or_default(),
                })
            })
            .collect()
    }

    fn sensors(&self, model: &Bound<'py, PyAny>, f: &Fields<'_, 'py>) -> Result<Vec<SensorInfo>> {
        let (stype, sdim) = (f.ints("sensor_type")?, f.ints("sensor_dim")?);
        let sensor_enum = self.module.getattr("mjtSensor").internal()?;
        (0..f.int("nsensor")?)
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
            .collect()
    }

    /// Whether a geom of a body welded to the world (no joint between them)
    /// can collide with some foot of `legs` (MuJoCo's contype/conaffinity
    /// rule). True for a model without legs: there is no foot to ask for.
    fn ground(&self, model: &Bound<'py, PyAny>, legs: &[LegInfo]) -> PyResult<bool> {
        if legs.is_empty() {
            return Ok(true);
        }
        let get =
            |n: &str| -> PyResult<Bound<'py, PyAny>> { model.getattr(n)?.call_method0("tolist") };
        let parent: Vec<usize> = get("body_parentid")?.extract()?;
        let jnum: Vec<i64> = get("body_jntnum")?.extract()?;
        let (gbody, ctype, caff) = geom_contacts(model)?;
        let welded = |mut b: usize| {
            while b != 0 {
                if jnum[b] != 0 {
                    return false;
                }
                b = parent[b];
            }
            true
        };
        Ok((0..gbody.len()).any(|g| {
            welded(gbody[g])
                && legs.iter().any(|l| {
                    let f = l.foot_geom;
                    ctype[g] & caff[f] != 0 || caff[g] & ctype[f] != 0
                })
        }))
    }

    /// SHA-256 of the compiled model as MuJoCo saves it (MJB): the robot
    /// that runs, whatever files it was read from. An edit to a file the
    /// MJCF includes changes it; a comment or a moved directory does not.
    fn fingerprint(&self, model: &Bound<'py, PyAny>) -> PyResult<String> {
        let py = self.py;
        let size: usize = self
            .module
            .getattr("mj_sizeModel")?
            .call1((model,))?
            .extract()?;
        let kw = pyo3::types::PyDict::new(py);
        kw.set_item("dtype", "uint8")?;
        let buf = py
            .import("numpy")?
            .getattr("zeros")?
            .call((size,), Some(&kw))?;
        self.module
            .getattr("mj_saveModel")?
            .call1((model, py.None(), &buf))?;
        let bytes = buf.call_method0("tobytes")?;
        let bytes = bytes.cast::<pyo3::types::PyBytes>()?.as_bytes();
        Ok(pupper_core::robot::model::sha256_hex(bytes))
    }

    /// The legs of a model at its default pose: below the base (body 1),
    /// each child chain with three or more hinges and a colliding geom in
    /// its last body. Positions come from `mj_kinematics`, so they are those
    /// of the compiled (possibly scaled) body.
    fn legs(
        &self,
        model: &Bound<'py, PyAny>,
        bodies: &[String],
        jtype: &[i64],
    ) -> PyResult<Vec<LegInfo>> {
        let get =
            |n: &str| -> PyResult<Bound<'py, PyAny>> { model.getattr(n)?.call_method0("tolist") };
        let parent: Vec<usize> = get("body_parentid")?.extract()?;
        let jbody: Vec<usize> = get("jnt_bodyid")?.extract()?;
        let (gbody, ctype, caff) = geom_contacts(model)?;
        let data = self.module.getattr("MjData")?.call1((model,))?;
        self.module
            .getattr("mj_kinematics")?
            .call1((model, &data))?;
        let rows = |n: &str| -> PyResult<Vec<[f64; 3]>> {
            data.getattr(n)?.call_method0("tolist")?.extract()
        };
        let (anchor, axis, gpos) = (rows("xanchor")?, rows("xaxis")?, rows("geom_xpos")?);
        let gsize: Vec<[f64; 3]> = get("geom_size")?.extract()?;
        let gtype: Vec<i64> = get("geom_type")?.extract()?;
        let nbody = parent.len();
        let children =
            |b: usize| -> Vec<usize> { (1..nbody).filter(|&c| parent[c] == b).collect() };
        let mut legs = Vec::new();
        for first in children(1) {
            let (hinges, b) = chain_hinges(first, &children, &jbody, jtype);
            let Some([haa, hfe, kfe]) = leg_joints(&hinges, &axis) else {
                continue;
            };
            // the foot: the last body's colliding geom furthest from the knee
            // (a calf may collide along its length too)
            let from_knee = |g: usize| -> f64 {
                (0..3)
                    .map(|i| (gpos[g][i] - anchor[kfe][i]).powi(2))
                    .sum::<f64>()
            };
            let Some(foot_geom) = (0..gbody.len())
                .filter(|&g| gbody[g] == b && (ctype[g] != 0 || caff[g] != 0))
                .max_by(|&a, &c| from_knee(a).total_cmp(&from_knee(c)))
            else {
                continue;
            };
            let (hip, knee, foot) = (anchor[hfe], anchor[kfe], gpos[foot_geom]);
            let d: f64 = (0..3)
                .map(|i| (foot[i] - hip[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            legs.push(LegInfo {
                name: bodies[first].clone(),
                joints: [haa, hfe, kfe],
                hip,
                knee,
                foot,
                hip_axis: axis[hfe],
                knee_axis: axis[kfe],
                hip_to_foot: d,
                foot_radius: gsize[foot_geom][0],
                // mjGEOM_SPHERE
                foot_sphere: gtype[foot_geom] == 2,
                foot_geom,
                abduction: anchor[haa],
                abduction_axis: axis[haa],
            });
        }
        Ok(legs)
    }
}

/// The hinges down the chain of bodies from `first` while each body has
/// one child (`children`), and the chain's last body.
fn chain_hinges(
    first: usize,
    children: &dyn Fn(usize) -> Vec<usize>,
    jbody: &[usize],
    jtype: &[i64],
) -> (Vec<usize>, usize) {
    let mut hinges: Vec<usize> = Vec::new();
    let mut b = first;
    loop {
        // mjJNT_HINGE is 3
        hinges.extend((0..jbody.len()).filter(|&j| jbody[j] == b && jtype[j] == 3));
        match children(b)[..] {
            [only] => b = only,
            _ => break,
        }
    }
    (hinges, b)
}

/// A leg's abduction, hip and knee among its `hinges`, by their axes, not
/// their order: abduction turns about the body's forward (x) axis, hip
/// flexion and knee about its side (y). None: not a leg.
fn leg_joints(hinges: &[usize], axis: &[[f64; 3]]) -> Option<[usize; 3]> {
    if hinges.len() < 3 {
        return None;
    }
    let haa = hinges
        .iter()
        .copied()
        .max_by(|&a, &c| axis[a][0].abs().total_cmp(&axis[c][0].abs()))?;
    let pitch: Vec<usize> = hinges
        .iter()
        .copied()
        .filter(|&j| j != haa && axis[j][1].abs() > 0.9)
        .collect();
    let [hfe, kfe, ..] = pitch[..] else {
        return None;
    };
    Some([haa, hfe, kfe])
}

/// Each geom's body, contype and conaffinity (MuJoCo's contact filter).
type GeomContacts = (Vec<usize>, Vec<i64>, Vec<i64>);

fn geom_contacts(model: &Bound<'_, PyAny>) -> PyResult<GeomContacts> {
    let get = |n: &str| model.getattr(n)?.call_method0("tolist");
    Ok((
        get("geom_bodyid")?.extract()?,
        get("geom_contype")?.extract()?,
        get("geom_conaffinity")?.extract()?,
    ))
}

/// A compiled model's fields, read by name (counts, and arrays as lists).
struct Fields<'a, 'py>(&'a Bound<'py, PyAny>);

impl<'py> Fields<'_, 'py> {
    fn int(&self, n: &str) -> Result<usize> {
        self.0.getattr(n).and_then(|v| v.extract()).internal()
    }
    fn list(&self, n: &str) -> Result<Bound<'py, PyAny>> {
        self.0
            .getattr(n)
            .and_then(|v| v.call_method0("tolist"))
            .internal()
    }
    fn ints(&self, n: &str) -> Result<Vec<i64>> {
        self.list(n)?.extract().internal()
    }
    fn floats2(&self, n: &str) -> Result<Vec<Vec<f64>>> {
        self.list(n)?.extract().internal()
    }
}
