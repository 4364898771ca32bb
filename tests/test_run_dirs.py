"""Run directories under hostile but fair use: kills at random moments, a
full disk, two writers, runs started in the same second, damaged rows, odd
timesteps, models that are not ours. Each case ends with what an
uninterrupted run writes, byte for byte, or with one clear line."""

from __future__ import annotations

import json
import math
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import REPO, clean_env, read_csv, same_files, stamp_of

# 64 traced cells of 3 s, 4 per batch, one thread: a few seconds of work.
TRACED = ["sweep", "--grid", "kp=10:120:16", "--grid", "kd=0.5,1,2,5", "--seconds", "3",
          "--trace", "--chunk-cells", "4", "--threads", "1", "-q"]


GLFW_PROBE_ORPHAN = ('Traceback (most recent call last):\n  File "<string>", line 36, in <module>\n'
                     "BrokenPipeError: [Errno 32] Broken pipe\n")


def start(pupper_bin: Path, args: list, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen([str(pupper_bin), *map(str, args)], cwd=cwd, env=clean_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def whole_rows(path: Path) -> int:
    """Data rows of a CSV that are complete lines (a kill may cut the last)."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return 0
    return max(0, text.count("\n") - 1)


def temp_files(d: Path) -> list[str]:
    return sorted(p.name for p in d.iterdir() if ".tmp" in p.name)


@pytest.fixture(scope="module")
def traced_reference(pupper_bin, tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("reference")
    p = subprocess.run([str(pupper_bin), *TRACED, "-o", str(d / "full")], cwd=d, env=clean_env(),
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    return d / "full"


def same_bytes(got: Path, want: Path) -> None:
    """Equal to the uninterrupted run's summary and traces."""
    same_files(got, want, ("summary.csv", "traces.csv"))


# ---------------------------------------------------------------- kills


def took_the_directory(out: Path, pid: int) -> bool:
    """Whether process `pid` holds the run directory: its lock names it."""
    try:
        return (out / ".pupper.lock").read_text().startswith(f"pid {pid} ")
    except (FileNotFoundError, UnicodeDecodeError):
        return False


def test_twenty_random_kills_then_resume_equal_one_run(pupper_bin, tmp_path, traced_reference):
    rng = random.Random(20261123)
    out = tmp_path / "run"
    kills = mid_run = 0
    finished = False
    while kills < 20 and not finished:
        args = TRACED + (["--resume", out] if out.exists() else ["-o", out])
        proc = start(pupper_bin, args, tmp_path)
        # A quarter of the kills land while it starts up (before, while or
        # just after it creates the directory); the rest at a random moment
        # after it took the directory, timed from then: on a loaded machine
        # start-up alone can outlast any fixed delay, and every kill would
        # land before the directory exists.
        starting = rng.random() < 0.25
        if starting:
            time.sleep(rng.uniform(0.05, 0.6))
        else:
            deadline = time.monotonic() + 120
            while proc.poll() is None and not took_the_directory(out, proc.pid):
                assert time.monotonic() < deadline, "no start-up in 120 s"
                time.sleep(0.005)
            time.sleep(rng.uniform(0.0, 0.5))
        if proc.poll() is not None:
            so, se = proc.communicate()
            assert proc.returncode == 0, f"exit {proc.returncode}: {se}"
            finished = True
            break
        sig = rng.choice([signal.SIGKILL, signal.SIGKILL, signal.SIGINT, signal.SIGTERM])
        proc.send_signal(sig)
        so, se = proc.communicate(timeout=30)
        kills += 1
        mid_run += not starting
        if sig == signal.SIGKILL:
            # nothing of pupper's prints after a SIGKILL, but one that lands
            # while mujoco imports pyGLFW orphans the child python it asks
            # for the GLFW version over a pipe (glfw/library.py), and that
            # child reports the broken pipe on the stderr it inherited
            se = se.replace(GLFW_PROBE_ORPHAN, "")
        assert "panicked" not in se and "Traceback" not in se, se
        if (out / "manifest.json").exists():
            m = json.loads((out / "manifest.json").read_text())
            rows = whole_rows(out / "summary.csv")
            # the manifest never claims a row that is not on disk
            assert m["cells_done"] <= rows, (m["cells_done"], rows, sig)
            assert m["complete"] is False or rows == m["cells_total"]
    assert kills >= 10, f"the run finished after {kills} kills: make it longer"
    assert mid_run >= 5, f"only {mid_run} of {kills} kills landed after the run took its directory"
    # the same command again: --resume where a run made the directory (a
    # path no run created is nothing to resume, and is refused)
    again = ["--resume", str(out)] if out.exists() else ["-o", str(out)]
    p = subprocess.run([str(pupper_bin), *TRACED, *again], cwd=tmp_path,
                       env=clean_env(), capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    same_bytes(out, traced_reference)
    assert temp_files(out) == []
    m = json.loads((out / "manifest.json").read_text())
    assert m["complete"] is True and m["cells_done"] == m["cells_total"] == 64


def test_a_directory_left_by_a_kill_at_its_creation_resumes_afresh(pupper_bin, run, tmp_path):
    """What a kill while the run creates its directory leaves (the
    directory alone; its lock; a table's temporary file; the tables'
    headers without the manifest), resumed with the full command, equals
    one run; a path no run made is refused in one line, nothing written."""
    args = ["sweep", "--grid", "kp=5,30", "--seconds", "1", "--trace", "-q"]
    run(*args, "-o", tmp_path / "one", check=0)
    one = tmp_path / "one"
    header = {n: (one / n).read_text().split("\n", 1)[0] + "\n" for n in ("summary.csv", "traces.csv")}
    left = {
        "bare": {},
        "locked": {".pupper.lock": ""},
        "temp": {".pupper.lock": "", ".traces.csv.tmp4242": "id,t"},
        "headers": {".pupper.lock": "", **header, ".manifest.json.tmp4242": "{"},
    }
    for name, files in left.items():
        d = tmp_path / name
        d.mkdir()
        for f, text in files.items():
            (d / f).write_text(text)
        run(*args, "--resume", d, check=0)
        same_bytes(d, one)
        assert temp_files(d) == [], name
        assert json.loads((d / "manifest.json").read_text())["complete"] is True, name
    p = run(*args, "--resume", tmp_path / "never", check=2)
    assert len(p.stderr.strip().splitlines()) == 1 and "never" in p.stderr, p.stderr
    assert not (tmp_path / "never").exists()


def test_ctrl_c_then_resume_keeps_every_trace(pupper_bin, tmp_path, traced_reference):
    out = tmp_path / "run"
    proc = start(pupper_bin, TRACED + ["-o", out], tmp_path)
    deadline = time.monotonic() + 60
    while whole_rows(out / "summary.csv") < 8:
        assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=30) == 130
    p = subprocess.run([str(pupper_bin), "sweep", "--resume", str(out), "-q"], cwd=tmp_path,
                       env=clean_env(), capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    same_bytes(out, traced_reference)


def test_a_stop_with_default_batches_keeps_finished_cells(pupper_bin, tmp_path):
    """Batches are sized by time, not 256 cells: a stop a few seconds into a
    long sweep keeps what was finished."""
    out = tmp_path / "run"
    args = ["sweep", "--grid", "kp=1:100:128", "--seconds", "12", "--threads", "1", "-q", "-o", out]
    proc = start(pupper_bin, args, tmp_path)
    deadline = time.monotonic() + 60
    while whole_rows(out / "summary.csv") < 1:
        assert proc.poll() is None, "finished before any batch was written"
        assert time.monotonic() < deadline, "no cell written in 60 s: batches too large"
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=30) == 130
    _, rows = read_csv(out / "summary.csv")
    assert 1 <= len(rows) < 128


def test_one_cell_batches_append_instead_of_rewriting(pupper_bin, tmp_path):
    """--chunk-cells 1 appends each row to the same file (a rewrite per
    batch made it quadratic): the file is not replaced while rows grow."""
    out = tmp_path / "run"
    args = ["sweep", "--grid", "kp=1:100:150", "--seconds", "0.3", "--chunk-cells", "1",
            "--threads", "1", "-q", "-o", out]
    proc = start(pupper_bin, args, tmp_path)
    seen: dict[int, set[int]] = {}
    while proc.poll() is None:
        try:
            st = (out / "summary.csv").stat()
            rows = whole_rows(out / "summary.csv")
        except FileNotFoundError:
            continue
        if 0 < rows < 150:
            seen.setdefault(st.st_ino, set()).add(rows)
        time.sleep(0.005)
    assert proc.returncode == 0, proc.stderr.read()
    growing = max((len(v) for v in seen.values()), default=0)
    assert growing >= 5, f"summary.csv was replaced as rows grew: {seen}"


# ---------------------------------------------------------------- writers


def test_a_second_writer_is_refused_naming_the_first(pupper_bin, run, tmp_path):
    out = tmp_path / "run"
    first = start(pupper_bin, ["sweep", "--grid", "kp=1:100:48", "--seconds", "4", "--chunk-cells", "2",
                               "--threads", "1", "-q", "-o", out], tmp_path)
    try:
        deadline = time.monotonic() + 60
        while whole_rows(out / "summary.csv") < 1:
            assert first.poll() is None and time.monotonic() < deadline
            time.sleep(0.02)
        for extra in (["--force", "-o", out], ["--resume", out]):
            p = run("sweep", "--grid", "kp=1:100:48", "--seconds", "4", *extra, check=2)
            lines = p.stderr.strip().splitlines()
            assert len(lines) == 1, p.stderr
            assert f"pid {first.pid}" in lines[0] and "another pupper" in lines[0], lines[0]
    finally:
        so, se = first.communicate(timeout=300)
    assert first.returncode == 0, se
    _, rows = read_csv(out / "summary.csv")
    assert [int(r["index"]) for r in rows] == list(range(48))
    m = json.loads((out / "manifest.json").read_text())
    assert m["complete"] is True and m["command"][-1] == str(out)


def test_runs_started_in_the_same_second_get_their_own_directories(pupper_bin, tmp_path):
    procs = [start(pupper_bin, ["sweep", "--grid", "kp=5,6", "--seconds", "0.2", "-q"], tmp_path)
             for _ in range(6)]
    for p in procs:
        so, se = p.communicate(timeout=120)
        assert p.returncode == 0, se
    dirs = sorted((tmp_path / "runs").iterdir())
    assert len(dirs) == 6, [d.name for d in dirs]
    for d in dirs:
        _, rows = read_csv(d / "summary.csv")
        assert len(rows) == 2


# ---------------------------------------------------------------- the disk


def _namespace_ok() -> str | None:
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        return "needs root and unshare for a private tmpfs"
    p = subprocess.run(["unshare", "-m", "--propagation", "private", "true"], capture_output=True)
    return None if p.returncode == 0 else f"unshare -m refused: {p.stderr.decode().strip()}"


def test_full_disk_leaves_a_consistent_run_that_resumes(pupper_bin, tmp_path, traced_reference):
    why = _namespace_ok()
    if why:
        pytest.skip(why)
    disk = tmp_path / "disk"
    disk.mkdir()
    script = f"""
set -u
mount -t tmpfs -o size=1m tmpfs {disk}
cd {disk}
{pupper_bin} {' '.join(TRACED)} -o run > {tmp_path}/out1.txt 2> {tmp_path}/err1.txt
echo $? > {tmp_path}/rc1
cp -a run {tmp_path}/after1
mount -o remount,size=64m {disk}
{pupper_bin} {' '.join(TRACED)} --resume run > {tmp_path}/out2.txt 2> {tmp_path}/err2.txt
echo $? > {tmp_path}/rc2
cp -a run {tmp_path}/after2
"""
    subprocess.run(["unshare", "-m", "--propagation", "private", "bash", "-c", script],
                   env=clean_env(), timeout=600, check=False)
    assert (tmp_path / "rc1").read_text().strip() == "2"
    err = (tmp_path / "err1.txt").read_text().strip().splitlines()
    assert len(err) == 1 and "No space left" in err[0] and "--resume" in err[0], err
    first = tmp_path / "after1"
    assert temp_files(first) == []
    m = json.loads((first / "manifest.json").read_text())
    assert m["cells_done"] == whole_rows(first / "summary.csv") and m["complete"] is False, m
    assert (tmp_path / "rc2").read_text().strip() == "0", (tmp_path / "err2.txt").read_text()
    same_bytes(tmp_path / "after2", traced_reference)
    assert temp_files(tmp_path / "after2") == []


# ---------------------------------------------------------------- damaged rows


@pytest.fixture
def small_run(run, tmp_path) -> Path:
    out = tmp_path / "small"
    run("sweep", "--grid", "kp=5,30,60", "--seconds", "1", "-o", out, "-q", check=0)
    return out


def test_a_row_outside_the_grid_is_named_not_looped_on(run, small_run):
    with open(small_run / "summary.csv", "a") as f:
        f.write("129,kp9,,9" + ",1" * 8 + ",ok,\n")
    p = run("sweep", "--resume", small_run, "-q", check=2)
    assert p.stderr.count("\n") == 1 and "summary.csv:5: index '129'" in p.stderr, p.stderr


def test_a_row_of_another_grid_is_refused(run, small_run):
    text = (small_run / "summary.csv").read_text().replace("\n1,kp30,,30,", "\n1,kp31,,31,")
    (small_run / "summary.csv").write_text(text)
    p = run("sweep", "--resume", small_run, "-q", check=2)
    assert "another grid" in p.stderr and "kp31" in p.stderr, p.stderr


def test_a_truncated_last_row_is_recomputed(run, small_run, tmp_path):
    whole = (small_run / "summary.csv").read_bytes()
    (small_run / "summary.csv").write_bytes(whole[: whole.rindex(b",ok,")])
    run("sweep", "--resume", small_run, "-q", check=0)
    assert (small_run / "summary.csv").read_bytes() == whole
    import pupper_core as pc

    cut = tmp_path / "cut"
    shutil.copytree(small_run, cut)
    (cut / "summary.csv").write_bytes(whole[:-7])
    assert len(pc.load_run(cut)) == 2  # the cut row is left out, no IndexError


# ---------------------------------------------------------------- odd input


def test_tiny_timesteps_are_refused_at_once(run, tmp_path):
    for args in (["--grid", "timestep=1e-17"], ["--grid", "timestep=1e-6", "--seconds", "100000"]):
        t = time.monotonic()
        p = run("sweep", *args, "-o", tmp_path / "x", check=2, timeout=30)
        assert time.monotonic() - t < 20
        assert p.stderr.count("\n") == 1 and "timestep" in p.stderr, p.stderr
        assert not (tmp_path / "x").exists()


def test_extreme_scales_are_refused_up_front(run, tmp_path):
    p = run("sweep", "--grid", "torso_mass_scale=1,1e-300", "-o", tmp_path / "x", check=2)
    assert "torso_mass_scale" in p.stderr and "pupper_v3" not in p.stderr, p.stderr
    assert not (tmp_path / "x").exists()


def test_resume_mismatch_names_only_what_differs(run, small_run):
    p = run("sweep", "--grid", "kp=5,30,60", "--seconds", "1", "--trace", "--resume", small_run, check=2)
    assert "schedule.trace_every: 0 then, 10 now" in p.stderr, p.stderr
    assert "grid" not in p.stderr.split("differs from the run's in")[1], p.stderr


def test_a_relative_model_resumes_from_another_directory(run, tmp_path):
    here = tmp_path / "a"
    shutil.copytree(REPO / "models" / "pupper_v3", here / "m")
    args = ["sweep", "--model", "m/scene.xml", "--grid", "kp=5,30", "--seconds", "0.5", "-q"]
    run(*args, "-o", "run", cwd=here, check=0)
    (here / "run" / "summary.csv").write_text((here / "run" / "summary.csv").read_text().rsplit("\n", 2)[0] + "\n")
    p = run("sweep", "--resume", here / "run", "-q", cwd=tmp_path, check=0)
    m = json.loads((here / "run" / "manifest.json").read_text())
    assert Path(m["config"]["model"]["path"]).is_absolute(), m["config"]["model"]
    # a comment is the same robot; a mass in the file the scene includes is not
    (here / "m" / "scene.xml").write_text((here / "m" / "scene.xml").read_text() + "\n<!-- edited -->\n")
    run("sweep", "--resume", here / "run", "-q", cwd=tmp_path, check=0)
    robot = here / "m" / "pupper_v3.xml"
    robot.write_text(robot.read_text().replace('mass="1.506"', 'mass="1.606"', 1))
    p = run("sweep", "--resume", here / "run", "-q", cwd=tmp_path, check=2)
    assert "changed since the run started" in p.stderr and "scene.xml" in p.stderr, p.stderr


def test_negative_counts_name_the_keyword():
    import pupper_core as pc

    for kw in ("threads", "trace_every", "max_cells", "chunk_cells"):
        with pytest.raises(ValueError, match=rf"^{kw} must be a whole number >= 0, not -1$"):
            pc.sweep({"kp": [5]}, seconds=0.1, progress=False, **{kw: -1})


def test_mujoco_log_goes_into_the_run_directory(run, tmp_path):
    p = run("sweep", "--grid", "kp=1e9", "--grid", "kd=0", "--grid", "timestep=0.05", "--seconds", "2",
            "-o", "run", "-q", check=0)
    _, rows = read_csv(tmp_path / "run" / "summary.csv")
    assert rows[0]["status"] == "diverged", rows
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    assert "unstable" in (tmp_path / "run" / "MUJOCO_LOG.TXT").read_text()


# ---------------------------------------------------------------- other models


def _dog(tmp_path: Path) -> Path:
    """Pupper's body with motor actuators and no keyframe: a model like a user's."""
    robot = (REPO / "models" / "pupper_v3" / "pupper_v3.xml").read_text()
    robot = re.sub(r"<keyframe>.*?</keyframe>", "", robot, flags=re.S)
    robot = re.sub(r'<general class="pupper" name="(\w+)" joint="(\w+)"/>',
                   r'<motor name="\1" joint="\2" ctrlrange="-2 2"/>', robot)
    assert robot.count("<motor") == 12 and "<key" not in robot
    (tmp_path / "dog.xml").write_text(robot)
    scene = (REPO / "models" / "pupper_v3" / "scene.xml").read_text().replace("pupper_v3.xml", "dog.xml")
    (tmp_path / "scene.xml").write_text(scene)
    return tmp_path / "scene.xml"


def test_a_model_without_keyframe_stands_and_sweeps(run, tmp_path):
    model = _dog(tmp_path)
    # its motors have no PD gains of their own: pupper asks for them
    p = run("stand", "--model", model, "--seconds", "2", "--json")
    assert p.returncode == 2 and "give --kp and --kd" in p.stderr, p.stderr
    assert len(p.stderr.strip().splitlines()) == 1, p.stderr
    p = run("stand", "--model", model, "--seconds", "2", "--json", "--kp", "5", "--kd", "0.1", check=0)
    rep = json.loads(p.stdout)
    assert rep["status"] == "ok" and 0.1 < rep["final_z"] < 0.14, rep
    assert "default pose" in p.stderr and "note:" in p.stderr
    p = run("sweep", "--model", model, "--mode", "torque", "--grid", "kp=10,30", "--kd", "0.1",
            "--seconds", "2", "-o", "run", "-q", check=0)
    _, rows = read_csv(tmp_path / "run" / "summary.csv")
    assert [r["status"] for r in rows] == ["ok", "ok"]
    # torque limits are the model's own (its motors' control range), not Pupper's 3 N·m
    m = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert m["torque_limits"] == [2.0] * 12 and m["config"]["defaults"]["max_torque"] is None
    assert all(float(r["peak_torque"]) <= 2.0 for r in rows), rows
    # servo mode drives motor actuators as PD servos too: stiffer gains stand taller
    p = run("sweep", "--model", model, "--grid", "kp=2,30", "--kd", "0.1", "--seconds", "2",
            "-o", "servo", "-q", check=0)
    _, rows = read_csv(tmp_path / "servo" / "summary.csv")
    assert float(rows[1]["final_z"]) > float(rows[0]["final_z"]) + 0.005, rows


def test_motors_without_ranges_run_unclipped_and_say_so(run, tmp_path):
    model = _dog(tmp_path)
    robot = (tmp_path / "dog.xml").read_text().replace(' ctrlrange="-2 2"', "")
    assert "ctrlrange" not in robot
    (tmp_path / "dog.xml").write_text(robot)
    p = run("sweep", "--model", model, "--mode", "torque", "--grid", "kp=10,30", "--kd", "0.1",
            "--seconds", "1", "-o", "run", "-q", check=0)
    assert "not clipped" in p.stderr and "--max-torque" in p.stderr, p.stderr
    _, rows = read_csv(tmp_path / "run" / "summary.csv")
    assert [r["status"] for r in rows] == ["ok", "ok"]
    assert all(float(r["saturation_frac"]) == 0.0 for r in rows)


@pytest.mark.filterwarnings("ignore:seconds=")
def test_a_run_read_back_knows_its_cell_steps_where_the_manifest_does(tmp_path):
    """load_run says each cell's steps as the run that wrote it did (the
    schedule's steps at the cell's timestep, its grid's or the model's
    recorded in the manifest, times its simulations), and None where the
    manifest cannot know: a replicate failed, or a manifest from before
    the model's timestep was recorded."""
    pc = pytest.importorskip("pupper_core")
    runs = {
        "fell": lambda o: pc.sweep({"kp": [0.5, 60]}, seconds=3, progress=False, out=o),
        "timestep": lambda o: pc.sweep({"kp": [60], "timestep": [0.001, 0.002]}, seconds=2, progress=False, out=o),
        "response": lambda o: pc.response({"kp": [5, 20]}, kd=0.5, seconds=1, joints="kfe", progress=False, out=o),
    }
    for name, sweep in runs.items():
        fresh = sweep(tmp_path / name)
        assert pc.load_run(tmp_path / name).cell_steps == fresh.cell_steps, name
        assert all(n is not None for n in fresh.cell_steps)
    fresh = pc.sweep({"kp": [0.5, 60]}, seconds=3, replicates=3, progress=False, out=tmp_path / "reps")
    assert list(fresh["failure_fraction"]) == [1.0, 0.0]
    assert pc.load_run(tmp_path / "reps").cell_steps == [None, fresh.cell_steps[1]] == [None, 3 * 1501]
    m = tmp_path / "fell" / "manifest.json"
    old = json.loads(m.read_text())
    del old["model"]["timestep"]
    m.write_text(json.dumps(old))
    assert pc.load_run(tmp_path / "fell").cell_steps == [None, None]


def test_every_kind_heads_its_manifest_with_the_same_stamp(run, tmp_path):
    """A sweep's manifest (Rust's) and a tune's (its body built in Python,
    written by the Rust core) start with one stamp: the kind, then which
    pupper, MuJoCo and Python wrote it, equal but for the kind."""
    pytest.importorskip("optuna")
    run("sweep", "--grid", "kp=10", "--grid", "kd=1", "--seconds", "0.5", "-q", "-o", tmp_path / "s")
    run("tune", "--space", "kp=5:50", "--trials", "2", "--batch", "2", "--seconds", "0.5", "--no-push", "-q",
        "-o", tmp_path / "t", check=0)
    sweep, tune = stamp_of(tmp_path / "s", "sweep"), stamp_of(tmp_path / "t", "tune")
    assert {**sweep, "kind": "tune"} == tune
    # one reader for every kind's manifest: the JSON as written, NaN kept
    import pupper_core as pc
    from pupper_core import _native

    for d in (tmp_path / "s", tmp_path / "t"):
        assert _native.read_manifest(str(d)) == json.loads((d / "manifest.json").read_text())
    m = json.loads((tmp_path / "t" / "manifest.json").read_text())
    (tmp_path / "t" / "manifest.json").write_text(json.dumps({**m, "x": float("nan")}, indent=2))
    assert math.isnan(_native.read_manifest(str(tmp_path / "t"))["x"])
    (tmp_path / "t" / "manifest.json").write_text('{"kind": "tune", "inp')
    with pytest.raises(pc.OutputError, match="not a pupper manifest .damaged.*run the tune again"):
        _native.read_manifest(str(tmp_path / "t"))
    with pytest.raises(pc.RunNotFoundError, match="holds no pupper run"):
        _native.read_manifest(str(tmp_path))
