"""`--ray` on a real two-node Ray cluster over loopback.

The cluster (tests/loopback_ray.py: a head and a second worker node, one
CPU each) runs inside a network and PID namespace of its own: nothing
outside can reach it, and it ends with its namespace. Drivers join its
network namespace with `nsenter`.
`make test` installs the optional extra (ray), so these run real Ray.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import clean_env, hidden, same_files, wait_rows

pytest.importorskip("ray", reason="the ray extra is not installed: make test installs it")

from loopback_ray import ADDRESS, LoopbackCluster

GRID16 = ["--grid", "kp=10,30,60,120", "--grid", "kd=0.5,1,2,5"]


def start_cluster(**kw) -> LoopbackCluster:
    try:
        return LoopbackCluster(**kw)
    except RuntimeError as e:
        pytest.fail(str(e), pytrace=False)


@pytest.fixture(scope="module")
def cluster():
    c = start_cluster()
    yield c
    c.stop()


@pytest.fixture
def in_cluster(cluster, pupper_bin, tmp_path):
    """Runs pupper (or, with python=True, Python) in the cluster's network."""

    def _run(*args, check: int | None = 0, python: bool = False, env: dict | None = None,
             timeout: float = 300):
        exe = [sys.executable] if python else [str(pupper_bin)]
        p = subprocess.run([*cluster.enter(), *exe, *map(str, args)], cwd=tmp_path,
                           env=clean_env(**(env or {})), capture_output=True, text=True,
                           timeout=timeout)
        if check is not None:
            assert p.returncode == check, (args, p.returncode, p.stdout[-3000:], p.stderr[-3000:])
        return p

    return _run


#: Ray's own lines on a driver's stderr: no route out of the namespace (it
#: only has loopback), and, at times through Ray's client, that Ray did not
#: take SIGTERM (pupper keeps its own handler either way).
RAY_NOISE = ("network_util.cc", "SIGTERM handler is not set")


def own_lines(stderr: str) -> list[str]:
    """stderr without Ray's own warnings."""
    return [ln for ln in stderr.strip().splitlines() if not any(n in ln for n in RAY_NOISE)]


def manifest(d: Path) -> dict:
    return json.loads((d / "manifest.json").read_text())


def test_default_sweep_on_ray_equals_a_local_run(run, in_cluster, tmp_path):
    """`make sweep`'s grid, on Ray by RAY_ADDRESS (--ray auto): the same
    bytes as here; the manifest says where it ran, and nothing else differs."""
    in_cluster("sweep", *GRID16, "--ray", "auto", "-q", "-o", tmp_path / "ray",
               env={"RAY_ADDRESS": ADDRESS})
    run("sweep", *GRID16, "-q", "-o", tmp_path / "local", check=0)
    same_files(tmp_path / "ray", tmp_path / "local")
    m, local = manifest(tmp_path / "ray"), manifest(tmp_path / "local")
    assert m["config"] == local["config"] and m["complete"]
    assert len(m["ray"]["nodes"]) == 2 and m["ray"]["slots"] == 2
    assert m["ray"]["threads_per_task"] == 1 and m["ray"]["address"] == "auto"
    assert "ray" not in local


def test_replicates_traces_and_python_on_ray(in_cluster, tmp_path):
    """A replicated sweep with traces, from Python (`ray=`): summary.csv,
    replicates.csv and traces.csv equal a local run's byte for byte."""
    code = f"""
import pupper_core as pc, sys
for where, ray in (("ray", {ADDRESS!r}), ("local", None)):
    pc.sweep({{"kp": [10, 60], "kd": [0.5, 2]}}, seconds=2.5, push_at=1.0, replicates=3,
             seed=7, randomize=["torso_mass=±10%", "friction=0.6:1.2"], trace=True,
             out=sys.argv[1] + "/" + where, ray=ray, progress=False)
"""
    in_cluster("-c", code, tmp_path, python=True)
    same_files(tmp_path / "ray", tmp_path / "local",
               ("summary.csv", "replicates.csv", "traces.csv"))


