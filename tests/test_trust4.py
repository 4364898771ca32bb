"""Trust, round 4 (issue 49): the newest commands (recommend, hold, excite,
tune) as hard to break as the oldest. Each test names the item of the issue
it answers and failed on the code before it.

Targets that are not regular files are FIFOs made here (never a real
device); a read-only folder and a full disk are a bind mount and a small
tmpfs in a private mount namespace (root and unshare(1); skipped with the
reason elsewhere); a full stream is `/dev/full`."""

from __future__ import annotations

import json
import os
import shutil
import signal
import stat
import subprocess
import time
from pathlib import Path

import pytest

from conftest import clean_env

pc = pytest.importorskip("pupper_core")
mujoco = pytest.importorskip("mujoco")

SCENE = Path(pc.__file__).parent / "models" / "pupper_v3" / "scene.xml"
HINGE = Path(__file__).resolve().parent / "models" / "hinge1.xml"
#: the least search a recommend run can be: one robot, one candidate
TINY = ("--robots", "1", "--trials", "1", "--batch", "1", "--polish", "0")
FULL = Path("/dev/full")


def _no_internal(p: subprocess.CompletedProcess[str]) -> None:
    """No panic, no traceback, no internal error."""
    assert p.returncode not in (1, 101), (p.returncode, p.stderr[-3000:])
    for said in ("panicked", "internal error", "Traceback", "RUST_BACKTRACE"):
        assert said not in p.stderr, p.stderr[-3000:]


def _one_error(p: subprocess.CompletedProcess[str], *words: str) -> str:
    """Exit 2 and one line on stderr, saying `words`."""
    _no_internal(p)
    assert p.returncode == 2, (p.returncode, p.stderr[-3000:])
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, p.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def _fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


def _still_fifo(path: Path) -> None:
    assert stat.S_ISFIFO(os.lstat(path).st_mode), f"{path} is no longer a FIFO"


def _namespace_why() -> str | None:
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        return "needs root and unshare(1) for a private mount namespace (a read-only bind mount, a small tmpfs)"
    p = subprocess.run(["unshare", "-m", "--propagation", "private", "true"], capture_output=True)
    return None if p.returncode == 0 else f"unshare -m refused: {p.stderr.decode().strip()}"


def _in_namespace(script: str, timeout: float = 600) -> None:
    why = _namespace_why()
    if why:
        pytest.skip(why)
    subprocess.run(["unshare", "-m", "--propagation", "private", "bash", "-c", "set -u\n" + script],
                   env=clean_env(), timeout=timeout, check=False)


def _result(d: Path, name: str) -> subprocess.CompletedProcess[str]:
    """What `name` (rc, out, err files) recorded inside a namespace."""
    return subprocess.CompletedProcess([], int((d / f"{name}.rc").read_text()),
                                       (d / f"{name}.out").read_text(errors="replace"),
                                       (d / f"{name}.err").read_text(errors="replace"))


def _motor_model(path: Path, ctrlrange: bool = True) -> Path:
    """The built-in robot with its servos turned into torque motors (gain 1,
    no bias, no force range), limited by their control range of ±3 N·m
    (or not at all)."""
    spec = mujoco.MjSpec.from_file(str(SCENE))
    for a in spec.actuators:
        a.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        a.biastype = mujoco.mjtBias.mjBIAS_NONE
        a.gainprm[0] = 1.0
        a.biasprm[0] = a.biasprm[1] = a.biasprm[2] = 0.0
        a.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
        a.forcerange = [0.0, 0.0]
        a.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE if ctrlrange else mujoco.mjtLimited.mjLIMITED_FALSE
        a.ctrlrange = [-3.0, 3.0] if ctrlrange else [0.0, 0.0]
    spec.meshdir = str(SCENE.parent)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(spec.to_xml())
    return path


# --------------------------------------------------------------- one run of recommend, read by several items


