"""`pupper fit` on logs as a robot writes them (issue 38): one motor on a
test stand, the other joints held and not logged, the control loop's own
jittered time stamps from an arbitrary start, its own column names through
a column map, and `pupper excite --joints --rate` for such a stand.

The stand is examples/stand_log.py: a plain MuJoCo loop, not pupper's code."""

from __future__ import annotations

import json
import math
import re
import sys
from pathlib import Path

import numpy as np
import pupper_core as pc
import pytest

from conftest import REPO, read_csv

sys.path.insert(0, str(REPO / "examples"))
from stand_log import COLUMNS, MOTOR, PLAIN, TRUTH, stand_log  # noqa: E402

pytest.importorskip("scipy", reason="the fit extra (make test installs it)")


@pytest.fixture(scope="module")
def bench(tmp_path_factory) -> dict[str, Path]:
    """The stand's logs at kp 5, kd 0.1 and 0.3 (as its loop writes them)."""
    d = tmp_path_factory.mktemp("bench")
    return {kd: stand_log(d / f"stand_kd{kd}.csv", kp=5.0, kd=kd, seed=s) for kd, s in ((0.1, 0), (0.3, 1))}


#: the stand's own model: the default parameters and the servo's torque lag
LAGGED = "armature,damping,frictionloss,kp_scale,kd_scale,delay,lag"


def one_line(p, *words: str) -> str:
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and all(w in lines[0] for w in words), p.stderr
    assert lines[0].startswith("error: ") and "internal error" not in lines[0], p.stderr
    return lines[0]


def test_the_stand_log_is_as_a_ros_loop_writes_it(bench):
    """What the fit is given: no header lines, the robot's names, time
    stamps from 1.7e9 s, 4 ms apart give or take up to 3.3 ms."""
    text = bench[0.1].read_text().splitlines()
    assert text[0].startswith("fr_knee_cmd,") and text[0].endswith(",stamp")
    stamps = np.array([float(r.rsplit(",", 1)[1]) for r in text[1:]])
    gaps = np.diff(stamps)
    assert stamps[0] > 1e9 and 0.0035 < gaps.mean() < 0.0045
    assert gaps.min() < 0.0025 and gaps.max() > 0.0055 and gaps.min() > 0


def test_a_bench_log_fits_without_editing_the_file(bench, tmp_path, run):
    """One motor, the others held: only it is fitted, and the fit finds the
    stand's motor (its gains, delay and torque lag as the hardware has
    them) from logs replayed as the loop took them (rows evenly, the
    velocity a few ms late), each said."""
    out = tmp_path / "fit"
    p = run("fit", bench[0.1], bench[0.3], "--columns", COLUMNS, "--params", LAGGED, "-o", out, check=0)
    assert "mean over 1 joint)" in p.stdout, p.stdout
    assert p.stderr.count("replayed evenly spaced") == 1 and p.stderr.count("velocity runs") == 1, p.stderr
    assert "stand_kd0.1.csv and stand_kd0.3.csv: the angles change smoothly" in p.stderr, p.stderr
    _, rows = read_csv(out / "fit.csv")
    v = {r["parameter"]: float(r["fitted"]) for r in rows}
    assert all(math.isfinite(float(r[k])) for r in rows for k in ("fitted", "low95", "high95")), rows
    assert v["kp_scale"] == pytest.approx(TRUTH["kp_scale"], rel=0.02)
    assert v["kd_scale"] == pytest.approx(TRUTH["kd_scale"], rel=0.05)
    assert v["armature"] == pytest.approx(TRUTH["armature"], rel=0.10)
    assert v["frictionloss"] == pytest.approx(TRUTH["frictionloss"], rel=0.20)
    assert abs(v["delay"] - TRUTH["delay"]) < 0.001 and abs(v["lag"] - TRUTH["lag"]) < 0.001, v
    _, resid = read_csv(out / "residuals.csv")
    assert [r["actuator"] for r in resid] == [MOTOR, MOTOR]
    for r in resid:
        # from a tenth of a radian to near the encoder's noise (1 mrad)
        assert float(r["rms_before_rad"]) > 0.05 and float(r["rms_after_rad"]) < 0.003, r


