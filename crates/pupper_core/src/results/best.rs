//! The best cell of each group of a sweep's table, by one documented rule:
//!
//! 1. A cell is eligible when it stood (status `ok`, or `saturated` under a
//!    raised bound), the metric is a number, and its `saturation_frac` (the
//!    share of actuator-steps at the torque limit) is below the threshold.
//!    In a replicated sweep: no replicate fell or diverged
//!    (`failure_fraction` 0), and `p95:saturation_frac` is below it.
//! 2. Among the eligible cells of a group, the lowest metric wins (the
//!    highest with `minimize = false`).
//! 3. Cells within [`TIE_MM`] of the winner on a `*_mm` metric (exactly
//!    equal on others) are tied: the smallest push dip among them wins
//!    (the same statistic of it in a replicated sweep), when the table has
//!    one, some tied cell has a dip (a run with a push) and the metric is
//!    not the dip itself; otherwise the lowest metric stands.
//! 4. Remaining ties go to the cell that comes first in grid order.
//!
//! Groups are the distinct values of the `by` columns, in order of first
//! appearance; without `by` the whole table is one group.

use crate::error::{Error, Result};
use crate::results::output::{STATISTICS, aggregated};
use crate::sim::metrics::METRIC_NAMES;

/// The default saturation threshold: cells whose actuators sit at their
/// torque limit in 5 % or more of the steps are not trusted as "best".
pub const MAX_SATURATION: f64 = crate::sim::metrics::SATURATED;
/// Cells whose `*_mm` metric lies within this many mm of the group's best
/// are tied (nanometres of last-second std are no difference): the smaller
/// push dip decides, then grid order.
pub const TIE_MM: f64 = 0.001;

/// The metric a standing run ranks by unless told (the stand kind's).
pub use crate::plan::kind::DEFAULT_METRIC;

/// The statistic a replicated run ranks `metric` by: its worst-side 95th
/// percentile over the replicates.
pub fn robust(metric: &str) -> String {
    format!("p95:{metric}")
}

/// A group's eligible cells: (row index, metric value), in grid order.
type Eligible = Vec<(usize, f64)>;

/// How to pick.
#[derive(Debug, Clone, PartialEq)]
pub struct Rule {
    pub metric: String,
    pub by: Vec<String>,
    pub max_saturation: f64,
    pub minimize: bool,
}

impl Rule {
    pub fn new(metric: &str, by: &[String]) -> Rule {
        Rule {
            metric: metric.to_string(),
            by: by.to_vec(),
            max_saturation: MAX_SATURATION,
            minimize: true,
        }
    }
}

/// One group and its winner.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// (column, value as in summary.csv) of the `by` columns.
    pub key: Vec<(String, String)>,
    /// Row index (into the table given) of the best cell; None when no cell
    /// of the group is eligible.
    pub best: Option<usize>,
    /// Cells in the group, and how many were eligible.
    pub cells: usize,
    pub eligible: usize,
    /// Eligible cells tied with the best on the metric (1: none).
    pub tied: usize,
    /// The column that broke the tie, when one did.
    pub tie_break: Option<String>,
}

fn column(header: &[String], name: &str) -> Option<usize> {
    header.iter().position(|h| h == name)
}

/// Where a table's figures start, after its cell columns and axes: the
/// stand metrics, a replicated run's count, or a response's first figure
/// of a joint group.
fn first_figure(header: &[String]) -> usize {
    column(header, METRIC_NAMES[0])
        .or_else(|| column(header, "replicates"))
        .or_else(|| {
            header.iter().position(|h| {
                h.split_once('.')
                    .is_some_and(|(m, _)| crate::sim::joints::JOINT_METRIC_NAMES.contains(&m))
            })
        })
        .unwrap_or(header.len())
}