@pytest.fixture(scope="module")
def motor_run(pupper_bin, tmp_path_factory):
    """recommend on a model of torque motors limited by their control range,
    kept in a folder whose name holds a newline and a YAML key, its card
    printed to a full disk (/dev/full): items 4, 7, 13, 25 and the
    Done-when's complete run directory read it."""
    base = tmp_path_factory.mktemp("motor")
    model = _motor_model(base / "odd\nkps: [999]\n#" / "motor.xml")
    out = base / "rec"
    with open(FULL, "w") as full:
        p = subprocess.run([str(pupper_bin), "recommend", "--model", str(model), "--kp-max", "100",
                            "--kd-max", "2", "--robots", "2", "--trials", "2", "--batch", "2", "--polish", "0",
                            "-q", "-o", str(out)], stdout=full, stderr=subprocess.PIPE, text=True,
                           env=clean_env(), cwd=base, timeout=900)
    return model, out, p


# --------------------------------------------------------------- wrong answer or data loss


def test_item_01_excite_force_onto_a_fifo_is_refused_and_the_fifo_stays(run, tmp_path: Path) -> None:
    fifo = _fifo(tmp_path / "fifo")
    p = run("excite", "--force", "-o", fifo, "--seconds", "1", "--hold", "0.2", timeout=120)
    _one_error(p, "not a regular file", str(fifo))
    _still_fifo(fifo)
    with pytest.raises(pc.PupperError, match="not a regular file"):
        pc.excite(out=fifo, force=True, seconds=1, hold=0.2)
    _still_fifo(fifo)
    # a regular file is still overwritten with --force
    (tmp_path / "old.csv").write_text("old\n")
    run("excite", "--force", "-o", tmp_path / "old.csv", "--seconds", "1", "--hold", "0.2", check=0)
    assert (tmp_path / "old.csv").read_text().startswith("# pupper joint log")


@pytest.fixture(scope="module")
def no_candidates(pupper_bin, tmp_path_factory):
    """recommend --force over an older run, with a phase margin no PD keeps:
    no candidate at all (items 2 and 17)."""
    d = tmp_path_factory.mktemp("nocand") / "old"
    d.mkdir()
    # what an older run left: ten candidates that held
    head = "trial,stage,kp.kfe,kd.kfe,p95_push_dip_mm,status\n"
    (d / "trials.csv").write_text(head + "".join(f"{k},search,OLDCANDIDATE{k},1,{k},ok\n" for k in range(10)))
    (d / "manifest.json").write_text(json.dumps({"kind": "recommend", "complete": True}))
    p = subprocess.run([str(pupper_bin), "recommend", *TINY, "--min-phase-margin", "179", "--force", "-q",
                        "-o", str(d)], capture_output=True, text=True, env=clean_env(), cwd=d.parent, timeout=900)
    return d, p


def test_item_02_a_forced_run_without_candidates_leaves_none_of_the_old_ones(no_candidates) -> None:
    d, p = no_candidates
    _no_internal(p)
    # no gains to name: the clear no (exit status 3), its run kept
    assert p.returncode == 3, p.stderr
    assert not (d / "trials.csv").exists() or "OLDCANDIDATE" not in (d / "trials.csv").read_text()
    assert "OLDCANDIDATE" not in (d / "report.html").read_text()
    m = json.loads((d / "manifest.json").read_text())
    assert m["kind"] == "recommend" and m["pick"] is None and m["candidates"] == 0


@pytest.mark.parametrize("order, words", [
    ("", ["--joint-order", "names no actuator"]),
    ("leg_front_r_1", ["--joint-order", "1 of the model's 12", "leg_front_r_2"]),
    (" , ,", ["--joint-order", "names no actuator"]),
])
def test_item_03_a_joint_order_must_name_every_actuator(run, tmp_path: Path, order, words) -> None:
    p = run("recommend", *TINY, "--joint-order", order, "-o", tmp_path / "r", timeout=600)
    _one_error(p, *words)
    assert not (tmp_path / "r").exists()
    with pytest.raises(pc.RecommendError, match="joint_order|--joint-order"):
        pc.recommend(robots=1, trials=1, joint_order=[order] if order.strip(" ,") else [], out=tmp_path / "p")
    assert not (tmp_path / "p").exists()