def test_a_held_joints_constant_column_is_said_not_nan(tmp_path):
    """The stand logs the held hip too, as a constant: it is said and left
    out, every number of the fit finite."""
    log = stand_log(tmp_path / "held.csv", kp=5.0, kd=0.1, seed=2, held_columns=True)
    cols = (COLUMNS.replace(f",{MOTOR}.kp=fr_knee_kp,{MOTOR}.kd=fr_knee_kd", "")
            + ",leg_front_r_1.target=fr_hip_cmd,leg_front_r_1.q=fr_hip_pos,leg_front_r_1.qd=fr_hip_vel")
    res = pc.fit(log, columns=cols, kp=5, kd=0.1, params="kp_scale,delay", max_iters=10, progress=False)
    assert any("leg_front_r_1 never moves" in w and "left out" in w for w in res.warnings), res.warnings
    assert res.actuators == [MOTOR]
    assert all(math.isfinite(r[k]) for r in res.table for k in ("fitted", "low95", "high95")), res.table


def test_a_header_line_map_and_the_flag_read_the_same(bench, tmp_path):
    """The map as a `# columns:` line (with the gains) or as --columns (the
    gains from their columns) reads the same numbers; declared degrees and
    milliseconds are converted."""
    from pupper_core._fit import load_robot
    from pupper_core._fit.log import read_log
    from pupper_core._fit.columns import read_map

    ranges = load_robot("pupper_v3").ranges
    flag = read_log(bench[0.1], ranges, columns=read_map(COLUMNS))
    lines = bench[0.1].read_text().splitlines()
    header = lines[0].split(",")
    k_pos, k_cmd, k_t = header.index("fr_knee_pos"), header.index("fr_knee_cmd"), header.index("stamp")
    rows = []
    for ln in lines[1:]:
        f = ln.split(",")
        f[k_pos] = repr(math.degrees(float(f[k_pos])))
        f[k_cmd] = repr(math.degrees(float(f[k_cmd])))
        f[k_t] = repr(float(f[k_t]) * 1000)
        rows.append(",".join(f))
    own = tmp_path / "own.csv"
    own.write_text("\n".join([
        "# kp: 5", "# kd: 0.1",
        f"# columns: time=stamp:ms, {MOTOR}.target=fr_knee_cmd:deg, {MOTOR}.q=fr_knee_pos:deg, "
        f"{MOTOR}.qd=fr_knee_vel", lines[0], *rows]) + "\n")
    got = read_log(own, ranges)
    assert got.actuators == flag.actuators == [MOTOR]
    assert np.allclose(got.q, flag.q, atol=1e-12) and np.allclose(got.target, flag.target, atol=1e-12)
    assert np.allclose(got.times - got.times[0], flag.times - flag.times[0], atol=1e-6)
    assert float(got.kp[0]) == float(flag.kp[0]) == 5.0 and float(flag.kd[0]) == 0.1


def _write_rows(path: Path, lines: list[str]) -> Path:
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("edit, args, words", [
    # a stamp that goes back: the row and the log's own column are named
    (lambda ls: ls[:40] + [ls[41], ls[40]] + ls[42:], [], ("bad.csv, column 'stamp', row 42", "time goes back")),
    (lambda ls: ls, ["--columns", COLUMNS.replace("fr_knee_pos", "fr_knee_angle")],
     ("bad.csv", "'leg_front_r_3.q=fr_knee_angle' names no column of the log", "fr_knee_cmd")),
    (lambda ls: ls, ["--columns", COLUMNS + ",leg_front_r_3.q=x"], ("'leg_front_r_3.q' is mapped twice",)),
    (lambda ls: ls, ["--columns", COLUMNS.replace("fr_knee_pos", "fr_knee_pos:grad")],
     ("unit 'grad' is not one of rad, deg",)),
    (lambda ls: ls, ["--columns", COLUMNS.replace("leg_front_r_3.q", "leg_front_r_3.angle")],
     ("'leg_front_r_3.angle' is not time or ACTUATOR.FIELD",)),
    (lambda ls: ls, ["--columns", COLUMNS.replace("time=stamp,", "")], ("bad.csv", "has no 'time' column", "--columns time=")),
    (lambda ls: [ls[0]] + [",".join(r.split(",")[:1] + ["7.5"] + r.split(",")[2:]) if i == 99 else r
                           for i, r in enumerate(ls[1:])],
     [], ("bad.csv, column 'fr_knee_kp'", "kp changes during the log", "split the log")),
    (lambda ls: ["# kp: 4"] + ls, [], ("bad.csv", "the kp columns", "'# kp: 4' disagree")),
    (lambda ls: ls, ["--columns", COLUMNS, "--held", "leg_front_r_3=0.2"], ("bad.csv: --held", "leg_front_r_3 is in the log")),
])
def test_a_robot_log_that_cannot_be_read_is_one_line(bench, tmp_path, run, edit, args, words):
    lines = edit(bench[0.1].read_text().splitlines())
    bad = _write_rows(tmp_path / "bad.csv", lines)
    p = run("fit", bad, *(args or ["--columns", COLUMNS]), "--params", "delay", "--max-iters", "1",
            "-o", tmp_path / "out", check=2)
    one_line(p, *words)
    assert not (tmp_path / "out").exists()


