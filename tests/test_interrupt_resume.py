"""Ctrl-C / SIGTERM keep the finished cells; --resume finishes the run and
gives the same summary.csv as an uninterrupted run."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest

from conftest import clean_env, read_csv, wait_rows

# 48 cells of 10 s, 4 per chunk, one thread: ~10+ s on 2 cores, so a signal
# sent after the first chunk lands mid-run.
ARGS = ["sweep", "--grid", "kp=10:120:24", "--grid", "kd=0.5,1", "--seconds", "10",
        "--chunk-cells", "4", "--threads", "1", "-q"]
CELLS = 48


@pytest.fixture(scope="module")
def reference(pupper_bin, tmp_path_factory):
    """An uninterrupted run of the same command, started in the background
    (it overlaps the interrupted run's resume); call it to wait for the dir."""
    d = tmp_path_factory.mktemp("reference")
    out = d / "full"
    proc = subprocess.Popen([str(pupper_bin), *ARGS, "-o", str(out)], cwd=d, env=clean_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def wait() -> Path:
        so, se = proc.communicate(timeout=300)
        assert proc.returncode == 0, se
        return out

    yield wait
    if proc.poll() is None:
        proc.kill()
        proc.wait()


def assert_same_csv(got: Path, want: Path) -> None:
    a, b = got.read_bytes(), want.read_bytes()
    if a != b:
        diff = [(x, y) for x, y in zip(a.decode().splitlines(), b.decode().splitlines()) if x != y]
        raise AssertionError(
            f"{got} differs from the uninterrupted {want} in {len(diff)} line(s):\n"
            + "\n".join(f"  resumed: {x}\n  full:    {y}" for x, y in diff[:4])
        )


def data_rows(path: Path) -> int:
    try:
        text = path.read_text()
    except FileNotFoundError:
        return 0
    return max(0, len([l for l in text.splitlines() if l]) - 1)


def start_and_interrupt(pupper_bin, tmp_path, out, sig) -> subprocess.CompletedProcess:
    proc = subprocess.Popen([str(pupper_bin), *ARGS, "-o", str(out)], cwd=tmp_path,
                            env=clean_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        deadline = time.monotonic() + 120
        while data_rows(out / "summary.csv") < 1:
            assert proc.poll() is None, f"exited {proc.returncode} before any chunk: {proc.stderr.read()}"
            assert time.monotonic() < deadline, "no row in summary.csv after 120 s"
            time.sleep(0.05)
        assert proc.poll() is None, "the run finished before the signal: make the grid bigger"
        sent = time.monotonic()
        proc.send_signal(sig)
        so, se = proc.communicate(timeout=10)
        elapsed = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert elapsed < 5, f"took {elapsed:.1f} s to stop after the signal"
    return subprocess.CompletedProcess(proc.args, proc.returncode, so, se)


def check_interrupted(p: subprocess.CompletedProcess, out: Path) -> int:
    assert p.returncode == 130, f"exit {p.returncode}\n{p.stderr}"
    assert "--resume" in p.stderr, p.stderr
    assert "Traceback" not in p.stderr and "panicked" not in p.stderr
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] is False
    header, rows = read_csv(out / "summary.csv")  # parses, no truncated line
    assert 1 <= len(rows) < CELLS
    assert manifest["cells_done"] == len(rows)
    assert manifest["cells_total"] == CELLS
    assert header[0] == "index"
    # the kept cells are the first ones, in grid order
    assert [int(r["index"]) for r in rows] == list(range(len(rows)))
    return len(rows)


def test_sigint_then_resume_alone(pupper_bin, run, tmp_path, reference):
    out = tmp_path / "run"
    p = start_and_interrupt(pupper_bin, tmp_path, out, signal.SIGINT)
    check_interrupted(p, out)
    r = run("sweep", "--resume", out, "-q", timeout=300)
    assert r.returncode == 0, r.stderr
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] is True and manifest["cells_done"] == CELLS
    full = reference()
    assert_same_csv(out / "summary.csv", full / "summary.csv")


def test_sigterm_then_resume_with_the_original_command(pupper_bin, run, tmp_path, reference):
    out = tmp_path / "run"
    p = start_and_interrupt(pupper_bin, tmp_path, out, signal.SIGTERM)
    check_interrupted(p, out)
    r = run(*ARGS, "--resume", out, timeout=300)
    assert r.returncode == 0, r.stderr
    full = reference()
    assert_same_csv(out / "summary.csv", full / "summary.csv")


def test_resume_with_different_inputs_is_refused(pupper_bin, run, tmp_path):
    out = tmp_path / "run"
    p = start_and_interrupt(pupper_bin, tmp_path, out, signal.SIGINT)
    kept = check_interrupted(p, out)
    before = (out / "summary.csv").read_bytes()
    r = run("sweep", "--resume", out, "--grid", "kp=1")
    assert r.returncode == 2, r.stderr
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    assert "differ" in lines[0] and "--resume" in lines[0], lines[0]
    # nothing changed
    assert (out / "summary.csv").read_bytes() == before
    assert data_rows(out / "summary.csv") == kept
    assert json.loads((out / "manifest.json").read_text())["complete"] is False


def test_resume_of_a_missing_directory(run, tmp_path):
    r = run("sweep", "--resume", tmp_path / "nope")
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.splitlines()) == 1 and r.stderr.startswith("error: "), r.stderr
    assert not (tmp_path / "nope").exists()


def test_python_sweep_stops_cleanly_on_keyboard_interrupt(tmp_path: Path) -> None:
    """In a notebook, Ctrl-C raises KeyboardInterrupt within a second and keeps
    the finished chunks in the run directory."""
    out = tmp_path / "run"
    script = (
        # Python's own Ctrl-C handling, as in a notebook; a shell that starts a
        # job in the background leaves SIGINT ignored, and Python keeps that.
        "import signal\n"
        "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
        "import pupper_core as pc\n"
        "try:\n"
        f"    pc.sweep({{'kp': [10 + i for i in range(48)]}}, seconds=10, chunk_cells=4, threads=1,\n"
        f"             out={str(out)!r}, progress=False)\n"
        "except KeyboardInterrupt:\n"
        "    print('KeyboardInterrupt', flush=True)\n"
        "    raise SystemExit(42)\n"
    )
    import sys
    import time

    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    summary = out / "summary.csv"
    wait_rows(summary, proc, 1)
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=30)
    latency = time.monotonic() - sent
    print(f"stopped {latency:.2f} s after SIGINT")
    # about 0.1 s here; the margin is for a loaded machine
    assert latency < 5
    assert proc.returncode == 42, stderr
    assert "KeyboardInterrupt" in stdout
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] is False
    rows = summary.read_text().splitlines()[1:]
    assert 1 <= len(rows) < 48
    assert all(r.count(",") == rows[0].count(",") for r in rows)
