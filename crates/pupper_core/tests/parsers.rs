//! Property tests: the grid and schedule parsers return errors, never panic,
//! whatever they are fed.

use proptest::prelude::*;
use pupper_core::plan::grid::{AxisValues, Grid};
use pupper_core::plan::schedule::Schedule;

proptest! {
    #[test]
    fn grid_spec_never_panics(s in ".{0,40}") {
        let _ = AxisValues::parse(&s);
        let _ = Grid::parse(&[s.as_str(), "kd=1"]);
    }

    #[test]
    fn structured_grid_specs_never_panic(
        axis in "(kp|kd|push_force|max_torque|friction|timestep|leg_scale|torso_mass_scale|k|)",
        a in "-?[0-9]{0,4}(\\.[0-9]{0,3})?(e-?[0-9])?|nan|inf|",
        b in "-?[0-9]{0,4}|",
        n in "[0-9]{0,3}|x",
        log in "(:log|:lin|)",
        sep in "(:|,)",
    ) {
        let spec = format!("{axis}={a}{sep}{b}{sep}{n}{log}");
        if let Ok(v) = AxisValues::parse(&spec) {
            prop_assert!(!v.values.is_empty());
            prop_assert!(v.values.iter().all(|x| x.is_finite()));
        }
    }

    #[test]
    fn schedule_validation_never_panics(
        duration in proptest::num::f64::ANY,
        start in proptest::num::f64::ANY,
        len in proptest::num::f64::ANY,
        force in proptest::num::f64::ANY,
    ) {
        let mut s = Schedule { duration, ..Schedule::default() };
        if let Some(p) = s.push.as_mut() {
            p.start = start;
            p.duration = len;
            p.force[2] = force;
        }
        if s.validate().is_ok() {
            prop_assert!(s.duration > 0.0);
            // a valid schedule has a finite number of steps
            prop_assert!(s.plan(0.5).unwrap().steps as f64 >= s.duration / 0.5);
        }
    }
}
