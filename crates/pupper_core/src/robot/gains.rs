//! PD gains from a joint's reflected inertia: what a bandwidth and damping
//! ratio ask for, what given gains give, and whether the PD at the model's
//! timestep is stable as the integrator takes its damping (explicitly, or
//! implicitly as `implicitfast` does for a servo).

use serde::Serialize;

use crate::math::margins::Feedback;
use crate::math::response::{gains_for, natural, pd_margin};
use crate::robot::model::ModelInfo;

/// What gains do to a joint (or a group, on its mean inertia).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Figures {
    /// Joint-space inertia diagonal at the pose, armature included (kg·m²).
    pub inertia: f64,
    /// The gains to command.
    pub kp: f64,
    pub kd: f64,
    /// What the motor delivers of them, where the model's gain scales
    /// (`pupper:kp_scale:ACT`, `pupper:kd_scale:ACT`: a fit's) are not 1.
    /// Every figure below is of these: the loop is closed on what the motor
    /// applies, not on what it is told.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub delivered: Option<[f64; 2]>,
    /// The natural frequency (Hz) and damping ratio these gains give.
    pub natural_hz: f64,
    pub damping_ratio: f64,
    /// The stability margin at the timestep ([`pd_margin`]): 1 or more is
    /// past the bound.
    pub stability_margin: f64,
    /// With a firmware ([`GainsReport::with_feedback`]): the loop's phase
    /// margin (deg) and gain margin (dB); a group's, its worst joint's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub phase_margin_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gain_margin_db: Option<f64>,
}

impl Figures {
    /// The figures of commanded `kp`, `kd` that the motor delivers times
    /// `scale` (kp's, kd's), on `inertia`, with the stability margin of the
    /// delivered gains at `timestep` (no loop margins until a firmware is
    /// given).
    fn new(
        inertia: f64,
        kp: f64,
        kd: f64,
        scale: [f64; 2],
        bound: impl Fn(f64, f64) -> f64,
    ) -> Figures {
        let [dkp, dkd] = [kp * scale[0], kd * scale[1]];
        let (natural_hz, damping_ratio) = natural(inertia, dkp, dkd);
        Figures {
            inertia,
            kp,
            kd,
            delivered: (scale != [1.0, 1.0]).then_some([dkp, dkd]),
            natural_hz,
            damping_ratio,
            stability_margin: bound(dkp, dkd),
            phase_margin_deg: None,
            gain_margin_db: None,
        }
    }

    /// The kp and kd the motor applies: the commanded ones times the
    /// model's gain scales.
    pub fn delivered(&self) -> [f64; 2] {
        self.delivered.unwrap_or([self.kp, self.kd])
    }
}

/// One actuated joint's figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointGains {
    pub actuator: String,
    pub group: String,
    #[serde(flatten)]
    pub figures: Figures,
    /// The loop its margins are of, where a firmware or a calibrated
    /// model's fitted servo closes one.
    #[serde(rename = "loop", skip_serializing_if = "Option::is_none")]
    pub loop_terms: Option<LoopTerms>,
}

/// What closes a joint's loop besides its inertia and gains: the
/// firmware's feedback path and the joint's viscous damping.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LoopTerms {
    #[serde(flatten)]
    pub feedback: Feedback,
    /// Viscous damping in the loop (N·m·s/rad): a calibrated model's fitted
    /// joint damping; 0 otherwise (unknown: the conservative case).
    pub damping: f64,
}

/// A joint group's gains: for a bandwidth, on the group's mean inertia.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupGains {
    pub group: String,
    pub joints: usize,
    #[serde(flatten)]
    pub figures: Figures,
}

/// What `pupper gains` reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GainsReport {
    pub model: String,
    pub timestep: f64,
    /// The bandwidth (Hz) and damping ratio asked for, if any.
    pub bandwidth_hz: Option<f64>,
    pub damping: Option<f64>,
    /// True when the margins take the damping implicitly.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub implicit_damping: bool,
    pub groups: Vec<GroupGains>,
    pub joints: Vec<JointGains>,
    /// The firmware the loop margins are for, when asked (a calibrated
    /// model's: its first joint's; each joint's own is in `joints[].loop`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub feedback: Option<Feedback>,
    /// The margins close the loop a fit found: the model's fitted servo
    /// (torque lag, feedback latency) and joint damping.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub fitted: bool,
}

impl GainsReport {
    /// Each joint's (and group's worst) phase and gain margin of the loop
    /// `fb` closes, the joint linearised at the report's pose with no
    /// viscous damping (the conservative case: damping adds phase).
    pub fn with_feedback(self, fb: Feedback) -> GainsReport {
        let n = self.joints.len();
        self.with_loops(
            &vec![
                LoopTerms {
                    feedback: fb,
                    damping: 0.0
                };
                n
            ],
            false,
        )
    }

    /// Each joint's (and group's worst) phase and gain margin of its own
    /// loop, `terms[j]` for joint j (`fitted`: a calibrated model's fitted
    /// servo and damping).
    pub fn with_loops(mut self, terms: &[LoopTerms], fitted: bool) -> GainsReport {
        for (j, t) in self.joints.iter_mut().zip(terms) {
            let f = &mut j.figures;
            let [kp, kd] = f.delivered();
            let (pm, gm) = t
                .feedback
                .servo(f.inertia, t.damping, kp, kd)
                .margins()
                .map_or((f64::NAN, f64::NAN), |m| (m.phase_deg, m.gain_db));
            (f.phase_margin_deg, f.gain_margin_db) = (Some(pm), Some(gm));
            j.loop_terms = Some(*t);
        }
        for g in &mut self.groups {
            let worst = |f: &dyn Fn(&JointGains) -> Option<f64>| {
                self.joints
                    .iter()
                    .filter(|j| j.group == g.group)
                    .filter_map(f)
                    .fold(f64::INFINITY, f64::min)
            };
            g.figures.phase_margin_deg = Some(worst(&|j| j.figures.phase_margin_deg));
            g.figures.gain_margin_db = Some(worst(&|j| j.figures.gain_margin_db));
        }
        self.feedback = terms.first().map(|t| t.feedback);
        self.fitted = fitted;
        self
    }
}