/// What is wrong with `x` as a saturation threshold, a share of
/// actuator-steps in (0, 1] (a 5 for 5 % is the usual slip, and over 1
/// would exclude nothing), or None.
pub fn saturation_problem(x: f64) -> Option<String> {
    match x.is_finite() && x > 0.0 && x <= 1.0 {
        true => None,
        false => Some(format!(
            "must lie in (0, 1]: a share of actuator-steps, e.g. {MAX_SATURATION} for {} %",
            MAX_SATURATION * 100.0
        )),
    }
}

/// `x` if it is a saturation threshold ([`saturation_problem`]).
pub fn check_max_saturation(x: f64) -> Result<f64> {
    match saturation_problem(x) {
        None => Ok(x),
        Some(p) => Err(Error::Config(format!("--max-saturation {x} {p}"))),
    }
}

/// The best cell of each group of `rows` (summary.csv's rows as text).
pub fn best(header: &[String], rows: &[Vec<String>], rule: &Rule) -> Result<Vec<Group>> {
    let replicated = column(header, "failure_fraction").is_some();
    let metric = metric_column(header, rule, replicated)?;
    let by = by_columns(header, rule)?;
    check_max_saturation(rule.max_saturation)?;
    let (status, failures, saturation) = judged_by(header, rule);
    let (tolerance, dip) = ties(header, rule);
    let number = |r: &Vec<String>, c: usize| r[c].parse::<f64>().unwrap_or(f64::NAN);
    // each group's eligible cells, in grid order
    let mut groups: Vec<(Vec<String>, Group, Eligible)> = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        let key: Vec<String> = by.iter().map(|&c| r[c].clone()).collect();
        let at = match groups.iter().position(|(k, _, _)| *k == key) {
            Some(at) => at,
            None => {
                let g = Group {
                    key: rule.by.iter().cloned().zip(key.iter().cloned()).collect(),
                    best: None,
                    cells: 0,
                    eligible: 0,
                    tied: 0,
                    tie_break: None,
                };
                groups.push((key, g, Vec::new()));
                groups.len() - 1
            }
        };
        let (_, g, eligible) = &mut groups[at];
        g.cells += 1;
        let v = number(r, metric);
        let sat: f64 = saturation.map_or(0.0, |c| number(r, c));
        let stood = match (status, failures) {
            (Some(c), _) => r[c] == "ok" || r[c] == "saturated",
            (None, Some(c)) => r[c].parse::<f64>() == Ok(0.0),
            (None, None) => false,
        };
        if stood && v.is_finite() && sat < rule.max_saturation {
            eligible.push((i, v));
        }
    }
    let sense = if rule.minimize { 1.0 } else { -1.0 };
    let decide = Decide {
        header,
        rows,
        metric,
        sense,
        tolerance,
        dip,
    };
    Ok(groups
        .into_iter()
        .map(|(_, g, eligible)| decide.group(g, &eligible, &number))
        .collect())
}

/// The columns a cell is judged by for `rule`: its status, its replicates'
/// failures, its saturation (of the metric's joint group, if it has one).
fn judged_by(header: &[String], rule: &Rule) -> (Option<usize>, Option<usize>, Option<usize>) {
    // a figure of one joint group (a response's `rise_time_s.kfe`) is
    // judged by that group's status and saturation
    let group = rule
        .metric
        .split_once('.')
        .map(|(_, g)| g)
        .filter(|g| column(header, &format!("status.{g}")).is_some());
    let status = match group {
        Some(g) => column(header, &format!("status.{g}")),
        None => column(header, "status"),
    };
    let failures = column(header, "failure_fraction");
    let saturation = match group {
        Some(g) => column(header, &format!("saturation_frac.{g}")),
        None => column(header, "saturation_frac").or_else(|| column(header, "p95:saturation_frac")),
    };
    (status, failures, saturation)
}

