//! What a run's simulations do: the experiment kinds, as one type. Each
//! kind is a module per layer (the response's plan is `plan::response`,
//! its probe `sim::response`, its tables `results::kinds::response`), and
//! each layer dispatches on [`Experiment`] in one place, its registry: a
//! new kind is a variant here and a module per layer.

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::plan::hold::Load;
use crate::plan::kind::{KindPlan, OnModel};
use crate::plan::response::Excitation;
use crate::plan::schedule::Schedule;
use crate::plan::stand::Stand;

/// The kinds besides the stand, a row each: the variant, the plan it
/// holds and the key a manifest's config writes it under. It makes
/// [`Experiment`], the manifest's record of it (the stand kind absent,
/// every other under its own key, so earlier runs' manifests read and
/// resume as they were written) and the registry of plans.
macro_rules! kinds {
    ($($(#[$doc:meta])* $v:ident($plan:ty) = $key:ident;)*) => {
        /// The experiment of a run (the manifest's config keeps it).
        #[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
        #[serde(from = "Record", into = "Record")]
        pub enum Experiment {
            /// The robot stands, is pushed (or shaken) and recovers: `pupper
            /// sweep` and the lab.
            #[default]
            Stand,
            $($(#[$doc])* $v($plan),)*
        }

        #[derive(Default, Serialize, Deserialize)]
        struct Record {
            $(#[serde(default, skip_serializing_if = "Option::is_none")]
            $key: Option<$plan>,)*
        }

        impl From<Record> for Experiment {
            fn from(r: Record) -> Experiment {
                // the first kind's key wins, should a record hold two
                $(if let Some(x) = r.$key {
                    return Experiment::$v(x);
                })*
                Experiment::Stand
            }
        }

        impl From<Experiment> for Record {
            fn from(e: Experiment) -> Record {
                match e {
                    Experiment::Stand => Record::default(),
                    $(Experiment::$v(x) => Record {
                        $key: Some(x),
                        ..Record::default()
                    },)*
                }
            }
        }

        impl Experiment {
            /// The kinds besides the stand, by the key a manifest writes
            /// each under (`pupper KEY` is its command), in the registry's
            /// order: what the other layers' registries are checked against.
            pub const KINDS: &'static [&'static str] = &[$(stringify!($key)),*];

            /// The registry: the kind's plan.
            pub fn plan(&self) -> &dyn KindPlan {
                match self {
                    Experiment::Stand => &Stand,
                    $(Experiment::$v(x) => x,)*
                }
            }

            /// The kind's plan, to resolve (None: the stand kind, which
            /// holds nothing).
            fn plan_mut(&mut self) -> Option<&mut dyn KindPlan> {
                match self {
                    Experiment::Stand => None,
                    $(Experiment::$v(x) => Some(x),)*
                }
            }
        }
    };
}

kinds! {
    /// Each joint excited alone, its target stepped, swept in a sine or a
    /// chirp: `pupper response`.
    Response(Excitation) = response;
    /// The robot stands under a load ramped onto its base, then is shoved
    /// sideways: `pupper hold`.
    Hold(Load) = hold;
    /// The robot walks a gait, open loop at the kinematic level: `pupper walk`.
    Walk(crate::plan::walk::Walk) = walk;
}

impl Experiment {
    /// What a kind takes from the compiled model before it runs (a hold's
    /// weight, groups and windings; the default push's force, scaled to the
    /// model's mass). A response's joints need the model's data too and
    /// are resolved beside it, in the adapter.
    pub fn resolve(&mut self, m: &OnModel<'_>, schedule: &mut Schedule) -> Result<()> {
        match self.plan_mut() {
            Some(p) => p.resolve(m, schedule),
            None => Stand.resolve(m, schedule),
        }
    }

    pub fn name(&self) -> &'static str {
        self.plan().name()
    }

    /// Simulations per replicate of a cell.
    pub fn sims_per_replicate(&self) -> usize {
        self.plan().excited().len().max(1)
    }

    /// The response's excitation, for the layers that finish its figures.
    pub fn excitation(&self) -> Option<&Excitation> {
        match self {
            Experiment::Response(e) => Some(e),
            _ => None,
        }
    }

    /// The excitation, to resolve on a compiled model.
    pub fn excitation_mut(&mut self) -> Option<&mut Excitation> {
        match self {
            Experiment::Response(e) => Some(e),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::response::Signal;

    fn step() -> Excitation {
        Excitation {
            signal: Signal::Step { amplitude: 0.2 },
            hold: 0.5,
            select: vec![],
            standing: false,
            joints: vec![2, 5],
            names: vec![],
            groups: vec![],
            inertia: vec![],
        }
    }

    #[test]
    fn a_stand_run_writes_no_key_and_a_response_its_own() {
        let stand = serde_json::to_string(&Experiment::Stand).unwrap();
        assert_eq!(stand, "{}");
        let resp = serde_json::to_value(Experiment::Response(step())).unwrap();
        assert_eq!(resp["response"]["hold"], 0.5);
        let back: Experiment = serde_json::from_value(resp).unwrap();
        assert_eq!(back, Experiment::Response(step()));
        let old: Experiment = serde_json::from_str("{}").unwrap();
        assert_eq!(old, Experiment::Stand);
    }

    #[test]
    fn the_registry_names_its_kinds_by_their_keys() {
        assert_eq!(Experiment::KINDS, ["response", "hold", "walk"]);
        for (kind, key) in [
            (Experiment::Response(step()), "response"),
            (Experiment::Hold(Load::new(1.0, 1.0, 2.0, 0.25)), "hold"),
        ] {
            let v = serde_json::to_value(kind).unwrap();
            assert!(v.get(key).is_some(), "{v}");
        }
    }

    #[test]
    fn each_kind_answers_for_itself() {
        let r = Experiment::Response(step());
        assert_eq!((r.name(), r.sims_per_replicate()), ("response", 2));
        let p = r.plan();
        assert_eq!(p.excited(), vec![Some(2), Some(5)]);
        assert!(!p.pushes() && p.suspended() && p.moving_targets());
        let s = Experiment::Stand;
        assert_eq!((s.name(), s.sims_per_replicate()), ("sweep", 1));
        let p = s.plan();
        assert!(p.pushes() && !p.suspended() && !p.moving_targets());
        assert_eq!(p.target_offset(3.0, 4.0), 0.0);
    }
}
