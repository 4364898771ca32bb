//! Every crate's sources stay readable: no file over 600 lines and no
//! function over 80, test code aside (an item under `#[cfg(test)]`, such as
//! the `mod tests` at a file's end). Read from the sources, so a file or a
//! function that grows past its limit fails here, named with its length.

use std::path::{Path, PathBuf};

const MAX_FILE_LINES: usize = 600;
const MAX_FN_LINES: usize = 80;

/// The `.rs` files under every crate's `src`, sorted.
fn sources() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut out = Vec::new();
    for entry in std::fs::read_dir(&crates).unwrap() {
        let src = entry.unwrap().path().join("src");
        if src.is_dir() {
            walk(&src, &mut out);
        }
    }
    out.sort();
    out
}

/// The text with comments, strings and character literals blanked to spaces
/// (newlines kept), so that the braces left are the code's own.
fn code_only(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let blank = |ch: char| if ch == '\n' { '\n' } else { ' ' };
    let mut i = 0;
    while i < c.len() {
        let at = |j: usize| c.get(j).copied();
        if c[i] == '/' && at(i + 1) == Some('/') {
            while i < c.len() && c[i] != '\n' {
                out.push(' ');
                i += 1;
            }
        } else if c[i] == '/' && at(i + 1) == Some('*') {
            // block comments nest in Rust
            let mut depth = 0;
            loop {
                if c[i] == '/' && at(i + 1) == Some('*') {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if c[i] == '*' && at(i + 1) == Some('/') {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    out.push(blank(c[i]));
                    i += 1;
                }
            }
        } else if c[i] == 'r'
            && (at(i + 1) == Some('"')
                || (at(i + 1) == Some('#') && matches!(at(i + 2), Some('"' | '#'))))
            && (i == 0 || !(c[i - 1].is_alphanumeric() || c[i - 1] == '_'))
        {
            // a raw string: r"…", r#"…"#, closed by the same count of #
            let mut hashes = 0;
            let mut j = i + 1;
            while c[j] == '#' {
                hashes += 1;
                j += 1;
            }
            j += 1; // the opening quote
            loop {
                if c[j] == '"' && (0..hashes).all(|h| c.get(j + 1 + h) == Some(&'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            out.extend(c[i..j].iter().map(|&ch| blank(ch)));
            i = j;
        } else if c[i] == '"' {
            let mut j = i + 1;
            while c[j] != '"' {
                j += if c[j] == '\\' { 2 } else { 1 };
            }
            out.extend(c[i..=j].iter().map(|&ch| blank(ch)));
            i = j + 1;
        } else if c[i] == '\'' {
            // a character literal ('x', '\n', '\u{..}'), not a lifetime ('a)
            let end = if at(i + 1) == Some('\\') {
                (i + 2..c.len()).find(|&j| c[j] == '\'')
            } else if at(i + 2) == Some('\'') {
                Some(i + 2)
            } else {
                None
            };
            match end {
                Some(j) => {
                    out.extend(c[i..=j].iter().map(|&ch| blank(ch)));
                    i = j + 1;
                }
                None => {
                    out.push(c[i]);
                    i += 1;
                }
            }
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

/// The line (0-based) of the brace closing the block opened at or after
/// line `from`; None where the item ends in `;` before any block opens.
fn block_end(lines: &[&str], from: usize) -> Option<usize> {
    let mut depth = 0i32;
    let mut opened = false;
    for (n, line) in lines.iter().enumerate().skip(from) {
        for ch in line.chars() {
            match ch {
                '{' => {
                    depth += 1;
                    opened = true;
                }
                '}' => {
                    depth -= 1;
                    if opened && depth == 0 {
                        return Some(n);
                    }
                }
                ';' if !opened && depth == 0 => return None,
                _ => {}
            }
        }
    }
    None
}

/// Whether a (code-only) line starts a function item.
fn starts_fn(line: &str) -> Option<String> {
    let mut words = line.split_whitespace().peekable();
    while let Some(w) = words.next() {
        let qualifier = w.starts_with("pub")
            || matches!(w, "const" | "async" | "unsafe" | "extern" | "default");
        if w == "fn" {
            let name = words.next()?;
            let name: String = name
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            return Some(name);
        }
        if !qualifier {
            return None;
        }
    }
    None
}

struct Measured {
    /// lines outside test items
    lines: usize,
    /// (name, first line 1-based, length) of each function outside test items
    fns: Vec<(String, usize, usize)>,
}

fn measure(text: &str) -> Measured {
    let code = code_only(text);
    let lines: Vec<&str> = code.lines().collect();
    let mut test = vec![false; lines.len()];
    let mut n = 0;
    while n < lines.len() {
        if lines[n].trim() == "#[cfg(test)]" {
            // the attributed item runs to its block's end (or its `;`)
            let end = block_end(&lines, n + 1).unwrap_or_else(|| {
                (n + 1..lines.len())
                    .find(|&k| lines[k].contains(';'))
                    .unwrap_or(n)
            });
            test[n..=end].iter_mut().for_each(|t| *t = true);
            n = end + 1;
        } else {
            n += 1;
        }
    }
    let mut fns = Vec::new();
    for (n, line) in lines.iter().enumerate() {
        if test[n] {
            continue;
        }
        if let Some(name) = starts_fn(line) {
            // a declaration without a body (a trait's) ends at its `;`
            if let Some(end) = block_end(&lines, n) {
                fns.push((name, n + 1, end - n + 1));
            }
        }
    }
    Measured {
        lines: test.iter().filter(|t| !**t).count(),
        fns,
    }
}

#[test]
fn no_file_or_function_past_its_limit() {
    let files = sources();
    assert!(files.len() > 50, "found only {} files", files.len());
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut over = Vec::new();
    for path in &files {
        let shown = path.strip_prefix(&crates).unwrap().display().to_string();
        let text = std::fs::read_to_string(path).unwrap();
        // braces that do not balance once strings and comments are blanked
        // mean the measure misread the file: say so rather than miscount
        let code = code_only(&text);
        assert_eq!(
            code.matches('{').count(),
            code.matches('}').count(),
            "{shown}: the measure misread its strings or comments"
        );
        let m = measure(&text);
        if m.lines > MAX_FILE_LINES {
            over.push(format!(
                "{shown}: {} lines (at most {MAX_FILE_LINES})",
                m.lines
            ));
        }
        for (name, at, len) in m.fns {
            if len > MAX_FN_LINES {
                over.push(format!(
                    "{shown}:{at}: fn {name} is {len} lines (at most {MAX_FN_LINES})"
                ));
            }
        }
    }
    assert!(over.is_empty(), "{over:#?}");
}

/// The measure itself: test items aside, braces in strings, comments and
/// characters ignored, a function counted from its `fn` to its closing brace.
#[test]
fn the_measure_counts_what_it_says() {
    let text = r##"
fn short() {
    let s = "}}}{";
    let c = '{';
    let r = r#"{"#;
    // }
    /* { /* } */ */
}

pub(crate) fn longer<'a>(x: &'a str) -> &'a str {
    x
}

trait T {
    fn declared(&self);
}

#[cfg(test)]
mod tests {
    fn inside() {}
}
"##;
    let m = measure(text);
    let fns: Vec<(&str, usize, usize)> = m
        .fns
        .iter()
        .map(|(n, at, len)| (n.as_str(), *at, *len))
        .collect();
    assert_eq!(fns, vec![("short", 2, 7), ("longer", 10, 3)]);
    // 21 lines in all (the leading newline opens an empty first line), the
    // test module's 4 aside
    assert_eq!(text.lines().count(), 21);
    assert_eq!(m.lines, 17);
}
