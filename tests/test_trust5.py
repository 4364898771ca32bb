"""Trust, round 5 (issue 61): a run directory is one kind's and one run's,
a unit typed without its unit is caught, a JSON reader can tell +inf from
-inf, messages blame the flag that is the cause, and a long run off a
terminal says how far it is. Each test names the item of the issue it
answers and failed on the code before it.

Items 4, 5 and 11 are tested in tests/test_trust5_fit.py, items 6, 12 and
14 in tests/test_fit_formats.py."""

from __future__ import annotations

import json
import math
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest

from conftest import clean_env, read_csv

pc = pytest.importorskip("pupper_core")
mujoco = pytest.importorskip("mujoco")

SCENE = Path(pc.__file__).parent / "models" / "pupper_v3" / "scene.xml"
#: the least walk: one cell, one whole gait cycle of steady walking
WALK = ("walk", "--kp", "5", "--kd", "0.25", "--seconds", "4")
#: the least recommend search, and what every refusal must be (round 4's)
from test_trust4 import TINY, _no_internal, _one_error  # noqa: E402


def _names(d: Path) -> set[str]:
    return {str(p.relative_to(d)) for p in d.rglob("*")}


@pytest.fixture(scope="module")
def walked(pupper_bin, tmp_path_factory) -> Path:
    """A finished one-cell walk run (items 1 and 2 copy it)."""
    d = tmp_path_factory.mktemp("walked") / "walk"
    subprocess.run([str(pupper_bin), *WALK, "-q", "-o", str(d)], env=clean_env(), capture_output=True,
                   check=True, timeout=300)
    return d


def _copy(src: Path, dst: Path) -> Path:
    import shutil

    shutil.copytree(src, dst)
    return dst


# --------------------------------------------------------------- run directories: one kind, one run


@pytest.mark.parametrize("command", ["sweep", "response", "hold", "lab"])
def test_item_01_resume_refuses_another_kinds_run(run, walked, tmp_path, command) -> None:
    d = _copy(walked, tmp_path / "w")
    before = {n: (d / n).read_bytes() for n in ("manifest.json", "summary.csv")}
    args = ("--kp", "6") if command == "hold" else ()
    line = _one_error(run(command, *args, "--resume", d, "-q"), "walk run", f"`pupper {command}`",
                      f"pupper walk --resume {d}")
    # response's named an "unknown metric" it then listed as valid
    assert "metric" not in line, line
    assert {n: (d / n).read_bytes() for n in before} == before, "the walk's manifest or table was rewritten"


def test_item_01_a_half_done_sweep_is_not_resumed_as_a_walk(run, tmp_path) -> None:
    d = tmp_path / "s"
    run("sweep", "--grid", "kp=5,6", "--seconds", "0.2", "-q", "-o", d, check=0)
    m = json.loads((d / "manifest.json").read_text())
    m["complete"], m["cells_done"] = False, 1
    (d / "manifest.json").write_text(json.dumps(m))
    (d / "summary.csv").write_text("".join((d / "summary.csv").read_text().splitlines(True)[:2]))
    _one_error(run("walk", "--resume", d, "-q"), "sweep run", "`pupper walk`", f"pupper sweep --resume {d}")
    _one_error(run("walk", "--resume", d, "--grid", "kp=5,6", "-q"), "sweep run")
    assert json.loads((d / "manifest.json").read_text())["kind"] == "sweep"
    with pytest.raises(pc.PupperError, match="sweep run"):
        pc.walk({"kp": [5, 6]}, out=d, resume=True, progress=False)


@pytest.mark.parametrize("kind", ["tune", "fit", "recommend"])
def test_item_01_a_python_kinds_run_is_named_not_misread(run, tmp_path, kind) -> None:
    d = tmp_path / kind
    d.mkdir()
    (d / "manifest.json").write_text(json.dumps({"kind": kind, "complete": False}))
    line = _one_error(run("sweep", "--resume", d, "-q"), f"{kind} run", "`pupper sweep`")
    assert "not a pupper manifest" not in line