def test_held_and_the_gains_flags_fill_what_a_log_does_not_say(bench, tmp_path):
    """--held sets what the joints the log does not cover hold (the
    thigh's angle loads the knee differently), --kp/--kd the gains of a log
    without them."""
    from pupper_core._fit import load_robot
    from pupper_core._fit.problem import _read_logs
    from pupper_core._fit.columns import read_map

    robot = load_robot("pupper_v3")
    no_gains = COLUMNS.replace(f",{MOTOR}.kp=fr_knee_kp,{MOTOR}.kd=fr_knee_kd", "")
    read = _read_logs([bench[0.1]], robot, read_map(no_gains), {"kp": "5", "kd": "0.1", "held": "leg_front_r_2=0.5"})
    lg = read[0]
    assert lg.logged == [MOTOR] and lg.actuators == robot.actuators
    i2, i3 = robot.actuators.index("leg_front_r_2"), robot.actuators.index(MOTOR)
    assert np.all(lg.target[:, i2] == 0.5) and np.all(lg.q[:, i2] == 0.5)
    assert np.all(lg.target[:, 0] == robot.rest[0]) and np.ptp(lg.target[:, i3]) > 0.3
    assert np.all(lg.kp == 5.0) and np.all(lg.kd == 0.1)
    with pytest.raises(pc.ConfigError, match=r"no '# kp:' line.*give --kp K --kd D"):
        pc.fit(bench[0.1], columns=no_gains, progress=False)


def test_excite_for_a_test_stand_writes_one_motor_at_its_rate(tmp_path, run):
    """`pupper excite --joints NAME --rate HZ`: the log covers that motor
    alone, a row per 1/HZ, the targets held between rows; fit reads it."""
    out = tmp_path / "stand.csv"
    run("excite", "--joints", MOTOR, "--rate", "250", "--seconds", "2", "--hold", "0.5", "-o", out, check=0)
    lines = out.read_text().splitlines()
    header = next(ln for ln in lines if not ln.startswith("#"))
    assert header == f"time,{MOTOR}.target,{MOTOR}.q,{MOTOR}.qd"
    data = np.array([[float(x) for x in ln.split(",")] for ln in lines[lines.index(header) + 1:]])
    assert np.allclose(np.diff(data[:, 0]), 0.004) and data[-1, 0] == pytest.approx(3.0)
    assert np.ptp(data[:, 1]) > 0.2
    res = pc.fit(out, params="kp_scale", max_iters=3, progress=False)
    # the nominal model's own response: its gains are the nominal ones
    assert res.actuators == [MOTOR] and res.value("kp_scale") == pytest.approx(1.0, abs=0.01)
    for args, words in ((["--joints", "foo"], "--joints names 'foo'"), (["--rate", "300"], "--rate 300 Hz")):
        p = run("excite", *args, "-o", tmp_path / "x.csv", check=2)
        one_line(p, *words)
        assert not (tmp_path / "x.csv").exists()


def test_logs_of_different_joints_fit_together(tmp_path):
    """A joint one log covers and another does not is fitted from the log
    that covers it (issue 47: it was left out); each log is compared on its
    own joints, and the fit says so."""
    a = Path(pc.excite(out=tmp_path / "a.csv", joints="kfe", seconds=0.6, hold=0.2, rate=250))
    b = Path(pc.excite(out=tmp_path / "b.csv", joints=MOTOR, seconds=0.6, hold=0.2, rate=250, seed=1))
    res = pc.fit([a, b], params="kp_scale", max_iters=2, progress=False)
    knees = ["leg_front_r_3", "leg_front_l_3", "leg_back_r_3", "leg_back_l_3"]
    assert sorted(res.actuators) == sorted(knees) and res.actuators_of("b.csv") == [MOTOR]
    assert sorted(res.actuators_of("a.csv")) == sorted(knees) and len(res.rms_after["a.csv"]) == 4
    assert not any("left out" in w for w in res.warnings), res.warnings
    assert any(n.startswith("the logs cover different actuators") and f"{MOTOR} in 2" in n for n in res.notes)
    # the nominal model's own responses: its gains are the nominal ones
    assert res.value("kp_scale") == pytest.approx(1.0, abs=0.01)


