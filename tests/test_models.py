"""Our MJCF models, in the spirit of MuJoCo Menagerie's model tests: each
compiles, steps one second with no MuJoCo warning, and has the physics of the
reference Pupper v3 description it was written from."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
MODELS = sorted((ROOT / "models").glob("*.xml"))
REFERENCE = ROOT.parent / "shared" / "reference" / "pupper_v3_description" / "mujoco_xml"


def test_there_are_two_models() -> None:
    assert [p.name for p in MODELS] == ["pupper_v3.xml", "pupper_v3_fixed.xml"]


@pytest.mark.parametrize("path", MODELS, ids=lambda p: p.stem)
def test_compiles_and_steps_without_warnings(path: Path) -> None:
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_step(model, data, int(round(1.0 / model.opt.timestep)))
    counts = [int(w.number) for w in data.warning]
    assert counts == [0] * len(counts)
    assert np.isfinite(data.qpos).all()


@pytest.mark.parametrize("path", MODELS, ids=lambda p: p.stem)
def test_no_meshes_and_massless_visuals(path: Path) -> None:
    model = mujoco.MjModel.from_xml_path(str(path))
    assert model.nmesh == 0
    visual = (model.geom_contype == 0) & (model.geom_conaffinity == 0)
    assert visual.sum() > 20, "the robot is drawn with primitives"
    assert model.nu == 12 and model.nbody == 14


def _pair(name: str, ref: str) -> tuple[mujoco.MjModel, mujoco.MjModel]:
    ref_path = REFERENCE / ref
    if not ref_path.exists():
        pytest.skip(f"reference description not found at {ref_path}")
    ours = mujoco.MjModel.from_xml_path(str(ROOT / "models" / name))
    theirs = mujoco.MjModel.from_xml_path(str(ref_path))
    # the reference's actuators are gain 1, bias 0; the chapter's are Kp 5, Kd 0.1
    theirs.actuator_gainprm[:, 0] = 5.0
    theirs.actuator_biasprm[:, 1] = -5.0
    theirs.actuator_biasprm[:, 2] = -0.1
    return ours, theirs


@pytest.mark.parametrize(
    "name,ref",
    [("pupper_v3.xml", "pupper_v3_complete.xml"), ("pupper_v3_fixed.xml", "pupper_v3_complete.fixed_base.xml")],
)
def test_physics_matches_the_reference(name: str, ref: str) -> None:
    ours, theirs = _pair(name, ref)
    for field in (
        "body_mass", "body_inertia", "body_ipos", "body_iquat", "body_pos", "body_quat",
        "jnt_range", "jnt_qposadr", "dof_armature", "dof_damping", "dof_frictionloss",
        "actuator_gainprm", "actuator_biasprm", "actuator_forcerange", "key_qpos",
    ):
        np.testing.assert_array_equal(getattr(ours, field), getattr(theirs, field), err_msg=field)
    cols = lambda m: (m.geom_contype | m.geom_conaffinity) != 0  # noqa: E731
    for field in ("geom_size", "geom_pos", "geom_quat", "geom_friction", "geom_type"):
        np.testing.assert_array_equal(
            getattr(ours, field)[cols(ours)], getattr(theirs, field)[cols(theirs)], err_msg=field
        )
    # and the same motion, step for step
    d1, d2 = mujoco.MjData(ours), mujoco.MjData(theirs)
    mujoco.mj_resetDataKeyframe(ours, d1, 0)
    mujoco.mj_resetDataKeyframe(theirs, d2, 0)
    mujoco.mj_step(ours, d1, 2000)
    mujoco.mj_step(theirs, d2, 2000)
    np.testing.assert_allclose(d1.qpos, d2.qpos, rtol=0, atol=1e-12)
