//! The walk kind's tables: the stand kind's row per cell (height, tilt,
//! torque, saturation, status and when it fell) followed by the walk's own
//! figures; a replicated walk's summary has their mean and worst-side 95 %
//! point over the replicates that stayed up, and replicates.csv a row per
//! replicate with its figures.

use crate::math::decimal::fmt_f64;
use crate::plan::config::SweepConfig;
use crate::plan::stand::Stand;
use crate::plan::walk::Walk;
use crate::results::kinds::KindTables;
use crate::results::output::{Detail, STATISTICS};
use crate::sim::metrics::Status;
use crate::sim::result::CellResult;
use crate::sim::walk::{FIGURES, worse_low};

/// A figure's value as text (empty past the end of a short list).
fn text(figures: &[f64], i: usize) -> String {
    fmt_f64(figures.get(i).copied().unwrap_or(f64::NAN))
}

impl KindTables for Walk {
    fn summary_header(&self, config: &SweepConfig) -> Vec<String> {
        let mut h = Stand.summary_header(config);
        if config.replicates.is_plain() {
            h.extend(FIGURES.map(String::from));
        } else {
            h.extend(
                FIGURES
                    .iter()
                    .flat_map(|m| STATISTICS.map(|s| format!("{s}:{m}"))),
            );
        }
        h
    }

    /// The stand's replicates.csv, each row followed by the figures.
    fn details(&self, config: &SweepConfig, nu: usize) -> Vec<Detail> {
        let mut details = Stand.details(config, nu);
        for d in &mut details {
            d.header.extend(FIGURES.map(String::from));
        }
        details
    }

    fn summary_row(&self, config: &SweepConfig, r: &CellResult) -> Vec<String> {
        let mut out = Stand.summary_row(config, r);
        if config.replicates.is_plain() {
            out.extend((0..FIGURES.len()).map(|i| text(&r.figures, i)));
            return out;
        }
        // over the replicates that stayed up, as robust_row takes them
        let up: Vec<&[f64]> = r
            .replicates
            .iter()
            .filter(|p| p.metrics.status.stood() && p.metrics.status != Status::PastBound)
            .map(|p| &p.figures[..])
            .collect();
        for (i, name) in FIGURES.iter().enumerate() {
            let mut xs: Vec<f64> = up
                .iter()
                .map(|f| f.get(i).copied().unwrap_or(f64::NAN))
                .collect();
            if xs.is_empty() || xs.iter().any(|x| !x.is_finite()) {
                out.extend([String::new(), String::new()]);
                continue;
            }
            xs.sort_by(f64::total_cmp);
            let p = if worse_low(name) { 0.05 } else { 0.95 };
            out.push(fmt_f64(crate::math::stats::mean(&xs)));
            out.push(fmt_f64(crate::math::stats::percentile(&xs, p)));
        }
        out
    }

    fn detail_rows(&self, config: &SweepConfig, r: &CellResult) -> Vec<Vec<Vec<String>>> {
        let mut tables = Stand.detail_rows(config, r);
        for rows in &mut tables {
            for (out, p) in rows.iter_mut().zip(&r.replicates) {
                out.extend((0..FIGURES.len()).map(|i| text(&p.figures, i)));
            }
        }
        tables
    }
}
