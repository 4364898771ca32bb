//! pupper_core: physics experiments on the Pupper v3 quadruped in MuJoCo.
//!
//! The plain Rust core, in layers that import only downwards: [`math`]
//! (PD, quaternions, statistics), [`robot`] (the compiled model), [`plan`]
//! (grids, schedules, configs), [`sim`] (the runner and its metrics),
//! [`results`] (run directories, ranking) and [`request`] (what a user
//! asks). No Python here: physics comes through the [`sim::physics::Physics`] trait, which
//! `pupper_mujoco` implements on MuJoCo's batch; the `#[pymodule]` lives in
//! `pupper_py`.

pub mod error;
pub mod math;
pub mod plan;
pub mod request;
pub mod results;
pub mod robot;
pub mod sim;

pub use error::{Error, ErrorKind, Result};

/// pupper's version, as recorded in manifests.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
