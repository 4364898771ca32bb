//! Whether a cell's gains lie past the stability bound of the PD as the
//! integrator computes it at the cell's timestep. Past it a cell's numbers
//! describe the integrator (chatter at the torque limit, or divergence),
//! not a robot: such a cell is marked `past_bound` and never ranked.

use crate::math::response::pd_margin;
use crate::plan::mode::Mode;
use crate::plan::setup::CellSetup;
use crate::robot::model::ModelInfo;

/// How the integrator takes the PD's damping term.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Damping {
    /// From the state at the start of the step: MuJoCo's Euler on a
    /// servo's velocity gain, and torque mode's PD (computed in Rust).
    Explicit,
    /// Implicitly (MuJoCo's `implicit` and `implicitfast` on a servo).
    Implicit,
}

impl Damping {
    /// How a run in `mode` on a model whose integrator is `integrator`
    /// (MuJoCo's `mjtIntegrator`: 0 Euler, 1 RK4, 2 implicit, 3
    /// implicitfast) takes the damping; None for RK4, for which pupper
    /// states no bound.
    pub fn of(mode: Mode, integrator: i64) -> Option<Damping> {
        match (mode, integrator) {
            (Mode::Torque, _) | (Mode::Servo, 0) => Some(Damping::Explicit),
            (Mode::Servo, 2 | 3) => Some(Damping::Implicit),
            _ => None,
        }
    }

    /// The margin of one joint of inertia `inertia` (kg·m²): 1 or more is
    /// past the bound.
    pub fn margin(self, inertia: f64, kp: f64, kd: f64, timestep: f64) -> f64 {
        pd_margin(inertia, kp, kd, timestep, self == Damping::Implicit)
    }
}

/// Each actuator's margin in a cell of setup `s` at its nominal gains and
/// timestep, from the joints' reflected inertias at the start pose
/// (`inertia`, ctrl order).
pub fn cell_margins(
    info: &ModelInfo,
    inertia: &[f64],
    s: &CellSetup,
    damping: Damping,
) -> Vec<f64> {
    let dt = s.timestep.unwrap_or(info.timestep);
    (0..info.nu.min(inertia.len()))
        .map(|a| damping.margin(inertia[a], s.kp(a), s.kd(a), dt))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_integrator_decides_how_damping_is_taken() {
        assert_eq!(Damping::of(Mode::Servo, 0), Some(Damping::Explicit));
        assert_eq!(Damping::of(Mode::Servo, 3), Some(Damping::Implicit));
        assert_eq!(Damping::of(Mode::Servo, 2), Some(Damping::Implicit));
        // the Rust PD is explicit whatever MuJoCo integrates
        assert_eq!(Damping::of(Mode::Torque, 3), Some(Damping::Explicit));
        assert_eq!(Damping::of(Mode::Servo, 1), None);
        // Pupper's knee (I = 1.816e-3) at kp 120 / kd 2, h = 2 ms: past the
        // bound explicitly (b = 2.2), well inside it with implicit damping
        let (i, h) = (1.816e-3, 0.002);
        assert!(Damping::Explicit.margin(i, 120.0, 2.0, h) > 1.0);
        assert!(Damping::Implicit.margin(i, 120.0, 2.0, h) < 0.05);
    }
}
