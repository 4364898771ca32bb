//! Layer 2, what to run: grids of cells, the schedule, the population of
//! replicates, the backend, shards, and the config that holds them all.

pub mod axis;
pub mod backend;
pub mod config;
pub mod experiment;
pub mod grid;
pub mod hold;
pub mod integrator;
pub mod kind;
pub mod mode;
pub mod motor;
pub mod randomize;
pub mod response;
pub mod schedule;
pub mod setup;
pub mod shard;
pub mod stability;
pub mod stand;
pub mod walk;
