//! The crate's layers import only downwards, and no modules import each
//! other in a circle: read from the sources, so a new `use` that breaks the
//! order fails here, naming the file and the import.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

const LAYERS: [&str; 6] = ["math", "robot", "plan", "sim", "results", "request"];

/// `layer/module` -> the `layer/module`s it names through `crate::`.
fn imports() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut out = BTreeMap::new();
    for layer in LAYERS {
        for entry in std::fs::read_dir(src.join(layer)).unwrap() {
            let path = entry.unwrap().path();
            let module = path.file_stem().unwrap().to_str().unwrap().to_string();
            if module == "mod" {
                continue;
            }
            // a folder module (a registry and its kinds) is one module: the
            // union of its files
            let text = if path.is_dir() {
                let mut files: Vec<_> = std::fs::read_dir(&path)
                    .unwrap()
                    .map(|e| e.unwrap().path())
                    .collect();
                files.sort();
                files
                    .iter()
                    .map(|f| std::fs::read_to_string(f).unwrap())
                    .collect::<Vec<_>>()
                    .join("\n")
            } else {
                std::fs::read_to_string(&path).unwrap()
            };
            let mut named = BTreeSet::new();
            for (at, _) in text.match_indices("crate::") {
                let rest = &text[at + "crate::".len()..];
                let mut parts = rest.split("::");
                let (Some(l), Some(m)) = (parts.next(), parts.next()) else {
                    continue;
                };
                let m: String = m
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if LAYERS.contains(&l) && !m.is_empty() {
                    named.insert(format!("{l}/{m}"));
                }
            }
            out.insert(format!("{layer}/{module}"), named);
        }
    }
    out
}

fn layer_of(module: &str) -> usize {
    let l = module.split('/').next().unwrap();
    LAYERS.iter().position(|x| *x == l).unwrap()
}

#[test]
fn layers_import_only_downwards() {
    let all = imports();
    assert!(all.len() > 20, "found only {} modules", all.len());
    let upward: Vec<String> = all
        .iter()
        .flat_map(|(m, named)| {
            named
                .iter()
                .filter(|n| layer_of(n) > layer_of(m))
                .map(move |n| format!("{m} imports {n}"))
        })
        .collect();
    assert!(upward.is_empty(), "{upward:#?}");
}

#[test]
fn no_import_cycle() {
    let all = imports();
    // depth-first search for a back edge
    fn visit(
        m: &str,
        all: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(i) = path.iter().position(|p| p == m) {
            let mut cycle = path[i..].to_vec();
            cycle.push(m.to_string());
            return Some(cycle);
        }
        if done.contains(m) {
            return None;
        }
        path.push(m.to_string());
        for n in all.get(m).into_iter().flatten().filter(|n| *n != m) {
            if let Some(c) = visit(n, all, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(m.to_string());
        None
    }
    let mut done = BTreeSet::new();
    for m in all.keys() {
        let cycle = visit(m, &all, &mut Vec::new(), &mut done);
        assert!(
            cycle.is_none(),
            "import cycle: {}",
            cycle.unwrap().join(" -> ")
        );
    }
}

/// The checker itself sees an upward import and a cycle when there is one.
#[test]
fn the_checker_sees_what_it_looks_for() {
    assert!(layer_of("request/spec") > layer_of("math/pd"));
    let all = imports();
    assert!(all["sim/runner"].contains("plan/config"));
    assert!(all["plan/axis"].contains("math/decimal"));
    assert!(all["results/kinds"].contains("sim/result"));
}
