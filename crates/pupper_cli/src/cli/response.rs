//! `pupper response`: how each joint follows its target, a run of the
//! sweep runner with an excitation instead of a push.

use std::sync::atomic::AtomicBool;

use clap::Args;
use pupper_core::Result;
use pupper_core::request::spec::SweepSpec;

use super::args::{
    GridArg, OutputArgs, PopulationArgs, RunnerArgs, ShowArgs, Shown, Shows, SimArgs,
};
use super::sweep::{Job, run_job};

#[derive(Args, Debug)]
#[command(
    after_help = "Step figures (python-control's step_info and MATLAB's stepinfo, for a step of
size A commanded at the end of the hold, from the angle y0 then to the final value yf, the mean
over the last tenth of the window): rise_time_s from 10 % to 90 % of yf - y0; settling_time_s
until the angle stays within 2 % of |yf - y0| of yf (empty: never settled); overshoot_pct past yf
in % of |yf - y0|; peak_time_s; ss_error_rad = y0 + A - yf and ss_error_pct in % of A.
Sine: gain_db and phase_deg of the joint against its target (a least-squares fit over the second
half of the window). Chirp (logarithmic, F0 to F1 over the window): gain and phase at 24
log-spaced frequencies inside the band (the angle's Fourier sum over the target's, on the whole
window) in bode.csv; bandwidth_hz where the gain falls 3 dB below its value at the lowest of them
(refined by bisection), phase_at_bw_deg there, resonance_db the peak above it.
peak_torque and saturation_frac are the excited joint's actuator over the window. Status: ok,
saturated (at its torque limit in 5 % of steps or more), diverged.
Joint groups: haa (abduction), hfe (hip pitch), kfe (knee), assigned by what each joint does in
its leg on the compiled model (`pupper info` lists them), not by its name.

Examples:
  pupper response --grid kp=5,20,60 --grid kd=0.1,0.5,2
  pupper response --signal chirp --chirp 0.5,30 --seconds 12 --joints hfe --kp 20 --kd 0.5
  pupper response --signal sine --frequency 3 --amplitude 0.1 --standing"
)]
pub(super) struct ResponseArgs {
    #[command(flatten)]
    grid: GridArg,
    #[command(flatten)]
    sim: SimArgs,
    /// The excitation: step (the target jumps by --amplitude), sine (--frequency), chirp
    /// (a logarithmic sweep over --chirp F0,F1 for the window after the hold).
    #[arg(long, default_value = "step", value_name = "KIND")]
    signal: String,
    /// The signal's size (rad), added to the joint's pose angle.
    #[arg(long, default_value_t = pupper_core::plan::response::AMPLITUDE, value_name = "RAD", allow_negative_numbers = true)]
    amplitude: f64,
    /// --signal sine: its frequency (Hz).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    frequency: Option<f64>,
    /// --signal chirp: its band, F0,F1 in Hz [default: 0.5,20].
    #[arg(long, value_name = "F0,F1")]
    chirp: Option<String>,
    /// Seconds the pose is held before the signal starts (the joints settle under gravity).
    #[arg(long, default_value_t = pupper_core::request::response::DEFAULT_HOLD, value_name = "S", allow_negative_numbers = true)]
    hold: f64,
    /// The excited joints: groups (haa, hfe, kfe) or actuator names, comma-separated
    /// [default: every actuator].
    #[arg(long, value_name = "NAMES", value_delimiter = ',')]
    joints: Vec<String>,
    /// Excite the joints of the floating robot standing on the floor instead of the one hung
    /// in the air.
    #[arg(long)]
    standing: bool,
    #[command(flatten)]
    show: ShowArgs<ResponseArgs>,
    #[command(flatten)]
    output: OutputArgs,
    #[command(flatten)]
    runner: RunnerArgs,
    #[command(flatten)]
    population: PopulationArgs,
}

impl Shows for ResponseArgs {
    const SHOWN: Shown = Shown {
        trace: Some(
            "Keep each excited joint's angle after the hold (response_traces.csv), every \
             --trace-every-th step",
        ),
        plot: Some(
            "Write plots into DIR/plots: step responses per joint group (target dashed, the 2 % \
             band shaded), Bode gain and phase per group (sine, chirp), heatmaps of rise time, \
             overshoot and settling time over Kp x Kd",
        ),
        render: None,
        rank: None,
    };
}

impl ResponseArgs {
    fn spec(&self) -> Result<SweepSpec> {
        let signal = pupper_core::request::response::SignalInput {
            kind: self.signal.clone(),
            amplitude: self.amplitude,
            frequency: self.frequency,
            chirp: self
                .chirp
                .as_deref()
                .map(pupper_core::request::response::parse_chirp)
                .transpose()?,
        };
        let sim = self.population.apply(self.sim.spec()?);
        let base = SweepSpec {
            grid: self.grid.input(),
            seconds: self
                .sim
                .seconds
                .unwrap_or(pupper_core::request::response::SECONDS),
            force: self.output.force,
            // the step plots draw the traces
            ..self.runner.apply(self.show.traces(), sim)
        };
        pupper_core::request::response::spec(
            base,
            &signal,
            self.hold,
            &self.joints,
            self.standing,
            self.sim.keyframe.is_some(),
        )
    }
}

/// `pupper response`.
pub(super) fn run(a: ResponseArgs, stop: &'static AtomicBool) -> Result<u8> {
    let baseline = pupper_core::request::response::spec(
        SweepSpec {
            seconds: pupper_core::request::response::SECONDS,
            ..SweepSpec::default()
        },
        &Default::default(),
        pupper_core::request::response::DEFAULT_HOLD,
        &[],
        false,
        false,
    )?;
    run_job(
        Job {
            resume_alone: a.grid.grid.is_empty(),
            preset: Some("response".into()),
            plot: a.show.plot,
            ..Job::new(a.spec()?, baseline, a.output.out, &a.runner.run)
        },
        stop,
    )
}
