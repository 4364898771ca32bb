//! pupper_core: physics experiments on the Pupper v3 quadruped in MuJoCo.
//!
//! A plain Rust core (grids, schedules, PD, index bookkeeping, quaternions,
//! statistics, the runner and its outputs) over one bridge to MuJoCo's
//! Python package. The `#[pymodule]` lives in the `pupper_py` crate.

pub mod api;
pub mod bridge;
pub mod embed;
pub mod error;
pub mod experiment;
pub mod grid;
pub mod layout;
pub mod metrics;
pub mod model;
pub mod output;
pub mod pd;
pub mod physics;
pub mod quat;
pub mod schedule;
pub mod stats;

pub use error::{Error, ErrorKind, Result};

/// pupper's version, as recorded in manifests.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
