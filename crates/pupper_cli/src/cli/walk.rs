//! `pupper walk`: how well each gain cell walks a gait, a run of the sweep
//! runner with the walk kind's moving targets instead of a push.

use std::sync::atomic::AtomicBool;

use clap::Args;
use pupper_core::Result;
use pupper_core::plan::grid::Axis;
use pupper_core::request::spec::SweepSpec;
use pupper_core::request::walk::{WalkInput, best_by, seconds, spec};
use pupper_core::results::{best, output};

use serde::Serialize;

use super::args::{
    GridArg, OutputArgs, PopulationArgs, RankHelp, RunnerArgs, ShowArgs, Shown, Shows, SimArgs,
    TRACE_HEIGHT, finite,
};
use super::sweep::{Job, run_job};

#[derive(Args, Debug)]
#[command(
    about = "How well the gains walk: the robot trots (or walks, paces, bounds) open loop at a \
             commanded velocity, each leg's targets from its foot by inverse kinematics on the \
             model's own legs; per gain cell over the steady part of the walk the speed achieved \
             against commanded, drift, body roll and pitch, foot slip, how the joints follow at the \
             gait frequency, torque, power and cost of transport, and falls",
    after_help = "Timeline (defaults): the robot lands on its start pose (1 s), moves its feet to the gait's
stance (0.5 s), then walks: its commanded velocity ramps up from 0 over 1 s, 1 s more to settle,
and the steady window is every whole gait cycle after that (3.5 s to 8 s at 2 Hz).
The gait is open loop at the kinematic level: stance feet move under the body at the commanded
velocity, swing feet lift by --step-height and land half a stance's travel ahead of their place
(a Raibert-style rule); each leg's joint targets come from its foot by inverse kinematics on its
abduction, hip and knee as the compiled model measures them; the servos (or torque mode's PD and
--motor) follow the targets as in every kind.
Grid axes: the sweep's (kp, kd, kp.GROUP, kd.GROUP, max_torque, friction, timestep,
torso_mass_scale) and the gait's: frequency (Hz), speed (m/s), duty, step_height (m).
Figures per cell over the steady window, besides the sweep's (final_z ... status, event_time):
speed_ms (the base's path along its heading over the window's time), speed_error_pct (the
achieved velocity's distance from the commanded one, % of the commanded speed), drift_ms
(sideways) and yaw_drift_deg_s (off the commanded yaw rate), roll_rms_deg and pitch_rms_deg (from
upright), height_std_mm, slip_mm_s (how fast the feet on the floor slide), amplitude_ratio and
lag_ms (the joints' response at the gait frequency against their targets'), torque_rms (N·m),
power_w (sum of |torque x joint speed|) and cost_of_transport (power / (weight x speed)).
The best walker of each gait setting (the gait axes of the grid) is the lowest speed_error_pct
(with replicates p95:speed_error_pct) among cells that stayed up (status ok, under 5 % saturation);
a fall is a status, with its time in event_time.

Examples:
  pupper walk --grid kp=2,5,10,20 --grid kd=0.1,0.25,0.5 --gait trot --speed 0.25
  pupper walk --kp 5 --kd 0.25 --grid speed=0.1,0.2,0.3 --plot
  pupper walk --grid kp=5,20 --replicates 8 --randomize torso_mass=±10% --randomize friction=0.6:1.2
  pupper walk --model tests/models/trotter15.xml --grid kp=10,50,100"
)]
pub(super) struct WalkArgs {
    #[command(flatten)]
    grid: GridArg,
    #[command(flatten)]
    sim: SimArgs,
    /// The footfall pattern: trot (diagonal pairs), walk (four beats: left front, right back,
    /// right front, left back), pace (lateral pairs) or bound (front pair, back pair).
    #[arg(long, default_value_t = WalkInput::default().gait, value_name = "GAIT")]
    gait: String,
    /// Gait cycles per second (Hz); a frequency grid axis overrides it.
    #[arg(long, default_value_t = WalkInput::default().frequency, value_name = "HZ", allow_negative_numbers = true)]
    frequency: f64,
    /// Commanded forward speed (m/s); a speed grid axis overrides it.
    #[arg(long, default_value_t = WalkInput::default().speed, value_name = "M_S", allow_negative_numbers = true)]
    speed: f64,
    /// Commanded sideways speed (m/s, to the robot's left).
    #[arg(long, default_value_t = WalkInput::default().sideways, value_name = "M_S", allow_negative_numbers = true)]
    sideways: f64,
    /// Commanded yaw rate (rad/s, to the left).
    #[arg(long, default_value_t = WalkInput::default().yaw_rate, value_name = "RAD_S", allow_negative_numbers = true)]
    yaw_rate: f64,
    /// The share of a cycle each foot is down; a duty grid axis overrides it [default: 0.75 for
    /// walk, 0.6 for trot, pace and bound]
    #[arg(long, value_name = "FRACTION", allow_negative_numbers = true)]
    duty: Option<f64>,
    /// How high a swing lifts the foot (m); a step_height grid axis overrides it [default:
    /// 0.06 m on Pupper v3's legs, scaled to the model's leg length]
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    step_height: Option<f64>,
    /// The base's height above the floor while walking (m) [default: the start pose's, the
    /// feet at most 85 % of the legs' reach below the hips]
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    height: Option<f64>,
    #[command(flatten)]
    output: OutputArgs,
    #[command(flatten)]
    show: ShowArgs<WalkArgs>,
    // last: their help headings would hold every option after them
    #[command(flatten)]
    runner: RunnerArgs,
    #[command(flatten)]
    population: PopulationArgs,
}

