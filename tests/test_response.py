"""`pupper response`: each joint's step and frequency response per gain
cell, checked against closed-form second-order values, between the CLI and
Python byte for byte, and on bad input."""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from conftest import REPO, assert_refused, read_csv

pc = pytest.importorskip("pupper_core")

HINGE = REPO / "tests" / "models" / "hinge1.xml"
#: The hinge's inertia (kg m^2) and the stiffness the grid runs at.
INERTIA, KP = 0.01, 1.0
WN = math.sqrt(KP / INERTIA)
ZETAS = (0.2, 0.7, 1.0, 2.0)
#: Kd for each damping ratio: 2 zeta sqrt(kp I).
KDS = [round(2 * z * math.sqrt(KP * INERTIA), 12) for z in ZETAS]
#: The hinge's timestep, 0.5 ms: wn dt = 0.005, so the discrete step of
#: the explicit PD differs from the continuous one by well under 0.1 %.
STEP_WINDOW = 6.0


def second_order_step(t: np.ndarray, zeta: float) -> np.ndarray:
    if zeta < 1:
        wd = WN * math.sqrt(1 - zeta * zeta)
        return 1 - np.exp(-zeta * WN * t) * (np.cos(wd * t) + zeta * WN / wd * np.sin(wd * t))
    if zeta == 1:
        return 1 - (1 + WN * t) * np.exp(-WN * t)
    r = math.sqrt(zeta * zeta - 1)
    s1, s2 = -WN * (zeta - r), -WN * (zeta + r)
    return 1 + (s2 * np.exp(s1 * t) - s1 * np.exp(s2 * t)) / (s1 - s2)


def analytic_figures(zeta: float) -> dict[str, float]:
    """The same definitions on the exact response, sampled at 1 us."""
    t = np.arange(0, STEP_WINDOW, 1e-6)
    y = second_order_step(t, zeta)
    rise = t[np.argmax(y >= 0.9)] - t[np.argmax(y >= 0.1)]
    outside = np.flatnonzero(np.abs(y - 1) > 0.02)
    settle = t[outside[-1] + 1]
    over = 100 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta * zeta)) if zeta < 1 else 0.0
    wb = WN * math.sqrt(1 - 2 * zeta**2 + math.sqrt(4 * zeta**4 - 4 * zeta**2 + 2))
    return {"rise": rise, "settle": settle, "over": over, "bw_hz": wb / (2 * math.pi)}


@pytest.fixture(scope="module")
def hinge_step(tmp_path_factory) -> dict[str, dict[str, str]]:
    d = tmp_path_factory.mktemp("hinge")
    res = pc.response({"kd": KDS}, model=str(HINGE), kp=KP, pose=[0.0], hold=0.05,
                      seconds=0.05 + STEP_WINDOW, out=d / "step", progress=False)
    rows = {r["kd"]: r for r in read_csv(d / "step" / "response.csv")[1]}
    assert res.tables["response"]["joint"] == ["swing"] * len(KDS)
    return rows


@pytest.mark.parametrize("zeta,kd", list(zip(ZETAS, KDS)))
def test_a_hinge_step_matches_the_second_order_closed_form(hinge_step, zeta, kd):
    row = hinge_step[f"{kd:g}"]
    want = analytic_figures(zeta)
    got = {k: float(row[c]) for k, c in
           (("rise", "rise_time_s"), ("settle", "settling_time_s"), ("over", "overshoot_pct"))}
    assert got["rise"] == pytest.approx(want["rise"], rel=0.02), (zeta, got, want)
    assert got["settle"] == pytest.approx(want["settle"], rel=0.02), (zeta, got, want)
    # overshoot within 2 % of its value, or 0.05 points where it is 0
    assert got["over"] == pytest.approx(want["over"], rel=0.02, abs=0.05), (zeta, got, want)
    assert abs(float(row["ss_error_pct"])) < 0.1 and row["status"] == "ok"


def gain_db(f: float, zeta: float) -> float:
    r = 2 * math.pi * f / WN
    return -10 * math.log10((1 - r * r) ** 2 + (2 * zeta * r) ** 2)


