//! Writing a run directory so that nothing is lost or mixed up: one writer
//! at a time (an advisory lock that dies with its process), directories
//! created atomically, rows and traces appended as chunks finish (so a
//! chunk costs its own rows, not a rewrite of the table), every failed write
//! rolled back to the last consistent state, files flushed before a rename.
//!
//! On disk, at any moment between chunks: `manifest.json` counts exactly the
//! rows of `summary.csv`, and every row's trace is in `traces.csv`. A kill
//! may leave a truncated last line or a temporary file; the next writer (who
//! holds the lock) drops the one and deletes the other.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::{Error, Result};
use crate::results::files::{Appender, refuse_non_regular, write_atomic};
use crate::results::lock::RunLock;
use crate::results::output::Detail;
use crate::results::output::{
    MANIFEST, Manifest, REPLICATES, SUMMARY, TRACES, Trace, csv_bytes, fmt_f64, read_manifest,
};
use crate::results::resume;
use crate::results::tables::NamedTable;
use crate::results::tables::{self, BODE, RESPONSE, RESPONSE_TRACES, header_of};
use crate::sim::runner::CellResult;

/// Seconds between flushes to disk while a run goes on (and at its end).
const SYNC_EVERY_S: f64 = 1.0;

/// How an `--out` directory is treated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Existing {
    /// Refuse if it exists.
    Refuse,
    /// Overwrite pupper's files in it.
    Overwrite,
    /// Continue it: keep its finished rows.
    Resume,
    /// `out` is a name to start from: the first of `out`, `out-1`, `out-2`,
    /// ... that does not exist is created (safe when many start at once).
    Unique,
}

/// The files a run directory may hold that pupper writes (its Python side
/// writes report.html and, on request, best.csv's neighbours): each must
/// be a regular file or absent before a run starts, so that no write at
/// its end is refused after the manifest has called it complete.
fn refuse_non_regular_outputs(dir: &Path) -> Result<()> {
    for name in [
        SUMMARY,
        MANIFEST,
        TRACES,
        REPLICATES,
        RESPONSE,
        BODE,
        RESPONSE_TRACES,
        crate::results::output::BEST,
        "report.html",
    ] {
        refuse_non_regular(&dir.join(name))?;
    }
    Ok(())
}

/// Open files of a directory being written.
struct Open {
    _lock: RunLock,
    summary: Option<Appender>,
    traces: Option<Appender>,
    /// One per table of [`RunWriter::details`].
    details: Vec<Appender>,
    synced: Instant,
}

/// A chunk's lines for each table, as appended.
struct Chunk<'a> {
    traces: &'a [u8],
    /// One per table of [`RunWriter::details`].
    details: &'a [Vec<u8>],
    rows: &'a [u8],
}

impl Open {
    /// Appends a chunk to the tables and writes `manifest`, flushing every
    /// [`SYNC_EVERY_S`]; if any write fails, every table goes back to its
    /// last consistent length and the error is returned.
    fn append(&mut self, dir: &Path, chunk: &Chunk<'_>, manifest: &Manifest) -> Result<()> {
        let sync = self.synced.elapsed().as_secs_f64() >= SYNC_EVERY_S;
        if let Err(e) = self.write(dir, chunk, manifest, sync) {
            for a in self
                .traces
                .iter_mut()
                .chain(self.details.iter_mut())
                .chain(self.summary.iter_mut())
            {
                a.roll_back();
            }
            return Err(e);
        }
        for a in self
            .traces
            .iter_mut()
            .chain(self.details.iter_mut())
            .chain(self.summary.iter_mut())
        {
            a.commit()?;
        }
        if sync {
            self.synced = Instant::now();
        }
        Ok(())
    }

    fn write(
        &mut self,
        dir: &Path,
        chunk: &Chunk<'_>,
        manifest: &Manifest,
        sync: bool,
    ) -> Result<()> {
        if let Some(t) = &mut self.traces {
            t.append(chunk.traces)?;
        }
        for (a, bytes) in self.details.iter_mut().zip(chunk.details) {
            a.append(bytes)?;
        }
        // the summary last: a row promises the rest is on disk
        if let Some(s) = &mut self.summary {
            s.append(chunk.rows)?;
        }
        if sync {
            for a in self.traces.iter().chain(&self.details).chain(&self.summary) {
                a.sync()?;
            }
        }
        let text = serde_json::to_string_pretty(manifest)
            .map_err(|e| Error::Internal(format!("manifest: {e}")))?;
        write_atomic(&dir.join(MANIFEST), (text + "\n").as_bytes())
    }
}

