"""Fidelity (issue 23): the stand pose by the chapter's rule on the real
geometry, and a robot that is not Pupper treated as its own robot.

Positions are measured here with MuJoCo's own forward kinematics on the
compiled bodies, never with pupper's search: pupper only says which angles
and base height it chose.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

import pupper_core as pc
from pupper_core import render

MODELS = Path(__file__).resolve().parent / "models"
#: A 15 kg quadruped written for these tests: other names, actuators ordered
#: abductions / hips / knees (not joint order), kp 50 kv 0.5 +-24 N.m of its
#: own, `home` standing at 0.27 m, collision geoms in hidden group 3 only.
TROTTER = MODELS / "trotter15.xml"
#: The chapter's stand depth of the feet below the hips on Pupper v3 (m).
CHAPTER_DEPTH = 0.14
#: Every foot within 1 mm of the depth and 2 mm of under its hip along x.
DEPTH_TOLERANCE = 1e-3
X_TOLERANCE = 2e-3


def _body(variant: str) -> mujoco.MjModel:
    """The compiled body of a Pupper v3 variant (what the runner ran on)."""
    rec = render.record({"variant": [variant]}, seconds=0.004, fps=250.0)
    return rec[0]["model"]


def _posed(model: mujoco.MjModel, pose: dict) -> mujoco.MjData:
    """`model` at pupper's chosen pose: joint targets by each actuator's
    joint, base at the chosen height; forward kinematics by MuJoCo."""
    d = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, d, 0)
    for a, q in enumerate(pose["targets"]):
        j = model.actuator_trnid[a, 0]
        d.qpos[model.jnt_qposadr[j]] = q
    d.qpos[2] = pose["base_z"]
    mujoco.mj_kinematics(model, d)
    return d


def _feet_from_hips(model: mujoco.MjModel, d: mujoco.MjData,
                    legs: list[tuple[str, str]]) -> list[tuple[float, float]]:
    """(depth below the hip pitch axis, x from it) of each (hip joint, foot geom or site)."""
    out = []
    for hip, foot in legs:
        h = d.xanchor[model.joint(hip).id]
        try:
            f = d.site_xpos[model.site(foot).id]
        except KeyError:
            f = d.geom_xpos[model.geom(foot).id]
        out.append((float(h[2] - f[2]), float(f[0] - h[0])))
    return out


def _pose(run, *args: str) -> dict:
    return json.loads(run("pose", "--json", *args, check=0).stdout)


# On Pupper v3 the `_1` joints pitch the hip (their axis is the body's y)
# and the foot is the `_3` body's site.
PUPPER_LEGS = [(f"leg_{leg}_1", f"leg_{leg}_3_foot_site")
               for leg in ("front_r", "front_l", "back_r", "back_l")]


@pytest.mark.parametrize("variant,leg_scale", [("original", 1.0), ("long-leg", 1.5), ("heavy", 1.0)])
def test_every_foot_lands_on_the_chapters_target(run, variant: str, leg_scale: float) -> None:
    pose = _pose(run, "--variant", variant)
    model = _body(variant)
    target = CHAPTER_DEPTH * min(max(leg_scale, 1.0), 1.5)
    assert abs(-pose["target_z"] - target) < 1e-9, pose
    d = _posed(model, pose)
    for depth, x in _feet_from_hips(model, d, PUPPER_LEGS):
        assert abs(depth - target) < DEPTH_TOLERANCE, (variant, depth, target)
        assert abs(x) < X_TOLERANCE, (variant, x)
    # the lowest foot is just above the floor (2 mm), the others no lower
    bottoms = [d.geom_xpos[g, 2] - model.geom_size[g, 0]
               for g in range(model.ngeom)
               if model.geom_bodyid[g] != 0 and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
               and (model.geom_contype[g] or model.geom_conaffinity[g])]
    assert len(bottoms) == 4 and abs(min(bottoms) - 0.002) < 1e-6, bottoms


def test_the_preferred_bend_is_a_thigh_angle_not_a_joint_value(run) -> None:
    """Pupper's hip joint zero is already a crouch: the chapter's 0.70 rad
    preference is measured from the downward vertical, so the pose's hip
    joint value differs from its thigh angle by the zero's own tilt."""
    pose = _pose(run)
    model = _body("original")
    d = _posed(model, pose)
    hip = d.xanchor[model.joint("leg_front_r_1").id]
    knee = d.xanchor[model.joint("leg_front_r_3").id]
    thigh = knee - hip
    from_vertical = math.atan2(abs(thigh[0]), -thigh[2])
    assert abs(from_vertical - abs(pose["thigh_angle"])) < 1e-6
    assert abs(pose["hfe"] - pose["thigh_angle"]) > 0.2, pose


