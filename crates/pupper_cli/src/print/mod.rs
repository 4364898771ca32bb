//! Text and JSON for the terminal.

mod figures;
mod gains;
mod hold;
mod model;
mod response;
mod stand;
mod walk;

pub use gains::gains;
pub use model::{doctor, info, pose, stand};

use std::fmt::Write;

use pupper_core::{Error, Result};
use pupper_mujoco::api::SweepOutcome;
use serde::Serialize;

pub fn json<T: Serialize>(v: &T) -> Result<String> {
    // ±inf as "inf" and "-inf" (serde_json's null would lose the sign)
    let v = pupper_core::results::json::to_value(v)?;
    serde_json::to_string_pretty(&v).map_err(|e| Error::Internal(format!("json: {e}")))
}

/// An axis value in at most 8 characters: as written when it fits, else
/// with 4 significant digits (summary.csv keeps every digit).
pub(crate) fn short(text: &str) -> String {
    match text.parse::<f64>() {
        Ok(v) if text.len() > 8 => {
            let digits = (3 - v.abs().log10().floor() as i32).clamp(0, 6) as usize;
            let t = format!("{v:.digits$}");
            let t = if t.contains('.') {
                t.trim_end_matches('0').trim_end_matches('.').to_string()
            } else {
                t
            };
            if t.len() <= 8 { t } else { format!("{v:.2e}") }
        }
        _ => text.to_string(),
    }
}

/// The registry: a finished run's table as its experiment kind prints it.
pub fn run_table(o: &SweepOutcome, e: &pupper_core::plan::experiment::Experiment) -> String {
    use pupper_core::plan::experiment::Experiment;
    match e {
        Experiment::Stand => stand::table(o),
        Experiment::Response(_) => response::table(o),
        Experiment::Hold(_) => hold::table(o, e.plan().default_metric()),
        Experiment::Walk(_) => walk::table(o),
    }
}

/// Where column `name` is in a run's table.
pub(crate) fn col(o: &SweepOutcome, name: &str) -> Option<usize> {
    o.header.iter().position(|h| h == name)
}

/// The axes on whose edge the picked row `best` lies: its value there is
/// the largest or smallest searched, so the best may lie beyond.
pub(crate) fn edges(s: &mut String, o: &SweepOutcome, best: usize, word: &str) {
    let end = o
        .header
        .iter()
        .position(|h| h == "final_z")
        .unwrap_or(o.header.len());
    // only a product grid has edges: named cells one by one (a preset)
    // are no range
    let distinct = |c: usize| {
        let mut v: Vec<&str> = o.rows.iter().map(|r| r[c].as_str()).collect();
        v.sort_unstable();
        v.dedup();
        v.len()
    };
    if (3..end).map(distinct).product::<usize>() != o.rows.len() {
        return;
    }
    let mut said = Vec::new();
    for c in 3..end {
        let values: Vec<f64> = o.rows.iter().filter_map(|r| r[c].parse().ok()).collect();
        let Ok(v) = o.rows[best][c].parse::<f64>() else {
            continue;
        };
        let (lo, hi) = values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        if lo == hi {
            continue;
        }
        if v == hi {
            said.push(format!("{} {}, the largest", o.header[c], o.rows[best][c]));
        } else if v == lo {
            said.push(format!("{} {}, the smallest", o.header[c], o.rows[best][c]));
        }
    }
    if !said.is_empty() {
        let _ = writeln!(
            s,
            "the {word} cell lies on the edge of the searched range ({}): the best may lie beyond it; widen the grid there",
            said.join("; ")
        );
    }
}

