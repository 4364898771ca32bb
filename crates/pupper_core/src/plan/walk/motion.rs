//! One simulation's joint targets as the walk moves them: the start pose
//! held through the landing, a smooth shift to the gait's stance, then each
//! leg's targets from where the gait puts its foot, by inverse kinematics.

use crate::plan::grid::Cell;
use crate::plan::kind::Motion;
use crate::plan::walk::gait::Gait;
use crate::plan::walk::leg::Leg;
use crate::plan::walk::{RAMP, SHIFT, Stance, Walk};

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// One simulation's joint targets as the walk moves them.
struct WalkMotion {
    gait: Gait,
    legs: Vec<Leg>,
    stance: Vec<Stance>,
    start_targets: Vec<f64>,
    start: f64,
}

impl Motion for WalkMotion {
    fn targets(&self, t: f64, out: &mut [f64]) {
        for (o, s) in out.iter_mut().zip(&self.start_targets) {
            *o = *s;
        }
        let shift_from = self.start - SHIFT;
        if t < shift_from {
            return;
        }
        if t < self.start {
            // from the start pose to the gait's stance, joint by joint
            let a = smoothstep((t - shift_from) / SHIFT);
            for (l, s) in self.legs.iter().zip(&self.stance) {
                for i in 0..3 {
                    let act = l.actuators[i];
                    if let (Some(o), Some(&from)) = (out.get_mut(act), self.start_targets.get(act))
                    {
                        *o = from + a * (l.zero[i] + s.turns[i] - from);
                    }
                }
            }
            return;
        }
        let tg = t - self.start;
        let ramp = if RAMP > 0.0 {
            (tg / RAMP).min(1.0)
        } else {
            1.0
        };
        let v = self.gait.velocity.map(|x| x * ramp);
        for (l, s) in self.legs.iter().zip(&self.stance) {
            let phase = self.gait.frequency * tg + self.gait.pattern.offset(l.front, l.left);
            let (p, _) = self.gait.foot(s.nominal, phase, v);
            let q = l.solve(p, s.turns);
            for (i, turn) in q.into_iter().enumerate() {
                if let Some(o) = out.get_mut(l.actuators[i]) {
                    *o = l.zero[i] + turn;
                }
            }
        }
    }
}
/// The walk's motion in a simulation of `cell` from the targets `start`
/// (None until the walk is resolved on a model).
pub(super) fn of(w: &Walk, cell: &Cell, start: &[f64]) -> Option<Box<dyn Motion>> {
    if w.legs.is_empty() || w.stance.len() != w.legs.len() {
        return None;
    }
    Some(Box::new(WalkMotion {
        gait: w.gait_of(cell),
        legs: w.legs.clone(),
        stance: w.stance.clone(),
        start_targets: start.to_vec(),
        start: w.start,
    }))
}

#[cfg(test)]
mod tests {
    use crate::plan::grid::Grid;
    use crate::plan::kind::KindPlan;
    use crate::plan::walk::RAMP;
    use crate::plan::walk::leg::{norm, sub};
    use crate::plan::walk::tests::walk;

    #[test]
    fn targets_hold_then_shift_then_walk_and_follow_the_feet() {
        let w = walk();
        let cell = Grid::default().cells().remove(0);
        let m = w.motion(&cell, &[0.1; 12]).unwrap();
        let mut out = [0.0; 12];
        m.targets(0.5, &mut out);
        assert_eq!(out, [0.1; 12]);
        // half-way through the shift: half-way from 0.1 to the stance (0)
        m.targets(1.25, &mut out);
        assert!(out.iter().all(|q| (q - 0.05).abs() < 1e-9), "{out:?}");
        // walking: each leg's targets put its foot where the gait says
        let g = w.gait_of(&cell);
        for t in [1.5, 1.9, 2.7, 3.3, 4.01] {
            m.targets(t, &mut out);
            for (l, s) in w.legs.iter().zip(&w.stance) {
                let q = [0, 1, 2].map(|i| out[l.actuators[i]] - l.zero[i]);
                let ramp = ((t - w.start) / RAMP).min(1.0);
                let v = g.velocity.map(|x| x * ramp);
                let phase = g.frequency * (t - w.start) + g.pattern.offset(l.front, l.left);
                let (p, _) = g.foot(s.nominal, phase, v);
                assert!(norm(sub(l.foot_at(q), p)) < 1e-12, "{} at {t}", l.name);
            }
        }
    }
}
