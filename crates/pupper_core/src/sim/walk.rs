//! The walk kind's probe: the stand kind's recorder (height, tilt, torque,
//! saturation, falls and when) plus what a gait shows of the gains, over
//! the steady window (`plan::walk::Walk::window`): the speed achieved
//! against the commanded one, the drift sideways and in yaw, the body's
//! roll, pitch and height, the feet's slip, how the joints follow their
//! targets at the gait frequency, torque, power and the cost of transport.

use nalgebra::{Quaternion, Unit, UnitQuaternion, Vector3};

use crate::plan::walk::Walk;
use crate::plan::walk::gait::Gait;
use crate::plan::walk::leg::{Leg, V3};
use crate::sim::probe::{Sample, Start};
use crate::sim::stand::Figures;

/// The walk's figures, in the order of [`WalkProbe`]'s.
pub const FIGURES: [&str; 13] = [
    "speed_ms",
    "speed_error_pct",
    "drift_ms",
    "yaw_drift_deg_s",
    "roll_rms_deg",
    "pitch_rms_deg",
    "height_std_mm",
    "slip_mm_s",
    "amplitude_ratio",
    "lag_ms",
    "torque_rms",
    "power_w",
    "cost_of_transport",
];

/// Whether a figure's bad side is low (a slow walk, joints that fall
/// short of their targets); every other's is high.
pub fn worse_low(figure: &str) -> bool {
    matches!(figure, "speed_ms" | "amplitude_ratio")
}

/// A foot whose centre is at most this far above its radius (m) is on the
/// floor: 0, its sphere touches the plane at z = 0, where MuJoCo makes a
/// contact (under load it sinks a few mm into the soft contact).
pub const GROUNDED: f64 = 0.0;

/// Roll, pitch and yaw (rad) of a (w, x, y, z) quaternion, z-y-x.
fn euler(q: [f64; 4]) -> (f64, f64, f64) {
    let [w, x, y, z] = q;
    let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
    let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
    let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
    (roll, pitch, yaw)
}

fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    let w = a.rem_euclid(t);
    if w > std::f64::consts::PI { w - t } else { w }
}

/// A foot after a step: its centre (world), whether it is on the floor,
/// and how its calf is turned (world).
type Foot = (V3, bool, UnitQuaternion<f64>);

/// The state a sample leaves for the next one.
struct Last {
    pos: V3,
    yaw: f64,
    q: Vec<f64>,
    feet: Vec<Foot>,
}

/// The walk's own figures, on the stand's recorder
/// ([`crate::sim::stand::OnStand`]).
pub struct WalkProbe {
    gait: Gait,
    legs: Vec<Leg>,
    gears: Vec<f64>,
    weight: f64,
    window: (f64, f64),
    dt: f64,
    last: Option<Last>,
    /// The time of the last sample (s).
    t: f64,
    n: usize,
    forward: f64,
    lateral: f64,
    yaw: f64,
    roll_sq: f64,
    pitch_sq: f64,
    z_sum: f64,
    z_sq: f64,
    slip: f64,
    grounded: usize,
    /// Per actuator, the target's and the joint's Fourier sums at the gait
    /// frequency (re, im).
    target_f: Vec<(f64, f64)>,
    joint_f: Vec<(f64, f64)>,
    torque_sq: f64,
    torque_n: usize,
    work: f64,
}

impl WalkProbe {
    pub fn new(s: &Start<'_>, walk: &Walk) -> WalkProbe {
        let gait = walk.gait_of(s.cell);
        let nu = s.layout.nu;
        WalkProbe {
            gait,
            legs: walk.legs.clone(),
            gears: walk.gears.clone(),
            weight: walk.weight,
            window: walk.window(gait.frequency, s.schedule.duration),
            dt: s.dt,
            last: None,
            t: 0.0,
            n: 0,
            forward: 0.0,
            lateral: 0.0,
            yaw: 0.0,
            roll_sq: 0.0,
            pitch_sq: 0.0,
            z_sum: 0.0,
            z_sq: 0.0,
            slip: 0.0,
            grounded: 0,
            target_f: vec![(0.0, 0.0); nu],
            joint_f: vec![(0.0, 0.0); nu],
            torque_sq: 0.0,
            torque_n: 0,
            work: 0.0,
        }
    }

