//! Layer 3, running it: the physics seam, the runner that steps chunks of
//! cells, what is measured and recorded, and cells sent to a cluster.

pub mod cluster;
pub mod frames;
pub mod metrics;
pub mod physics;
pub mod response;
pub mod runner;
