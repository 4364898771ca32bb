//! The table a kind with its own figures prints (hold, walk): the grid's
//! axes, the kind's columns, then one text column (a status, or the share
//! of robots that fell).

use std::fmt::Write;

use pupper_mujoco::api::SweepOutcome;

use super::{Sig, short};

/// One table's layout: which summary.csv columns, under which headings,
/// how wide, and the text column that closes each row.
pub(super) struct Figures<'a> {
    /// The grid's axes (summary.csv's columns), each 8 wide.
    pub axes: Vec<usize>,
    /// The kind's figures: (summary.csv's column, heading).
    pub cols: Vec<(usize, String)>,
    /// The width of each figure's column.
    pub width: usize,
    /// The closing column: its heading, and summary.csv's column.
    pub last: (&'a str, Option<usize>),
}

impl Figures<'_> {
    /// The heading and a row per cell; a figure that is not a finite
    /// number shows as `-`.
    pub fn rows(&self, o: &SweepOutcome) -> String {
        let w = self.width;
        let mut s = String::new();
        let mut head = String::new();
        for &i in &self.axes {
            let _ = write!(head, "{:>8} ", o.header[i]);
        }
        for (_, label) in &self.cols {
            let _ = write!(head, "{label:>w$} ");
        }
        let _ = write!(head, "{:>10}", self.last.0);
        let _ = writeln!(s, "{}", head.trim_end());
        for r in &o.rows {
            let mut line = String::new();
            for &i in &self.axes {
                let _ = write!(line, "{:>8} ", short(&r[i]));
            }
            for (i, _) in &self.cols {
                let text = match r[*i].parse::<f64>() {
                    Ok(v) if v.is_finite() => format!("{}", Sig(v)),
                    _ => "-".into(),
                };
                let _ = write!(line, "{text:>w$} ");
            }
            let _ = write!(line, "{:>10}", self.last.1.map_or("", |i| r[i].as_str()));
            let _ = writeln!(s, "{}", line.trim_end());
        }
        s
    }
}

/// The row that ranks best by `metric` (the run's own rule), if any.
pub(super) fn best_row(o: &SweepOutcome, metric: &str) -> Option<usize> {
    let rule = pupper_core::results::best::Rule::new(metric, &[]);
    pupper_core::results::best::best(&o.header, &o.rows, &rule)
        .ok()
        .and_then(|g| g.first().and_then(|g| g.best))
}