    /// Each foot: its centre in the world, whether it is on the floor, and
    /// its calf's orientation in the world.
    fn feet(&self, pos: V3, quat: [f64; 4], q: &[f64]) -> Vec<Foot> {
        let base =
            UnitQuaternion::from_quaternion(Quaternion::new(quat[0], quat[1], quat[2], quat[3]));
        let at = Vector3::from(pos);
        self.legs
            .iter()
            .map(|l| {
                // every axis is taken at the default pose: the chain's
                // rotations compose first joint first, each about its anchor
                let turn = |i: usize| {
                    let angle = q.get(l.actuators[i]).copied().unwrap_or(0.0) - l.zero[i];
                    let u = Unit::new_unchecked(Vector3::from(l.axes[i]));
                    UnitQuaternion::from_axis_angle(&u, angle)
                };
                let r = [turn(0), turn(1), turn(2)];
                let p = l.anchors.map(Vector3::from);
                let mut f = Vector3::from(l.foot) - p[2];
                f = r[2] * f + (p[2] - p[1]);
                f = r[1] * f + (p[1] - p[0]);
                f = r[0] * f + p[0];
                let world = at + base * f;
                let calf = base * r[0] * r[1] * r[2];
                let f = [world.x, world.y, world.z];
                (f, f[2] <= l.radius + GROUNDED, calf)
            })
            .collect()
    }
}

impl Figures for WalkProbe {
    fn figures(&self) -> Vec<f64> {
        let (from, to) = self.window;
        let span = to - from;
        // a window the run did not reach (or left early: diverged) is not
        // measured
        if self.n == 0 || span <= 0.0 || self.t < to - 0.5 * self.dt {
            return vec![f64::NAN; FIGURES.len()];
        }
        let v = self.gait.velocity;
        let speed = self.forward / span;
        let side = self.lateral / span;
        let asked = v[0].hypot(v[1]);
        let error = if asked > 0.0 {
            100.0 * (speed - v[0]).hypot(side - v[1]) / asked
        } else {
            f64::NAN
        };
        let n = self.n as f64;
        let z_mean = self.z_sum / n;
        let z_var = (self.z_sq / n - z_mean * z_mean).max(0.0);
        // the joints' response at the gait frequency over the targets':
        // magnitudes summed, the phase of the summed cross-spectrum
        let (mut num, mut den, mut cross_re, mut cross_im) = (0.0, 0.0, 0.0, 0.0);
        for (&(tr, ti), &(jr, ji)) in self.target_f.iter().zip(&self.joint_f) {
            num += jr.hypot(ji);
            den += tr.hypot(ti);
            // joint x conj(target)
            cross_re += jr * tr + ji * ti;
            cross_im += ji * tr - jr * ti;
        }
        let omega = std::f64::consts::TAU * self.gait.frequency;
        let ratio = if den > 0.0 { num / den } else { f64::NAN };
        let lag = if den > 0.0 {
            -cross_im.atan2(cross_re) / omega * 1e3
        } else {
            f64::NAN
        };
        let power = self.work / span;
        vec![
            speed,
            error,
            (side - v[1]).abs(),
            (self.yaw / span - v[2]).abs().to_degrees(),
            (self.roll_sq / n).sqrt().to_degrees(),
            (self.pitch_sq / n).sqrt().to_degrees(),
            z_var.sqrt() * 1e3,
            if self.grounded > 0 {
                self.slip / (self.grounded as f64 * self.dt) * 1e3
            } else {
                f64::NAN
            },
            ratio,
            lag,
            if self.torque_n > 0 {
                (self.torque_sq / self.torque_n as f64).sqrt()
            } else {
                f64::NAN
            },
            power,
            if speed > 0.0 && self.weight > 0.0 {
                power / (self.weight * speed)
            } else {
                f64::NAN
            },
        ]
    }