def test_item_04_the_export_of_a_motor_model_keeps_its_torque_limit(motor_run) -> None:
    _, out, p = motor_run
    m = mujoco.MjModel.from_xml_path(str(out / "recommended.xml"))
    for a in range(m.nu):
        # the PD's force limited as the motor's torque was; its target not clamped to ±3 rad
        assert m.actuator_forcelimited[a] and list(m.actuator_forcerange[a]) == [-3.0, 3.0], m.actuator(a).name
        assert not m.actuator_ctrllimited[a], m.actuator(a).name
    # a 1 rad error: plain MuJoCo applies at most the motor's 3 N·m
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    d.ctrl[:] = d.qpos[7:] + 1.0
    mujoco.mj_forward(m, d)
    assert abs(d.actuator_force).max() <= 3.0 + 1e-12
    # the card's limit is that torque
    import csv

    with open(out / "recommend.csv", newline="") as f:
        assert {float(r["torque_limit"]) for r in csv.DictReader(f)} == {3.0}


def test_item_05_a_command_delay_the_step_response_cannot_show_is_refused(run, tmp_path: Path) -> None:
    for args in (("--command-delay", "100"), ("--motor", "rate=500,counts=16384,delay=100")):
        p = run("recommend", *TINY, *args, "-o", tmp_path / "r", timeout=600)
        _one_error(p, "delay", "100")
        assert not (tmp_path / "r").exists()


def test_item_06_a_hold_too_short_for_the_shove_is_refused(run, tmp_path: Path) -> None:
    p = run("hold", "--kp", "6", "--seconds", "3.6", "-o", tmp_path / "h")
    _one_error(p, "--seconds 3.6", "shove", "5.25")
    assert not (tmp_path / "h").exists()
    with pytest.raises(pc.ConfigError, match="5.25"):
        pc.hold(kp=6, seconds=3.6, progress=False)
    # long enough, or no shove at all: it runs
    run("hold", "--kp", "6", "--seconds", "5.25", "-q", "-o", tmp_path / "ok", check=0)
    run("hold", "--kp", "6", "--seconds", "3.6", "--shove", "0", "-q", "-o", tmp_path / "calm", check=0)


def test_item_07_a_model_path_with_a_newline_stays_in_the_yaml_comment(motor_run) -> None:
    import yaml

    model, out, _ = motor_run
    text = (out / "recommended.yaml").read_text()
    doc = yaml.safe_load(text)
    assert list(doc) == ["neural_controller"], list(doc)
    assert len(doc["neural_controller"]["ros__parameters"]["kps"]) == 12
    head = text.splitlines()[0]
    assert head.startswith("# pupper recommend: ") and "odd\\nkps: [999]\\n#" in head, head


def test_item_11_tune_stops_on_sigint_and_sigterm_and_resumes(pupper_bin, tmp_path: Path) -> None:
    for sig in (signal.SIGINT, signal.SIGTERM):
        out = tmp_path / sig.name
        proc = subprocess.Popen([str(pupper_bin), "tune", "--space", "kp=5:50", "--trials", "400", "--batch", "4",
                                 "--seconds", "10", "-q", "-o", str(out)], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, env=clean_env(), cwd=tmp_path)
        from conftest import wait_rows

        wait_rows(out / "trials.csv", proc, 4, timeout=300)
        sent = time.monotonic()
        proc.send_signal(sig)
        so, se = proc.communicate(timeout=300)
        assert time.monotonic() - sent < 60, "the study ran on after the signal"
        assert proc.returncode == 130, (sig, proc.returncode, se)
        lines = [ln for ln in se.splitlines() if ln.strip()]
        assert len(lines) == 1 and f"tune stopped by {sig.name}" in lines[0] and "--resume" in lines[0], se
    # what was kept resumes to the study's end
    p = subprocess.run([str(pupper_bin), "tune", "--resume", str(tmp_path / "SIGINT"), "--trials", "12", "-q"],
                       capture_output=True, text=True, env=clean_env(), cwd=tmp_path, timeout=600)
    assert p.returncode == 0, p.stderr
    from conftest import read_csv

    _, rows = read_csv(tmp_path / "SIGINT" / "trials.csv")
    assert len(rows) == 12


# --------------------------------------------------------------- crash, traceback, internal error, panic


