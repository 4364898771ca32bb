//! The run directory: `summary.csv` (one row per cell), `manifest.json`
//! (inputs, model hash, versions, timing, completeness) and optional
//! `traces.csv`: their formats, and reading them back (rows checked
//! against the manifest's grid). Rows are formatted the same way every time,
//! so the same inputs give the same bytes; `rundir` writes them.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
pub use crate::math::decimal::fmt_f64;
use crate::plan::config::SweepConfig;
use crate::plan::grid::Cell;
use crate::sim::metrics::{METRIC_NAMES, Metrics};

pub const SUMMARY: &str = "summary.csv";
pub const MANIFEST: &str = "manifest.json";
pub const TRACES: &str = "traces.csv";
pub const BEST: &str = "best.csv";
pub const REPLICATES: &str = "replicates.csv";
/// The lock file every writer of a run directory holds.
pub const LOCK: &str = ".pupper.lock";

/// The metrics summarised over replicates: the numeric ones but the time
/// of an event, which only failed replicates have.
pub fn aggregated() -> impl Iterator<Item = &'static str> {
    METRIC_NAMES
        .iter()
        .copied()
        .filter(|m| !matches!(*m, "status" | "event_time"))
}

/// The statistics a replicated summary has per metric: `mean:METRIC` and
/// `p95:METRIC` (the worst-side 95 % point).
pub const STATISTICS: [&str; 2] = ["mean", "p95"];

/// Whether a metric's bad side is high (all but the base height, whose
/// bad side is low: a sagging robot).
pub fn worse_high(metric: &str) -> bool {
    metric != "final_z"
}

/// The header of `summary.csv` for a grid with these axis names.
pub fn header(axes: &[String]) -> Vec<String> {
    let mut h: Vec<String> = ["index", "id", "name"].map(String::from).to_vec();
    h.extend(axes.iter().cloned());
    h.extend(METRIC_NAMES.iter().map(|s| s.to_string()));
    h
}

pub(crate) fn axis_names(config: &SweepConfig) -> Vec<String> {
    config
        .grid
        .axes
        .iter()
        .map(|a| a.axis.name().to_string())
        .collect()
}

/// A table of rows per cell beside summary.csv.
#[derive(Debug, Clone, PartialEq)]
pub struct Detail {
    pub file: &'static str,
    pub header: Vec<String>,
    /// Rows every finished cell has (a cell with fewer runs again).
    /// None: as many as the cell has (a trace's length varies with the
    /// cell's timestep); its summary row, written last, vouches for them.
    pub per_cell: Option<usize>,
    /// A column numbering each cell's rows 0, 1, ... (checked on reading).
    pub sequence: Option<usize>,
}

pub fn cell_fields(cell: &Cell) -> Vec<String> {
    let mut r = vec![cell.index.to_string(), cell.id.clone(), cell.name.clone()];
    r.extend(cell.values.iter().map(|(a, v)| a.text(*v)));
    r
}

/// The columns naming a cell: index, id, name and its axes.
pub fn cell_columns(config: &SweepConfig) -> Vec<String> {
    let mut h: Vec<String> = ["index", "id", "name"].map(String::from).to_vec();
    h.extend(axis_names(config));
    h
}

/// The header of `replicates.csv`, for a model of `nu` actuators.
pub fn replicates_header(config: &SweepConfig, nu: usize) -> Vec<String> {
    let mut h: Vec<String> = ["index", "id", "name"].map(String::from).to_vec();
    h.extend(axis_names(config));
    h.push("replicate".into());
    h.extend(config.replicates.columns(nu));
    h.extend(METRIC_NAMES.iter().map(|s| s.to_string()));
    h
}

/// One row of `replicates.csv`.
pub fn replicate_row(cell: &Cell, replicate: usize, drawn: &[f64], m: &Metrics) -> Vec<String> {
    let mut r = row(cell, m);
    let at = 3 + cell.values.len();
    let mut mid = vec![replicate.to_string()];
    mid.extend(drawn.iter().map(|v| fmt_f64(*v)));
    r.splice(at..at, mid);
    r
}

