//! The walk kind's plan (`pupper walk`): the robot lands on its start pose,
//! moves its feet to the gait's stance, then walks open loop at the
//! kinematic level: a gait (`gait`) places every foot, each leg's inverse
//! kinematics (`leg`, its lengths and offsets read from the compiled model)
//! turns the feet into joint targets, and the same servo, firmware and
//! torque-mode paths as every kind's follow them. What it measures is in
//! `sim::walk`, its tables in `results::kinds::walk`.
//!
//! Timeline (defaults): the landing (the schedule's, 1 s); [`SHIFT`] s from
//! the start pose to the gait's stance; the gait, its speed ramped from 0
//! over [`RAMP`] s; [`SETTLE`] s more; then the steady window, the whole
//! gait cycles that fit before the run ends.

mod check;
pub mod gait;
pub mod leg;
pub mod measure;
mod motion;
mod stance;

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::plan::grid::{Axis, Cell, Grid};
use crate::plan::kind::{KindPlan, Motion, OnModel};
use crate::plan::schedule::Schedule;
use gait::{Gait, Pattern};
use leg::{Leg, V3};

/// Gait cycles per second unless told (Hz).
pub const FREQUENCY: f64 = 2.0;
/// Commanded forward speed unless told (m/s).
pub const SPEED: f64 = 0.25;
/// The step height on Pupper v3's legs (m), scaled to a model's own leg
/// length: at Pupper's kp 5 a swing that asks for less barely clears the
/// floor (measured: 12 mm of a 30 mm step at 2 Hz).
pub const STEP_HEIGHT: f64 = 0.06;
/// Seconds from the start pose to the gait's stance, after the landing.
pub const SHIFT: f64 = 0.5;
/// Seconds over which the commanded velocity ramps up from 0.
pub const RAMP: f64 = 1.0;
/// Seconds at full speed before the steady window opens.
pub const SETTLE: f64 = 1.0;
/// Simulated seconds unless `--seconds` says: 4.5 s of steady walking.
pub const SECONDS: f64 = 8.0;
/// The default stance puts the feet at most this share of the leg's reach
/// below the shoulder: a leg started straight has no stride left.
pub const MAX_DEPTH: f64 = 0.85;
/// How far a foot may land from where the gait asks (m) before the gait is
/// out of the legs' reach.
pub const REACH_SLACK: f64 = 1e-3;

/// Where a leg's foot stands in the gait's stance (base frame, m), and
/// its joints' turns from the default pose there (chain order).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Stance {
    pub nominal: V3,
    pub turns: [f64; 3],
}

/// A walk: the gait and what it is resolved on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Walk {
    pub gait: Pattern,
    /// Cycles per second (Hz); a `frequency` grid axis overrides it.
    pub frequency: f64,
    /// Commanded forward speed (m/s); a `speed` axis overrides it.
    pub speed: f64,
    /// Commanded sideways speed (m/s, to the left).
    #[serde(default)]
    pub sideways: f64,
    /// Commanded yaw rate (rad/s, to the left).
    #[serde(default)]
    pub yaw_rate: f64,
    /// The share of a cycle each foot is down; a `duty` axis overrides it.
    pub duty: f64,
    /// How high a swing lifts a foot (m); None until resolved: scaled to
    /// the legs. A `step_height` axis overrides it.
    pub step_height: Option<f64>,
    /// The base's height in the gait's stance (m); None until resolved:
    /// the start pose's.
    pub height: Option<f64>,
    /// When the gait starts (s): the landing's end plus [`SHIFT`].
    pub start: f64,
    /// Resolved: the legs, measured on the compiled model (base frame).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub legs: Vec<Leg>,
    /// Resolved: each leg's place in the stance.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stance: Vec<Stance>,
    /// Resolved: the robot's weight (N), for the cost of transport.
    #[serde(default)]
    pub weight: f64,
    /// Resolved: each actuator's gear (joint torque per unit of force).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub gears: Vec<f64>,
}

impl Walk {
    /// A walk of `gait` at these numbers, its stance and step resolved on
    /// the model; the gait starts [`SHIFT`] s after `landing`.
    pub fn new(gait: Pattern, velocity: [f64; 3], landing: f64) -> Walk {
        Walk {
            gait,
            frequency: FREQUENCY,
            speed: velocity[0],
            sideways: velocity[1],
            yaw_rate: velocity[2],
            duty: gait.default_duty(),
            step_height: None,
            height: None,
            start: landing + SHIFT,
            legs: Vec::new(),
            stance: Vec::new(),
            weight: 0.0,
            gears: Vec::new(),
        }
    }

