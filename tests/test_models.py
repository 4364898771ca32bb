"""Our MJCF models, in the spirit of MuJoCo Menagerie's model tests: each
compiles, steps one second with no MuJoCo warning, and has the physics of the
reference Pupper v3 description it was written from."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
FILES = ROOT / "models" / "pupper_v3"
REFERENCE = ROOT.parent / "shared" / "reference" / "pupper_v3_description" / "mujoco_xml"
BUILTINS = ["pupper_v3", "pupper_v3_fixed"]

pc = pytest.importorskip("pupper_core")


def builtin(name: str) -> mujoco.MjModel:
    return pc._native.builtin_model(name)


def test_menagerie_layout() -> None:
    names = sorted(p.name for p in FILES.iterdir())
    assert names == ["LICENSE", "README.md", "pupper_v3.xml", "scene.xml"], names
    assert [p.name for p in (ROOT / "models").iterdir()] == ["pupper_v3"]
    assert '<include file="pupper_v3.xml"/>' in (FILES / "scene.xml").read_text()


def test_builtins_are_the_files() -> None:
    """pupper_v3 is scene.xml as MuJoCo loads it from disk; pupper_v3_fixed is
    the robot file with its base welded to the world."""
    scene = mujoco.MjModel.from_xml_path(str(FILES / "scene.xml"))
    robot = mujoco.MjModel.from_xml_path(str(FILES / "pupper_v3.xml"))
    ours, fixed = builtin("pupper_v3"), builtin("pupper_v3_fixed")
    for field in ("body_mass", "body_inertia", "body_pos", "geom_size", "geom_friction", "jnt_range",
                  "actuator_gainprm", "actuator_biasprm", "key_qpos", "opt.timestep"):
        get = lambda m: np.asarray(eval(f"m.{field}"))  # noqa: E731, S307 - field names above
        np.testing.assert_array_equal(get(ours), get(scene), err_msg=field)
    assert (scene.nq, fixed.nq, robot.nq) == (19, 12, 19)
    assert fixed.njnt == robot.njnt - 1 and fixed.ngeom == robot.ngeom
    assert not (fixed.jnt_type == mujoco.mjtJoint.mjJNT_FREE).any()
    np.testing.assert_array_equal(fixed.body_mass, robot.body_mass)
    np.testing.assert_array_equal(fixed.key_qpos[0], robot.key_qpos[0][7:])
    floor = mujoco.mj_name2id(scene, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    assert floor >= 0 and mujoco.mj_name2id(fixed, mujoco.mjtObj.mjOBJ_GEOM, "floor") == -1


@pytest.mark.parametrize("name", BUILTINS)
def test_compiles_and_steps_without_warnings(name: str) -> None:
    model = builtin(name)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_step(model, data, int(round(1.0 / model.opt.timestep)))
    counts = [int(w.number) for w in data.warning]
    assert counts == [0] * len(counts)
    assert np.isfinite(data.qpos).all()


@pytest.mark.parametrize("name", BUILTINS)
def test_no_meshes_and_massless_visuals(name: str) -> None:
    model = builtin(name)
    assert model.nmesh == 0
    visual = (model.geom_contype == 0) & (model.geom_conaffinity == 0)
    assert visual.sum() > 20, "the robot is drawn with primitives"
    assert model.nu == 12 and model.nbody == 14
    # removing every visual geom leaves every mass and inertia as it was
    spec = mujoco.MjSpec.from_file(str(FILES / "pupper_v3.xml"))
    drawn = [g for g in spec.geoms if g.contype == 0 and g.conaffinity == 0]
    assert len(drawn) == visual.sum()
    before = spec.compile()
    for g in drawn:
        spec.delete(g)
    after = spec.compile()
    assert after.ngeom == before.ngeom - len(drawn)
    np.testing.assert_array_equal(after.body_mass, before.body_mass)
    np.testing.assert_array_equal(after.body_inertia, before.body_inertia)
    np.testing.assert_array_equal(after.body_ipos, before.body_ipos)


def _pair(name: str, ref: str) -> tuple[mujoco.MjModel, mujoco.MjModel]:
    ref_path = REFERENCE / ref
    if not ref_path.exists():
        pytest.skip(f"reference description not found at {ref_path}")
    ours = builtin(name)
    theirs = mujoco.MjModel.from_xml_path(str(ref_path))
    # the reference's actuators are gain 1, bias 0; the chapter's are Kp 5, Kd 0.1
    theirs.actuator_gainprm[:, 0] = 5.0
    theirs.actuator_biasprm[:, 1] = -5.0
    theirs.actuator_biasprm[:, 2] = -0.1
    return ours, theirs


@pytest.mark.parametrize(
    "name,ref",
    [("pupper_v3", "pupper_v3_complete.xml"), ("pupper_v3_fixed", "pupper_v3_complete.fixed_base.xml")],
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
