"""The warp backend (MuJoCo Warp) against the cpu backend, on Warp's CPU
device: CI has no GPU. `make test` installs the optional extra (gpu), so
these run real MuJoCo Warp; the first one compiles Warp's kernels (about
half a minute, then cached)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import as_float, hidden, read_csv

pytest.importorskip("warp", reason="the gpu extra is not installed: make test installs it")
pc = pytest.importorskip("pupper_core")

WARP = ["--backend", "warp", "--device", "cpu"]
# a short schedule that still measures everything: 2 s (the last second
# after the 1 s landing), a push at 0.2 s whose dip window ends by 1.95 s
SHORT = ["--seconds", "2", "--push-at", "0.2", "-q"]
NUMBERS = ["final_z", "last_1s_std_mm", "push_dip_mm", "max_tilt_deg", "peak_torque",
           "tracking_rms"]


def both(run, tmp_path: Path, *args: str) -> tuple[tuple, tuple]:
    """summary.csv (header, rows) of the same sweep on warp and on cpu."""
    run("sweep", *args, *WARP, "-o", tmp_path / "warp", check=0)
    run("sweep", *args, "-o", tmp_path / "cpu", check=0)
    return read_csv(tmp_path / "warp" / "summary.csv"), read_csv(tmp_path / "cpu" / "summary.csv")


def assert_agree(warp: tuple, cpu: tuple, tol_z: float = 1e-4) -> None:
    (hw, rw), (hc, rc) = warp, cpu
    assert hw == hc, "the backends write different columns"
    assert [r["id"] for r in rw] == [r["id"] for r in rc]
    # a plain sweep's status, or a replicated one's failure fraction
    status, z = ("status", "final_z") if "status" in hw else ("failure_fraction", "mean:final_z")
    assert [r[status] for r in rw] == [r[status] for r in rc]
    for a, b in zip(rw, rc):
        assert abs(as_float(a[z]) - as_float(b[z])) < tol_z, (a, b)


@pytest.mark.parametrize("mode", ["servo", "torque"])
def test_warp_agrees_with_cpu(run, tmp_path, mode):
    warp, cpu = both(run, tmp_path, "--grid", "kp=5,30", "--grid", "kd=0.1,1",
                     "--mode", mode, *SHORT)
    assert_agree(warp, cpu)
    # float32 against float64 on a 2 s schedule: far closer than the bound
    for a, b in zip(warp[1], cpu[1]):
        assert abs(float(a["final_z"]) - float(b["final_z"])) < 1e-5, (a, b)
    m = json.loads((tmp_path / "warp" / "manifest.json").read_text())
    assert m["config"]["backend"] == {"name": "warp", "device": "cpu", "precision": "float32"}
    # a cpu run's manifest is what it always was: no backend entry
    assert "backend" not in json.loads((tmp_path / "cpu" / "manifest.json").read_text())["config"]


def test_torque_mode_pd_as_actuator_parameters(run, tmp_path):
    """Warp runs torque mode's PD as actuator gain kp, bias (0, -kp, -kd)
    and the torque limit as force range. On the cpu backend (float64) that
    mapping is servo mode, and it gives the Rust PD's numbers exactly."""
    args = ["--grid", "kp=5,60", "--grid", "kd=0.1,2", "--max-torque", "1.5", *SHORT]
    run("sweep", *args, "--mode", "servo", "-o", tmp_path / "servo", check=0)
    run("sweep", *args, "--mode", "torque", "-o", tmp_path / "torque", check=0)
    run("sweep", *args, "--mode", "torque", *WARP, "-o", tmp_path / "warp", check=0)
    _, servo = read_csv(tmp_path / "servo" / "summary.csv")
    _, torque = read_csv(tmp_path / "torque" / "summary.csv")
    _, warp = read_csv(tmp_path / "warp" / "summary.csv")
    for s, t, w in zip(servo, torque, warp):
        for k in NUMBERS:
            a, b = as_float(s[k]), as_float(t[k])
            assert math.isfinite(b), (k, t)
            assert abs(a - b) <= 1e-9 * max(1.0, abs(b)), (k, s, t)
        # the 1.5 N·m limit binds: the clip is part of the mapping
        assert float(t["peak_torque"]) == pytest.approx(1.5)
        assert abs(float(w["final_z"]) - float(t["final_z"])) < 1e-4
        assert w["status"] == t["status"]