/// Writes a run directory as chunks finish.
pub struct RunWriter {
    /// None: keep the table in memory only (the Python API without `out`).
    dir: Option<PathBuf>,
    existing: Existing,
    header: Vec<String>,
    pub(crate) rows: BTreeMap<usize, Vec<String>>,
    pub(crate) traces: BTreeMap<usize, Trace>,
    pub(crate) want_traces: bool,
    /// The tables of rows per cell beside summary.csv (replicates.csv;
    /// response.csv, bode.csv) and their rows by cell.
    pub(crate) details: Vec<Detail>,
    pub(crate) detail_rows: Vec<BTreeMap<usize, Vec<Vec<String>>>>,
    pub manifest: Manifest,
    lock: Option<RunLock>,
    open: Option<Open>,
    started: Instant,
}

impl RunWriter {
    /// Checks `dir` without creating it (that waits for [`RunWriter::create`],
    /// so bad input never leaves a directory behind). For a resume, takes
    /// the lock, loads the finished rows and traces, and checks the run's
    /// inputs equal `manifest.config`.
    pub fn new(dir: Option<&Path>, existing: Existing, manifest: Manifest) -> Result<RunWriter> {
        let mut w = RunWriter {
            dir: dir.map(Path::to_path_buf),
            existing,
            header: header_of(&manifest.config),
            rows: BTreeMap::new(),
            traces: BTreeMap::new(),
            want_traces: manifest.config.schedule.trace_every > 0
                && tables::kind_traces_base_z(&manifest.config),
            details: tables::details_of(&manifest.config, manifest.torque_limits.len()),
            detail_rows: Vec::new(),
            manifest,
            lock: None,
            open: None,
            started: Instant::now(),
        };
        w.detail_rows = vec![BTreeMap::new(); w.details.len()];
        let Some(dir) = dir else { return Ok(w) };
        refuse_file_above(dir)?;
        if dir.exists() && !dir.is_dir() {
            return Err(Error::Output(format!(
                "--out '{}' is a file, not a directory: choose another path",
                dir.display()
            )));
        }
        if dir.is_dir() && matches!(existing, Existing::Overwrite | Existing::Resume) {
            refuse_non_regular_outputs(dir)?;
        }
        match existing {
            Existing::Refuse if dir.exists() => {
                return Err(Error::RunExists(format!(
                    "output directory '{}' already exists: choose another --out, add --force to overwrite it, or --resume it",
                    dir.display()
                )));
            }
            // a run killed while creating its directory left no manifest
            // and no rows: the full command with --resume starts it afresh
            Existing::Resume if !dir.join(MANIFEST).exists() && resume::only_ours(dir) => {
                w.lock = Some(RunLock::take(dir)?);
            }
            Existing::Resume => {
                // another kind's run is refused before its manifest is parsed
                // (a tune's or a fit's is not a sweep's)
                crate::results::clear::check_kind(dir, &w.manifest.kind)?;
                let old = read_manifest(dir)?;
                w.lock = Some(RunLock::take(dir)?);
                // read under the lock: no writer is changing it now
                let old = read_manifest(dir).unwrap_or(old);
                resume::check_continues(dir, &old, &w.manifest)?;
                let kept = resume::read_kept(dir, &w.manifest.config, &w.details, w.want_traces)?;
                (w.rows, w.detail_rows, w.traces) = (kept.rows, kept.details, kept.traces);
            }
            Existing::Overwrite if dir.is_dir() => w.lock = Some(RunLock::take(dir)?),
            _ => {}
        }
        Ok(w)
    }

    pub fn dir(&self) -> Option<&Path> {
        self.dir.as_deref()
    }

    fn detail(&self, file: &str) -> Option<usize> {
        self.details.iter().position(|d| d.file == file)
    }

