//! Every function of our Python package that the Rust side calls by name,
//! in one table: its module, its name, the parameters it is given. The
//! boundary no import graph or type checker sees is checked from both
//! sides: [`crate::bridge::call_helper`] refuses a call that does not match
//! its entry, `tests/test_python_calls.py` checks every entry against the
//! Python function's signature, and a test here that no call names a
//! Python function outside this table.

/// One Python function the Rust side calls.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PyCall {
    pub module: &'static str,
    pub function: &'static str,
    /// Its positional parameters, in order, each given as a string.
    pub positional: &'static [&'static str],
    /// The keyword parameters a call may give.
    pub keywords: &'static [&'static str],
    /// Whether it takes other keywords too (a `**options` of sweep inputs).
    pub open: bool,
}

impl PyCall {
    /// The dotted name, as messages show it.
    pub fn name(&self) -> String {
        format!("{}.{}", self.module, self.function)
    }

    /// Whether `args` positional values and the keywords of `kwargs` (a JSON
    /// object) are what this entry says the function takes.
    pub fn accepts(&self, args: usize, kwargs: &serde_json::Value) -> bool {
        let keys_ok = match kwargs.as_object() {
            Some(m) => self.open || m.keys().all(|k| self.keywords.contains(&k.as_str())),
            None => false,
        };
        args == self.positional.len() && keys_ok
    }
}

const fn call(
    module: &'static str,
    function: &'static str,
    positional: &'static [&'static str],
    keywords: &'static [&'static str],
) -> PyCall {
    PyCall {
        module,
        function,
        positional,
        keywords,
        open: false,
    }
}

/// A run's plots, by the kind its manifest names.
pub const WRITE_PLOTS: PyCall = call("pupper_core.plots", "write_plots", &["run_dir"], &[]);
/// The lab's bodies at their best gains, side by side (PNG, and a GIF).
pub const WRITE_LAB_EFFECTS: PyCall = call(
    "pupper_core.render",
    "write_lab_effects",
    &["run_dir"],
    &["gif"],
);
/// A sweep's cells rendered (`--render`).
pub const WRITE_RUN_EFFECTS: PyCall =
    call("pupper_core.render", "write_run_effects", &["run_dir"], &[]);
/// MuJoCo's interactive viewer on a model.
pub const VIEW: PyCall = call("pupper_core.render", "view", &["model"], &[]);
/// One model rendered to a PNG; the sweep's inputs as keywords.
pub const RENDER_PNG: PyCall = PyCall {
    open: true,
    ..call(
        "pupper_core.render",
        "render_png",
        &["path"],
        &["width", "height", "time"],
    )
};
/// One cell of a run rendered to a PNG.
pub const RENDER_CELL_PNG: PyCall = call(
    "pupper_core.render",
    "render_cell_png",
    &["path", "run_dir"],
    &["cell", "time", "width", "height"],
);
/// `pupper tune`, its options as JSON.
pub const TUNE: PyCall = call("pupper_core._tune", "_cli", &["args_json"], &[]);
/// `pupper lab --tune`, its options as JSON.
pub const LAB_TUNE: PyCall = call("pupper_core._tune", "_lab_cli", &["args_json"], &[]);
/// `pupper excite`, its options as JSON.
pub const EXCITE: PyCall = call("pupper_core._fit", "_cli_excite", &["args_json"], &[]);
/// `pupper fit`, its options as JSON.
pub const FIT: PyCall = call("pupper_core._fit", "_cli_fit", &["args_json"], &[]);
/// `pupper recommend`, its options as JSON; prints the card.
pub const RECOMMEND: PyCall = call("pupper_core._recommend", "_cli", &["args_json"], &[]);
/// A run directory's report.html, the directory's path as the hex of its
/// bytes.
pub const REPORT: PyCall = call("pupper_core._report", "_cli_hex", &["run_dir"], &[]);

/// The table.
pub const ALL: [PyCall; 12] = [
    WRITE_PLOTS,
    WRITE_LAB_EFFECTS,
    WRITE_RUN_EFFECTS,
    VIEW,
    RENDER_PNG,
    RENDER_CELL_PNG,
    TUNE,
    LAB_TUNE,
    EXCITE,
    FIT,
    RECOMMEND,
    REPORT,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_call_must_match_its_entry() {
        assert!(WRITE_LAB_EFFECTS.accepts(1, &serde_json::json!({"gif": true})));
        assert!(!WRITE_LAB_EFFECTS.accepts(1, &serde_json::json!({"fps": 3})));
        assert!(!WRITE_LAB_EFFECTS.accepts(2, &serde_json::json!({})));
        assert!(RENDER_PNG.accepts(1, &serde_json::json!({"kp": 5, "width": 3})));
        assert!(!TUNE.accepts(1, &serde_json::json!([])));
    }

    #[test]
    fn every_name_is_unique() {
        let mut names: Vec<String> = ALL.iter().map(PyCall::name).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), ALL.len());
    }

    /// No Rust source of the CLI or the bridge names a function of our
    /// Python package outside this table: every call goes through an entry.
    #[test]
    fn no_call_names_a_python_function_outside_the_table() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let mut stray = Vec::new();
        for dir in ["pupper_cli/src", "pupper_mujoco/src"] {
            let mut stack = vec![root.join(dir)];
            while let Some(d) = stack.pop() {
                for e in std::fs::read_dir(&d).unwrap() {
                    let p = e.unwrap().path();
                    if p.is_dir() {
                        stack.push(p);
                    } else if p.extension().is_some_and(|x| x == "rs")
                        && !p.ends_with("bridge/calls.rs")
                    {
                        let text = std::fs::read_to_string(&p).unwrap();
                        for (n, line) in text.lines().enumerate() {
                            let called = line.contains("call_helper(\"")
                                || line.contains("python_command(\"")
                                || ALL
                                    .iter()
                                    .any(|c| line.contains(&format!("\"{}\"", c.function)));
                            if called {
                                stray.push(format!("{}:{}: {line}", p.display(), n + 1));
                            }
                        }
                    }
                }
            }
        }
        assert!(stray.is_empty(), "{stray:#?}");
    }
}