def _plant(d: Path) -> None:
    """What older runs of other kinds left, and a file of the user's."""
    d.mkdir(parents=True, exist_ok=True)
    for n in ("fit.csv", "calibrated.xml", "residuals.csv", "robots.csv", "recommended.yaml",
              "recommended.xml", "trials.csv", "summary.csv", "best.csv", "report.html"):
        (d / n).write_text("OLD\n")
    (d / "manifest.json").write_text(json.dumps({"kind": "fit", "complete": True}))
    (d / "robots").mkdir(exist_ok=True)
    (d / "robots" / "robot_0.xml").write_text("OLD")
    (d / "plots").mkdir(exist_ok=True)
    (d / "plots" / "fit_oldlog.png").write_text("OLD")
    (d / "mine.txt").write_text("the user's own notes\n")


def _nothing_old(d: Path) -> None:
    for p in d.rglob("*"):
        if p.is_file() and p.name != "mine.txt":
            assert "OLD" not in p.read_text(errors="replace")[:4], f"{p} is the old run's"
    assert (d / "mine.txt").read_text() == "the user's own notes\n"
    assert not (d / "robots").exists(), "an empty robots/ was left"
    assert not (d / "plots").exists() or any((d / "plots").iterdir()), "an empty plots/ was left"


def test_item_02_a_forced_walk_leaves_nothing_of_a_fit_or_recommend_run(run, tmp_path) -> None:
    d = tmp_path / "d"
    _plant(d)
    run(*WALK, "--force", "-q", "-o", d, check=0)
    _nothing_old(d)
    for gone in ("fit.csv", "calibrated.xml", "residuals.csv", "robots.csv", "recommended.yaml", "trials.csv"):
        assert not (d / gone).exists(), gone
    assert json.loads((d / "manifest.json").read_text())["kind"] == "walk"
    assert (d / "summary.csv").is_file() and (d / "report.html").is_file()


def test_item_02_a_forced_tune_leaves_nothing_of_a_walk_run(run, walked, tmp_path) -> None:
    d = _copy(walked, tmp_path / "t")
    _plant(d)
    run("tune", "--space", "kp=5:50", "--trials", "2", "--batch", "2", "--seconds", "1", "--force", "-q",
        "-o", d, check=0)
    _nothing_old(d)
    assert not (d / "summary.csv").exists() and not (d / "fit.csv").exists()
    assert json.loads((d / "manifest.json").read_text())["kind"] == "tune"


def test_item_02_a_forced_run_refuses_a_fifo_first_and_removes_nothing(run, tmp_path) -> None:
    import os

    d = tmp_path / "d"
    _plant(d)
    os.mkfifo(d / "robots" / "robot_1.xml")
    _one_error(run(*WALK, "--force", "-q", "-o", d), "robot_1.xml", "not a regular file")
    assert (d / "fit.csv").read_text() == "OLD\n", "a file was removed before the refusal"