def test_three_delay_starts_give_one_answer(bench):
    """Issue 48: the delay's nominal 0 lies where MuJoCo's delay has no
    slope (up to a step it is one whole step), and a fit started there
    never moved it (the stand's 20 ms stalled at 1.3e-07 s, every other
    parameter bent to make up for it). The fit now estimates the delay from
    the logs before it starts, and starts no delay under 1.5 steps: from
    none (the logs' estimate), 0 and 40 ms it lands the same answer."""
    got = [pc.fit([bench[0.1]], columns=COLUMNS, params="kp_scale,kd_scale,delay", progress=False,
                  **({} if start is None else {"start": {"delay": start}})) for start in (None, 0.0, 0.04)]
    # the scan's estimate, at the nominal values (the torque lag reads as more delay there)
    assert 0.015 < got[0].delay_scan["starts_s"][0] < 0.035, got[0].delay_scan
    for res in got:
        assert 0.015 < res.value("delay") < 0.035, res.table
        for row in got[0].table:
            lo, hi = row["low95"], row["high95"]
            assert abs(res.value(row["parameter"]) - row["fitted"]) <= 0.01 * (hi - lo), (row, res.table)


def two_knees(d: Path, back_kp_scale: float) -> tuple[Path, str]:
    """One log of two knees of one motor type (the right front and back),
    the back one's servo delivering ``back_kp_scale`` of its kp where the
    front's delivers the stand's 0.95: two runs of the plain stand at one
    seed (the same stamps and command; hung from a welded base the legs do
    not interact), side by side as one loop would log them. Its column map."""
    import csv

    rows = [list(csv.reader(p.open())) for p in (
        stand_log(d / "front.csv", kp=5.0, kd=0.1, seed=0, **PLAIN),
        stand_log(d / "back.csv", kp=5.0, kd=0.1, seed=0,
                  **{**PLAIN, "truth": {**PLAIN["truth"], "kp_scale": back_kp_scale}}))]
    head = rows[0][0]
    take = [head.index(c) for c in ("fr_knee_cmd", "fr_knee_pos", "fr_knee_vel")]
    out = d / "two_knees.csv"
    with out.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(head + ["br_knee_cmd", "br_knee_pos", "br_knee_vel"])
        for front, back in zip(rows[0][1:], rows[1][1:]):
            w.writerow(front + [back[i] for i in take])
    cmap = (f"time=stamp,{MOTOR}.target=fr_knee_cmd,{MOTOR}.q=fr_knee_pos,{MOTOR}.qd=fr_knee_vel,"
            "leg_back_r_3.target=br_knee_cmd,leg_back_r_3.q=br_knee_pos,leg_back_r_3.qd=br_knee_vel")
    return out, cmap


def test_motors_of_one_type_that_disagree_are_said(tmp_path):
    """Issues 47 and 48: two knees of one motor type, one servo's kp 1.6 /
    0.95 times the other's, fitted per joint in one fit: their kp scales
    come out with disjoint intervals while their delays agree, and a
    warning names the parameter, both motors with their values and
    intervals, and the gain structure as the suspect, in the manifest and
    on the report's fit page. Where intervals overlap, nothing is said."""
    from pupper_core._fit import disagreements, fit_entries, load_robot, motor_types

    log, cmap = two_knees(tmp_path, 1.6)
    res = pc.fit([log], columns=cmap, kp=5.0, kd=0.1, per="joint", params="kp_scale,delay", progress=False,
                 out=tmp_path / "fit")
    front, back = res.value(f"kp_scale.{MOTOR}"), res.value("kp_scale.leg_back_r_3")
    assert 1.5 < back / front < 1.85, (front, back)
    said = [w for w in res.warnings if w.startswith("kp_scale disagrees")]
    assert len(said) == 1, res.warnings
    lo, hi = res.interval("kp_scale.leg_back_r_3")
    for words in (f"{MOTOR} {front:.4g}", f"leg_back_r_3 {back:.4g} [{lo:.4g}, {hi:.4g}]",
                  "while delay agrees", "suspect the motor model's gain structure"):
        assert words in said[0], (words, said[0])
    assert not any(w.startswith("delay disagrees") for w in res.warnings), res.warnings
    manifest = json.loads((tmp_path / "fit" / "manifest.json").read_text())
    assert said[0] in manifest["warnings"]
    assert "kp_scale disagrees between motors of one type" in (tmp_path / "fit" / "report.html").read_text()
    # the same values with intervals that overlap (or one not finite): no warning
    entries = fit_entries(res)
    types = motor_types(load_robot("pupper_v3"))
    assert disagreements(entries, types) == said
    wide = [(k, m, x, x - 1.0, x + 1.0) for k, m, x, _, _ in entries]
    assert disagreements(wide, types) == []
    assert disagreements([(k, m, x, math.nan, math.nan) for k, m, x, _, _ in entries], types) == []