def test_a_notebook_connection_is_used_only_when_asked(in_cluster, tmp_path):
    """Python already connected to Ray (a notebook's ray.init): ray="auto"
    runs on that connection and leaves it open; another address is refused
    (pc.ClusterError, one line) rather than silently ignored."""
    code = f"""
import logging, ray, pupper_core as pc
ray.init({ADDRESS!r}, logging_level=logging.ERROR)
res = pc.sweep({{"kp": [10, 60]}}, seconds=1, ray="auto", progress=False)
print("rows", len(res.table["id"]), "still", ray.is_initialized())
try:
    pc.sweep({{"kp": [10]}}, seconds=1, ray="127.0.0.1:6380", progress=False)
except pc.ClusterError as e:
    print("refused", e.kind, e)
"""
    p = in_cluster("-c", code, python=True)
    assert "rows 2 still True" in p.stdout, p.stdout + p.stderr
    assert "refused cluster this Python is already connected" in p.stdout, p.stdout


def test_lab_on_ray_equals_a_local_lab(run, in_cluster, tmp_path):
    """`pupper lab --ray`: three bodies from their own stand poses, torque
    mode under the sine force; same table and best gains as a local lab."""
    args = ["--grid", "kp=30,60", "--grid", "kd=1,2", "--seconds", "1.5", "-q"]
    in_cluster("lab", *args, "--ray", ADDRESS, "-o", tmp_path / "ray")
    run("lab", *args, "-o", tmp_path / "local", check=0)
    same_files(tmp_path / "ray", tmp_path / "local", ("summary.csv", "best.csv"))


def test_ray_client_address(run, in_cluster, cluster, tmp_path):
    """ray://HOST:PORT goes through Ray's client (the head's port 10001)."""
    args = ["--grid", "kp=10,120", "--seconds", "2", "--no-push", "-q"]
    p = in_cluster("sweep", *args, "--ray", "ray://127.0.0.1:10001", "-o", tmp_path / "client",
                   check=None)
    # the head's client server logs, should it have failed
    logs = "".join(f"\n--- {f.name}\n{f.read_text()[-2000:]}"
                   for f in sorted(cluster.tmp.glob("session_latest/logs/ray_client_server*")))
    assert p.returncode == 0, (p.stderr, logs)
    assert own_lines(p.stderr) == [], p.stderr
    run("sweep", *args, "-o", tmp_path / "local", check=0)
    same_files(tmp_path / "client", tmp_path / "local")


# 128 cells of 4 s in tasks of 4 cells: long enough to stop mid-way
LONG = ["--grid", "kp=5,10,20,30,45,60,90,120", "--grid", "kd=0.1,0.5,1,2",
        "--grid", "push_force=-10,-25,-50,-80", "--seconds", "4", "--chunk-cells", "4", "-q"]