/// A replicated cell's summary row: how many replicates, the share that
/// fell or diverged, and each metric's mean and worst-side 95th percentile
/// over the replicates that stayed up (empty when none did, or when one
/// of them has no value for it, e.g. never settled).
pub fn robust_row(cell: &Cell, runs: &[&Metrics]) -> Vec<String> {
    let mut r = vec![cell.index.to_string(), cell.id.clone(), cell.name.clone()];
    r.extend(cell.values.iter().map(|(a, v)| a.text(*v)));
    // a robot past the stability bound counts as failed: its figures
    // describe the integrator, so they are not aggregated and the cell is
    // never ranked (no robot was past it before the bound was marked)
    let up: Vec<&Metrics> = runs
        .iter()
        .copied()
        .filter(|m| m.status.stood() && m.status != crate::sim::metrics::Status::PastBound)
        .collect();
    r.push(runs.len().to_string());
    let failed = (runs.len() - up.len()) as f64 / runs.len().max(1) as f64;
    r.push(fmt_f64(failed));
    for name in aggregated() {
        let mut xs: Vec<f64> = up.iter().map(|m| m.get(name).unwrap_or(f64::NAN)).collect();
        if xs.is_empty() || xs.iter().any(|x| !x.is_finite()) {
            r.extend([String::new(), String::new()]);
            continue;
        }
        xs.sort_by(f64::total_cmp);
        let mean = crate::math::stats::mean(&xs);
        let p = if worse_high(name) { 0.95 } else { 0.05 };
        r.push(fmt_f64(mean));
        r.push(fmt_f64(crate::math::stats::percentile(&xs, p)));
    }
    r
}

/// One summary row as text fields.
pub fn row(cell: &Cell, m: &Metrics) -> Vec<String> {
    let mut r = vec![cell.index.to_string(), cell.id.clone(), cell.name.clone()];
    r.extend(cell.values.iter().map(|(a, v)| a.text(*v)));
    for name in METRIC_NAMES {
        r.push(match name {
            "status" => m.status.as_str().to_string(),
            n => fmt_f64(m.get(n).unwrap_or(f64::NAN)),
        });
    }
    r
}

/// CSV text of `rows` after a `header` row (none when empty).
pub fn csv_bytes(header: &[String], rows: &[Vec<String>]) -> Result<Vec<u8>> {
    let mut w = csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new());
    let bad = |e: csv::Error| Error::Internal(format!("csv: {e}"));
    if !header.is_empty() {
        w.write_record(header).map_err(bad)?;
    }
    for r in rows {
        w.write_record(r).map_err(bad)?;
    }
    w.into_inner()
        .map_err(|e| Error::Internal(format!("csv: {e}")))
}

/// Model identity recorded in the manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelRecord {
    pub name: String,
    pub source: String,
    pub sha256: String,
    /// The model's own timestep (s), a cell's unless its grid sets one:
    /// what a run read back needs to say each cell's steps. None in a
    /// manifest written before it was recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub timestep: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// What the run is, as users name it: sweep, lab or response (tune and
    /// fit write their own manifests). Empty in a manifest written before
    /// the kind was recorded.
    #[serde(default)]
    pub kind: String,
    pub pupper_version: String,
    pub mujoco_version: String,
    pub python: String,
    pub config: SweepConfig,
    pub model: ModelRecord,
    /// Each actuator's torque limit (N·m) for cells without a max_torque
    /// value: --max-torque, else the model's own limits.
    #[serde(default)]
    pub torque_limits: Vec<f64>,
    /// Where the cells start when that is not the model's `home` keyframe
    /// (a model without one starts from its first keyframe, else its
    /// default pose, legs often straight): the notes the run printed, kept
    /// for report.html's warnings. Absent when the start is `home`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub start_notes: Vec<String>,
    pub cells_total: usize,
    pub cells_done: usize,
    /// Batches (one MuJoCo batch run each) whose cells are in this directory.
    #[serde(default)]
    pub batches: usize,
    pub complete: bool,
    pub threads: usize,
    pub started_unix: u64,
    pub wall_seconds: f64,
    pub command: Vec<String>,
    /// The shard of the grid this run holds (`--shard I/N`), and its host.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<ShardRecord>,
    /// The shards a `pupper merge` put together.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub merged: Vec<MergedShard>,
    /// The Ray cluster that ran this run's cells (`--ray`), as last seen.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ray: Option<RayRecord>,
}

/// Where a `--ray` run's tasks ran.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RayRecord {
    pub address: String,
    /// The cluster's live nodes when the run started.
    pub nodes: Vec<RayNode>,
    /// Tasks run at once, and the CPUs (batch threads) of each.
    pub slots: usize,
    pub threads_per_task: usize,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RayNode {
    pub host: String,
    pub address: String,
    pub cpus: f64,
}

/// A sharded run's part of the grid and where it ran.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardRecord {
    #[serde(flatten)]
    pub shard: crate::plan::shard::Shard,
    pub host: String,
}

/// One shard of a merged run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MergedShard {
    pub dir: String,
    pub index: u32,
    pub count: u32,
    pub host: String,
    pub cells: usize,
    pub wall_seconds: f64,
    pub started_unix: u64,
}

/// The first 12 hex digits of a SHA-256, as messages show it.
pub fn short(sha: &str) -> &str {
    &sha[..sha.len().min(12)]
}

