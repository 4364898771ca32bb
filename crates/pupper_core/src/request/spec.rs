//! The one specification of a sweep: every parameter, its default and its
//! checks are written here and nowhere else. The CLI (clap) and the Python
//! module only convert what the user gave into a [`SweepSpec`];
//! [`SweepSpec::build`] validates it into the [`Sweep`] the runner takes,
//! the way ripgrep turns low-level arguments into high-level ones once.
//! `stand` is a one-cell sweep without a push, built from the same spec.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::plan::backend::Backend;
use crate::plan::config::{Defaults, SweepConfig};
use crate::plan::experiment::Experiment;
use crate::plan::grid::{Axis, AxisValues, DEFAULT_MAX_CELLS, Grid, parse_values};
use crate::plan::integrator::Integrator;
use crate::plan::mode::Mode;
use crate::plan::motor::Motor;
use crate::plan::randomize::{Randomize, Replicates};
use crate::plan::schedule::{InitialState, Push, Schedule, SineForce};
use crate::plan::shard::Shard;
use crate::results::rundir::Existing;
use crate::robot::model::ModelSource;
use crate::robot::variant::variant;
use crate::sim::cluster::Address;
use crate::sim::runner::RunOptions;

/// Where the grid comes from.
/// The most batch threads a run may ask for: more than any machine's cores,
/// and few enough that MuJoCo's thread pool is never asked for 2^40.
pub const MAX_THREADS: usize = 1024;

#[derive(Debug, Clone, Default, PartialEq)]
pub enum GridInput {
    /// No grid: one cell at the default gains.
    #[default]
    None,
    /// The CLI's `AXIS=VALUES` strings.
    Specs(Vec<String>),
    /// Axis names and their values (a Python dict).
    Axes(Vec<(String, AxisInput)>),
    /// A named preset.
    Preset(String),
    /// Cells one by one: axis names, a row of values per cell, and names
    /// (empty, or one per cell).
    Cells {
        axes: Vec<String>,
        rows: Vec<Vec<f64>>,
        names: Vec<String>,
    },
}

/// One axis's values as a Python dict gives them.
#[derive(Debug, Clone, PartialEq)]
pub enum AxisInput {
    Values(Vec<f64>),
    /// Text parsed as the CLI parses the right of `AXIS=VALUES`.
    Text(String),
}