def test_a_given_depth_is_where_the_feet_go(run) -> None:
    pose = _pose(run, "--depth", "0.12")
    assert pose["depth_from"] == "given" and pose["target_z"] == -0.12
    d = _posed(_body("original"), pose)
    for depth, x in _feet_from_hips(_body("original"), d, PUPPER_LEGS):
        assert abs(depth - 0.12) < DEPTH_TOLERANCE and abs(x) < X_TOLERANCE, (depth, x)
    bad = run("pose", "--depth", "-1")
    assert bad.returncode == 2 and "--depth" in bad.stderr, bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1
    off = run("sweep", "--depth", "0.1", "--seconds", "0.1")
    assert off.returncode == 2 and "--pose auto" in off.stderr, off.stderr


# ---------------------------------------------------------------------------
# A robot that is not ours

TROTTER_LEGS = [(f"{leg}_hip_pitch", f"{leg}_foot") for leg in ("fl", "fr", "rl", "rr")]


def test_a_model_runs_at_its_own_gains_by_default(run) -> None:
    rep = json.loads(run("stand", "--model", TROTTER, "--json", "--seconds", "3", check=0).stdout)
    assert (rep["kp"], rep["kd"], rep["gains_from"]) == (50.0, 0.5, "model"), rep
    assert rep["status"] == "ok" and rep["final_z"] > 0.2, rep
    text = run("stand", "--model", TROTTER, "--seconds", "0.5", check=0).stdout
    assert "kp 50 kd 0.5" in text, text
    given = json.loads(run("stand", "--model", TROTTER, "--json", "--seconds", "0.5",
                           "--kp", "80", "--kd", "1", check=0).stdout)
    assert (given["kp"], given["kd"], given["gains_from"]) == (80.0, 1.0, "given")
    # Pupper's own actuators say 5 / 0.1: what it always ran at
    assert "kp 5 kd 0.1" in run("stand", "--seconds", "0.2", check=0).stdout


def test_a_collapsed_cell_is_fell_and_never_the_steadiest(tmp_path: Path) -> None:
    res = pc.sweep({"kp": [10, 60]}, model=str(TROTTER), seconds=3.0, push=False,
                   out=tmp_path / "run", progress=False)
    rows = {int(r["kp"]): r for r in (res.row(i) for i in range(len(res)))}
    # Kp 10 on 15 kg: the legs fold, the base sinks to about half its
    # stance height and stays there, perfectly still
    assert rows[10]["status"] == "fell", rows[10]
    assert rows[10]["final_z"] < 0.6 * 0.27
    assert rows[60]["status"] == "ok", rows[60]
    best = res.best()
    assert int(best["kp"]) == 60, best


def test_the_pose_aims_at_the_depth_scaled_to_its_legs(run) -> None:
    pose = _pose(run, "--model", TROTTER)
    legs = 0.21 + 0.21
    assert abs(pose["leg_length"] - legs) < 1e-9, pose
    target = CHAPTER_DEPTH * legs / 0.17429019530912043
    assert pose["depth_from"] == "scaled" and abs(-pose["target_z"] - target) < 1e-9
    model = mujoco.MjModel.from_xml_path(str(TROTTER))
    d = _posed(model, pose)
    for depth, x in _feet_from_hips(model, d, TROTTER_LEGS):
        assert abs(depth - target) < DEPTH_TOLERANCE and abs(x) < X_TOLERANCE, (depth, x, target)
    text = run("pose", "--model", TROTTER, check=0).stdout
    assert f"feet {target:.4f} m below the hips" in text and "scaled to legs of 0.420 m" in text, text
    # the knee is not at its range limit (-2.7, -0.8)
    kfe = pose["kfe"]
    assert -2.7 + 0.05 < kfe < -0.8 - 0.05, pose


