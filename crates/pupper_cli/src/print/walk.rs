//! `pupper walk`'s table: a row per cell with the walk's own figures (with
//! replicates, their worst side over the drawn robots).

use std::fmt::Write;

use pupper_mujoco::api::SweepOutcome;

use super::{Sig, counts, edges, footer, short};

/// The columns shown (summary.csv's name, the heading), in this order.
const SHOWN: [(&str, &str); 11] = [
    ("speed_ms", "m/s"),
    ("speed_error_pct", "err %"),
    ("drift_ms", "drift m/s"),
    ("roll_rms_deg", "roll °"),
    ("pitch_rms_deg", "pitch °"),
    ("slip_mm_s", "slip mm/s"),
    ("amplitude_ratio", "amp"),
    ("lag_ms", "lag ms"),
    ("torque_rms", "τ rms"),
    ("cost_of_transport", "CoT"),
    ("saturation_frac", "sat"),
];

/// The table of a walk: each shown column as summary.csv has it, or with
/// replicates its worst-side statistic (and the share that fell).
pub(super) fn table(o: &SweepOutcome) -> String {
    let col = |name: &str| o.header.iter().position(|h| h == name);
    let replicated = col("failure_fraction").is_some();
    let metrics_at = col("final_z")
        .or_else(|| col("replicates"))
        .unwrap_or(o.header.len());
    let axes: Vec<usize> = (3..metrics_at).collect();
    let cols: Vec<(usize, String)> = SHOWN
        .iter()
        .filter_map(|(name, label)| match replicated {
            false => col(name).map(|i| (i, label.to_string())),
            true => col(&format!("p95:{name}")).map(|i| (i, format!("p95 {label}"))),
        })
        .collect();
    let last = if replicated { "failed" } else { "status" };
    let last_col = col(if replicated {
        "failure_fraction"
    } else {
        "status"
    });
    let mut s = String::new();
    let mut head = String::new();
    for &i in &axes {
        let _ = write!(head, "{:>8} ", o.header[i]);
    }
    for (_, label) in &cols {
        let _ = write!(head, "{label:>10} ");
    }
    let _ = write!(head, "{last:>10}");
    let _ = writeln!(s, "{}", head.trim_end());
    for r in &o.rows {
        let mut line = String::new();
        for &i in &axes {
            let _ = write!(line, "{:>8} ", short(&r[i]));
        }
        for (i, _) in &cols {
            let text = match r[*i].parse::<f64>() {
                Ok(v) if v.is_finite() => format!("{}", Sig(v)),
                _ => "-".into(),
            };
            let _ = write!(line, "{text:>10} ");
        }
        let _ = write!(line, "{:>10}", last_col.map_or("", |i| r[i].as_str()));
        let _ = writeln!(s, "{}", line.trim_end());
    }
    not_walking(&mut s, o, replicated);
    counts(&mut s, o);
    footer(&mut s, o);
    s
}

/// A pick this far off the commanded velocity (% of it) does not walk the
/// gait.
const NOT_WALKING: f64 = 50.0;

/// A line when the closest walker of the whole table is still far off the
/// commanded velocity (the gains carry the robot but do not walk), and one
/// when it lies on the edge of the searched grid: the pick is advice, and
/// a better one may lie beyond.
fn not_walking(s: &mut String, o: &SweepOutcome, replicated: bool) {
    let metric = match replicated {
        true => "p95:speed_error_pct",
        false => "speed_error_pct",
    };
    let rule = pupper_core::results::best::Rule::new(metric, &[]);
    let Some((i, c)) = pupper_core::results::best::best(&o.header, &o.rows, &rule)
        .ok()
        .and_then(|g| g.first().and_then(|g| g.best))
        .zip(o.header.iter().position(|h| h == metric))
    else {
        return;
    };
    let error: f64 = o.rows[i][c].parse().unwrap_or(f64::NAN);
    if error >= NOT_WALKING {
        let _ = writeln!(
            s,
            "no cell walks within {NOT_WALKING} % of the commanded velocity (the closest, {}, is {error:.0} % off): these gains carry the robot but do not walk this gait; try stiffer gains, another frequency or step height",
            o.rows[i][1]
        );
    }
    edges(s, o, i, "best-walking");
}