/// Everything a user can set for a sweep. `SweepSpec::default()` holds the
/// defaults that `--help` and the Python signature show; the field names are
/// the Python keyword arguments (unknown ones are refused).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SweepSpec {
    /// Built-in model name or MJCF path.
    pub model: String,
    #[serde(skip)]
    pub grid: GridInput,
    /// A named body (original, long-leg, heavy) for cells whose grid has no
    /// leg_scale / torso_mass_scale axis.
    pub variant: String,
    pub mode: Mode,
    /// Simulated seconds per cell.
    pub seconds: f64,
    /// Gains for cells whose grid has no such axis; None: each actuator's
    /// own gains from the model (Pupper v3: Kp 5, Kd 0.1).
    pub kp: Option<f64>,
    pub kd: Option<f64>,
    /// None: each actuator's own limit (Pupper v3: 3 N·m).
    pub max_torque: Option<f64>,
    /// The timed push on the base.
    pub push: bool,
    /// Its force along world z (N); None: the chapter's −25 N scaled to the
    /// model's mass (−25 N on Pupper v3; see
    /// [`crate::plan::schedule::default_push_n`]).
    pub push_force: Option<f64>,
    pub push_at: f64,
    pub push_duration: f64,
    /// A continuous vertical force (amplitude N, frequency Hz).
    pub sine: Option<[f64; 2]>,
    /// Start from this keyframe, or from `pose` when given.
    pub keyframe: String,
    pub pose: Option<PoseInput>,
    /// With the `auto` pose: the feet's depth below the hips (m); None: the
    /// chapter's 0.14 m scaled to the model's legs.
    pub depth: Option<f64>,
    /// Keep base-z traces, every `trace_every`-th step.
    pub trace: bool,
    pub trace_every: usize,
    /// Runs of every cell, each with its own draws of `randomize`.
    pub replicates: u32,
    /// Seed of the draws: the same seed gives the same robots.
    pub seed: u64,
    /// `QUANTITY=DISTRIBUTION` specs (see `pupper sweep --help`).
    pub randomize: Vec<String>,
    /// Every cell's replicate r is the same drawn robot (common random
    /// numbers): cells then differ only by their settings.
    pub common_draws: bool,
    /// What steps the physics: `cpu` (MuJoCo, float64) or `warp` (MuJoCo
    /// Warp, float32) on `device` (warp only; default cuda:0).
    pub backend: String,
    pub device: Option<String>,
    /// Batch threads (0: all cores) and cells per batch: speed, never numbers.
    pub threads: usize,
    /// None: 256 on the cpu backend, as many as the device holds on warp.
    pub chunk_cells: Option<usize>,
    /// Refuse grids with more cells than this.
    pub max_cells: usize,
    /// Run directory; None keeps the results in memory (Python only).
    pub out: Option<PathBuf>,
    /// Overwrite pupper's files in an existing `out`.
    pub force: bool,
    /// Continue the run in `out`.
    pub resume: bool,
    /// Run only shard `I/N` of the grid's cells (interleaved).
    pub shard: Option<String>,
    /// Run the cells as tasks on this Ray cluster (`auto`, `ray://HOST:PORT`
    /// or `HOST:PORT`); None runs them here.
    pub ray: Option<String>,
    /// Stop stepping a robot once it has fallen (see
    /// [`crate::plan::schedule::Schedule::stop_fallen`]).
    pub stop_fallen: bool,
    /// What the run's simulations do (`pupper response`, `pupper hold`);
    /// the default, a stand: a sweep.
    #[serde(skip)]
    pub experiment: Experiment,
    /// The name a request gives its run in the manifest when it is not the
    /// experiment's own (`lab`); None: the experiment's.
    #[serde(skip)]
    pub kind: Option<&'static str>,
    /// Torque mode's servo firmware and motor (`--motor`); None: ideal.
    pub motor: Option<String>,
    /// MuJoCo's integrator for every cell (`--integrator`: euler,
    /// implicitfast, implicit, rk4); None: the model's own.
    pub integrator: Option<String>,
}

impl Default for SweepSpec {
    fn default() -> Self {
        SweepSpec {
            model: "pupper_v3".into(),
            grid: GridInput::None,
            variant: "original".into(),
            mode: Mode::Servo,
            seconds: 10.0,
            kp: None,
            kd: None,
            max_torque: None,
            push: true,
            push_force: None,
            push_at: 2.0,
            push_duration: 0.25,
            sine: None,
            keyframe: "home".into(),
            pose: None,
            depth: None,
            trace: false,
            trace_every: 10,
            replicates: 1,
            seed: 0,
            randomize: Vec::new(),
            common_draws: false,
            backend: "cpu".into(),
            device: None,
            threads: 0,
            chunk_cells: None,
            max_cells: DEFAULT_MAX_CELLS,
            out: None,
            force: false,
            resume: false,
            shard: None,
            ray: None,
            stop_fallen: false,
            experiment: Experiment::Stand,
            kind: None,
            integrator: None,
            motor: None,
        }
    }
}

/// A validated sweep: what decides the numbers, what decides only speed,
/// and where it is written.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// What the run is, as its manifest names it: the experiment kind's
    /// name, or the request's own (the lab is a sweep of bodies).
    pub kind: String,
    pub config: SweepConfig,
    pub options: RunOptions,
    pub out: Option<PathBuf>,
    pub existing: Existing,
    /// The part of the grid this run holds; None: all of it.
    pub shard: Option<Shard>,
    /// The Ray cluster that runs the cells; None: this machine.
    pub ray: Option<Address>,
}

