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


@pytest.fixture(scope="module")
def lab_run(pupper_bin, tmp_path_factory):
    import subprocess

    from conftest import clean_env

    d = tmp_path_factory.mktemp("lab")
    p = subprocess.run([str(pupper_bin), "lab", "-o", str(d / "run"), "-q"], cwd=d,
                       env=clean_env(MUJOCO_GL="egl"), capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    return d / "run", p


def test_lab_prints_a_line_per_body_and_writes_its_artifacts(lab_run):
    out, p = lab_run
    lines = p.stdout.strip().splitlines()
    assert [ln.split()[0] for ln in lines] == ["original", "long-leg", "heavy"], p.stdout
    for ln in lines:
        std = float(ln.split("z_std=")[1].split()[0])
        assert std < 0.1, ln
        assert "Kp=" in ln and "Kd=" in ln and " z=" in ln
    _, rows = read_csv(out / "summary.csv")
    assert len(rows) == 48 and {r["variant"] for r in rows} == {"original", "long-leg", "heavy"}
    best = read_csv(out / "best.csv")[1]
    assert [b["variant"] for b in best] == ["original", "long-leg", "heavy"]
    plots = {f.name for f in (out / "plots").iterdir()}
    assert {"lab_heatmaps.png", "lab_best_base_z.png"} <= plots, plots
    from PIL import Image

    for name in ("lab_heatmaps.png", "lab_best_base_z.png"):
        with Image.open(out / "plots" / name) as im:
            assert im.width > 600 and np.asarray(im.convert("L")).std() > 5
    # all bodies in one batch run
    m = json.loads((out / "manifest.json").read_text())
    assert m["batches"] == 1 and m["complete"] is True


def test_lab_renders_the_bodies_at_their_best_gains(lab_run):
    if pc.render.gl_available() is not None:
        pytest.skip("no OpenGL here")
    out, _ = lab_run
    frames = read_csv(out / "plots" / "lab_best.csv")[1]
    best = read_csv(out / "best.csv")[1]
    assert sorted({f["id"] for f in frames}) == sorted(b["id"] for b in best)
    assert (out / "plots" / "lab_best.png").exists()


def test_stiffer_gains_beat_a_soft_cell(run, tmp_path):
    run("lab", "--variants", "original", "--grid", "kp=5,10,30,60,120", "--grid", "kd=0.5,1,2,5",
        "-o", tmp_path / "run", "-q", check=0)
    res = pc.load_run(tmp_path / "run")
    best = res.best("last_1s_std_mm", by=["variant"])[0]
    assert best["kp"] >= 30, best
    soft = [i for i in range(len(res)) if res["kp"][i] == 5 and res["kd"][i] == 1][0]
    assert not (res["last_1s_std_mm"][soft] <= best["last_1s_std_mm"]), (res.row(soft), best)


def test_lab_bad_input_is_one_line_and_no_directory(run, tmp_path):
    p = run("lab", "--variants", "original,tall", "-o", tmp_path / "x", check=2)
    assert p.stderr.count("\n") == 1 and "'tall'" in p.stderr
    assert not (tmp_path / "x").exists()


def test_lab_ctrl_c_then_resume_equals_one_run(pupper_bin, lab_run, tmp_path):
    import signal
    import subprocess
    import time

    from conftest import clean_env

    out = tmp_path / "run"
    proc = subprocess.Popen([str(pupper_bin), "lab", "-j", "1", "-o", str(out), "-q"], cwd=tmp_path,
                            env=clean_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not (out / "manifest.json").exists():
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    so, se = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "pupper lab --resume" in se, se
    p = subprocess.run([str(pupper_bin), "lab", "--resume", str(out), "-q"], cwd=tmp_path,
                       env=clean_env(MUJOCO_GL="egl"), capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert p.stdout == lab_run[1].stdout
    assert (out / "summary.csv").read_bytes() == (lab_run[0] / "summary.csv").read_bytes()
    assert (out / "best.csv").read_bytes() == (lab_run[0] / "best.csv").read_bytes()
