//! The module's functions, a file per command or small group; each turns
//! its arguments into the Rust call the CLI makes.

pub(crate) mod cli;
pub(crate) mod hold;
pub(crate) mod lab;
pub(crate) mod model;
pub(crate) mod record;
pub(crate) mod replay;
pub(crate) mod response;
pub(crate) mod rundir;
pub(crate) mod runs;
pub(crate) mod sweep;
pub(crate) mod walk;

use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::Options;

/// Each experiment kind's own keywords and their defaults, by the kind's
/// key in the Rust core's registry (`Experiment::KINDS`): the defaults
/// the Python functions' signatures take (the structs the CLI's flags
/// default to, written once).
#[pyfunction]
pub(crate) fn kind_defaults(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let out = PyDict::new(py);
    for &kind in pupper_core::plan::experiment::Experiment::KINDS {
        out.set_item(kind, defaults_of(py, kind)?)?;
    }
    Ok(out)
}

fn defaults_of<'py>(py: Python<'py>, kind: &str) -> PyResult<Bound<'py, PyDict>> {
    match kind {
        "response" => response::ResponseOptions::defaults(py),
        "hold" => pupper_core::request::hold::HoldInput::defaults(py),
        "walk" => pupper_core::request::walk::WalkInput::defaults(py),
        // a kind new to the registry: its binding's keywords go here
        other => Err(crate::error::to_py(pupper_core::error::Error::Internal(
            format!("no Python keywords for the experiment kind '{other}'"),
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_of_the_registry_has_its_keywords() {
        Python::initialize();
        Python::attach(|py| {
            let d = kind_defaults(py).unwrap();
            assert_eq!(
                d.len(),
                pupper_core::plan::experiment::Experiment::KINDS.len()
            );
            let walk = d.get_item("walk").unwrap().unwrap();
            let speed: f64 = walk.get_item("speed").unwrap().extract().unwrap();
            assert_eq!(speed, pupper_core::plan::walk::SPEED);
        });
    }
}
