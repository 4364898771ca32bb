//! `pupper render`: one model, or one cell of a finished run, to a PNG.

use std::path::PathBuf;

use clap::Args;
use pupper_core::request::spec::SweepSpec;
use pupper_core::results::output;
use pupper_core::{Error, Result};
use pupper_mujoco::bridge;

use super::args::SimArgs;
use pupper_mujoco::bridge::calls;

#[derive(Args, Debug)]
#[command(after_help = "Examples:
  pupper render --kp 5 --kd 0.1 -o stand.png          the robot after 10 s standing
  pupper render --run runs/X --cell 5 --time 2.5     cell 5 of a finished sweep at 2.5 s")]
pub(super) struct RenderArgs {
    #[command(flatten)]
    sim: SimArgs,
    /// A finished run directory: draw one of its cells (--cell), re-simulated with the run's
    /// own inputs (its push too); the model and controller flags are then not given.
    #[arg(long, value_name = "DIR")]
    run: Option<PathBuf>,
    /// With --run: the cell, by its id or index in summary.csv [default: the first].
    #[arg(long, value_name = "ID", requires = "run")]
    cell: Option<String>,
    /// The moment drawn, in simulated seconds from the start [default: the end of the run].
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    time: Option<f64>,
    /// Output PNG; an existing directory gets a file named for what is drawn
    /// [default: pupper.png, or with --run DIR/plots/render-<ID>-t<T>.png]
    #[arg(long, short = 'o', value_name = "FILE")]
    out: Option<PathBuf>,
    /// Overwrite FILE if it exists (only ever a PNG: any other file is refused).
    #[arg(long)]
    force: bool,
    /// Image width in pixels.
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Print {"path": ...} as JSON instead of the "wrote" line.
    #[arg(long)]
    json: bool,
}

impl RenderArgs {
    /// The PNG to write: `-o` as given, inside it when it is a directory,
    /// else the default for what is drawn.
    fn target(&self, default_name: &str, default_dir: Option<&std::path::Path>) -> PathBuf {
        match &self.out {
            Some(o) if o.is_dir() => o.join(default_name),
            Some(o) => o.clone(),
            None => default_dir
                .map(|d| d.join(default_name))
                .unwrap_or_else(|| PathBuf::from(default_name)),
        }
    }

    pub(super) fn run(&self) -> Result<u8> {
        let written = match &self.run {
            Some(dir) => self.render_cell(dir)?,
            None => self.render_stand()?,
        };
        if self.json {
            outln!("{}", serde_json::json!({ "path": written }));
        } else {
            outln!("wrote {written}");
        }
        Ok(0)
    }

    fn check_time(&self, seconds: f64) -> Result<()> {
        match self.time {
            Some(t) if !(0.0..=seconds).contains(&t) => Err(Error::Config(format!(
                "--time {t} is outside the run's 0..{seconds} s: give a time in that range"
            ))),
            _ => Ok(()),
        }
    }

    fn render_stand(&self) -> Result<String> {
        // the spec checks the values; the runner simulates, Python draws
        let spec = self.sim.spec()?;
        spec.build()?;
        self.check_time(spec.seconds)?;
        let out = self.target("pupper.png", None);
        check_png_target(&out, self.force)?;
        let written = bridge::call_helper(
            &calls::RENDER_PNG,
            &[out.display().to_string()],
            &serde_json::json!({
                "width": self.width,
                "height": self.height,
                "time": self.time,
                "model": spec.model,
                "variant": spec.variant,
                "mode": spec.mode,
                "seconds": spec.seconds,
                "kp": spec.kp,
                "kd": spec.kd,
                "max_torque": spec.max_torque,
                "keyframe": spec.keyframe,
                "pose": spec.pose,
            }),
        )?;
        Ok(written.first().cloned().unwrap_or_default())
    }

    fn render_cell(&self, dir: &std::path::Path) -> Result<String> {
        if self.sim.spec()? != SweepSpec::default() {
            return Err(Error::Config(format!(
                "--run {} draws a cell with the run's own inputs: drop the model and controller options, or render without --run",
                dir.display()
            )));
        }
        let cfg = output::read_manifest(dir)?.config;
        let cells = cfg.grid.cells();
        let cell = match &self.cell {
            None => cells.first(),
            Some(want) => cells
                .iter()
                .find(|c| &c.id == want || want.parse::<usize>().ok() == Some(c.index)),
        }
        .ok_or_else(|| {
            let ids: Vec<&str> = cells.iter().take(6).map(|c| c.id.as_str()).collect();
            Error::Config(format!(
                "--cell {} is not a cell of {}: give an id or index from its summary.csv (e.g. {}{})",
                self.cell.as_deref().unwrap_or(""),
                dir.display(),
                ids.join(", "),
                if cells.len() > ids.len() { ", ..." } else { "" }
            ))
        })?;
        let seconds = cfg.schedule.duration;
        self.check_time(seconds)?;
        let at = self.time.unwrap_or(seconds);
        let out = self.target(
            &format!("render-{}-t{}.png", cell.id, output::fmt_f64(at)),
            Some(&dir.join("plots")),
        );
        check_png_target(&out, self.force)?;
        let written = bridge::call_helper(
            &calls::RENDER_CELL_PNG,
            &[out.display().to_string(), dir.display().to_string()],
            &serde_json::json!({
                "cell": cell.index,
                "time": at,
                "width": self.width,
                "height": self.height,
            }),
        )?;
        Ok(written.first().cloned().unwrap_or_default())
    }
}

/// `render -o FILE`: a new file, or with `force` an existing PNG; never
/// anything else (a directory, a file that is not a PNG).
fn check_png_target(path: &std::path::Path, force: bool) -> Result<()> {
    let shown = path.display();
    let Ok(meta) = std::fs::symlink_metadata(path) else {
        return Ok(());
    };
    if !meta.is_file() {
        return Err(Error::Output(format!(
            "'{shown}' exists and is not a file: give -o a new .png path"
        )));
    }
    let mut head = [0u8; 8];
    let is_png = std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
        .is_ok()
        && head == *b"\x89PNG\r\n\x1a\n";
    match (is_png, force) {
        (false, _) => Err(Error::Output(format!(
            "'{shown}' exists and is not a PNG: pupper never writes over it; give -o a new .png path"
        ))),
        (true, false) => Err(Error::RunExists(format!(
            "'{shown}' exists: add --force to overwrite it, or give -o a new path"
        ))),
        (true, true) => Ok(()),
    }
}