def test_bodies_friction_and_replicates_per_world(run, tmp_path):
    """Body variants (one Warp model: masses are per world), friction per world and drawn
    masses, gains, push times: the same robots as on cpu."""
    warp, cpu = both(
        run, tmp_path, "--grid", "variant=original,heavy", "--grid", "friction=0.6,1.1",
        "--kp", "20", "--kd", "0.5", "--replicates", "3", "--seed", "4",
        "--randomize", "torso_mass=±10%", "--randomize", "motor_gain=±5%",
        "--randomize", "push_at=0.1:0.25", *SHORT,
    )
    assert_agree(warp, cpu)
    _, rw = read_csv(tmp_path / "warp" / "replicates.csv")
    _, rc = read_csv(tmp_path / "cpu" / "replicates.csv")
    assert len(rw) == len(rc) == 12
    for a, b in zip(rw, rc):
        # the same draws, to the digit: they come from Rust either way
        drawn = [k for k in a if k.startswith(("torso_mass", "motor_gain")) or k == "push_at"]
        assert len(drawn) == 14, drawn
        assert {k: a[k] for k in drawn} == {k: b[k] for k in drawn}
        assert abs(float(a["final_z"]) - float(b["final_z"])) < 1e-4, (a, b)


def test_a_population_of_drawn_masses_is_one_warp_model(caplog):
    """64 robots with drawn torso and leg masses, and the heavy body beside
    the original, run as worlds of one Warp model (masses, inertias and
    what MuJoCo derives from them per world), as the log says; the numbers
    are the cpu backend's."""
    import logging

    from pupper_core import _warp

    kw = dict(kp=20, kd=0.5, replicates=64, seed=3, seconds=2.0, push_at=0.2, progress=False,
              randomize=["torso_mass=±15%", "leg_mass=±10%"])
    grid = {"variant": ["original", "heavy"]}
    before = _warp.MODELS_BUILT
    with caplog.at_level(logging.INFO, logger="pupper_core.warp"):
        w = pc.sweep(grid, backend="warp", device="cpu", **kw)
    assert _warp.MODELS_BUILT - before == 1
    assert [r.getMessage() for r in caplog.records] == [
        "one Warp model for 128 worlds (128 bodies of masses) on cpu"]
    c = pc.sweep(grid, **kw)
    assert w.header == c.header and list(w["failure_fraction"]) == list(c["failure_fraction"])
    zw, zc = w.replicates["final_z"], c.replicates["final_z"]
    assert len(zw) == 128 and len(set(zc)) == 128  # every robot its own
    assert max(abs(a - b) for a, b in zip(zw, zc)) < 1e-4


@pytest.mark.parametrize("args", [
    ["--mode", "servo"],
    ["--mode", "torque"],
    ["--signal", "sine", "--frequency", "3", "--amplitude", "0.1"],
    ["--standing"],
], ids=["servo-step", "torque-step", "sine", "standing"])
def test_response_on_warp(run, tmp_path, args):
    """pupper response (targets that move every step, written on the device
    before each step) agrees with cpu: the same rows and statuses, rise and
    settling times to the step, the rest to float32's noise."""
    common = ["response", "--joints", "kfe,hfe", "--grid", "kp=5,20", "--kd", "0.5",
              "--seconds", "1.5", *args, "-q"]
    run(*common, *WARP, "-o", tmp_path / "warp", check=0)
    run(*common, "-o", tmp_path / "cpu", check=0)
    hw, rw = read_csv(tmp_path / "warp" / "response.csv")
    hc, rc = read_csv(tmp_path / "cpu" / "response.csv")
    assert hw == hc and len(rw) == len(rc) == 16
    for a, b in zip(rw, rc):
        assert (a["id"], a["joint"], a["status"]) == (b["id"], b["joint"], b["status"])
        for k in ("rise_time_s", "settling_time_s"):
            if b[k]:
                assert abs(float(a[k]) - float(b[k])) <= 0.0021, (k, a, b)
        for k in ("overshoot_pct", "ss_error_pct", "gain_db", "phase_deg", "peak_torque"):
            if b[k]:
                assert abs(float(a[k]) - float(b[k])) <= 0.01 * max(1.0, abs(float(b[k]))), (k, a, b)