#: the stand's feedback latency (inside the loop) and command delay (outside it), issue 48
LATENCY, DELAY = 0.006, 0.015
#: a shorter stepped sine (3.7 s) for the latency's logs: the test's time
SHORT = (3.0, 5.0, 7.0, 10.0, 14.0)


@pytest.fixture(scope="module")
def latent(tmp_path_factory) -> dict[float, Path]:
    """The plain stand with 6 ms of feedback latency and 15 ms of command
    delay, at kp 5 and 7.5 (kd 0.1)."""
    d = tmp_path_factory.mktemp("latent")
    truth = {**PLAIN["truth"], "latency": LATENCY, "delay": DELAY}
    return {kp: stand_log(d / f"stand_kp{kp:g}.csv", kp=kp, kd=0.1, seed=s, freqs=SHORT, **{**PLAIN, "truth": truth})
            for kp, s in ((5.0, 0), (7.5, 1))}


def test_a_feedback_latency_and_a_command_delay_come_back_apart(latent):
    """Issue 48: logs at two kps tell the latency (it changes the loop's
    resonance, more at the higher kp) from the delay (a pure lag); the
    default parameters and the latency land both within 1 ms of the stand's,
    from the fit's own start (the latency's profile: from the nominal
    values a free latency fell to 0 and the rest bent to make up for it)."""
    res = pc.fit(list(latent.values()), columns=COLUMNS, params=LAGGED.replace("lag", "latency"), progress=False)
    assert abs(res.value("latency") - LATENCY) < 0.001, res.table
    assert abs(res.value("delay") - DELAY) < 0.001, res.table
    assert len(res.delay_scan["latency_profile_s"]) == 4, res.delay_scan
    assert not any("cannot tell the feedback latency" in w for w in res.warnings), res.warnings


def test_the_latency_profile_runs_every_delay_start_within_max_iters(latent):
    """Every delay start the manifest lists runs beside the latency's
    profile (a caller's `delay=` start was dropped), and the best start's
    probe counts towards --max-iters (a profile probe ran 6 iterations and
    the best went on for max-iters - 4)."""
    said: list[str] = []
    res = pc.fit(list(latent.values()), columns=COLUMNS, params=LAGGED.replace("lag", "latency"),
                 start={"delay": 0.04}, max_iters=8, progress=said.append)
    starts = res.delay_scan["starts_s"]
    assert any(abs(s - 0.04) < 1e-12 for s in starts), res.delay_scan
    stages = [re.search(r"iteration (\d+) \((start (\d+) of (\d+)|on from start (\d+))", s) for s in said]
    stages = [m for m in stages if m]
    total = {int(m[4]) for m in stages if m[4]}
    # the best delay start is the profile's; every other runs after it
    assert total == {len(res.delay_scan["latency_profile_s"]) + len(starts) - 1}, said
    best = next(int(m[5]) for m in stages if m[5])
    # a run's first report is its start's cost, before any iteration
    probe = max(int(m[1]) for m in stages if m[3] and int(m[3]) == best) - 1
    went_on = max(int(m[1]) for m in stages if m[5]) - 1
    assert probe + went_on <= 8, said


def test_one_kp_cannot_tell_the_latency_from_the_delay_and_says_so(latent):
    """At one kp the latency reads as less damping and more delay: the fit
    says it cannot tell them apart (and what would), and the interval it
    gives the latency is wide enough to hold the stand's."""
    res = pc.fit([latent[5.0]], columns=COLUMNS, params=LAGGED.replace("lag", "latency"), progress=False)
    said = [w for w in res.warnings if "cannot tell the feedback latency" in w]
    assert len(said) == 1 and "add a log at another kp (another kd does not separate them" in said[0], res.warnings
    lo, hi = res.interval("latency")
    assert lo <= LATENCY <= hi, (lo, hi)