def test_item_13_excite_into_a_read_only_folder_or_onto_a_full_disk(pupper_bin, tmp_path: Path) -> None:
    ro, disk = tmp_path / "ro", tmp_path / "disk"
    ro.mkdir()
    disk.mkdir()
    b = pupper_bin
    _in_namespace(f"""
mount --bind {ro} {ro} && mount -o remount,bind,ro {ro}
{b} excite -o {ro}/e.csv --seconds 1 --hold 0.2 > {tmp_path}/ro.out 2> {tmp_path}/ro.err; echo $? > {tmp_path}/ro.rc
mount -t tmpfs -o size=64k tmpfs {disk}
{b} excite -o {disk}/e.csv --seconds 1 --hold 0.2 > {tmp_path}/full.out 2> {tmp_path}/full.err
echo $? > {tmp_path}/full.rc
ls -A {disk} > {tmp_path}/full.ls
# a disk with no room left at all: recommend cannot even say who holds its lock
head -c 1m /dev/zero > {disk}/filler 2>/dev/null
{b} recommend {' '.join(TINY)} -o {disk}/rec > {tmp_path}/rec.out 2> {tmp_path}/rec.err; echo $? > {tmp_path}/rec.rc
""")
    _one_error(_result(tmp_path, "ro"), "e.csv", "Read-only file system")
    _one_error(_result(tmp_path, "full"), "e.csv", "No space left on device")
    # no temporary file is left behind
    assert (tmp_path / "full.ls").read_text().split() == []
    _one_error(_result(tmp_path, "rec"), "No space left on device")


def test_item_13_recommend_with_a_full_stdout_keeps_a_whole_run(motor_run) -> None:
    _, out, p = motor_run
    line = _one_error(p, "standard output", "No space left on device")
    assert "--resume" not in line
    m = json.loads((out / "manifest.json").read_text())
    assert m["complete"] is True
    for f in ("recommend.csv", "trials.csv", "recommended.yaml", "recommended.xml", "report.html"):
        assert (out / f).is_file(), f


@pytest.mark.skipif(not FULL.exists(), reason="no /dev/full here")
@pytest.mark.parametrize("args, status", [
    (("info",), 0),
    (("stand", "--seconds", "0.2"), 0),
    (("sweep", "--seconds", "0.2", "-o", "s"), 0),
    (("hold", "--kp", "6", "-o", "h"), 0),
    (("response", "--seconds", "1", "--joints", "kfe", "-o", "r"), 0),
    (("gains", "--kp", "5", "--kd", "0.1"), 0),
    (("excite", "--seconds", "1", "--hold", "0.2", "-o", "e.csv"), 0),
    (("tune", "--space", "kp=5:50", "--trials", "2", "--batch", "2", "--seconds", "1", "-o", "t"), 0),
    (("recommend", "--robots", "0", "-o", "rec"), 2),
    (("sweep", "--grid", "kq=1"), 2),
    (("doctor",), 0),
])
def test_item_14_a_full_stderr_is_no_panic(pupper_bin: Path, tmp_path: Path, args, status) -> None:
    with open(FULL, "w") as full:
        p = subprocess.run([str(pupper_bin), *args], stdout=subprocess.PIPE, stderr=full, text=True,
                           env=clean_env(), cwd=tmp_path, timeout=300)
    # what it did is its exit status; there is nowhere to say more
    assert p.returncode == status, p.returncode


def test_item_15_recommend_checks_its_python_arguments_before_any_work(tmp_path: Path) -> None:
    cases = [({"seed": -1}, "seed"), ({"seed": 2**64}, "seed"), ({"spread": [5]}, "spread"),
             ({"joint_order": [1, 2]}, "joint_order"), ({"robots": True}, "robots"),
             ({"seconds": "4"}, "seconds"), ({"motor": 500}, "motor"), ({"controller": None}, "controller")]
    for kw, said in cases:
        t = time.monotonic()
        with pytest.raises(pc.RecommendError, match=said):
            pc.recommend(out=tmp_path / "r", progress=False, **kw)
        assert time.monotonic() - t < 10, kw
        assert not (tmp_path / "r").exists()


