//! Layer 5, what a user asks: the command-line/Python spec of a sweep and
//! the chapter's lab, turned into a config and run settings.

pub mod hold;
pub mod lab;
pub mod response;
pub mod spec;
pub mod walk;
