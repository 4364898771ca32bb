//! Which model to load, and a plain-data description of a compiled model
//! (what `pupper info` prints).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::error::{Error, Result};

/// The Pupper v3 robot alone (models/pupper_v3/, laid out as in MuJoCo
/// Menagerie: the robot file, and a scene that includes it).
pub const PUPPER_V3_ROBOT_XML: &str = include_str!("../../../../models/pupper_v3/pupper_v3.xml");
/// Pupper v3 on a floor, under a light and a sky.
pub const PUPPER_V3_SCENE_XML: &str = include_str!("../../../../models/pupper_v3/scene.xml");

/// A model compiled into pupper: a main MJCF text, the files it includes
/// (by the name it includes them under), and whether the base is welded to
/// the world (the free joint removed in memory, with MjSpec).
#[derive(Debug)]
pub struct Builtin {
    pub name: &'static str,
    pub main: &'static str,
    pub includes: &'static [(&'static str, &'static str)],
    pub fixed_base: bool,
}

pub const BUILTINS: [Builtin; 2] = [
    Builtin {
        name: "pupper_v3",
        main: PUPPER_V3_SCENE_XML,
        includes: &[("pupper_v3.xml", PUPPER_V3_ROBOT_XML)],
        fixed_base: false,
    },
    // hung in the air at the robot file's base height; for joint-level tests
    Builtin {
        name: "pupper_v3_fixed",
        main: PUPPER_V3_ROBOT_XML,
        includes: &[],
        fixed_base: true,
    },
];

pub const BUILTIN_NAMES: [&str; 2] = [BUILTINS[0].name, BUILTINS[1].name];

/// The torque limit of an actuator that has none (no clipping).
pub const UNLIMITED: f64 = f64::MAX;

/// A built-in model by name, or an MJCF file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ModelSource {
    Builtin(String),
    Path(PathBuf),
}

impl Default for ModelSource {
    fn default() -> Self {
        ModelSource::Builtin("pupper_v3".into())
    }
}

impl ModelSource {
    /// A built-in name, else a path. A path must exist and be readable.
    pub fn parse(text: &str) -> Result<ModelSource> {
        if BUILTIN_NAMES.contains(&text) {
            return Ok(ModelSource::Builtin(text.to_string()));
        }
        let path = PathBuf::from(text);
        if !path.exists() {
            let hint = if text.contains('/') || text.ends_with(".xml") {
                String::new()
            } else {
                format!(
                    " and is not a built-in model ({})",
                    BUILTIN_NAMES.join(", ")
                )
            };
            return Err(Error::ModelNotFound(format!(
                "model file '{text}' does not exist{hint}: check the path, or use --model pupper_v3"
            )));
        }
        if path.is_dir() {
            return Err(Error::Model(format!(
                "model path '{text}' is a directory: give the MJCF .xml file inside it"
            )));
        }
        std::fs::File::open(&path).map_err(|e| {
            Error::Model(format!(
                "model file '{text}' cannot be read ({e}): check its permissions"
            ))
        })?;
        // absolute, so a run can be resumed (and re-rendered) from anywhere
        Ok(ModelSource::Path(
            std::fs::canonicalize(&path).unwrap_or(path),
        ))
    }

    /// The built-in model, if this names one.
    pub fn builtin(&self) -> Option<&'static Builtin> {
        match self {
            ModelSource::Builtin(n) => BUILTINS.iter().find(|b| b.name == n),
            ModelSource::Path(_) => None,
        }
    }

    pub fn display(&self) -> String {
        match self {
            ModelSource::Builtin(n) => n.clone(),
            ModelSource::Path(p) => p.display().to_string(),
        }
    }
}

/// The SHA-256 of `bytes`, as 64 hex digits (what manifests record of the
/// compiled model).
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// One leg's geometry at the default pose, measured on the compiled model
/// (world frame, m): where its hip flexion and knee joints sit and where its
/// foot is, with the joints' world axes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LegInfo {
    /// The leg's first body.
    pub name: String,
    /// Indices into `joints`: abduction, hip flexion, knee.
    pub joints: [usize; 3],
    pub hip: [f64; 3],
    pub knee: [f64; 3],
    pub foot: [f64; 3],
    pub hip_axis: [f64; 3],
    pub knee_axis: [f64; 3],
    pub hip_to_foot: f64,
    /// First size of the foot geom (a sphere's radius).
    pub foot_radius: f64,
    /// Whether the foot geom is a sphere, whose centre and radius say where
    /// the foot touches the floor (a capsule's centre is mid-calf).
    #[serde(default = "yes")]
    pub foot_sphere: bool,
    /// Index of the foot geom.
    #[serde(default)]
    pub foot_geom: usize,
    /// Where the abduction joint sits, and its world axis (a walk's leg
    /// kinematics chain all three joints).
    #[serde(default)]
    pub abduction: [f64; 3],
    #[serde(default)]
    pub abduction_axis: [f64; 3],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointInfo {
    pub name: String,
    /// free, ball, slide or hinge.
    pub kind: String,
    pub qpos_adr: usize,
    pub dof_adr: usize,
    /// Range if limited.
    pub range: Option<[f64; 2]>,
    /// Index of the body the joint moves.
    pub body: usize,
}

