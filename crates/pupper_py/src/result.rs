//! `SweepResult`: a sweep's table as Python objects. Numeric columns are
//! numpy float64 arrays (NaN where summary.csv has an empty field), `index`
//! is int64, `id`/`name`/`status` are lists of str; traces are numpy too.

use std::path::Path;

use numpy::PyArray1;
use pyo3::exceptions::{PyIndexError, PyKeyError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::error::{ConfigError, InternalError, to_py};
use pupper_core::results::best;
use pupper_core::results::output::Trace;
use pupper_core::results::tables::NamedTable;
use pupper_core::sim::metrics::METRIC_NAMES;

/// Columns of text in summary.csv.
const TEXT: [&str; 6] = ["id", "name", "status", "variant", "joint", "group"];

/// True for a text column: those above, and a response run's per-group
/// status (`status.hfe`).
fn is_text(name: &str) -> bool {
    TEXT.contains(&name) || name.starts_with("status.")
}

/// Where a table's axis columns end: its first column that is not an axis.
fn axes_end(header: &[String]) -> usize {
    header
        .iter()
        .position(|h| {
            h == METRIC_NAMES[0]
                || ["replicates", "replicate", "joint", "status"].contains(&h.as_str())
                // a response run's per-group figures, e.g. rise_time_s.hfe
                || h.contains('.')
        })
        .unwrap_or(header.len())
}

/// Per-cell metrics of a sweep: the rows of its summary.csv, as numpy columns.
///
/// `res["kp"]` is a column; `res.table` maps every column to its array;
/// `res.traces` maps a cell id to its (t, z) arrays when traces were kept.
#[pyclass(module = "pupper_core", name = "SweepResult", frozen)]
pub struct SweepResult {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
    columns: Py<PyDict>,
    /// Cell id -> (t, z) numpy arrays.
    #[pyo3(get)]
    traces: Py<PyDict>,
    /// The run directory, or None when nothing was written.
    #[pyo3(get)]
    out: Py<PyAny>,
    /// False when the sweep was interrupted before every cell ran.
    #[pyo3(get)]
    complete: bool,
    /// Seconds the sweep took (for a run read back from disk, as its
    /// manifest says).
    #[pyo3(get)]
    wall_seconds: f64,
    /// The inputs that decide the numbers, as stored in manifest.json.
    #[pyo3(get)]
    config: Py<PyAny>,
    /// replicates.csv as a SweepResult (a row per cell and replicate, with
    /// the drawn values and its metrics); None for a sweep without
    /// replicates.
    #[pyo3(get)]
    replicates: Option<Py<SweepResult>>,
    /// Every table beside summary.csv by name ("replicates"; a response
    /// run's "response" and "bode"), each a SweepResult.
    #[pyo3(get)]
    tables: Py<PyDict>,
    /// The tables as text, for pickling: file name, header, rows.
    detail_text: Vec<NamedTable>,
    /// The experiment kind's metric, what `best()` ranks by unless told.
    metric: &'static str,
    /// Cell-steps each row's cell took when it ran in this call (None for
    /// a row read back or kept by a resume).
    #[pyo3(get)]
    cell_steps: Vec<Option<u64>>,
}

/// What a result is made from.
pub struct Parts<'a> {
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
    pub traces: &'a [Trace],
    pub out: Option<&'a Path>,
    pub complete: bool,
    pub wall_seconds: f64,
    pub config: &'a pupper_core::plan::config::SweepConfig,
    /// Every table beside summary.csv: file name, header, rows.
    pub tables: Vec<NamedTable>,
    /// Cell-steps per row, when the cells ran in this call.
    pub cell_steps: Vec<Option<u64>>,
}

fn number(text: &str) -> f64 {
    // written by fmt_f64: shortest round-trip text, empty for NaN
    text.parse().unwrap_or(f64::NAN)
}

