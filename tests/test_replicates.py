"""Randomized replicates (issue 12): every cell run on a seeded population
of plausible robots. The draws are keyed, so bytes never depend on threads,
batches or resume points; the statistics in summary.csv are recomputed here
from replicates.csv; latency and noise are checked against hand-written
loops; a drawn torso mass equals the same mass compiled."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import REPO, as_float, assert_refused, chapter_metrics, clean_env, read_csv

mujoco = pytest.importorskip("mujoco")
pc = pytest.importorskip("pupper_core")

SCENE = REPO / "models" / "pupper_v3" / "scene.xml"
AGGREGATED = ["final_z", "last_1s_std_mm", "push_dip_mm", "settle_time_s", "max_tilt_deg",
              "peak_torque", "saturation_frac", "tracking_rms"]
#: A small replicated torque sweep (the README's, shorter).
SMALL = ["--grid", "kp=30,120", "--grid", "kd=0.5,2", "--mode", "torque", "--seconds", "3",
         "--replicates", "6", "--randomize", "torso_mass=±15%", "--randomize", "friction=0.5:1.2",
         "--randomize", "delay=0:2", "--seed", "7", "-q"]


def files(d: Path) -> dict[str, bytes]:
    return {n: (d / n).read_bytes() for n in ("summary.csv", "replicates.csv")}


@pytest.fixture(scope="module")
def small_run(pupper_bin, tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("small") / "run"
    p = subprocess.run([str(pupper_bin), "sweep", *SMALL, "-o", str(d)], env=clean_env(),
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    return d


def test_the_run_directory_has_replicates_and_their_statistics(small_run):
    header, reps = read_csv(small_run / "replicates.csv")
    assert header[:7] == ["index", "id", "name", "kp", "kd", "replicate", "torso_mass"]
    assert header[7:9] == ["friction", "delay"] and header[9] == "final_z"
    assert len(reps) == 4 * 6
    assert [r["replicate"] for r in reps[:6]] == [str(k) for k in range(6)]
    for r in reps:
        assert 0.85 <= float(r["torso_mass"]) <= 1.15
        assert 0.5 <= float(r["friction"]) <= 1.2
        assert r["delay"] in ("0", "1", "2")
    assert len({r["torso_mass"] for r in reps}) == len(reps), "every replicate draws its own"
    _, summary = read_csv(small_run / "summary.csv")
    assert len(summary) == 4
    for cell in summary:
        mine = [r for r in reps if r["id"] == cell["id"]]
        up = [r for r in mine if r["status"] in ("ok", "saturated")]
        assert cell["replicates"] == "6"
        assert float(cell["failure_fraction"]) == pytest.approx((6 - len(up)) / 6, abs=0)
        for m in AGGREGATED:
            xs = np.array([as_float(r[m]) for r in up])
            if not up or not np.isfinite(xs).all():
                assert cell[f"mean:{m}"] == cell[f"p95:{m}"] == ""
                continue
            q = 5 if m == "final_z" else 95  # the worst side
            assert float(cell[f"mean:{m}"]) == pytest.approx(xs.mean(), rel=1e-12, abs=1e-15)
            assert float(cell[f"p95:{m}"]) == pytest.approx(np.percentile(xs, q), rel=1e-12, abs=1e-15)
    m = json.loads((small_run / "manifest.json").read_text())
    assert m["config"]["replicates"] == {
        "count": 6, "seed": 7,
        "randomize": [{"quantity": "torso_mass", "dist": {"relative": 0.15}},
                      {"quantity": "friction", "dist": {"uniform": [0.5, 1.2]}},
                      {"quantity": "delay", "dist": {"steps": [0, 2]}}]}


def test_threads_batches_and_resume_never_change_the_bytes(run, pupper_bin, tmp_path, small_run):
    run("sweep", *SMALL, "-o", tmp_path / "one", "-j", "1", "--chunk-cells", "1", check=0)
    assert files(tmp_path / "one") == files(small_run)
    m = json.loads((tmp_path / "one" / "manifest.json").read_text())
    assert m["batches"] == 4, "--chunk-cells 1: a batch per cell, its replicates inside"
    # killed after its first batch, then resumed
    out = tmp_path / "killed"
    proc = subprocess.Popen([str(pupper_bin), "sweep", *SMALL, "-o", str(out),
                             "--chunk-cells", "1", "-j", "1"], env=clean_env())
    deadline = time.time() + 120
    while time.time() < deadline:
        text = (out / "summary.csv").read_text() if (out / "summary.csv").exists() else ""
        if text.count("\n") >= 2 and proc.poll() is None:
            proc.send_signal(signal.SIGKILL)
            break
        if proc.poll() is not None:
            break
        time.sleep(0.01)
    proc.wait(timeout=60)
    run("sweep", *SMALL, "--resume", out, check=0)
    assert files(out) == files(small_run)
    # another seed draws other robots
    run("sweep", *SMALL[:-3], "--seed", "8", "-q", "-o", tmp_path / "seed8", check=0)
    _, a = read_csv(small_run / "replicates.csv")
    _, b = read_csv(tmp_path / "seed8" / "replicates.csv")
    assert [r["torso_mass"] for r in a] != [r["torso_mass"] for r in b]


def test_one_replicate_without_draws_is_todays_sweep(run, tmp_path):
    base = ["sweep", "--grid", "kp=30,120", "--grid", "kd=1", "--mode", "torque", "--seconds", "3", "-q"]
    run(*base, "-o", tmp_path / "plain", check=0)
    run(*base, "--replicates", "1", "--seed", "9", "-o", tmp_path / "r1", check=0)
    assert (tmp_path / "r1" / "summary.csv").read_bytes() == (tmp_path / "plain" / "summary.csv").read_bytes()
    assert not (tmp_path / "r1" / "replicates.csv").exists()
    cfg = lambda d: json.loads((d / "manifest.json").read_text())["config"]  # noqa: E731
    assert cfg(tmp_path / "r1") == cfg(tmp_path / "plain") and "replicates" not in cfg(tmp_path / "plain")
    # zero latency and zero noise are the plain torque-mode PD, to the bit
    run(*base, "--replicates", "2", "--randomize", "delay=0:0", "--randomize", "q_noise=N(0,0)",
        "-o", tmp_path / "zero", check=0)
    _, plain = read_csv(tmp_path / "plain" / "summary.csv")
    _, reps = read_csv(tmp_path / "zero" / "replicates.csv")
    for r in reps:
        want = next(p for p in plain if p["id"] == r["id"])
        for m in AGGREGATED + ["status", "event_time"]:
            assert r[m] == want[m], (r["id"], r["replicate"], m)


def serial_delayed_torque(kp: float, kd: float, seconds: float, delay: int,
                          noise: list[float] | None = None) -> dict[str, float]:
    """A torque-mode loop by hand, one MjData: actuators as direct torque
    inputs clipped at ±3 N·m, the PD reading the joints `delay` control
    steps late (the start state until then), -25 N on the base while
    2.0 <= t < 2.25."""
    m = mujoco.MjModel.from_xml_path(str(SCENE))
    m.actuator_gaintype[:] = 0
    m.actuator_biastype[:] = 1
    m.actuator_gainprm[:, :] = 0
    m.actuator_gainprm[:, 0] = 1.0
    m.actuator_biasprm[:, :] = 0
    m.actuator_ctrllimited[:] = 0
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    target = d.ctrl.copy() if m.key_ctrl.size == 0 else m.key_ctrl[0].copy()
    joints = m.actuator_trnid[:, 0]
    qadr, vadr = m.jnt_qposadr[joints], m.jnt_dofadr[joints]
    base = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "base_link")
    history: list[tuple[np.ndarray, np.ndarray]] = []
    ts, zs = [], []
    while d.time < seconds:
        history.append((d.qpos[qadr].copy(), d.qvel[vadr].copy()))
        if len(history) > delay + 1:
            history.pop(0)
        q, v = history[0]
        tau = np.clip(kp * (target - q) - kd * v, -3.0, 3.0)
        d.ctrl[:] = tau
        d.xfrc_applied[base] = [0, 0, -25, 0, 0, 0] if 2.0 <= d.time < 2.25 else 0.0
        mujoco.mj_step(m, d)
        ts.append(d.time)
        zs.append(d.qpos[2])
    return chapter_metrics(ts, zs, m.opt.timestep)


@pytest.mark.parametrize("k", [1, 3])
def test_a_delay_of_k_steps_equals_a_hand_written_delayed_pd_loop(k):
    # 4 s: the push at 2 s and the 1.5 s after it fit, so the dip is measured
    res = pc.sweep({"kp": [60], "kd": [0.5]}, mode="torque", seconds=4, replicates=2,
                   randomize=[f"delay={k}:{k}"], progress=False)
    reps = res.replicates
    assert reps is not None and len(reps) == 2 and list(reps["delay"]) == [k, k]
    want = serial_delayed_torque(60, 0.5, 4.0, k)
    for i in range(2):
        row = reps.row(i)
        for m in ("final_z", "last_1s_std_mm", "push_dip_mm"):
            assert abs(row[m] - want[m]) <= 1e-9, (k, m, row[m], want[m])
    # and the latency matters: k steps late is not on time
    on_time = serial_delayed_torque(60, 0.5, 4.0, 0)
    assert abs(on_time["last_1s_std_mm"] - want["last_1s_std_mm"]) > 1e-6


def test_a_drawn_torso_mass_equals_that_mass_compiled(run, tmp_path):
    run("sweep", "--grid", "kp=60", "--grid", "kd=1", "--seconds", "3", "--replicates", "2",
        "--randomize", "torso_mass=±15%", "--randomize", "leg_mass=±0%", "--seed", "3", "-q",
        "-o", tmp_path / "drawn", check=0)
    _, reps = read_csv(tmp_path / "drawn" / "replicates.csv")
    for r in reps:
        f = r["torso_mass"]
        assert float(f) != 1.0
        run("sweep", "--grid", "kp=60", "--grid", "kd=1", "--grid", f"torso_mass_scale={f}",
            "--seconds", "3", "-q", "-o", tmp_path / f"compiled{r['replicate']}", check=0)
        _, (compiled,) = read_csv(tmp_path / f"compiled{r['replicate']}" / "summary.csv")
        for m in AGGREGATED:
            a, b = as_float(r[m]), as_float(compiled[m])
            assert (math.isnan(a) and math.isnan(b)) or abs(a - b) <= 1e-9 * max(1.0, abs(b)), (m, a, b)


def test_drawn_values_follow_their_distributions(run, tmp_path):
    """2,000 replicates of one 10 ms cell: the values applied (replicates.csv)
    have the spec's mean and spread, within five standard errors."""
    n = 2000
    run("sweep", "--seconds", "0.01", "--replicates", n, "--randomize", "friction=0.5:1.2",
        "--randomize", "motor_gain=±5%", "--randomize", "push_at=0:0.005", "--seed", "11",
        "-q", "-o", tmp_path / "many", check=0)
    _, reps = read_csv(tmp_path / "many" / "replicates.csv")
    assert len(reps) == n
    mu = np.array([float(r["friction"]) for r in reps])
    se = 0.7 / math.sqrt(12) / math.sqrt(n)
    assert abs(mu.mean() - 0.85) < 5 * se and abs(mu.std() - 0.7 / math.sqrt(12)) < 0.01
    g = np.array([[float(r[f"motor_gain_{a}"]) for a in range(12)] for r in reps])
    assert g.min() >= 0.95 and g.max() <= 1.05
    assert abs(g.mean() - 1.0) < 5 * 0.1 / math.sqrt(12) / math.sqrt(g.size)
    assert abs(np.corrcoef(g[:, 0], g[:, 1])[0, 1]) < 5 / math.sqrt(n), "actuators draw independently"
    at = np.array([float(r["push_at"]) for r in reps])
    assert 0 <= at.min() and at.max() <= 0.005


