//! The hold kind's probe: the stand kind's recorder (height, tilt, the
//! shove's dip and settling, falls) plus what a load shows of the gains:
//! the sag from the unloaded to the loaded height, the sideways sway under
//! the shove, and the torque each joint group spends holding the load.

use crate::math::stats::Settle;
use crate::plan::hold::Load;
use crate::plan::schedule::Schedule;
use crate::sim::probe::Sample;
use crate::sim::stand::Figures;

/// The hold kind's figures, in the order of [`HoldProbe`]'s `figures`.
pub fn figure_names(load: &Load) -> Vec<String> {
    let mut out: Vec<String> = ["sag_mm", "compliance_mm_per_n", "sway_mm", "recovery_s"]
        .map(String::from)
        .to_vec();
    out.extend(load.group_names().iter().map(|g| format!("torque_rms.{g}")));
    if load.copper() {
        out.push("copper_w".into());
    }
    out
}

/// The band, as a fraction of the sway, within which the base has
/// recovered: it stays that close to where it comes to rest.
pub const RECOVERED: f64 = 0.05;

/// A mean over the samples inside a time window `(from, to]`.
#[derive(Default)]
struct Mean {
    sum: f64,
    n: usize,
}

impl Mean {
    fn add(&mut self, v: f64) {
        self.sum += v;
        self.n += 1;
    }
    fn value(&self) -> f64 {
        if self.n == 0 {
            f64::NAN
        } else {
            self.sum / self.n as f64
        }
    }
}

/// The hold's own figures, on the stand's recorder
/// ([`crate::sim::stand::OnStand`]).
pub struct HoldProbe {
    free: (f64, f64),
    loaded: (f64, f64),
    /// From the shove's start until its dip is known (s).
    shoved: Option<(f64, f64)>,
    full: f64,
    /// Each actuator's group, as an index into the group names.
    group_of: Vec<usize>,
    /// Each actuator's `R / kt²` (W per (N·m)²), where declared.
    copper: Option<Vec<f64>>,
    z_free: Mean,
    z_loaded: Mean,
    y_loaded: Mean,
    /// Per group: the sum of squared torques and the count.
    torque_sq: Vec<Mean>,
    copper_w: Mean,
    sway: f64,
    /// The sideways position from the shove's start, for `recovery_s`.
    settle: Option<Settle>,
    last_y: f64,
    dt: f64,
}

impl HoldProbe {
    pub fn new(load: &Load, schedule: &Schedule, dt: f64) -> HoldProbe {
        let names = load.group_names();
        let group_of = load
            .groups
            .iter()
            .map(|g| names.iter().position(|n| n == g).unwrap_or(0))
            .collect();
        let copper = load.copper().then(|| {
            load.winding
                .iter()
                .map(|w| w.map_or(0.0, |[kt, r]| r / (kt * kt)))
                .collect()
        });
        let shoved = schedule
            .push
            .as_ref()
            .zip(schedule.dip_end())
            .map(|(p, end)| (p.start, end));
        HoldProbe {
            free: load.free_window(),
            loaded: load.loaded_window(schedule),
            shoved,
            full: load.full(),
            group_of,
            copper,
            z_free: Mean::default(),
            z_loaded: Mean::default(),
            y_loaded: Mean::default(),
            torque_sq: (0..names.len()).map(|_| Mean::default()).collect(),
            copper_w: Mean::default(),
            sway: f64::NAN,
            settle: schedule
                .push
                .as_ref()
                .map(|p| Settle::new(p.start, RECOVERED, crate::plan::schedule::SETTLE_FLOOR)),
            last_y: f64::NAN,
            dt,
        }
    }
}

impl Figures for HoldProbe {
    fn figures(&self) -> Vec<f64> {
        let sag = (self.z_free.value() - self.z_loaded.value()) * 1000.0;
        let mut out = vec![
            sag,
            if self.full > 0.0 {
                sag / self.full
            } else {
                f64::NAN
            },
            self.sway,
            self.settle
                .as_ref()
                .and_then(|st| st.value(self.last_y, self.sway / 1000.0, self.dt))
                .unwrap_or(f64::NAN),
        ];
        out.extend(self.torque_sq.iter().map(|m| m.value().sqrt()));
        if self.copper.is_some() {
            out.push(self.copper_w.value());
        }
        out
    }

    fn observe(&mut self, s: &Sample<'_>) {
        let Some(q) = s.layout.base.qpos else {
            return;
        };
        let (y, z) = (s.qpos[q + 1], s.qpos[q + 2]);
        self.last_y = y;
        if let Some(st) = self.settle.as_mut() {
            st.push(s.t, y);
        }
        if inside(s.t, self.free) {
            self.z_free.add(z);
        }
        if inside(s.t, self.loaded) {
            self.z_loaded.add(z);
            self.y_loaded.add(y);
            // a group's actuators are a fixed set: the mean over its
            // actuator-steps is the mean over steps of their mean, with no
            // buffer per step
            for (a, &f) in s.act.iter().enumerate() {
                let g = self.group_of.get(a).copied().unwrap_or(0);
                self.torque_sq[g].add(f * f);
            }
            if let Some(c) = &self.copper {
                self.copper_w
                    .add(s.act.iter().zip(c).map(|(f, c)| c * f * f).sum());
            }
        }
        if let Some(w) = self.shoved
            && inside(s.t, w)
        {
            let d = (y - self.y_loaded.value()).abs() * 1000.0;
            if !d.is_nan() {
                self.sway = if self.sway.is_nan() {
                    d
                } else {
                    self.sway.max(d)
                };
            }
        }
    }
}

fn inside(t: f64, (from, to): (f64, f64)) -> bool {
    // samples are taken at the end of each step
    t > from + 1e-12 && t <= to + 1e-12
}
