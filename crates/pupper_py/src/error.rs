//! pupper's Python exceptions: a class per error family (all `PupperError`),
//! four that are also builtin `OSError`s, and the translation of a Rust
//! error (its class, its `kind`, its message in Python's words).

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt};
use pyo3::prelude::*;

use pupper_core::error::{Error, ErrorKind};

create_exception!(
    pupper_core,
    PupperError,
    PyException,
    "Base class of pupper's errors."
);
create_exception!(
    pupper_core,
    GridError,
    PupperError,
    "A bad grid: unknown axis, bad values, too many cells."
);
create_exception!(
    pupper_core,
    ConfigError,
    PupperError,
    "A bad schedule, pose, gain or option."
);
create_exception!(
    pupper_core,
    ModelError,
    PupperError,
    "A model that is missing, unreadable, invalid or unsuitable."
);
create_exception!(
    pupper_core,
    MujocoError,
    PupperError,
    "The mujoco package is missing or the wrong version."
);
create_exception!(
    pupper_core,
    OutputError,
    PupperError,
    "The run directory exists, or a resume does not match."
);
create_exception!(
    pupper_core,
    DisplayError,
    PupperError,
    "Rendering or a viewer is not possible here."
);
create_exception!(
    pupper_core,
    ClusterError,
    PupperError,
    "Ray is missing, the cluster cannot be reached, or a node cannot run pupper."
);
create_exception!(
    pupper_core,
    InternalError,
    PupperError,
    "A bug in pupper or MuJoCo."
);

/// Errors that are also the builtin `OSError` subclass a user would catch
/// (the way polars raises `FileNotFoundError`): (name, family, builtin, doc).
/// Classes with two bases are made at import, so they live in the module
/// only, and [`to_py`] finds them there.
pub(crate) const DUAL_ERRORS: [(&str, &str, &str, &str); 4] = [
    (
        "ModelNotFoundError",
        "ModelError",
        "FileNotFoundError",
        "A model file that does not exist.",
    ),
    (
        "RunNotFoundError",
        "OutputError",
        "FileNotFoundError",
        "A run directory, or a file in it, that does not exist.",
    ),
    (
        "RunExistsError",
        "OutputError",
        "FileExistsError",
        "The run directory exists; pass force=True or resume=True.",
    ),
    (
        "OutputPermissionError",
        "OutputError",
        "PermissionError",
        "The run directory cannot be written or read.",
    ),
];

/// The Python exception of a Rust error: the family's class (or its
/// `OSError` twin), with the stable `kind` code as an attribute.
pub(crate) fn to_py(e: Error) -> PyErr {
    let msg = match &e {
        // a KeyboardInterrupt says why it stopped, as Python's own does
        Error::Interrupted(why) => pythonic(why),
        _ => pythonic(&e.to_string()),
    };
    let dual = match e.code() {
        "model_not_found" => Some("ModelNotFoundError"),
        "run_not_found" | "not_found" => Some("RunNotFoundError"),
        "run_exists" => Some("RunExistsError"),
        "permission" => Some("OutputPermissionError"),
        _ => None,
    };
    Python::attach(|py| {
        let dual = dual
            .and_then(|name| {
                PyModule::import(py, "pupper_core._native")
                    .and_then(|m| m.getattr(name))
                    .ok()
            })
            .and_then(|c| c.cast_into::<pyo3::types::PyType>().ok());
        let err = match dual {
            Some(cls) => PyErr::from_type(cls, msg),
            None => match e.kind() {
                ErrorKind::Grid => GridError::new_err(msg),
                ErrorKind::Config => ConfigError::new_err(msg),
                ErrorKind::Model => ModelError::new_err(msg),
                ErrorKind::Mujoco => MujocoError::new_err(msg),
                ErrorKind::Output => OutputError::new_err(msg),
                ErrorKind::Interrupted => PyKeyboardInterrupt::new_err(msg),
                ErrorKind::Display => DisplayError::new_err(msg),
                ErrorKind::Cluster => ClusterError::new_err(msg),
                ErrorKind::Internal => InternalError::new_err(msg),
            },
        };
        // an exception without the attribute is still raised, only plainer
        let _ = err.value(py).setattr("kind", e.code());
        // the command line's words, for a command whose work is in Python
        // (tune, fit, recommend) to say its error as the CLI does
        let _ = err.value(py).setattr("cli_message", e.to_string());
        err
    })
}