/// How many cells fell, saturated or had replicates that fell.
pub(crate) fn counts(s: &mut String, o: &SweepOutcome) {
    let col = |name: &str| col(o, name);
    let bad = o
        .rows
        .iter()
        .filter(|r| col("status").is_some_and(|i| r[i] == "fell" || r[i] == "diverged"))
        .count();
    let saturated = o
        .rows
        .iter()
        .filter(|r| col("status").is_some_and(|i| r[i] == "saturated"))
        .count();
    let shaky = o
        .rows
        .iter()
        .filter(|r| col("failure_fraction").is_some_and(|i| r[i] != "0"))
        .count();
    if shaky > 0 {
        let _ = writeln!(
            s,
            "{shaky} cell(s) had replicates that fell, diverged or lay past the stability bound: see failure_fraction, and replicates.csv"
        );
    }
    if saturated > 0 {
        let _ = writeln!(
            s,
            "{saturated} cell(s) saturated: at the torque limit in {}% or more of actuator-steps (sat %), so never the steadiest",
            pupper_core::sim::metrics::SATURATED * 100.0
        );
    }
    let past = o
        .rows
        .iter()
        .filter(|r| col("status").is_some_and(|i| r[i] == "past_bound"))
        .count();
    if past > 0 {
        let _ = writeln!(
            s,
            "{past} cell(s) past_bound: past the stability bound of the PD at the timestep, so never the steadiest"
        );
    }
    if bad > 0 {
        let _ = writeln!(
            s,
            "{bad} cell(s) fell or diverged: see the status and event_time columns"
        );
    }
}

/// How many cells ran and where the table went.
pub(crate) fn footer(s: &mut String, o: &SweepOutcome) {
    match &o.out {
        Some(d) if o.cells_run == 0 => {
            let _ = writeln!(
                s,
                "nothing left to run: {} holds all {} cells",
                d.display(),
                o.rows.len()
            );
        }
        Some(d) => {
            let _ = writeln!(
                s,
                "{} cells in {:.2} s (mujoco {}); wrote {}/summary.csv",
                o.cells_run,
                o.wall_seconds,
                o.mujoco_version,
                d.display()
            );
        }
        None => {}
    }
}

/// The summary rows as JSON objects, numbers as numbers.
pub fn rows_json(o: &SweepOutcome) -> serde_json::Value {
    let rows: Vec<serde_json::Value> = o.rows.iter().map(|r| row_json(&o.header, r)).collect();
    serde_json::json!({
        "out": o.out,
        "complete": o.complete,
        "cells": rows,
    })
}

/// A summary row as a JSON object: numbers as numbers, an empty field
/// (a metric not measured) as null, text (ids, names, body names, status)
/// as strings.
fn row_json(header: &[String], r: &[String]) -> serde_json::Value {
    let mut m = serde_json::Map::new();
    for (h, v) in header.iter().zip(r) {
        let val = match (h.as_str(), v.parse::<f64>()) {
            ("id" | "name" | "status", _) => serde_json::Value::String(v.clone()),
            ("index", _) => v
                .parse::<u64>()
                .map_or(serde_json::Value::Null, |i| serde_json::json!(i)),
            (_, Ok(x)) if x.is_finite() => serde_json::json!(x),
            _ if v.is_empty() => serde_json::Value::Null,
            _ => serde_json::Value::String(v.clone()),
        };
        m.insert(h.clone(), val);
    }
    serde_json::Value::Object(m)
}

/// The best cell of each group as JSON: the group's key, the rule, how
/// many cells were eligible or tied, and the best row (null when none).
pub fn best_json(
    o: &SweepOutcome,
    rule: &pupper_core::results::best::Rule,
    groups: &[pupper_core::results::best::Group],
) -> serde_json::Value {
    let groups: Vec<serde_json::Value> = groups
        .iter()
        .map(|g| {
            let key: serde_json::Map<String, serde_json::Value> = g
                .key
                .iter()
                .map(|(k, v)| (k.clone(), serde_json::Value::String(v.clone())))
                .collect();
            serde_json::json!({
                "group": key,
                "cells": g.cells,
                "eligible": g.eligible,
                "tied": g.tied,
                "tie_break": g.tie_break,
                "cell": g.best.map(|i| row_json(&o.header, &o.rows[i])),
            })
        })
        .collect();
    serde_json::json!({
        "metric": rule.metric,
        "by": rule.by,
        "max_saturation": rule.max_saturation,
        "groups": groups,
    })
}