    /// Every table beside summary.csv: file name, header, rows so far.
    pub fn detail_tables(&self) -> Vec<NamedTable> {
        self.details
            .iter()
            .map(|d| {
                let (h, rows) = self.detail_table(d.file);
                (d.file.to_string(), h, rows)
            })
            .collect()
    }

    /// A table beside summary.csv by file name: its header and its rows
    /// so far, in cell order (empty when the run has no such table).
    pub fn detail_table(&self, file: &str) -> (Vec<String>, Vec<Vec<String>>) {
        match self.detail(file) {
            Some(k) => (
                self.details[k].header.clone(),
                self.detail_rows[k].values().flatten().cloned().collect(),
            ),
            None => (Vec::new(), Vec::new()),
        }
    }

    pub fn header(&self) -> &[String] {
        &self.header
    }

    /// The summary table so far, in cell order, as written to summary.csv.
    pub fn rows(&self) -> impl Iterator<Item = &Vec<String>> {
        self.rows.values()
    }

    /// Traces kept so far (resumed ones included), in cell order.
    pub fn traces(&self) -> impl Iterator<Item = &Trace> {
        self.traces.values()
    }

    /// Indices of the cells already finished (a resume skips them).
    pub fn done(&self) -> impl Iterator<Item = usize> + '_ {
        self.rows.keys().copied()
    }

    /// Creates (or takes over) the directory under its lock, writes the
    /// kept rows and traces afresh, and marks the manifest incomplete.
    pub fn create(&mut self) -> Result<()> {
        let Some(dir) = self.dir.clone() else {
            return Ok(());
        };
        let dir = match self.existing {
            Existing::Unique => create_unique(&dir)?,
            Existing::Refuse => {
                create_new(&dir)?;
                dir
            }
            Existing::Overwrite | Existing::Resume => {
                std::fs::create_dir_all(&dir).map_err(|e| Error::io("create", &dir, e))?;
                dir
            }
        };
        let lock = match self.lock.take() {
            Some(l) => l,
            None => RunLock::take(&dir)?,
        };
        if self.existing == Existing::Overwrite {
            // an overwritten run keeps no file of the old one, whatever
            // kind wrote it (a fit's calibrated.xml under a walk's manifest
            // would be read as this run's)
            crate::results::clear::clear_run(&dir)?;
        }
        // a resume's files are rewritten from what was read: sorted, without
        // a truncated last line or traces of cells that must run again
        self.write_tables(&dir)?;
        self.open = Some(Open {
            _lock: lock,
            summary: Some(Appender::open(dir.join(SUMMARY))?),
            traces: match self.want_traces {
                true => Some(Appender::open(dir.join(TRACES))?),
                false => None,
            },
            details: self
                .details
                .iter()
                .map(|d| Appender::open(dir.join(d.file)))
                .collect::<Result<_>>()?,
            synced: Instant::now(),
        });
        self.dir = Some(dir);
        self.manifest.cells_done = self.rows.len();
        self.write_manifest()
    }

    /// Writes summary.csv (and traces.csv) whole, in cell order.
    fn write_tables(&self, dir: &Path) -> Result<()> {
        if self.want_traces {
            let mut out = String::from("id,t,z\n");
            for tr in self.traces.values() {
                trace_lines(&mut out, &tr.0, &tr.1);
            }
            write_atomic(&dir.join(TRACES), out.as_bytes())?;
        }
        for (d, rows) in self.details.iter().zip(&self.detail_rows) {
            let rows: Vec<Vec<String>> = rows.values().flatten().cloned().collect();
            write_atomic(&dir.join(d.file), &csv_bytes(&d.header, &rows)?)?;
        }
        let rows: Vec<Vec<String>> = self.rows.values().cloned().collect();
        write_atomic(&dir.join(SUMMARY), &csv_bytes(&self.header, &rows)?)
    }

    fn write_manifest(&self) -> Result<()> {
        let Some(dir) = &self.dir else { return Ok(()) };
        let text = serde_json::to_string_pretty(&self.manifest)
            .map_err(|e| Error::Internal(format!("manifest: {e}")))?;
        write_atomic(&dir.join(MANIFEST), (text + "\n").as_bytes())
    }

    /// Adds finished cells: their traces and replicates, then their rows,
    /// appended (a row promises the rest is on disk); then the manifest.
    /// If any write fails, the files and the manifest go back to how they
    /// were before this call and the error is returned.
    pub fn add(&mut self, results: &[CellResult]) -> Result<()> {
        if self.dir.is_some() && self.open.is_none() {
            self.create()?;
        }
        let config = &self.manifest.config;
        let new_rows: Vec<Vec<String>> = results
            .iter()
            .map(|r| tables::summary_row(config, r))
            .collect();
        // per cell, its rows of each detail table
        let new_details: Vec<Vec<Vec<Vec<String>>>> = results
            .iter()
            .map(|r| tables::detail_rows(config, r))
            .collect();
        if let Some(open) = &mut self.open {
            let mut traces = String::new();
            if self.want_traces {
                for r in results {
                    trace_lines(&mut traces, &r.cell.id, &r.trace);
                }
            }
            let rows = csv_bytes(&[], &new_rows)?;
            let details = (0..self.details.len())
                .map(|k| {
                    let rows: Vec<Vec<String>> = new_details
                        .iter()
                        .flat_map(|d| d[k].iter().cloned())
                        .collect();
                    csv_bytes(&[], &rows)
                })
                .collect::<Result<Vec<_>>>()?;
            let mut manifest = self.manifest.clone();
            manifest.cells_done = self.rows.len() + results.len();
            manifest.batches += 1;
            manifest.wall_seconds = self.started.elapsed().as_secs_f64();
            let dir = self.dir.as_deref().unwrap_or(Path::new("."));
            let chunk = Chunk {
                traces: traces.as_bytes(),
                details: &details,
                rows: &rows,
            };
            open.append(dir, &chunk, &manifest)?;
        }
        for ((r, fields), details) in results.iter().zip(new_rows).zip(new_details) {
            self.rows.insert(r.cell.index, fields);
            for (k, rows) in details.into_iter().enumerate() {
                self.detail_rows[k].insert(r.cell.index, rows);
            }
            if self.want_traces {
                self.traces
                    .insert(r.cell.index, (r.cell.id.clone(), r.trace.clone()));
            }
        }
        self.manifest.cells_done = self.rows.len();
        self.manifest.batches += 1;
        self.manifest.wall_seconds = self.started.elapsed().as_secs_f64();
        Ok(())
    }

    /// Ends the run: the tables rewritten in cell order (so a finished run's
    /// bytes do not depend on how it was interrupted and resumed), flushed,
    /// and the final manifest. The lock is released.
    pub fn finish(&mut self, complete: bool) -> Result<()> {
        if self.dir.is_some() && self.open.is_none() {
            self.create()?;
        }
        self.manifest.complete = complete && self.rows.len() == self.manifest.cells_total;
        self.manifest.cells_done = self.rows.len();
        self.manifest.wall_seconds = self.started.elapsed().as_secs_f64();
        if let Some(dir) = self.dir.clone() {
            self.write_tables(&dir)?;
            self.write_manifest()?;
        }
        // released: the lock file stays, naming nobody
        self.open = None;
        Ok(())
    }
}