@pytest.mark.parametrize("args, words", [
    (["--randomize", "friction=±"], "friction=LOW:HIGH"),
    (["--randomize", "torso_mass=abc"], "±P%"),
    (["--randomize", "friction=-0.5:1"], "make no sense"),
    (["--randomize", "push_at=3:1"], "LOW is above HIGH"),
    (["--randomize", "wind=1:2"], "unknown quantity 'wind'"),
    (["--randomize", "delay=0:2"], "--mode torque"),
    (["--randomize", "q_noise=N(0,0.01)"], "--mode torque"),
    (["--randomize", "push_force=-30:-20", "--no-push"], "--no-push"),
    (["--randomize", "friction=0.5:1", "--grid", "friction=0.8"], "drop the friction axis"),
    (["--randomize", "delay=0:1", "--randomize", "delay=1:2", "--mode", "torque"], "twice"),
    (["--replicates", "0"], "--replicates"),
    (["--replicates", "200000"], "simulations"),
    (["--best-by", "kd", "--rank", "p95:last_1s_std_mm"], "--replicates or --randomize"),
    (["--replicates", "2", "--best-by", "kd", "--rank", "last_1s_std_mm"], "statistic over replicates"),
])
def test_bad_population_specs_get_one_line_and_exit_2(run, tmp_path, args, words):
    p = run("sweep", "--grid", "kd=1,2", "-o", tmp_path / "never", *args, check=2)
    assert_refused(p, words, tmp_path / "never")


