//! The stand kind's plan: nothing excited, the schedule's push acts; every
//! [`KindPlan`] default is the stand kind's.

use crate::plan::kind::KindPlan;

/// The stand kind: nothing excited, the schedule's push acts.
pub struct Stand;

impl KindPlan for Stand {
    fn name(&self) -> &'static str {
        "sweep"
    }
}