/// Reads a run's manifest.
pub fn read_manifest(dir: &Path) -> Result<Manifest> {
    let p = dir.join(MANIFEST);
    let text = std::fs::read_to_string(&p).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => Error::RunNotFound(format!(
            "'{}' is not a run directory: it has no {MANIFEST}; give the directory of an earlier `pupper sweep`",
            dir.display()
        )),
        _ => Error::io("read", &p, e),
    })?;
    serde_json::from_str(&text).map_err(|e| {
        Error::Output(format!(
            "'{}': its {MANIFEST} is not a pupper manifest ({e}); start a new run with --out",
            dir.display()
        ))
    })
}

/// A cell's trace: its id and (t, z) samples.
pub type Trace = (String, Vec<(f64, f64)>);

/// A run file's text, or None when the run has not written it yet.
fn read_if_there(path: &Path) -> Result<Option<String>> {
    match std::fs::read_to_string(path) {
        Ok(t) => Ok(Some(t)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(Error::io("read", path, e)),
    }
}

/// Lines of a file that ends cleanly: a last line without its newline is
/// the trace of a write that was cut short, and is left out.
fn whole_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    let whole = match text.rfind('\n') {
        Some(i) => &text[..i + 1],
        None => "",
    };
    whole.lines().enumerate().map(|(i, l)| (i + 1, l))
}

/// The data rows of a run table's text, each with its line number: every
/// line a CSV row, the first equal to `header`, the others as wide. A
/// truncated last line is dropped. Errors name `path:line`.
fn table_rows(path: &Path, text: &str, header: &[String]) -> Result<Vec<(usize, Vec<String>)>> {
    let broken = |line: usize, what: String| broken_row(path, line, what);
    let mut out = Vec::new();
    for (n, line) in whole_lines(text) {
        let fields: Vec<String> = match csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(line.as_bytes())
            .records()
            .next()
        {
            Some(Ok(rec)) => rec.iter().map(String::from).collect(),
            _ => return Err(broken(n, "not a CSV row".into())),
        };
        if n == 1 {
            if fields != header {
                return Err(broken(
                    n,
                    format!("its columns are not {}", header.join(",")),
                ));
            }
            continue;
        }
        if fields.len() != header.len() {
            return Err(broken(
                n,
                format!(
                    "{} fields where the header has {}",
                    fields.len(),
                    header.len()
                ),
            ));
        }
        out.push((n, fields));
    }
    Ok(out)
}

/// A run file's row that does not fit the run's manifest.
fn broken_row(path: &Path, line: usize, what: String) -> Error {
    Error::Output(format!(
        "{}:{line}: {what}; this file does not belong to the run's manifest: move it away, or start a new run with --force",
        path.display()
    ))
}

/// The rows of a run's `summary.csv`, by cell index, each checked against
/// the manifest's grid: its index in range, its id and axis values those of
/// that cell. A truncated last line is dropped (its cell runs again).
pub(crate) fn read_rows(
    dir: &Path,
    config: &SweepConfig,
    want: &[String],
) -> Result<BTreeMap<usize, Vec<String>>> {
    let p = dir.join(SUMMARY);
    let mut rows = BTreeMap::new();
    let Some(text) = read_if_there(&p)? else {
        return Ok(rows);
    };
    let cells = config.grid.cells();
    let broken = |line: usize, what: String| broken_row(&p, line, what);
    for (n, fields) in table_rows(&p, &text, want)? {
        let cell = fields[0]
            .parse::<usize>()
            .ok()
            .and_then(|i| cells.get(i))
            .ok_or_else(|| {
                broken(
                    n,
                    format!(
                        "index '{}' is not a cell of this {}-cell grid",
                        fields[0],
                        cells.len()
                    ),
                )
            })?;
        let values: Vec<String> = cell.values.iter().map(|(a, v)| a.text(*v)).collect();
        if fields[1] != cell.id || fields[3..3 + values.len()] != values[..] {
            return Err(broken(
                n,
                format!(
                    "row {} is cell '{}' of another grid (this grid's cell {} is '{}')",
                    fields[0], fields[1], cell.index, cell.id
                ),
            ));
        }
        rows.insert(cell.index, fields);
    }
    Ok(rows)
}

