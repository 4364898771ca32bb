//! Layer 0, pure math with known answers: PD torque, quaternions,
//! statistics, numbers as text. Depends on nothing else in the crate.

pub mod decimal;
pub mod margins;
pub mod motor;
pub mod pd;
pub mod quat;
pub mod response;
pub mod stats;