#[cfg(test)]
impl ActuatorInfo {
    /// A test actuator on joint `joint` with these gain and bias
    /// parameters, clipped at 3 N·m.
    pub(crate) fn for_test(
        name: String,
        joint: Option<usize>,
        gainprm: [f64; 3],
        biasprm: [f64; 3],
    ) -> ActuatorInfo {
        ActuatorInfo {
            name,
            joint,
            gainprm,
            biasprm,
            forcerange: Some([-3.0, 3.0]),
            ctrlrange: None,
            gear: 1.0,
            delay: 0.0,
            gain_scale: [1.0, 1.0],
            winding: None,
            lag: 0.0,
            latency: 0.0,
        }
    }
}

#[cfg(test)]
impl ModelInfo {
    /// A test model of these joints (a free base first) and actuators.
    pub(crate) fn for_test(
        name: &str,
        joints: Vec<JointInfo>,
        actuators: Vec<ActuatorInfo>,
    ) -> ModelInfo {
        let hinges = joints.len() - 1;
        ModelInfo {
            name: name.into(),
            source: "test".into(),
            sha256: String::new(),
            nq: 7 + hinges,
            nv: 6 + hinges,
            nu: actuators.len(),
            nbody: 2 + hinges,
            timestep: 0.002,
            integrator: 0,
            total_mass: 1.0,
            gravity: EARTH,
            bodies: vec![],
            body_parent: vec![],
            joints,
            actuators,
            keyframes: vec![],
            sensors: vec![],
            qpos0: vec![0.0; 7 + hinges],
            legs: vec![],
            ground: true,
        }
    }
}

