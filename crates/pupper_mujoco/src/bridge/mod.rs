//! The MuJoCo bridge: the only code that touches Python objects for
//! physics. One job per module.

pub mod calls;
pub mod cpu;
mod helpers;
mod inspect;
pub mod model;
pub mod python;
pub mod ray;
pub mod replay;
mod setup;
pub mod warp;

pub use helpers::{Picked, call_helper, physics, with_config_model, with_model};
pub use model::LoadedModel;
pub use python::{MUJOCO_MAJOR, Mujoco, PythonReport, doctor};
pub use setup::start_stance;
