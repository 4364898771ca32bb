//! The walk kind's tables: the stand kind's row per cell (height, tilt,
//! torque, saturation, status and when it fell) followed by the walk's own
//! figures; a replicated walk's summary has their mean and worst-side 95 %
//! point over the replicates that stayed up, and replicates.csv a row per
//! replicate with its figures.

use crate::math::decimal::fmt_f64;
use crate::plan::config::SweepConfig;
use crate::plan::walk::Walk;
use crate::results::kinds::KindTables;
use crate::results::output::{
    Detail, REPLICATES, STATISTICS, aggregated, axis_names, header, replicate_row,
    replicates_header, robust_row, row,
};
use crate::sim::metrics::Status;
use crate::sim::result::CellResult;
use crate::sim::walk::{FIGURES, worse_low};

/// A figure's value as text (empty past the end of a short list).
fn text(figures: &[f64], i: usize) -> String {
    fmt_f64(figures.get(i).copied().unwrap_or(f64::NAN))
}

impl KindTables for Walk {
    fn summary_header(&self, config: &SweepConfig) -> Vec<String> {
        if config.replicates.is_plain() {
            let mut h = header(&axis_names(config));
            h.extend(FIGURES.map(String::from));
            return h;
        }
        let mut h: Vec<String> = ["index", "id", "name"].map(String::from).to_vec();
        h.extend(axis_names(config));
        h.extend(["replicates", "failure_fraction"].map(String::from));
        for m in aggregated().chain(FIGURES) {
            for s in STATISTICS {
                h.push(format!("{s}:{m}"));
            }
        }
        h
    }

    fn details(&self, config: &SweepConfig, nu: usize) -> Vec<Detail> {
        if config.replicates.is_plain() {
            return Vec::new();
        }
        let mut header = replicates_header(config, nu);
        header.extend(FIGURES.map(String::from));
        let sequence = header.iter().position(|h| h == "replicate");
        vec![Detail {
            file: REPLICATES,
            header,
            per_cell: Some(config.replicate_count()),
            sequence,
        }]
    }

    fn summary_row(&self, config: &SweepConfig, r: &CellResult) -> Vec<String> {
        if config.replicates.is_plain() {
            let mut out = row(&r.cell, &r.metrics);
            out.extend((0..FIGURES.len()).map(|i| text(&r.figures, i)));
            return out;
        }
        let mut out = robust_row(
            &r.cell,
            &r.replicates.iter().map(|p| &p.metrics).collect::<Vec<_>>(),
        );
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
        if config.replicates.is_plain() {
            return Vec::new();
        }
        vec![
            r.replicates
                .iter()
                .enumerate()
                .map(|(k, p)| {
                    let mut out = replicate_row(&r.cell, k, &p.drawn, &p.metrics);
                    out.extend((0..FIGURES.len()).map(|i| text(&p.figures, i)));
                    out
                })
                .collect(),
        ]
    }
}