fn trace_lines(out: &mut String, id: &str, samples: &[(f64, f64)]) {
    for (t, z) in samples {
        out.push_str(&format!("{id},{},{}\n", fmt_f64(*t), fmt_f64(*z)));
    }
}

/// Refuses a `dir` below a file (`-o notes.txt/run`): no directory can
/// be made there, and the OS's "File exists" names neither.
fn refuse_file_above(dir: &Path) -> Result<()> {
    for above in dir
        .ancestors()
        .skip(1)
        .filter(|a| !a.as_os_str().is_empty())
    {
        match std::fs::metadata(above) {
            Ok(m) if m.is_dir() => return Ok(()),
            Ok(_) => {
                return Err(Error::Output(format!(
                    "--out '{}' lies under '{}', which is a file, not a directory: choose another --out",
                    dir.display(),
                    above.display()
                )));
            }
            Err(_) => continue,
        }
    }
    Ok(())
}

/// Creates `dir` (its parents as needed); it must not exist yet.
fn create_new(dir: &Path) -> Result<()> {
    if let Some(parent) = dir.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| Error::io("create", parent, e))?;
    }
    std::fs::create_dir(dir).map_err(|e| match e.kind() {
        std::io::ErrorKind::AlreadyExists => Error::RunExists(format!(
            "output directory '{}' already exists (another run just made it): choose another --out, add --force to overwrite it, or --resume it",
            dir.display()
        )),
        _ => Error::io("create", dir, e),
    })
}

