//! `pupper response`'s table: one per joint group, a row per cell.

use std::fmt::Write;

use pupper_mujoco::api::SweepOutcome;

use super::{Sig, short};

/// Below this an overshoot (%) is the integrator's rounding, not a robot's
/// (report.html draws it as 0 too).
const OVERSHOOT_NOISE_PCT: f64 = 1e-6;

/// A response run's summary: a table per joint group, a row per cell.
pub(super) fn table(o: &SweepOutcome) -> String {
    let status_at = o.header.iter().position(|h| h == "status");
    // axis columns come before the first "<metric>.<group>" column
    let first = o
        .header
        .iter()
        .position(|h| h.contains('.'))
        .unwrap_or(o.header.len());
    let axes: Vec<(usize, &String)> = o.header.iter().enumerate().take(first).skip(3).collect();
    let mut groups: Vec<&str> = Vec::new();
    for h in &o.header[first..] {
        if let Some((_, g)) = h.split_once('.')
            && !groups.contains(&g)
        {
            groups.push(g);
        }
    }
    let mut s = String::new();
    for (k, g) in groups.into_iter().enumerate() {
        if k > 0 {
            s.push('\n');
        }
        let cols: Vec<(usize, &str)> = o
            .header
            .iter()
            .enumerate()
            .filter_map(|(i, h)| h.strip_suffix(&format!(".{g}")).map(|m| (i, m)))
            .filter(|(_, m)| *m != "status")
            .collect();
        let status_of = o
            .header
            .iter()
            .position(|h| *h == format!("status.{g}"))
            .or(status_at);
        let _ = writeln!(s, "{}", group_title(g));
        let mut head = String::new();
        for (_, a) in &axes {
            let _ = write!(head, "{:>8} ", a);
        }
        for (_, m) in &cols {
            let _ = write!(head, "{:>16} ", m);
        }
        let _ = write!(head, "{:>10}", "status");
        let _ = writeln!(s, "{}", head.trim_end());
        for r in &o.rows {
            let mut line = String::new();
            for (i, _) in &axes {
                let _ = write!(line, "{:>8} ", short(&r[*i]));
            }
            for (i, m) in &cols {
                let text = match r[*i].parse::<f64>() {
                    // an overshoot below the simulation's resolution is none
                    Ok(v) if *m == "overshoot_pct" && v.abs() < OVERSHOOT_NOISE_PCT => "0".into(),
                    Ok(v) => format!("{}", Sig(v)),
                    Err(_) => "-".into(),
                };
                let _ = write!(line, "{:>16} ", text);
            }
            let _ = write!(line, "{:>10}", status_of.map_or("", |i| r[i].as_str()));
            let _ = writeln!(s, "{}", line.trim_end());
        }
    }
    s
}

fn group_title(g: &str) -> String {
    match g {
        "haa" => "haa (hip abduction/adduction)".into(),
        "hfe" => "hfe (hip flexion/extension)".into(),
        "kfe" => "kfe (knee flexion/extension)".into(),
        other => other.to_string(),
    }
}