def test_item_16_recommend_seconds_short_of_the_push_are_refused_up_front(run, tmp_path: Path) -> None:
    for s in ("2", "3", "3.5"):
        t = time.monotonic()
        p = run("recommend", "--seconds", s, "-o", tmp_path / "r", timeout=600)
        _one_error(p, f"--seconds {s}", "3.75")
        assert time.monotonic() - t < 20
        assert not (tmp_path / "r").exists()


def test_item_17_a_margin_no_loop_can_keep_is_refused(run, tmp_path: Path) -> None:
    for deg in ("180", "200"):
        p = run("recommend", "--min-phase-margin", deg, "-o", tmp_path / "r", timeout=600)
        _one_error(p, f"--min-phase-margin {deg}", "180")
        assert not (tmp_path / "r").exists()


def test_item_17_no_gains_keeping_the_margins_is_said(no_candidates) -> None:
    _, p = no_candidates
    assert "most common reason: none" not in p.stdout, p.stdout
    assert "no gains keep the loop margins" in p.stdout and "phase margin >= 179°" in p.stdout, p.stdout


def test_item_18_robots_that_fall_are_counted_and_a_floorless_model_refused(run, tmp_path: Path,
                                                                             capsys) -> None:
    from pupper_core._recommend import Recommendation
    from pupper_core._recommend.card import print_card
    from pupper_core._recommend import plan_for as make_plan
    from pupper_core._recommend.search import Candidate

    p = make_plan(robots=2, trials=2, batch=2, kp_max=0.3)
    fell = "2 of 2 robots fell, diverged or lay past the stability bound"
    cands = [Candidate({g.name: (0.3, 0.1) for g in p.groups}, failed=fell, fell=2, robots=2, cell_steps=4002,
                       number=k) for k in range(2)]
    print_card(Recommendation(None, [], cands, p, None))
    said = capsys.readouterr().out
    assert "N of N" not in said and "2 of 2 robots fell" in said, said
    # every robot fell on every candidate: the gains may be too soft to stand
    assert "--kp-max" in said and "0.3" in said, said
    bare = SCENE.parent / "pupper_v3.xml"  # the robot alone, no floor
    q = run("recommend", *TINY, "--model", bare, "-o", tmp_path / "r", timeout=600)
    _one_error(q, "no ground the feet can touch")
    assert not (tmp_path / "r").exists()


def test_item_19_a_model_without_legs_is_not_told_to_give_pose(run, tmp_path: Path) -> None:
    p = run("recommend", "--model", HINGE, "-o", tmp_path / "r", timeout=600)
    line = _one_error(p, "no legs")
    assert "--pose" not in line and "pose=" not in line
    assert not (tmp_path / "r").exists()
    # excite hangs the robot in the air at its rest pose: one hinge is a robot to excite
    p = run("excite", "--model", HINGE, "--seconds", "1", "--hold", "0.2", "-o", tmp_path / "e.csv", timeout=300)
    _no_internal(p)
    assert "--pose" not in p.stderr and "pose=" not in p.stderr, p.stderr
    assert p.returncode == 0, p.stderr
    assert "swing.target" in (tmp_path / "e.csv").read_text()


def test_item_20_a_model_of_unlimited_motors_is_refused_in_the_commands_words(run, tmp_path: Path) -> None:
    model = _motor_model(tmp_path / "m" / "motors.xml", ctrlrange=False)
    p = run("recommend", *TINY, "--model", model, "--kp-max", "100", "--kd-max", "2", "-o", tmp_path / "r",
            timeout=600)
    line = _one_error(p, "no force or control range", "forcerange")
    assert "max_torque=" not in line and "kp_max=" not in line
    assert not (tmp_path / "r").exists()


def test_item_21_a_late_shove_asks_for_enough_seconds(run, tmp_path: Path) -> None:
    p = run("hold", "--kp", "6", "--shove-at", "100", "--seconds", "7", "-o", tmp_path / "h")
    line = _one_error(p, "--seconds 7")
    assert "give --seconds 101.75 or more" in line, line
    assert not (tmp_path / "h").exists()


