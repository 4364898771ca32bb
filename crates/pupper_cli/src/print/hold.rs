//! `pupper hold`'s table: a row per cell with the hold's own figures.

use pupper_mujoco::api::SweepOutcome;

use super::figures::{Figures, best_row};
use super::{counts, edges, footer};

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
    let mut s = Figures {
        axes,
        cols,
        width: 12,
        last: ("status", col("status")),
    }
    .rows(o);
    // the stiffest cell on the edge of the searched gains says so
    if let Some(i) = best_row(o, metric) {
        edges(&mut s, o, i, "stiffest");
    }
    counts(&mut s, o);
    footer(&mut s, o);
    s
}
