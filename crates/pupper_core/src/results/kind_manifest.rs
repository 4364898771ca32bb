//! The manifest of a run whose kind Python drives (fit, tune, recommend):
//! the kind builds its body; the run directory heads it with the stamp
//! every manifest carries (the kind, and which pupper, MuJoCo and Python
//! wrote it) and writes it the way a sweep's is written, whole or not at
//! all.

use std::path::Path;

use crate::error::{Error, Result};
use crate::results::files::write_atomic;
use crate::results::json::Doc;
use crate::results::output::MANIFEST;

/// Which MuJoCo and which Python ran the kind (pupper's own version is
/// this crate's).
#[derive(Debug, Clone)]
pub struct Stamp {
    pub mujoco_version: String,
    /// The interpreter's executable, as a sweep's manifest names it.
    pub python: String,
}

/// The kinds whose manifest body Python builds; every other kind's
/// manifest is a [`crate::results::output::Manifest`].
pub const KINDS: [&str; 3] = ["fit", "tune", "recommend"];

/// The keys the stamp owns, first in every manifest, a sweep's too.
pub const STAMP_KEYS: [&str; 4] = ["kind", "pupper_version", "mujoco_version", "python"];

/// The manifest text: the stamp, then `body`'s fields in their order.
pub fn manifest_text(kind: &str, stamp: &Stamp, body: Doc) -> Result<String> {
    if !KINDS.contains(&kind) {
        return Err(Error::Internal(format!(
            "'{kind}' is not a kind whose manifest Python builds ({})",
            KINDS.join(", ")
        )));
    }
    let Doc::Map(fields) = body else {
        return Err(Error::Internal(format!(
            "a {kind} manifest's body must be a map"
        )));
    };
    if let Some((k, _)) = fields
        .iter()
        .find(|(k, _)| STAMP_KEYS.contains(&k.as_str()))
    {
        return Err(Error::Internal(format!(
            "a {kind} manifest's body sets '{k}', which the stamp owns"
        )));
    }
    let text = |s: &str| Doc::Text(s.to_string());
    let mut all = vec![
        ("kind".to_string(), text(kind)),
        ("pupper_version".to_string(), text(crate::VERSION)),
        ("mujoco_version".to_string(), text(&stamp.mujoco_version)),
        ("python".to_string(), text(&stamp.python)),
    ];
    all.extend(fields);
    let mut out = String::new();
    Doc::Map(all).write_python_pretty(&mut out, 0)?;
    out.push('\n');
    Ok(out)
}

/// Writes `dir/manifest.json` (see [`manifest_text`]) through a temporary
/// file renamed into place.
pub fn write_manifest(dir: &Path, kind: &str, stamp: &Stamp, body: Doc) -> Result<()> {
    write_atomic(
        &dir.join(MANIFEST),
        manifest_text(kind, stamp, body)?.as_bytes(),
    )
}

/// The text of `dir`'s manifest, whichever kind wrote it: one line naming
/// the fix where there is none.
pub fn read_text(dir: &Path) -> Result<String> {
    let path = dir.join(MANIFEST);
    std::fs::read_to_string(&path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => Error::RunNotFound(format!(
            "'{}' holds no pupper run (no {MANIFEST}): give the directory a pupper command wrote",
            dir.display()
        )),
        _ => Error::io("read", &path, e),
    })
}

/// What kind of run a manifest's text says it is, as far as a glance at
/// its head tells ([`STAMP_KEYS`] first; None for an old sweep's manifest,
/// which named no kind, or for text that is no manifest).
pub fn kind_of(text: &str) -> Option<String> {
    #[derive(serde::Deserialize)]
    struct Head {
        kind: String,
    }
    // the kind is the first field: read up to it only (a Python kind's body
    // may hold NaN, which serde_json does not read)
    let start = text.find("\"kind\"")?;
    let end = start + text[start..].find(',').unwrap_or(text.len() - start);
    serde_json::from_str::<Head>(&format!("{{{}}}", &text[start..end]))
        .ok()
        .map(|h| h.kind)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stamp() -> Stamp {
        Stamp {
            mujoco_version: "9.9.9".into(),
            python: "/x/python".into(),
        }
    }

    #[test]
    fn the_stamp_heads_the_body_in_pythons_json_dialect() {
        let body = Doc::Map(vec![
            (
                "fit".into(),
                Doc::Map(vec![("kp".into(), Doc::Float(f64::INFINITY))]),
            ),
            (
                "low".into(),
                Doc::List(vec![
                    Doc::Float(f64::NAN),
                    Doc::Float(-f64::INFINITY),
                    Doc::Float(0.5),
                ]),
            ),
            ("none".into(), Doc::List(vec![])),
            ("n".into(), Doc::Int(3)),
        ]);
        let t = manifest_text("fit", &stamp(), body).unwrap();
        let want = format!(
            "{{\n  \"kind\": \"fit\",\n  \"pupper_version\": \"{}\",\n  \"mujoco_version\": \"9.9.9\",\n  \"python\": \"/x/python\",\n  \"fit\": {{\n    \"kp\": Infinity\n  }},\n  \"low\": [\n    NaN,\n    -Infinity,\n    0.5\n  ],\n  \"none\": [],\n  \"n\": 3\n}}\n",
            crate::VERSION
        );
        assert_eq!(t, want);
    }

    #[test]
    fn the_kind_is_read_from_the_head() {
        let t = manifest_text(
            "fit",
            &stamp(),
            Doc::Map(vec![("x".into(), Doc::Float(f64::NAN))]),
        )
        .unwrap();
        assert_eq!(kind_of(&t).as_deref(), Some("fit"));
        assert_eq!(
            kind_of("{\n  \"kind\": \"sweep\",\n  \"config\": {}\n}").as_deref(),
            Some("sweep")
        );
        assert_eq!(kind_of("{\"pupper_version\": \"0.1\"}"), None);
        assert_eq!(kind_of("not json"), None);
    }

    #[test]
    fn only_a_python_kind_is_written_here() {
        assert!(manifest_text("sweep", &stamp(), Doc::Map(vec![])).is_err());
    }

    #[test]
    fn a_body_may_not_set_what_the_stamp_owns() {
        let body = Doc::Map(vec![("kind".into(), Doc::Text("sweep".into()))]);
        assert!(manifest_text("fit", &stamp(), body).is_err());
        assert!(manifest_text("fit", &stamp(), Doc::List(vec![])).is_err());
    }

    #[test]
    fn written_whole_into_the_directory() {
        let dir = tempfile::tempdir().unwrap();
        write_manifest(dir.path(), "tune", &stamp(), Doc::Map(vec![])).unwrap();
        let text = std::fs::read_to_string(dir.path().join(MANIFEST)).unwrap();
        assert!(text.starts_with("{\n  \"kind\": \"tune\","), "{text}");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .flatten()
            .map(|e| e.file_name())
            .collect();
        assert_eq!(names, [MANIFEST], "no temporary left");
    }
}