def test_item_24_recommend_takes_a_spread_string_as_one_spec_and_refuses_half_robots(tmp_path: Path) -> None:
    from pupper_core._recommend import plan_for as make_plan

    p = make_plan(spread="torso_mass=±15%")
    assert p.spread[0] == "torso_mass=±15%", p.spread
    with pytest.raises(pc.RecommendError, match="robots") as e:
        pc.recommend(robots=4.5, out=tmp_path / "r", progress=False)
    assert "from_fit" not in str(e.value) and "from-fit" not in str(e.value)
    assert not (tmp_path / "r").exists()


def test_item_25_the_lock_names_nobody_after_a_recommend_run(motor_run) -> None:
    _, out, _ = motor_run
    assert (out / ".pupper.lock").read_text() == ""


def test_item_26_a_file_that_is_no_model_prints_no_mujoco_warning(run, tmp_path: Path) -> None:
    junk = tmp_path / "notamodel"
    junk.write_text("name: value\nnot an MJCF file, nor XML at all\n")
    for args in (("sweep", "--seconds", "0.2", "-o", tmp_path / "s"), ("info",),
                 ("recommend", "-o", tmp_path / "r")):
        p = run(*args, "--model", junk, timeout=300)
        _one_error(p, "notamodel")
        assert "WARNING" not in p.stdout + p.stderr, p.stdout + p.stderr
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_item_27_a_command_delay_moves_the_cards_settling_by_exactly_the_delay() -> None:
    from pupper_core._recommend.card import _step_response
    from pupper_core._recommend import plan_for as make_plan
    from pupper_core.render import builtin_model_path

    xml = builtin_model_path("pupper_v3")
    now = _step_response(make_plan(robots=1), xml)
    late = _step_response(make_plan(robots=1, command_delay=0.02), xml)
    for g in now:
        assert late[g]["settling_time_s"] - now[g]["settling_time_s"] == pytest.approx(0.02, abs=1e-9), (g, now, late)
        assert late[g]["rise_time_s"] == pytest.approx(now[g]["rise_time_s"], rel=1e-3)


@pytest.mark.skipif(not FULL.exists(), reason="no /dev/full here")
@pytest.mark.parametrize("args", [("recommend", "--help"), ("--help",), ("--version",), ("hold", "-h")])
def test_item_28_help_to_a_full_stdout_fails(pupper_bin: Path, tmp_path: Path, args) -> None:
    with open(FULL, "w") as full:
        p = subprocess.run([str(pupper_bin), *args], stdout=full, stderr=subprocess.PIPE, text=True,
                           env=clean_env(), cwd=tmp_path, timeout=60)
    _one_error(p, "standard output")


@pytest.mark.skipif(not FULL.exists(), reason="no /dev/full here")
@pytest.mark.parametrize("args", [("hold", "--kp", "6"), ("sweep", "--grid", "kp=5,6", "--seconds", "4")])
def test_item_29_a_full_stdout_leaves_a_whole_run(pupper_bin: Path, tmp_path: Path, args) -> None:
    with open(FULL, "w") as full:
        p = subprocess.run([str(pupper_bin), *args, "-o", "run"], stdout=full, stderr=subprocess.PIPE,
                           text=True, env=clean_env(), cwd=tmp_path, timeout=300)
    _no_internal(p)
    assert p.returncode == 2 and "standard output" in p.stderr, p.stderr
    m = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert m["complete"] is True
    # every file the run writes with a stdout that takes the table
    subprocess.run([str(pupper_bin), *args, "-o", "ref"], capture_output=True, env=clean_env(), cwd=tmp_path,
                   timeout=300, check=True)
    files = {d: sorted(p.name for p in (tmp_path / d).iterdir()) for d in ("run", "ref")}
    assert files["run"] == files["ref"] and "report.html" in files["run"], files
    if args[0] == "hold":
        assert "best.csv" in files["run"]


# --------------------------------------------------------------- done when


