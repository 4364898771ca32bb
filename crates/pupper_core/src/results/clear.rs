//! What a run directory holds of one run, whatever kind wrote it: the one
//! list of the files every kind of pupper writes there, so that `--force`
//! leaves nothing of an older run (of this kind or another) and `--resume`
//! continues only a run of its own kind.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::results::output::MANIFEST;

/// Every file a pupper run writes at the top of its directory, every kind
/// (sweep, lab, response, hold, walk, merge; tune; fit; recommend) together.
pub const RUN_FILES: &[&str] = &[
    // the Rust kinds' tables and what follows them
    "summary.csv",
    MANIFEST,
    "traces.csv",
    "replicates.csv",
    "response.csv",
    "bode.csv",
    "response_traces.csv",
    "best.csv",
    "report.html",
    "MUJOCO_LOG.TXT",
    // tune
    "study.db",
    "study.db-journal",
    "study.db-wal",
    "study.db-shm",
    "journal.jsonl",
    "trials.csv",
    "best.json",
    "pareto.csv",
    // fit
    "fit.csv",
    "residuals.csv",
    "warnings.csv",
    "calibrated.xml",
    "robots.csv",
    "validation.csv",
    "validation_bode.csv",
    // recommend
    "recommend.csv",
    "tradeoffs.csv",
    "recommended.yaml",
    "recommended.xml",
];

/// The folders a run fills with files of its own, and the endings of
/// those files: figures and renderings (`plots/`), recommend's drawn
/// robots (`robots/`). A folder left empty is removed.
const RUN_FOLDERS: &[(&str, &[&str])] = &[
    ("plots", &["png", "gif", "csv", "svg", "html"]),
    ("robots", &["xml"]),
];

/// The files of an older run in `dir`, any kind's: the top-level names of
/// [`RUN_FILES`] that exist, and the files of [`RUN_FOLDERS`].
fn old_files(dir: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = RUN_FILES
        .iter()
        .map(|n| dir.join(n))
        .filter(|p| std::fs::symlink_metadata(p).is_ok())
        .collect();
    for (folder, endings) in RUN_FOLDERS {
        let Ok(entries) = std::fs::read_dir(dir.join(folder)) else {
            continue;
        };
        found.extend(entries.flatten().map(|e| e.path()).filter(|p| {
            p.extension()
                .and_then(|x| x.to_str())
                .is_some_and(|x| endings.contains(&x))
        }));
    }
    found
}

/// Removes every file an older run of any kind left in `dir` (`--force`),
/// and its folders once empty; a user's own files stay. Each is refused
/// first if it is not a regular file (a FIFO, a device), so nothing is
/// removed when one is.
pub fn clear_run(dir: &Path) -> Result<()> {
    let old = old_files(dir);
    for p in &old {
        crate::results::files::refuse_non_regular(p)?;
    }
    for p in &old {
        match std::fs::remove_file(p) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(Error::io("remove", p, e)),
        }
    }
    for (folder, _) in RUN_FOLDERS {
        // only when empty: a folder holding a user's files stays
        let _ = std::fs::remove_dir(dir.join(folder));
    }
    Ok(())
}

/// The kind a run directory's manifest names ("" for one written before
/// kinds were recorded), or None without a readable manifest. Read
/// leniently: tune's, fit's and recommend's manifests are not a sweep's.
pub fn kind_of(dir: &Path) -> Option<String> {
    let text = std::fs::read_to_string(dir.join(MANIFEST)).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    Some(v.get("kind")?.as_str().unwrap_or_default().to_string())
}

/// Refuses to resume `dir` with a command of `kind` when another kind's
/// run is there, in one line naming both (and the command that continues
/// it, where that kind resumes).
pub fn check_kind(dir: &Path, kind: &str) -> Result<()> {
    let Some(was) = kind_of(dir) else {
        return Ok(());
    };
    // a manifest from before kinds were recorded is a sweep runner's
    if was.is_empty() || was == kind {
        return Ok(());
    }
    let fix = match was.as_str() {
        "sweep" | "lab" | "response" | "hold" | "walk" | "tune" => {
            format!("continue it with `pupper {was} --resume {}`", dir.display())
        }
        _ => format!("give --resume a {kind} run's directory"),
    };
    Err(Error::ResumeMismatch(format!(
        "cannot resume '{}': it holds a {was} run, and `pupper {kind}` continues only {kind} runs: {fix}, or use a new --out",
        dir.display()
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_forced_run_leaves_no_file_of_any_kind_and_keeps_the_users() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        for n in [
            "fit.csv",
            "calibrated.xml",
            "recommended.yaml",
            "summary.csv",
            "mine.txt",
        ] {
            std::fs::write(d.join(n), "x").unwrap();
        }
        std::fs::create_dir(d.join("robots")).unwrap();
        std::fs::write(d.join("robots").join("robot_0.xml"), "x").unwrap();
        std::fs::create_dir(d.join("plots")).unwrap();
        std::fs::write(d.join("plots").join("fit_old.png"), "x").unwrap();
        std::fs::write(d.join("plots").join("notes.txt"), "x").unwrap();
        clear_run(d).unwrap();
        let mut left: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, ["mine.txt", "plots"]);
        assert!(d.join("plots").join("notes.txt").exists());
    }

    #[test]
    fn another_kinds_run_is_not_resumed() {
        let tmp = tempfile::tempdir().unwrap();
        std::fs::write(tmp.path().join(MANIFEST), r#"{"kind": "walk"}"#).unwrap();
        let e = check_kind(tmp.path(), "sweep").unwrap_err().to_string();
        assert!(
            e.contains("walk run") && e.contains("only sweep runs"),
            "{e}"
        );
        assert!(e.contains("pupper walk --resume"), "{e}");
        check_kind(tmp.path(), "walk").unwrap();
        std::fs::write(tmp.path().join(MANIFEST), r#"{"kind": "fit"}"#).unwrap();
        let e = check_kind(tmp.path(), "walk").unwrap_err().to_string();
        assert!(
            e.contains("fit run") && !e.contains("pupper fit --resume"),
            "{e}"
        );
    }
}
