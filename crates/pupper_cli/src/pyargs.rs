//! Flags for a command whose work is in pupper's Python package, as the
//! JSON text its `_cli` function reads.
//!
//! Paths are the one thing serde_json cannot carry: a path need not be
//! UTF-8, and serde_json writes only `str`s. Python's `json` reads a lone
//! surrogate escape `\udcXX`, which `os.fsencode` turns back into the byte
//! XX (the `surrogateescape` rule Python uses for every path it is given),
//! so such a path goes in as a placeholder and leaves as that escape.

use std::cell::RefCell;
use std::ffi::OsStr;
use std::os::unix::ffi::OsStrExt;

use serde::{Serialize, Serializer};

thread_local! {
    /// The literals of the paths [`to_text`] is serializing that are not
    /// UTF-8, by placeholder index.
    static LITERALS: RefCell<Vec<String>> = const { RefCell::new(Vec::new()) };
}

/// A command's flags as the JSON text its `_cli` function reads: `args`
/// serialize themselves (their fields named as Python's keywords), their
/// paths through [`path`], [`opt_path`] or [`paths`].
pub fn to_text<T: Serialize>(args: &T) -> serde_json::Result<String> {
    LITERALS.with(|l| l.borrow_mut().clear());
    let value = serde_json::to_value(args);
    let literals = LITERALS.with(|l| std::mem::take(&mut *l.borrow_mut()));
    Ok(PyArgs { literals }.text(&value?))
}

/// Serializes a path as [`PyArgs::path`] does (for `serialize_with`).
pub fn path<P: AsRef<OsStr>, S: Serializer>(p: &P, s: S) -> Result<S::Ok, S::Error> {
    let bytes = p.as_ref().as_bytes();
    if let Ok(text) = std::str::from_utf8(bytes) {
        return s.serialize_str(text);
    }
    let i = LITERALS.with(|l| {
        let mut l = l.borrow_mut();
        l.push(escaped(bytes));
        l.len() - 1
    });
    s.serialize_str(&format!("\0{i}\0"))
}

/// An optional path: null when absent.
pub fn opt_path<P: AsRef<OsStr>, S: Serializer>(p: &Option<P>, s: S) -> Result<S::Ok, S::Error> {
    match p {
        Some(p) => path(p, s),
        None => s.serialize_none(),
    }
}

/// Paths as a list.
#[allow(dead_code)] // fit and excite take lists of logs
pub fn paths<P: AsRef<OsStr>, S: Serializer>(ps: &[P], s: S) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeSeq;
    let mut seq = s.serialize_seq(Some(ps.len()))?;
    for p in ps {
        seq.serialize_element(&PathOf(p.as_ref()))?;
    }
    seq.end()
}

#[allow(dead_code)]
struct PathOf<'a>(&'a OsStr);

impl Serialize for PathOf<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        path(&self.0, s)
    }
}

/// Paths as a list, or null when none is given (a repeatable path flag left out).
pub fn paths_or_none<P: AsRef<OsStr>, S: Serializer>(ps: &[P], s: S) -> Result<S::Ok, S::Error> {
    if ps.is_empty() {
        s.serialize_none()
    } else {
        paths(ps, s)
    }
}

/// A repeatable flag given no times is the keyword left out: null.
pub fn none_if_empty<T: Serialize, S: Serializer>(v: &[T], s: S) -> Result<S::Ok, S::Error> {
    if v.is_empty() {
        s.serialize_none()
    } else {
        v.serialize(s)
    }
}

/// Builds the JSON text of a command's flags, paths included.
#[derive(Debug, Default)]
pub struct PyArgs {
    /// The JSON literal of each path that is not UTF-8, by placeholder index.
    literals: Vec<String>,
}

impl PyArgs {
    pub fn new() -> PyArgs {
        PyArgs::default()
    }

