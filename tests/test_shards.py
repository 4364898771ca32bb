"""Sharded sweeps (`--shard I/N`) and `pupper merge`: shards merged equal
one run byte for byte; bad sets of shards are refused in one line."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from conftest import clean_env, read_csv

pc = pytest.importorskip("pupper_core")

# an uneven grid (7 x 2: 14 cells over 3 shards), traces kept
GRID = ["--grid", "kp=8,15,30,45,60,90,120", "--grid", "kd=0.3,2", "--seconds", "1.5",
        "--push-at", "0.5", "--trace", "-q"]


def shards(run, tmp_path: Path, n: int, *extra: str) -> list[Path]:
    dirs = []
    for i in range(1, n + 1):
        d = tmp_path / f"shard{i}"
        run("sweep", *GRID, *extra, "--shard", f"{i}/{n}", "-o", d, check=0)
        dirs.append(d)
    return dirs


FILES = ("summary.csv", "traces.csv")


def test_three_shards_merge_to_one_run(run, tmp_path):
    dirs = shards(run, tmp_path, 3)
    run("sweep", *GRID, "-o", tmp_path / "whole", check=0)
    # interleaved: shard 2/3 holds cells 1, 4, 7, 10, 13
    _, rows = read_csv(dirs[1] / "summary.csv")
    assert [int(r["index"]) for r in rows] == [1, 4, 7, 10, 13]
    m = json.loads((dirs[1] / "manifest.json").read_text())
    assert m["shard"]["index"] == 2 and m["shard"]["count"] == 3 and m["shard"]["host"]
    assert m["cells_total"] == 5 and m["complete"]
    assert len(m["config"]["grid"]["axes"][0]["values"]) == 7, "a shard's manifest keeps the whole grid"
    p = run("merge", *dirs, "-o", tmp_path / "merged", check=0)
    assert "merged 3 shards (14 cells)" in p.stdout
    for f in FILES:
        assert (tmp_path / "merged" / f).read_bytes() == (tmp_path / "whole" / f).read_bytes(), f
    merged = json.loads((tmp_path / "merged" / "manifest.json").read_text())
    assert merged["complete"] and merged["cells_total"] == 14 and "shard" not in merged
    assert [s["index"] for s in merged["merged"]] == [1, 2, 3]
    assert all(s["host"] and s["wall_seconds"] > 0 and s["cells"] in (4, 5) for s in merged["merged"])
    # the merged run is an ordinary run directory
    res = pc.load_run(tmp_path / "merged")
    assert len(res) == 14
    # shards given in any order, from Python
    again = pc.merge(list(reversed(dirs)), tmp_path / "py")
    assert (tmp_path / "py" / "summary.csv").read_bytes() == (tmp_path / "whole" / "summary.csv").read_bytes()
    assert len(again) == 14


def test_replicated_shards_merge_to_one_run(run, tmp_path):
    rep = ["--replicates", "3", "--randomize", "torso_mass=±10%", "--seed", "5"]
    dirs = shards(run, tmp_path, 2, *rep)
    run("sweep", *GRID, *rep, "-o", tmp_path / "whole", check=0)
    run("merge", *dirs, "-o", tmp_path / "merged", check=0)
    for f in ("summary.csv", "replicates.csv", "traces.csv"):
        assert (tmp_path / "merged" / f).read_bytes() == (tmp_path / "whole" / f).read_bytes(), f


def one_line_exit_2(run, out: Path, *args) -> str:
    p = run("merge", *args, "-o", out, check=2)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    assert not out.exists(), "a refused merge left a directory"
    return lines[0]


def test_bad_sets_of_shards_are_refused(run, tmp_path):
    s1, s2, s3 = shards(run, tmp_path, 3)
    out = tmp_path / "never"
    line = one_line_exit_2(run, out, s1, s3)
    assert "shard 2/3" in line and "--shard 2/3" in line, line
    line = one_line_exit_2(run, out, s1, s2, s2, s3)
    assert "twice" in line and "2/3" in line, line
    # a shard of another grid
    other = tmp_path / "other"
    run("sweep", "--grid", "kp=8,15", *GRID[4:], "--shard", "2/3", "-o", other, check=0)
    line = one_line_exit_2(run, out, s1, other, s3)
    assert "different sweeps" in line and "grid" in line, line
    # a whole run is not a shard
    whole = tmp_path / "whole"
    run("sweep", "--grid", "kp=8", "--seconds", "0.5", "--no-push", "-q", "-o", whole, check=0)
    assert "not a shard" in one_line_exit_2(run, out, whole, s1)
    # an out that exists
    out.mkdir()
    p = run("merge", s1, s2, s3, "-o", out, check=2)
    assert "already exists" in p.stderr


@pytest.mark.parametrize("text", ["0/3", "4/3", "2", "a/b"])
def test_bad_shard_flag(run, tmp_path, text):
    p = run("sweep", "--shard", text, "-o", tmp_path / "never", check=2)
    assert len(p.stderr.strip().splitlines()) == 1 and "I/N" in p.stderr
    assert not (tmp_path / "never").exists()


def test_interrupted_shard_resumes_then_merges(pupper_bin, run, tmp_path):
    """Ctrl-C in a shard, then `--resume DIR` alone (which keeps its shard):
    the merged result equals one run."""
    grid = ["--grid", "kp=8,15,30,45,60,90,120", "--grid", "kd=0.3,1,2", "--seconds", "4",
            "--push-at", "1", "-q", "-j", "1", "--chunk-cells", "1"]
    s1 = tmp_path / "s1"
    proc = subprocess.Popen([str(pupper_bin), "sweep", *grid, "--shard", "1/2", "-o", str(s1)],
                            cwd=tmp_path, env=clean_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    manifest = s1 / "manifest.json"
    deadline = time.time() + 120
    while time.time() < deadline:
        if manifest.exists() and json.loads(manifest.read_text() or "{}").get("cells_done", 0) >= 1:
            break
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGINT)
    proc.communicate(timeout=120)
    m = json.loads(manifest.read_text())
    assert not m["complete"] and m["cells_done"] < m["cells_total"] == 11, m
    # a merge refuses the unfinished shard, saying how to finish it
    run("sweep", *grid, "--shard", "2/2", "-o", tmp_path / "s2", check=0)
    line = one_line_exit_2(run, tmp_path / "never", s1, tmp_path / "s2")
    assert "incomplete" in line and "--resume" in line, line
    # resuming with another shard is refused
    p = run("sweep", *grid, "--shard", "2/2", "--resume", s1, check=2)
    assert "shard 1/2" in p.stderr
    run("sweep", "--resume", s1, "-q", check=0)
    run("sweep", *grid, "-o", tmp_path / "whole", check=0)
    run("merge", s1, tmp_path / "s2", "-o", tmp_path / "merged", check=0)
    assert (tmp_path / "merged" / "summary.csv").read_bytes() == \
        (tmp_path / "whole" / "summary.csv").read_bytes()