/// What counts as a tie for `rule` (mm for a metric in mm) and the column
/// that breaks it: the push dip of the same statistic.
fn ties(header: &[String], rule: &Rule) -> (f64, Option<usize>) {
    let tolerance = if rule.metric.ends_with("_mm") {
        TIE_MM
    } else {
        0.0
    };
    // the dip of the same statistic breaks ties
    let (stat, name) = match rule.metric.split_once(':') {
        Some((s, m)) => (format!("{s}:"), m),
        None => (String::new(), rule.metric.as_str()),
    };
    let dip = (name != "push_dip_mm")
        .then(|| column(header, &format!("{stat}push_dip_mm")))
        .flatten();
    (tolerance, dip)
}

/// The column `rule` ranks by: a numeric column of the table (a
/// statistic over replicates in a replicated one), else a one-line error
/// listing them.
fn metric_column(header: &[String], rule: &Rule, replicated: bool) -> Result<usize> {
    let numeric: Vec<String> = if replicated {
        // the metrics' statistics, then a kind's own figures' (a walk's)
        let stat = |h: &String| STATISTICS.iter().any(|s| h.starts_with(&format!("{s}:")));
        aggregated()
            .flat_map(|m| STATISTICS.iter().map(move |s| format!("{s}:{m}")))
            .chain(header.iter().filter(|h| stat(h)).cloned())
            .fold(Vec::new(), |mut v, m| {
                if !v.contains(&m) {
                    v.push(m);
                }
                v
            })
    } else {
        // status is text; when a cell fell is no quality to rank by. A
        // kind's own figures follow the metrics (a hold's sag, torques; a
        // response's figures per joint group)
        METRIC_NAMES
            .iter()
            .map(|m| m.to_string())
            .chain(header[first_figure(header)..].iter().cloned())
            .filter(|m| !matches!(m.as_str(), "status" | "event_time") && !m.starts_with("status."))
            .fold(Vec::new(), |mut v, m| {
                if !v.contains(&m) {
                    v.push(m);
                }
                v
            })
    };
    column(header, &rule.metric)
        .filter(|_| numeric.contains(&rule.metric))
        .ok_or_else(|| {
            let hint = match (replicated, rule.metric.contains(':')) {
                (false, true) => {
                    " (mean: and p95: statistics need replicates: add --replicates or --randomize)"
                }
                (true, false) => " (a replicated sweep ranks by a statistic over replicates)",
                _ => "",
            };
            let shown: Vec<&str> = numeric.iter().map(String::as_str).collect();
            Error::Config(format!(
                "unknown metric '{}'{hint}: use one of {}",
                rule.metric,
                shown.join(", ")
            ))
        })
}

/// The columns of `rule.by`: axes of the grid, else a one-line error.
fn by_columns(header: &[String], rule: &Rule) -> Result<Vec<usize>> {
    let first_metric = first_figure(header);
    let axes = &header[3.min(first_metric)..first_metric];
    rule.by
        .iter()
        .map(|b| {
            axes.iter()
                .position(|a| a == b)
                .map(|i| i + 3)
                .ok_or_else(|| {
                    Error::Config(format!(
                        "cannot group by '{b}': it is not an axis of this grid; use one of {}",
                        if axes.is_empty() {
                            "(none: the grid has no axes)".to_string()
                        } else {
                            axes.join(", ")
                        }
                    ))
                })
        })
        .collect::<Result<Vec<usize>>>()
}

/// What decides a group's winner among its eligible cells.
struct Decide<'a> {
    header: &'a [String],
    rows: &'a [Vec<String>],
    metric: usize,
    /// 1 to minimize, -1 to maximize.
    sense: f64,
    tolerance: f64,
    dip: Option<usize>,
}

