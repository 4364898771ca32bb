//! A running sweep's progress on stderr: indicatif's bar on a terminal; off
//! one (a pipe, nohup, CI) a plain line now and then, as build tools print,
//! so a long run says that it runs, how big it is and when it should end.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};
use pupper_core::Result;
use pupper_core::sim::runner::{CellResult, Hooks};
use pupper_mujoco::api::SweepUi;

/// Off a terminal, the first line comes after this long (a run shorter than
/// it prints what it always did), then one every [`EVERY`].
const FIRST: Duration = Duration::from_secs(10);
const EVERY: Duration = Duration::from_secs(30);

/// Plain progress lines: what runs, its size, and where it stands.
struct Lines {
    what: String,
    cells: usize,
    steps: u64,
    done: u64,
    kept: usize,
    started: Instant,
    next: Duration,
}

impl Lines {
    fn tick(&mut self) {
        let spent = self.started.elapsed();
        if spent < self.next || self.steps == 0 {
            return;
        }
        let share = self.done as f64 / self.steps as f64;
        let left = match share > 0.0 {
            true => format!(
                "about {} left",
                clock(spent.as_secs_f64() * (1.0 - share) / share)
            ),
            false => "no estimate yet".into(),
        };
        let percent = 100.0 * share;
        if self.next == FIRST {
            errln!(
                "progress: {} of {} cells ({} cell-steps) running for {}: {percent:.0} % done, {} cells kept, {left}; a line every {} s",
                self.what,
                self.cells,
                self.steps,
                clock(spent.as_secs_f64()),
                self.kept,
                EVERY.as_secs()
            );
        } else {
            errln!(
                "progress: {} {percent:.0} % done ({} of {} cells kept) in {}, {left}",
                self.what,
                self.kept,
                self.cells,
                clock(spent.as_secs_f64())
            );
        }
        self.next = spent + EVERY;
    }
}

/// `s` seconds as 42 s, 3m05s or 1h02m.
fn clock(s: f64) -> String {
    let s = s.max(0.0).round() as u64;
    match s {
        0..60 => format!("{s} s"),
        60..3600 => format!("{}m{:02}s", s / 60, s % 60),
        _ => format!("{}h{:02}m", s / 3600, s / 60 % 60),
    }
}

/// The progress of a run (a bar on a terminal, lines off one, nothing with
/// -q) and the Ctrl-C flag.
pub(super) struct Progress {
    bar: Option<ProgressBar>,
    lines: Option<Lines>,
    quiet: bool,
    /// The run's kind, as its lines name it (sweep, lab, walk, ...).
    what: String,
    stop: &'static AtomicBool,
}

impl Progress {
    pub(super) fn new(what: &str, quiet: bool, stop: &'static AtomicBool) -> Progress {
        Progress {
            bar: None,
            lines: None,
            quiet,
            what: what.to_string(),
            stop,
        }
    }
}

impl SweepUi for Progress {
    fn start(&mut self, cells: usize, steps: u64) {
        if self.quiet {
            return;
        }
        if !std::io::stderr().is_terminal() {
            self.lines = Some(Lines {
                what: self.what.clone(),
                cells,
                steps,
                done: 0,
                kept: 0,
                started: Instant::now(),
                next: FIRST,
            });
            return;
        }
        let bar = ProgressBar::new(steps);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} {msg} [{bar:30}] {percent:>3}% {elapsed} (eta {eta})",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        bar.set_message(format!("{cells} cells"));
        self.bar = Some(bar);
    }

    fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
        self.lines = None;
    }

    fn hooks(&mut self) -> &mut dyn Hooks {
        self
    }
}

impl Hooks for Progress {
    fn progress(&mut self, steps: u64) {
        if let Some(b) = &self.bar {
            b.inc(steps);
        }
        if let Some(l) = &mut self.lines {
            l.done += steps;
            l.tick();
        }
    }

    fn should_stop(&mut self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    fn chunk_done(&mut self, results: &[CellResult]) -> Result<()> {
        if let Some(l) = &mut self.lines {
            l.kept += results.len();
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::clock;

    #[test]
    fn clocks_read_as_a_person_says_them() {
        assert_eq!(clock(9.6), "10 s");
        assert_eq!(clock(185.0), "3m05s");
        assert_eq!(clock(3720.0), "1h02m");
    }
}
