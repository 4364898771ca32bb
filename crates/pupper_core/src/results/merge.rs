//! `pupper merge`: finished shards of one sweep put together into one run
//! directory whose tables are those an unsharded run writes (its rows are
//! the same strings, written in cell order by the same writer).

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::plan::config::SweepConfig;
use crate::plan::shard::Shard;
use crate::results::output::{
    Manifest, MergedShard, config_diff, read_detail, read_manifest, read_rows, read_traces, short,
};
use crate::results::rundir::{Existing, RunWriter};
use crate::results::tables::header_of;

fn bad(text: String) -> Error {
    Error::Config(text)
}

/// Puts finished shards of one sweep together into one run directory at
/// `out`. Refuses, before writing anything, shards of different sweeps or
/// models, an incomplete shard, a shard given twice, and a missing one
/// (naming it and the command that runs it).
pub fn merge(dirs: &[PathBuf], out: &Path, existing: Existing) -> Result<(PathBuf, Manifest)> {
    check_out(dirs, out, existing)?;
    let mut parts: Vec<(&PathBuf, Manifest)> = Vec::with_capacity(dirs.len());
    for d in dirs {
        parts.push((d, read_manifest(d)?));
    }
    let count = check_shards(&parts)?;
    let config = parts[0].1.config.clone();
    let mut w = RunWriter::new(Some(out), existing, merged_manifest(&parts, count))?;
    for (d, m) in &parts {
        gather(&mut w, d, m, &config)?;
    }
    if w.rows.len() != w.manifest.cells_total {
        return Err(bad(format!(
            "the shards hold {} of the grid's {} cells: a shard directory was edited; rerun its shard",
            w.rows.len(),
            w.manifest.cells_total
        )));
    }
    w.manifest.batches = parts.iter().map(|(_, m)| m.batches).sum();
    w.create()?;
    w.finish(true)?;
    let dir = w.dir().unwrap_or(out).to_path_buf();
    Ok((dir, w.manifest.clone()))
}

/// The merged run is a new directory: never one of the shards it reads.
fn check_out(dirs: &[PathBuf], out: &Path, existing: Existing) -> Result<()> {
    if dirs.is_empty() {
        return Err(bad(
            "merge needs the shards' run directories: pupper merge DIR... -o OUT".into(),
        ));
    }
    let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    };
    if let Some(d) = dirs.iter().find(|d| same(d, out)) {
        return Err(Error::Output(format!(
            "-o '{}' is the shard '{}' itself: merge into a new directory",
            out.display(),
            d.display()
        )));
    }
    if existing == Existing::Refuse && out.exists() {
        return Err(Error::RunExists(format!(
            "output directory '{}' already exists: choose another -o, or add --force to overwrite it",
            out.display()
        )));
    }
    Ok(())
}

/// The shards' count, once every shard is one of the same sweep and
/// model, finished, given once, and none is missing.
fn check_shards(parts: &[(&PathBuf, Manifest)]) -> Result<u32> {
    let (first_dir, first) = (&parts[0].0, &parts[0].1);
    let count = match &first.shard {
        Some(s) => s.shard.count,
        None => {
            return Err(bad(format!(
                "'{}' is not a shard (it ran the whole grid, no --shard I/N): merge only shards of one sweep",
                first_dir.display()
            )));
        }
    };
    let mut seen: Vec<Option<&PathBuf>> = vec![None; count as usize];
    for (d, m) in parts {
        let Some(s) = &m.shard else {
            return Err(bad(format!(
                "'{}' is not a shard (no --shard I/N): merge only shards of one sweep",
                d.display()
            )));
        };
        // first: another model explains a config resolved on it (the push
        // scaled to its mass)
        if m.model.sha256 != first.model.sha256 {
            return Err(bad(format!(
                "'{}' and '{}' ran different models (SHA-256 {} vs {}): rerun one shard on the same model",
                first_dir.display(),
                d.display(),
                short(&first.model.sha256),
                short(&m.model.sha256)
            )));
        }
        let diff = config_diff(&first.config, &m.config);
        if !diff.is_empty() || s.shard.count != count {
            let what = match diff.is_empty() {
                true => format!("the number of shards ({} vs {count})", s.shard.count),
                false => diff.join(", "),
            };
            return Err(bad(format!(
                "'{}' and '{}' are shards of different sweeps (they differ in {what}): merge the shards of one sweep",
                first_dir.display(),
                d.display()
            )));
        }
        let slot = &mut seen[(s.shard.index - 1) as usize];
        if let Some(other) = slot {
            return Err(bad(format!(
                "shard {} is given twice ('{}' and '{}'): give each shard once",
                s.shard,
                other.display(),
                d.display()
            )));
        }
        *slot = Some(d);
        if !m.complete {
            return Err(bad(format!(
                "shard {} in '{}' is incomplete ({} of {} cells): finish it with pupper sweep --resume {}",
                s.shard,
                d.display(),
                m.cells_done,
                m.cells_total,
                d.display()
            )));
        }
    }
    let missing: Vec<String> = (0..count)
        .filter(|&i| seen[i as usize].is_none())
        .map(|i| format!("{}/{count}", i + 1))
        .collect();
    if !missing.is_empty() {
        return Err(bad(format!(
            "shard{} {} of this sweep {} missing: run the same pupper sweep command with --shard {} (and -o a new directory), then merge again",
            if missing.len() > 1 { "s" } else { "" },
            missing.join(", "),
            if missing.len() > 1 { "are" } else { "is" },
            missing[0]
        )));
    }
    Ok(count)
}

