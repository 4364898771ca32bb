//! Reading a compiled `MjModel` into plain data ([`ModelInfo`]): what
//! `pupper info` prints and what the runner's layout is built from.

use pyo3::prelude::*;

use super::python::{Mujoco, PyResultExt};
use pupper_core::error::Result;
use pupper_core::model::{
    ActuatorInfo, JointInfo, KeyframeInfo, ModelInfo, ModelSource, SensorInfo,
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
            qpos0: model
                .getattr("qpos0")
                .and_then(|q| q.call_method0("tolist"))
                .and_then(|q| q.extract())
                .internal()?,
        })
    }
}