def bandwidth_from(f_ref: float, zeta: float) -> float:
    """Where the exact gain falls 3 dB below its value at f_ref (bisection)."""
    lo, hi, want = f_ref, 50.0, gain_db(f_ref, zeta) - 3
    for _ in range(100):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if gain_db(mid, zeta) > want else (lo, mid)
    return lo


def test_a_hinge_chirp_gives_the_second_order_bandwidth(tmp_path):
    res = pc.response({"kd": KDS}, model=str(HINGE), kp=KP, pose=[0.0], hold=0.05, signal="chirp",
                      chirp=(0.1, 8.0), amplitude=0.05, seconds=60.05, out=tmp_path / "chirp",
                      progress=False)
    rows = {r["kd"]: r for r in read_csv(tmp_path / "chirp" / "response.csv")[1]}
    bode = res.tables["bode"]
    f_ref = float(bode["hz"][0])  # the band's lowest point, the gain's reference
    for zeta, kd in zip(ZETAS, KDS):
        bw = float(rows[f"{kd:g}"]["bandwidth_hz"])
        # by its definition: 3 dB below the gain at the band's lowest point
        assert bw == pytest.approx(bandwidth_from(f_ref, zeta), rel=0.02), (zeta, bw)
        if zeta <= 1:
            # where the gain there is the DC gain, the textbook bandwidth
            assert bw == pytest.approx(analytic_figures(zeta)["bw_hz"], rel=0.02), (zeta, bw)
    # the light damping peaks: 1 / (2 zeta sqrt(1 - zeta^2)) = 8.1 dB at 0.2
    peak = float(rows[f"{KDS[0]:g}"]["resonance_db"])
    assert peak == pytest.approx(20 * math.log10(1 / (2 * 0.2 * math.sqrt(1 - 0.04))), abs=0.5)
    assert len(bode) == len(KDS) * 24 and set(bode.header) >= {"hz", "gain_db", "phase_deg"}


def test_pupper_response_prints_a_table_per_joint_group(run, tmp_path):
    p = run("response", "--grid", "kp=5,20,60", "--grid", "kd=0.1,0.5,2", "-o", tmp_path / "r", "-q",
            check=0)
    blocks = [b for b in p.stdout.strip().split("\n\n") if b]
    titles = [b.splitlines()[0].split()[0] for b in blocks]
    assert titles == ["haa", "hfe", "kfe"], p.stdout
    for b in blocks:
        assert len(b.splitlines()) == 2 + 9, b
        assert "rise_time_s" in b.splitlines()[1]
    header, rows = read_csv(tmp_path / "r" / "response.csv")
    assert len(rows) == 9 * 12
    # the groups follow what each joint does: on Pupper v3 the _1 joints pitch the hip
    groups = {r["joint"]: r["group"] for r in rows}
    assert groups["leg_front_r_1"] == "hfe" and groups["leg_front_r_2"] == "haa"
    assert groups["leg_front_r_3"] == "kfe"
    # a stiffer, damped cell rises faster than a soft one, every joint
    by = {(r["kp"], r["kd"], r["joint"]): float(r["rise_time_s"]) for r in rows}
    assert all(by[("60", "2", j)] < by[("5", "0.5", j)] for j in groups)


def test_python_and_the_cli_write_the_same_bytes(run, tmp_path):
    args = ["--grid", "kp=10,30", "--kd", "0.5", "--joints", "hfe,leg_back_l_3", "--seconds", "1.5"]
    run("response", *args, "-o", tmp_path / "cli", "-q", check=0)
    pc.response({"kp": [10, 30]}, kd=0.5, joints="hfe,leg_back_l_3", seconds=1.5,
                out=tmp_path / "py", progress=False)
    for name in ("summary.csv", "response.csv"):
        assert (tmp_path / "cli" / name).read_bytes() == (tmp_path / "py" / name).read_bytes(), name
    _, rows = read_csv(tmp_path / "cli" / "response.csv")
    assert sorted({r["joint"] for r in rows}) == sorted(
        ["leg_front_r_1", "leg_front_l_1", "leg_back_r_1", "leg_back_l_1", "leg_back_l_3"])


