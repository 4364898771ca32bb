//! MuJoCo's integrator for every cell of a run (`--integrator`), by its
//! name in MJCF; the manifest keeps it when it is not the model's own.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// MuJoCo's integrators, by their names in MJCF (`<option integrator=>`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    Euler,
    Rk4,
    Implicit,
    Implicitfast,
}

impl Integrator {
    const NAMES: [(&str, Integrator); 4] = [
        ("euler", Integrator::Euler),
        ("rk4", Integrator::Rk4),
        ("implicit", Integrator::Implicit),
        ("implicitfast", Integrator::Implicitfast),
    ];

    pub fn parse(name: &str) -> Result<Integrator> {
        let n = name.trim().to_ascii_lowercase();
        Integrator::NAMES
            .iter()
            .find(|(k, _)| *k == n)
            .map(|(_, i)| *i)
            .ok_or_else(|| {
                Error::Config(format!(
                    "--integrator {name} is unknown: use euler, implicitfast, implicit or rk4"
                ))
            })
    }

    /// MuJoCo's `mjtIntegrator` value.
    pub fn mj(self) -> i64 {
        match self {
            Integrator::Euler => 0,
            Integrator::Rk4 => 1,
            Integrator::Implicit => 2,
            Integrator::Implicitfast => 3,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integrators_by_their_mjcf_names() {
        assert_eq!(Integrator::parse("implicitfast").unwrap().mj(), 3);
        assert_eq!(Integrator::parse(" Euler ").unwrap().mj(), 0);
        assert_eq!(Integrator::parse("rk4").unwrap().mj(), 1);
        let e = Integrator::parse("leapfrog").unwrap_err().to_string();
        assert!(
            e.contains("leapfrog is unknown") && e.contains("implicitfast"),
            "{e}"
        );
        assert_eq!(
            serde_json::to_string(&Integrator::Implicitfast).unwrap(),
            "\"implicitfast\""
        );
    }
}