@pytest.fixture(scope="module")
def a_log(pupper_bin, tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("log")
    subprocess.run([str(pupper_bin), "excite", "--seconds", "1", "--hold", "0.2", "--joints", "kfe", "-o",
                    str(d / "ex.csv")], env=clean_env(), capture_output=True, check=True, timeout=300)
    return d / "ex.csv"


def test_item_02_a_forced_fit_leaves_nothing_of_a_walk_or_an_older_fit(run, walked, a_log, tmp_path) -> None:
    d = _copy(walked, tmp_path / "f")
    _plant(d)
    run("fit", a_log, "--params", "armature", "--max-iters", "2", "--force", "-o", d, check=0)
    _nothing_old(d)
    assert not (d / "summary.csv").exists(), "the walk's table outlived the fit"
    assert not (d / "plots" / "fit_oldlog.png").exists()
    assert "fit_oldlog" not in (d / "report.html").read_text()


def test_item_02_a_forced_recommend_leaves_nothing_of_a_walk(run, walked, tmp_path) -> None:
    pytest.importorskip("optuna")
    d = _copy(walked, tmp_path / "r")
    run("recommend", *TINY, "--force", "-q", "-o", d, check=0)
    assert not (d / "summary.csv").exists() and not (d / "best.csv").exists()


def test_item_02_the_python_kinds_share_the_rule(tmp_path) -> None:
    from pupper_core._rundir import clear_run

    d = tmp_path / "d"
    _plant(d)
    clear_run(d)
    # plots/ and robots/ held only the old run's files: gone with them
    assert _names(d) == {"mine.txt"}


# --------------------------------------------------------------- item 3: an interrupted walk keeps its cells


def test_item_03_a_walk_too_large_names_a_flag_walk_takes(run, tmp_path) -> None:
    grid = ("--grid", "kp=1:60:400", "--grid", "kd=0.1:1:300")
    line = _one_error(run("walk", *grid, "-o", tmp_path / "w"), "120000 cells", "--max-cells")
    assert not (tmp_path / "w").exists()
    assert "--max-cells" in run("walk", "--help").stdout
    # raised, the size passes: what is refused next is the length
    _one_error(run("walk", *grid, "--max-cells", "200000", "--seconds", "1", "-o", tmp_path / "w"), "--seconds 1")
    assert line


def test_item_03_and_15_a_stopped_walk_keeps_its_first_batch_and_said_how_far(pupper_bin, tmp_path) -> None:
    """The first batch is sized before any speed is measured: 256 walk
    cells on 8 threads (45 s of work where the walk's Rust steps do not
    spread over threads) became about 10 s of work. Off a terminal the run
    says what it is, how far it got and how long it has left."""
    out = tmp_path / "w"
    proc = subprocess.Popen([str(pupper_bin), "walk", "--grid", "kp=1:60:60", "--grid", "kd=0.1:1:60",
                             "--threads", "8", "-o", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=clean_env(), cwd=tmp_path)
    started = time.monotonic()
    try:
        first = 0
        while first == 0:
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            assert time.monotonic() - started < 240, "no batch finished"
            if (out / "summary.csv").exists():
                first = max(0, (out / "summary.csv").read_text().count("\n") - 1)
            time.sleep(0.05)
        # ceil(10 s x 25,000 steps/s / 4,000 steps): not 256
        assert first <= 100, f"the first batch held {first} cells"
        time.sleep(max(0.0, 11.0 - (time.monotonic() - started)))
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    _, rows = read_csv(out / "summary.csv")
    assert len(rows) >= first >= 1
    said = [ln for ln in err.splitlines() if ln.startswith("progress: walk")]
    assert said and "of 3600 cells" in said[0] and "cell-steps" in said[0] and "left" in said[0], err
    assert f"kept {len(rows)} of 3600 cells" in err, err


# --------------------------------------------------------------- items 7 and 8: units a person types


@pytest.mark.parametrize("args", [
    ("sweep", "--mode", "torque"),
    ("walk", "--mode", "torque"),
    ("hold", "--kp", "6", "--mode", "torque"),
    ("response", "--mode", "torque"),
    ("lab",),
    ("tune", "--space", "kp=5:50", "--trials", "2", "--batch", "2", "--seconds", "1", "--mode", "torque"),
    ("recommend", *TINY),
])
def test_item_07_a_lag_in_milliseconds_without_its_unit_is_refused(run, tmp_path, args) -> None:
    p = run(*args, "--motor", "rate=500,lag=10", "-o", tmp_path / "o", timeout=300)
    _one_error(p, "lag=10", "0.05 s", "write lag=0.01")
    assert not (tmp_path / "o").exists()


def test_item_07_gains_and_a_drawn_lag_are_checked_too(run, tmp_path) -> None:
    _one_error(run("gains", "--kp", "5", "--kd", "0.1", "--motor", "lag=10"), "write lag=0.01")
    p = run("sweep", "--mode", "torque", "--replicates", "2", "--randomize", "motor_lag=0:10", "-o", tmp_path / "o")
    _one_error(p, "motor_lag=0:10", "motor_lag=0:0.01")
    # a lag past even 50 ms as milliseconds: no value is guessed, the unit is said
    line = _one_error(run("gains", "--kp", "5", "--kd", "0.1", "--motor", "lag=200"), "in seconds")
    assert "lag=0.2" not in line
    with pytest.raises(pc.ConfigError, match="write lag=0.01"):
        pc.sweep({"kp": [5]}, mode="torque", motor="lag=10", seconds=0.2, progress=False)


def test_item_08_a_lag_of_zero_is_no_lag(run, tmp_path) -> None:
    g = run("gains", "--kp", "5", "--kd", "0.1", "--motor", "rate=500,lag=0", "--json", check=0)
    ideal = run("gains", "--kp", "5", "--kd", "0.1", "--motor", "rate=500", "--json", check=0)
    assert json.loads(g.stdout) == json.loads(ideal.stdout)
    run("sweep", "--mode", "torque", "--motor", "lag=0", "--seconds", "0.2", "-q", "-o", tmp_path / "s", check=0)


def test_item_08_a_given_lag_beside_a_drawn_one_is_refused(run, tmp_path) -> None:
    p = run("sweep", "--mode", "torque", "--motor", "lag=0.01", "--replicates", "2", "--randomize",
            "motor_lag=0:0.02", "-o", tmp_path / "o")
    _one_error(p, "--motor lag=", "--randomize motor_lag=", "keep one")
    assert not (tmp_path / "o").exists()


def test_item_08_fit_says_lag_is_its_own_parameter(run, a_log, tmp_path) -> None:
    p = run("fit", a_log, "--motor", "lag=0.01", "--params", "delay", "-o", tmp_path / "o")
    _one_error(p, "--motor", "lag", "its parameter 'lag'")


# --------------------------------------------------------------- item 9: the sign of an infinite margin


def test_item_09_gains_json_keeps_the_sign_of_infinite_margins(run) -> None:
    # kd/kp shorter than a 16 ms torque lag: no gain is stable (-inf)
    doc = json.loads(run("gains", "--kp", "40", "--kd", "0.5", "--motor", "lag=0.016", "--json", check=0).stdout)
    assert {j["gain_margin_db"] for j in doc["joints"]} == {"-inf"}, doc["joints"][0]
    res = pc.gains(kp=40, kd=0.5, motor="lag=0.016")
    assert all(j["gain_margin_db"] == -math.inf for j in res["joints"]), res["joints"][0]
    # a finite one stays a number
    doc = json.loads(run("gains", "--kp", "5", "--kd", "0.1", "--motor", "rate=500", "--json", check=0).stdout)
    assert all(isinstance(j["gain_margin_db"], float) for j in doc["joints"])


def test_item_09_the_representation_is_one_rule() -> None:
    """+inf and -inf as "inf" and "-inf" on the CLI, floats in Python, NaN
    null in both (what --json always wrote for a number it has not)."""
    assert math.isinf(pc.gains(kp=40, kd=0.5, motor="lag=0.016")["groups"][0]["gain_margin_db"])


# --------------------------------------------------------------- item 10: the flag that is the cause


@pytest.mark.parametrize("args, flag", [
    (("--sideways", "3"), "--sideways 3"),
    (("--yaw-rate", "10"), "--yaw-rate 10"),
    (("--height", "2"), "--height 2"),
    (("--speed", "5"), "--speed 5"),
    (("--step-height", "0.5"), "--step-height"),
])
def test_item_10_a_walk_out_of_reach_names_the_flag_that_is_the_cause(run, tmp_path, args, flag) -> None:
    line = _one_error(run("walk", "--kp", "5", "--kd", "0.25", *args, "-o", tmp_path / "w"), flag,
                      "beyond its reach")
    others = {"--sideways", "--yaw-rate", "--height", "--step-height"} - {flag.split()[0]}
    assert not any(o in line for o in others), line
    assert "cell " not in line, line
    # every number to the millimetre or the thousandth
    assert not re.search(r"\d\.\d{4,}", line), line
    assert not (tmp_path / "w").exists()


def test_item_10_a_speed_axis_out_of_reach_prints_short_numbers(run, tmp_path) -> None:
    line = _one_error(run("walk", "--kp", "5", "--kd", "0.25", "--grid", "speed=0.1:3:7", "-o", tmp_path / "w"),
                      "--speed")
    assert not re.search(r"\d\.\d{4,}", line), line


def test_item_10_recommend_names_no_flag_it_lacks_and_no_cell_id(run, tmp_path) -> None:
    pytest.importorskip("optuna")
    line = _one_error(run("recommend", "--task", "walk", "--speed", "5", *TINY, "-o", tmp_path / "r"), "--speed")
    assert "--height" not in line and "--sideways" not in line, line
    assert len(line) < 400 and not re.search(r"\w{60,}", line), line
    assert not re.search(r"\d\.\d{4,}", line), line


def test_item_10_a_walk_push_force_axis_is_refused_for_the_push(run, tmp_path) -> None:
    line = _one_error(run("walk", "--kp", "5", "--kd", "0.25", "--grid", "push_force=-10,-20", "-o", tmp_path / "w"),
                      "no push", "push_force")
    assert "body" not in line and "legs" not in line, line


# --------------------------------------------------------------- item 13: a walk on a model it cannot measure


def _edited(path: Path, edit) -> Path:
    spec = mujoco.MjSpec.from_file(str(SCENE))
    spec.meshdir = str(SCENE.parent)
    edit(spec)
    path.write_text(spec.to_xml())
    return path


def test_item_13_feet_that_are_no_spheres_are_refused(run, tmp_path) -> None:
    def no_spheres(spec) -> None:
        # each foot a capsule along the calf: its centre lies inside the leg
        for g in spec.geoms:
            if g.type == mujoco.mjtGeom.mjGEOM_SPHERE and (g.contype or g.conaffinity):
                g.type = mujoco.mjtGeom.mjGEOM_CAPSULE
                g.size = [g.size[0], 0.02, 0.0]

    model = _edited(tmp_path / "capsule_feet.xml", no_spheres)
    _one_error(run(*WALK, "--model", model, "-o", tmp_path / "w"), "not a sphere", "sphere geom")
    assert not (tmp_path / "w").exists()


def test_item_13_a_model_without_gravity_is_refused(run, tmp_path) -> None:
    def weightless(spec) -> None:
        spec.option.gravity = [0.0, 0.0, 0.0]

    model = _edited(tmp_path / "space.xml", weightless)
    _one_error(run(*WALK, "--model", model, "-o", tmp_path / "w"), "no weight", "gravity")
    assert not (tmp_path / "w").exists()


# --------------------------------------------------------------- item 15: progress off a terminal


def test_item_15_a_fit_off_a_terminal_says_it_runs(capsys, monkeypatch) -> None:
    from pupper_core._fit import optimize

    p = optimize._Progress(True)  # pytest's stderr is no terminal
    assert p.say is None and p.plain
    p("2 log(s), 1 parameter(s): expect about 600 s")
    p.tick()
    assert capsys.readouterr().err == "", "a line before 10 s"
    monkeypatch.setattr(p, "started", p.started - 11)
    p.rollouts = 40
    p.tick()
    first = capsys.readouterr().err.strip()
    assert first.startswith("progress: fit running for 11 s: 2 log(s)") and "expect about 600 s" in first, first
    assert "40 rollouts" in first and "a line every 30 s" in first, first
    p.tick()
    assert capsys.readouterr().err == "", "a second line within 30 s"
    monkeypatch.setattr(p, "started", p.started - 30)
    p.tick()
    assert capsys.readouterr().err.startswith("progress: fit 40 rollouts, 41 s")
    # on a terminal (or to a callable) as before
    said: list[str] = []
    q = optimize._Progress(said.append)
    q("x")
    assert said == ["fit: x"] and not q.plain


def test_item_15_the_python_runs_off_a_terminal_print_lines(capsys, monkeypatch) -> None:
    from pupper_core._run import progress

    # a notebook test in this process may have imported ipykernel: that is no notebook
    import ipykernel  # noqa: F401

    update = progress.progress_printer("pupper walk")
    assert update is not None
    update(10, 100)
    assert capsys.readouterr().err == ""
    t = time.monotonic()
    monkeypatch.setattr(progress.time, "monotonic", lambda: t + 20)
    update(25, 100)
    line = capsys.readouterr().err.strip()
    assert line.startswith("progress: pupper walk of 100 steps 25 % done") and "left" in line, line


def test_item_12_a_joint_order_naming_an_actuator_twice_says_which(run, tmp_path) -> None:
    order = "leg_front_r_1,leg_front_r_2,leg_front_r_1"
    p = run("recommend", *TINY, "--joint-order", order, "-o", tmp_path / "r", timeout=600)
    line = _one_error(p, "--joint-order names leg_front_r_1 twice (at 1 and 3)")
    assert "name each actuator once" in line and not (tmp_path / "r").exists()


def test_round_6_probes_name_the_flag_that_is_wrong(run, tmp_path) -> None:
    """A second hostile round on this stop's code: hold's own times are
    refused by hold's flags (not the sweep's --push-at they become); a
    sensing delay typed in milliseconds is caught as the torque lag is,
    with a reading to the nanosecond and none where milliseconds make no
    servo; a sweep's --rank without --best-by is refused, not ignored."""
    for args, words in [
        (("hold", "--grid", "kp=5", "--ramp", "nan"), "--ramp NaN must be a time >= 0 s"),
        (("hold", "--grid", "kp=5", "--shove-at", "-2"), "--shove-at -2 must be a time >= 0 s"),
        (("hold", "--grid", "kp=5", "--shove-duration", "-1"), "--shove-duration -1 must be a time >= 0 s"),
        (("gains", "--kp", "5", "--kd", "0.25", "--sensing-delay", "2"),
         "for 2 ms give --sensing-delay 0.002"),
        (("gains", "--kp", "5", "--kd", "0.25", "--motor", "lag=7.3"), "for 7.3 ms write lag=0.0073"),
        (("gains", "--kp", "5", "--kd", "0.25", "--motor", "lag=0.06"), "e.g. lag=0.007 for 7 ms"),
        (("sweep", "--grid", "kp=5", "--rank", "bogus"), "--rank bogus ranks the cells --best-by picks from"),
    ]:
        out = tmp_path / args[0]
        p = run(*args, *(("-o", out) if args[0] != "gains" else ()), check=None)
        line = _one_error(p, words)
        assert "--push" not in line and "0.0000" not in line, line
        assert not out.exists()


def test_round_6_usage_errors_are_one_line_and_saturation_is_a_share(run, tmp_path) -> None:
    """What clap refuses is one line too (its details, tips and where the
    help is, without its usage block); a value after a flag that clap reads
    as a flag says how to give it; --max-saturation past 1 (a percentage
    typed) is refused by sweep, lab and recommend alike, before anything
    runs."""
    for args, words in [
        (("swep",), ("unrecognized subcommand 'swep'", "similar subcommand exists: 'sweep'", "`pupper --help`")),
        (("sweep", "--mode", "x"), ("possible values: servo, torque", "`pupper sweep --help`")),
        (("sweep", "-j", "-1"), ("unexpected argument '-1'", "join them with '='")),
        (("fit",), ("required arguments were not provided: <LOG>", "`pupper fit --help`")),
        (("sweep", "--grid", "kp=5", "--max-saturation", "5"), ("must lie in (0, 1]",)),
        (("lab", "--max-saturation", "0"), ("must lie in (0, 1]",)),
        (("recommend", "--max-saturation", "1.5"), ("must lie in (0, 1]",)),
        (("recommend", "--joint-order", "a,,b"), ("empty entry at position 2",)),
    ]:
        out = tmp_path / "run"
        p = run(*args, *(("-o", out) if args[0] in ("sweep", "lab", "recommend") else ()), check=None)
        _one_error(p, *words)
        assert not out.exists()
    # a run directory under a file: the file named, not the OS's "File exists"
    (tmp_path / "notes.txt").write_text("mine")
    for kind in ("sweep", "lab"):
        p = run(kind, "--seconds", "0.5", "-o", tmp_path / "notes.txt" / "run", check=None)
        _one_error(p, f"lies under '{tmp_path / 'notes.txt'}', which is a file", "choose another --out")
    assert (tmp_path / "notes.txt").read_text() == "mine"
