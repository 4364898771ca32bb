//! Where a run's cells start, checked on the compiled model, and what a
//! kind takes from the model before it runs.

use crate::bridge;
use pupper_core::error::{Error, Result};
use pupper_core::plan::config::SweepConfig;
use pupper_core::plan::kind::OnModel;
use pupper_core::plan::schedule::InitialState;
use pupper_core::robot::model::ModelInfo;

/// The checks of where cells start that need the model; notes when the
/// start is a fallback (no `home` keyframe) or asks a joint to go past its
/// range.
pub(super) fn check_start(
    info: &ModelInfo,
    initial: &InitialState,
    standing: bool,
) -> Result<Vec<String>> {
    let (targets, notes) = start_targets(info, initial)?;
    let mut notes = notes;
    if standing {
        notes.extend(info.ground_note());
    }
    // the stand-pose search keeps inside the ranges
    if !matches!(initial, InitialState::Auto | InitialState::AutoDepth(_))
        && let Some(t) = targets
    {
        notes.extend(info.targets_outside_ranges(&t));
    }
    Ok(notes)
}

/// The joint targets cells start from on the nominal body (None where the
/// model gives none), and what the user should know about them. A body
/// pupper cannot pose is refused here, before anything is written.
pub(super) fn start_targets(
    info: &ModelInfo,
    initial: &InitialState,
) -> Result<(Option<Vec<f64>>, Vec<String>)> {
    let mut notes = Vec::new();
    let targets = match initial {
        InitialState::Pose(p) => {
            info.check_pose(p)?;
            Some(p.clone())
        }
        InitialState::Keyframe(k) => {
            let (key, note) = info.start_keyframe(k)?;
            notes.extend(note);
            let layout = pupper_core::robot::layout::Layout::floating(info)
                .or_else(|_| pupper_core::robot::layout::Layout::suspended(info))
                .ok();
            match (key, layout) {
                (Some(k), _) if info.keyframes[k].ctrl.len() == info.nu => {
                    Some(info.keyframes[k].ctrl.clone())
                }
                (Some(k), Some(l)) => Some(l.joint_targets(&info.keyframes[k].qpos)),
                (None, Some(l)) => Some(l.joint_targets(&info.qpos0)),
                _ => None,
            }
        }
        InitialState::Auto | InitialState::AutoDepth(_) => Some(
            pupper_core::robot::pose::stand_pose(info, 1.0, initial.auto_depth().flatten())?
                .targets,
        ),
    };
    Ok((targets, notes))
}

/// Each actuated joint's reflected inertia at the cells' start pose on
/// the nominal body (None where the model gives no start targets).
pub(super) fn start_inertia(
    model: &bridge::LoadedModel<'_>,
    initial: &InitialState,
) -> Result<Option<Vec<f64>>> {
    match start_qpos(model, initial)? {
        Some(q) => Ok(Some(model.joint_inertia(&q)?)),
        None => Ok(None),
    }
}

/// The qpos of the cells' start pose on the nominal body: the keyframe (or
/// the model's default) with the start targets in the joints.
pub(super) fn start_qpos(
    model: &bridge::LoadedModel<'_>,
    initial: &InitialState,
) -> Result<Option<Vec<f64>>> {
    let info = model.info();
    let Some(layout) = model.layout() else {
        return Ok(None);
    };
    let (Some(targets), _) = start_targets(info, initial)? else {
        return Ok(None);
    };
    let mut q = match initial {
        InitialState::Keyframe(k) => match info.start_keyframe(k)?.0 {
            Some(key) => info.keyframes[key].qpos.clone(),
            None => info.qpos0.clone(),
        },
        _ => info.qpos0.clone(),
    };
    for (a, &t) in targets.iter().enumerate() {
        q[layout.act_qpos[a]] = t;
    }
    Ok(Some(q))
}

/// `cfg` with what its kind takes from the model resolved on `info` (a
/// hold's weight; a response run's excited joints, its signal checked
/// against every timestep of its grid).
pub(super) fn resolved(cfg: &SweepConfig, model: &bridge::LoadedModel<'_>) -> Result<SweepConfig> {
    let info = model.info();
    let mut c = cfg.clone();
    let start = || Ok(start_targets(info, &cfg.schedule.initial)?.0);
    let on = OnModel {
        info,
        grid: &cfg.grid,
        start: &start,
    };
    c.experiment.resolve(&on, &mut c.schedule)?;
    if let Some(e) = c.experiment.excitation_mut() {
        if e.joints.is_empty() {
            e.resolve(info)?;
            if let Some(all) = start_inertia(model, &cfg.schedule.initial)? {
                e.inertia = e.joints.iter().map(|&a| all[a]).collect();
            }
        }
        if let (Some(t), _) = start_targets(info, &cfg.schedule.initial)? {
            e.check_ranges(info, &t)?;
        }
        let mut seen: Vec<u64> = Vec::new();
        for cell in cfg.grid.cells() {
            let setup = cfg.setup(&cell, info);
            // without a spring the joint never follows: every figure would be
            // a 100 % error printed as `ok`
            if let Some(&a) = e.joints.iter().find(|&&a| setup.kp(a) <= 0.0) {
                return Err(Error::Config(format!(
                    "cell {} gives {} kp 0: a joint without a servo spring does not follow its target, so there is no response to measure; give kp > 0 (--kp or a kp grid starting above 0)",
                    cell.id, info.actuators[a].name
                )));
            }
            let dt = setup.timestep.unwrap_or(info.timestep);
            if !seen.contains(&dt.to_bits()) {
                seen.push(dt.to_bits());
                e.validate(cfg.schedule.duration, dt)?;
            }
        }
    }
    Ok(c)
}