impl Decide<'_> {
    /// The winner of `g` among its `eligible` (row, value) pairs.
    fn group(
        &self,
        mut g: Group,
        eligible: &[(usize, f64)],
        number: &dyn Fn(&Vec<String>, usize) -> f64,
    ) -> Group {
        let (rows, sense) = (self.rows, self.sense);
        g.eligible = eligible.len();
        let Some(top) = eligible
            .iter()
            .map(|&(_, v)| sense * v)
            .min_by(f64::total_cmp)
        else {
            return g;
        };
        let tied: Vec<usize> = eligible
            .iter()
            .filter(|&&(_, v)| sense * v <= top + self.tolerance)
            .map(|&(i, _)| i)
            .collect();
        g.tied = tied.len();
        // the lowest metric (grid order on equal values) ...
        let value = |i: usize| sense * number(&rows[i], self.metric);
        g.best = tied
            .iter()
            .copied()
            .min_by(|&a, &b| value(a).total_cmp(&value(b)).then(a.cmp(&b)));
        // ... unless the dip tells the tied cells apart: the smallest
        // dip wins (a cell without one last)
        let with_dip = self
            .dip
            .filter(|&d| tied.len() > 1 && tied.iter().any(|&i| number(&rows[i], d).is_finite()));
        if let Some(d) = with_dip {
            let key = |i: usize| {
                let v = number(&rows[i], d);
                if v.is_nan() { f64::INFINITY } else { v }
            };
            g.best = tied
                .iter()
                .copied()
                .min_by(|&a, &b| key(a).total_cmp(&key(b)).then(a.cmp(&b)));
            g.tie_break = Some(self.header[d].clone());
        }
        g
    }
}

/// `best.csv`: per group, its `by` values, how many cells it has and how
/// many were eligible, then the best cell's summary row (empty when none).
pub fn table(
    header: &[String],
    rows: &[Vec<String>],
    rule: &Rule,
    groups: &[Group],
) -> (Vec<String>, Vec<Vec<String>>) {
    let mut h: Vec<String> = rule.by.clone();
    h.extend(["cells", "eligible"].map(String::from));
    h.extend(header.iter().cloned());
    let out = groups
        .iter()
        .map(|g| {
            let mut r: Vec<String> = g.key.iter().map(|(_, v)| v.clone()).collect();
            r.push(g.cells.to_string());
            r.push(g.eligible.to_string());
            match g.best {
                Some(i) => r.extend(rows[i].iter().cloned()),
                None => r.extend(header.iter().map(|_| String::new())),
            }
            r
        })
        .collect();
    (h, out)
}

#[cfg(test)]
mod tests {
    /// A replicated table: eligibility is "no replicate failed" and
    /// p95:saturation_frac under the bound.
    #[test]
    fn replicated_cells_are_ranked_by_a_statistic() {
        let mut header: Vec<String> = [
            "index",
            "id",
            "name",
            "kp",
            "replicates",
            "failure_fraction",
        ]
        .map(String::from)
        .to_vec();
        for m in aggregated() {
            for st in STATISTICS {
                header.push(format!("{st}:{m}"));
            }
        }
        let col = |n: &str| header.iter().position(|h| h == n).unwrap();
        let row = |i: usize, failed: &str, p95: &str, sat: &str| {
            let mut r = vec![String::new(); header.len()];
            r[0] = i.to_string();
            r[1] = format!("kp{i}");
            r[3] = i.to_string();
            r[4] = "8".into();
            r[5] = failed.into();
            r[col("p95:last_1s_std_mm")] = p95.into();
            r[col("mean:last_1s_std_mm")] = "0.5".into();
            r[col("p95:saturation_frac")] = sat.into();
            r
        };
        let rows = vec![
            row(0, "0.125", "0.1", "0"), // lowest, but one replicate fell
            row(1, "0", "0.3", "0.2"),   // saturated
            row(2, "0", "0.4", "0"),
            row(3, "0", "0.2", "0.01"),
        ];
        let g = best(&header, &rows, &Rule::new("p95:last_1s_std_mm", &[])).unwrap();
        assert_eq!((g[0].best, g[0].eligible), (Some(3), 2));
        // the mean ranks too (all equal: the first eligible cell wins)
        let g = best(&header, &rows, &Rule::new("mean:last_1s_std_mm", &[])).unwrap();
        assert_eq!(g[0].best, Some(2));
        let e = best(&header, &rows, &Rule::new("last_1s_std_mm", &[]))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("statistic over replicates") && e.contains("p95:last_1s_std_mm"),
            "{e}"
        );
        let plain: Vec<String> = ["index", "id", "name", "kp"]
            .iter()
            .map(|s| s.to_string())
            .chain(METRIC_NAMES.iter().map(|s| s.to_string()))
            .collect();
        let e = best(&plain, &[], &Rule::new("p95:last_1s_std_mm", &[]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("--replicates"), "{e}");
    }

