//! The gait's stance, from the start pose: where each foot stands under
//! the body while walking (its place as the start pose puts it, the base at
//! the given height or the start pose's), and the check that every cell's
//! gait keeps the feet within the legs' reach.

use crate::error::{Error, Result};
use crate::plan::grid::{Cell, Grid};
use crate::plan::walk::gait::Gait;
use crate::plan::walk::leg::{V3, norm, sub};
use crate::plan::walk::{MAX_DEPTH, REACH_SLACK, Stance, Walk};

impl Walk {
    /// The stance on the start pose's joint targets `start` (actuator
    /// order): the feet where they stand there, the base at the given
    /// height or the start pose's; then every cell of `grid` checked to
    /// stay within the legs' reach.
    pub fn stand_on(&mut self, start: &[f64], grid: &Grid) -> Result<()> {
        let at_start: Vec<[f64; 3]> = self
            .legs
            .iter()
            .map(|l| {
                [0, 1, 2].map(|i| start.get(l.actuators[i]).copied().unwrap_or(0.0) - l.zero[i])
            })
            .collect();
        let feet: Vec<V3> = self
            .legs
            .iter()
            .zip(&at_start)
            .map(|(l, &q)| l.foot_at(q))
            .collect();
        let given = self.height.is_some();
        let height = match self.height {
            Some(h) => h,
            None => {
                let own = self
                    .legs
                    .iter()
                    .zip(&feet)
                    .map(|(l, f)| l.radius - f[2])
                    .sum::<f64>()
                    / self.legs.len().max(1) as f64;
                // no deeper than the legs can stride from
                self.legs
                    .iter()
                    .map(|l| MAX_DEPTH * l.reach() - l.shoulder()[2] + l.radius)
                    .fold(own, f64::min)
            }
        };
        self.height = Some(height);
        self.stance = self
            .legs
            .iter()
            .zip(&feet)
            .zip(&at_start)
            .map(|((l, f), &seed)| {
                let nominal = [f[0], f[1], l.radius - height];
                Stance {
                    nominal,
                    turns: l.solve(nominal, seed),
                }
            })
            .collect();
        for cell in grid.cells() {
            self.check_reach(&cell, given)?;
        }
        Ok(())
    }

    /// Refuses a cell whose feet the gait sends beyond its legs' reach,
    /// naming the flag that is the cause (`given`: the base's height was
    /// --height's).
    fn check_reach(&self, cell: &Cell, given: bool) -> Result<()> {
        let gait = self.gait_of(cell);
        match self.miss(&gait) {
            Some(_) => Err(Error::Config(self.reach_words(&gait, given))),
            None => Ok(()),
        }
    }

    /// The first leg `gait` sends beyond its reach, and by how much (m).
    fn miss(&self, gait: &Gait) -> Option<(&str, f64)> {
        self.legs.iter().zip(&self.stance).find_map(|(l, s)| {
            gait.extremes(s.nominal)
                .iter()
                .map(|&p| norm(sub(l.foot_at(l.solve(p, s.turns)), p)))
                .find(|&m| m > REACH_SLACK)
                .map(|m| (l.name.as_str(), m))
        })
    }

    /// What sends a foot beyond its reach, by the flag that sets it: the
    /// base's height (a foot misses standing still), the sideways speed or
    /// the yaw rate (the walk fits without it), the step (it misses at no
    /// speed), else the forward speed at the gait's frequency. Only
    /// `pupper walk` takes --height, --sideways, --yaw-rate and
    /// --step-height, so only their own causes name them.
    fn reach_words(&self, gait: &Gait, given: bool) -> String {
        let at = |v: [f64; 3], step: f64| Gait {
            velocity: v,
            step_height: step,
            ..*gait
        };
        let [vx, vy, wz] = gait.velocity;
        let h = self.height.unwrap_or(f64::NAN);
        let said = |g: &Gait, cause: String, fix: &str| match self.miss(g) {
            Some((leg, m)) => format!(
                "{cause} puts {leg}'s foot {:.0} mm beyond its reach: {fix}",
                m * 1e3
            ),
            None => format!("{cause} puts a foot beyond its reach: {fix}"),
        };
        if self.miss(&at([0.0; 3], 0.0)).is_some() {
            let cause = format!("the base {} m high, standing still,", round(h));
            return match given {
                true => said(
                    &at([0.0; 3], 0.0),
                    format!("--height {}: {cause}", round(h)),
                    "give a --height the legs reach standing, or leave it out (the start pose's)",
                ),
                false => said(
                    &at([0.0; 3], 0.0),
                    cause,
                    "give the model a start pose whose feet stand within the legs' reach",
                ),
            };
        }
        if vy != 0.0 && self.miss(&at([vx, 0.0, wz], gait.step_height)).is_none() {
            let cause = format!(
                "--sideways {} m/s (a sideways stride of {} m at {} Hz)",
                round(vy),
                round(vy.abs() * gait.stance_time()),
                round(gait.frequency)
            );
            return said(gait, cause, "lower --sideways, or raise --frequency");
        }
        if wz != 0.0 && self.miss(&at([vx, vy, 0.0], gait.step_height)).is_none() {
            let cause = format!(
                "--yaw-rate {} rad/s (a turn of {:.0}° per stance at {} Hz)",
                round(wz),
                (wz * gait.stance_time()).to_degrees(),
                round(gait.frequency)
            );
            return said(gait, cause, "lower --yaw-rate, or raise --frequency");
        }
        if self.miss(&at([0.0; 3], gait.step_height)).is_some() {
            let cause = format!("a {} m step (--step-height)", round(gait.step_height));
            return said(gait, cause, "lower --step-height");
        }
        let cause = format!(
            "a stride of {} m (--speed {} m/s at --frequency {} Hz, a {} m step, the base {} m high)",
            round(vx.hypot(vy) * gait.stance_time()),
            round(vx),
            round(gait.frequency),
            round(gait.step_height),
            round(h)
        );
        said(gait, cause, "lower --speed, or raise --frequency")
    }
}

/// `v` to the millimetre (or the thousandth), without trailing zeros.
fn round(v: f64) -> String {
    let t = format!("{v:.3}");
    let t = t.trim_end_matches('0').trim_end_matches('.');
    match t {
        "-0" => "0".into(),
        t => t.into(),
    }
}
#[cfg(test)]
mod tests {
    use crate::plan::grid::{Axis, AxisValues, Grid};
    use crate::plan::walk::tests::walk;

    #[test]
    fn the_stance_is_where_the_start_pose_stands() {
        let w = walk();
        // Pupper's feet at joints 0: 0.1116 m below the base, 2 cm radius
        assert!((w.height.unwrap() - (0.11156 + 0.02)).abs() < 1e-12);
        for (l, s) in w.legs.iter().zip(&w.stance) {
            assert!(s.turns.iter().all(|q| q.abs() < 1e-9), "{:?}", s.turns);
            assert!((s.nominal[0] - l.foot[0]).abs() < 1e-12);
        }
    }

    #[test]
    fn a_stride_out_of_reach_is_refused_with_the_cell() {
        let mut w = walk();
        let grid = Grid {
            axes: vec![AxisValues::new(Axis::Speed, vec![0.2, 3.0]).unwrap()],
            ..Grid::default()
        };
        let e = w.stand_on(&[0.0; 12], &grid).unwrap_err().to_string();
        assert!(
            e.contains("--speed 3 m/s") && e.contains("beyond its reach"),
            "{e}"
        );
        assert!(!e.contains("cell v3") && !e.contains("--height"), "{e}");
    }
}
