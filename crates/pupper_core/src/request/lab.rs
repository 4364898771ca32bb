//! The chapter's lab as one sweep: every body variant, each from a stand
//! pose searched on its own body, a Kp x Kd grid in torque mode under a
//! small vertical sine force, no push; the best gains per body by the rule
//! of [`crate::results::best`]. Its defaults are written here once, for the CLI's
//! `pupper lab` and Python's `pupper_core.lab()`.

use crate::plan::mode::Mode;
use crate::request::spec::{AutoPose, GridInput, PoseInput, SweepSpec};

/// The bodies of the lab, by default: every named variant.
pub const VARIANTS: [&str; 3] = {
    let v = crate::robot::variant::VARIANTS;
    [v[0].name, v[1].name, v[2].name]
};
/// The gains, by default.
pub const GRID: [&str; 2] = ["kp=10,30,60,120", "kd=0.5,1,2,5"];
/// Simulated seconds per cell.
pub const SECONDS: f64 = 6.0;
/// The disturbance: `2 sin(2 pi 1.2 t)` N, vertical.
pub const SINE: [f64; 2] = [2.0, 1.2];

/// The lab's sweep over `variants` and `grid` (the default gains when
/// empty; a grid that names its own `variant` axis replaces `variants`).
pub fn spec(variants: &[String], grid: &[String], seconds: f64, sine: [f64; 2]) -> SweepSpec {
    let mut specs = Vec::new();
    let names_bodies = grid
        .iter()
        .any(|g| g.split('=').next().is_some_and(|a| a.trim() == "variant"));
    if !names_bodies {
        specs.push(format!("variant={}", variants.join(",")));
    }
    if grid.is_empty() {
        specs.extend(GRID.map(String::from));
    } else {
        specs.extend(grid.iter().cloned());
    }
    SweepSpec {
        grid: GridInput::Specs(specs),
        mode: Mode::Torque,
        pose: Some(PoseInput::Auto(AutoPose::Auto)),
        push: false,
        sine: Some(sine),
        seconds,
        trace: true,
        kind: Some("lab"),
        ..SweepSpec::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::grid::Axis;

    #[test]
    fn three_bodies_times_sixteen_gains_in_torque_mode() {
        let v: Vec<String> = VARIANTS.map(String::from).to_vec();
        let s = spec(&v, &[], SECONDS, SINE).build().unwrap();
        assert_eq!(s.config.grid.len(), 48);
        assert_eq!(s.config.grid.axes[0].axis, Axis::Variant);
        assert_eq!(s.config.mode, Mode::Torque);
        assert!(s.config.schedule.push.is_none() && s.config.schedule.sine.is_some());
        let own = spec(&v, &["variant=heavy".into(), "kp=5".into()], 1.0, SINE)
            .build()
            .unwrap();
        assert_eq!(own.config.grid.len(), 1);
    }
}