def test_a_heavier_torso_is_heavier_when_its_mass_comes_from_geoms(run) -> None:
    def mass(*args: str) -> float:
        return json.loads(run("info", "--model", TROTTER, "--json", *args, check=0).stdout)["total_mass"]

    # the trunk's box is 11.2 kg of its 15.2 (no <inertial>: MuJoCo derives it)
    assert abs(mass("--variant", "heavy") - (mass() + 11.2)) < 1e-9
    a = json.loads(run("stand", "--model", TROTTER, "--json", "--seconds", "1", check=0).stdout)
    b = json.loads(run("stand", "--model", TROTTER, "--json", "--seconds", "1",
                       "--variant", "heavy", check=0).stdout)
    assert b["final_z"] < a["final_z"] - 1e-3, (a, b)


def test_targets_outside_the_joint_ranges_get_one_warning(run, tmp_path: Path) -> None:
    text = TROTTER.read_text()
    # the knees at 0: outside their range [-2.7, -0.8]
    home = text.split('<key name="home" qpos="', 1)[1].split('"', 1)[0].split()
    ctrl = text.split('ctrl="', 1)[1].split('"', 1)[0].split()
    for i in range(8, 12):
        ctrl[i] = "0"
    bent = text.replace(" ".join(text.split('ctrl="', 1)[1].split('"', 1)[0].split()), " ".join(ctrl))
    assert home and bent != text
    model = tmp_path / "straight_knees.xml"
    model.write_text(bent)
    proc = run("stand", "--model", model, "--seconds", "0.2", check=0)
    warned = [ln for ln in proc.stderr.splitlines() if "outside their joint's range" in ln]
    assert len(warned) == 1 and "4 joint target(s)" in warned[0] and "fl_knee" in warned[0], proc.stderr
    quiet = run("stand", "--model", TROTTER, "--seconds", "0.2", check=0)
    assert "outside" not in quiet.stderr


def test_a_model_without_visual_geoms_is_drawn_from_its_collision_geoms() -> None:
    reason = render.gl_available()
    if reason is not None:
        pytest.skip(f"no OpenGL context for offscreen rendering: {reason}")
    model = mujoco.MjModel.from_xml_path(str(TROTTER))
    d = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d, 0)
    mujoco.mj_forward(model, d)
    shown = render.frame(model, d, camera=None, width=160, height=120)
    with mujoco.Renderer(model, height=120, width=160) as r:
        r.update_scene(d)  # MuJoCo's defaults: group 3 hidden
        plain = r.render().copy()
    changed = np.any(np.abs(shown.astype(int) - plain.astype(int)) > 30, axis=2).mean()
    assert changed > 0.02, f"the robot covers {changed:.1%} of the picture"
    # Pupper has visual geoms: drawn as MuJoCo draws it
    pupper = pc.render.builtin_model_path("pupper_v3")
    assert pupper is not None
    opt = render.scene_option(mujoco.MjModel.from_xml_path(str(pupper)))
    assert list(opt.geomgroup) == list(mujoco.MjvOption().geomgroup)


def test_a_run_too_short_to_measure_is_never_ranked(run, tmp_path: Path) -> None:
    """--seconds 0.5: the last second holds the landing, the push never
    comes; the metrics it cannot have are empty, a note says why, and no
    cell is called steadiest (it was, with the drop inside its last second)."""
    p = run("sweep", "--grid", "kp=10,30", "--seconds", "0.5", "-o", tmp_path / "run", check=0)
    assert "steadiest" not in p.stdout, p.stdout
    notes = [ln for ln in p.stderr.splitlines() if ln.startswith("note:")]
    assert any("last_1s_std_mm is left empty" in n for n in notes), p.stderr
    assert any("push_dip_mm and settle_time_s are left empty" in n for n in notes), p.stderr
    import csv

    with open(tmp_path / "run" / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert all(r["last_1s_std_mm"] == "" and r["push_dip_mm"] == "" for r in rows), rows
    best = run("sweep", "--grid", "kp=10,30", "--seconds", "0.5", "--best-by", "kp", "-q",
               "-o", tmp_path / "ranked", check=0)
    with open(tmp_path / "ranked" / "best.csv", newline="") as f:
        assert all(r["id"] == "" for r in csv.DictReader(f)), "no cell ranked"
    assert best.returncode == 0
