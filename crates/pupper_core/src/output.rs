//! The run directory: `summary.csv` (one row per cell), `manifest.json`
//! (inputs, model hash, versions, timing, completeness) and optional
//! `traces.csv`. Every file is written to a temporary name and renamed, so a
//! killed process never leaves a truncated one; rows are formatted the same
//! way every time, so the same inputs give the same bytes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::experiment::{CellResult, SweepConfig};
use crate::grid::Cell;
use crate::metrics::{METRIC_NAMES, Metrics};

pub const SUMMARY: &str = "summary.csv";
pub const MANIFEST: &str = "manifest.json";
pub const TRACES: &str = "traces.csv";

/// Writes `bytes` to `path` through a temporary file in the same directory.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    std::fs::write(&tmp, bytes).map_err(|e| Error::io("write", &tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io("rename into", path, e)
    })
}

/// A float as the shortest text that reads back to the same bits; NaN empty.
pub fn fmt_f64(v: f64) -> String {
    if v.is_nan() {
        String::new()
    } else {
        format!("{v}")
    }
}

/// The header of `summary.csv` for a grid with these axis names.
pub fn header(axes: &[String]) -> Vec<String> {
    let mut h: Vec<String> = ["index", "id", "name"].map(String::from).to_vec();
    h.extend(axes.iter().cloned());
    h.extend(METRIC_NAMES.iter().map(|s| s.to_string()));
    h
}

/// The header of a sweep's `summary.csv`.
pub fn header_of(config: &SweepConfig) -> Vec<String> {
    let axes: Vec<String> = config
        .grid
        .axes
        .iter()
        .map(|a| a.axis.name().to_string())
        .collect();
    header(&axes)
}

/// One summary row as text fields.
pub fn row(cell: &Cell, m: &Metrics) -> Vec<String> {
    let mut r = vec![cell.index.to_string(), cell.id.clone(), cell.name.clone()];
    r.extend(cell.values.iter().map(|(_, v)| fmt_f64(*v)));
    for name in METRIC_NAMES {
        r.push(match name {
            "status" => m.status.as_str().to_string(),
            n => fmt_f64(m.get(n).unwrap_or(f64::NAN)),
        });
    }
    r
}

fn csv_bytes(header: &[String], rows: &[Vec<String>]) -> Result<Vec<u8>> {
    let mut w = csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new());
    let bad = |e: csv::Error| Error::Internal(format!("csv: {e}"));
    w.write_record(header).map_err(bad)?;
    for r in rows {
        w.write_record(r).map_err(bad)?;
    }
    w.into_inner()
        .map_err(|e| Error::Internal(format!("csv: {e}")))
}

/// Model identity recorded in the manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelRecord {
    pub name: String,
    pub source: String,
    pub sha256: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub pupper_version: String,
    pub mujoco_version: String,
    pub python: String,
    pub config: SweepConfig,
    pub model: ModelRecord,
    pub cells_total: usize,
    pub cells_done: usize,
    pub complete: bool,
    pub threads: usize,
    pub started_unix: u64,
    pub wall_seconds: f64,
    pub command: Vec<String>,
}

/// How an existing `--out` directory is treated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Existing {
    /// Refuse if it exists.
    Refuse,
    /// Overwrite pupper's files in it.
    Overwrite,
    /// Continue it: keep its finished rows.
    Resume,
}

/// Reads a run's manifest.
pub fn read_manifest(dir: &Path) -> Result<Manifest> {
    let p = dir.join(MANIFEST);
    let text = std::fs::read_to_string(&p).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => Error::RunNotFound(format!(
            "'{}' is not a run directory: it has no {MANIFEST}; give the directory of an earlier `pupper sweep`",
            dir.display()
        )),
        _ => Error::io("read", &p, e),
    })?;
    serde_json::from_str(&text).map_err(|e| {
        Error::Output(format!(
            "'{}': its {MANIFEST} is not a pupper manifest ({e}); start a new run with --out",
            dir.display()
        ))
    })
}

/// A cell's trace: its id and (t, z) samples.
pub type Trace = (String, Vec<(f64, f64)>);

/// Lines of a file that ends cleanly: a last line without its newline is
/// the trace of a write that was cut short, and is left out.
fn whole_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    let whole = match text.rfind('\n') {
        Some(i) => &text[..i + 1],
        None => "",
    };
    whole.lines().enumerate().map(|(i, l)| (i + 1, l))
}