/// The traces of a run's `traces.csv` by cell id (a truncated last line is
/// dropped), for the cells in `keep`.
pub(crate) fn read_traces(
    dir: &Path,
    keep: &BTreeMap<usize, Vec<String>>,
) -> Result<BTreeMap<usize, Trace>> {
    let p = dir.join(TRACES);
    let mut out = BTreeMap::new();
    let Some(text) = read_if_there(&p)? else {
        return Ok(out);
    };
    let by_id: BTreeMap<&str, usize> = keep.iter().map(|(i, r)| (r[1].as_str(), *i)).collect();
    let mut samples: BTreeMap<usize, Vec<(f64, f64)>> = BTreeMap::new();
    for (n, line) in whole_lines(&text).skip(1) {
        let mut parts = line.rsplitn(3, ',');
        let (z, t, id) = (parts.next(), parts.next(), parts.next());
        let parsed = match (id, t.map(str::parse::<f64>), z.map(str::parse::<f64>)) {
            (Some(id), Some(Ok(t)), Some(Ok(z))) => Some((id, t, z)),
            _ => None,
        };
        let Some((id, t, z)) = parsed else {
            return Err(Error::Output(format!(
                "{}:{n}: not an 'id,t,z' row; move the file away, or start a new run with --force",
                p.display()
            )));
        };
        if let Some(&i) = by_id.get(id) {
            samples.entry(i).or_default().push((t, z));
        }
    }
    for (i, s) in samples {
        out.insert(i, (keep[&i][1].clone(), s));
    }
    Ok(out)
}

/// The rows of a table beside summary.csv (replicates.csv, response.csv,
/// bode.csv) for the finished cells in `keep`, by cell index. A cell whose
/// rows are not all there is left out (it runs again); a truncated last
/// line is dropped.
pub(crate) fn read_detail(
    dir: &Path,
    detail: &Detail,
    keep: &BTreeMap<usize, Vec<String>>,
) -> Result<BTreeMap<usize, Vec<Vec<String>>>> {
    let p = dir.join(detail.file);
    let mut out: BTreeMap<usize, Vec<Vec<String>>> = BTreeMap::new();
    let Some(text) = read_if_there(&p)? else {
        return Ok(out);
    };
    let broken = |line: usize, what: String| broken_row(&p, line, what);
    for (n, fields) in table_rows(&p, &text, &detail.header)? {
        let Some(index) = fields[0].parse::<usize>().ok() else {
            return Err(broken(n, format!("index '{}' is not a cell", fields[0])));
        };
        let Some(cell_row) = keep.get(&index) else {
            continue; // its cell did not finish: it runs again
        };
        let rows = out.entry(index).or_default();
        let in_order = detail
            .sequence
            .is_none_or(|at| fields[at] == rows.len().to_string());
        if fields[1] != cell_row[1] || !in_order {
            let at = detail.sequence.unwrap_or(0);
            return Err(broken(
                n,
                format!(
                    "row of cell '{}' replicate {} is out of place (expected cell '{}' replicate {})",
                    fields[1],
                    fields[at],
                    cell_row[1],
                    rows.len()
                ),
            ));
        }
        rows.push(fields);
    }
    out.retain(|_, rows| detail.per_cell.is_none_or(|n| rows.len() == n));
    Ok(out)
}

/// The fields in which two configs differ, as `path: old -> new` (only
/// those), for a resume that does not match.
pub fn config_diff(old: &SweepConfig, new: &SweepConfig) -> Vec<String> {
    fn walk(path: &str, a: &serde_json::Value, b: &serde_json::Value, out: &mut Vec<String>) {
        use serde_json::Value::Object;
        match (a, b) {
            (Object(x), Object(y)) => {
                let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
                keys.sort();
                keys.dedup();
                let null = serde_json::Value::Null;
                for k in keys {
                    let p = if path.is_empty() {
                        k.clone()
                    } else {
                        format!("{path}.{k}")
                    };
                    walk(
                        &p,
                        x.get(k).unwrap_or(&null),
                        y.get(k).unwrap_or(&null),
                        out,
                    );
                }
            }
            _ if a != b => out.push(format!("{path}: {a} then, {b} now")),
            _ => {}
        }
    }
    let (Ok(a), Ok(b)) = (serde_json::to_value(old), serde_json::to_value(new)) else {
        return vec!["the inputs".into()];
    };
    let mut out = Vec::new();
    walk("", &a, &b, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_round_trip_and_nan_is_empty() {
        assert_eq!(fmt_f64(0.1), "0.1");
        assert_eq!(fmt_f64(f64::NAN), "");
        let x = 1.0 / 3.0;
        assert_eq!(fmt_f64(x).parse::<f64>().unwrap().to_bits(), x.to_bits());
    }

    #[test]
    fn a_resume_mismatch_names_only_what_differs() {
        let a = SweepConfig::default();
        let mut b = a.clone();
        b.schedule.trace_every = 10;
        b.defaults.kp = Some(30.0);
        let d = config_diff(&a, &b);
        assert_eq!(
            d,
            [
                "defaults.kp: null then, 30.0 now",
                "schedule.trace_every: 0 then, 10 now"
            ]
        );
        assert!(config_diff(&a, &a).is_empty());
    }
}
