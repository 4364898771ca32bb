//! What each experiment kind writes: a summary row per cell, and the
//! tables of rows per cell beside it (replicates.csv for a replicated
//! sweep; response.csv and bode.csv for a response run). The run
//! directory appends, resumes and merges them all the same way.

use crate::math::decimal::fmt_f64;
use crate::plan::config::SweepConfig;
use crate::plan::excitation::{Excitation, Signal};
use crate::results::output::{Detail, cell_columns, cell_fields};
use std::path::Path;

use crate::error::Result;
use crate::results::output::{
    Manifest, REPLICATES, Trace, group_metrics, groups, header_of, read_detail, read_manifest,
    read_rows, read_traces, replicate_row, replicates_header, robust_row, row,
};
use crate::sim::metrics::Status;
use crate::sim::response::{CHIRP_POINTS, JOINT_METRIC_NAMES, JointResult};
use crate::sim::runner::CellResult;

pub const RESPONSE: &str = "response.csv";
pub const BODE: &str = "bode.csv";
/// With `--trace`: each excited joint's angle after the hold (replicate 0).
pub const RESPONSE_TRACES: &str = "response_traces.csv";

/// The tables beside summary.csv, for a model of `nu` actuators.
pub fn details_of(config: &SweepConfig, nu: usize) -> Vec<Detail> {
    let reps = config.replicate_count();
    match &config.response {
        None if config.replicates.is_plain() => Vec::new(),
        None => {
            let header = replicates_header(config, nu);
            let sequence = header.iter().position(|h| h == "replicate");
            vec![Detail {
                file: REPLICATES,
                header,
                per_cell: Some(reps),
                sequence,
            }]
        }
        Some(e) => {
            let joints = e.joints.len();
            let mut out = vec![Detail {
                file: RESPONSE,
                header: response_header(config),
                per_cell: Some(joints * reps),
                sequence: None,
            }];
            if let Some(points) = bode_points(e) {
                let mut header: Vec<String> = ["index", "id", "joint", "replicate"]
                    .map(String::from)
                    .to_vec();
                header.extend(["hz", "gain_db", "phase_deg"].map(String::from));
                out.push(Detail {
                    file: BODE,
                    header,
                    per_cell: Some(joints * reps * points),
                    sequence: None,
                });
            }
            if config.schedule.trace_every > 0 {
                let header = ["index", "id", "joint", "t", "angle"]
                    .map(String::from)
                    .to_vec();
                out.push(Detail {
                    file: RESPONSE_TRACES,
                    header,
                    per_cell: None,
                    sequence: None,
                });
            }
            out
        }
    }
}

/// Frequencies per joint in bode.csv; None for a step.
fn bode_points(e: &Excitation) -> Option<usize> {
    match e.signal {
        Signal::Step { .. } => None,
        Signal::Sine { .. } => Some(1),
        Signal::Chirp { .. } => Some(CHIRP_POINTS),
    }
}

fn response_header(config: &SweepConfig) -> Vec<String> {
    let mut h = cell_columns(config);
    h.extend(["joint", "group", "replicate"].map(String::from));
    h.extend(JOINT_METRIC_NAMES.iter().map(|s| s.to_string()));
    h
}

/// The worst status of a set: diverged, then saturated, then ok.
fn worst(statuses: impl Iterator<Item = Status>) -> Status {
    let rank = |s: Status| match s {
        Status::Diverged => 3,
        Status::Fell => 2,
        Status::Saturated => 1,
        Status::Ok => 0,
    };
    statuses.max_by_key(|s| rank(*s)).unwrap_or(Status::Ok)
}

fn summary_of_response(e: &Excitation, r: &CellResult) -> Vec<String> {
    let mut out = cell_fields(&r.cell);
    for g in groups(e) {
        let of_group: Vec<&JointResult> = r
            .joints
            .iter()
            .filter(|j| e.group_of(j.actuator) == Some(g.as_str()))
            .collect();
        for m in group_metrics(e) {
            let at = JOINT_METRIC_NAMES.iter().position(|n| n == m).unwrap_or(0);
            let xs: Vec<f64> = of_group.iter().map(|j| j.metrics.values()[at]).collect();
            let v = match *m {
                "peak_torque" | "saturation_frac" => xs.iter().copied().fold(f64::NAN, f64::max),
                _ if xs.is_empty() => f64::NAN,
                // a joint without the figure (never settled) leaves it empty
                _ => xs.iter().sum::<f64>() / xs.len() as f64,
            };
            out.push(fmt_f64(v));
        }
        out.push(
            worst(of_group.iter().map(|j| j.metrics.status))
                .as_str()
                .into(),
        );
    }
    out.push(
        worst(r.joints.iter().map(|j| j.metrics.status))
            .as_str()
            .into(),
    );
    out
}