/// One line per group of `--best-by`.
pub fn best(
    o: &SweepOutcome,
    rule: &pupper_core::results::best::Rule,
    groups: &[pupper_core::results::best::Group],
) -> String {
    let col = |name: &str| o.header.iter().position(|h| h == name);
    let metric = col(&rule.metric);
    let mut s = match rule.by.is_empty() {
        true => format!("\nbest {}:\n", rule.metric),
        false => format!("\nbest {} by {}:\n", rule.metric, rule.by.join(", ")),
    };
    for g in groups {
        let key: Vec<String> = g.key.iter().map(|(k, v)| format!("{k}={v}")).collect();
        let key = if key.is_empty() {
            "all".to_string()
        } else {
            key.join(" ")
        };
        match (g.best, metric) {
            (Some(i), Some(m)) => {
                let r = &o.rows[i];
                let v: f64 = r[m].parse().unwrap_or(f64::NAN);
                let _ = writeln!(
                    s,
                    "  {key:<24} {:<28} {} {v:.4}  ({} of {} cells eligible)",
                    r[1], rule.metric, g.eligible, g.cells
                );
            }
            _ => {
                let _ = writeln!(
                    s,
                    "  {key:<24} no eligible cell: all {} fell, diverged, saturated, lie past the stability bound or have no {}",
                    g.cells, rule.metric
                );
            }
        }
    }
    s
}

/// `pupper lab`: a line per body, its steadiest gains.
pub fn lab(
    o: &SweepOutcome,
    rule: &pupper_core::results::best::Rule,
    groups: &[pupper_core::results::best::Group],
) -> String {
    let col = |name: &str| o.header.iter().position(|h| h == name);
    let (kp, kd, std) = (col("kp"), col("kd"), col(&rule.metric));
    let z = col("final_z").or_else(|| col("mean:final_z"));
    let label = match rule.metric.as_str() {
        "last_1s_std_mm" => "z_std".to_string(),
        m => m.to_string(),
    };
    let unit = if rule.metric.ends_with("_mm") {
        " mm"
    } else {
        ""
    };
    let num = |r: &[String], c: Option<usize>| -> f64 {
        c.and_then(|c| r[c].parse().ok()).unwrap_or(f64::NAN)
    };
    let mut s = String::new();
    for g in groups {
        let body = g.key.first().map_or("all", |(_, v)| v.as_str());
        match g.best {
            Some(i) => {
                let r = &o.rows[i];
                let _ = writeln!(
                    s,
                    "{body:<9} Kp={:<5} Kd={:<4} {label}={:.2}{unit}  z={:.3} m",
                    format!("{}", num(r, kp)),
                    format!("{}", num(r, kd)),
                    num(r, std),
                    num(r, z)
                );
            }
            None => {
                let _ = writeln!(
                    s,
                    "{body:<9} no gains kept it standing (all {} cells fell, diverged, saturated or lie past the stability bound)",
                    g.cells
                );
            }
        }
    }
    s
}

/// A number to 3 significant digits, as a table shows it.
pub(crate) struct Sig(pub(crate) f64);

impl std::fmt::Display for Sig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = self.0;
        if v == 0.0 || !v.is_finite() {
            return write!(f, "{v}");
        }
        // past a million, digits say nothing a reader can use
        if v.abs() < 1e-3 || v.abs() >= 1e6 {
            return write!(f, "{v:.2e}");
        }
        let digits = (2 - v.abs().log10().floor() as i32).clamp(0, 6) as usize;
        write!(f, "{v:.digits$}")
    }
}

#[cfg(test)]
mod tests {
    use super::short;

    #[test]
    fn axis_values_fit_their_column() {
        assert_eq!(short("30"), "30");
        assert_eq!(short("long-leg"), "long-leg");
        assert_eq!(short("1.779527559055118"), "1.78");
        assert_eq!(short("99.22047244094489"), "99.22");
        assert_eq!(short("0.000123456789"), "0.000123");
        assert!(short("123456789.5").len() <= 9);
    }
}
