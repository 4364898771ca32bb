//! The commands about one model or body: info, pose, stand, view; and
//! doctor, which says what pupper found to run them.

use clap::Args;
use pupper_core::request::spec::SweepSpec;
use pupper_core::robot::model::ModelSource;
use pupper_core::{Error, Result};
use pupper_mujoco::api;
use pupper_mujoco::bridge;

use super::args::{ModelArg, SimArgs};
use crate::print;
use pupper_mujoco::bridge::calls;

/// A model, one of its bodies, and how to print what is found.
#[derive(Args, Debug)]
pub(super) struct BodyArgs {
    #[command(flatten)]
    model: ModelArg,
    /// A named body: original, long-leg (legs 1.5x), heavy (torso mass 2x).
    #[arg(long, default_value_t = SweepSpec::default().variant, value_name = "NAME")]
    variant: String,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Args, Debug)]
pub(super) struct PoseArgs {
    #[command(flatten)]
    body: BodyArgs,
    /// Aim the feet this far below the hips (m) instead of the chapter's 0.14 m scaled to the
    /// model's legs.
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    depth: Option<f64>,
}

impl BodyArgs {
    /// Runs `find` on the body and prints its answer as text or JSON.
    fn show<T: serde::Serialize>(
        &self,
        find: impl FnOnce(&ModelSource, &pupper_core::robot::variant::Variant) -> Result<T>,
        text: impl FnOnce(&T) -> String,
    ) -> Result<()> {
        let found = find(
            &self.model.source()?,
            pupper_core::robot::variant::variant(&self.variant)?,
        )?;
        if self.json {
            outln!("{}", print::json(&found)?);
        } else {
            outp!("{}", text(&found));
        }
        Ok(())
    }
}

#[derive(Args, Debug)]
pub(super) struct StandArgs {
    #[command(flatten)]
    sim: SimArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// `pupper info`.
pub(super) fn info(a: &BodyArgs) -> Result<u8> {
    a.show(api::info, print::info)?;
    Ok(0)
}

/// `pupper pose`.
pub(super) fn pose(a: &PoseArgs) -> Result<u8> {
    a.body.show(|m, v| api::pose(m, v, a.depth), print::pose)?;
    Ok(0)
}

/// `pupper stand`.
pub(super) fn stand(a: &StandArgs) -> Result<u8> {
    let r = api::stand(&a.sim.spec()?)?;
    for n in &r.notes {
        errln!("note: {n}");
    }
    if a.json {
        outln!("{}", print::json(&r)?);
    } else {
        outp!("{}", print::stand(&r));
    }
    Ok(0)
}

/// `pupper doctor`.
pub(super) fn doctor(json: bool) -> Result<u8> {
    let r = bridge::doctor()?;
    if json {
        outln!("{}", print::json(&r)?);
    } else {
        outp!("{}", print::doctor(&r));
    }
    if let Some(p) = r.problem {
        return Err(Error::Mujoco(p));
    }
    Ok(0)
}

/// `pupper view`.
pub(super) fn view(model: &ModelArg) -> Result<u8> {
    let source = model.source()?;
    if std::env::var_os("DISPLAY").is_none() && std::env::var_os("WAYLAND_DISPLAY").is_none() {
        return Err(Error::Display(
            "no display found (DISPLAY and WAYLAND_DISPLAY are unset): run pupper view in a desktop session, or use `pupper render` for a PNG".into(),
        ));
    }
    let name = match &source {
        ModelSource::Path(p) => p.display().to_string(),
        ModelSource::Builtin(n) => n.clone(),
    };
    bridge::call_helper(&calls::VIEW, &[name], &serde_json::json!({}))?;
    Ok(0)
}
