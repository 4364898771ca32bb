//! pupper_core: physics experiments on the Pupper v3 quadruped in MuJoCo.
//!
//! The plain Rust core: grids, schedules, PD, index bookkeeping, quaternions,
//! statistics, metrics, the experiment runner and its run directory. No
//! Python here: physics comes through the [`physics::Physics`] trait, which
//! `pupper_mujoco` implements on MuJoCo's batch; the `#[pymodule]` lives in
//! `pupper_py`.

pub mod backend;
pub mod best;
pub mod cluster;
pub mod error;
pub mod experiment;
pub mod frames;
pub mod grid;
pub mod lab;
pub mod layout;
pub mod metrics;
pub mod model;
pub mod output;
pub mod pd;
pub mod physics;
pub mod pose;
pub mod quat;
pub mod randomize;
pub mod rundir;
pub mod schedule;
pub mod shard;
pub mod spec;
pub mod stats;
pub mod variant;

pub use error::{Error, ErrorKind, Result};

/// pupper's version, as recorded in manifests.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
