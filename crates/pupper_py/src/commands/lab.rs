//! `lab`: the chapter's lab, as `pupper lab` runs it.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use pupper_core::request::lab as request;
use pupper_core::request::spec::SweepSpec;
use pupper_core::results::best;

use super::sweep::run_spec;
use crate::convert::{Keywords, Options, argument, keywords, out_from};
use crate::result::SweepResult;

/// The chapter's lab (what `pupper lab` runs): every body from its own
/// stand pose, the grid in torque mode under the sine force, no push;
/// best.csv (the best gains per body) in `out`. Plots and rendering are the
/// Python wrapper's.
#[pyfunction]
#[pyo3(signature = (variants=None, grid=None, *, out=None, progress=None, **options),
    // the options as inspect and help() show them (tests/test_api.py reads
    // them): LabOptions::default(), kept equal by a test below
    text_signature = "(variants=None, grid=None, *, seconds=6.0, sine=(2.0, 1.2), model='pupper_v3', out=None, force=False, resume=False, threads=0, max_saturation=0.05, rank=None, replicates=1, seed=0, randomize=(), backend='cpu', device=None, ray=None, depth=None, motor=None, progress=None)")]
pub(crate) fn lab(
    py: Python<'_>,
    variants: Option<&Bound<'_, PyAny>>,
    grid: Option<&Bound<'_, PyAny>>,
    out: Option<&Bound<'_, PyAny>>,
    progress: Option<Bound<'_, PyAny>>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<SweepResult> {
    let keywords = Keywords::of("lab", options, LabOptions::KEYWORDS)?;
    let variants: Option<Vec<String>> = variants.map(|v| argument("variants", v)).transpose()?;
    let grid: Option<Vec<String>> = grid.map(|g| argument("grid", g)).transpose()?;
    let lab = LabOptions::read(&keywords)?;
    let (spec, rule) = lab.spec(variants, grid, out)?;
    run_spec(py, spec, progress, "python: pupper_core.lab", Some(&rule))
}

/// The lab's keywords: the sweep's that it takes (with the lab's defaults),
/// and the ranking of its best.csv.
struct LabOptions {
    seconds: f64,
    sine: [f64; 2],
    model: String,
    force: bool,
    resume: bool,
    threads: usize,
    max_saturation: f64,
    rank: Option<String>,
    // wider than the spec's counts: out of range is a ValueError saying so
    replicates: i128,
    seed: i128,
    randomize: Vec<String>,
    backend: String,
    device: Option<String>,
    ray: Option<String>,
    depth: Option<f64>,
    motor: Option<String>,
}

impl Default for LabOptions {
    fn default() -> Self {
        LabOptions {
            seconds: request::SECONDS,
            sine: request::SINE,
            model: "pupper_v3".into(),
            force: false,
            resume: false,
            threads: 0,
            max_saturation: best::MAX_SATURATION,
            rank: None,
            replicates: 1,
            seed: 0,
            randomize: Vec::new(),
            backend: "cpu".into(),
            device: None,
            ray: None,
            depth: None,
            motor: None,
        }
    }
}

// as `lab` has always taken them: pyo3's conversions, not `spec_from`'s,
// so `seconds=True` is 1.0 and a huge `replicates` a ValueError saying so
keywords!(LabOptions {
    seconds,
    sine,
    model,
    force,
    resume,
    threads,
    max_saturation,
    rank,
    replicates,
    seed,
    randomize,
    backend,
    device,
    ray,
    depth,
    motor,
});

impl LabOptions {
    /// The lab's sweep over `variants` (default: every body) and `grid`
    /// (CLI strings; default: the lab's gains), and the rule of its best.csv.
    fn spec(
        self,
        variants: Option<Vec<String>>,
        grid: Option<Vec<String>>,
        out: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<(SweepSpec, best::Rule)> {
        let replicates = whole("replicates", self.replicates, u32::MAX as u64)? as u32;
        let seed = whole("seed", self.seed, u64::MAX)?;
        let variants = variants.unwrap_or_else(|| request::VARIANTS.map(String::from).to_vec());
        let grid = grid.unwrap_or_default();
        let metric = self.rank.unwrap_or_else(|| {
            if replicates > 1 || !self.randomize.is_empty() {
                "p95:last_1s_std_mm".into()
            } else {
                "last_1s_std_mm".into()
            }
        });
        let spec = SweepSpec {
            model: self.model,
            out: out_from(out)?,
            force: self.force,
            resume: self.resume,
            threads: self.threads,
            replicates,
            seed,
            randomize: self.randomize,
            backend: self.backend,
            device: self.device,
            ray: self.ray,
            depth: self.depth,
            motor: self.motor,
            ..request::spec(&variants, &grid, self.seconds, self.sine)
        };
        let rule = best::Rule {
            max_saturation: self.max_saturation,
            ..best::Rule::new(&metric, &["variant".to_string()])
        };
        Ok((spec, rule))
    }
}

/// A count in the range `sweep` takes, with its messages.
fn whole(name: &str, v: i128, most: u64) -> PyResult<u64> {
    match u64::try_from(v) {
        Ok(v) if v <= most => Ok(v),
        Ok(_) => Err(PyValueError::new_err(format!(
            "{name} {v} is too large: use at most {most}"
        ))),
        Err(_) => Err(PyValueError::new_err(format!(
            "{name} must be a whole number >= 0, not {v}"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::LabOptions;
    use crate::convert::Options;
    use crate::convert::shown::assert_declares;

    #[test]
    fn the_text_signature_shows_the_defaults() {
        // `out` among them, after `model`, as the signature has always had it
        let options = LabOptions::shown().replacen(", force=", ", out=None, force=", 1);
        let shown = format!("(variants=None, grid=None, *, {options}, progress=None)");
        assert_declares(include_str!("lab.rs"), &shown);
    }
}
