//! The hold kind's tables: the stand kind's row per cell (its height,
//! tilt, the shove's dip and settling, status) followed by the hold's own
//! figures (sag, compliance, sway, the torque each joint group spends, the
//! copper loss where the model declares its motors).

use crate::math::decimal::fmt_f64;
use crate::plan::config::SweepConfig;
use crate::plan::hold::Load;
use crate::results::kinds::KindTables;
use crate::results::output::{Detail, axis_names, header, row};
use crate::sim::hold::figure_names;
use crate::sim::result::CellResult;

impl KindTables for Load {
    fn summary_header(&self, config: &SweepConfig) -> Vec<String> {
        let mut h = header(&axis_names(config));
        h.extend(figure_names(self));
        h
    }

    fn details(&self, _config: &SweepConfig, _nu: usize) -> Vec<Detail> {
        Vec::new()
    }

    fn summary_row(&self, _config: &SweepConfig, r: &CellResult) -> Vec<String> {
        let mut out = row(&r.cell, &r.metrics);
        let n = figure_names(self).len();
        out.extend((0..n).map(|i| fmt_f64(r.figures.get(i).copied().unwrap_or(f64::NAN))));
        out
    }

    fn detail_rows(&self, _config: &SweepConfig, _r: &CellResult) -> Vec<Vec<Vec<String>>> {
        Vec::new()
    }
}