fn config_error(text: String) -> Error {
    Error::Config(text)
}

impl SweepSpec {
    /// The spec of `stand`: one cell, no push.
    pub fn stand() -> SweepSpec {
        SweepSpec {
            push: false,
            ..SweepSpec::default()
        }
    }

    /// The defaults as (name, JSON value) pairs, for the Python signature.
    pub fn defaults_json() -> serde_json::Value {
        serde_json::to_value(SweepSpec::default()).unwrap_or(serde_json::Value::Null)
    }

    /// The options checked on their own, before the grid: each mistake in
    /// one line naming the fix.
    fn check_options(&self) -> Result<()> {
        if self.trace && self.trace_every == 0 {
            return Err(config_error(
                "trace_every is 0 with tracing on: give --trace-every a whole number >= 1".into(),
            ));
        }
        if self.chunk_cells == Some(0) {
            return Err(config_error(
                "chunk_cells is 0: give --chunk-cells a whole number >= 1".into(),
            ));
        }
        if self.resume && self.out.is_none() {
            return Err(Error::Output(
                "resume needs the run directory to continue: give out (or --resume DIR)".into(),
            ));
        }
        if self.depth.is_some() && !matches!(self.pose, Some(PoseInput::Auto(_))) {
            return Err(config_error(
            "depth sets how deep the searched stand pose puts the feet: give it with --pose auto (pupper lab always searches)".into(),
        ));
        }
        if self.threads > MAX_THREADS {
            return Err(config_error(format!(
                "--threads {} is more than {MAX_THREADS}: give 0 (every core) or a count up to {MAX_THREADS}",
                self.threads
            )));
        }
        Ok(())
    }

    /// The schedule of every cell: the run's length, where it starts, the
    /// push (when the kind has one) and the sine force.
    fn schedule(&self, experiment: &Experiment) -> Schedule {
        Schedule {
            duration: self.seconds,
            initial: match &self.pose {
                Some(PoseInput::Auto(_)) => match self.depth {
                    Some(d) => InitialState::AutoDepth(d),
                    None => InitialState::Auto,
                },
                Some(PoseInput::Angles(p)) => InitialState::Pose(p.clone()),
                None => InitialState::Keyframe(self.keyframe.clone()),
            },
            // a response run excites joints, it does not push the robot (a
            // hold's push is its shove, resolved on the model's weight)
            push: (self.push && experiment.plan().pushes()).then(|| Push {
                start: self.push_at,
                duration: self.push_duration,
                force: [
                    0.0,
                    0.0,
                    self.push_force
                        .unwrap_or(crate::plan::schedule::PUPPER_PUSH_N),
                ],
                body: String::new(),
                // a hold's shove is its own, in multiples of the weight
                by_weight: self.push_force.is_none() && matches!(experiment, Experiment::Stand),
            }),
            sine: self.sine.map(|[amplitude, frequency]| SineForce {
                amplitude,
                frequency,
                axis: [0.0, 0.0, 1.0],
            }),
            trace_every: if self.trace { self.trace_every } else { 0 },
            stop_fallen: self.stop_fallen,
            ..Schedule::default()
        }
    }