/// A finished cell's summary row.
pub fn summary_row(config: &SweepConfig, r: &CellResult) -> Vec<String> {
    match (&config.response, config.replicates.is_plain()) {
        (Some(e), _) => summary_of_response(e, r),
        (None, true) => row(&r.cell, &r.metrics),
        (None, false) => robust_row(
            &r.cell,
            &r.replicates.iter().map(|p| &p.metrics).collect::<Vec<_>>(),
        ),
    }
}

/// A finished cell's rows of each table of [`details_of`], in that order.
pub fn detail_rows(config: &SweepConfig, r: &CellResult) -> Vec<Vec<Vec<String>>> {
    match &config.response {
        None if config.replicates.is_plain() => Vec::new(),
        None => vec![
            r.replicates
                .iter()
                .enumerate()
                .map(|(k, p)| replicate_row(&r.cell, k, &p.drawn, &p.metrics))
                .collect(),
        ],
        Some(e) => {
            let name = |a: usize| e.name_of(a).to_string();
            let responses = r
                .joints
                .iter()
                .map(|j| {
                    let mut row = cell_fields(&r.cell);
                    row.push(name(j.actuator));
                    row.push(e.group_of(j.actuator).unwrap_or("").to_string());
                    row.push(j.replicate.to_string());
                    row.extend(j.metrics.values().iter().map(|v| fmt_f64(*v)));
                    row.push(j.metrics.status.as_str().into());
                    row
                })
                .collect();
            let mut out = vec![responses];
            let traces: Vec<Vec<String>> = r
                .joints
                .iter()
                .filter(|j| j.replicate == 0)
                .flat_map(|j| {
                    j.trace.iter().map(move |(t, q)| {
                        vec![
                            r.cell.index.to_string(),
                            r.cell.id.clone(),
                            name(j.actuator),
                            fmt_f64(*t),
                            fmt_f64(*q),
                        ]
                    })
                })
                .collect();
            if bode_points(e).is_some() {
                out.push(
                    r.joints
                        .iter()
                        .flat_map(|j| {
                            j.bode.iter().map(move |b| {
                                vec![
                                    r.cell.index.to_string(),
                                    r.cell.id.clone(),
                                    name(j.actuator),
                                    j.replicate.to_string(),
                                    fmt_f64(b.hz),
                                    fmt_f64(b.gain_db),
                                    fmt_f64(b.phase_deg),
                                ]
                            })
                        })
                        .collect(),
                );
            }
            if config.schedule.trace_every > 0 {
                out.push(traces);
            }
            out
        }
    }
}

/// A run directory read back (what Python's `load_run` returns).
#[derive(Debug, Clone)]
pub struct RunTables {
    pub manifest: Manifest,
    pub header: Vec<String>,
    /// summary.csv's rows in cell order.
    pub rows: Vec<Vec<String>>,
    /// (cell id, (t, z) samples) in cell order, for traced runs.
    pub traces: Vec<(String, Vec<(f64, f64)>)>,
    /// replicates.csv's header and rows (cell, then replicate order), for
    /// replicated runs.
    pub replicate_header: Vec<String>,
    pub replicate_rows: Vec<Vec<String>>,
    /// Every table beside summary.csv (replicates.csv too): file name,
    /// header, rows in cell order.
    pub details: Vec<(String, Vec<String>, Vec<Vec<String>>)>,
}

/// Reads a run directory, checking its rows against its manifest.
pub fn read_run(dir: &Path) -> Result<RunTables> {
    let manifest = read_manifest(dir)?;
    let mut rows = read_rows(dir, &manifest.config)?;
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
    let traced = manifest.config.schedule.trace_every > 0;
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
    let details: Vec<(String, Vec<String>, Vec<Vec<String>>)> = details
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
    let (replicate_header, replicate_rows) = details
        .iter()
        .find(|(f, _, _)| f == REPLICATES)
        .map(|(_, h, r)| (h.clone(), r.clone()))
        .unwrap_or_default();
    Ok(RunTables {
        replicate_header,
        replicate_rows,
        details,
        header: header_of(&manifest.config),
        rows: rows.into_values().collect(),
        traces,
        manifest,
    })
}
