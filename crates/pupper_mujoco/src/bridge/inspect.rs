//! Reading a compiled `MjModel` into plain data ([`ModelInfo`]): what
//! `pupper info` prints and what the runner's layout is built from.

use pyo3::prelude::*;

use super::python::{Mujoco, PyResultExt};
use pupper_core::error::{Error, Result};
use pupper_core::robot::model::{
    ActuatorInfo, JointInfo, KeyframeInfo, LegInfo, ModelInfo, ModelSource, SensorInfo, gain_scale,
    motor_constant,
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
        let (trntype, trnid, flim, clim) = (
            ints("actuator_trntype")?,
            floats2("actuator_trnid")?,
            ints("actuator_forcelimited")?,
            ints("actuator_ctrllimited")?,
        );
        let (crange, gear) = (floats2("actuator_ctrlrange")?, floats2("actuator_gear")?);
        let (gain, bias, frange) = (
            floats2("actuator_gainprm")?,
            floats2("actuator_biasprm")?,
            floats2("actuator_forcerange")?,
        );
        let delays: Vec<f64> = list("actuator_delay")
            .and_then(|l| l.extract().internal())
            .unwrap_or_default();
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
                ctrlrange: (clim[i] != 0).then(|| [crange[i][0], crange[i][1]]),
                gear: gear[i][0],
                delay: delays.get(i).copied().unwrap_or(0.0),
                gain_scale: [1.0, 1.0],
                winding: None,
            });
        }
        // a calibrated model's gain scales (`pupper fit`)
        let nnumeric = int("nnumeric")?;
        if nnumeric > 0 {
            let (adr, size): (Vec<i64>, Vec<i64>) = (ints("numeric_adr")?, ints("numeric_size")?);
            let data: Vec<f64> = list("numeric_data")?.extract().internal()?;
            // a motor's torque constant and resistance (for copper loss)
            let mut motor: Vec<[Option<f64>; 2]> = vec![[None; 2]; actuators.len()];
            for n in 0..nnumeric {
                let name = self.name_of(model, "mjOBJ_NUMERIC", n)?;
                let values = &data[adr[n] as usize..(adr[n] + size[n]) as usize];
                if let Some((k, actuator, scale)) =
                    gain_scale(&name, values, &actuators, &source.display())?
                {
                    actuators[actuator].gain_scale[k] = scale;
                }
                if let Some((k, actuator, v)) =
                    motor_constant(&name, values, &actuators, &source.display())?
                {
                    motor[actuator][k] = Some(v);
                }
            }
            for (a, m) in actuators.iter_mut().zip(motor) {
                a.winding = match m {
                    [Some(kt), Some(r)] => Some([kt, r]),
                    [None, None] => None,
                    _ => {
                        return Err(Error::Model(format!(
                            "{}: actuator {} declares {} but not {}: copper loss needs both pupper:kt:{} (N·m/A) and pupper:resistance:{} (Ω)",
                            source.display(),
                            a.name,
                            if m[0].is_some() {
                                "a torque constant"
                            } else {
                                "a resistance"
                            },
                            if m[0].is_some() {
                                "its resistance"
                            } else {
                                "its torque constant"
                            },
                            a.name,
                            a.name
                        )));
                    }
                };
            }
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
        let legs = self.legs(model, &bodies, &jtype).internal()?;
        let ground = self.ground(model, &legs).internal()?;
        Ok(ModelInfo {
            name,
            source: source.display(),
            sha256: self.fingerprint(model).internal()?,
            nq,
            nv,
            nu,
            nbody,
            timestep,
            integrator: model
                .getattr("opt")
                .and_then(|o| o.getattr("integrator"))
                .and_then(|i| i.extract())
                .internal()?,
            total_mass: masses.iter().sum(),
            gravity: model
                .getattr("opt")
                .and_then(|o| o.getattr("gravity"))
                .and_then(|g| g.call_method0("tolist"))
                .and_then(|g| g.extract())
                .internal()?,
            bodies,
            body_parent: ints("body_parentid")?
                .into_iter()
                .map(|p| p as usize)
                .collect(),
            joints,
            actuators,
            keyframes,
            sensors,
            qpos0: model
                .getattr("qpos0")
                .and_then(|q| q.call_method0("tolist"))
                .and_then(|q| q.extract())
                .internal()?,
            legs,
            ground,
        })
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
        let nbody = parent.len();
        let children =
            |b: usize| -> Vec<usize> { (1..nbody).filter(|&c| parent[c] == b).collect() };
        let mut legs = Vec::new();
        for first in children(1) {
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
            if hinges.len() < 3 {
                continue;
            }
            // By their axes, not their order: abduction turns about the
            // body's forward (x) axis, hip flexion and knee about its side (y).
            let Some(haa) = hinges
                .iter()
                .copied()
                .max_by(|&a, &c| axis[a][0].abs().total_cmp(&axis[c][0].abs()))
            else {
                continue;
            };
            let pitch: Vec<usize> = hinges
                .iter()
                .copied()
                .filter(|&j| j != haa && axis[j][1].abs() > 0.9)
                .collect();
            let [hfe, kfe, ..] = pitch[..] else { continue };
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
                foot_geom,
            });
        }
        Ok(legs)
    }
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