    /// A path as a JSON value: a string when it is UTF-8 (the JSON is then
    /// what it always was), else a placeholder that [`PyArgs::text`] swaps
    /// for its escaped literal.
    pub fn path(&mut self, path: impl AsRef<OsStr>) -> serde_json::Value {
        let bytes = path.as_ref().as_bytes();
        if let Ok(text) = std::str::from_utf8(bytes) {
            return serde_json::Value::String(text.to_string());
        }
        self.literals.push(escaped(bytes));
        // NUL cannot be in an argument or a path: no flag can spell this
        serde_json::Value::String(format!("\0{}\0", self.literals.len() - 1))
    }

    /// The JSON text of `args`, every placeholder replaced by its path.
    pub fn text(&self, args: &serde_json::Value) -> String {
        let mut text = args.to_string();
        for (i, literal) in self.literals.iter().enumerate() {
            text = text.replace(&format!("\"\\u0000{i}\\u0000\""), literal);
        }
        text
    }
}

/// The JSON string literal of a path's bytes: UTF-8 runs as serde_json
/// writes them, every other byte as Python's surrogate escape.
fn escaped(bytes: &[u8]) -> String {
    let mut out = String::from("\"");
    for chunk in bytes.utf8_chunks() {
        let valid = serde_json::Value::String(chunk.valid().to_string()).to_string();
        out.push_str(&valid[1..valid.len() - 1]);
        for b in chunk.invalid() {
            out.push_str(&format!("\\udc{b:02x}"));
        }
    }
    out.push('"');
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::OsString;
    use std::os::unix::ffi::OsStringExt;

    #[test]
    fn a_utf8_path_is_a_plain_string() {
        let mut a = PyArgs::new();
        let v = serde_json::json!({"out": a.path("runs/a \"b\"")});
        assert_eq!(a.text(&v), r#"{"out":"runs/a \"b\""}"#);
    }

    #[test]
    fn other_bytes_cross_as_surrogate_escapes() {
        let mut a = PyArgs::new();
        let odd = OsString::from_vec(b"r\xffun/\xe9\"x".to_vec());
        let v = serde_json::json!({"out": a.path(&odd), "b": a.path("b")});
        assert_eq!(a.text(&v), r#"{"out":"r\udcffun/\udce9\"x","b":"b"}"#);
    }

    #[test]
    fn serialized_args_carry_their_paths_as_the_builder_does() {
        #[derive(Serialize)]
        struct Args {
            #[serde(serialize_with = "paths")]
            logs: Vec<OsString>,
            #[serde(serialize_with = "opt_path")]
            out: Option<OsString>,
            #[serde(serialize_with = "opt_path")]
            none: Option<OsString>,
            #[serde(serialize_with = "none_if_empty")]
            spread: Vec<String>,
            seed: u64,
        }
        let odd = OsString::from_vec(b"r\xffun/\xe9\"x".to_vec());
        let args = Args {
            logs: vec![odd.clone(), "b".into()],
            out: Some(odd),
            none: None,
            spread: vec![],
            seed: 3,
        };
        assert_eq!(
            to_text(&args).unwrap(),
            r#"{"logs":["r\udcffun/\udce9\"x","b"],"out":"r\udcffun/\udce9\"x","none":null,"spread":null,"seed":3}"#
        );
    }

    #[test]
    fn ten_paths_do_not_mix_their_placeholders() {
        #[derive(Serialize)]
        struct Args {
            #[serde(serialize_with = "paths")]
            logs: Vec<OsString>,
        }
        let logs: Vec<OsString> = (0..12u8)
            .map(|i| OsString::from_vec(vec![b'p', 0xf0 + i / 4, b'0' + i]))
            .collect();
        let text = to_text(&Args { logs }).unwrap();
        assert!(
            text.ends_with(r#""p\udcf29","p\udcf2:","p\udcf2;"]}"#),
            "{text}"
        );
        assert!(!text.contains("u0000"), "{text}");
    }
}
