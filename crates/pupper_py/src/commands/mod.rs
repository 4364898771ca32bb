//! The module's functions, a file per command or small group; each turns
//! its arguments into the Rust call the CLI makes.

pub(crate) mod cli;
pub(crate) mod hold;
pub(crate) mod lab;
pub(crate) mod model;
pub(crate) mod record;
pub(crate) mod replay;
pub(crate) mod response;
pub(crate) mod runs;
pub(crate) mod sweep;
pub(crate) mod walk;