@pytest.mark.parametrize("resume_on", ["ray", "local"])
def test_interrupted_driver_resumes_to_the_same_bytes(cluster, run, pupper_bin, tmp_path,
                                                      resume_on):
    """Ctrl-C on the driver mid-sweep: finished tasks are kept, running ones
    cancelled (exit 130); --resume, on Ray or here, ends identical."""
    out = tmp_path / "run"
    p = subprocess.Popen([*cluster.enter(), str(pupper_bin), "sweep", *LONG, "--ray", ADDRESS,
                          "-o", out], cwd=tmp_path, env=clean_env(),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_rows(out / "summary.csv", p, 8)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
    finally:
        p.kill()
    assert p.returncode == 130, err
    assert f"--resume {out} --ray {ADDRESS}" in err, err
    m = manifest(out)
    assert not m["complete"] and 8 <= m["cells_done"] < 128, m["cells_done"]
    resume = ["sweep", "--resume", out] + (["--ray", ADDRESS] if resume_on == "ray" else [])
    if resume_on == "ray":
        subprocess.run([*cluster.enter(), str(pupper_bin), *resume], cwd=tmp_path,
                       env=clean_env(), check=True, capture_output=True, timeout=300)
    else:
        run(*resume, check=0)
    run("sweep", *LONG, "-o", tmp_path / "local", check=0)
    same_files(out, tmp_path / "local")
    assert manifest(out)["complete"]


def test_errors_are_one_line_and_write_nothing(run, in_cluster, tmp_path):
    """A bad address, no cluster there, or tasks bigger than any node: one
    line naming the fix, exit 2, no run directory."""
    cases = [
        (["--ray", "headnode"], "is not a Ray address", run),
        (["--ray", "127.0.0.1:1"], "nothing answers at 127.0.0.1:1", run),
        (["--ray", ADDRESS, "-j", "2"], "--threads 2 asks each task for more CPUs", in_cluster),
    ]
    for i, (args, words, runner) in enumerate(cases):
        out = tmp_path / f"never{i}"
        p = runner("sweep", "--grid", "kp=10", "--seconds", "0.5", *args, "-o", out, check=2)
        lines = own_lines(p.stderr)
        assert len(lines) == 1 and words in lines[0], (args, p.stderr)
        assert not out.exists()


def test_without_ray_installed_one_line_names_the_extra(run, tmp_path):
    out = tmp_path / "never"
    p = run("sweep", "--grid", "kp=10", "--ray", ADDRESS, "-o", out,
            env=hidden(tmp_path, "ray"), check=2)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "pupper_core[ray]" in lines[0], p.stderr
    assert not out.exists()


def test_nodes_without_pupper_core_are_refused_before_anything_is_written(pupper_bin, tmp_path):
    """Workers that cannot import pupper_core (hidden from the nodes by a
    sitecustomize): one line saying what to install where, exit 2, no run
    directory."""
    c = start_cluster(env=hidden(tmp_path, "pupper_core"))
    try:
        out = tmp_path / "never"
        p = subprocess.run([*c.enter(), str(pupper_bin), "sweep", "--grid", "kp=10", "--ray",
                            ADDRESS, "-o", out], cwd=tmp_path, env=clean_env(),
                           capture_output=True, text=True, timeout=300)
    finally:
        c.stop()
    assert p.returncode == 2, p.stderr
    lines = own_lines(p.stderr)
    assert len(lines) == 1 and "cannot import pupper_core" in lines[0], p.stderr
    assert "make wheel" in lines[0]
    assert not out.exists()


def test_a_killed_worker_node_loses_nothing(pupper_bin, run, tmp_path):
    """A 256-cell grid on a fresh two-node cluster whose second node's raylet
    is SIGKILLed mid-sweep: Ray runs its tasks again on the head, and the
    summary.csv is a local run's, byte for byte."""
    grid = ["--grid", "kp=5,10,20,30,45,60,90,120", "--grid", "kd=0.1,0.5,1,2",
            "--grid", "push_force=-10,-25,-40,-60,-80,-100,-120,-150", "--seconds", "2",
            "--push-at", "1", "-q"]
    c = start_cluster()
    try:
        out = tmp_path / "ray"
        p = subprocess.Popen([*c.enter(), str(pupper_bin), "sweep", *grid, "--ray", ADDRESS,
                              "--chunk-cells", "8", "-o", out], cwd=tmp_path, env=clean_env(),
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            wait_rows(out / "summary.csv", p, 16)
            c.kill_worker_node()
            _, err = p.communicate(timeout=300)
        finally:
            p.kill()
        assert p.returncode == 0, err
    finally:
        c.stop()
    run("sweep", *grid, "-o", tmp_path / "local", check=0)
    same_files(out, tmp_path / "local")
    assert manifest(out)["cells_done"] == 256
