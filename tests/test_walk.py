"""`pupper walk` (and `pupper_core.walk`): the robot trots open loop at a
commanded velocity, its joint targets from each leg's inverse kinematics.
Real MuJoCo on the built-in model and on a third-party quadruped
(tests/models/trotter15.xml, its own geometry, gains and limits).

The physics checks: the speed pupper reports is recomputed from the
recorded states with plain MuJoCo; at the Pupper team's kp 5 / kd 0.25 a trot
at 0.2-0.3 m/s walks without falling, far softer gains (kp 0.5) drag or
fall, and the speed achieved rises with the speed commanded."""

from __future__ import annotations

import json
import math
import shlex
from pathlib import Path

import mujoco
import numpy as np
import pupper_core as pc
import pytest

from conftest import REPO, assert_refused, read_csv

#: Runs of 5 s: the steady window is 3.5-5 s (three cycles at 2 Hz).
SHORT = ("--seconds", "5", "-q")
WINDOW = (3.5, 5.0)


def num(row: dict[str, str], col: str) -> float:
    return float(row[col]) if row[col] else math.nan


def by_id(rows: list[dict[str, str]]) -> dict[str, dict[str, str]]:
    return {r["id"]: r for r in rows}


def recomputed(rec: dict, window: tuple[float, float]) -> tuple[float, float]:
    """From recorded states, with plain MuJoCo (no pupper arithmetic): the
    base's path along its heading over ``window`` per second, and its plain
    displacement along world x per second."""
    m = rec["model"]
    d = mujoco.MjData(m)
    base = int(m.jnt_bodyid[np.flatnonzero(m.jnt_type == mujoco.mjtJoint.mjJNT_FREE)[0]])
    pos, yaw = [], []
    for q in rec["qpos"]:
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        pos.append(d.xpos[base, :2].copy())
        w, x, y, z = d.xquat[base]
        yaw.append(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
    t = np.asarray(rec["times"])
    inside = np.flatnonzero((t > window[0] + 1e-12) & (t <= window[1] + 1e-12))
    forward = 0.0
    for k in inside:
        turn = (yaw[k] - yaw[k - 1] + math.pi) % (2 * math.pi) - math.pi
        h = yaw[k - 1] + turn / 2
        forward += float(np.dot(pos[k] - pos[k - 1], [math.cos(h), math.sin(h)]))
    span = window[1] - window[0]
    return forward / span, float(pos[inside[-1]][0] - pos[inside[0] - 1][0]) / span


@pytest.fixture(scope="module")
def pupper_run(pupper_bin, tmp_path_factory) -> Path:
    """kp 0.5 and the Pupper team's kp 5 at kd 0.25, trotting at 0.2 and 0.3 m/s."""
    import subprocess

    from conftest import clean_env

    out = tmp_path_factory.mktemp("walk") / "pupper"
    subprocess.run([str(pupper_bin), "walk", "--grid", "kp=0.5,5", "--kd", "0.25", "--grid", "speed=0.2,0.3",
                    *SHORT, "-o", str(out)], env=clean_env(), check=True, capture_output=True, text=True)
    return out


def test_the_pupper_teams_gains_trot_soft_gains_drag_and_speed_follows_the_command(pupper_run):
    header, rows = read_csv(pupper_run / "summary.csv")
    for col in ("speed_ms", "speed_error_pct", "roll_rms_deg", "slip_mm_s", "amplitude_ratio", "lag_ms",
                "cost_of_transport", "status", "event_time"):
        assert col in header, col
    r = by_id(rows)
    slow, fast = r["kp5_v0.2"], r["kp5_v0.3"]
    # kp 5 / kd 0.25 walks: stays up and moves forward, faster when told
    assert slow["status"] == fast["status"] == "ok"
    assert 0.02 < num(slow, "speed_ms") < num(fast, "speed_ms") < 0.3
    # kp 0.5: the legs fold (a fall, dated), or the robot drags
    for cell in ("kp0.5_v0.2", "kp0.5_v0.3"):
        soft = r[cell]
        assert soft["status"] == "fell" or num(soft, "speed_ms") < 0.25 * num(fast, "speed_ms"), soft
        if soft["status"] == "fell":
            assert 0 < num(soft, "event_time") <= 5
    # the speed error is the distance from the commanded velocity
    assert num(fast, "speed_error_pct") == pytest.approx(
        100 * math.hypot(num(fast, "speed_ms") - 0.3, num(fast, "drift_ms")) / 0.3, rel=1e-9)
    m = json.loads((pupper_run / "manifest.json").read_text())
    assert m["kind"] == "walk" and m["config"]["schedule"]["push"] is None
    walk = m["config"]["walk"]
    assert walk["gait"] == "trot" and len(walk["legs"]) == 4 and walk["height"] == pytest.approx(0.1316, abs=1e-3)
    # open loop, kp 5 makes under half the commanded speed: the page does
    # not call that walking
    page = (pupper_run / "report.html").read_text()
    assert "kp5_v0.3</b> comes closest but does not walk the gait" in page
    assert "walks best" not in page


def test_the_reported_speed_is_the_bases_path_recomputed_with_plain_mujoco(pupper_run):
    _, rows = read_csv(pupper_run / "summary.csv")
    fast = by_id(rows)["kp5_v0.3"]
    # every physics step recorded (dt 2 ms): the states the probe saw
    (rec,) = pc.render.record_run(pupper_run, [int(fast["index"])], fps=500)
    path, straight = recomputed(rec, WINDOW)
    assert path == pytest.approx(num(fast, "speed_ms"), rel=1e-9, abs=1e-12)
    # walking straight ahead, the plain displacement says the same
    assert straight == pytest.approx(path, rel=0.03)


#: docs/walk.md's example on a robot that is not Pupper, run as written (from
#: a directory whose tests/ is the repository's)
TROTTER_EXAMPLE = """
pupper walk --model tests/models/trotter15.xml --grid kp=5,50 --grid speed=0.25,0.4 --seconds 5
""".strip()


def test_a_third_party_quadruped_walks_on_its_own_legs_gains_and_limits(run, tmp_path):
    (tmp_path / "tests").symlink_to(REPO / "tests")
    out = tmp_path / "trot"
    said = run(*shlex.split(TROTTER_EXAMPLE)[1:], "-q", "-o", out, check=0).stdout
    _, rows = read_csv(out / "summary.csv")
    r = by_id(rows)
    # its own gains (kp 50, +-24 N.m): up, forward, faster when told
    own, faster = r["kp50_v0.25"], r["kp50_v0.4"]
    assert own["status"] == faster["status"] == "ok"
    # the pick is on the grid's edge (kp 50 is the largest searched): the table says so where it names it
    best = read_csv(out / "best.csv")[1][0]["id"]
    assert best.startswith("kp50_")
    assert "the best-walking cell lies on the edge of the searched range (kp 50, the largest" in said
    assert 0.02 < num(own, "speed_ms") < num(faster, "speed_ms")
    assert num(own, "peak_torque") <= 24 + 1e-9
    # a tenth of them does not carry 15 kg
    for cell in ("kp5_v0.25", "kp5_v0.4"):
        assert r[cell]["status"] == "fell" or num(r[cell], "speed_ms") < 0.25 * num(own, "speed_ms")
    walk = json.loads((out / "manifest.json").read_text())["config"]["walk"]
    # its legs as the model has them: hips 0.19 m ahead, 0.21 m thigh and calf
    legs = {(l["front"], l["left"]): l for l in walk["legs"]}
    fl = legs[(True, True)]
    assert fl["anchors"][0] == pytest.approx([0.19, 0.06, 0.0]) and fl["foot"][2] == pytest.approx(-0.42)
    # the step scaled to its legs (6 cm on Pupper's 0.174 m), its stance from its keyframe
    assert walk["step_height"] == pytest.approx(0.06 * 0.42 / 0.17429019530912043)
    assert walk["height"] == pytest.approx(0.27, abs=2e-3)


def test_a_robot_started_on_straight_legs_bends_its_knees_the_way_they_go(run, tmp_path):
    # crawler8: torque motors (gains given), no keyframe, legs straight at
    # qpos0 and knees that bend one way only: its stance is lowered into
    # reach and each knee takes the bend its range allows
    out = tmp_path / "crawl"
    run("walk", "--model", REPO / "tests" / "models" / "crawler8.xml", "--kp", "40", "--kd", "1",
        "--speed", "0.3", *SHORT, "-o", out, check=0)
    (row,) = read_csv(out / "summary.csv")[1]
    assert row["status"] == "ok" and num(row, "speed_ms") > 0.1, row


def test_replicates_rank_by_the_worst_side_and_keep_each_robots_figures(run, tmp_path):
    out = tmp_path / "rep"
    p = run("walk", "--grid", "kp=10,20", "--kd", "0.25", "--replicates", "3", "--randomize", "torso_mass=±10%",
            *SHORT, "-o", out, check=0)
    header, rows = read_csv(out / "summary.csv")
    assert {"mean:speed_ms", "p95:speed_ms", "p95:speed_error_pct", "failure_fraction"} <= set(header)
    rh, reps = read_csv(out / "replicates.csv")
    assert "speed_ms" in rh and len(reps) == 6
    for r in rows:
        mine = [num(x, "speed_ms") for x in reps if x["id"] == r["id"]]
        assert num(r, "mean:speed_ms") == pytest.approx(float(np.mean(mine)), rel=1e-12)
        # the worst side of a speed is the slow one
        assert num(r, "p95:speed_ms") <= num(r, "mean:speed_ms")
    _, best = read_csv(out / "best.csv")
    assert "p95:speed_error_pct" in p.stdout
    want = min(rows, key=lambda r: num(r, "p95:speed_error_pct"))["id"]
    assert best[0]["id"] == want


def test_the_same_walk_gives_the_same_bytes_and_torque_mode_walks_too(run, tmp_path):
    args = ("walk", "--grid", "kp=10,20", "--kd", "0.5", *SHORT)
    run(*args, "-o", tmp_path / "a", check=0)
    run(*args, "--chunk-cells", "1", "-j", "1", "-o", tmp_path / "b", check=0)
    assert (tmp_path / "a" / "summary.csv").read_bytes() == (tmp_path / "b" / "summary.csv").read_bytes()
    # torque mode: the PD in Rust follows the same moving targets
    run(*args, "--mode", "torque", "-o", tmp_path / "t", check=0)
    _, servo = read_csv(tmp_path / "a" / "summary.csv")
    _, torque = read_csv(tmp_path / "t" / "summary.csv")
    for s, t in zip(servo, torque):
        assert t["status"] == "ok"
        assert num(t, "speed_ms") == pytest.approx(num(s, "speed_ms"), abs=0.03)


def test_a_cut_walk_resumes_to_the_same_bytes_and_picks(run, tmp_path):
    out = tmp_path / "r"
    run("walk", "--grid", "kp=5,20", "--grid", "speed=0.1,0.2", *SHORT, "-o", out, check=0)
    whole, best = (out / "summary.csv").read_bytes(), (out / "best.csv").read_bytes()
    # two of four cells kept, as a stopped run keeps them
    (out / "summary.csv").write_bytes(b"".join(whole.splitlines(keepends=True)[:3]))
    run("walk", "--resume", out, "-q", check=0)
    assert (out / "summary.csv").read_bytes() == whole
    # the best walker of each speed, as the run it continues picked them
    assert (out / "best.csv").read_bytes() == best
    _, picks = read_csv(out / "best.csv")
    assert [p["speed"] for p in picks] == ["0.1", "0.2"]


def test_the_python_walk_is_the_cli_walk(run, tmp_path):
    run("walk", "--grid", "kp=5,20", "--kd", "0.25", *SHORT, "-o", tmp_path / "cli", check=0)
    res = pc.walk({"kp": [5, 20]}, kd=0.25, seconds=5, progress=False, out=tmp_path / "py")
    assert (tmp_path / "py" / "summary.csv").read_bytes() == (tmp_path / "cli" / "summary.csv").read_bytes()
    assert res.best()["id"] == "kp20"
    page = (tmp_path / "py" / "report.html").read_text()
    # the page opens with the answer: the gains that walk best
    answer = page.index('<section id="answer">')
    assert page.index("kp20</b> walks best", answer) < page.index("<h2>Figures</h2>")


def test_a_walking_cell_is_rendered(run, tmp_path, pupper_run):
    if (reason := pc.render.gl_available()) is not None:
        pytest.skip(f"no OpenGL context for offscreen rendering: {reason}")
    png = tmp_path / "walk.png"
    run("render", "--run", pupper_run, "--cell", "kp5_v0.3", "--time", "4.5", "-o", png, check=0)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(("args", "words"), [
    (("--gait", "gallop"), "unknown gait 'gallop': use trot, walk, pace or bound"),
    (("--duty", "1.2"), "--duty 1.2: give a duty factor in [0.05, 0.95]"),
    (("--seconds", "3"), "leaves no whole gait cycle of steady walking"),
    (("--grid", "speed=4"), "beyond its reach"),
    (("--variant", "long-leg"), "--variant long-leg: a walk runs the gait on the compiled model's own legs"),
    (("--grid", "push_force=-10"), "drop the push_force grid axis"),
])
def test_bad_input_is_one_line(run, tmp_path, args, words):
    out = tmp_path / "bad"
    assert_refused(run("walk", *args, "-o", out), words, out)


def test_a_gait_axis_belongs_to_a_walk(run, tmp_path):
    out = tmp_path / "s"
    assert_refused(run("sweep", "--grid", "speed=0.1,0.2", "-o", out), "is a walk's own axis: run it with `pupper walk`",
                   out)