/// The rows of a run's `summary.csv`, by cell index, each checked against
/// the manifest's grid: its index in range, its id and axis values those of
/// that cell. A truncated last line is dropped (its cell runs again).
fn read_rows(dir: &Path, config: &SweepConfig) -> Result<BTreeMap<usize, Vec<String>>> {
    let p = dir.join(SUMMARY);
    let mut rows = BTreeMap::new();
    let text = match std::fs::read_to_string(&p) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(rows),
        Err(e) => return Err(Error::io("read", &p, e)),
    };
    let want = header_of(config);
    let cells = config.grid.cells();
    let broken = |line: usize, what: String| {
        Error::Output(format!(
            "{}:{line}: {what}; this file does not belong to the run's manifest: move it away, or start a new run with --force",
            p.display()
        ))
    };
    for (n, line) in whole_lines(&text) {
        let mut r = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(line.as_bytes());
        let fields: Vec<String> = match r.records().next() {
            Some(Ok(rec)) => rec.iter().map(String::from).collect(),
            _ => return Err(broken(n, "not a CSV row".into())),
        };
        if n == 1 {
            if fields != want {
                return Err(broken(n, format!("its columns are not {}", want.join(","))));
            }
            continue;
        }
        if fields.len() != want.len() {
            return Err(broken(
                n,
                format!(
                    "{} fields where the header has {}",
                    fields.len(),
                    want.len()
                ),
            ));
        }
        let cell = fields[0]
            .parse::<usize>()
            .ok()
            .and_then(|i| cells.get(i))
            .ok_or_else(|| {
                broken(
                    n,
                    format!(
                        "index '{}' is not a cell of this {}-cell grid",
                        fields[0],
                        cells.len()
                    ),
                )
            })?;
        let values: Vec<String> = cell.values.iter().map(|(_, v)| fmt_f64(*v)).collect();
        if fields[1] != cell.id || fields[3..3 + values.len()] != values[..] {
            return Err(broken(
                n,
                format!(
                    "row {} is cell '{}' of another grid (this grid's cell {} is '{}')",
                    fields[0], fields[1], cell.index, cell.id
                ),
            ));
        }
        rows.insert(cell.index, fields);
    }
    Ok(rows)
}

/// The traces of a run's `traces.csv` by cell id (a truncated last line is
/// dropped), for the cells in `keep`.
fn read_traces(dir: &Path, keep: &BTreeMap<usize, Vec<String>>) -> Result<BTreeMap<usize, Trace>> {
    let p = dir.join(TRACES);
    let mut out = BTreeMap::new();
    let text = match std::fs::read_to_string(&p) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(out),
        Err(e) => return Err(Error::io("read", &p, e)),
    };
    let by_id: BTreeMap<&str, usize> = keep.iter().map(|(i, r)| (r[1].as_str(), *i)).collect();
    let mut samples: BTreeMap<usize, Vec<(f64, f64)>> = BTreeMap::new();
    for (n, line) in whole_lines(&text).skip(1) {
        let mut parts = line.rsplitn(3, ',');
        let (z, t, id) = (parts.next(), parts.next(), parts.next());
        let parsed = match (id, t.map(str::parse::<f64>), z.map(str::parse::<f64>)) {
            (Some(id), Some(Ok(t)), Some(Ok(z))) => Some((id, t, z)),
            _ => None,
        };
        let Some((id, t, z)) = parsed else {
            return Err(Error::Output(format!(
                "{}:{n}: not an 'id,t,z' row; move the file away, or start a new run with --force",
                p.display()
            )));
        };
        if let Some(&i) = by_id.get(id) {
            samples.entry(i).or_default().push((t, z));
        }
    }
    for (i, s) in samples {
        out.insert(i, (keep[&i][1].clone(), s));
    }
    Ok(out)
}

/// A run directory read back (what Python's `load_run` returns).
#[derive(Debug, Clone)]
pub struct RunTables {
    pub manifest: Manifest,
    pub header: Vec<String>,
    /// summary.csv's rows in cell order.
    pub rows: Vec<Vec<String>>,
    /// (cell id, (t, z) samples) in cell order, for traced runs.
    pub traces: Vec<(String, Vec<(f64, f64)>)>,
}

/// Reads a run directory, checking its rows against its manifest.
pub fn read_run(dir: &Path) -> Result<RunTables> {
    let manifest = read_manifest(dir)?;
    let rows = read_rows(dir, &manifest.config)?;
    let traces = read_traces(dir, &rows)?;
    Ok(RunTables {
        header: header_of(&manifest.config),
        rows: rows.into_values().collect(),
        traces: traces.into_values().collect(),
        manifest,
    })
}

/// Writes a run directory as chunks finish.
pub struct RunWriter {
    /// None: keep the table in memory only (the Python API without `out`).
    dir: Option<PathBuf>,
    header: Vec<String>,
    rows: BTreeMap<usize, Vec<String>>,
    traces: BTreeMap<usize, Trace>,
    want_traces: bool,
    pub manifest: Manifest,
    created: bool,
    overwrite: bool,
    started: std::time::Instant,
}

