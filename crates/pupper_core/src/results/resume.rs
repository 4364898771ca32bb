//! Resuming a run directory: whether this command continues the run in it
//! (the same inputs, shard and model), and the finished cells read back
//! from its tables (a cell whose rows are not all on disk runs again).

use std::collections::BTreeMap;
use std::path::Path;

use crate::error::{Error, Result};
use crate::plan::config::SweepConfig;
use crate::results::output::{
    Detail, Manifest, REPLICATES, SUMMARY, TRACES, Trace, config_diff, read_detail, read_rows,
    read_traces, short,
};
use crate::results::tables::{BODE, RESPONSE, RESPONSE_TRACES, header_of};

/// Refuses to resume the run `old` with the command of `new`: its inputs,
/// its shard of the grid or its model differ, each named in one line.
pub(crate) fn check_continues(dir: &Path, old: &Manifest, new: &Manifest) -> Result<()> {
    let diff = config_diff(&old.config, &new.config);
    if !diff.is_empty() {
        return Err(Error::ResumeMismatch(format!(
            "cannot resume '{}': this command differs from the run's in {}; rerun the original command with --resume (or --resume DIR alone), or use a new --out",
            dir.display(),
            diff.join(", ")
        )));
    }
    let shard_of = |m: &Manifest| m.shard.as_ref().map(|s| s.shard.to_string());
    if shard_of(old) != shard_of(new) {
        let name = |s: Option<String>| s.map_or("no shard".into(), |s| format!("shard {s}"));
        return Err(Error::ResumeMismatch(format!(
            "cannot resume '{}': it holds {} of the grid, this command {}; resume it with --resume DIR alone, or use a new --out",
            dir.display(),
            name(shard_of(old)),
            name(shard_of(new))
        )));
    }
    if old.model.sha256 != new.model.sha256 {
        return Err(Error::ResumeMismatch(format!(
            "cannot resume '{}': the model '{}' changed since the run started (SHA-256 {} then, {} now); use a new --out",
            dir.display(),
            old.model.source,
            short(&old.model.sha256),
            short(&new.model.sha256)
        )));
    }
    Ok(())
}

/// What a resumed run keeps of its finished cells, by cell index.
pub(crate) struct Kept {
    pub(crate) rows: BTreeMap<usize, Vec<String>>,
    /// Per table beside summary.csv, its rows by cell.
    pub(crate) details: Vec<BTreeMap<usize, Vec<Vec<String>>>>,
    pub(crate) traces: BTreeMap<usize, Trace>,
}

/// The finished cells of the run in `dir`: its summary rows, the rows of
/// each of its `details` tables and (`want_traces`) its traces.
pub(crate) fn read_kept(
    dir: &Path,
    config: &SweepConfig,
    details: &[Detail],
    want_traces: bool,
) -> Result<Kept> {
    let mut rows = read_rows(dir, config, &header_of(config))?;
    let detail_rows = details
        .iter()
        .map(|d| read_detail(dir, d, &rows))
        .collect::<Result<Vec<_>>>()?;
    // a cell without all its rows on disk runs again
    rows.retain(|i, _| detail_rows.iter().all(|d| d.contains_key(i)));
    let traces = match want_traces {
        true => read_traces(dir, &rows)?,
        false => BTreeMap::new(),
    };
    Ok(Kept {
        rows,
        details: detail_rows,
        traces,
    })
}

/// True when `dir` holds nothing a run would keep: no rows, only our lock,
/// temporary files, and a summary with at most its header.
pub(crate) fn only_ours(dir: &Path) -> bool {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return false;
    };
    entries.flatten().all(|e| {
        let name = e.file_name().to_string_lossy().into_owned();
        crate::results::lock::is_ours_to_ignore(&name)
            || ((name == SUMMARY
                || name == TRACES
                || name == REPLICATES
                || name == RESPONSE
                || name == BODE
                || name == RESPONSE_TRACES)
                && std::fs::read_to_string(e.path()).is_ok_and(|t| t.lines().count() <= 1))
    })
}