#[cfg(test)]
impl JointInfo {
    /// A free joint at qpos 0 moving body 1: the base of test models.
    pub(crate) fn free_base() -> JointInfo {
        JointInfo {
            name: "root".into(),
            kind: "free".into(),
            qpos_adr: 0,
            dof_adr: 0,
            range: None,
            body: 1,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActuatorInfo {
    pub name: String,
    /// Index into `joints` of the joint it drives, if it drives a joint.
    pub joint: Option<usize>,
    pub gainprm: [f64; 3],
    pub biasprm: [f64; 3],
    pub forcerange: Option<[f64; 2]>,
    /// Control range, if limited.
    #[serde(default)]
    pub ctrlrange: Option<[f64; 2]>,
    /// First gear entry (1 for Pupper).
    #[serde(default = "one")]
    pub gear: f64,
    /// MuJoCo's actuator delay (s): the control reaches the actuator this
    /// late (a calibrated model's command delay; `pupper fit`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub delay: f64,
    /// Factors on every Kp and Kd pupper commands to this actuator: what the
    /// servo really delivers of them (a calibrated model's custom numerics
    /// `pupper:kp_scale:NAME` and `pupper:kd_scale:NAME`; `pupper fit`).
    #[serde(default = "unit_scales", skip_serializing_if = "is_unit")]
    pub gain_scale: [f64; 2],
    /// The motor's torque constant (N·m/A) and winding resistance (Ω),
    /// where the model declares both (custom numerics `pupper:kt:NAME` and
    /// `pupper:resistance:NAME`): the copper loss `pupper hold` reports.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub winding: Option<[f64; 2]>,
    /// The servo's torque lag behind its PD (s, a current loop's first-order
    /// time constant) and the PD's feedback latency (s, how old the angle
    /// and velocity it reads are), as `pupper fit` measured them: custom
    /// numerics `pupper:lag:NAME` and `pupper:latency:NAME` of a calibrated
    /// model. Torque mode's firmware runs them, and the loop margins close
    /// the loop through them, unless `--motor lag=`/`--sensing-delay` stand
    /// instead.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub lag: f64,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub latency: f64,
}

fn one() -> f64 {
    1.0
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// MuJoCo's default gravity.
pub const EARTH: [f64; 3] = [0.0, 0.0, -9.81];

fn earth() -> [f64; 3] {
    EARTH
}

fn is_earth(v: &[f64; 3]) -> bool {
    *v == EARTH
}

/// The custom numerics that declare a motor's constants
/// (`pupper:kt:ACT`, N·m/A, and `pupper:resistance:ACT`, Ω): kind 0 the
/// torque constant, 1 the resistance; each one finite number above 0.
pub const MOTOR_CONSTANT: ActuatorNumeric = ActuatorNumeric {
    kinds: ["kt:", "resistance:"],
    what: "a motor constant",
    rule: "a number > 0",
    fits: |v| v > 0.0,
};

/// A family of custom numerics `pupper:KIND:ACTUATOR` holding one number
/// about an actuator: its two kinds, what it is and the rule its value
/// follows (in words and as a check of a finite value).
pub struct ActuatorNumeric {
    kinds: [&'static str; 2],
    what: &'static str,
    rule: &'static str,
    fits: fn(f64) -> bool,
}

impl ActuatorNumeric {
    /// `Some((kind index, actuator index, value))` for a numeric of this
    /// family, None for another; a bad one is a one-line model error.
    pub fn read(
        &self,
        numeric: &str,
        values: &[f64],
        actuators: &[ActuatorInfo],
        model: &str,
    ) -> Result<Option<(usize, usize, f64)>> {
        let Some(rest) = numeric.strip_prefix("pupper:") else {
            return Ok(None);
        };
        let Some((k, actuator)) =
            (0..2).find_map(|k| rest.strip_prefix(self.kinds[k]).map(|a| (k, a)))
        else {
            return Ok(None);
        };
        let bad = |why: String| {
            Err(Error::Model(format!(
                "{model}: custom numeric '{numeric}' {why}"
            )))
        };
        let Some(index) = actuators.iter().position(|a| a.name == actuator) else {
            let names: Vec<&str> = actuators.iter().map(|a| a.name.as_str()).collect();
            return bad(format!(
                "names no actuator of the model: use one of {}, or remove it",
                names.join(", ")
            ));
        };
        let what = self.what;
        match values {
            [v] if v.is_finite() && (self.fits)(*v) => Ok(Some((k, index, *v))),
            [v] => bad(format!("is {v}: {what} must be {}", self.rule)),
            _ => bad(format!(
                "has {} values: {what} is one number (size=\"1\")",
                values.len()
            )),
        }
    }
}

fn unit_scales() -> [f64; 2] {
    [1.0, 1.0]
}

fn is_unit(v: &[f64; 2]) -> bool {
    *v == [1.0, 1.0]
}

/// The custom numeric that holds a gain scale of an actuator, as `pupper
/// fit` writes it into a calibrated model (`kind`: kp_scale or kd_scale).
pub fn scale_numeric(kind: &str, actuator: &str) -> String {
    format!("pupper:{kind}:{actuator}")
}

/// The custom numerics that scale a gain (`pupper:kp_scale:ACT`,
/// `pupper:kd_scale:ACT`): kind 0 kp, 1 kd. A scale is one finite number
/// in (0, [`MAX_GAIN_SCALE`]]: zero or below would flip or remove the servo,
/// and the run would print `ok` for a robot that no servo holds.
pub const GAIN_SCALE: ActuatorNumeric = ActuatorNumeric {
    kinds: ["kp_scale:", "kd_scale:"],
    what: "a gain scale",
    rule: "a number in (0, 100]; refit the model or remove it",
    fits: |v| v > 0.0 && v <= MAX_GAIN_SCALE,
};

/// The fitted servo times of an actuator (`pupper:lag:ACT`,
/// `pupper:latency:ACT`): kind 0 the torque lag, 1 the feedback latency,
/// each in seconds within the bounds `pupper fit` fits them in.
pub const SERVO_TIMES: ActuatorNumeric = ActuatorNumeric {
    kinds: ["lag:", "latency:"],
    what: "a servo time (s)",
    rule: "a number of seconds in [0, 0.05]; refit the model or remove it",
    fits: |v| (0.0..=MAX_SERVO_TIME).contains(&v),
};

/// The longest torque lag or feedback latency a model may declare (s): the
/// upper bound `pupper fit` fits them within.
pub const MAX_SERVO_TIME: f64 = 0.05;

/// Why a torque lag `v` (s) past [`MAX_SERVO_TIME`] is refused, and the
/// value likely meant: milliseconds typed bare ("10" for 10 ms) are
/// `v / 1000` s, where that is a plausible lag. None for a plausible lag.
pub fn servo_time_typo(v: f64) -> Option<(String, Option<f64>)> {
    let why = format!(
        "{v} s is past the {MAX_SERVO_TIME} s a servo's torque lag can be (the bound `pupper fit` fits it within); it is in seconds"
    );
    // milliseconds only where that reads as a servo's time, to the nanosecond
    let meant =
        Some((v / 1000.0 * 1e9).round() / 1e9).filter(|&s| (0.001..=MAX_SERVO_TIME).contains(&s));
    (v > MAX_SERVO_TIME).then_some((why, meant))
}

/// The largest gain scale a model may declare: a fit that lands past it has
/// found no servo but a different robot.
pub const MAX_GAIN_SCALE: f64 = 100.0;

impl ActuatorInfo {
    /// Kp of an affine position servo (gain), Kd (−biasprm[2]).
    pub fn kp_kd(&self) -> (f64, f64) {
        (self.gainprm[0], -self.biasprm[2])
    }

    /// [Kp, Kd] when the actuator is a position servo (an affine bias that
    /// pulls towards the control: `biasprm[1] == -gainprm[0]`, Kp > 0);
    /// None for a motor, whose gains pupper must be given.
    pub fn own_gains(&self) -> Option<[f64; 2]> {
        let (kp, kd) = self.kp_kd();
        (kp > 0.0 && self.biasprm[1] == -kp && kd.is_finite() && kd >= 0.0).then_some([kp, kd])
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KeyframeInfo {
    pub name: String,
    pub qpos: Vec<f64>,
    pub ctrl: Vec<f64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensorInfo {
    pub name: String,
    pub kind: String,
    pub dim: usize,
}

/// What `pupper info` shows, read from a compiled model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelInfo {
    pub name: String,
    pub source: String,
    pub sha256: String,
    pub nq: usize,
    pub nv: usize,
    pub nu: usize,
    pub nbody: usize,
    pub timestep: f64,
    /// MuJoCo's `mjtIntegrator`: 0 Euler (explicit actuator forces), 1
    /// RK4, 2 implicit, 3 implicitfast.
    #[serde(default)]
    pub integrator: i64,
    pub total_mass: f64,
    /// MuJoCo's `opt.gravity` (m/s²); written only when it is not Earth's
    /// default, so the info of every model before it reads as it was.
    #[serde(default = "earth", skip_serializing_if = "is_earth")]
    pub gravity: [f64; 3],
    pub bodies: Vec<String>,
    /// Each body's parent (the world, 0, is its own).
    #[serde(default)]
    pub body_parent: Vec<usize>,
    pub joints: Vec<JointInfo>,
    pub actuators: Vec<ActuatorInfo>,
    pub keyframes: Vec<KeyframeInfo>,
    pub sensors: Vec<SensorInfo>,
    /// The default pose (MuJoCo's `qpos0`), where a model without keyframes starts.
    #[serde(default)]
    pub qpos0: Vec<f64>,
    /// Each leg (a chain of three or more hinges below the base ending in a
    /// colliding foot), measured at the default pose.
    #[serde(default)]
    pub legs: Vec<LegInfo>,
    /// Whether a geom fixed in the world can touch a foot (a floor): a
    /// model without one falls forever. Written only when false, so the
    /// info of every model with a floor reads as before.
    #[serde(default = "yes", skip_serializing_if = "is_yes")]
    pub ground: bool,
}

fn yes() -> bool {
    true
}

fn is_yes(v: &bool) -> bool {
    *v
}

/// Joint groups by what a leg joint does, in a leg's joint order:
/// abduction/adduction, hip flexion/extension, knee flexion/extension.
pub const JOINT_GROUPS: [&str; 3] = ["haa", "hfe", "kfe"];

impl ModelInfo {
    /// Whether the model carries a servo `pupper fit` measured: a torque
    /// lag or feedback latency (custom numerics), a command delay (MuJoCo's
    /// actuator delay) or gain scales on some actuator. Its loop margins
    /// are then of that servo and the model's joint damping.
    pub fn calibrated(&self) -> bool {
        self.actuators
            .iter()
            .any(|a| a.lag > 0.0 || a.latency > 0.0 || a.delay > 0.0 || a.gain_scale != [1.0, 1.0])
    }

    /// Whether some actuator has a fitted torque lag or feedback latency
    /// of half a physics step or more: a servo only torque mode's firmware
    /// runs (MuJoCo's servo has none). Less is none a step can show (a
    /// noise-free fit ends near, not at, zero).
    pub fn fitted_servo_times(&self) -> bool {
        let half = 0.5 * self.timestep;
        self.actuators
            .iter()
            .any(|a| a.lag >= half || a.latency >= half)
    }

    /// What a standing run should know of the ground: a note when the
    /// robot has legs but nothing in the world for its feet to touch.
    pub fn ground_note(&self) -> Option<String> {
        (!self.ground && !self.legs.is_empty()).then(|| {
            format!(
                "{} has no ground the feet can touch (no geom fixed in the world that collides with them): the robot falls from the start and every cell reads `fell`; add a floor, e.g. <geom type=\"plane\" size=\"0 0 0.05\"/> in the worldbody, or include the model in a scene that has one",
                self.source
            )
        })
    }

    /// The joint group of actuator `a`: what its joint does in its leg, as
    /// measured on the compiled model (see [`LegInfo::joints`]); None for
    /// a joint in no leg.
    pub fn actuator_group(&self, a: usize) -> Option<&'static str> {
        let joint = self.actuators.get(a)?.joint?;
        self.legs.iter().find_map(|leg| {
            leg.joints
                .iter()
                .position(|&j| j == joint)
                .map(|i| JOINT_GROUPS[i.min(2)])
        })
    }

    /// Each actuator's own torque limit, the default of `--max-torque`: its
    /// force range, else its control range (the force a unit-gain actuator
    /// makes at full control; times the gear at the joint). Pupper v3: 3 N·m.
    /// Refuses a pose (start and target angles) without one angle per actuator.
    pub fn check_pose(&self, pose: &[f64]) -> Result<()> {
        if pose.len() == self.nu {
            return Ok(());
        }
        Err(Error::Config(format!(
            "the pose has {} angles but model '{}' has {} actuated joints: give one angle per actuator, in actuator order",
            pose.len(),
            self.name,
            self.nu
        )))
    }

    /// An actuator with neither range is [`UNLIMITED`]: not clipped.
    pub fn torque_limits(&self) -> Result<Vec<f64>> {
        Ok(self
            .actuators
            .iter()
            .map(|a| {
                let bound = |r: [f64; 2]| r[0].abs().max(r[1].abs());
                a.forcerange
                    .map(bound)
                    .or(a.ctrlrange.map(bound))
                    .filter(|l| l.is_finite() && *l > 0.0)
                    .unwrap_or(UNLIMITED)
            })
            .collect())
    }

    /// A note naming the actuators [`ModelInfo::torque_limits`] leaves unclipped.
    pub fn unlimited_note(&self) -> Option<String> {
        let limits = self.torque_limits().ok()?;
        let names: Vec<&str> = self
            .actuators
            .iter()
            .zip(&limits)
            .filter(|(_, l)| **l == UNLIMITED)
            .map(|(a, _)| a.name.as_str())
            .collect();
        (!names.is_empty()).then(|| {
            format!(
                "actuators {} of model '{}' have no force or control range: their torques are not clipped (give --max-torque to clip them)",
                names.join(", "),
                self.name
            )
        })
    }

    /// The keyframe cells start from (None: the default pose), and a note
    /// when it is not the one asked for: a model without `home` starts from
    /// its first keyframe, or from its default pose when it has none, as
    /// the chapter's scripts do. Another missing name is an error.
    /// One line when joint targets (in actuator order) lie outside their
    /// joints' ranges: such a servo pushes its joint against the limit for
    /// the whole run.
    pub fn targets_outside_ranges(&self, targets: &[f64]) -> Option<String> {
        let outside: Vec<String> = self
            .actuators
            .iter()
            .zip(targets)
            .filter_map(|(a, &t)| {
                let j = &self.joints[a.joint?];
                let [lo, hi] = j.range?;
                (!(lo..=hi).contains(&t))
                    .then(|| format!("{} {t:.3} not in [{lo:.3}, {hi:.3}]", j.name))
            })
            .collect();
        let first = outside.first()?;
        let more = match outside.len() {
            1 => String::new(),
            n => format!(" and {} more", n - 1),
        };
        Some(format!(
            "{} joint target(s) lie outside their joint's range ({first}{more}): those servos press against the limit for the whole run; give a keyframe or --pose inside the ranges, or --pose auto",
            outside.len()
        ))
    }

    pub fn start_keyframe(&self, name: &str) -> Result<(Option<usize>, Option<String>)> {
        match self.keyframe(name) {
            Ok((k, _)) => Ok((Some(k), None)),
            Err(_) if name == "home" && !self.keyframes.is_empty() => Ok((
                Some(0),
                Some(format!(
                    "model '{}' has no keyframe 'home': starting from its first keyframe '{}'",
                    self.name, self.keyframes[0].name
                )),
            )),
            Err(_) if name == "home" => Ok((
                None,
                Some(format!(
                    "model '{}' has no keyframe: starting from its default pose (qpos0), which is also the joint target: the pose the model is written in (often straight legs), not a stand pose; add a keyframe, or give --pose (auto searches a stand pose)",
                    self.name
                )),
            )),
            Err(e) => Err(e),
        }
    }

    pub fn keyframe(&self, name: &str) -> Result<(usize, &KeyframeInfo)> {
        self.keyframes
            .iter()
            .enumerate()
            .find(|(_, k)| k.name == name)
            .ok_or_else(|| {
                let names: Vec<&str> = self.keyframes.iter().map(|k| k.name.as_str()).collect();
                let have = if names.is_empty() {
                    "it has none: add a <keyframe> or use --pose".to_string()
                } else {
                    format!("it has {}", names.join(", "))
                };
                Error::Config(format!(
                    "model '{}' has no keyframe '{name}': {have}",
                    self.name
                ))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gain_scale_rule_names_the_largest_scale() {
        // one home for the bound: the words an error shows say the constant
        assert!(GAIN_SCALE.rule.contains(&format!("(0, {MAX_GAIN_SCALE}]")));
    }

    fn actuator(name: &str) -> ActuatorInfo {
        ActuatorInfo::for_test(name.into(), Some(0), [5.0, 0.0, 0.0], [0.0, -5.0, -0.1])
    }

    fn check(numeric: &str, values: &[f64]) -> Result<Option<(usize, usize, f64)>> {
        GAIN_SCALE.read(numeric, values, &[actuator("a"), actuator("knee")], "m.xml")
    }

    #[test]
    fn a_fitted_servo_time_counts_from_half_a_physics_step() {
        let with = |lag: f64, latency: f64| {
            let mut a = actuator("knee");
            (a.lag, a.latency) = (lag, latency);
            ModelInfo::for_test("m", vec![JointInfo::free_base()], vec![actuator("a"), a])
        };
        // the test model steps at 2 ms: from 1 ms on, a step can show it
        assert!(!with(0.0, 0.0).fitted_servo_times());
        assert!(!with(1.05e-4, 0.0).fitted_servo_times());
        assert!(!with(0.0, 0.000_999).fitted_servo_times());
        assert!(with(0.001, 0.0).fitted_servo_times());
        assert!(with(0.0, 0.004).fitted_servo_times());
        // still calibrated: the model carries what the fit found
        assert!(with(1.05e-4, 0.0).calibrated());
    }

    #[test]
    fn a_gain_scale_names_its_gain_and_actuator() {
        assert_eq!(
            check("pupper:kp_scale:knee", &[0.9]).unwrap(),
            Some((0, 1, 0.9))
        );
        assert_eq!(
            check("pupper:kd_scale:a", &[1.2]).unwrap(),
            Some((1, 0, 1.2))
        );
        // not a gain scale: left to whoever reads it
        assert_eq!(check("other", &[1.0, 2.0]).unwrap(), None);
        assert_eq!(check("pupper:kp_max:a", &[30.0]).unwrap(), None);
    }

    #[test]
    fn a_bad_gain_scale_is_refused_with_its_name() {
        let e = |n: &str, v: &[f64]| check(n, v).unwrap_err().to_string();
        for v in [-1.0, 0.0, f64::NAN, f64::INFINITY, 1e3] {
            let msg = e("pupper:kp_scale:a", &[v]);
            assert!(
                msg.contains("'pupper:kp_scale:a'") && msg.contains("(0, 100]"),
                "{msg}"
            );
        }
        assert!(e("pupper:kd_scale:a", &[-5.0]).contains("must be a number in (0, 100]"));
        let msg = e("pupper:kp_scale:elbow", &[1.0]);
        assert!(
            msg.contains("names no actuator") && msg.contains("a, knee"),
            "{msg}"
        );
        assert!(e("pupper:kp_scale:a", &[1.0, 1.0]).contains("has 2 values"));
    }
}
