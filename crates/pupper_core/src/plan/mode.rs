//! Who computes the joint torques: MuJoCo's servos or the PD in Rust.

use serde::{Deserialize, Serialize};

/// Who computes the joint torques.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// MuJoCo's affine actuators are the PD: gains written once per cell.
    #[default]
    Servo,
    /// PD computed in Rust every step; actuators are direct torque inputs.
    Torque,
}

impl Mode {
    pub fn as_str(self) -> &'static str {
        match self {
            Mode::Servo => "servo",
            Mode::Torque => "torque",
        }
    }
}