impl SweepResult {
    pub fn new(py: Python<'_>, p: Parts<'_>) -> PyResult<SweepResult> {
        let columns = PyDict::new(py);
        for (i, name) in p.header.iter().enumerate() {
            let values = p.rows.iter().map(|r| r[i].as_str());
            if is_text(name) {
                columns.set_item(name, PyList::new(py, values)?)?;
            } else if name == "index" {
                let v: Vec<i64> = values.map(|s| s.parse().unwrap_or(-1)).collect();
                columns.set_item(name, PyArray1::from_vec(py, v))?;
            } else {
                let v: Vec<f64> = values.map(number).collect();
                columns.set_item(name, PyArray1::from_vec(py, v))?;
            }
        }
        let traces = PyDict::new(py);
        for (id, samples) in p.traces {
            let t: Vec<f64> = samples.iter().map(|s| s.0).collect();
            let z: Vec<f64> = samples.iter().map(|s| s.1).collect();
            traces.set_item(id, (PyArray1::from_vec(py, t), PyArray1::from_vec(py, z)))?;
        }
        let out = match p.out {
            Some(dir) => PyModule::import(py, "pathlib")?
                .getattr("Path")?
                .call1((dir,))?
                .unbind(),
            None => py.None(),
        };
        let config_text =
            serde_json::to_string(p.config).map_err(|e| InternalError::new_err(e.to_string()))?;
        let config = PyModule::import(py, "json")?
            .getattr("loads")?
            .call1((config_text,))?
            .unbind();
        let tables = PyDict::new(py);
        let mut replicates = None;
        for (file, header, rows) in &p.tables {
            if header.is_empty() {
                continue;
            }
            let table = Py::new(
                py,
                SweepResult::new(
                    py,
                    Parts {
                        header: header.clone(),
                        rows: rows.clone(),
                        traces: &[],
                        out: p.out,
                        complete: p.complete,
                        wall_seconds: p.wall_seconds,
                        config: p.config,
                        tables: Vec::new(),
                        cell_steps: Vec::new(),
                    },
                )?,
            )?;
            let stem = file.trim_end_matches(".csv");
            if stem == "replicates" {
                replicates = Some(table.clone_ref(py));
            }
            tables.set_item(stem, table)?;
        }
        Ok(SweepResult {
            replicates,
            tables: tables.unbind(),
            detail_text: p.tables,
            cell_steps: p.cell_steps,
            header: p.header,
            rows: p.rows,
            columns: columns.unbind(),
            traces: traces.unbind(),
            out,
            complete: p.complete,
            wall_seconds: p.wall_seconds,
            metric: p.config.experiment.plan().default_metric(),
            config,
        })
    }

    /// What a result is made from, as plain values (for pickling): its
    /// table as text, traces as lists, where it was written, its inputs.
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("header", self.header.clone())?;
        d.set_item("rows", self.rows.clone())?;
        let traces = PyDict::new(py);
        for (id, tz) in self.traces.bind(py).iter() {
            let (t, z): (Bound<'py, PyAny>, Bound<'py, PyAny>) = tz.extract()?;
            let t: Vec<f64> = t.call_method0("tolist")?.extract()?;
            let z: Vec<f64> = z.call_method0("tolist")?.extract()?;
            traces.set_item(id, (t, z))?;
        }
        d.set_item("traces", traces)?;
        let out = self.out.bind(py);
        d.set_item(
            "out",
            if out.is_none() {
                None
            } else {
                Some(out.str()?.to_string())
            },
        )?;
        d.set_item("complete", self.complete)?;
        d.set_item("wall_seconds", self.wall_seconds)?;
        let text: String = PyModule::import(py, "json")?
            .getattr("dumps")?
            .call1((self.config.bind(py),))?
            .extract()?;
        d.set_item("config", text)?;
        d.set_item("tables", self.detail_text.clone())?;
        d.set_item("cell_steps", self.cell_steps.clone())?;
        Ok(d)
    }

    fn column<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        self.columns.bind(py).get_item(name)?.ok_or_else(|| {
            PyKeyError::new_err(format!(
                "no column '{name}'; columns are {}",
                self.header.join(", ")
            ))
        })
    }

    fn value<'py>(&self, py: Python<'py>, row: usize, col: usize) -> PyResult<Bound<'py, PyAny>> {
        let text = &self.rows[row][col];
        let name = self.header[col].as_str();
        Ok(if is_text(name) {
            text.into_pyobject(py)?.into_any()
        } else if name == "index" {
            text.parse::<i64>()
                .unwrap_or(-1)
                .into_pyobject(py)?
                .into_any()
        } else {
            number(text).into_pyobject(py)?.into_any()
        })
    }
}