impl Shows for WalkArgs {
    const SHOWN: Shown = Shown {
        trace: Some(TRACE_HEIGHT),
        plot: Some(
            "Write plots into DIR/plots (speed achieved against commanded, the metric per cell, \
             base height while walking)",
        ),
        render: Some(
            "Render a walking cell (the best, up to 6 cells) as an effects GIF and PNG into \
             DIR/plots",
        ),
        rank: Some(RankHelp {
            help: "Rank cells by this summary column instead of speed_error_pct (lowest wins; \
                   with replicates a statistic, e.g. p95:roll_rms_deg)",
            value_name: "[STAT:]METRIC",
            alias: None,
        }),
    };
}

impl WalkArgs {
    fn input(&self) -> WalkInput {
        WalkInput {
            gait: self.gait.clone(),
            frequency: self.frequency,
            speed: self.speed,
            sideways: self.sideways,
            yaw_rate: self.yaw_rate,
            duty: self.duty,
            step_height: self.step_height,
            height: self.height,
        }
    }

    fn spec(&self) -> Result<SweepSpec> {
        let input = self.input();
        let sim = self.population.apply(self.sim.spec()?);
        let base = SweepSpec {
            grid: self.grid.input(),
            seconds: self.sim.seconds.unwrap_or_else(|| seconds(&input)),
            force: self.output.force,
            // the height plot draws the traces
            ..self.runner.apply(self.show.traces(), sim)
        };
        spec(base, &input)
    }
}

/// The axes of a grid's specs (a bad one is refused when the spec is built).
fn axes(grid: &[String]) -> Vec<Axis> {
    grid.iter()
        .filter_map(|g| g.split_once('=').map(|(a, _)| a))
        .filter_map(|a| Axis::parse(a).ok())
        .collect()
}

/// `pupper walk`.
pub(super) fn run(a: WalkArgs, stop: &'static AtomicBool) -> Result<u8> {
    let input = WalkInput::default();
    let baseline = spec(
        SweepSpec {
            seconds: seconds(&input),
            ..SweepSpec::default()
        },
        &input,
    )?;
    // no --rank: the kind's metric (over the replicates when there are
    // some), chosen in run_job once the run's config is known
    let metric = a.show.rank.clone().unwrap_or_default();
    let alone = a.grid.grid.is_empty();
    // `--resume DIR` alone: the run's own grid picks per gait setting
    let grid = match (&a.runner.run.resume, alone) {
        (Some(dir), true) => {
            pupper_core::results::clear::check_kind(dir, "walk")?;
            output::read_manifest(dir)?
                .config
                .grid
                .axes
                .iter()
                .map(|x| x.axis)
                .collect()
        }
        _ => axes(&a.grid.grid),
    };
    run_job(
        Job {
            resume_alone: alone,
            preset: Some("walk".into()),
            plot: a.show.plot,
            render: a.show.render,
            rule: Some(best::Rule::new(&metric, &best_by(&grid))),
            ..Job::new(a.spec()?, baseline, a.output.out, &a.runner.run)
        },
        stop,
    )
}

/// `recommend --task walk`'s gait: the walk each candidate makes on the
/// drawn robots (`pupper walk`'s, and its defaults, where not given).
#[derive(Args, Debug, Serialize)]
pub(super) struct WalkTaskArgs {
    /// With --task walk: the gait (trot, walk, pace or bound) [default: a trot]
    #[arg(long, value_name = "GAIT")]
    gait: Option<String>,
    /// With --task walk: the commanded forward speed (m/s) [default: 0.25 m/s]
    #[arg(long, value_name = "M_S", allow_negative_numbers = true, value_parser = finite)]
    speed: Option<f64>,
    /// With --task walk: gait cycles per second (Hz) [default: 2 Hz]
    #[arg(long, value_name = "HZ", allow_negative_numbers = true, value_parser = finite)]
    frequency: Option<f64>,
    /// With --task walk: the most roll or pitch RMS any robot may keep while walking (degrees)
    /// [default: 10 degrees]
    #[arg(long, value_name = "DEG", allow_negative_numbers = true, value_parser = finite)]
    max_tilt: Option<f64>,
}
