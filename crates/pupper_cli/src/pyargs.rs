//! Flags for a command whose work is in pupper's Python package, as the
//! JSON text its `_cli` function reads.
//!
//! Paths are the one thing serde_json cannot carry: a path need not be
//! UTF-8, and serde_json writes only `str`s. Python's `json` reads a lone
//! surrogate escape `\udcXX`, which `os.fsencode` turns back into the byte
//! XX (the `surrogateescape` rule Python uses for every path it is given),
//! so such a path goes in as a placeholder and leaves as that escape.

use std::ffi::OsStr;
use std::os::unix::ffi::OsStrExt;

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

    /// Paths as a JSON list.
    pub fn paths<P: AsRef<OsStr>>(&mut self, paths: &[P]) -> serde_json::Value {
        serde_json::Value::Array(paths.iter().map(|p| self.path(p)).collect())
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
        let v =
            serde_json::json!({"logs": a.paths(&[odd.clone(), "b".into()]), "out": a.path(&odd)});
        assert_eq!(
            a.text(&v),
            r#"{"logs":["r\udcffun/\udce9\"x","b"],"out":"r\udcffun/\udce9\"x"}"#
        );
    }

    #[test]
    fn ten_paths_do_not_mix_their_placeholders() {
        let mut a = PyArgs::new();
        let paths: Vec<OsString> = (0..12u8)
            .map(|i| OsString::from_vec(vec![b'p', 0xf0 + i / 4, b'0' + i]))
            .collect();
        let v = a.paths(&paths);
        let text = a.text(&v);
        assert!(
            text.ends_with(r#""p\udcf29","p\udcf2:","p\udcf2;"]"#),
            "{text}"
        );
        assert!(!text.contains("u0000"), "{text}");
    }
}
