"""The chapter's lab, piece by piece: named body variants measured on the
compiled model, a stand pose searched on each body, the best gains per group."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import read_csv

mujoco = pytest.importorskip("mujoco")
pc = pytest.importorskip("pupper_core")


def info(run, variant: str) -> dict:
    return json.loads(run("info", "--variant", variant, "--json", check=0).stdout)


def test_variants_are_measured_on_the_compiled_body(run):
    original, long_leg, heavy = (info(run, v) for v in ("original", "long-leg", "heavy"))
    assert len(original["legs"]) == 4
    for a, b in zip(original["legs"], long_leg["legs"]):
        assert b["hip_to_foot"] / a["hip_to_foot"] == pytest.approx(1.5, abs=0.03)
        # the knee and the foot really moved, the hip did not
        assert b["hip"] == pytest.approx(a["hip"], abs=1e-9)
        assert b["knee"] != pytest.approx(a["knee"], abs=1e-3)
    base = original["bodies"].index("base_link")
    m = pc._native.builtin_model("pupper_v3")
    assert heavy["total_mass"] == pytest.approx(original["total_mass"] + m.body_mass[base], rel=1e-12)
    # thighs and calves (two and three levels below the base) scale with the legs
    depth = {base: 0}
    for b in range(base + 1, m.nbody):
        depth[b] = depth.get(int(m.body_parentid[b]), -9) + 1
    scaled = sum(m.body_mass[b] for b, d in depth.items() if d >= 2)
    assert long_leg["total_mass"] == pytest.approx(original["total_mass"] + 0.5 * scaled, rel=1e-12)
    assert pc.info(variant="heavy")["total_mass"] == heavy["total_mass"]
    p = run("info", "--variant", "tall", check=2)
    assert "unknown variant 'tall'" in p.stderr and "long-leg" in p.stderr


def test_the_original_stand_pose_puts_every_foot_at_the_target(run):
    pose = json.loads(run("pose", "--json", check=0).stdout)
    legs = info(run, "original")["legs"]
    m = pc._native.builtin_model("pupper_v3")
    d = mujoco.MjData(m)
    d.qpos[2] = pose["base_z"]
    d.qpos[3] = 1.0
    for a in range(m.nu):
        d.qpos[m.jnt_qposadr[m.actuator_trnid[a, 0]]] = pose["targets"][a]
    mujoco.mj_kinematics(m, d)
    lowest = np.inf
    for leg in legs:
        haa, hfe, kfe = leg["joints"]
        body = int(m.jnt_bodyid[kfe])
        foot = [g for g in range(m.ngeom) if m.geom_bodyid[g] == body and m.geom_contype[g] | m.geom_conaffinity[g]]
        z = d.geom_xpos[foot[0], 2] - d.xanchor[hfe, 2]
        assert abs(z - pose["target_z"]) < 0.005, (leg["name"], z)
        lowest = min(lowest, d.geom_xpos[foot[0], 2] - m.geom_size[foot[0], 0])
        assert pose["targets"][list(m.actuator_trnid[:, 0]).index(haa)] == 0.0
    assert 0.0 < lowest < 0.005  # just above the floor
    # left legs mirror right legs: opposite hip and knee angles
    t = pose["targets"]
    assert t[0:3] == [-x for x in t[3:6]] and t[6:9] == [-x for x in t[9:12]]


def test_auto_pose_makes_every_body_stand(run, tmp_path):
    run("sweep", "--pose", "auto", "--grid", "leg_scale=1,1.5", "--grid", "torso_mass_scale=1,2",
        "--mode", "torque", "--sine", "2,1.2", "--no-push", "--seconds", "4", "--kp", "60", "--kd", "1",
        "-o", tmp_path / "run", "-q", check=0)
    _, rows = read_csv(tmp_path / "run" / "summary.csv")
    assert len(rows) == 4
    for r in rows:
        assert r["status"] == "ok" and float(r["last_1s_std_mm"]) < 5.0, r
    # each body its own pose: the long legs stand taller
    z = {(r["leg_scale"], r["torso_mass_scale"]): float(r["final_z"]) for r in rows}
    assert z[("1.5", "1")] > z[("1", "1")] + 0.04
    rep = pc.stand(variant="long-leg", pose="auto", mode="torque", kp=60, kd=1, seconds=3)
    assert rep["status"] == "ok" and rep["final_z"] == pytest.approx(z[("1.5", "1")], abs=0.01)
