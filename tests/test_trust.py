"""Trust, round 2 (issue 24): one robot per run, merges that check every
file, no hang, no panic, no silent overwrite. Each test here failed on the
release before it."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from conftest import read_csv


def _no_panic(proc) -> None:
    assert proc.returncode != 101 and "panicked" not in proc.stderr, proc.stderr
    assert "RUST_BACKTRACE" not in proc.stderr, proc.stderr


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full here")
@pytest.mark.parametrize("args", [
    ("info",),
    ("stand", "--seconds", "0.1"),
    ("sweep", "--seconds", "0.1", "-o", "run"),
    ("sweep", "--seconds", "0.1", "--json", "-o", "json"),
])
def test_a_full_stdout_is_one_error_line_not_a_panic(pupper_bin: Path, tmp_path: Path, args) -> None:
    import subprocess

    from conftest import clean_env

    with open("/dev/full", "w") as full:
        p = subprocess.run([str(pupper_bin), *args], stdout=full, stderr=subprocess.PIPE, text=True,
                           env=clean_env(), cwd=tmp_path, timeout=120)
    _no_panic(p)
    assert p.returncode == 2, p.stderr
    errors = [ln for ln in p.stderr.splitlines() if ln.startswith("error:")]
    assert errors == [errors[0]] and "standard output" in errors[0], p.stderr


def test_a_closed_pipe_ends_the_output_quietly(pupper_bin: Path, tmp_path: Path) -> None:
    import subprocess

    from conftest import clean_env

    p = subprocess.Popen([str(pupper_bin), "info"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         env=clean_env(), cwd=tmp_path)
    assert p.stdout is not None and p.stderr is not None
    p.stdout.readline()
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait(timeout=60) == 0, err
    assert "panicked" not in err


def test_paths_that_are_not_utf8_are_paths(run, tmp_path: Path) -> None:
    out = os.fsencode(tmp_path) + b"/run\xff"
    p = run("sweep", "--seconds", "0.1", "-q", "-o", os.fsdecode(out))
    _no_panic(p)
    assert p.returncode == 0, p.stderr
    assert os.path.isfile(out + b"/summary.csv")
    again = run("sweep", "--resume", os.fsdecode(out), "-q")
    _no_panic(again)
    assert again.returncode == 0, again.stderr
    missing = run("sweep", "--resume", os.fsdecode(os.fsencode(tmp_path) + b"/none\xfe"))
    _no_panic(missing)
    assert missing.returncode == 2 and "not a run directory" in missing.stderr, missing.stderr
    merged = run("merge", "-o", os.fsdecode(os.fsencode(tmp_path) + b"/m\xfe"), os.fsdecode(out))
    _no_panic(merged)
    assert merged.returncode == 2, merged.stderr


def test_json_keeps_the_body_and_the_labs_answer(run, tmp_path: Path) -> None:
    p = run("sweep", "--grid", "variant=original,heavy", "--seconds", "0.1", "--json",
            "-o", tmp_path / "sweep", check=0)
    cells = json.loads(p.stdout)["cells"]
    assert [c["variant"] for c in cells] == ["original", "heavy"]
    _, rows = read_csv(tmp_path / "sweep" / "summary.csv")
    assert [r["variant"] for r in rows] == ["original", "heavy"]
    # a metric the 0.1 s run could not measure is null, not a string
    assert all(c["last_1s_std_mm"] is None for c in cells)
    lab = run("lab", "--grid", "kp=30,60", "--grid", "kd=1", "--seconds", "2", "--json",
              "-o", tmp_path / "lab", check=0)
    doc = json.loads(lab.stdout)
    best = doc["best"]
    assert best["metric"] == "last_1s_std_mm" and best["by"] == ["variant"]
    assert [g["group"]["variant"] for g in best["groups"]] == ["original", "long-leg", "heavy"]
    _, written = read_csv(tmp_path / "lab" / "best.csv")
    for g, w in zip(best["groups"], written):
        assert g["cell"]["id"] == w["id"] and g["cell"]["kp"] == float(w["kp"]), (g, w)
    # and the lab overwrites its own run with --force, as sweep does
    again = run("lab", "--grid", "kp=30", "--grid", "kd=1", "--seconds", "2", "-q",
                "-o", tmp_path / "lab")
    assert again.returncode == 2 and "--force" in again.stderr
    run("lab", "--grid", "kp=30", "--grid", "kd=1", "--seconds", "2", "-q", "--force",
        "-o", tmp_path / "lab", check=0)


def test_render_never_overwrites_without_force_and_never_a_non_png(run, tmp_path: Path) -> None:
    text = tmp_path / "notes.txt"
    text.write_text("mine\n")
    for args in ([], ["--force"]):
        p = run("render", "--seconds", "0.01", "-o", text, *args)
        _no_panic(p)
        assert p.returncode == 2 and "not a PNG" in p.stderr, p.stderr
        assert text.read_text() == "mine\n"
    png = tmp_path / "old.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\n" + b"old")
    p = run("render", "--seconds", "0.01", "-o", png)
    assert p.returncode == 2 and "--force" in p.stderr, p.stderr
    assert png.read_bytes().endswith(b"old")
    # a directory takes the picture inside it, under the same rule
    (tmp_path / "pupper.png").mkdir()
    d = run("render", "--seconds", "0.01", "-o", tmp_path)
    assert d.returncode == 2 and "not a file" in d.stderr, d.stderr


def test_ray_at_an_address_that_is_not_ray_is_refused_at_once(run, tmp_path: Path) -> None:
    """A web server where the head should be: one line, exit 2, no directory,
    in seconds (Ray alone retried for minutes, deaf to Ctrl-C)."""
    import http.server
    import threading
    import time

    pytest.importorskip("ray")
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        port = server.server_address[1]
        for address in (f"127.0.0.1:{port}", f"ray://127.0.0.1:{port}"):
            started = time.monotonic()
            p = run("sweep", "--seconds", "0.1", "--ray", address, "-o", tmp_path / "run", timeout=90)
            took = time.monotonic() - started
            _no_panic(p)
            assert p.returncode == 2, p.stderr
            assert "is not a Ray cluster" in p.stderr and "it answered" in p.stderr, p.stderr
            assert len([ln for ln in p.stderr.splitlines() if ln.startswith("error:")]) == 1
            assert not (tmp_path / "run").exists()
            assert took < 30, took
    finally:
        server.shutdown()
        server.server_close()


_THREADED = """
import sys, threading, time
import pupper_core as pc