/// Creates the first of `base`, `base-1`, `base-2`, ... that is free.
fn create_unique(base: &Path) -> Result<PathBuf> {
    for i in 0..10_000 {
        let candidate = match i {
            0 => base.to_path_buf(),
            i => PathBuf::from(format!("{}-{i}", base.display())),
        };
        match create_new(&candidate) {
            Ok(()) => return Ok(candidate),
            Err(Error::RunExists(_)) => continue,
            Err(e) => return Err(e),
        }
    }
    Err(Error::Output(format!(
        "no free run directory name next to '{}': give --out",
        base.display()
    )))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::config::SweepConfig;
    use crate::plan::grid::{Cell, Grid};
    use crate::results::output::{LOCK, ModelRecord};
    use crate::sim::metrics::{Metrics, Status};
    use std::fs::OpenOptions;
    use std::io::Write;

    fn manifest(cfg: SweepConfig) -> Manifest {
        Manifest {
            kind: "sweep".into(),
            pupper_version: "t".into(),
            mujoco_version: "t".into(),
            python: "t".into(),
            cells_total: cfg.grid.len(),
            config: cfg,
            model: ModelRecord {
                name: "m".into(),
                source: "builtin".into(),
                sha256: "0".repeat(64),
                timestep: None,
            },
            torque_limits: vec![],
            start_notes: vec![],
            cells_done: 0,
            batches: 0,
            complete: false,
            threads: 1,
            started_unix: 0,
            wall_seconds: 0.0,
            command: vec![],
            shard: None,
            merged: vec![],
            ray: None,
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
            trace: vec![(0.002, 0.25)],
            frames: None,
            joints: Vec::new(),
            figures: Vec::new(),
            steps: 0,
            replicates: Vec::new(),
        }
    }

    /// A replicated cell: replicate k has final_z 0.1 + k/100; replicate 1
    /// fell.
    fn replicated(cell: Cell, count: usize) -> CellResult {
        let mut r = result(cell);
        r.replicates = (0..count)
            .map(|k| {
                let mut m = r.metrics.clone();
                m.final_z = 0.1 + k as f64 / 100.0;
                if k == 1 {
                    m.status = Status::Fell;
                    m.event_time = 1.5;
                }
                crate::sim::runner::Replicate {
                    drawn: vec![1.0 + k as f64 / 10.0],
                    metrics: m,
                    figures: Vec::new(),
                }
            })
            .collect();
        r
    }

    fn cfg(grid: &str, traces: bool) -> SweepConfig {
        let mut c = SweepConfig {
            grid: Grid::parse(&[grid]).unwrap(),
            ..SweepConfig::default()
        };
        c.schedule.trace_every = if traces { 1 } else { 0 };
        c
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn replicates_are_written_before_their_rows_and_resumed_whole() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("run");
        let mut c = cfg("kp=1,2,3", false);
        c.replicates = crate::plan::randomize::Replicates {
            count: 3,
            seed: 7,
            randomize: vec![crate::plan::randomize::Randomize::parse("friction=0.5:1.2").unwrap()],
            common_draws: false,
        };
        let cells = c.grid.cells();
        let mut w = RunWriter::new(Some(&dir), Existing::Refuse, manifest(c.clone())).unwrap();
        w.add(&[
            replicated(cells[0].clone(), 3),
            replicated(cells[1].clone(), 3),
        ])
        .unwrap();
        drop(w); // killed
        let reps = std::fs::read_to_string(dir.join(REPLICATES)).unwrap();
        assert!(
            reps.starts_with("index,id,name,kp,replicate,friction,final_z,"),
            "{reps}"
        );
        assert!(reps.contains("\n0,kp1,,1,1,1.1,0.11,"), "{reps}");
        let summary = std::fs::read_to_string(dir.join(SUMMARY)).unwrap();
        assert!(
            summary.starts_with(
                "index,id,name,kp,replicates,failure_fraction,mean:final_z,p95:final_z,"
            ),
            "{summary}"
        );
        // one of three fell; the others have final_z 0.1 and 0.12: mean
        // 0.11, 5th percentile (final_z's bad side is low) 0.101
        let first = summary.lines().nth(1).unwrap();
        assert!(
            first.starts_with("0,kp1,,1,3,0.3333333333333333,"),
            "{first}"
        );
        let fields: Vec<f64> = first
            .split(',')
            .skip(6)
            .take(2)
            .map(|v| v.parse().unwrap())
            .collect();
        assert!(
            (fields[0] - 0.11).abs() < 1e-12 && (fields[1] - 0.101).abs() < 1e-12,
            "{first}"
        );
        // a statistic some replicate has no value for is empty
        assert!(first.contains(",0.11000000000000001,0.101,,,"), "{first}");
        // cell 1's replicate rows are cut short on disk: it must run again
        let cut = reps.trim_end().rsplit_once('\n').unwrap().0.to_string() + "\n";
        std::fs::write(dir.join(REPLICATES), cut).unwrap();
        let mut w = RunWriter::new(Some(&dir), Existing::Resume, manifest(c.clone())).unwrap();
        assert_eq!(w.done().collect::<Vec<_>>(), vec![0]);
        w.create().unwrap();
        w.add(&[
            replicated(cells[1].clone(), 3),
            replicated(cells[2].clone(), 3),
        ])
        .unwrap();
        w.finish(true).unwrap();
        let again = std::fs::read_to_string(dir.join(REPLICATES)).unwrap();
        assert_eq!(again.lines().count(), 1 + 9);
        assert_eq!(
            again.lines().take(7).collect::<Vec<_>>(),
            reps.lines().take(7).collect::<Vec<_>>()
        );
        let back = crate::results::tables::read_run(&dir).unwrap();
        let replicates = back.details.iter().find(|(f, _, _)| f == REPLICATES);
        assert_eq!(
            (back.rows.len(), replicates.map(|(_, _, r)| r.len())),
            (3, Some(9))
        );
        assert_eq!(names(&dir), [LOCK, MANIFEST, REPLICATES, SUMMARY]);
    }

    #[test]
    fn write_refuse_resume() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("run");
        let c = cfg("kp=1,2", false);
        let cells = c.grid.cells();
        let mut w = RunWriter::new(Some(&dir), Existing::Refuse, manifest(c.clone())).unwrap();
        assert!(!dir.exists(), "nothing is created before the run starts");
        w.add(&[result(cells[1].clone())]).unwrap();
        assert_eq!(read_manifest(&dir).unwrap().cells_done, 1);
        w.finish(false).unwrap();
        let text = std::fs::read_to_string(dir.join(SUMMARY)).unwrap();
        assert!(text.starts_with("index,id,name,kp,final_z,"));
        assert!(
            text.contains("\n1,kp2,,2,0.1,,0.3333333333333333,"),
            "{text}"
        );
        assert_eq!(names(&dir), [LOCK, MANIFEST, SUMMARY], "no temp files left");
        assert!(!read_manifest(&dir).unwrap().complete);

        let e = RunWriter::new(Some(&dir), Existing::Refuse, manifest(c.clone()))
            .err()
            .unwrap();
        assert_eq!(e.code(), "run_exists");
        let e = RunWriter::new(Some(&dir), Existing::Resume, manifest(cfg("kp=1,3", false)))
            .err()
            .unwrap();
        assert_eq!(e.code(), "resume_mismatch");
        assert!(e.to_string().contains("grid"), "{e}");
        let w = RunWriter::new(Some(&dir), Existing::Resume, manifest(c)).unwrap();
        assert_eq!(w.done().collect::<Vec<_>>(), vec![1]);
    }

    #[test]
    fn a_target_that_is_not_a_regular_file_is_refused_and_kept() {
        use std::os::unix::fs::FileTypeExt;
        // a socket stands in for a FIFO or a device: a node a rename would replace
        let tmp = tempfile::tempdir().unwrap();
        let node = tmp.path().join("summary.csv");
        let _listener = std::os::unix::net::UnixListener::bind(&node).unwrap();
        let e = write_atomic(&node, b"x").unwrap_err();
        assert_eq!(e.code(), "output");
        assert!(
            e.to_string().contains("not a regular file (a socket)"),
            "{e}"
        );
        assert!(
            std::fs::symlink_metadata(&node)
                .unwrap()
                .file_type()
                .is_socket()
        );
        // nothing else left beside it
        assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 1);
        // a regular file, or none, is written as before
        write_atomic(&tmp.path().join("new.csv"), b"a\n").unwrap();
        write_atomic(&tmp.path().join("new.csv"), b"b\n").unwrap();
        assert_eq!(std::fs::read(tmp.path().join("new.csv")).unwrap(), b"b\n");
    }

    #[test]
    fn a_run_over_a_directory_holding_a_node_is_refused_before_it_starts() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("run");
        std::fs::create_dir(&dir).unwrap();
        let _listener = std::os::unix::net::UnixListener::bind(dir.join("report.html")).unwrap();
        let c = cfg("kp=1,2", false);
        for existing in [Existing::Overwrite, Existing::Resume] {
            let e = RunWriter::new(Some(&dir), existing, manifest(c.clone()))
                .err()
                .unwrap();
            assert!(e.to_string().contains("report.html"), "{e}");
        }
        // nothing was written there
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
    }

    #[test]
    fn a_second_writer_is_refused_while_the_first_holds_the_lock() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("run");
        let c = cfg("kp=1,2", false);
        let mut first = RunWriter::new(Some(&dir), Existing::Refuse, manifest(c.clone())).unwrap();
        first.create().unwrap();
        let e = RunWriter::new(Some(&dir), Existing::Overwrite, manifest(c.clone()))
            .err()
            .unwrap();
        assert_eq!(e.code(), "run_busy");
        assert!(
            e.to_string()
                .contains(&format!("pid {}", std::process::id())),
            "{e}"
        );
        first.finish(false).unwrap();
        drop(first);
        // released with its writer
        let mut again = RunWriter::new(Some(&dir), Existing::Overwrite, manifest(c)).unwrap();
        again.create().unwrap();
    }

    #[test]
    fn unique_names_never_collide() {
        let tmp = tempfile::tempdir().unwrap();
        let base = tmp.path().join("runs").join("stamp-kp");
        let c = cfg("kp=1", false);
        let dirs: Vec<PathBuf> = (0..3)
            .map(|_| {
                let mut w =
                    RunWriter::new(Some(&base), Existing::Unique, manifest(c.clone())).unwrap();
                w.create().unwrap();
                w.dir().unwrap().to_path_buf()
            })
            .collect();
        let shown: Vec<String> = dirs
            .iter()
            .map(|d| d.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(shown, ["stamp-kp", "stamp-kp-1", "stamp-kp-2"]);
    }

    #[test]
    fn resume_keeps_traces_and_drops_a_truncated_line() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("run");
        let c = cfg("kp=1,2,3", true);
        let cells = c.grid.cells();
        let mut w = RunWriter::new(Some(&dir), Existing::Refuse, manifest(c.clone())).unwrap();
        w.add(&[result(cells[0].clone()), result(cells[1].clone())])
            .unwrap();
        drop(w); // killed: no finish
        // a write cut short leaves half a row
        let mut f = OpenOptions::new()
            .append(true)
            .open(dir.join(SUMMARY))
            .unwrap();
        f.write_all(b"2,kp3,,3,0.1").unwrap();
        std::fs::write(dir.join(".manifest.json.tmp999"), b"{").unwrap();
        let mut w = RunWriter::new(Some(&dir), Existing::Resume, manifest(c.clone())).unwrap();
        assert_eq!(w.done().collect::<Vec<_>>(), vec![0, 1]);
        assert_eq!(w.traces().count(), 2);
        w.create().unwrap();
        w.add(&[result(cells[2].clone())]).unwrap();
        w.finish(true).unwrap();
        assert!(read_manifest(&dir).unwrap().complete);
        let traces = std::fs::read_to_string(dir.join(TRACES)).unwrap();
        assert_eq!(
            traces,
            "id,t,z\nkp1,0.002,0.25\nkp2,0.002,0.25\nkp3,0.002,0.25\n"
        );
        assert_eq!(names(&dir), [LOCK, MANIFEST, SUMMARY, TRACES]);
    }

    /// What a kill at each step of [`RunWriter::create`] leaves, in its
    /// order: the directory made, its lock taken and signed, each table
    /// through its temporary file, then the manifest's temporary file. Each
    /// is resumed with the full command into exactly what one run writes.
    #[test]
    fn a_run_killed_at_any_step_of_creating_its_directory_resumes_afresh() {
        let tmp = tempfile::tempdir().unwrap();
        let c = cfg("kp=1,2,3", true);
        let cells: Vec<CellResult> = c.grid.cells().into_iter().map(result).collect();
        let whole = |dir: &Path, existing: Existing| {
            let mut w = RunWriter::new(Some(dir), existing, manifest(c.clone())).unwrap();
            assert_eq!(w.done().count(), 0, "{}", dir.display());
            w.add(&cells).unwrap();
            w.finish(true).unwrap();
        };
        let want = tmp.path().join("one-run");
        whole(&want, Existing::Refuse);
        let header = |name: &str| {
            let text = std::fs::read_to_string(want.join(name)).unwrap();
            text.lines().next().unwrap().to_string() + "\n"
        };
        let steps: [&[(&str, String)]; 7] = [
            &[],
            &[(LOCK, String::new())],
            &[(LOCK, "pid 1 on host, since unix time 0".into())],
            &[(LOCK, String::new()), (".traces.csv.tmp77", "id,t".into())],
            &[(LOCK, String::new()), (TRACES, header(TRACES))],
            &[
                (LOCK, String::new()),
                (TRACES, header(TRACES)),
                (".summary.csv.tmp77", header(SUMMARY)),
            ],
            &[
                (LOCK, String::new()),
                (TRACES, header(TRACES)),
                (SUMMARY, header(SUMMARY)),
                (".manifest.json.tmp77", "{".into()),
            ],
        ];
        for (k, files) in steps.iter().enumerate() {
            let dir = tmp.path().join(format!("killed-{k}"));
            std::fs::create_dir(&dir).unwrap();
            for (name, text) in files.iter() {
                std::fs::write(dir.join(name), text).unwrap();
            }
            whole(&dir, Existing::Resume);
            for name in [SUMMARY, TRACES] {
                assert_eq!(
                    std::fs::read(dir.join(name)).unwrap(),
                    std::fs::read(want.join(name)).unwrap(),
                    "step {k}: {name}"
                );
            }
            assert!(read_manifest(&dir).unwrap().complete, "step {k}");
            assert_eq!(names(&dir), [LOCK, MANIFEST, SUMMARY, TRACES], "step {k}");
        }
        // a path no run ever created is nothing to resume: refused, naming it
        let never = tmp.path().join("never-made");
        let e = RunWriter::new(Some(&never), Existing::Resume, manifest(c.clone()))
            .err()
            .unwrap();
        assert!(e.to_string().contains("never-made"), "{e}");
        assert!(!never.exists());
    }

    #[test]
    fn rows_of_another_grid_are_refused_with_their_line() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("run");
        let c = cfg("kp=1,2", false);
        let mut w = RunWriter::new(Some(&dir), Existing::Refuse, manifest(c.clone())).unwrap();
        w.finish(false).unwrap();
        drop(w);
        let mut f = OpenOptions::new()
            .append(true)
            .open(dir.join(SUMMARY))
            .unwrap();
        f.write_all(b"129,kp9,,9,0.1,,,,,,,,ok,\n").unwrap();
        let e = RunWriter::new(Some(&dir), Existing::Resume, manifest(c))
            .err()
            .unwrap();
        assert!(e.to_string().contains("summary.csv:2: index '129'"), "{e}");
    }
}
