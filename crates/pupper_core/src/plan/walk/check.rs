//! What a walk refuses before anything runs, each in one line naming the
//! flag and the fix: its numbers out of range, a push, a grid that changes
//! the body under the legs measured on the model, a run too short for one
//! whole gait cycle of steady walking.

use crate::error::{Error, Result};
use crate::plan::grid::{Axis, Grid};
use crate::plan::schedule::Schedule;
use crate::plan::walk::{RAMP, SETTLE, SHIFT, Walk};

/// A number's flag, its value (None: not given, resolved on the model
/// later), whether a value is in range, and the fix.
type Rule<'a> = (&'a str, Option<f64>, fn(f64) -> bool, &'a str);

impl Walk {
    /// The gait's own numbers, each within its range.
    pub(super) fn check_numbers(&self) -> Result<()> {
        let rows: [Rule; 7] = [
            (
                "--frequency",
                Some(self.frequency),
                |v| v > 0.0 && v <= 20.0,
                "give a gait frequency in (0, 20] Hz",
            ),
            (
                "--duty",
                Some(self.duty),
                |v| (0.05..=0.95).contains(&v),
                "give a duty factor in [0.05, 0.95]",
            ),
            (
                "--speed",
                Some(self.speed),
                |v| v.abs() <= 5.0,
                "give a speed in [-5, 5] m/s",
            ),
            (
                "--sideways",
                Some(self.sideways),
                |v| v.abs() <= 5.0,
                "give a sideways speed in [-5, 5] m/s",
            ),
            (
                "--yaw-rate",
                Some(self.yaw_rate),
                |v| v.abs() <= 10.0,
                "give a yaw rate in [-10, 10] rad/s",
            ),
            (
                "--step-height",
                self.step_height,
                |v| (0.0..=1.0).contains(&v),
                "give a step height in [0, 1] m",
            ),
            (
                "--height",
                self.height,
                |v| v > 0.0,
                "give the base's height above the floor (m), > 0",
            ),
        ];
        for (flag, v, ok, rule) in rows {
            if let Some(v) = v
                && !(v.is_finite() && ok(v))
            {
                return Err(Error::Config(format!("{flag} {v}: {rule}")));
            }
        }
        Ok(())
    }

    /// No push, one body, and a run long enough for one whole cycle of
    /// steady walking at the grid's slowest frequency.
    pub(super) fn check_run(&self, s: &Schedule, grid: &Grid) -> Result<()> {
        let bad = |what: String| Err(Error::Config(what));
        if s.push.is_some() {
            return bad("a walk has no push: drop the push options".into());
        }
        if grid.has_axis(Axis::PushForce) {
            return bad(
                "a walk has no push (its robot is moved by the gait alone): drop the push_force grid axis".into(),
            );
        }
        for axis in [Axis::LegScale, Axis::Variant] {
            if grid.has_axis(axis) {
                return bad(format!(
                    "a walk runs the gait on one body's legs (measured on the compiled model): drop the {axis} grid axis, or give the other body as its own --model"
                ));
            }
        }
        let slowest = grid
            .axes
            .iter()
            .filter(|a| a.axis == Axis::Frequency)
            .flat_map(|a| a.values.iter().copied())
            .fold(self.frequency, f64::min);
        let (from, to) = self.window(slowest, s.duration);
        if to <= from {
            let need = from + 1.0 / slowest;
            return bad(format!(
                "--seconds {} leaves no whole gait cycle of steady walking: the window opens at {from} s (landing, {SHIFT} s to the stance, a {RAMP} s speed ramp, {SETTLE} s to settle) and a cycle at {slowest} Hz lasts {} s; give --seconds {} or more",
                s.duration,
                1.0 / slowest,
                crate::math::decimal::fmt_f64((need * 1000.0).ceil() / 1000.0)
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::plan::grid::Grid;
    use crate::plan::kind::KindPlan;
    use crate::plan::schedule::Schedule;
    use crate::plan::walk::tests::walk;

    #[test]
    fn checks_name_the_flag_and_the_fix() {
        let mut w = walk();
        let s = Schedule {
            duration: 8.0,
            push: None,
            ..Schedule::default()
        };
        assert!(w.check(&s, &Grid::default(), false).is_ok());
        let short = Schedule {
            duration: 3.9,
            ..s.clone()
        };
        let e = w
            .check(&short, &Grid::default(), false)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("--seconds 3.9") && e.contains("give --seconds 4 or more"),
            "{e}"
        );
        w.duty = 1.0;
        let e = w
            .check(&s, &Grid::default(), false)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("--duty 1:"), "{e}");
        w.duty = 0.6;
        w.step_height = Some(f64::NAN);
        let e = w
            .check(&s, &Grid::default(), false)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("--step-height NaN:"), "{e}");
        w.step_height = Some(0.06);
        let pushed = Schedule::default();
        assert!(w.check(&pushed, &Grid::default(), false).is_err());
    }
}
