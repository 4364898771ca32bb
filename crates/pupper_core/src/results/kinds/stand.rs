//! The stand kind's tables: a row of metrics per cell, or for a
//! replicated run their statistics over the replicates in summary.csv and
//! a row per replicate in replicates.csv.

use crate::plan::config::SweepConfig;
use crate::plan::stand::Stand;
use crate::results::kinds::KindTables;
use crate::results::output::{
    Detail, REPLICATES, STATISTICS, aggregated, axis_names, header, replicate_row,
    replicates_header, robust_row, row,
};
use crate::sim::result::CellResult;

impl KindTables for Stand {
    fn summary_header(&self, config: &SweepConfig) -> Vec<String> {
        if config.replicates.is_plain() {
            return header(&axis_names(config));
        }
        let mut h: Vec<String> = ["index", "id", "name"].map(String::from).to_vec();
        h.extend(axis_names(config));
        h.extend(["replicates", "failure_fraction"].map(String::from));
        for m in aggregated() {
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
        let header = replicates_header(config, nu);
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
            return row(&r.cell, &r.metrics);
        }
        robust_row(
            &r.cell,
            &r.replicates.iter().map(|p| &p.metrics).collect::<Vec<_>>(),
        )
    }

    fn detail_rows(&self, config: &SweepConfig, r: &CellResult) -> Vec<Vec<Vec<String>>> {
        if config.replicates.is_plain() {
            return Vec::new();
        }
        vec![
            r.replicates
                .iter()
                .enumerate()
                .map(|(k, p)| replicate_row(&r.cell, k, &p.drawn, &p.metrics))
                .collect(),
        ]
    }
}
