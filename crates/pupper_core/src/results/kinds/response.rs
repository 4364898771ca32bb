//! The response kind's tables: summary.csv per joint group, response.csv
//! per cell and joint, bode.csv for a sine or chirp, and each joint's
//! angle after the hold with `--trace`.

use crate::math::decimal::fmt_f64;
use crate::plan::config::SweepConfig;
use crate::plan::response::{Excitation, Signal};
use crate::results::kinds::KindTables;
use crate::results::output::{Detail, cell_columns, cell_fields};
use crate::sim::metrics::Status;
use crate::sim::response::{CHIRP_POINTS, JOINT_METRIC_NAMES, JointResult};
use crate::sim::result::CellResult;

pub const RESPONSE: &str = "response.csv";
pub const BODE: &str = "bode.csv";
/// With `--trace`: each excited joint's angle after the hold (replicate 0).
pub const RESPONSE_TRACES: &str = "response_traces.csv";

impl KindTables for Excitation {
    /// Per joint group, each figure (mean over the group's joints; the
    /// largest for torque and saturation) and the group's status.
    fn summary_header(&self, config: &SweepConfig) -> Vec<String> {
        let e = self;
        let mut h = cell_columns(config);
        for g in groups(e) {
            for m in group_metrics(e) {
                h.push(format!("{m}.{g}"));
            }
            h.push(format!("status.{g}"));
        }
        h.push("status".into());
        h
    }

    fn details(&self, config: &SweepConfig, _nu: usize) -> Vec<Detail> {
        let (e, reps) = (self, config.replicate_count());

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

    fn summary_row(&self, _config: &SweepConfig, r: &CellResult) -> Vec<String> {
        summary_of_response(self, r)
    }

    fn detail_rows(&self, config: &SweepConfig, r: &CellResult) -> Vec<Vec<Vec<String>>> {
        let e = self;

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

    /// The joints' angles go to response_traces.csv; the base hangs.
    fn traces_base_z(&self) -> bool {
        false
    }
}

/// The figures a response run's summary shows per joint group.
pub fn group_metrics(e: &Excitation) -> &'static [&'static str] {
    match e.signal {
        Signal::Step { .. } => &[
            "rise_time_s",
            "settling_time_s",
            "overshoot_pct",
            "ss_error_pct",
            "peak_torque",
            "saturation_frac",
        ],
        Signal::Sine { .. } => &["gain_db", "phase_deg", "peak_torque", "saturation_frac"],
        Signal::Chirp { .. } => &[
            "bandwidth_hz",
            "phase_at_bw_deg",
            "resonance_db",
            "peak_torque",
            "saturation_frac",
        ],
    }
}

/// The joint groups of a response run, in a leg's order.
pub fn groups(e: &Excitation) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for g in &e.groups {
        if !out.contains(g) {
            out.push(g.clone());
        }
    }
    // a leg's order (abduction, hip, knee), then any other
    let rank = |g: &String| {
        crate::robot::model::JOINT_GROUPS
            .iter()
            .position(|x| x == g)
            .unwrap_or(usize::MAX)
    };
    out.sort_by_key(rank);
    out
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

/// The worst status of a set: diverged, fell, past the bound, saturated, ok.
fn worst(statuses: impl Iterator<Item = Status>) -> Status {
    let rank = |s: Status| match s {
        Status::Diverged => 4,
        Status::Fell => 3,
        Status::PastBound => 2,
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