@pytest.mark.parametrize("args", [
    ("excite", "--seconds", "1", "--hold", "0.2", "-o"),
    ("sweep", "--seconds", "0.2", "--force", "-o"),
    ("hold", "--kp", "6", "--force", "-o"),
    ("tune", "--space", "kp=5:50", "--trials", "2", "--batch", "2", "--seconds", "1", "--force", "-o"),
    ("recommend", "--force", "-o"),
    ("render", "--force", "-o"),
])
def test_done_when_a_fifo_as_out_is_refused_in_one_line(run, tmp_path: Path, args) -> None:
    fifo = _fifo(tmp_path / "fifo")
    p = run(*args, fifo, timeout=300)
    _one_error(p)
    _still_fifo(fifo)


@pytest.mark.parametrize("name", ["report.html", "summary.csv", "manifest.json"])
def test_done_when_a_fifo_inside_a_run_directory_is_refused_before_the_run(run, tmp_path: Path, name) -> None:
    d = tmp_path / "run"
    d.mkdir()
    _fifo(d / name)
    p = run("sweep", "--seconds", "0.2", "--force", "-o", d, timeout=300)
    _one_error(p, name, "not a regular file")
    _still_fifo(d / name)
    assert not (d / "summary.csv").is_file() or name == "summary.csv"
    # a report asked for alone refuses it too
    if name == "report.html":
        run("sweep", "--seconds", "0.2", "-q", "-o", tmp_path / "ok", check=0)
        os.unlink(tmp_path / "ok" / "report.html")
        _fifo(tmp_path / "ok" / "report.html")
        _one_error(run("report", tmp_path / "ok"), "report.html", "not a regular file")
        _still_fifo(tmp_path / "ok" / "report.html")


def test_done_when_python_commands_into_a_read_only_folder_say_so(pupper_bin, tmp_path: Path) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    log = tmp_path / "ex.csv"
    subprocess.run([str(pupper_bin), "excite", "--seconds", "1", "--hold", "0.2", "--joints", "kfe", "-o", str(log)],
                   env=clean_env(), capture_output=True, check=True, timeout=300)
    b = pupper_bin
    cmds = {
        "tune": f"tune --space kp=5:50 --trials 2 --batch 2 --seconds 1 -q -o {ro}/t",
        "recommend": f"recommend {' '.join(TINY)} -q -o {ro}/r",
        "fit": f"fit {log} --params armature --max-iters 2 -o {ro}/f",
        "sweep": f"sweep --seconds 0.2 -q -o {ro}/s",
        "report": f"report {ro}",
    }
    script = f"mount --bind {ro} {ro} && mount -o remount,bind,ro {ro}\n" + "".join(
        f"{b} {c} > {tmp_path}/{n}.out 2> {tmp_path}/{n}.err; echo $? > {tmp_path}/{n}.rc\n" for n, c in cmds.items())
    _in_namespace(script)
    for n in cmds:
        p = _result(tmp_path, n)
        _no_internal(p)
        assert p.returncode == 2, (n, p.stderr)


@pytest.mark.skipif(not FULL.exists(), reason="no /dev/full here")
@pytest.mark.parametrize("args", [
    ("tune", "--space", "kp=5:50", "--trials", "2", "--batch", "2", "--seconds", "1", "-o", "t"),
    ("excite", "--seconds", "1", "--hold", "0.2", "-o", "e.csv"),
    ("gains", "--kp", "5", "--kd", "0.1"),
    ("pose",),
])
def test_done_when_a_full_stdout_is_one_line_in_any_command(pupper_bin: Path, tmp_path: Path, args) -> None:
    with open(FULL, "w") as full:
        p = subprocess.run([str(pupper_bin), *args], stdout=full, stderr=subprocess.PIPE, text=True,
                           env=clean_env(), cwd=tmp_path, timeout=300)
    _no_internal(p)
    errors = [ln for ln in p.stderr.splitlines() if ln.startswith("error:")]
    if p.returncode != 0 or errors:  # a command that prints nothing on stdout may succeed
        assert p.returncode == 2 and len(errors) == 1 and "standard output" in errors[0], p.stderr


def test_done_when_python_writers_refuse_a_fifo(tmp_path: Path) -> None:
    from pupper_core._rundir import atomic_write_text

    fifo = _fifo(tmp_path / "f")
    with pytest.raises(pc.OutputError, match="not a regular file"):
        atomic_write_text(fifo, "x")
    _still_fifo(fifo)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]
