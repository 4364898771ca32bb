//! Layer 1, the robot as compiled: its description (joints, actuators,
//! legs), the state-vector layout, named bodies and the stand-pose search.

pub mod gains;
pub mod layout;
pub mod model;
pub mod pose;
pub mod variant;
