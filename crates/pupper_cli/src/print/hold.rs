//! `pupper hold`'s table: a row per cell with the hold's own figures.

use std::fmt::Write;

use pupper_mujoco::api::SweepOutcome;

use super::{Sig, counts, edges, footer, short};

/// The columns shown, by prefix, in this order (the torque and copper
/// columns are the model's own joint groups).
const SHOWN: [(&str, &str); 6] = [
    ("sag_mm", "sag mm"),
    ("compliance_mm_per_n", "mm/N"),
    ("sway_mm", "sway mm"),
    ("recovery_s", "recovery s"),
    ("torque_rms.", "rms N·m "),
    ("copper_w", "copper W"),
];

/// The table, and the line of the stiffest cell (by `metric`, the kind's
/// own) when it lies on the edge of the searched gains.
pub(super) fn table(o: &SweepOutcome, metric: &str) -> String {
    let col = |name: &str| o.header.iter().position(|h| h == name);
    let metrics_at = col("final_z").unwrap_or(o.header.len());
    let axes: Vec<usize> = (3..metrics_at).collect();
    let mut cols: Vec<(usize, String)> = Vec::new();
    for (prefix, label) in SHOWN {
        for (i, h) in o.header.iter().enumerate() {
            if let Some(rest) = h.strip_prefix(prefix)
                && (rest.is_empty() || prefix.ends_with('.'))
            {
                cols.push((i, format!("{label}{rest}")));
            }
        }
    }
    let status = col("status");
    let mut s = String::new();
    let mut head = String::new();
    for &i in &axes {
        let _ = write!(head, "{:>8} ", o.header[i]);
    }
    for (_, label) in &cols {
        let _ = write!(head, "{label:>12} ");
    }
    let _ = write!(head, "{:>10}", "status");
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
            let _ = write!(line, "{text:>12} ");
        }
        let _ = write!(line, "{:>10}", status.map_or("", |i| r[i].as_str()));
        let _ = writeln!(s, "{}", line.trim_end());
    }
    // the stiffest cell on the edge of the searched gains says so
    let rule = pupper_core::results::best::Rule::new(metric, &[]);
    if let Some(i) = pupper_core::results::best::best(&o.header, &o.rows, &rule)
        .ok()
        .and_then(|g| g.first().and_then(|g| g.best))
    {
        let mut edge = String::new();
        edges(&mut edge, o, i, "stiffest");
        s.push_str(&edge);
    }
    counts(&mut s, o);
    footer(&mut s, o);
    s
}