#[pymethods]
impl SweepResult {
    /// Every column by name (a new dict; the arrays are shared).
    #[getter]
    fn table<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.columns.bind(py).copy()
    }

    /// summary.csv's columns, in order.
    #[getter]
    fn header(&self) -> Vec<String> {
        self.header.clone()
    }

    /// summary.csv's rows as text, in cell order.
    #[getter]
    fn rows(&self) -> Vec<Vec<String>> {
        self.rows.clone()
    }

    /// The grid's axis columns, in grid order.
    #[getter]
    fn axes(&self) -> Vec<String> {
        let end = axes_end(&self.header);
        self.header[3.min(end)..end].to_vec()
    }

    /// Cell ids, in cell order.
    #[getter]
    fn ids(&self) -> Vec<String> {
        self.rows.iter().map(|r| r[1].clone()).collect()
    }

    fn __len__(&self) -> usize {
        self.rows.len()
    }

    fn __getitem__<'py>(&self, py: Python<'py>, column: &str) -> PyResult<Bound<'py, PyAny>> {
        self.column(py, column)
    }

    /// Pickling (a result crosses to worker processes, or is saved): the
    /// table, traces and inputs; rebuilt by `_result_from_state`.
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyDict>,))> {
        let rebuild = PyModule::import(py, "pupper_core._native")?.getattr("_result_from_state")?;
        Ok((rebuild, (self.state(py)?,)))
    }

    /// `"kp" in res`: whether the table has that column.
    fn __contains__(&self, column: &str) -> bool {
        self.header.iter().any(|h| h == column)
    }

    /// `for row in res`: each row as a dict of typed values (as `row(i)`).
    fn __iter__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyIterator>> {
        let rows = (0..self.rows.len() as isize)
            .map(|i| self.row(py, i))
            .collect::<PyResult<Vec<_>>>()?;
        pyo3::types::PyList::new(py, rows)?.try_iter()
    }

    /// The table as HTML, for notebooks: every column, the first 100 rows,
    /// a status other than ok in its own colour.
    fn _repr_html_(&self, py: Python<'_>) -> PyResult<String> {
        let esc = |s: &str| {
            s.replace('&', "&amp;")
                .replace('<', "&lt;")
                .replace('>', "&gt;")
                .replace('"', "&quot;")
        };
        let shown: Vec<usize> = (0..self.header.len())
            .filter(|&c| !(self.header[c] == "name" && self.rows.iter().all(|r| r[c].is_empty())))
            .collect();
        let status = self.header.iter().position(|h| h == "status");
        let format = PyModule::import(py, "builtins")?.getattr("format")?;
        let mut html = String::from("<table class=\"pupper-sweep\"><thead><tr>");
        for &c in &shown {
            html.push_str(&format!("<th>{}</th>", esc(&self.header[c])));
        }
        html.push_str("</tr></thead><tbody>");
        for r in 0..self.rows.len().min(100) {
            let colour = match status.map(|s| self.rows[r][s].as_str()) {
                Some("fell") | Some("diverged") => " style=\"color:#b00020\"",
                Some("saturated") => " style=\"color:#9a6700\"",
                _ => "",
            };
            html.push_str(&format!("<tr{colour}>"));
            for &c in &shown {
                let v = self.value(py, r, c)?;
                let text = if v.is_instance_of::<pyo3::types::PyFloat>() {
                    format.call1((v, ".4g"))?.extract::<String>()?
                } else {
                    v.str()?.to_string()
                };
                html.push_str(&format!("<td>{}</td>", esc(&text)));
            }
            html.push_str("</tr>");
        }
        html.push_str("</tbody></table>");
        let more = self.rows.len().saturating_sub(100);
        let out = self.out.bind(py);
        let mut foot = format!("{} rows", self.rows.len());
        if more > 0 {
            foot.push_str(&format!(" ({more} not shown)"));
        }
        if !out.is_none() {
            foot.push_str(&format!(", written to {}", esc(&out.str()?.to_string())));
        }
        html.push_str(&format!("<p>{foot}</p>"));
        Ok(html)
    }

    /// Row `i` as a dict: index an int, text as str, numbers as float.
    fn row<'py>(&self, py: Python<'py>, i: isize) -> PyResult<Bound<'py, PyDict>> {
        let n = self.rows.len() as isize;
        let k = if i < 0 { i + n } else { i };
        if !(0..n).contains(&k) {
            return Err(PyIndexError::new_err(format!(
                "row {i} is out of range for {n} rows"
            )));
        }
        let d = PyDict::new(py);
        for (c, name) in self.header.iter().enumerate() {
            d.set_item(name, self.value(py, k as usize, c)?)?;
        }
        Ok(d)
    }

    /// The best cell, by pupper's rule: among cells whose status is ok,
    /// whose metric is a number and whose saturation_frac is under
    /// `max_saturation`, the lowest metric (highest with `minimize=False`).
    /// Ties: on a millimetre metric (`*_mm`) cells within 0.001 mm of the
    /// best are tied, on others only equal values; the smallest push dip
    /// among the tied wins, then the first in grid order. A cell past the
    /// stability bound (status past_bound) is never eligible. `metric` is
    /// any numeric column the table carries (a hold's sag, a response's
    /// `settling_time_s.kfe`, judged by that group's status); by default
    /// the kind's own (last_1s_std_mm; a hold's compliance_mm_per_n).
    /// With `by` (axis names), the
    /// best of each group of those axes' values, as a list of dicts that
    /// also hold `cells` and `eligible` (a group with no eligible cell has
    /// only its axis values, `cells`, `eligible` and `id` None).
    ///
    /// A replicated sweep ranks by a statistic over its replicates,
    /// `"mean:METRIC"` or `"p95:METRIC"` (the default metric is
    /// `"p95:last_1s_std_mm"`); a cell is eligible when none of its
    /// replicates fell or diverged and its p95:saturation_frac is under
    /// `max_saturation`.
    #[pyo3(
        signature = (metric = None, *, by = None, minimize = true, max_saturation = best::MAX_SATURATION),
        text_signature = "($self, metric=None, *, by=None, minimize=True, max_saturation=0.05)"
    )]
    fn best<'py>(
        &self,
        py: Python<'py>,
        metric: Option<&str>,
        by: Option<Vec<String>>,
        minimize: bool,
        max_saturation: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let replicated = self.header.iter().any(|h| h == "failure_fraction");
        let robust = best::robust(self.metric);
        let metric = metric.unwrap_or(if replicated { &robust } else { self.metric });
        let grouped = by.is_some();
        let rule = best::Rule {
            minimize,
            max_saturation,
            ..best::Rule::new(metric, &by.unwrap_or_default())
        };
        let groups = best::best(&self.header, &self.rows, &rule).map_err(to_py)?;
        if !grouped {
            return match groups.first().and_then(|g| g.best) {
                Some(i) => Ok(self.row(py, i as isize)?.into_any()),
                None => Err(ConfigError::new_err(format!(
                    "no cell is eligible for best {metric}: every cell fell, diverged, saturated (saturation_frac >= {max_saturation}) or has no value"
                ))),
            };
        }
        let out = PyList::empty(py);
        for g in &groups {
            let d = match g.best {
                Some(i) => self.row(py, i as isize)?,
                None => {
                    let d = PyDict::new(py);
                    d.set_item("id", py.None())?;
                    d
                }
            };
            for (k, v) in &g.key {
                if is_text(k) {
                    d.set_item(k, v)?;
                } else {
                    d.set_item(k, number(v))?;
                }
            }
            d.set_item("cells", g.cells)?;
            d.set_item("eligible", g.eligible)?;
            out.append(d)?;
        }
        Ok(out.into_any())
    }

    /// The table as a pandas DataFrame (pandas must be installed).
    fn to_pandas<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let pd = PyModule::import(py, "pandas").map_err(|_| {
            pyo3::exceptions::PyImportError::new_err("to_pandas() needs pandas: pip install pandas")
        })?;
        let data = PyDict::new(py);
        for name in &self.header {
            data.set_item(name, self.column(py, name)?)?;
        }
        pd.getattr("DataFrame")?.call1((data,))
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        // names are given by presets only: an empty column is not shown
        let named = self
            .header
            .iter()
            .position(|h| h == "name")
            .is_some_and(|c| self.rows.iter().any(|r| !r[c].is_empty()));
        let mut cols: Vec<String> = if named {
            vec!["name".into()]
        } else {
            Vec::new()
        };
        cols.extend(self.axes());
        let per_replicate = self.header.iter().any(|h| h == "replicate");
        if per_replicate {
            cols.push("replicate".into());
        }
        let shown = if self.header.iter().any(|h| h == "failure_fraction") {
            [
                "failure_fraction",
                "mean:final_z",
                "mean:last_1s_std_mm",
                "p95:last_1s_std_mm",
            ]
        } else {
            ["final_z", "last_1s_std_mm", "push_dip_mm", "status"]
        };
        cols.extend(shown.iter().map(|s| s.to_string()));
        let idx: Vec<usize> = cols
            .iter()
            .filter_map(|c| self.header.iter().position(|h| h == c))
            .collect();
        let format = PyModule::import(py, "builtins")?.getattr("format")?;
        let mut lines = vec![
            idx.iter()
                .map(|&c| format!("{:>14}", self.header[c]))
                .collect::<Vec<_>>()
                .join("  "),
        ];
        for r in 0..self.rows.len() {
            let mut cells = Vec::with_capacity(idx.len());
            for &c in &idx {
                let v = self.value(py, r, c)?;
                let spec = if v.is_instance_of::<pyo3::types::PyFloat>() {
                    ">14.4g"
                } else {
                    ">14"
                };
                cells.push(format.call1((v, spec))?.extract::<String>()?);
            }
            lines.push(cells.join("  "));
        }
        let out = self.out.bind(py);
        let place = if out.is_none() {
            String::new()
        } else {
            format!(", written to {}", out.str()?)
        };
        Ok(format!(
            "SweepResult({} {}{place})\n{}",
            self.rows.len(),
            if per_replicate { "replicates" } else { "cells" },
            lines.join("\n")
        ))
    }
}

