//! `pupper gains`'s printout: a line per joint group, then per joint, and
//! what the columns mean.

use std::fmt::Write;

use pupper_core::robot::gains::{Figures, GainsReport};

use super::Sig;

/// The loop margins' columns, when a firmware is given: below 0 deg the
/// loop is unstable.
fn margins(pm: Option<f64>, gm: Option<f64>) -> String {
    match (pm, gm) {
        (Some(pm), Some(gm)) => format!(
            " {:>9} {:>9}",
            if pm < 0.0 {
                format!("{pm:.0} UNST")
            } else {
                format!("{pm:.0}")
            },
            if gm.is_finite() {
                format!("{gm:.1}")
            } else if gm > 0.0 {
                "inf".into()
            } else {
                "-inf".into()
            }
        ),
        _ => String::new(),
    }
}

/// `pupper gains`: a line per joint group, then per joint.
pub fn gains(r: &GainsReport) -> String {
    let mut s = String::new();
    title(&mut s, r);
    let table = Table {
        looped: r.feedback.is_some(),
        // a calibrated model's motors deliver other gains than they are told
        scaled: r.joints.iter().any(|j| j.figures.delivered.is_some()),
    };
    let _ = writeln!(s, "{}", table.header());
    for g in &r.groups {
        let _ = writeln!(
            s,
            "{}",
            table.row(format!("{} ({})", g.group, g.joints), &g.figures)
        );
    }
    let _ = writeln!(s);
    for j in &r.joints {
        let _ = writeln!(s, "{}", table.row(j.actuator.clone(), &j.figures));
    }
    notes(&mut s, r, table.scaled);
    s
}

/// What the gains are for: a bandwidth and damping, or given gains.
fn title(s: &mut String, r: &GainsReport) {
    match (r.bandwidth_hz, r.damping) {
        (Some(hz), Some(z)) => {
            let _ = writeln!(
                s,
                "{}: gains for a {hz} Hz bandwidth at damping {z} (timestep {} s)",
                r.model, r.timestep
            );
        }
        _ => {
            let _ = writeln!(
                s,
                "{}: what the gains give (timestep {} s{})",
                r.model,
                r.timestep,
                if r.implicit_damping {
                    ", damping integrated implicitly"
                } else {
                    ""
                }
            );
        }
    }
}

/// The table's columns: the motor's delivered gains where they differ
/// (`scaled`), the loop margins where a firmware is given (`looped`).
struct Table {
    looped: bool,
    scaled: bool,
}

impl Table {
    fn header(&self) -> String {
        let (looped, scaled) = (self.looped, self.scaled);
        let mut head = format!("{:<16} {:>12} {:>10} {:>10}", "", "inertia", "kp", "kd");
        if scaled {
            head.push_str(&format!(" {:>10} {:>10}", "motor kp", "motor kd"));
        }
        head.push_str(&format!(
            " {:>11} {:>9} {:>10}",
            "natural_hz", "damping", "stability"
        ));
        if looped {
            head.push_str(&format!(" {:>9} {:>9}", "PM deg", "GM dB"));
        }
        head.trim_end().to_string()
    }

    /// A row of figures under `label`.
    fn row(&self, label: String, f: &Figures) -> String {
        let (looped, scaled) = (self.looped, self.scaled);
        // a stability margin of 1 or more is past the bound
        let flag = |m: f64| {
            if m >= 1.0 {
                format!("{} PAST", Sig(m))
            } else {
                format!("{}", Sig(m))
            }
        };
        let [dkp, dkd] = f.delivered();
        format!(
            "{:<16} {:>12} {:>10} {:>10}{} {:>11} {:>9} {:>10}{}",
            label,
            format!("{:.3e}", f.inertia),
            Sig(f.kp).to_string(),
            Sig(f.kd).to_string(),
            if scaled {
                format!(" {:>10} {:>10}", Sig(dkp).to_string(), Sig(dkd).to_string())
            } else {
                String::new()
            },
            Sig(f.natural_hz).to_string(),
            Sig(f.damping_ratio).to_string(),
            flag(f.stability_margin),
            if looped {
                margins(f.phase_margin_deg, f.gain_margin_db)
            } else {
                String::new()
            }
        )
    }
}

/// What the columns mean, and the loop the margins are of.
fn notes(s: &mut String, r: &GainsReport, scaled: bool) {
    let _ = writeln!(
        s,
        "inertia: kg·m² (armature included); stability: 1 or more is past the explicit PD's bound (see --help)"
    );
    if scaled {
        let _ = writeln!(
            s,
            "kp, kd: what to command; motor kp, motor kd: what the motor delivers of them (the model's gain scales, pupper:kp_scale/kd_scale, a fit's); every other figure is of the delivered gains"
        );
    }
    if r.fitted {
        let range = |f: &dyn Fn(&pupper_core::robot::gains::LoopTerms) -> f64| {
            let v: Vec<f64> = r
                .joints
                .iter()
                .filter_map(|j| j.loop_terms.as_ref().map(f))
                .collect();
            let (lo, hi) = v
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                });
            if (hi - lo).abs() <= 1e-12 * hi.abs().max(1.0) {
                format!("{}", Sig(lo))
            } else {
                format!("{} to {}", Sig(lo), Sig(hi))
            }
        };
        let _ = writeln!(
            s,
            "PM/GM: phase and gain margin of the loop the fit found (the model's calibrated servo{}): torque lag {} ms, feedback latency {} ms, joint damping {} N·m·s/rad; --motor and --sensing-delay stand in for the fitted terms they name (see --help)",
            match r
                .joints
                .first()
                .and_then(|j| j.loop_terms)
                .and_then(|t| t.feedback.sampled)
            {
                Some(s) => format!(", its PD every {} ms physics step", Sig(s.step * 1000.0)),
                None => String::new(),
            },
            range(&|t| t.feedback.torque_lag * 1000.0),
            range(&|t| t
                .feedback
                .sampled
                .map_or(t.feedback.latency, |s| s.late * s.step)
                * 1000.0),
            range(&|t| t.damping),
        );
    } else if let Some(fb) = &r.feedback {
        let _ = writeln!(
            s,
            "PM/GM: phase and gain margin of the loop the firmware closes: {} ms of feedback latency{}{} (see --help)",
            Sig(fb.latency * 1000.0),
            fb.filter_hz
                .map(|f| format!(", derivative filtered at {} Hz", Sig(f)))
                .unwrap_or_default(),
            if fb.derivative_delay > 0.0 {
                format!(
                    ", derivative differenced over a period (+{} ms)",
                    Sig(fb.derivative_delay * 1000.0)
                )
            } else {
                String::new()
            }
        );
    }
}
