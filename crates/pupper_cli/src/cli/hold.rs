//! `pupper hold`: how firmly each gain cell holds the robot up under a
//! load and against a sideways shove, a run of the sweep runner with the
//! hold kind's load instead of the sweep's push.

use std::sync::atomic::AtomicBool;

use clap::Args;
use pupper_core::Result;
use pupper_core::request::hold::{HoldInput, seconds, spec};
use pupper_core::request::spec::SweepSpec;
use pupper_core::results::best;

use super::args::{
    GridArg, OutputArgs, RankHelp, RunnerArgs, ShowArgs, Shown, Shows, SimArgs, TRACE_HEIGHT,
};
use super::sweep::{Job, run_job};

#[derive(Args, Debug)]
#[command(
    after_help = "Timeline (defaults): the robot lands and stands for 1 s; a vertical load on its base ramps
from 0 to --load times its own weight (total mass x gravity, from the model) over --ramp 2 s and
is held; 0.5 s after it is full (--shove-at, 3.5 s) a sideways shove of --shove times the weight
acts for 0.25 s towards the world's -y; 7 s in all.
Figures per cell, besides the sweep's (final_z ... status): sag_mm, the mean base height over
the 0.5 s before the ramp minus the mean over the 0.5 s before the shove; compliance_mm_per_n,
sag per newton of load (lower is stiffer); sway_mm, the largest sideways excursion of the base
from its loaded position, from the shove until its dip is known (1.5 s after it ends);
recovery_s, seconds from the shove's start until the base stays within 5 % of the sway of where
it comes to rest (empty: it never does within the run); push_dip_mm and settle_time_s are the
sweep's, for the height, about the shove; torque_rms.GROUP, the RMS actuator
torque of each joint group (haa, hfe, kfe) over the loaded window: what standing under the load
costs; copper_w, the mean copper loss R (tau/kt)^2 summed over the motors, when the model
declares each motor's torque constant and resistance as custom numerics pupper:kt:ACTUATOR
(N m/A) and pupper:resistance:ACTUATOR (ohm). Cells past the stability bound of the integrator
are marked past_bound and never ranked.
The stiffest cell is the lowest compliance_mm_per_n among cells that stood (status ok, under 5 %
saturation); equal values go to the smaller push dip, then to the first in grid order.

Examples:
  pupper hold --grid kp=5,10,20,40 --grid kd=0.25,0.5,1
  pupper hold --grid kp=10,20 --load 2 --shove 0.5 --plot
  pupper hold --kp 20 --kd 0.5 --mode torque --motor rate=500,filter=100"
)]
pub(super) struct HoldArgs {
    #[command(flatten)]
    grid: GridArg,
    #[command(flatten)]
    sim: SimArgs,
    /// Full load, in multiples of the robot's own weight.
    #[arg(long, default_value_t = pupper_core::plan::hold::LOAD, value_name = "WEIGHTS", allow_negative_numbers = true)]
    load: f64,
    /// Seconds the load takes to ramp from 0 to full (starting after the 1 s landing).
    #[arg(long, default_value_t = pupper_core::plan::hold::RAMP, value_name = "S", allow_negative_numbers = true)]
    ramp: f64,
    /// The sideways shove, in multiples of the robot's weight (0: none).
    #[arg(long, default_value_t = pupper_core::plan::hold::SHOVE, value_name = "WEIGHTS", allow_negative_numbers = true)]
    shove: f64,
    /// When the shove starts (s) [default: 0.5 s after the load is full].
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    shove_at: Option<f64>,
    /// How long the shove acts (s).
    #[arg(long, default_value_t = pupper_core::plan::hold::SHOVE_DURATION, value_name = "S", allow_negative_numbers = true)]
    shove_duration: f64,
    #[command(flatten)]
    output: OutputArgs,
    #[command(flatten)]
    show: ShowArgs<HoldArgs>,
    #[command(flatten)]
    runner: RunnerArgs,
}

impl Shows for HoldArgs {
    const SHOWN: Shown = Shown {
        trace: Some(TRACE_HEIGHT),
        plot: Some("Write plots into DIR/plots (compliance heatmap, base height under the load)"),
        render: None,
        rank: Some(RankHelp {
            help: "Rank cells by this summary column instead of compliance_mm_per_n (lowest wins)",
            value_name: "METRIC",
            alias: None,
        }),
    };
}

impl HoldArgs {
    fn input(&self) -> HoldInput {
        HoldInput {
            load: self.load,
            ramp: self.ramp,
            shove: self.shove,
            shove_at: self.shove_at,
            shove_duration: self.shove_duration,
        }
    }

    fn spec(&self) -> Result<SweepSpec> {
        let input = self.input();
        let sim = self.sim.spec()?;
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

/// `pupper hold`.
pub(super) fn run(a: HoldArgs, stop: &'static AtomicBool) -> Result<u8> {
    let input = HoldInput::default();
    let baseline = spec(
        SweepSpec {
            seconds: seconds(&input),
            ..SweepSpec::default()
        },
        &input,
    )?;
    let metric = a
        .show
        .rank
        .clone()
        .unwrap_or_else(|| baseline.experiment.plan().default_metric().to_string());
    run_job(
        Job {
            resume_alone: a.grid.grid.is_empty(),
            preset: Some("hold".into()),
            plot: a.show.plot,
            rule: Some(best::Rule::new(&metric, &[])),
            ..Job::new(a.spec()?, baseline, a.output.out, &a.runner.run)
        },
        stop,
    )
}
