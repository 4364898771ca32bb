//! The gait's stance, from the start pose: where each foot stands under
//! the body while walking (its place as the start pose puts it, the base at
//! the given height or the start pose's), and the check that every cell's
//! gait keeps the feet within the legs' reach.

use crate::error::{Error, Result};
use crate::plan::grid::{Cell, Grid};
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
            self.check_reach(&cell)?;
        }
        Ok(())
    }

    /// Refuses a cell whose feet the gait sends beyond its legs' reach.
    fn check_reach(&self, cell: &Cell) -> Result<()> {
        let gait = self.gait_of(cell);
        for (l, s) in self.legs.iter().zip(&self.stance) {
            for p in gait.extremes(s.nominal) {
                let miss = norm(sub(l.foot_at(l.solve(p, s.turns)), p));
                if miss > REACH_SLACK {
                    return Err(Error::Config(format!(
                        "cell {}: the gait puts {}'s foot {:.0} mm beyond its reach (a stride of {:.3} m at {} m/s and {} Hz, a {} m step, the base {:.3} m high): lower the speed or the step height, raise the frequency, or give --height",
                        cell.id,
                        l.name,
                        miss * 1e3,
                        gait.velocity[0].hypot(gait.velocity[1]) * gait.stance_time(),
                        gait.velocity[0],
                        gait.frequency,
                        gait.step_height,
                        self.height.unwrap_or(f64::NAN),
                    )));
                }
            }
        }
        Ok(())
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
            e.contains("cell v3:") && e.contains("beyond its reach"),
            "{e}"
        );
    }
}
