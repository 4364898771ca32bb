//! The parameters a grid can vary: their names, how a value of each is
//! written into a cell's id, and the values each accepts.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::robot::variant::VARIANTS;

/// The axes, a row each: the variant, its name (as `--grid` and
/// summary.csv write it), its tag in cell ids, the kind whose own axis it
/// is (None: every kind's), and what its values must be (None: any).
macro_rules! axes {
    ($($(#[$doc:meta])* $v:ident = $name:literal, $tag:literal, $kind:expr, $rule:expr;)*) => {
        /// A named experiment parameter that a grid can vary.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
        #[serde(rename_all = "snake_case")]
        pub enum Axis {
            $($(#[$doc])* $v,)*
        }

        impl Axis {
            pub const ALL: &'static [Axis] = &[$(Axis::$v),*];

            pub fn name(self) -> &'static str {
                match self {
                    $(Axis::$v => $name,)*
                }
            }

            /// Short form used in cell ids.
            pub(crate) fn tag(self) -> &'static str {
                match self {
                    $(Axis::$v => $tag,)*
                }
            }

            /// The experiment kind whose own axis this is (a manifest's kind
            /// name); None for an axis every kind takes.
            pub fn kind(self) -> Option<&'static str> {
                match self {
                    $(Axis::$v => $kind,)*
                }
            }

            /// What is wrong with value `v` of this axis, if anything.
            fn rule(self, v: f64) -> Option<&'static str> {
                let rule: fn(f64) -> Option<&'static str> = match self {
                    $(Axis::$v => $rule,)*
                };
                rule(v)
            }
        }
    };
}

const GAIN: fn(f64) -> Option<&'static str> = |v| (v < 0.0).then_some("gains must be >= 0");
const ANY: fn(f64) -> Option<&'static str> = |_| None;

axes! {
    /// Proportional gain (N·m/rad).
    Kp = "kp", "kp", None, GAIN;
    /// Derivative gain (N·m·s/rad).
    Kd = "kd", "kd", None, GAIN;
    /// Vertical push force on the base (N, world z; negative pushes down).
    PushForce = "push_force", "push", None, ANY;
    /// Torque limit of every actuator (N·m).
    MaxTorque = "max_torque", "tmax", None, |v| (v <= 0.0).then_some("max_torque must be > 0");
    /// Sliding friction of the feet and the floor.
    Friction = "friction", "mu", None, |v| (v <= 0.0).then_some("friction must be > 0");
    /// Physics timestep (s).
    Timestep = "timestep", "dt", None,
        |v| (!(1e-6..=0.05).contains(&v)).then_some("timestep must be in [1e-6, 0.05] s");
    /// Scale of thigh and calf lengths and masses.
    LegScale = "leg_scale", "leg", None,
        |v| (!(0.25..=4.0).contains(&v)).then_some("leg_scale must be in [0.25, 4]");
    /// Scale of the torso mass and inertia.
    TorsoMassScale = "torso_mass_scale", "torso", None,
        |v| (!(0.05..=20.0).contains(&v)).then_some("torso_mass_scale must be in [0.05, 20]");
    /// A named body (original, long-leg, heavy); values are indices into
    /// [`crate::robot::variant::VARIANTS`], shown by name.
    Variant = "variant", "", None, ANY;
    /// Kp and Kd of one joint group (abduction, hip pitch, knee), over the
    /// common `kp`/`kd` for the joints of that group.
    KpHaa = "kp.haa", "kphaa", None, GAIN;
    KpHfe = "kp.hfe", "kphfe", None, GAIN;
    KpKfe = "kp.kfe", "kpkfe", None, GAIN;
    KdHaa = "kd.haa", "kdhaa", None, GAIN;
    KdHfe = "kd.hfe", "kdhfe", None, GAIN;
    KdKfe = "kd.kfe", "kdkfe", None, GAIN;
    /// A walk's gait: cycles per second (Hz), commanded forward speed (m/s), duty factor, step height (m).
    Frequency = "frequency", "f", Some("walk"), |v| (!(v > 0.0 && v <= 20.0)).then_some("frequency must be in (0, 20] Hz");
    Speed = "speed", "v", Some("walk"), |v| (v.abs() > 5.0).then_some("speed must be in [-5, 5] m/s");
    Duty = "duty", "duty", Some("walk"), |v| (!(0.05..=0.95).contains(&v)).then_some("duty must be in [0.05, 0.95]");
    StepHeight = "step_height", "step", Some("walk"), |v| (!(0.0..=1.0).contains(&v)).then_some("step_height must be in [0, 1] m");
}