impl RunWriter {
    /// Checks `dir` without creating it (that waits for [`RunWriter::create`],
    /// so bad input never leaves a directory behind). For a resume, loads the
    /// finished rows and checks the manifest's inputs equal `manifest.config`.
    pub fn new(dir: Option<&Path>, existing: Existing, manifest: Manifest) -> Result<RunWriter> {
        let header = header_of(&manifest.config);
        let mut rows = BTreeMap::new();
        let mut traces = BTreeMap::new();
        let Some(dir) = dir else {
            return Ok(RunWriter {
                dir: None,
                header,
                rows,
                traces: BTreeMap::new(),
                want_traces: manifest.config.schedule.trace_every > 0,
                manifest,
                created: true,
                overwrite: false,
                started: std::time::Instant::now(),
            });
        };
        match existing {
            Existing::Refuse if dir.exists() => {
                return Err(Error::RunExists(format!(
                    "output directory '{}' already exists: choose another --out, add --force to overwrite it, or --resume it",
                    dir.display()
                )));
            }
            Existing::Resume => {
                let old = read_manifest(dir)?;
                if old.config != manifest.config {
                    return Err(Error::ResumeMismatch(format!(
                        "cannot resume '{}': its inputs ({}) differ from this command's ({}); rerun the original command with --resume, or use a new --out",
                        dir.display(),
                        describe(&old.config),
                        describe(&manifest.config)
                    )));
                }
                if old.model.sha256 != manifest.model.sha256 {
                    return Err(Error::ResumeMismatch(format!(
                        "cannot resume '{}': the model file changed since the run started (SHA-256 differs); use a new --out",
                        dir.display()
                    )));
                }
                rows = read_rows(dir, &manifest.config)?;
                // earlier cells' traces stay: a resumed run keeps them all
                traces = read_traces(dir, &rows)?;
            }
            _ => {}
        }
        if dir.exists() && !dir.is_dir() {
            return Err(Error::Output(format!(
                "--out '{}' is a file, not a directory: choose another path",
                dir.display()
            )));
        }
        let want_traces = manifest.config.schedule.trace_every > 0;
        Ok(RunWriter {
            dir: Some(dir.to_path_buf()),
            header,
            rows,
            traces,
            want_traces,
            manifest,
            created: false,
            overwrite: existing == Existing::Overwrite,
            started: std::time::Instant::now(),
        })
    }

    pub fn dir(&self) -> Option<&Path> {
        self.dir.as_deref()
    }

    pub fn header(&self) -> &[String] {
        &self.header
    }

    /// The summary table so far, in cell order, as written to summary.csv.
    pub fn rows(&self) -> impl Iterator<Item = &Vec<String>> {
        self.rows.values()
    }

    /// Traces kept so far: cell id and (time, z) samples.
    pub fn traces(&self) -> impl Iterator<Item = &(String, Vec<(f64, f64)>)> {
        self.traces.values()
    }

    /// Indices of the cells already finished (a resume skips them).
    pub fn done(&self) -> impl Iterator<Item = usize> + '_ {
        self.rows.keys().copied()
    }

    /// Creates the directory and writes the manifest, marked incomplete.
    pub fn create(&mut self) -> Result<()> {
        let Some(dir) = &self.dir else { return Ok(()) };
        std::fs::create_dir_all(dir).map_err(|e| Error::io("create", dir, e))?;
        if self.overwrite {
            // an overwritten run must not keep files of the old one
            for f in [SUMMARY, TRACES] {
                let p = dir.join(f);
                if p.exists() {
                    std::fs::remove_file(&p).map_err(|e| Error::io("remove", &p, e))?;
                }
            }
        }
        self.created = true;
        self.manifest.cells_done = self.rows.len();
        self.write_manifest()
    }

    fn write_manifest(&self) -> Result<()> {
        let Some(dir) = &self.dir else { return Ok(()) };
        let text = serde_json::to_string_pretty(&self.manifest)
            .map_err(|e| Error::Internal(format!("manifest: {e}")))?;
        write_atomic(&dir.join(MANIFEST), (text + "\n").as_bytes())
    }

    /// Adds finished cells and rewrites the summary (and traces).
    pub fn add(&mut self, results: &[CellResult]) -> Result<()> {
        if !self.created {
            self.create()?;
        }
        for r in results {
            self.rows.insert(r.cell.index, row(&r.cell, &r.metrics));
            if self.want_traces {
                self.traces
                    .insert(r.cell.index, (r.cell.id.clone(), r.trace.clone()));
            }
        }
        self.manifest.cells_done = self.rows.len();
        self.manifest.wall_seconds = self.started.elapsed().as_secs_f64();
        let Some(dir) = &self.dir else { return Ok(()) };
        // traces first: a row in summary.csv promises its trace is on disk
        if self.want_traces {
            let mut out = String::from("id,t,z\n");
            for (id, tr) in self.traces.values() {
                for (t, z) in tr {
                    out.push_str(&format!("{id},{},{}\n", fmt_f64(*t), fmt_f64(*z)));
                }
            }
            write_atomic(&dir.join(TRACES), out.as_bytes())?;
        }
        let rows: Vec<Vec<String>> = self.rows.values().cloned().collect();
        write_atomic(&dir.join(SUMMARY), &csv_bytes(&self.header, &rows)?)?;
        self.write_manifest()
    }

    /// Final manifest: complete or not.
    pub fn finish(&mut self, complete: bool) -> Result<()> {
        if !self.created {
            self.create()?;
        }
        self.manifest.complete = complete && self.rows.len() == self.manifest.cells_total;
        self.manifest.cells_done = self.rows.len();
        self.manifest.wall_seconds = self.started.elapsed().as_secs_f64();
        self.write_manifest()
    }
}