def test_robust_ranking_from_the_cli_and_python_agree(run, tmp_path, small_run):
    p = run("sweep", *SMALL, "--best-by", "kp", "-o", tmp_path / "ranked", check=0)
    assert "best p95:last_1s_std_mm by kp:" in p.stdout
    _, best = read_csv(tmp_path / "ranked" / "best.csv")
    res = pc.load_run(small_run)
    assert res.replicates is not None and len(res.replicates) == 24
    picked = res.best(by=["kp"])
    assert [b["id"] or "" for b in picked] == [b["id"] for b in best]
    py = pc.sweep(["kp=30,120", "kd=0.5,2"], mode="torque", seconds=3, replicates=6, seed=7,
                  randomize=["torso_mass=±15%", "friction=0.5:1.2", "delay=0:2"],
                  out=tmp_path / "py", progress=False)
    assert files(tmp_path / "py") == files(small_run)
    assert py.rows == res.rows


def test_lab_with_replicates(run, tmp_path):
    p = run("lab", "--variants", "original,heavy", "--grid", "kp=30,120", "--grid", "kd=1",
            "--seconds", "2", "--replicates", "3", "--randomize", "torso_mass=±10%",
            "--randomize", "q_noise=N(0,0.001)", "-o", tmp_path / "lab", check=0)
    lines = p.stdout.strip().splitlines()
    assert [line.split()[0] for line in lines] == ["original", "heavy"], p.stdout
    assert all("p95:last_1s_std_mm=" in line for line in lines if "no gains" not in line), p.stdout
    _, reps = read_csv(tmp_path / "lab" / "replicates.csv")
    assert len(reps) == 2 * 2 * 3
    assert json.loads((tmp_path / "lab" / "manifest.json").read_text())["batches"] == 1
    plots = {q.name for q in (tmp_path / "lab" / "plots").iterdir()}
    assert {"lab_heatmaps.png", "lab_failure_fraction.png", "lab_spread_last_1s_std_mm.png"} <= plots