    /// The gait of `cell`: its axes over the walk's own numbers.
    pub fn gait_of(&self, cell: &Cell) -> Gait {
        Gait {
            pattern: self.gait,
            frequency: cell.get(Axis::Frequency).unwrap_or(self.frequency),
            duty: cell.get(Axis::Duty).unwrap_or(self.duty),
            step_height: cell
                .get(Axis::StepHeight)
                .or(self.step_height)
                .unwrap_or(0.0),
            velocity: [
                cell.get(Axis::Speed).unwrap_or(self.speed),
                self.sideways,
                self.yaw_rate,
            ],
        }
    }

    /// When the velocity is full and settled: the steady window opens.
    pub fn steady_from(&self) -> f64 {
        self.start + RAMP + SETTLE
    }

    /// The steady window of a run of `duration` s at `frequency` Hz: from
    /// [`Walk::steady_from`], the whole cycles that fit (`(from, from)`
    /// when none does).
    pub fn window(&self, frequency: f64, duration: f64) -> (f64, f64) {
        let from = self.steady_from();
        let cycles = ((duration - from) * frequency + 1e-9).floor().max(0.0);
        (from, from + cycles / frequency)
    }
}

impl KindPlan for Walk {
    fn name(&self) -> &'static str {
        "walk"
    }

    fn pushes(&self) -> bool {
        false
    }

    fn moving_targets(&self) -> bool {
        true
    }

    /// The cell that walks at the commanded speed most nearly.
    fn default_metric(&self) -> &'static str {
        "speed_error_pct"
    }

    fn motion(&self, cell: &Cell, start: &[f64]) -> Option<Box<dyn Motion>> {
        motion::of(self, cell, start)
    }

    /// The legs measured on the model, then the stance on the start pose's
    /// targets, every cell of the grid within the legs' reach.
    fn resolve(&mut self, m: &OnModel<'_>, schedule: &mut Schedule) -> Result<()> {
        self.measure(m.info, schedule)?;
        let start = (m.start)()?.unwrap_or_else(|| vec![0.0; m.info.nu]);
        self.stand_on(&start, m.grid)
    }

    /// The gait's numbers in range; a run long enough for one whole cycle
    /// of steady walking at its slowest frequency; one body, no push.
    fn check(&self, s: &Schedule, grid: &Grid, _replicated: bool) -> Result<()> {
        self.check_numbers()?;
        self.check_run(s, grid)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::plan::grid::AxisValues;
    use leg::tests::pupper_front_right;

    /// Pupper v3's four legs, mirrored from the front right one.
    pub(crate) fn pupper_legs() -> Vec<Leg> {
        let fr = pupper_front_right();
        let mirror = |l: &Leg, front: bool, left: bool, name: &str, first: usize| {
            let ly = if left { -1.0 } else { 1.0 };
            let mut m = l.clone();
            m.name = name.into();
            m.front = front;
            m.left = left;
            let place = |p: V3| {
                let x = if front { p[0] } else { p[0] - 0.15 };
                [x, p[1] * ly, p[2]]
            };
            m.anchors = l.anchors.map(place);
            m.foot = place(l.foot);
            // a mirrored leg turns the other way about its pitch axes
            m.axes = l.axes.map(|u| [u[0], u[1] * ly, u[2]]);
            m.actuators = [first, first + 1, first + 2];
            m
        };
        vec![
            mirror(&fr, true, false, "leg_front_r_1", 0),
            mirror(&fr, true, true, "leg_front_l_1", 3),
            mirror(&fr, false, false, "leg_back_r_1", 6),
            mirror(&fr, false, true, "leg_back_l_1", 9),
        ]
    }

    pub(crate) fn walk() -> Walk {
        let mut w = Walk::new(Pattern::Trot, [0.25, 0.0, 0.0], 1.0);
        w.legs = pupper_legs();
        w.step_height = Some(0.06);
        w.stand_on(&[0.0; 12], &Grid::default()).unwrap();
        w
    }

    #[test]
    fn the_window_is_whole_cycles_after_the_settle() {
        let w = walk();
        assert_eq!(w.steady_from(), 3.5);
        assert_eq!(w.window(2.0, 8.0), (3.5, 8.0));
        let (from, to) = w.window(1.5, 8.0);
        assert!((from, (to - 3.5) * 1.5) == (3.5, 6.0), "{to}");
        assert_eq!(w.window(2.0, 3.9), (3.5, 3.5));
    }

    #[test]
    fn a_cell_axis_overrides_the_walks_numbers() {
        let w = walk();
        let grid = Grid {
            axes: vec![
                AxisValues::new(Axis::Speed, vec![0.1]).unwrap(),
                AxisValues::new(Axis::Frequency, vec![3.0]).unwrap(),
            ],
            ..Grid::default()
        };
        let g = w.gait_of(&grid.cells()[0]);
        assert_eq!((g.velocity[0], g.frequency, g.duty), (0.1, 3.0, 0.6));
    }
}
