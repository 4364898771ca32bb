"""Benchmark: `pupper sweep --ray` against the same sweep run locally, on the
same machine.

Run from the repository root, after `make setup PUPPER_EXTRAS=ray` (needs
root, or user namespaces, for the loopback cluster):

    .venv/bin/python benches/bench_ray.py                 # 3 repeats, medians
    .venv/bin/python benches/bench_ray.py --seconds 3 --repeat 5 --json ray.json

The workload is a 256-cell grid, kp 5,10,20,30,45,60,90,120 x kd 0.1,0.5,1,2
x push_force -10,-25,-40,-60,-80,-100,-120,-150 N, servo mode, --seconds
per cell (default 10: the chapter's schedule, 5000 steps at dt 0.002). It is
run two ways, alternating, each --repeat times, as whole `pupper` commands
(process start, model load and writing the run directory included in both):

  local   pupper sweep GRID -j CORES: one process, every core of this machine.
  ray     pupper sweep GRID --ray 127.0.0.1:6379 on a Ray cluster of --nodes
          nodes with CORES/nodes CPUs each, all on this machine (in a network
          and PID namespace of their own, tests/loopback_ray.py): the same
          cores, so the ratio is what --ray adds: connecting, shipping tasks
          and results, per-task model loads, and the tail of the last tasks.
          The cluster is started once, before the timings.

Ratio: ray / local (median of per-repeat ratios), target <= 1.3. Both runs'
summary.csv must be byte-identical (exit 1 otherwise). PASS/MISS is printed;
the exit status is 0 regardless. Timings need an idle machine.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from loopback_ray import ADDRESS, LoopbackCluster, clean_env  # noqa: E402

GRID = ["--grid", "kp=5,10,20,30,45,60,90,120", "--grid", "kd=0.1,0.5,1,2",
        "--grid", "push_force=-10,-25,-40,-60,-80,-100,-120,-150"]
TARGET = 1.3


def timed(cmd: list[str], cwd: Path) -> float:
    t = time.perf_counter()
    subprocess.run(cmd, cwd=cwd, env=clean_env(), check=True, capture_output=True, timeout=3600)
    return time.perf_counter() - t


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per cell")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--nodes", type=int, default=2, help="Ray nodes sharing this machine's cores")
    ap.add_argument("--bin", default=str(ROOT / "target" / "release" / "pupper"))
    ap.add_argument("--json", help="also write the figures here")
    a = ap.parse_args()
    cores = os.cpu_count() or 1
    per_node = max(1, cores // a.nodes)
    args = [*GRID, "--seconds", str(a.seconds), "-q"]
    print(f"256 cells x {a.seconds:g} s; local: -j {cores}; "
          f"ray: {a.nodes} nodes x {per_node} CPUs, all on this machine")
    cluster = LoopbackCluster(nodes=a.nodes, cpus=per_node)
    local_s, ray_s = [], []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp)
            for i in range(a.repeat):
                lo, ra = work / f"local{i}", work / f"ray{i}"
                local_s.append(timed([a.bin, "sweep", *args, "-j", str(cores), "-o", str(lo)], work))
                ray_s.append(timed([*cluster.enter(), a.bin, "sweep", *args, "--ray", ADDRESS,
                                    "-o", str(ra)], work))
                if (lo / "summary.csv").read_bytes() != (ra / "summary.csv").read_bytes():
                    print("FAIL: --ray wrote another summary.csv than the local run")
                    return 1
                print(f"  repeat {i + 1}: local {local_s[-1]:.2f} s, ray {ray_s[-1]:.2f} s, "
                      f"ratio {ray_s[-1] / local_s[-1]:.3f}")
    finally:
        cluster.stop()
    ratio = statistics.median(r / lo for r, lo in zip(ray_s, local_s))
    print(f"local {statistics.median(local_s):.2f} s, ray {statistics.median(ray_s):.2f} s "
          f"(medians); summary.csv identical")
    print(f"ray / local = {ratio:.3f} (target <= {TARGET}): {'PASS' if ratio <= TARGET else 'MISS'}")
    if a.json:
        Path(a.json).write_text(json.dumps({
            "cells": 256, "seconds": a.seconds, "cores": cores, "nodes": a.nodes,
            "local_s": local_s, "ray_s": ray_s, "ratio": ratio,
        }, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