/// A result rebuilt from what `SweepResult.__reduce__` gave (unpickling).
#[pyfunction]
pub fn _result_from_state(py: Python<'_>, state: &Bound<'_, PyDict>) -> PyResult<SweepResult> {
    let get = |k: &str| -> PyResult<Bound<'_, PyAny>> {
        state.get_item(k)?.ok_or_else(|| {
            pyo3::exceptions::PyValueError::new_err(format!("no '{k}' in a result's state"))
        })
    };
    let header: Vec<String> = get("header")?.extract()?;
    let rows: Vec<Vec<String>> = get("rows")?.extract()?;
    let mut traces: Vec<Trace> = Vec::new();
    for (id, tz) in get("traces")?.cast_into::<PyDict>()?.iter() {
        let (t, z): (Vec<f64>, Vec<f64>) = tz.extract()?;
        traces.push((id.extract()?, t.into_iter().zip(z).collect()));
    }
    let out: Option<String> = get("out")?.extract()?;
    let text: String = get("config")?.extract()?;
    let config: pupper_core::plan::config::SweepConfig =
        serde_json::from_str(&text).map_err(|e| {
            pyo3::exceptions::PyValueError::new_err(format!(
                "a result's inputs do not read back: {e}"
            ))
        })?;
    let tables: Vec<NamedTable> = get("tables")?.extract()?;
    let cell_steps: Vec<Option<u64>> = get("cell_steps")?.extract()?;
    SweepResult::new(
        py,
        Parts {
            header,
            rows,
            traces: &traces,
            out: out.as_deref().map(Path::new),
            complete: get("complete")?.extract()?,
            wall_seconds: get("wall_seconds")?.extract()?,
            config: &config,
            tables,
            cell_steps,
        },
    )
}
