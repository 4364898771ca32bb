//! A `pupper fit` run directory, checked before it is believed: its
//! manifest says it is a fit's, and the files it names (fit.csv,
//! calibrated.xml, robots.csv) are there and are the bytes it wrote (their
//! SHA-256 in the manifest's `outputs`). `gains --from-fit` and `recommend
//! --from-fit` read a fit through it; an edited or mixed-up run is refused
//! in one line, not silently run.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::error::{Error, Result};
use crate::robot::model::sha256_hex;

/// The files of a fit run every reader needs; robots.csv too where the
/// manifest names it.
const NEEDED: [&str; 2] = ["fit.csv", "calibrated.xml"];

/// The checked fit run in `dir`: its calibrated model's path. Refused
/// (one line naming the directory, what is wrong and the fix) where the
/// manifest is missing or not a fit's, a file it needs is missing, or a
/// file differs from what the fit wrote.
pub fn calibrated(dir: &Path) -> Result<PathBuf> {
    let bad = |what: String| {
        Err(Error::Config(format!(
            "--from-fit {}: {what}",
            dir.display()
        )))
    };
    let manifest = dir.join("manifest.json");
    let text = match std::fs::read_to_string(&manifest) {
        Ok(t) => t,
        Err(_) if !dir.is_dir() => {
            return bad(
                "no such directory: give the run directory `pupper fit -o DIR` wrote".into(),
            );
        }
        Err(_) => {
            return bad("no manifest.json: not a `pupper fit` run directory; give the one `pupper fit -o DIR` wrote".into());
        }
    };
    // Python's json writes NaN and ±Infinity as bare words, which JSON has
    // not: read as null (inside a string, still a string)
    let text = text
        .replace("-Infinity", "null")
        .replace("Infinity", "null")
        .replace("NaN", "null");
    let m: Value = match serde_json::from_str(&text) {
        Ok(v) => v,
        Err(e) => {
            return bad(format!(
                "manifest.json is not JSON ({e}): run `pupper fit` again"
            ));
        }
    };
    match m.get("kind").and_then(Value::as_str) {
        Some("fit") => {}
        Some(other) => {
            return bad(format!(
                "its manifest is a {other} run's, not a fit's: give a `pupper fit` run directory"
            ));
        }
        None => return bad("its manifest names no kind: give a `pupper fit` run directory".into()),
    }
    for name in NEEDED {
        if !dir.join(name).is_file() {
            return bad(format!(
                "{name} is missing: the run is incomplete; run `pupper fit` again"
            ));
        }
    }
    // each file the fit recorded is the one it wrote (a run made before the
    // fit recorded them is taken as it is)
    if let Some(outputs) = m.get("outputs").and_then(Value::as_object) {
        for (name, want) in outputs {
            let Some(want) = want.as_str() else { continue };
            let path = dir.join(name);
            let got = match std::fs::read(&path) {
                Ok(bytes) => sha256_hex(&bytes),
                Err(_) => {
                    return bad(format!(
                        "{name}, which the fit wrote, is missing: run `pupper fit` again"
                    ));
                }
            };
            if got != want {
                return bad(format!(
                    "{name} is not the file the fit wrote (its SHA-256 differs from the manifest's): it was edited or copied from another run; run `pupper fit` again, or restore it"
                ));
            }
        }
    }
    Ok(dir.join("calibrated.xml"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(files: &[(&str, &str)], manifest: &str) -> tempfile::TempDir {
        let d = tempfile::tempdir().unwrap();
        for (n, t) in files {
            std::fs::write(d.path().join(n), t).unwrap();
        }
        std::fs::write(d.path().join("manifest.json"), manifest).unwrap();
        d
    }

    #[test]
    fn a_fit_run_is_checked_against_its_manifest() {
        let sha = |t: &str| sha256_hex(t.as_bytes());
        let manifest = format!(
            r#"{{"kind": "fit", "outputs": {{"fit.csv": "{}", "calibrated.xml": "{}"}}}}"#,
            sha("a"),
            sha("<mujoco/>")
        );
        // Python's NaN and Infinity in it are read
        let manifest = manifest.replacen('{', r#"{"x": [NaN, -Infinity, Infinity], "#, 1);
        let d = run(
            &[("fit.csv", "a"), ("calibrated.xml", "<mujoco/>")],
            &manifest,
        );
        assert_eq!(
            calibrated(d.path()).unwrap(),
            d.path().join("calibrated.xml")
        );
        // an edited file
        std::fs::write(d.path().join("fit.csv"), "b").unwrap();
        let e = calibrated(d.path()).unwrap_err().to_string();
        assert!(e.contains("fit.csv is not the file the fit wrote"), "{e}");
        // another kind's run
        let d = run(
            &[("fit.csv", "a"), ("calibrated.xml", "x")],
            r#"{"kind": "sweep"}"#,
        );
        let e = calibrated(d.path()).unwrap_err().to_string();
        assert!(e.contains("a sweep run's, not a fit's"), "{e}");
        // a file missing
        let d = run(&[("fit.csv", "a")], r#"{"kind": "fit"}"#);
        assert!(
            calibrated(d.path())
                .unwrap_err()
                .to_string()
                .contains("calibrated.xml is missing")
        );
        // no run at all
        let e = calibrated(Path::new("/no/such/dir"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no such directory"), "{e}");
    }
}
