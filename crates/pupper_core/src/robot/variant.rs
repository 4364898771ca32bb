//! Named body variants of the chapter's lab: the robot with longer legs or
//! a heavier torso, built in memory from the model (see the bridge's
//! `scale_spec`: thigh and calf lengths and masses, torso mass and inertia).

use serde::Serialize;

use crate::error::{Error, Result};

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Variant {
    pub name: &'static str,
    pub leg_scale: f64,
    pub torso_mass_scale: f64,
    pub about: &'static str,
}

pub const VARIANTS: [Variant; 3] = [
    Variant {
        name: "original",
        leg_scale: 1.0,
        torso_mass_scale: 1.0,
        about: "the model as written",
    },
    Variant {
        name: "long-leg",
        leg_scale: 1.5,
        torso_mass_scale: 1.0,
        about: "thighs and calves 1.5x as long (and heavy)",
    },
    Variant {
        name: "heavy",
        leg_scale: 1.0,
        torso_mass_scale: 2.0,
        about: "torso twice as heavy",
    },
];

/// Leg and torso scales of a body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scales {
    pub leg_scale: f64,
    pub torso_mass_scale: f64,
}

/// A variant by name.
pub fn variant(name: &str) -> Result<&'static Variant> {
    VARIANTS.iter().find(|v| v.name == name).ok_or_else(|| {
        let names: Vec<&str> = VARIANTS.iter().map(|v| v.name).collect();
        Error::Config(format!(
            "unknown variant '{name}': use one of {}",
            names.join(", ")
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_chapters_three_bodies() {
        assert_eq!(variant("long-leg").unwrap().leg_scale, 1.5);
        assert_eq!(variant("heavy").unwrap().torso_mass_scale, 2.0);
        let e = variant("tall").unwrap_err().to_string();
        assert!(e.contains("original, long-leg, heavy"), "{e}");
    }
}