def test_tune_on_warp(run, tmp_path):
    """A tune generation is one Warp batch: the same trials as on cpu (the
    sampler sees values that agree to float32's noise)."""
    args = ["tune", "--space", "kp=5:50:log", "--space", "kd=0.1:2:log", "--trials", "8", "--batch", "8",
            "--seconds", "2", "--push-at", "0.2", "-q"]
    run(*args, *WARP, "-o", tmp_path / "warp", check=0)
    run(*args, "-o", tmp_path / "cpu", check=0)
    _, rw = read_csv(tmp_path / "warp" / "trials.csv")
    _, rc = read_csv(tmp_path / "cpu" / "trials.csv")
    assert [(r["kp"], r["kd"], r["status"]) for r in rw] == [(r["kp"], r["kd"], r["status"]) for r in rc]
    for a, b in zip(rw, rc):
        assert abs(float(a["last_1s_std_mm"]) - float(b["last_1s_std_mm"])) < 1e-4, (a, b)
    m = json.loads((tmp_path / "warp" / "manifest.json").read_text())
    assert m["inputs"]["options"]["backend"] == "warp"


def test_sine_force_lab_on_warp(tmp_path):
    """The lab (torque mode, each body from its own searched stand pose,
    a force per step) agrees with cpu."""
    kw = dict(seconds=1.0, progress=False)
    a = pc.lab(["original", "long-leg"], ["kp=10,60", "kd=0.5"], backend="warp", device="cpu", **kw)
    b = pc.lab(["original", "long-leg"], ["kp=10,60", "kd=0.5"], **kw)
    assert a.header == b.header and list(a["status"]) == list(b["status"])
    assert max(abs(x - y) for x, y in zip(a["final_z"], b["final_z"])) < 1e-4


def test_diverging_world_leaves_the_others_alone(run, tmp_path):
    common = ["--grid", "timestep=0.01", "--max-torque", "1e6", "--seconds", "2", "-q", *WARP]
    run("sweep", "--grid", "kp=5,1e6", *common, "-o", tmp_path / "both", check=0)
    run("sweep", "--grid", "kp=5", *common, "-o", tmp_path / "alone", check=0)
    _, both_rows = read_csv(tmp_path / "both" / "summary.csv")
    _, alone = read_csv(tmp_path / "alone" / "summary.csv")
    ok, bad = both_rows
    assert bad["status"] == "diverged" and 0 < as_float(bad["event_time"]) <= 2, bad
    assert ok == {**alone[0], "index": ok["index"]}, "a diverging world changed a healthy one"


def test_same_inputs_same_bytes_whatever_the_batches(run, tmp_path):
    args = ["--grid", "kp=10,40,80", "--grid", "kd=0.5,2", *SHORT, *WARP]
    run("sweep", *args, "-o", tmp_path / "a", check=0)
    run("sweep", *args, "--chunk-cells", "2", "-o", tmp_path / "b", check=0)
    assert (tmp_path / "a" / "summary.csv").read_bytes() == (tmp_path / "b" / "summary.csv").read_bytes()
    assert json.loads((tmp_path / "b" / "manifest.json").read_text())["batches"] == 3
    # resuming alone keeps the manifest's backend
    p = run("sweep", "--resume", tmp_path / "b", "-q", check=0)
    assert (tmp_path / "a" / "summary.csv").read_bytes() == (tmp_path / "b" / "summary.csv").read_bytes(), p.stderr