/// What the gains are for: a bandwidth and damping, or given gains.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Ask {
    Bandwidth { hz: f64, zeta: f64 },
    Gains { kp: f64, kd: f64 },
}

/// Actuator `a`'s joint group ("other" where the model names none).
fn group_of(info: &ModelInfo, a: usize) -> String {
    info.actuator_group(a).unwrap_or("other").to_string()
}

/// What actuator `a`'s motor delivers of a commanded kp and kd.
fn gain_scale(info: &ModelInfo, a: usize) -> [f64; 2] {
    info.actuators.get(a).map_or([1.0, 1.0], |x| x.gain_scale)
}

/// The model's joint groups in the order of `JOINT_GROUPS` (others last).
fn group_names(info: &ModelInfo) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for a in 0..info.nu {
        if !names.contains(&group_of(info, a)) {
            names.push(group_of(info, a));
        }
    }
    let order = |g: &String| {
        crate::robot::model::JOINT_GROUPS
            .iter()
            .position(|x| x == g)
            .unwrap_or(usize::MAX)
    };
    names.sort_by_key(order);
    names
}

/// Group `g`'s row: its gains (for the bandwidth, or as given) on its mean
/// joint, its stability margin that of its first joint past the bound.
fn group_row(
    info: &ModelInfo,
    inertia: &[f64],
    g: &str,
    ask: Ask,
    timestep: f64,
    implicit: bool,
) -> GroupGains {
    let group = |a: usize| group_of(info, a);
    let scale = |a: usize| gain_scale(info, a);
    let bound = |i: f64| move |kp: f64, kd: f64| pd_margin(i, kp, kd, timestep, implicit);
    let members: Vec<usize> = (0..info.nu).filter(|&a| group(a) == g).collect();
    let n = members.len().max(1) as f64;
    let i = members.iter().map(|&a| inertia[a]).sum::<f64>() / n;
    // the group's mean scale: its row is on its mean joint
    let s = [0, 1].map(|k| members.iter().map(|&a| scale(a)[k]).sum::<f64>() / n);
    let s = if members.is_empty() { [1.0, 1.0] } else { s };
    let (kp, kd) = match ask {
        Ask::Bandwidth { hz, zeta } => {
            let (kp, kd) = gains_for(i, hz, zeta);
            (kp / s[0], kd / s[1])
        }
        Ask::Gains { kp, kd } => (kp, kd),
    };
    let mut figures = Figures::new(i, kp, kd, s, bound(i));
    // the group's gains on each of its joints as it delivers them:
    // the lightest, or the most scaled, is the first past the bound
    figures.stability_margin = members
        .iter()
        .map(|&a| {
            pd_margin(
                inertia[a],
                kp * scale(a)[0],
                kd * scale(a)[1],
                timestep,
                implicit,
            )
        })
        .fold(0.0, f64::max);
    GroupGains {
        group: g.to_string(),
        joints: members.len(),
        figures,
    }
}

/// The report for `inertia` (one per actuator, in ctrl order) on `info`;
/// `implicit` when the integrator takes the damping implicitly. Given
/// gains are what to command; a bandwidth's are too, divided by what the
/// motor delivers of them (the model's gain scales), so that the loop the
/// motor closes has that bandwidth. Every figure is of the delivered gains.
pub fn report(
    info: &ModelInfo,
    inertia: &[f64],
    timestep: f64,
    ask: Ask,
    implicit: bool,
) -> GainsReport {
    let group = |a: usize| group_of(info, a);
    let scale = |a: usize| gain_scale(info, a);
    let bound = |i: f64| move |kp: f64, kd: f64| pd_margin(i, kp, kd, timestep, implicit);
    let groups = group_names(info)
        .iter()
        .map(|g| group_row(info, inertia, g, ask, timestep, implicit))
        .collect::<Vec<_>>();
    let joints = (0..info.nu)
        .map(|a| {
            let g = group(a);
            // a bandwidth's gains are the group's, as a grid would run them
            let (kp, kd) = match ask {
                Ask::Gains { kp, kd } => (kp, kd),
                Ask::Bandwidth { .. } => groups
                    .iter()
                    .find(|x| x.group == g)
                    .map_or((0.0, 0.0), |x| (x.figures.kp, x.figures.kd)),
            };
            JointGains {
                actuator: info.actuators[a].name.clone(),
                group: g,
                figures: Figures::new(inertia[a], kp, kd, scale(a), bound(inertia[a])),
                loop_terms: None,
            }
        })
        .collect();
    let (bandwidth_hz, damping) = match ask {
        Ask::Bandwidth { hz, zeta } => (Some(hz), Some(zeta)),
        Ask::Gains { .. } => (None, None),
    };
    GainsReport {
        model: info.name.clone(),
        timestep,
        bandwidth_hz,
        damping,
        implicit_damping: implicit,
        groups,
        joints,
        feedback: None,
        fitted: false,
    }
}