/// The merged run's manifest: the first shard's, with the shards listed.
fn merged_manifest(parts: &[(&PathBuf, Manifest)], count: u32) -> Manifest {
    let first = &parts[0].1;
    Manifest {
        cells_total: first.config.grid.len(),
        cells_done: 0,
        batches: 0,
        complete: false,
        wall_seconds: 0.0,
        started_unix: parts.iter().map(|(_, m)| m.started_unix).min().unwrap_or(0),
        command: std::env::args_os()
            .map(|a| a.to_string_lossy().into_owned())
            .collect(),
        shard: None,
        ray: None,
        merged: parts
            .iter()
            .map(|(d, m)| {
                let s = m.shard.as_ref().map(|s| (s.shard, s.host.clone()));
                let (shard, host) = s.unwrap_or((Shard { index: 0, count }, String::new()));
                MergedShard {
                    dir: d.display().to_string(),
                    index: shard.index,
                    count: shard.count,
                    host,
                    cells: m.cells_done,
                    wall_seconds: m.wall_seconds,
                    started_unix: m.started_unix,
                }
            })
            .collect(),
        ..first.clone()
    }
}

/// Adds one shard's rows, tables and traces to the writer, each file
/// checked to hold every cell its summary promises.
fn gather(w: &mut RunWriter, d: &Path, m: &Manifest, config: &SweepConfig) -> Result<()> {
    let rows = read_rows(d, config, &header_of(config))?;
    let shard = m.shard.as_ref().map(|s| s.shard);
    if let Some(i) = rows.keys().find(|&&i| shard.is_some_and(|s| !s.holds(i))) {
        return Err(bad(format!(
            "'{}' holds cell {i}, which is not its shard's: it was not written by pupper sweep --shard",
            d.display()
        )));
    }
    let lacking = |file: &str, have: &dyn Fn(&usize) -> bool| -> Result<()> {
        let gone: Vec<&str> = rows
            .iter()
            .filter(|(i, _)| !have(i))
            .map(|(_, r)| r[1].as_str())
            .collect();
        match gone.first() {
            None => Ok(()),
            Some(first) => Err(bad(format!(
                "'{}' has {} of {} cells without their rows in {file} (first: '{first}'): the file was cut or edited; recompute them with pupper sweep --resume {}, then merge again",
                d.display(),
                gone.len(),
                rows.len(),
                d.display()
            ))),
        }
    };
    for (k, detail) in w.details.iter().enumerate() {
        let got = read_detail(d, detail, &rows)?;
        lacking(detail.file, &|i| got.contains_key(i))?;
        w.detail_rows[k].extend(got);
    }
    if w.want_traces {
        let traces = read_traces(d, &rows)?;
        lacking(crate::results::output::TRACES, &|i| traces.contains_key(i))?;
        w.traces.extend(traces);
    }
    w.rows.extend(rows);
    Ok(())
}
