"""The physics: the batched runner equals a plain serial MuJoCo loop, and
threads, chunking, divergence and neighbours never change a cell's numbers."""

from __future__ import annotations

import json
import math

import pytest

from conftest import REPO, as_float, chapter_metrics, read_csv

mujoco = pytest.importorskip("mujoco")
pc = pytest.importorskip("pupper_core")

#: The built-in model's file, loaded by MuJoCo alone (not through pupper).
SCENE = REPO / "models" / "pupper_v3" / "scene.xml"
NUMERIC = ["final_z", "last_1s_std_mm", "push_dip_mm", "settle_time_s", "max_tilt_deg",
           "peak_torque", "saturation_frac", "tracking_rms", "event_time"]


def serial_servo(kp: float, kd: float, seconds: float) -> dict[str, float]:
    """The chapter's loop, one MjData, no batching: servo gains written into
    the affine actuators, -25 N on base_link while 2.0 <= data.time < 2.25."""
    m = mujoco.MjModel.from_xml_path(str(SCENE))
    m.actuator_gainprm[:, 0] = kp
    m.actuator_biasprm[:, 1] = -kp
    m.actuator_biasprm[:, 2] = -kd
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    base = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "base_link")
    ts, zs = [], []
    while d.time < seconds:
        d.xfrc_applied[base] = [0, 0, -25, 0, 0, 0] if 2.0 <= d.time < 2.25 else 0.0
        mujoco.mj_step(m, d)
        ts.append(d.time)
        # base z after the step: the free joint's position (d.xpos would be
        # the pre-integration kinematics of this step)
        zs.append(d.qpos[2])
    return chapter_metrics(ts, zs, m.opt.timestep)


def test_servo_batch_equals_serial_python_loop():
    res = pc.sweep({"kp": [1, 30], "kd": [0.05, 0.5]}, seconds=4, progress=False)
    assert len(res) == 4
    assert res.ids == ["kp1_kd0.05", "kp1_kd0.5", "kp30_kd0.05", "kp30_kd0.5"]
    for i in range(len(res)):
        row = res.row(i)
        want = serial_servo(row["kp"], row["kd"], 4.0)
        assert want["samples"] == 2001  # accumulated time: 2000 steps leave t just under 4
        assert row["status"] == "ok"
        for k in ("final_z", "last_1s_std_mm", "push_dip_mm"):
            assert abs(row[k] - want[k]) <= 1e-9, (row["id"], k, row[k], want[k])


def test_threads_and_chunks_never_change_the_numbers(run, tmp_path):
    grid = ["--grid", "kp=10,60,120", "--grid", "kd=0.5,2", "--mode", "torque",
            "--seconds", "3", "-q"]
    outs = {}
    for name, extra in {
        "t1": ["--threads", "1"],
        "t2": ["--threads", "2"],
        "c1": ["--chunk-cells", "1"],
        "default": [],
    }.items():
        run("sweep", *grid, *extra, "-o", tmp_path / name, check=0)
        outs[name] = (tmp_path / name / "summary.csv").read_bytes()
    _, rows = read_csv(tmp_path / "default" / "summary.csv")
    assert len(rows) == 6
    assert outs["t1"] == outs["t2"], "--threads 1 and --threads 2 differ"
    assert outs["c1"] == outs["default"], "--chunk-cells 1 and the default chunking differ"
    assert outs["t1"] == outs["default"]


def test_diverging_cell_beside_healthy_ones(run, tmp_path):
    common = ["--grid", "timestep=0.01", "--max-torque", "1e6", "--seconds", "4", "-q"]
    run("sweep", "--grid", "kp=5,1e6", *common, "-o", tmp_path / "both", check=0)
    run("sweep", "--grid", "kp=5", *common, "-o", tmp_path / "alone", check=0)
    _, both = read_csv(tmp_path / "both" / "summary.csv")
    _, alone = read_csv(tmp_path / "alone" / "summary.csv")
    assert len(both) == 2 and len(alone) == 1
    ok, bad = both
    assert float(bad["kp"]) == 1e6
    assert bad["status"] == "diverged", bad
    assert math.isfinite(as_float(bad["event_time"])) and 0 < as_float(bad["event_time"]) <= 3
    assert ok["status"] == "ok", ok
    assert ok["event_time"] == ""
    for k in NUMERIC:
        if k == "event_time":
            continue
        assert math.isfinite(as_float(ok[k])) or k == "settle_time_s", (k, ok[k])
    # the healthy cell's numbers are the same alone and in the batch
    for k in NUMERIC + ["status"]:
        assert ok[k] == alone[0][k], (k, ok[k], alone[0][k])
    m = json.loads((tmp_path / "both" / "manifest.json").read_text())
    assert m["complete"] is True


def test_cell_does_not_depend_on_its_neighbours(run, tmp_path):
    base = ["--mode", "torque", "--seconds", "3", "-q"]
    run("sweep", "--grid", "kp=10,30,60,120", "--grid", "kd=0.5,1,2,5", *base,
        "-o", tmp_path / "grid", check=0)
    run("sweep", "--grid", "kp=30", "--grid", "kd=1", *base, "-o", tmp_path / "one", check=0)
    header, rows = read_csv(tmp_path / "grid" / "summary.csv")
    _, (one,) = read_csv(tmp_path / "one" / "summary.csv")
    (cell,) = [r for r in rows if r["id"] == "kp30_kd1"]
    assert one["id"] == "kp30_kd1"
    for k in ["kp", "kd"] + NUMERIC + ["status"]:
        assert cell[k] == one[k], (k, cell[k], one[k])
    assert cell["index"] == "5" and one["index"] == "0"
