//! The stand kind's table: `pupper sweep` and the lab print a row per
//! cell, then the steadiest cell (over the replicates too, when there are
//! any), the counts and where the table went.

use std::fmt::Write;

use pupper_mujoco::api::SweepOutcome;

use super::{col, counts, edges, footer, short};

/// A column of the table: (summary.csv name, header, width, decimals).
type Column = (&'static str, &'static str, usize, usize);

/// The table's columns, a row per metric: its column in a sweep's table,
/// then those of the statistics over it in a replicated sweep's (in that
/// order: each kind of table reads its own down this list).
const SHOWN: [(Option<Column>, &[Column]); 10] = [
    (None, &[("failure_fraction", "fail %", 6, 0)]),
    (
        Some(("final_z", "final z m", 9, 3)),
        &[("mean:final_z", "z m", 6, 3)],
    ),
    (
        Some(("last_1s_std_mm", "std mm", 7, 2)),
        &[
            ("mean:last_1s_std_mm", "std mm", 7, 3),
            ("p95:last_1s_std_mm", "p95 std", 7, 3),
        ],
    ),
    (
        Some(("push_dip_mm", "dip mm", 7, 2)),
        &[("p95:push_dip_mm", "p95 dip", 7, 2)],
    ),
    (Some(("settle_time_s", "settle s", 8, 2)), &[]),
    (
        Some(("max_tilt_deg", "tilt °", 7, 2)),
        &[("p95:max_tilt_deg", "p95 tilt", 8, 2)],
    ),
    (
        Some(("peak_torque", "peak N·m", 8, 2)),
        &[("p95:peak_torque", "p95 N·m", 7, 2)],
    ),
    (
        Some(("saturation_frac", "sat %", 6, 1)),
        &[("p95:saturation_frac", "p95 sat%", 8, 1)],
    ),
    (Some(("tracking_rms", "track rad", 9, 4)), &[]),
    (Some(("status", "status", 8, 0)), &[]),
];

/// The stand kind's table (`pupper sweep`, the lab): a row per cell, the
/// steadiest cell, the counts, where it went.
pub(super) fn table(o: &SweepOutcome) -> String {
    let replicated = col(o, "failure_fraction").is_some();
    let mut s = rows(o, replicated);
    steadiest(&mut s, o);
    if replicated {
        steadiest_robust(&mut s, o);
    }
    counts(&mut s, o);
    footer(&mut s, o);
    s
}

/// A sweep's rows as a table: the case, the axes, the metrics shown.
fn rows(o: &SweepOutcome, replicated: bool) -> String {
    let col = |name: &str| col(o, name);
    let shown: Vec<Column> = if replicated {
        SHOWN
            .iter()
            .flat_map(|(_, stats)| stats.iter().copied())
            .collect()
    } else {
        SHOWN.iter().filter_map(|(plain, _)| *plain).collect()
    };
    let metrics_at = col("final_z")
        .or_else(|| col("replicates"))
        .unwrap_or(o.header.len());
    let axes: Vec<(usize, &String)> = o
        .header
        .iter()
        .enumerate()
        .take(metrics_at)
        .skip(3)
        .collect();
    let named = o.rows.iter().any(|r| !r[2].is_empty());
    let mut s = String::new();
    let mut head = String::new();
    if named {
        let _ = write!(head, "{:<8} ", "case");
    }
    for (_, a) in &axes {
        let _ = write!(head, "{:>8} ", a);
    }
    for &(_, h, w, _) in &shown {
        let _ = write!(head, "{:>w$} ", h);
    }
    let _ = writeln!(s, "{}", head.trim_end());
    for r in &o.rows {
        let mut line = String::new();
        if named {
            let _ = write!(line, "{:<8} ", r[2]);
        }
        for (i, _) in &axes {
            let _ = write!(line, "{:>8} ", short(&r[*i]));
        }
        for &(name, _, w, d) in &shown {
            let text = col(name).map(|i| r[i].as_str()).unwrap_or("");
            let shown = match text.parse::<f64>() {
                Ok(v) if name.ends_with("saturation_frac") || name == "failure_fraction" => {
                    format!("{:.d$}", v * 100.0)
                }
                Ok(v) => format!("{v:.d$}"),
                Err(_) if text.is_empty() => "-".into(),
                Err(_) => text.to_string(),
            };
            let _ = write!(line, "{shown:>w$} ");
        }
        let _ = writeln!(s, "{}", line.trim_end());
    }
    s
}

/// The steadiest cell's line, when the table has the columns it needs.
fn steadiest(s: &mut String, o: &SweepOutcome) {
    let col = |name: &str| col(o, name);
    // the steadiest cell by the --best-by rule (it stood, under 5 %
    // saturation; nanometres are a tie the smaller dip breaks)
    if let (Some(si), Some(_)) = (col("last_1s_std_mm"), col("status")) {
        let rule = pupper_core::results::best::Rule::new("last_1s_std_mm", &[]);
        let group = pupper_core::results::best::best(&o.header, &o.rows, &rule)
            .ok()
            .and_then(|g| g.into_iter().next());
        if let Some((i, g)) = group.and_then(|g| g.best.map(|i| (i, g))) {
            let r = &o.rows[i];
            let label = if r[2].is_empty() {
                r[1].clone()
            } else {
                format!("{} ({})", r[2], r[1])
            };
            let v: f64 = r[si].parse().unwrap_or(f64::NAN);
            let _ = write!(s, "\nsteadiest: {label}, last-1s std {v:.4} mm");
            match (&g.tie_break, col("push_dip_mm")) {
                (Some(_), Some(di)) => {
                    let _ = writeln!(
                        s,
                        " ({} cells within {} mm of the lowest std: the smallest push dip, {} mm, decides)",
                        g.tied,
                        pupper_core::results::best::TIE_MM,
                        r[di]
                            .parse::<f64>()
                            .map_or("-".into(), |d| format!("{d:.2}"))
                    );
                }
                _ if g.tied > 1 => {
                    let _ = writeln!(
                        s,
                        " ({} cells within {} mm of the lowest std: the first in grid order)",
                        g.tied,
                        pupper_core::results::best::TIE_MM
                    );
                }
                _ => {
                    let _ = writeln!(s);
                }
            }
            edges(s, o, i, "steadiest");
        }
    }
}

/// The steadiest cell over the replicates (the `--best-by` rule on the whole
/// table), and how the nominal ranking would have differed.
fn steadiest_robust(s: &mut String, o: &SweepOutcome) {
    let rule = pupper_core::results::best::Rule::new("p95:last_1s_std_mm", &[]);
    let Ok(groups) = pupper_core::results::best::best(&o.header, &o.rows, &rule) else {
        return;
    };
    let col = |name: &str| o.header.iter().position(|h| h == name);
    let num = |r: &[String], c: &str| -> f64 {
        col(c).and_then(|i| r[i].parse().ok()).unwrap_or(f64::NAN)
    };
    match groups.first().and_then(|g| g.best) {
        Some(i) => {
            let r = &o.rows[i];
            let _ = writeln!(
                s,
                "\nsteadiest over {} replicates (none fell, p95 saturation < 5%): {}, last-1s std p95 {:.4} mm, mean {:.4} mm",
                r[col("replicates").unwrap_or(0)],
                r[1],
                num(r, "p95:last_1s_std_mm"),
                num(r, "mean:last_1s_std_mm")
            );
        }
        None => {
            let _ = writeln!(
                s,
                "\nno cell kept every replicate standing below 5% saturation"
            );
        }
    }
}