out, daemon = sys.argv[1], sys.argv[2] == "daemon"
def work():
    try:
        pc.sweep({"kp": [10, 20, 30, 40, 50, 60, 70, 80]}, seconds=600.0, out=out, progress=False,
                 chunk_cells=1, threads=1)
    except KeyboardInterrupt as e:
        # a file, not stdout: a daemon thread still printing while Python
        # finalizes trips CPython's own stdout lock check, pupper or not
        with open(out + ".stopped", "w") as f:
            f.write(str(e))
t = threading.Thread(target=work, daemon=daemon)
t.start()
time.sleep(4.0)
print("main done", flush=True)
"""


@pytest.mark.parametrize("how", ["daemon", "non-daemon+SIGINT"])
def test_the_interpreter_exits_cleanly_while_a_sweep_runs_in_a_thread(tmp_path: Path, how: str) -> None:
    import signal
    import subprocess
    import sys
    import time

    from conftest import clean_env

    out = tmp_path / "run"
    p = subprocess.Popen([sys.executable, "-c", _THREADED, str(out), how.split("+")[0]],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=clean_env())
    if how.endswith("SIGINT"):
        time.sleep(2.0)
        p.send_signal(signal.SIGINT)
    try:
        stdout, stderr = p.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        p.kill()
        raise
    assert p.returncode not in (-11, 139, -6, 134), (p.returncode, stderr)
    assert "Fatal Python error" not in stderr and "panicked" not in stderr, stderr
    if how == "daemon":
        assert "main done" in stdout, (stdout, stderr)
    # a non-daemon thread ends before Python finalizes: its sweep was told
    # why it stopped (a daemon thread may be frozen anywhere in its own
    # code once the sweep has left Rust, so only the process is checked)
    if how != "daemon":
        assert "interpreter is exiting" in Path(str(out) + ".stopped").read_text()
    m = json.loads((out / "manifest.json").read_text())
    assert m["complete"] is False
    assert m["cells_done"] < 8


def test_a_run_never_mixes_two_robots(run, tmp_path: Path) -> None:
    """The fingerprint is the compiled model's: a mass edited in a file the
    scene includes splits shards, resumes and cluster nodes apart."""
    import shutil

    from conftest import REPO

    robot = tmp_path / "robot"
    shutil.copytree(REPO / "models" / "pupper_v3", robot)
    scene = robot / "scene.xml"
    args = ["sweep", "--model", scene, "--grid", "kp=10,30,60,120", "--seconds", "0.1", "-q"]
    run(*args, "--shard", "1/2", "-o", tmp_path / "s1", check=0)
    before = json.loads(run("info", "--model", scene, "--json", check=0).stdout)["sha256"]
    included = robot / "pupper_v3.xml"
    text = included.read_text()
    assert 'mass="1.506"' in text
    included.write_text(text.replace('mass="1.506"', 'mass="1.906"', 1))
    after = json.loads(run("info", "--model", scene, "--json", check=0).stdout)["sha256"]
    assert before != after
    run(*args, "--shard", "2/2", "-o", tmp_path / "s2", check=0)
    p = run("merge", tmp_path / "s1", tmp_path / "s2", "-o", tmp_path / "merged")
    assert p.returncode == 2 and "different models" in p.stderr, p.stderr
    assert not (tmp_path / "merged").exists()
    # a resume after the edit is refused too
    r = run("sweep", "--resume", tmp_path / "s1")
    assert r.returncode == 2 and "changed since the run started" in r.stderr, r.stderr
    # a comment is not a different robot
    included.write_text(text + "\n<!-- a note -->\n")
    assert json.loads(run("info", "--model", scene, "--json", check=0).stdout)["sha256"] == before


@pytest.mark.parametrize("damage", ["delete", "truncate"])
def test_merge_checks_every_file_of_every_shard(run, tmp_path: Path, damage: str) -> None:
    import pupper_core as pc

    args = ["sweep", "--grid", "kp=10,30,60", "--seconds", "0.1", "--replicates", "2",
            "--randomize", "torso_mass=±10%", "--trace", "-q"]
    run(*args, "--shard", "1/2", "-o", tmp_path / "s1", check=0)
    run(*args, "--shard", "2/2", "-o", tmp_path / "s2", check=0)
    for name in ("replicates.csv", "traces.csv"):
        for d in ("s1", "s2"):
            (tmp_path / f"{d}-{name}").write_bytes((tmp_path / d / name).read_bytes())
        f = tmp_path / "s1" / name
        if damage == "delete":
            f.unlink()
        else:
            lines = f.read_text().splitlines(keepends=True)
            f.write_text("".join(lines[:2]))
        p = run("merge", tmp_path / "s1", tmp_path / "s2", "-o", tmp_path / "merged")
        assert p.returncode == 2 and name in p.stderr and "--resume" in p.stderr, p.stderr
        assert not (tmp_path / "merged").exists()
        # read back, the damaged shard is not complete
        assert pc.load_run(tmp_path / "s1").complete is False
        f.write_bytes((tmp_path / f"s1-{name}").read_bytes())
    assert pc.load_run(tmp_path / "s1").complete is True
    run("merge", tmp_path / "s1", tmp_path / "s2", "-o", tmp_path / "merged", check=0)


def test_smaller_holes(run, tmp_path: Path) -> None:
    """The smaller items: a resume never drops options silently, --force
    leaves nothing of the old run, merge never writes into a shard, Python
    takes one name as one name, a non-finite option names itself."""
    import math

    import pupper_core as pc

    args = ["sweep", "--grid", "kp=5,30", "--seconds", "0.2", "-q"]
    run(*args, "-o", tmp_path / "r", "--best-by", "kp", check=0)
    assert (tmp_path / "r" / "best.csv").exists()
    p = run("sweep", "--resume", tmp_path / "r", "--seconds", "5")
    assert p.returncode == 2 and "schedule.duration" in p.stderr, p.stderr
    # the same value as the run's is no conflict; a complete run says so
    again = run("sweep", "--resume", tmp_path / "r", "--seconds", "0.2", check=0)
    assert "nothing left to run" in again.stdout, again.stdout
    # --force: no best.csv of the old run beside the new summary
    run(*args, "-o", tmp_path / "r", "--force", check=0)
    assert not (tmp_path / "r" / "best.csv").exists()
    # a value given twice is refused (two cells with one id)
    dup = run("sweep", "--grid", "kp=10,10", "-o", tmp_path / "d")
    assert dup.returncode == 2 and "twice" in dup.stderr and not (tmp_path / "d").exists()
    # replicates without draws are identical: said
    same = run("sweep", "--replicates", "2", "--seconds", "0.1", "-q", "-o", tmp_path / "rep", check=0)
    assert "identical copies" in same.stderr, same.stderr
    # merge never writes into one of its shards
    for i in (1, 2):
        run(*args, "--shard", f"{i}/2", "-o", tmp_path / f"s{i}", check=0)
    m = run("merge", tmp_path / "s1", tmp_path / "s2", "-o", tmp_path / "s1", "--force")
    assert m.returncode == 2 and "itself" in m.stderr, m.stderr
    (tmp_path / "taken").mkdir()
    m = run("merge", tmp_path / "s1", tmp_path / "s2", "-o", tmp_path / "taken")
    assert m.returncode == 2 and "--force" in m.stderr and "--resume" not in m.stderr, m.stderr
    with pytest.raises(pc.ConfigError):
        pc.merge(tmp_path / "s1", tmp_path / "one")  # one path: one shard, not its letters
    # Python: one body name, a grid dict, a NaN named by its keyword
    res = pc.lab("heavy", {"kp": [30], "kd": 1}, seconds=2.0, progress=False)
    assert list(res["variant"]) == ["heavy"] and list(res["kp"]) == [30.0]
    with pytest.raises(pc.ConfigError, match="push_force=nan"):
        pc.sweep({"kp": [5]}, seconds=0.1, push_force=math.nan, progress=False)
