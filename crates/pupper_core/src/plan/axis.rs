//! The parameters a grid can vary: their names, how a value of each is
//! written into a cell's id, and the values each accepts.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::robot::variant::VARIANTS;

/// A named experiment parameter that a grid can vary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Axis {
    /// Proportional gain (N·m/rad).
    Kp,
    /// Derivative gain (N·m·s/rad).
    Kd,
    /// Vertical push force on the base (N, world z; negative pushes down).
    PushForce,
    /// Torque limit of every actuator (N·m).
    MaxTorque,
    /// Sliding friction of the feet and the floor.
    Friction,
    /// Physics timestep (s).
    Timestep,
    /// Scale of thigh and calf lengths and masses.
    LegScale,
    /// Scale of the torso mass and inertia.
    TorsoMassScale,
    /// A named body (original, long-leg, heavy); values are indices into
    /// [`crate::robot::variant::VARIANTS`], shown by name.
    Variant,
    /// Kp and Kd of one joint group (abduction, hip pitch, knee), over the
    /// common `kp`/`kd` for the joints of that group.
    KpHaa,
    KpHfe,
    KpKfe,
    KdHaa,
    KdHfe,
    KdKfe,
}

impl Axis {
    pub const ALL: [Axis; 15] = [
        Axis::Kp,
        Axis::Kd,
        Axis::PushForce,
        Axis::MaxTorque,
        Axis::Friction,
        Axis::Timestep,
        Axis::LegScale,
        Axis::TorsoMassScale,
        Axis::Variant,
        Axis::KpHaa,
        Axis::KpHfe,
        Axis::KpKfe,
        Axis::KdHaa,
        Axis::KdHfe,
        Axis::KdKfe,
    ];

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

    pub fn name(self) -> &'static str {
        match self {
            Axis::Kp => "kp",
            Axis::Kd => "kd",
            Axis::PushForce => "push_force",
            Axis::MaxTorque => "max_torque",
            Axis::Friction => "friction",
            Axis::Timestep => "timestep",
            Axis::LegScale => "leg_scale",
            Axis::TorsoMassScale => "torso_mass_scale",
            Axis::Variant => "variant",
            Axis::KpHaa => "kp.haa",
            Axis::KpHfe => "kp.hfe",
            Axis::KpKfe => "kp.kfe",
            Axis::KdHaa => "kd.haa",
            Axis::KdHfe => "kd.hfe",
            Axis::KdKfe => "kd.kfe",
        }
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

    /// Short form used in cell ids.
    pub(crate) fn tag(self) -> &'static str {
        match self {
            Axis::Kp => "kp",
            Axis::Kd => "kd",
            Axis::PushForce => "push",
            Axis::MaxTorque => "tmax",
            Axis::Friction => "mu",
            Axis::Timestep => "dt",
            Axis::LegScale => "leg",
            Axis::TorsoMassScale => "torso",
            Axis::Variant => "",
            Axis::KpHaa => "kphaa",
            Axis::KpHfe => "kphfe",
            Axis::KpKfe => "kpkfe",
            Axis::KdHaa => "kdhaa",
            Axis::KdHfe => "kdhfe",
            Axis::KdKfe => "kdkfe",
        }
    }

    pub fn parse(name: &str) -> Result<Axis> {
        let key = name.trim().to_ascii_lowercase().replace('-', "_");
        if let Some(axis) = Axis::ALL.iter().find(|a| a.name() == key) {
            return Ok(*axis);
        }
        let names: Vec<&str> = Axis::ALL.iter().map(|a| a.name()).collect();
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
            "unknown grid axis '{}': {hint}known axes are {}",
            name.trim(),
            names.join(", ")
        )))
    }

    /// Checks one value against the axis's physical domain.
    pub(crate) fn check(self, v: f64) -> Result<()> {
        let problem = match self {
            a if a.is_gain() && v < 0.0 => Some("gains must be >= 0"),
            Axis::MaxTorque if v <= 0.0 => Some("max_torque must be > 0"),
            Axis::Friction if v <= 0.0 => Some("friction must be > 0"),
            Axis::Timestep if !(1e-6..=0.05).contains(&v) => {
                Some("timestep must be in [1e-6, 0.05] s")
            }
            Axis::LegScale if !(0.25..=4.0).contains(&v) => Some("leg_scale must be in [0.25, 4]"),
            Axis::TorsoMassScale if !(0.05..=20.0).contains(&v) => {
                Some("torso_mass_scale must be in [0.05, 20]")
            }
            _ => None,
        };
        match problem {
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