    use super::*;

    #[test]
    fn a_saturation_threshold_is_a_share_of_steps() {
        for ok in [MAX_SATURATION, 1.0, 1e-9] {
            assert_eq!(check_max_saturation(ok).unwrap(), ok);
        }
        for bad in [0.0, -0.5, 1.5, 5.0, f64::NAN, f64::INFINITY] {
            let e = check_max_saturation(bad).unwrap_err().to_string();
            assert!(e.contains("must lie in (0, 1]"), "{e}");
        }
    }
    use crate::results::output::header;

    fn table(rows: &[(&str, &str, &str, &str, &str)]) -> (Vec<String>, Vec<Vec<String>>) {
        // (kp, kd, std, saturation, status)
        let h = header(&["kp".to_string(), "kd".to_string()]);
        let rows = rows
            .iter()
            .enumerate()
            .map(|(i, (kp, kd, std, sat, status))| {
                let mut r = vec![i.to_string(), format!("c{i}"), String::new()];
                r.push(kp.to_string());
                r.push(kd.to_string());
                for m in METRIC_NAMES {
                    r.push(match m {
                        "last_1s_std_mm" => std.to_string(),
                        "saturation_frac" => sat.to_string(),
                        "status" => status.to_string(),
                        _ => "0.1".to_string(),
                    });
                }
                r
            })
            .collect();
        (h, rows)
    }

    #[test]
    fn best_of_each_group_with_ties_nans_and_a_fallen_group() {
        let (h, rows) = table(&[
            ("10", "1", "0.5", "0", "ok"),
            ("30", "1", "0.2", "0", "ok"),
            ("60", "1", "0.2", "0", "ok"), // ties with kp 30: the first wins
            ("120", "1", "0.01", "0.2", "ok"), // saturated: not eligible
            ("10", "2", "", "0", "ok"),    // NaN: not eligible
            ("30", "2", "0.001", "0", "fell"), // fell: not eligible
            ("60", "2", "0.3", "0", "ok"),
            ("10", "5", "0.1", "0", "diverged"),
            ("30", "5", "0.1", "0", "fell"),
        ]);
        let g = best(&h, &rows, &Rule::new("last_1s_std_mm", &["kd".into()])).unwrap();
        assert_eq!(g.len(), 3);
        assert_eq!(g[0].key, vec![("kd".to_string(), "1".to_string())]);
        assert_eq!((g[0].best, g[0].cells, g[0].eligible), (Some(1), 4, 3));
        assert_eq!((g[1].best, g[1].eligible), (Some(6), 1));
        assert_eq!((g[2].best, g[2].cells, g[2].eligible), (None, 2, 0));
        // one group; a looser threshold lets the saturated cell win
        let all = best(&h, &rows, &Rule::new("last_1s_std_mm", &[])).unwrap();
        assert_eq!(all[0].best, Some(1));
        let loose = Rule {
            max_saturation: 0.5,
            ..Rule::new("last_1s_std_mm", &[])
        };
        assert_eq!(best(&h, &rows, &loose).unwrap()[0].best, Some(3));
        let highest = Rule {
            minimize: false,
            ..Rule::new("last_1s_std_mm", &["kd".into()])
        };
        assert_eq!(best(&h, &rows, &highest).unwrap()[0].best, Some(0));
    }

