"""The motor model of torque mode (`--motor`): the servo firmware's PD rate
with a held torque, a filter on the derivative, encoder quantisation, a
command delay and a torque-speed limit, all on real MuJoCo."""

from __future__ import annotations

import json
import math
import warnings

import pupper_core as pc
import pytest

from conftest import REPO, assert_refused, read_csv, same_files

GRID = {"kp": [30, 120], "kd": [0.5, 5]}


def sweep(**kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the Kd 5 cells' stability-bound warning
        return pc.sweep(GRID, mode="torque", seconds=4, progress=False, **kw)


def by_id(res) -> dict[str, dict]:
    return {r["id"]: r for r in (res.row(i) for i in range(len(res.rows)))}


def test_the_ideal_motor_at_the_physics_rate_is_todays_torque_mode(run, tmp_path):
    # 500 Hz on the 2 ms step, no filter, delay, quantisation or speed limit
    assert sweep(motor="rate=500").rows == sweep().rows
    # with noise and a sensing delay drawn too (the same draws, the same reads)
    kw = dict(replicates=2, seed=3, randomize=["q_noise=N(0,0.002)", "delay=0:2"])
    assert sweep(motor="rate=500", **kw).rows == sweep(**kw).rows
    # and through the CLI, whose manifest leaves the ideal motor out
    args = ["sweep", "-g", "kp=30,120", "-g", "kd=0.5,5", "--mode", "torque", "--seconds", "3", "-q"]
    run(*args, "-o", tmp_path / "a", check=0)
    run(*args, "--motor", "rate=500", "-o", tmp_path / "b", check=0)
    run(*args, "--motor", "ideal", "-o", tmp_path / "c", check=0)
    same_files(tmp_path / "b", tmp_path / "a")
    same_files(tmp_path / "c", tmp_path / "a")
    m = json.loads((tmp_path / "b" / "manifest.json").read_text())
    assert m["config"]["motor"] == {"rate": 500.0}
    assert "motor" not in json.loads((tmp_path / "c" / "manifest.json").read_text())["config"]


def test_the_chattering_kd5_cells_follow_the_filter_and_the_rate():
    """At Kd 5 the knee is past the explicit PD's stability bound (h kd / I =
    5.5 > 2): the ideal motor chatters at the torque limit. A derivative
    filter well below the step's Nyquist rate takes the gain out of the
    frequencies that chatter; a slower firmware (a longer hold) makes it
    worse; a command delay does nothing to a robot whose targets stand still.
    A firmware with a filter or a slower rate closes another loop than the PD
    at the physics step, for which pupper states no bound: its cells keep the
    status the simulation gives them."""
    ideal = by_id(sweep())
    for cell in ("kp30_kd5", "kp120_kd5"):
        # past the bound of the PD at the physics step, and chattering
        assert ideal[cell]["status"] == "past_bound", ideal[cell]
        assert ideal[cell]["saturation_frac"] >= 0.05, ideal[cell]
    calm = by_id(sweep(motor="filter=50"))
    slow = by_id(sweep(motor="rate=250"))
    for cell in ("kp30_kd5", "kp120_kd5"):
        assert calm[cell]["status"] == "ok"
        assert calm[cell]["last_1s_std_mm"] < 0.05 * ideal[cell]["last_1s_std_mm"]
        assert slow[cell]["status"] == "saturated"
        assert slow[cell]["last_1s_std_mm"] > 2 * ideal[cell]["last_1s_std_mm"]
    # the Kd 0.5 cells stand well in all three
    for res in (ideal, calm, slow):
        for cell in ("kp30_kd0.5", "kp120_kd0.5"):
            assert res[cell]["status"] == "ok"
    assert sweep(motor="delay=0.01").rows == sweep().rows


def test_quantisation_and_speed_limit_change_what_they_touch():
    coarse = by_id(sweep(motor="counts=4096"))
    ideal = by_id(sweep())
    # a 1.5 mrad encoder step shows as limit-cycle jitter on a stiff stance
    assert coarse["kp120_kd0.5"]["last_1s_std_mm"] > 5 * ideal["kp120_kd0.5"]["last_1s_std_mm"]
    # a slow motor cannot push as hard into the motion: the landing's peak
    # torque (taken after it) and the chatter are bounded by the band
    slow = by_id(sweep(motor="noload=5"))
    assert slow["kp30_kd0.5"]["final_z"] == pytest.approx(ideal["kp30_kd0.5"]["final_z"], abs=2e-3)
    assert slow["kp30_kd5"]["peak_torque"] <= ideal["kp30_kd5"]["peak_torque"] + 1e-9


def test_response_sees_the_command_delay():
    """A step target reaches the servo `delay` later: the rise starts that
    much later, while the shape of the response is the same."""
    kw = dict(grid={"kp": [8], "kd": [0.2]}, signal="step", amplitude=0.2, seconds=1.5,
              mode="torque", joints=["leg_front_r_2"], progress=False)
    a = pc.response(**kw).tables["response"]
    b = pc.response(motor="delay=0.02", **kw).tables["response"]
    assert b["peak_time_s"][0] == pytest.approx(a["peak_time_s"][0] + 0.02, abs=1e-9)
    assert b["rise_time_s"][0] == pytest.approx(a["rise_time_s"][0], rel=1e-4)
    assert b["overshoot_pct"][0] == pytest.approx(a["overshoot_pct"][0], abs=0.05)


def test_a_torque_lag_costs_the_loop_its_phase():
    """A current loop's first-order lag sits inside the servo loop (unlike
    a command delay, which only moves the response later): the lag holds
    back the damping torque as much as the drive, so a step overshoots
    more, the more so the longer the lag (kp 8, kd 0.2 on the front right
    thigh: 1.7 % without, about 6 % at 8 ms and 25 % at 16 ms)."""
    kw = dict(grid={"kp": [8], "kd": [0.2]}, signal="step", amplitude=0.2, seconds=1.5,
              mode="torque", joints=["leg_front_r_2"], progress=False)
    over = [pc.response(motor=m, **kw).tables["response"]["overshoot_pct"][0]
            for m in ("rate=500", "lag=0.008", "lag=0.016")]
    assert over[0] + 3 < over[1] < over[2] - 10, over
    # a lag closes another loop than the PD at the physics step: no explicit-PD bound is stated for it
    lagged = by_id(sweep(motor="lag=0.004"))
    assert all(r["status"] != "past_bound" for r in lagged.values()), lagged


@pytest.mark.parametrize(
    "args, words",
    [
        (["--motor", "rate=500"], "--mode torque"),
        (["--mode", "torque", "--motor", "rate=1000"], "faster than the physics"),
        (["--mode", "torque", "--motor", "filtr=10"], "did you mean 'filter'"),
        (["--mode", "torque", "--motor", "delay=-0.1"], ">= 0"),
        (["--mode", "torque", "--motor", "counts=1.5"], "whole number"),
        # lag=0 is no lag (issue 61, item 8); 10, 10 ms typed bare, is refused
        (["--mode", "torque", "--motor", "lag=10"], "write lag=0.01"),
    ],
)
def test_a_bad_motor_is_one_line_and_writes_nothing(run, tmp_path, args, words):
    out = tmp_path / "run"
    p = run("sweep", "-g", "kp=30", "--seconds", "1", "-q", "-o", out, *args, check=2)
    assert_refused(p, words, out)


def test_the_manifest_keeps_the_motor_and_a_resume_matches_it(run, tmp_path):
    out = tmp_path / "run"
    args = ["sweep", "-g", "kp=30,120", "--mode", "torque", "--seconds", "2", "-q",
            "--motor", "rate=250,filter=100,counts=16384,delay=0.004,noload=30"]
    run(*args, "-o", out, check=0)
    _, rows = read_csv(out / "summary.csv")
    assert len(rows) == 2
    m = json.loads((out / "manifest.json").read_text())["config"]["motor"]
    assert m == {"rate": 250.0, "filter": 100.0, "counts": 16384, "delay": 0.004, "noload": 30.0}
    # a resume with another motor is refused: it would give other numbers
    p = run(*args[:-1], "filter=100", "--resume", out, check=2)
    assert "motor" in p.stderr


def test_replicates_draw_the_motor():
    """motor_delay, motor_filter and motor_noload are drawn per replicate
    (torque mode), recorded in the replicates table, and each replicate runs
    its own firmware: a replicate drawn with the filter that calms the Kd 5
    chatter stands steadier than the ideal motor."""
    kw = dict(replicates=4, seed=2, randomize=["motor_filter=30:60", "motor_delay=0:0.01"])
    res = sweep(**kw)
    reps = res.tables["replicates"]
    filters = [float(v) for v in reps["motor_filter"]]
    delays = [float(v) for v in reps["motor_delay"]]
    assert all(30 <= f <= 60 for f in filters) and len(set(filters)) == len(filters)
    assert all(0 <= d <= 0.01 for d in delays)
    ideal = by_id(sweep())
    kd5 = [i for i, c in enumerate(reps["id"]) if c == "kp120_kd5"]
    for i in kd5:
        assert float(reps["last_1s_std_mm"][i]) < 0.1 * ideal["kp120_kd5"]["last_1s_std_mm"]
    # the same draws give the same table; another seed other robots
    assert sweep(**kw).rows == res.rows
    assert sweep(**{**kw, "seed": 3}).rows != res.rows
    with pytest.raises(pc.ConfigError, match="torque: it acts on the motor model"):
        pc.sweep(GRID, seconds=1, randomize=["motor_delay=0:0.01"], progress=False)


def test_replicates_draw_the_torque_lag():
    """motor_lag is drawn per replicate like the command delay: each
    replicate is the robot that `--motor lag=` at its drawn value is, to the
    byte; a drawn 0 is the robot without a lag. With a lag drawn the
    explicit-PD bound is not stated (another loop than the PD's)."""
    kw = dict(mode="torque", seconds=3, push_at=1, progress=False)
    res = pc.sweep({"kp": [30], "kd": [0.5]}, replicates=3, seed=5, randomize=["motor_lag=0:0.02"], **kw)
    reps = res.tables["replicates"]
    lags = [float(v) for v in reps["motor_lag"]]
    assert all(0 <= t <= 0.02 for t in lags) and len(set(lags)) == 3
    metrics = [h for h in res.tables["replicates"].header if h.endswith(("_mm", "_s", "_frac"))]
    for i, t in enumerate(lags):
        one = pc.sweep({"kp": [30], "kd": [0.5]}, motor=f"lag={t!r}", **kw).row(0)
        assert [reps[m][i] for m in metrics] == [one[m] for m in metrics], (t, metrics)
    zero = pc.sweep({"kp": [30], "kd": [0.5]}, replicates=1, randomize=["motor_lag=0:0"], **kw)
    plain = pc.sweep({"kp": [30], "kd": [0.5]}, **kw).row(0)
    assert [zero.tables["replicates"][m][0] for m in metrics] == [plain[m] for m in metrics]
    with pytest.raises(pc.ConfigError, match="motor_lag"):
        pc.sweep({"kp": [30], "kd": [0.5]}, randomize=["motor_lag=-0.01:0.01"], **kw)
    # kd 5 is past the bound of the ideal motor's PD; with a lag drawn no bound is stated
    kd5 = {"kp": [120], "kd": [5]}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert pc.sweep(kd5, **kw).row(0)["status"] == "past_bound"
    lagged = pc.sweep(kd5, replicates=1, randomize=["motor_lag=0.001:0.002"], **kw)
    assert lagged.tables["replicates"]["status"][0] != "past_bound"


def test_the_lab_runs_through_the_motor(run, tmp_path):
    """`pupper lab --motor` (the lab is torque mode): the filter that calms
    the chattering Kd 5 cells does so in every body, CLI and Python alike."""
    args = ["--grid", "kp=60", "--grid", "kd=5", "--seconds", "3", "-q"]
    run("lab", *args, "-o", tmp_path / "ideal", check=0)
    run("lab", *args, "--motor", "filter=50", "-o", tmp_path / "calm", check=0)
    _, ideal = read_csv(tmp_path / "ideal" / "summary.csv")
    _, calm = read_csv(tmp_path / "calm" / "summary.csv")
    for a, b in zip(ideal, calm):
        # the sine force still moves the body: the chatter on top of it is what goes
        assert float(b["last_1s_std_mm"]) < 0.5 * float(a["last_1s_std_mm"]), (a["id"], a, b)
    res = pc.lab(grid=["kp=60", "kd=5"], seconds=3, motor="filter=50", progress=False)
    col = res.header.index("last_1s_std_mm")
    assert [r[col] for r in res.rows] == [r["last_1s_std_mm"] for r in calm]


def test_a_lag_longer_than_kd_over_kp_has_no_gain_that_is_stable(run):
    """Past −180° from the lowest frequency (an undamped joint whose kd/kp,
    12.5 ms here, is shorter than a 16 ms lag and 2 ms of latency), no
    common gain makes the loop stable: the gain margin is −inf, not the
    +inf of a loop whose phase never reaches −180° (which it read before),
    and recommend's margins (loop_margins) fail it on both counts."""
    from pupper_core._native import loop_margins

    pm, gm = loop_margins(3.166e-2, 40.0, 0.5, motor="lag=0.016", sensing_delay=0.002, timestep=0.002)
    assert pm < 0 and gm == float("-inf"), (pm, gm)
    pm, gm = loop_margins(3.166e-2, 40.0, 1.0, motor="lag=0.016", sensing_delay=0.002, timestep=0.002)
    assert math.isfinite(gm), (pm, gm)
    out = run("gains", "--model", REPO / "tests" / "models" / "trotter15.xml", "--kp", "40", "--kd", "0.5", "--motor", "lag=0.016",
              check=0).stdout
    haa = next(line for line in out.splitlines() if line.startswith("haa"))
    assert haa.split()[-2:] == ["UNST", "-inf"], haa