    /// Checks every value and builds the sweep ([`SweepConfig::validate`]
    /// holds the checks a config read back from a manifest needs too).
    /// Model-dependent checks (the pose length, the keyframe) happen when the
    /// model is loaded.
    pub fn build(&self) -> Result<Sweep> {
        self.check_options()?;
        let grid = self.grid()?;
        grid.check_size(self.max_cells)?;
        let randomize = self
            .randomize
            .iter()
            .map(|r| Randomize::parse(r))
            .collect::<Result<Vec<_>>>()?;
        let sims = grid.len().saturating_mul(self.replicates.max(1) as usize);
        if sims > self.max_cells {
            return Err(Error::Grid(format!(
                "{} cells x {} replicates make {sims} simulations, over the limit of {}: use fewer values or replicates, or raise --max-cells",
                grid.len(),
                self.replicates,
                self.max_cells
            )));
        }
        let experiment = self.experiment.clone();
        let schedule = self.schedule(&experiment);
        let config = SweepConfig {
            model: ModelSource::parse(&self.model)?,
            grid,
            schedule,
            mode: self.mode,
            defaults: {
                let body = variant(&self.variant)?;
                Defaults {
                    kp: self.kp,
                    kd: self.kd,
                    max_torque: self.max_torque,
                    leg_scale: body.leg_scale,
                    torso_mass_scale: body.torso_mass_scale,
                }
            },
            replicates: Replicates {
                count: self.replicates,
                seed: self.seed,
                randomize,
                common_draws: self.common_draws,
            },
            backend: Backend::parse(&self.backend, self.device.as_deref())?,
            experiment,
            integrator: self
                .integrator
                .as_deref()
                .map(Integrator::parse)
                .transpose()?,
            motor: Motor::parse(self.motor.as_deref().unwrap_or(""))?,
        };
        config.validate()?;
        let existing = match (self.resume, self.force) {
            (true, _) => Existing::Resume,
            (false, true) => Existing::Overwrite,
            (false, false) => Existing::Refuse,
        };
        Ok(Sweep {
            kind: self
                .kind
                .unwrap_or_else(|| config.experiment.name())
                .to_string(),
            config,
            options: RunOptions {
                threads: self.threads,
                chunk_cells: self.chunk_cells,
                ..RunOptions::default()
            },
            out: self.out.clone(),
            existing,
            shard: self.shard.as_deref().map(Shard::parse).transpose()?,
            ray: self.ray.as_deref().map(Address::parse).transpose()?,
        })
    }

    fn grid(&self) -> Result<Grid> {
        match &self.grid {
            GridInput::None => Ok(Grid::default()),
            GridInput::Specs(s) => Grid::parse(s),
            GridInput::Axes(a) => a
                .iter()
                .map(|(name, values)| {
                    let axis = Axis::parse(name)?;
                    let values = match values {
                        AxisInput::Values(v) => v.clone(),
                        AxisInput::Text(t) => parse_values(axis, t)?,
                    };
                    AxisValues::new(axis, values)
                })
                .collect::<Result<Vec<_>>>()
                .and_then(Grid::from_axes),
            GridInput::Preset(p) => Grid::preset(p),
            GridInput::Cells { axes, rows, names } => {
                Grid::explicit(axes, rows.clone(), names.clone())
            }
        }
    }
}

/// Parses a mode name.
pub fn parse_mode(text: &str) -> Result<Mode> {
    match text {
        "servo" => Ok(Mode::Servo),
        "torque" => Ok(Mode::Torque),
        _ => Err(config_error(format!(
            "mode '{text}' is unknown: use 'servo' or 'torque'"
        ))),
    }
}

/// `--pose`: `auto`, or joint angles.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PoseInput {
    Auto(AutoPose),
    Angles(Vec<f64>),
}

/// The word `auto`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AutoPose {
    Auto,
}

/// Parses `--pose auto` or `--pose Q1,Q2,...` (radians, actuator order).
pub fn parse_pose(text: &str) -> Result<PoseInput> {
    if text.trim() == "auto" {
        return Ok(PoseInput::Auto(AutoPose::Auto));
    }
    text.split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    config_error(format!(
                        "--pose value '{}' is not a finite number: give radians like 0,0.7,-1.4",
                        t.trim()
                    ))
                })
        })
        .collect::<Result<Vec<f64>>>()
        .map(PoseInput::Angles)
}