def test_resume_alone_ranks_a_replicated_run_by_its_statistic(run, tmp_path):
    out = tmp_path / "run"
    run("sweep", "--grid", "kd=0.5,1", "--seconds", "2.5", "--no-push", "--replicates", "2",
        "--randomize", "friction=0.6:1", "-q", "-o", out, check=0)
    # the flags are the manifest's: the default ranking must be its statistic
    p = run("sweep", "--resume", out, "--best-by", "kd", "-q", check=0)
    assert "best p95:last_1s_std_mm by kd:" in p.stdout, p.stdout + p.stderr


def test_lab_takes_the_counts_sweep_takes():
    with pytest.raises(ValueError, match="replicates must be a whole number >= 0, not -1"):
        pc.lab(replicates=-1, progress=False)
    with pytest.raises(ValueError, match="seed must be a whole number >= 0, not -2"):
        pc.lab(seed=-2, progress=False)
    with pytest.raises(pc.ConfigError, match="replicates="):
        pc.lab(replicates=0, progress=False)


def test_the_spread_plot_shows_every_replicate_and_the_pick(run, tmp_path):
    """Read back from the figure: a dot per replicate that stayed up, a red
    cross per replicate that fell, dots coloured by the drawn quantity that
    orders the metric (named on the colour bar), the rule's pick starred."""
    from pupper_core import plots

    d = tmp_path / "falls"
    run("sweep", "--grid", "kp=0.8,1,30", "--grid", "kd=0.05", "--replicates", "8", "--seconds", "4",
        "--randomize", "torso_mass=±60%", "--randomize", "push_force=-150:-10", "-o", d, "-q", check=0)
    _, reps = read_csv(d / "replicates.csv")
    fell = sum(r["status"] != "ok" for r in reps)
    assert 0 < fell < len(reps), "the grid must hold both fallen and standing replicates"
    fig = plots.replicate_spread(d)
    ax = fig.axes[0]
    crosses = sum(len(line.get_xdata()) for line in ax.lines if line.get_marker() == "x")
    dots = sum(len(c.get_offsets()) for c in ax.collections if c.get_array() is not None)
    assert (crosses, dots) == (fell, len(reps) - fell)
    assert fig.axes[1].get_ylabel() in ("drawn torso_mass", "drawn push_force")
    ticks = [t.get_text() for t in ax.get_xticklabels()]
    starred = [t for t in ticks if t.startswith("★")]
    assert starred == ["★ kp30_kd0.05"], ticks
    summary = {r["id"]: r for r in read_csv(d / "summary.csv")[1]}
    for t in ticks:
        cid = t.lstrip("★ ").split("\n")[0]
        n_down = round(float(summary[cid]["failure_fraction"]) * 8)
        assert (f"{n_down}/8 fell" in t) == (n_down > 0), t
