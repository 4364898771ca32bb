//! Layer 4, what a run leaves: the CSV and manifest formats, the run
//! directory (atomic writes, resume, merge) and the ranking rule.

pub mod best;
pub mod clear;
pub mod files;
pub mod fit_run;
pub mod json;
pub mod kind_manifest;
pub mod kinds;
pub mod lock;
pub mod merge;
pub mod output;
pub mod resume;
pub mod rundir;
pub mod tables;