def test_python_keywords(tmp_path):
    r = pc.sweep({"kp": [5, 30]}, seconds=1.0, push_at=0.5, backend="warp", device="cpu",
                 progress=False, out=tmp_path / "py")
    c = pc.sweep({"kp": [5, 30]}, seconds=1.0, push_at=0.5, progress=False)
    assert list(r["status"]) == list(c["status"])
    assert max(abs(x - y) for x, y in zip(r["final_z"], c["final_z"])) < 1e-4
    assert r.config["backend"]["name"] == "warp"


@pytest.mark.parametrize(
    "args, words",
    [
        (["--backend", "warp", "--device", "gpu"], ["device 'gpu'", "cuda:0", "cpu"]),
        (["--device", "cpu"], ["--device", "--backend warp"]),
        (["--backend", "warp", "--device", "cuda:7"], ["no device 'cuda:7'", "--device cpu"]),
        (["--backend", "warp", "--device", "cpu", "--mode", "torque", "--replicates", "2",
          "--randomize", "delay=0:2"], ["delay", "--backend cpu"]),
        (["--backend", "warp", "--device", "cpu", "--mode", "torque", "--replicates", "2",
          "--randomize", "q_noise=N(0,0.01)"], ["q_noise", "--backend cpu"]),
    ],
)
def test_bad_backend_input(run, tmp_path, args, words):
    out = tmp_path / "never"
    p = run("sweep", *args, "-o", out, check=2)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert not out.exists()


def test_a_calibrated_delay_in_torque_mode_needs_cpu(run, tmp_path):
    """Torque mode runs a model's command delay in the Rust firmware, which
    warp does not have: refused before anything is written, not dropped."""
    import mujoco

    from conftest import REPO

    spec = mujoco.MjSpec.from_file(str(REPO / "models" / "pupper_v3" / "pupper_v3.xml"))
    for a in spec.actuators:
        a.nsample, a.interp, a.delay = 8, 1, 0.01
    (tmp_path / "late.xml").write_text(spec.to_xml())
    out = tmp_path / "never"
    p = run("sweep", "--model", tmp_path / "late.xml", "--mode", "torque", *WARP, "-o", out, check=2)
    assert p.stderr.count("\n") == 1 and "command delay of 0.01 s" in p.stderr and "--backend cpu" in p.stderr
    assert not out.exists()


def test_missing_warp_says_what_to_install(run, tmp_path):
    """Without MuJoCo Warp (hidden here by a sitecustomize that blocks its
    import), --backend warp fails in one line naming the extra, exit 2."""
    env = hidden(tmp_path, "warp")
    out = tmp_path / "never"
    p = run("sweep", *WARP, "-o", out, env=env, check=2)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    assert "pupper_core[gpu]" in lines[0] and "'warp'" in lines[0], lines[0]
    assert not out.exists()
    # the cpu backend does not need it
    run("sweep", "--grid", "kp=5", "--seconds", "0.5", "--no-push", "-q", "-o", tmp_path / "cpu",
        env=env, check=0)
    # and Python raises the same line
    code = ("import sys; sys.modules['warp'] = None\nimport pupper_core as pc\n"
            "try:\n    pc.sweep(backend='warp', device='cpu', progress=False)\n"
            "except Exception as e:\n    print(type(e).__name__, e)\n")
    py = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert "pupper_core[gpu]" in py.stdout, (py.stdout, py.stderr)


def test_doctor_lists_warp_devices(run):
    p = run("doctor", "--json", check=0)
    report = json.loads(p.stdout)
    assert report["warp"].startswith("warp-lang ")
    assert any(d.startswith("cpu") for d in report["warp_devices"]), report
