//! `pupper merge`: the shards of one sweep as one run directory.

use std::path::PathBuf;

use clap::Args;
use pupper_core::Result;
use pupper_core::results::rundir::Existing;

use super::args::rundir_name;

#[derive(Args, Debug)]
pub(super) struct MergeArgs {
    /// The shards' run directories (e.g. runs/study-shard-*).
    #[arg(required = true, value_name = "DIR")]
    dirs: Vec<PathBuf>,
    /// The merged run directory (default runs/<time>-merged).
    #[arg(long, short = 'o', value_name = "OUT")]
    out: Option<PathBuf>,
    /// Overwrite pupper's files in an existing OUT.
    #[arg(long)]
    force: bool,
    /// Print {"out", "shards", "cells"} as JSON instead of the "merged" line.
    #[arg(long)]
    json: bool,
}

impl MergeArgs {
    pub(super) fn run(self) -> Result<u8> {
        let (out, existing) = match (self.out, self.force) {
            (Some(o), true) => (o, Existing::Overwrite),
            (Some(o), false) => (o, Existing::Refuse),
            (None, _) => (rundir_name("merged"), Existing::Unique),
        };
        let (dir, m) = pupper_core::results::merge::merge(&self.dirs, &out, existing)?;
        if self.json {
            outln!(
                "{}",
                serde_json::json!({"out": dir, "shards": m.merged.len(), "cells": m.cells_total})
            );
            return Ok(0);
        }
        outln!(
            "merged {} shards ({} cells) into {}",
            m.merged.len(),
            m.cells_total,
            dir.join("summary.csv").display()
        );
        Ok(0)
    }
}