def test_a_sine_reads_gain_and_phase_and_threads_never_change_the_bytes(run, tmp_path):
    args = ["--signal", "sine", "--frequency", "4", "--amplitude", "0.1", "--joints", "kfe",
            "--grid", "kp=5,20", "--kd", "0.2", "--seconds", "2"]
    run("response", *args, "-j", "1", "-o", tmp_path / "a", "-q", check=0)
    run("response", *args, "-j", "2", "--chunk-cells", "1", "-o", tmp_path / "b", "-q", check=0)
    for name in ("summary.csv", "response.csv", "bode.csv"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    _, rows = read_csv(tmp_path / "a" / "bode.csv")
    assert len(rows) == 2 * 4 and {r["hz"] for r in rows} == {"4"}
    gains = {r["index"]: float(r["gain_db"]) for r in rows}
    # 4 Hz lies past a soft joint's corner and below a stiff one's
    assert gains["0"] < gains["1"] < 3


BAD = [
    (["--amplitude", "-0.1"], "not positive"),
    (["--joints", "nope"], "no actuator or joint group"),
    (["--signal", "chirp", "--chirp", "1,300", "--seconds", "10"], "Nyquist"),
    (["--signal", "sine", "--frequency", "0.5", "--seconds", "2"], "periods"),
    (["--seconds", "0.6"], "too short to settle"),
    (["--amplitude", "3"], "outside its range"),
    (["--signal", "ramp"], "unknown"),
]


@pytest.mark.parametrize("args,words", BAD, ids=[w for _, w in BAD])
def test_bad_input_is_one_line_exit_2_and_nothing_written(run, tmp_path, args, words):
    out = tmp_path / "never"
    p = run("response", *args, "-o", out)
    assert_refused(p, words, out)


def test_resume_after_a_kill_gives_the_uninterrupted_bytes(pupper_bin, tmp_path):
    import signal

    from conftest import clean_env, wait_rows

    args = [str(pupper_bin), "response", "--grid", "kp=4:40:6", "--grid", "kd=0.1,0.5", "--seconds", "1.5",
            "--chunk-cells", "1", "-j", "1", "-q"]
    subprocess.run([*args, "-o", str(tmp_path / "whole")], check=True, env=clean_env(), cwd=tmp_path,
                   capture_output=True, timeout=600)
    proc = subprocess.Popen([*args, "-o", str(tmp_path / "cut")], env=clean_env(), cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    summary = tmp_path / "cut" / "summary.csv"
    wait_rows(summary, proc, 2)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    kept = len(summary.read_text().splitlines()) - 1
    assert 0 < kept < 12, kept
    subprocess.run([str(pupper_bin), "response", "--resume", str(tmp_path / "cut"), "-q"], check=True,
                   env=clean_env(), cwd=tmp_path, capture_output=True, timeout=600)
    for name in ("summary.csv", "response.csv"):
        assert (tmp_path / "cut" / name).read_bytes() == (tmp_path / "whole" / name).read_bytes(), name


def test_the_stability_bound_parts_a_chattering_cell_from_a_quiet_one(tmp_path):
    """On the hinge (I 0.01, dt 0.5 ms) at kp 1000 the explicit PD's bound
    falls at kd = 39.75: a cell just inside it settles, one just past it
    chatters at the torque limit; the column and the note say which."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pc.response({"kd": [38, 42]}, model=str(HINGE), kp=1000, pose=[0.0], hold=0.05, amplitude=0.05,
                    seconds=0.6, out=tmp_path / "edge", progress=False)
    rows = {r["kd"]: r for r in read_csv(tmp_path / "edge" / "response.csv")[1]}
    inside, past = rows["38"], rows["42"]
    assert float(inside["stability_margin"]) == pytest.approx(0.25 * (0.025 + 2 * 1.9), rel=1e-6)
    assert float(past["stability_margin"]) > 1
    assert inside["status"] == "ok" and float(inside["saturation_frac"]) < 0.01
    # past the bound: marked, never the best, and chattering at the limit
    assert past["status"] == "past_bound" and float(past["saturation_frac"]) > 0.05, past
    notes = [str(w.message) for w in caught]
    assert any("1 cell(s) lie past the stability bound" in n and "kd42" in n for n in notes), notes


def test_gains_for_a_bandwidth_follow_the_closed_form_and_respond_as_asked(run, tmp_path):
    """`pupper gains --bandwidth 8 --damping 0.7` on Pupper v3: kp = I wn^2,
    kd = 2 zeta I wn per group; the response at those gains overshoots as a
    second-order system of that damping would, within 5 points, and its
    bandwidth is within 25 % of 8 Hz, per group."""
    import json

    p = run("gains", "--bandwidth", "8", "--damping", "0.7", "--json", check=0)
    report = json.loads(p.stdout)
    wn = 2 * math.pi * 8 / math.sqrt(1 - 2 * 0.49 + math.sqrt(4 * 0.49**2 - 4 * 0.49 + 2))
    for g in report["groups"]:
        assert g["kp"] == pytest.approx(g["inertia"] * wn**2, rel=1e-9)
        assert g["kd"] == pytest.approx(2 * 0.7 * g["inertia"] * wn, rel=1e-9)
        assert g["stability_margin"] < 1
        step = pc.response(None, joints=g["group"], kp=g["kp"], kd=g["kd"], amplitude=0.1, progress=False,
                           out=tmp_path / f"step-{g['group']}")
        over = float(step[f"overshoot_pct.{g['group']}"][0])
        assert abs(over - 100 * math.exp(-0.7 * math.pi / math.sqrt(1 - 0.49))) < 5, (g["group"], over)
        chirp = pc.response(None, joints=g["group"], kp=g["kp"], kd=g["kd"], amplitude=0.05, signal="chirp",
                            chirp=(0.5, 40), seconds=12.5, progress=False, out=tmp_path / f"chirp-{g['group']}")
        bw = float(chirp[f"bandwidth_hz.{g['group']}"][0])
        assert bw == pytest.approx(8, rel=0.25), (g["group"], bw)


def test_gains_per_joint_group_are_grid_axes(run, tmp_path):
    """kp.hfe overrides the common kp for the hip-pitch joints only."""
    run("response", "--grid", "kp.hfe=10,40", "--kp", "20", "--kd", "0.5", "--joints", "hfe,kfe",
        "--seconds", "1.5", "-o", tmp_path / "g", "-q", check=0)
    header, rows = read_csv(tmp_path / "g" / "response.csv")
    assert "kp.hfe" in header
    rise = {(r["kp.hfe"], r["group"], r["joint"]): float(r["rise_time_s"]) for r in rows}
    for (kp, group, joint), t in rise.items():
        other = rise[("40" if kp == "10" else "10", group, joint)]
        if group == "hfe":
            assert (t > 1.2 * other) == (kp == "10"), (joint, t, other)
        else:
            # the knees keep kp 20; only the hips' sag under them differs
            assert t == pytest.approx(other, rel=0.01), (joint, t, other)
    ids = [r["id"] for r in read_csv(tmp_path / "g" / "summary.csv")[1]]
    assert ids == ["kphfe10", "kphfe40"]
    # `info` names each actuator's group
    info = run("info", check=0).stdout
    assert any(line.split()[1:4] == ["leg_front_r_2", "leg_front_r_2", "haa"] for line in info.splitlines()
               if line.strip().startswith("1 ")), info


def test_response_plots_read_back(run, tmp_path):
    from pupper_core import plots

    d = tmp_path / "p"
    run("response", "--grid", "kp=5,30", "--grid", "kd=0.1,0.5", "--joints", "hfe,kfe", "--seconds", "1.5",
        "--plot", "-o", d, "-q", check=0)
    names = sorted(p.name for p in (d / "plots").iterdir())
    assert names == ["response_overshoot_pct.png", "response_rise_time_s.png", "response_settling_time_s.png",
                     "response_steps.png"], names
    fig = plots.response_steps(d)
    assert [a.get_title() for a in fig.axes if a.get_title()] == ["hip pitch (hfe)", "knee (kfe)"]
    ax = fig.axes[0]
    curves = [line for line in ax.lines if line.get_label() in fig.pupper_cells]
    assert len(curves) == 4
    # every cell ends near its target, normalised by the step
    assert all(abs(line.get_ydata()[-1] - 1) < 0.1 for line in curves)
    assert any(line.get_linestyle() == "--" and line.get_ydata()[0] == 1 for line in ax.lines)


def test_standing_runs_the_same_excitation_on_the_floor(run, tmp_path):
    import json

    run("response", "--standing", "--joints", "kfe", "--kp", "20", "--kd", "0.5", "--seconds", "2",
        "-o", tmp_path / "s", "-q", check=0)
    manifest = json.loads((tmp_path / "s" / "manifest.json").read_text())
    assert manifest["config"]["response"]["standing"] is True
    _, rows = read_csv(tmp_path / "s" / "response.csv")
    assert len(rows) == 4 and all(r["status"] == "ok" for r in rows)
    # the suspended knee follows faster than one carrying the body
    run("response", "--joints", "kfe", "--kp", "20", "--kd", "0.5", "--seconds", "2", "-o", tmp_path / "h", "-q",
        check=0)
    _, hung = read_csv(tmp_path / "h" / "response.csv")
    assert [r["rise_time_s"] for r in rows] != [r["rise_time_s"] for r in hung]


def test_shards_merge_into_the_unsharded_bytes(run, tmp_path):
    args = ["response", "--grid", "kp=5,20,60", "--kd", "0.5", "--joints", "hfe", "--signal", "sine",
            "--frequency", "3", "--amplitude", "0.1", "--seconds", "2", "-q"]
    run(*args, "-o", tmp_path / "whole", check=0)
    for i in (1, 2):
        run(*args, "--shard", f"{i}/2", "-o", tmp_path / f"s{i}", check=0)
    run("merge", tmp_path / "s1", tmp_path / "s2", "-o", tmp_path / "merged", check=0)
    for name in ("summary.csv", "response.csv", "bode.csv"):
        assert (tmp_path / "merged" / name).read_bytes() == (tmp_path / "whole" / name).read_bytes(), name


def test_replicates_draw_each_joint_its_own_robot(run, tmp_path):
    run("response", "--kp", "20", "--kd", "0.5", "--joints", "kfe", "--seconds", "1.5", "--replicates", "3",
        "--randomize", "motor_gain=±20%", "-o", tmp_path / "r", "-q", check=0)
    _, rows = read_csv(tmp_path / "r" / "response.csv")
    assert len(rows) == 4 * 3
    by_joint: dict[str, list[float]] = {}
    for r in rows:
        by_joint.setdefault(r["joint"], []).append(float(r["rise_time_s"]))
    # each replicate's motor gain differs: so does its rise time
    assert all(len(set(v)) == 3 for v in by_joint.values()), by_joint


def test_trace_writes_the_joints_and_no_header_only_file_and_noise_is_zero(run, tmp_path):
    """--trace on a response keeps the joints' angles (response_traces.csv)
    and writes no traces.csv (the base hangs: it would hold its header
    alone); an overshoot below the simulation's resolution prints as 0
    while summary.csv keeps its digits."""
    d = tmp_path / "t"
    p = run("response", "--joints", "kfe", "--grid", "kp=5,20", "--kd", "0.5", "--trace",
            "-o", d, "-q", check=0)
    assert not (d / "traces.csv").exists()
    _, traces = read_csv(d / "response_traces.csv")
    assert {r["id"] for r in traces} == {"kp5", "kp20"}
    _, rows = read_csv(d / "summary.csv")
    noise = next(r for r in rows if r["id"] == "kp20")
    assert 0 < float(noise["overshoot_pct.kfe"]) < 1e-6, noise
    # kp, rise, settling, overshoot, ...
    line = next(ln for ln in p.stdout.splitlines() if ln.split()[:1] == ["20"])
    assert line.split()[3] == "0", line
    kept = next(ln for ln in p.stdout.splitlines() if ln.split()[:1] == ["5"])
    assert float(kept.split()[3]) == pytest.approx(float(rows[0]["overshoot_pct.kfe"]), rel=1e-2), kept
    # read back whole (a traced response once loaded with no rows: its
    # cells were looked for in a traces.csv it has no reason to hold)
    res = pc.load_run(d)
    assert res.complete and res.ids == ["kp5", "kp20"]
    want = min(rows, key=lambda r: float(r["settling_time_s.kfe"]))
    assert res.best("settling_time_s.kfe")["id"] == want["id"]
