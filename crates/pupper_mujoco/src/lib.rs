//! pupper's physics through MuJoCo's Python package: the bridge (the only
//! code that touches Python objects), embedding CPython in the binary, and
//! the operations the CLI and the Python module share.

pub mod api;
pub mod bridge;
pub mod embed;
