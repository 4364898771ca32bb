//! A run's tables as the layers above ask for them: each answered by the
//! run's experiment kind ([`crate::results::kinds`]); and a run directory
//! read back whole.

use std::path::Path;

use crate::error::Result;
use crate::plan::config::SweepConfig;
use crate::results::kinds;
use crate::results::output::{
    Detail, Manifest, Trace, read_detail, read_manifest, read_rows, read_traces,
};
use crate::sim::result::CellResult;

pub use crate::results::kinds::response::{BODE, RESPONSE, RESPONSE_TRACES};

/// The header of a run's `summary.csv`.
pub fn header_of(config: &SweepConfig) -> Vec<String> {
    kinds::of(&config.experiment).summary_header(config)
}

/// The tables beside summary.csv, for a model of `nu` actuators.
pub fn details_of(config: &SweepConfig, nu: usize) -> Vec<Detail> {
    kinds::of(&config.experiment).details(config, nu)
}

/// Whether `--trace` writes traces.csv for this config's kind.
pub fn kind_traces_base_z(config: &SweepConfig) -> bool {
    kinds::of(&config.experiment).traces_base_z()
}

/// A finished cell's summary row.
pub fn summary_row(config: &SweepConfig, r: &CellResult) -> Vec<String> {
    kinds::of(&config.experiment).summary_row(config, r)
}

/// A finished cell's rows of each table of [`details_of`], in that order.
pub fn detail_rows(config: &SweepConfig, r: &CellResult) -> Vec<Vec<Vec<String>>> {
    kinds::of(&config.experiment).detail_rows(config, r)
}

/// A table beside summary.csv as text: its file name, header, and rows in
/// cell order.
pub type NamedTable = (String, Vec<String>, Vec<Vec<String>>);

/// A run directory read back (what Python's `load_run` returns).
#[derive(Debug, Clone)]
pub struct RunTables {
    pub manifest: Manifest,
    pub header: Vec<String>,
    /// summary.csv's rows in cell order.
    pub rows: Vec<Vec<String>>,
    /// (cell id, (t, z) samples) in cell order, for traced runs.
    pub traces: Vec<Trace>,
    /// Every table beside summary.csv (replicates.csv too): file name,
    /// header, rows in cell order.
    pub details: Vec<NamedTable>,
}

/// Reads a run directory, checking its rows against its manifest.
pub fn read_run(dir: &Path) -> Result<RunTables> {
    let manifest = read_manifest(dir)?;
    let mut rows = read_rows(dir, &manifest.config, &header_of(&manifest.config))?;
    let details = details_of(&manifest.config, manifest.torque_limits.len());
    let mut read = Vec::with_capacity(details.len());
    for d in &details {
        let got = read_detail(dir, d, &rows)?;
        rows.retain(|i, _| got.contains_key(i));
        read.push(got);
    }
    // traces of the cells kept (not of one whose replicates are cut short)
    let traces = read_traces(dir, &rows)?;
    let mut manifest = manifest;
    // (a response traces its joints in a table of its own, kept above)
    let traced = manifest.config.schedule.trace_every > 0 && kind_traces_base_z(&manifest.config);
    if traced {
        rows.retain(|i, _| traces.contains_key(i));
    }
    // a run whose files lost rows is not complete, whatever its manifest
    // says: --resume recomputes what is missing
    if rows.len() < manifest.cells_done {
        manifest.complete = false;
        manifest.cells_done = rows.len();
    }
    let traces: Vec<Trace> = traces
        .into_iter()
        .filter(|(i, _)| rows.contains_key(i))
        .map(|(_, t)| t)
        .collect();
    let details: Vec<NamedTable> = details
        .into_iter()
        .zip(read)
        .map(|(d, got)| {
            let kept = got
                .into_iter()
                .filter(|(i, _)| rows.contains_key(i))
                .flat_map(|(_, r)| r)
                .collect();
            (d.file.to_string(), d.header, kept)
        })
        .collect();
    Ok(RunTables {
        details,
        header: header_of(&manifest.config),
        rows: rows.into_values().collect(),
        traces,
        manifest,
    })
}