/// A short account of a config for messages.
pub fn describe(c: &SweepConfig) -> String {
    let grid: Vec<String> = c
        .grid
        .axes
        .iter()
        .map(|a| {
            let v: Vec<String> = a.values.iter().map(|v| fmt_f64(*v)).collect();
            format!("{}={}", a.axis, v.join(","))
        })
        .collect();
    format!(
        "{} grid {} mode {} {} s",
        c.model.display(),
        if grid.is_empty() {
            "none".into()
        } else {
            grid.join(" ")
        },
        c.mode.as_str(),
        c.schedule.duration
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{Axis, Grid};
    use crate::metrics::Status;

    fn manifest(cfg: SweepConfig) -> Manifest {
        Manifest {
            pupper_version: "t".into(),
            mujoco_version: "t".into(),
            python: "t".into(),
            cells_total: cfg.grid.len(),
            config: cfg,
            model: ModelRecord {
                name: "m".into(),
                source: "m".into(),
                sha256: "0".into(),
            },
            cells_done: 0,
            complete: false,
            threads: 1,
            started_unix: 0,
            wall_seconds: 0.0,
            command: vec![],
        }
    }

    fn result(cell: Cell) -> CellResult {
        CellResult {
            cell,
            metrics: Metrics {
                final_z: 0.1,
                last_1s_std_mm: f64::NAN,
                push_dip_mm: 1.0 / 3.0,
                settle_time_s: 0.5,
                max_tilt_deg: 1.0,
                peak_torque: 3.0,
                saturation_frac: 0.0,
                tracking_rms: 0.01,
                status: Status::Ok,
                event_time: f64::NAN,
            },
            trace: vec![],
            frames: None,
        }
    }

    #[test]
    fn floats_round_trip_and_nan_is_empty() {
        assert_eq!(fmt_f64(0.1), "0.1");
        assert_eq!(fmt_f64(f64::NAN), "");
        let x = 1.0 / 3.0;
        assert_eq!(fmt_f64(x).parse::<f64>().unwrap().to_bits(), x.to_bits());
    }

    #[test]
    fn write_refuse_resume() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("run");
        let cfg = SweepConfig {
            grid: Grid::parse(&["kp=1,2"]).unwrap(),
            ..SweepConfig::default()
        };
        let cells = cfg.grid.cells();
        let mut w = RunWriter::new(Some(&dir), Existing::Refuse, manifest(cfg.clone())).unwrap();
        assert!(!dir.exists(), "nothing is created before the run starts");
        w.add(&[result(cells[1].clone())]).unwrap();
        w.finish(false).unwrap();
        let text = std::fs::read_to_string(dir.join(SUMMARY)).unwrap();
        assert!(text.starts_with("index,id,name,kp,final_z,"));
        assert!(
            text.contains("\n1,kp2,,2,0.1,,0.3333333333333333,"),
            "{text}"
        );
        // no temp files left
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2, "{names:?}");
        assert!(!read_manifest(&dir).unwrap().complete);

        // refuse an existing directory
        let e = RunWriter::new(Some(&dir), Existing::Refuse, manifest(cfg.clone()))
            .err()
            .unwrap();
        assert!(e.to_string().contains("already exists"));
        // resume with other inputs is refused
        let other = SweepConfig {
            grid: Grid::parse(&["kp=1,3"]).unwrap(),
            ..SweepConfig::default()
        };
        let e = RunWriter::new(Some(&dir), Existing::Resume, manifest(other))
            .err()
            .unwrap();
        assert!(e.to_string().contains("differ"), "{e}");
        // resume keeps the finished row
        let w = RunWriter::new(Some(&dir), Existing::Resume, manifest(cfg)).unwrap();
        assert_eq!(w.done().collect::<Vec<_>>(), vec![1]);
        assert_eq!(cells[0].get(Axis::Kp), Some(1.0));
    }
}