    fn observe(&mut self, s: &Sample<'_>) {
        let Some(b) = s.layout.base.qpos else {
            return;
        };
        let qpos = s.qpos;
        let pos = [qpos[b], qpos[b + 1], qpos[b + 2]];
        let quat = [qpos[b + 3], qpos[b + 4], qpos[b + 5], qpos[b + 6]];
        let (roll, pitch, yaw) = euler(quat);
        self.t = s.t;
        let (from, to) = self.window;
        // samples are taken at the end of each step
        let inside = s.t > from + 1e-12 && s.t <= to + 1e-12;
        // the joints and feet matter from the sample before the window on
        let near = s.t > from - 1.5 * self.dt && s.t <= to + 1e-12;
        let q: Vec<f64> = match near {
            true => s.layout.act_qpos.iter().map(|&i| qpos[i]).collect(),
            false => Vec::new(),
        };
        let feet = match near {
            true => self.feet(pos, quat, &q),
            false => Vec::new(),
        };
        if let (true, Some(last)) = (inside, &self.last) {
            self.n += 1;
            // along the heading half-way through the step
            let turn = wrap(yaw - last.yaw);
            let (sin, cos) = (last.yaw + 0.5 * turn).sin_cos();
            let (dx, dy) = (pos[0] - last.pos[0], pos[1] - last.pos[1]);
            self.forward += dx * cos + dy * sin;
            self.lateral += -dx * sin + dy * cos;
            self.yaw += turn;
            self.roll_sq += roll * roll;
            self.pitch_sq += pitch * pitch;
            self.z_sum += pos[2];
            self.z_sq += pos[2] * pos[2];
            for ((l, (f, down, calf)), (g, was, before)) in
                self.legs.iter().zip(&feet).zip(&last.feet)
            {
                if *down && *was {
                    // the sphere's point on the floor: its centre's move
                    // less what rolling carries (the turn x (-r z))
                    let turn = (calf * before.inverse()).scaled_axis();
                    let dx = f[0] - g[0] - l.radius * turn.y;
                    let dy = f[1] - g[1] + l.radius * turn.x;
                    self.slip += dx.hypot(dy);
                    self.grounded += 1;
                }
            }
            // the target that drove the step was set at its start
            let omega = std::f64::consts::TAU * self.gait.frequency;
            let (ts, tc) = (omega * (s.t - self.dt)).sin_cos();
            let (js, jc) = (omega * s.t).sin_cos();
            for (a, (&target, &angle)) in s.targets.iter().zip(&q).enumerate() {
                if let (Some(tf), Some(jf)) = (self.target_f.get_mut(a), self.joint_f.get_mut(a)) {
                    tf.0 += target * tc;
                    tf.1 -= target * ts;
                    jf.0 += angle * jc;
                    jf.1 -= angle * js;
                }
            }
            for (a, &f) in s.act.iter().enumerate() {
                self.torque_sq += f * f;
                self.torque_n += 1;
                let gear = self.gears.get(a).copied().unwrap_or(1.0);
                let moved =
                    q.get(a).copied().unwrap_or(0.0) - last.q.get(a).copied().unwrap_or(0.0);
                // no regeneration: negative work costs as much as positive
                self.work += (f * gear * moved).abs();
            }
        }
        self.last = Some(Last { pos, yaw, q, feet });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_angles_have_known_answers() {
        let about = |axis: [f64; 3], a: f64| {
            let (s, c) = (a / 2.0).sin_cos();
            [c, s * axis[0], s * axis[1], s * axis[2]]
        };
        let (r, p, y) = euler(about([1.0, 0.0, 0.0], 0.2));
        assert!((r - 0.2).abs() < 1e-12 && p.abs() < 1e-12 && y.abs() < 1e-12);
        let (r, p, y) = euler(about([0.0, 1.0, 0.0], -0.3));
        assert!(r.abs() < 1e-12 && (p + 0.3).abs() < 1e-12 && y.abs() < 1e-12);
        let (_, _, y) = euler(about([0.0, 0.0, 1.0], 3.0));
        assert!((y - 3.0).abs() < 1e-12);
        assert!((wrap(3.5) - (3.5 - std::f64::consts::TAU)).abs() < 1e-15);
    }

    #[test]
    fn the_probes_feet_are_the_legs_kinematics_turned_with_the_base() {
        use crate::plan::grid::Grid;
        use crate::plan::schedule::Schedule;
        use crate::plan::walk::gait::Pattern;
        use crate::plan::walk::leg::{add, norm, sub};
        use crate::plan::walk::measure::rotate_by;
        use crate::robot::layout::Layout;
        let info = crate::robot::layout::tests::quadruped_info(4);
        let layout = Layout::floating(&info).unwrap();
        let mut w = Walk::new(Pattern::Trot, [0.25, 0.0, 0.0], 1.0);
        w.legs = (0..4)
            .map(|i| {
                let mut l = crate::plan::walk::leg::tests::textbook();
                l.actuators = [i * 3, i * 3 + 1, i * 3 + 2];
                l
            })
            .collect();
        let schedule = Schedule {
            push: None,
            ..Schedule::default()
        };
        let cell = Grid::default().cells().remove(0);
        let p = WalkProbe::new(
            &Start {
                excited: None,
                replicate: 0,
                cell: &cell,
                schedule: &schedule,
                dt: 0.002,
                stance: 0.3,
                layout: &layout,
                limits: &[3.0; 12],
            },
            &w,
        );
        let (s, c) = (0.15f64).sin_cos();
        let quat = [c, 0.3 * s, -0.2 * s, (1.0 - 0.13f64).sqrt() * s];
        let q: Vec<f64> = (0..12).map(|a| 0.1 * a as f64 - 0.5).collect();
        let pos = [0.4, -0.2, 0.3];
        for (l, (f, _, _)) in w.legs.iter().zip(p.feet(pos, quat, &q)) {
            let turns = l.actuators.map(|a| q[a]);
            let want = add(pos, rotate_by(quat, l.foot_at(turns)));
            assert!(norm(sub(f, want)) < 1e-12, "{f:?} {want:?}");
        }
    }

    #[test]
    fn the_bad_side_of_a_figure() {
        assert!(worse_low("speed_ms") && worse_low("amplitude_ratio"));
        assert!(!worse_low("speed_error_pct") && !worse_low("lag_ms"));
    }
}