impl Axis {
    /// The axis of Kp (`kd`: Kd) for joint group `group`, if it has one.
    pub fn group_gain(kd: bool, group: &str) -> Option<Axis> {
        Some(match (kd, group) {
            (false, "haa") => Axis::KpHaa,
            (false, "hfe") => Axis::KpHfe,
            (false, "kfe") => Axis::KpKfe,
            (true, "haa") => Axis::KdHaa,
            (true, "hfe") => Axis::KdHfe,
            (true, "kfe") => Axis::KdKfe,
            _ => return None,
        })
    }

    /// True for an axis of gains (common or per group).
    pub fn is_gain(self) -> bool {
        matches!(
            self,
            Axis::Kp
                | Axis::Kd
                | Axis::KpHaa
                | Axis::KpHfe
                | Axis::KpKfe
                | Axis::KdHaa
                | Axis::KdHfe
                | Axis::KdKfe
        )
    }

    /// A value as summary.csv and cell ids show it: a variant by its name,
    /// a number as its shortest round-trip text.
    pub fn text(self, v: f64) -> String {
        match self {
            Axis::Variant => VARIANTS
                .get(v as usize)
                .map_or_else(|| format!("{v}"), |b| b.name.to_string()),
            _ => crate::math::decimal::fmt_f64(v),
        }
    }

    pub fn parse(name: &str) -> Result<Axis> {
        let key = name.trim().to_ascii_lowercase().replace('-', "_");
        if let Some(axis) = Axis::ALL.iter().find(|a| a.name() == key) {
            return Ok(*axis);
        }
        let names: Vec<&str> = Axis::ALL.iter().map(|a| a.name()).collect();
        // the axes every kind takes, then each kind's own under its name
        // (this parse does not know which kind asks)
        let listed: Vec<&str> = Axis::ALL
            .iter()
            .filter(|a| a.kind().is_none())
            .map(|a| a.name())
            .collect();
        let mut own: Vec<(&str, Vec<&str>)> = Vec::new();
        for a in Axis::ALL.iter() {
            if let Some(k) = a.kind() {
                match own.iter_mut().find(|(kind, _)| *kind == k) {
                    Some((_, names)) => names.push(a.name()),
                    None => own.push((k, vec![a.name()])),
                }
            }
        }
        let own: String = own
            .iter()
            .map(|(k, names)| format!("; {k} also takes {}", names.join(", ")))
            .collect();
        let dist: Vec<(usize, &str)> = names
            .iter()
            .map(|n| (strsim::damerau_levenshtein(&key, n), *n))
            .filter(|(d, n)| *d <= 2.max(n.len() / 3))
            .collect();
        let best = dist.iter().map(|(d, _)| *d).min();
        let close: Vec<String> = dist
            .iter()
            .filter(|(d, _)| Some(*d) == best)
            .map(|(_, n)| format!("'{n}'"))
            .collect();
        let hint = if close.is_empty() {
            String::new()
        } else {
            format!("did you mean {}? ", close.join(" or "))
        };
        Err(Error::Grid(format!(
            "unknown grid axis '{}': {hint}known axes are {}{own}",
            name.trim(),
            listed.join(", ")
        )))
    }

    /// Checks one value against the axis's physical domain.
    pub(crate) fn check(self, v: f64) -> Result<()> {
        match self.rule(v) {
            Some(p) => Err(Error::Grid(format!(
                "grid axis '{}' has value {v}: {p}; fix the value list",
                self.name()
            ))),
            None => Ok(()),
        }
    }
}

impl std::fmt::Display for Axis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
