//! Layer 3, running it: the physics seam, the runner that steps chunks of
//! cells, what is measured and recorded, and cells sent to a cluster.

pub mod chunk;
pub mod cluster;
pub mod firmware;
pub mod frames;
pub mod hold;
pub mod hooks;
pub mod joints;
pub mod metrics;
pub mod physics;
pub mod probe;
pub mod replay;
pub mod response;
pub mod result;
pub mod runner;
pub mod stand;
pub mod stepping;
pub mod torque;
pub mod walk;