    #[test]
    fn nanometres_are_a_tie_the_smaller_dip_decides() {
        let (h, mut rows) = table(&[
            ("60", "1", "0.0000094", "0", "ok"),
            ("120", "1", "0.0000057", "0", "ok"), // lowest by 4 nm
            ("120", "2", "0.0004", "0", "ok"),    // within 1 um: tied
            ("120", "5", "0.002", "0.7", "saturated"),
            ("30", "1", "0.0015", "0", "ok"), // 1.5 um: not tied
        ]);
        let dip = h.iter().position(|c| c == "push_dip_mm").unwrap();
        for (r, d) in rows.iter_mut().zip(["1.16", "0.99", "0.94", "0.5", "0.2"]) {
            r[dip] = d.into();
        }
        let g = best(&h, &rows, &Rule::new("last_1s_std_mm", &[])).unwrap();
        assert_eq!((g[0].best, g[0].tied, g[0].eligible), (Some(2), 3, 4));
        assert_eq!(g[0].tie_break.as_deref(), Some("push_dip_mm"));
        // ranked by the dip itself: no tolerance, no tie-break
        let by_dip = best(&h, &rows, &Rule::new("push_dip_mm", &[])).unwrap();
        assert_eq!((by_dip[0].best, by_dip[0].tied), (Some(4), 1));
        assert_eq!(by_dip[0].tie_break, None);
        // a saturated cell is eligible only under a raised bound
        let loose = Rule {
            max_saturation: 0.8,
            ..Rule::new("push_dip_mm", &[])
        };
        let g = best(&h, &rows, &loose).unwrap();
        assert_eq!((g[0].best, g[0].eligible), (Some(4), 5));
        // without a push (no dip anywhere) the lowest metric stands
        for r in rows.iter_mut() {
            r[dip] = String::new();
        }
        let g = best(&h, &rows, &Rule::new("last_1s_std_mm", &[])).unwrap();
        assert_eq!(
            (g[0].best, g[0].tied, g[0].tie_break.clone()),
            (Some(1), 3, None)
        );
        // exactly equal values on a metric without a tolerance: grid order
        let (h, rows) = table(&[("10", "1", "0.5", "0", "ok"), ("30", "1", "0.5", "0", "ok")]);
        let g = best(&h, &rows, &Rule::new("final_z", &[])).unwrap();
        assert_eq!((g[0].best, g[0].tied), (Some(0), 2));
    }

    #[test]
    fn a_joint_groups_figure_ranks_by_that_groups_status() {
        let header: Vec<String> = [
            "index",
            "id",
            "name",
            "kp",
            "rise_time_s.kfe",
            "saturation_frac.kfe",
            "status.kfe",
            "status",
        ]
        .map(String::from)
        .to_vec();
        let rows: Vec<Vec<String>> = [
            ["0", "kp60", "", "60", "0.05", "0", "past_bound", "-"],
            ["1", "kp20", "", "20", "0.1", "0", "ok", "saturated"],
            ["2", "kp5", "", "5", "0.2", "0", "ok", "ok"],
        ]
        .iter()
        .map(|r| r.map(String::from).to_vec())
        .collect();
        let g = best(&header, &rows, &Rule::new("rise_time_s.kfe", &[])).unwrap();
        assert_eq!((g[0].best, g[0].eligible), (Some(1), 2));
        let by = best(
            &header,
            &rows,
            &Rule::new("rise_time_s.kfe", &["kp".into()]),
        )
        .unwrap();
        assert_eq!(by.len(), 3);
        let err = best(&header, &rows, &Rule::new("nope", &[])).unwrap_err();
        assert!(err.to_string().contains("rise_time_s.kfe"), "{err}");
    }

    #[test]
    fn bad_metric_or_column_is_named() {
        let (h, rows) = table(&[("10", "1", "0.5", "0", "ok")]);
        let e = best(&h, &rows, &Rule::new("status", &[])).unwrap_err();
        assert!(e.to_string().contains("unknown metric 'status'"), "{e}");
        let e = best(&h, &rows, &Rule::new("final_z", &["leg_scale".into()])).unwrap_err();
        assert!(e.to_string().contains("use one of kp, kd"), "{e}");
    }
}