/// A message written for the command line, in Python's words: `--kp -1`
/// becomes `kp=-1`, `add --force` `add force=True`, `--no-push`
/// `push=False`, `--max-torque` `max_torque=`. Command lines quoted in it
/// (from `pupper` to the next `:` `;` or `,`) stay as they are.
pub(crate) fn pythonic(msg: &str) -> String {
    const SWITCHES: [(&str, &str); 4] = [
        ("force", "force=True"),
        ("resume", "resume=True"),
        ("trace", "trace=True"),
        ("no-push", "push=False"),
    ];
    const NAMED: [&str; 4] = ["model", "preset", "keyframe", "integrator"];
    let words: Vec<&str> = msg.split(' ').collect();
    let mut out: Vec<String> = Vec::with_capacity(words.len());
    let mut quoted = false;
    let mut i = 0;
    while i < words.len() {
        let w = words[i];
        if w.trim_start_matches('`') == "pupper" {
            quoted = true;
        }
        let flag = w
            .strip_prefix("--")
            .filter(|f| f.chars().next().is_some_and(|c| c.is_ascii_lowercase()));
        match flag {
            Some(f) if !quoted => {
                let name: String = f
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                    .collect();
                let rest = &f[name.len()..];
                let key = name.replace('-', "_");
                // a flag that names a thing takes it as a string: `model="pupper_v3"`
                let named = words.get(i + 1).filter(|v| {
                    rest.is_empty()
                        && NAMED.contains(&name.as_str())
                        && v.trim_end_matches([',', ':', ';', ')']).chars().all(|c| {
                            c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '/')
                        })
                });
                if let Some(v) = named {
                    let bare = v.trim_end_matches([',', ':', ';', ')']);
                    out.push(format!("{key}=\"{bare}\"{}", &v[bare.len()..]));
                    i += 2;
                    continue;
                }
                let value = words.get(i + 1).filter(|v| {
                    rest.is_empty()
                        && v.trim_end_matches([',', ':', ';', ')'])
                            .parse::<f64>()
                            .is_ok()
                });
                match (SWITCHES.iter().find(|(s, _)| *s == name), value) {
                    (Some((_, py)), _) => out.push(format!("{py}{rest}")),
                    (None, Some(v)) => {
                        out.push(format!("{key}={v}"));
                        i += 1;
                    }
                    (None, None) => out.push(format!("{key}={rest}")),
                }
            }
            _ => out.push(w.to_string()),
        }
        if w.ends_with([':', ';', ',']) {
            quoted = false;
        }
        i += 1;
    }
    out.join(" ")
}

#[cfg(test)]
mod tests {
    use super::pythonic;

    #[test]
    fn cli_words_become_keywords() {
        assert_eq!(
            pythonic("--kp -1 is negative or not finite: gains must be >= 0"),
            "kp=-1 is negative or not finite: gains must be >= 0"
        );
        assert_eq!(
            pythonic(
                "output directory 'x' already exists: choose another --out, add --force to overwrite it, or --resume it"
            ),
            "output directory 'x' already exists: choose another out=, add force=True to overwrite it, or resume=True it"
        );
        assert_eq!(
            pythonic("give --max-torque a value > 0"),
            "give max_torque= a value > 0"
        );
        assert_eq!(
            pythonic("drop --no-push or the axis"),
            "drop push=False or the axis"
        );
        assert_eq!(
            pythonic(
                "model file 'nope.xml' does not exist: check the path, or use --model pupper_v3"
            ),
            "model file 'nope.xml' does not exist: check the path, or use model=\"pupper_v3\""
        );
        // a quoted command line stays one
        assert_eq!(
            pythonic("finish it with pupper sweep --resume d, then merge"),
            "finish it with pupper sweep --resume d, then merge"
        );
    }
}