/// Parses `--sine AMPLITUDE,FREQUENCY`.
pub fn parse_sine(text: &str) -> Result<[f64; 2]> {
    let bad = || {
        config_error(format!(
            "--sine '{text}' is not AMPLITUDE,FREQUENCY: give two numbers, e.g. --sine 2,1.2"
        ))
    };
    let v: Vec<f64> = text
        .split(',')
        .map(|t| t.trim().parse::<f64>().map_err(|_| bad()))
        .collect::<Result<_>>()?;
    match v[..] {
        [a, f] => Ok([a, f]),
        _ => Err(bad()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_build_the_chapter_schedule() {
        let mut s = SweepSpec::default().build().unwrap();
        // the default push waits for the model's mass; on Pupper's it is the chapter's
        let push = s.config.schedule.push.as_mut().unwrap();
        assert!(push.by_weight);
        push.resolve(3.1699999999999995).unwrap();
        assert_eq!(s.config, SweepConfig::default());
        assert_eq!(s.options, RunOptions::default());
        assert_eq!(s.existing, Existing::Refuse);
        let stand = SweepSpec::stand().build().unwrap();
        assert!(stand.config.schedule.push.is_none());
    }

    #[test]
    fn every_check_names_the_flag() {
        let e = |spec: SweepSpec| spec.build().unwrap_err().to_string();
        let d = SweepSpec::default;
        assert!(
            e(SweepSpec {
                kp: Some(-1.0),
                ..d()
            })
            .contains("--kp")
        );
        assert!(
            e(SweepSpec {
                kd: Some(f64::NAN),
                ..d()
            })
            .contains("--kd")
        );
        assert!(
            e(SweepSpec {
                max_torque: Some(0.0),
                ..d()
            })
            .contains("--max-torque")
        );
        assert!(
            e(SweepSpec {
                seconds: -1.0,
                ..d()
            })
            .contains("--seconds")
        );
        assert!(
            e(SweepSpec {
                trace: true,
                trace_every: 0,
                ..d()
            })
            .contains("--trace-every")
        );
        assert!(
            e(SweepSpec {
                resume: true,
                ..d()
            })
            .contains("resume")
        );
        assert!(
            e(SweepSpec {
                push: false,
                grid: GridInput::Specs(vec!["push_force=-10".into()]),
                ..d()
            })
            .contains("--no-push")
        );
    }

    #[test]
    fn dict_axes_parse_text_as_the_cli_does() {
        let spec = |v: AxisInput| SweepSpec {
            grid: GridInput::Axes(vec![("kp".into(), v)]),
            ..SweepSpec::default()
        };
        let values = |v| spec(v).build().unwrap().config.grid.axes[0].values.clone();
        assert_eq!(values(AxisInput::Text("10".into())), vec![10.0]);
        assert_eq!(values(AxisInput::Text("10,30".into())), vec![10.0, 30.0]);
        assert_eq!(values(AxisInput::Text("1:120:16:log".into())).len(), 16);
        assert_eq!(values(AxisInput::Values(vec![1.0, 0.0])), vec![1.0, 0.0]);
        assert!(spec(AxisInput::Text("ten".into())).build().is_err());
    }

    #[test]
    fn keyword_names_are_the_fields() {
        let s: SweepSpec = serde_json::from_str(r#"{"kp": 30, "mode": "torque"}"#).unwrap();
        assert_eq!((s.kp, s.mode, s.kd), (Some(30.0), Mode::Torque, None));
        assert!(serde_json::from_str::<SweepSpec>(r#"{"kq": 1}"#).is_err());
    }

    #[test]
    fn text_parsers() {
        assert_eq!(parse_sine("2, 1.2").unwrap(), [2.0, 1.2]);
        assert!(parse_sine("2").is_err());
        assert_eq!(
            parse_pose("0,0.5,-1").unwrap(),
            PoseInput::Angles(vec![0.0, 0.5, -1.0])
        );
        assert_eq!(parse_pose("auto").unwrap(), PoseInput::Auto(AutoPose::Auto));
        assert!(parse_pose("0,x").unwrap_err().to_string().contains("'x'"));
        assert_eq!(parse_mode("torque").unwrap(), Mode::Torque);
        assert!(parse_mode("pd").is_err());
    }
}
