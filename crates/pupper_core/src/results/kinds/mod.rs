//! What each experiment kind writes: summary.csv's header and a row per
//! cell, and the tables of rows per cell beside it. A kind's tables are its
//! own module; [`of`] is the registry. The run directory appends, resumes
//! and merges every kind's tables the same way.

pub mod hold;
pub mod response;
pub mod stand;
pub mod walk;

use crate::plan::config::SweepConfig;
use crate::results::output::Detail;
use crate::sim::result::CellResult;
use crate::{plan::experiment::Experiment, plan::stand::Stand};

pub trait KindTables {
    /// summary.csv's header.
    fn summary_header(&self, config: &SweepConfig) -> Vec<String>;
    /// The tables beside summary.csv, for a model of `nu` actuators.
    fn details(&self, config: &SweepConfig, nu: usize) -> Vec<Detail>;
    /// A finished cell's summary row.
    fn summary_row(&self, config: &SweepConfig, r: &CellResult) -> Vec<String>;
    /// A finished cell's rows of each table of [`KindTables::details`], in
    /// that order.
    fn detail_rows(&self, config: &SweepConfig, r: &CellResult) -> Vec<Vec<Vec<String>>>;
    /// Whether `--trace` records the base's height (traces.csv); a kind
    /// that traces something else in a table of its own writes none, so
    /// no run directory holds a traces.csv of its header alone.
    fn traces_base_z(&self) -> bool {
        true
    }
}

/// The registry: the tables of an experiment's kind.
pub fn of(e: &Experiment) -> &dyn KindTables {
    match e {
        Experiment::Stand => &Stand,
        Experiment::Response(x) => x,
        Experiment::Hold(l) => l,
        Experiment::Walk(w) => w,
    }
}
