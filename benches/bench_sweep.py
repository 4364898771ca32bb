"""Benchmark: pupper's batched sweep vs a hand-written Python loop vs bare physics.

Run from the repository root, after `maturin develop` into the project venv:

    .venv/bin/python benches/bench_sweep.py               # 3 repeats, medians
    .venv/bin/python benches/bench_sweep.py --repeat 5 --json bench.json
    .venv/bin/python benches/bench_sweep.py --breakdown   # also time bare Batch calls

The workload is the chapter grid, kp 10,30,60,120 x kd 0.5,1,2,5 (16 cells),
servo mode, 10 s per cell at dt 0.002 (5000 steps), from the `home` keyframe,
with the default push (-25 N world z on `base_link` while
2.0 <= data.time < 2.25, decided before each step). It is timed three ways, in
this one process, each repeated --repeat times (median reported):

  pupper   pupper_core.sweep(grid, seconds=10, progress=False, threads=0):
           every cell in one mujoco.batch.Batch, all cores. Also timed with
           threads=1 to show how it scales.
  plain    what a user writes by hand (the tutorial): per cell, set the servo
           gains, mj_resetDataKeyframe, then `while data.time < 10:` set the
           push in xfrc_applied, mj_step, append qpos[2]; metrics with numpy.
           Serial, one process.
  physics  the same 16 cells with no per-step Python: mj_step(m, d, nstep)
           for 1000 steps, 126 push steps, then 3874 steps. Serial, one core.
           physics / os.cpu_count() is the "physics floor": what a perfectly
           parallel runner with zero overhead would take on this machine.

Ratios:
  speedup vs plain loop = plain / pupper        target >= 2.5 (on 2 cores)
  pupper / physics floor                        target <= 1.15 (what pupper
      adds over pure stepping: recording, metrics, the Python/Rust bridge,
      setup, and cores left idle by uneven cells and per-call barriers)
Note plain / floor = ncpu * plain / physics bounds the speedup: when the
physics dominates the hand-written loop (its per-step Python is a few us
against tens of us of physics), no runner can beat ~ncpu x. The bench prints
this bound ("best possible speedup"), the per-step Python cost, and the cores
pupper kept busy (its CPU seconds / wall seconds). Each ratio is also printed
as the median of per-repeat ratios (back-to-back runs), which drifts less.
Per-step figures are seconds / (16 * 5000) in microseconds (wall time per
cell-step, so a parallel run's figure is below its per-core cost).

PASS/MISS is printed per target; the exit status is 0 regardless, except when
the correctness check fails: pupper's final_z, last_1s_std_mm and push_dip_mm
must equal the plain loop's to 1e-9 (exit 1 otherwise).

Timings need an idle machine. The bench measures, from /proc/stat, how many
cores other processes used during each timing and prints a WARNING when that
exceeds 0.1 cores (the parallel timing suffers most); on a shared machine,
rerun until it reports "machine quiet". Even then a VM's speed can drift by
10-20% between runs, so compare ratios, not seconds, across runs.

--breakdown additionally times bare mujoco.batch.Batch calls on the same 16
cells (step vs rollout recording qpos+actuator_force, in one call and in
pupper's 250-step chunks, 1 thread and all), and the load balance of the
cells' serial costs over the cores, to show where pupper's time goes.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import mujoco
import pupper_core

ROOT = Path(__file__).resolve().parent.parent
KP = [10.0, 30.0, 60.0, 120.0]
KD = [0.5, 1.0, 2.0, 5.0]
SECONDS = 10.0
DT = 0.002
PUSH_START, PUSH_END, PUSH_FZ = 2.0, 2.25, -25.0
NSTEP = 5000
PRE_PUSH, PUSH_STEPS, POST_PUSH = 1000, 126, 3874  # sums to NSTEP
NCELL = len(KP) * len(KD)
TOL = 1e-9
SPEEDUP_TARGET = 2.5
FLOOR_TARGET = 1.15
BUSY_CORES = 0.1  # other processes' average use (cores) above which timings are flagged


def load_model() -> tuple[mujoco.MjModel, int]:
    model = mujoco.MjModel.from_xml_path(str(ROOT / "models" / "pupper_v3" / "scene.xml"))
    assert abs(model.opt.timestep - DT) < 1e-15, model.opt.timestep
    base = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "base_link")
    assert base >= 0
    assert model.nkey >= 1 and model.key(0).name == "home", "keyframe 0 must be 'home'"
    return model, base


def servo_model(base_model: mujoco.MjModel, kp: float, kd: float) -> mujoco.MjModel:
    model = copy.copy(base_model)
    model.actuator_gainprm[:, 0] = kp
    model.actuator_biasprm[:, 1] = -kp
    model.actuator_biasprm[:, 2] = -kd
    return model


# --- the three ways ---------------------------------------------------------


def _busy_cpu_seconds() -> float:
    """CPU seconds the whole machine has spent busy (all processes), from /proc/stat."""
    try:
        with open("/proc/stat") as f:
            fields = f.readline().split()[1:]
    except OSError:
        return math.nan
    user, nice, system, _idle, _iowait, irq, softirq, steal = (int(x) for x in fields[:8])
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


class Clock:
    """Wall and process CPU seconds (all threads) of a block, and how many
    cores other processes kept busy meanwhile (`others`, from /proc/stat)."""

    def __enter__(self) -> "Clock":
        self.b0 = _busy_cpu_seconds()
        self.t0, self.c0 = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc: object) -> None:
        self.wall = time.perf_counter() - self.t0
        self.cpu = time.process_time() - self.c0
        busy = _busy_cpu_seconds() - self.b0
        self.others = max(busy - self.cpu, 0.0) / self.wall if self.wall > 0 else math.nan


def run_pupper(threads: int) -> tuple[Clock, dict]:
    with Clock() as clock:
        res = pupper_core.sweep(
            {"kp": KP, "kd": KD}, seconds=SECONDS, progress=False, threads=threads
        )
    cells = {}
    for i in range(len(res)):
        r = res.row(i)
        cells[(r["kp"], r["kd"])] = (r["final_z"], r["last_1s_std_mm"], r["push_dip_mm"])
    return clock, cells


def run_plain(base_model: mujoco.MjModel, base: int) -> tuple[Clock, dict]:
    clock = Clock().__enter__()
    cells = {}
    for kp in KP:
        for kd in KD:
            model = servo_model(base_model, kp, kd)
            data = mujoco.MjData(model)
            mujoco.mj_resetDataKeyframe(model, data, 0)
            ts: list[float] = []
            zs: list[float] = []
            while data.time < SECONDS:
                data.xfrc_applied[base, 2] = (
                    PUSH_FZ if PUSH_START <= data.time < PUSH_END else 0.0
                )
                mujoco.mj_step(model, data)
                ts.append(data.time)
                zs.append(data.qpos[2])
            t = np.array(ts)
            z = np.array(zs)
            final_z = z[-1]
            std_mm = np.std(z[-500:]) * 1e3
            pre = z[(t >= PUSH_START - 0.5) & (t < PUSH_START)].mean()
            low = z[(t >= PUSH_START) & (t < PUSH_END + 1.5)].min()
            dip_mm = max(pre - low, 0.0) * 1e3
            cells[(kp, kd)] = (float(final_z), float(std_mm), float(dip_mm))
    clock.__exit__()
    return clock, cells


def run_physics(base_model: mujoco.MjModel, base: int) -> tuple[Clock, dict]:
    """Serial bare stepping; also each cell's seconds (for load-balance figures)."""
    clock = Clock().__enter__()
    per_cell = {}
    for kp in KP:
        for kd in KD:
            model = servo_model(base_model, kp, kd)
            data = mujoco.MjData(model)
            mujoco.mj_resetDataKeyframe(model, data, 0)
            mujoco.mj_step(model, data, PRE_PUSH)
            data.xfrc_applied[base, 2] = PUSH_FZ
            mujoco.mj_step(model, data, PUSH_STEPS)
            data.xfrc_applied[base, 2] = 0.0
            mujoco.mj_step(model, data, POST_PUSH)
            per_cell[(kp, kd)] = time.perf_counter() - clock.t0 - sum(per_cell.values())
    clock.__exit__()
    return clock, per_cell


# --- optional: where does pupper's time go? ---------------------------------


def batch_for_grid(base_model: mujoco.MjModel, nthread: int):
    """A bare mujoco.batch.Batch holding the 16 cells, reset to `home`."""
    import mujoco.batch

    b = mujoco.batch.Batch(base_model, NCELL, nthread)
    g, bias = b.expand("actuator_gainprm"), b.expand("actuator_biasprm")
    for i, (kp, kd) in enumerate((kp, kd) for kp in KP for kd in KD):
        g[i, :, 0] = kp
        bias[i, :, 1] = -kp
        bias[i, :, 2] = -kd
    b.reset(keyframe=0, stage=0)
    return b


def pupper_chunks() -> list[int]:
    """nstep of each rollout call pupper makes (250-step chunks cut at the push)."""
    out, k = [], 0
    while k < NSTEP:
        end = min(k + 250, NSTEP)
        for bnd in (PRE_PUSH, PRE_PUSH + PUSH_STEPS):
            if k < bnd < end:
                end = bnd
        out.append(end - k)
        k = end
    return out


def breakdown(base_model: mujoco.MjModel, repeat: int) -> dict[str, tuple[float, float, float]]:
    """Median (wall, cpu) and other processes' most cores of bare Batch calls on the 16 cells (push left out:
    it changes the work by well under 1%)."""
    rec = ("qpos", "actuator_force")
    cases = [
        ("Batch(...,1).step(nstep=5000)", 1, lambda b: b.step(nstep=NSTEP)),
        ("Batch(...,0).step(nstep=5000)", 0, lambda b: b.step(nstep=NSTEP)),
        ("Batch(...,0).rollout(5000, record=qpos+act)", 0, lambda b: b.rollout(NSTEP, record=rec)),
        ("Batch(...,0).rollout, pupper's 250-step chunks", 0,
         lambda b: [b.rollout(n, record=rec) for n in pupper_chunks()]),
        ("Batch(...,1).rollout, pupper's 250-step chunks", 1,
         lambda b: [b.rollout(n, record=rec) for n in pupper_chunks()]),
    ]
    samples: dict[str, list[Clock]] = {name: [] for name, _, _ in cases}
    for _ in range(repeat):
        for name, nthread, fn in cases:  # interleaved, like the main timings
            b = batch_for_grid(base_model, nthread)
            with Clock() as c:
                fn(b)
            samples[name].append(c)
    return {
        name: (
            statistics.median(c.wall for c in cs),
            statistics.median(c.cpu for c in cs),
            max(c.others for c in cs),
        )
        for name, cs in samples.items()
    }


def makespans(per_cell: dict, ncpu: int) -> dict[str, float]:
    """Load balance of the 16 cells' serial costs over ncpu threads, for the
    whole run in one call (the chunked calls pupper makes add their barriers)."""
    costs = [per_cell[(kp, kd)] for kp in KP for kd in KD]  # grid order

    def greedy(order: list[float]) -> float:
        # each free thread takes the next cell, as the batch appears to do
        loads = [0.0] * ncpu
        for c in order:
            loads[loads.index(min(loads))] += c
        return max(loads)

    return {
        "perfect (sum / ncpu)": sum(costs) / ncpu,
        "cells in grid order to the next free thread": greedy(costs),
        "costliest first (LPT)": greedy(sorted(costs, reverse=True)),
        "costliest cell": max(costs),
    }


# --- main -------------------------------------------------------------------


def median_clock(cs: list[Clock]) -> tuple[float, float]:
    return statistics.median(c.wall for c in cs), statistics.median(c.cpu for c in cs)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="repeats per way (median taken)")
    ap.add_argument("--json", metavar="FILE", help="write the numbers as JSON to FILE")
    ap.add_argument("--breakdown", action="store_true",
                    help="also time bare mujoco.batch.Batch calls and the cells' load balance")
    args = ap.parse_args()
    repeat = max(1, args.repeat)
    ncpu = os.cpu_count() or 1
    load0 = os.getloadavg()

    base_model, base = load_model()
    print(
        f"pupper_core {pupper_core.__version__}, mujoco {mujoco.__version__}, "
        f"os.cpu_count() = {ncpu}, {NCELL} cells x {NSTEP} steps, repeat {repeat}, "
        f"load average {load0[0]:.2f}",
        flush=True,
    )

    # warm-up: imports, thread pools, caches
    pupper_core.sweep({"kp": [10.0], "kd": [1.0]}, seconds=0.2, progress=False)
    m = servo_model(base_model, 10.0, 1.0)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_step(m, d, 200)

    runs: dict[str, list[Clock]] = {"pupper": [], "pupper1": [], "plain": [], "physics": []}
    per_cell_runs: list[dict] = []
    pupper_cells = plain_cells = None
    for r in range(repeat):
        # interleaved, so that drift in the machine's speed hits every way alike
        c, pupper_cells = run_pupper(threads=0)
        runs["pupper"].append(c)
        c, _ = run_pupper(threads=1)
        runs["pupper1"].append(c)
        c, plain_cells = run_plain(base_model, base)
        runs["plain"].append(c)
        c, per_cell = run_physics(base_model, base)
        runs["physics"].append(c)
        per_cell_runs.append(per_cell)
        print(
            f"  repeat {r + 1}/{repeat}: "
            + ", ".join(f"{k} {v[-1].wall:.3f} s" for k, v in runs.items())
            + f"; other processes used {max(v[-1].others for v in runs.values()):.2f} cores",
            flush=True,
        )

    # correctness: pupper vs the hand-written loop
    assert pupper_cells is not None and plain_cells is not None
    names = ("final_z", "last_1s_std_mm", "push_dip_mm")
    maxdiff = {n: 0.0 for n in names}
    missing = sorted(set(plain_cells) ^ set(pupper_cells))
    for key, want in plain_cells.items():
        got = pupper_cells.get(key)
        if got is None:
            continue
        for n, a, b in zip(names, got, want):
            if np.isnan(a) and np.isnan(b):
                diff = 0.0
            elif np.isfinite(a) and np.isfinite(b):
                diff = abs(a - b)
            else:
                diff = float("inf")
            maxdiff[n] = max(maxdiff[n], diff)
    correct = max(maxdiff.values()) <= TOL and not missing

    (pupper, pupper_cpu), (pupper1, pupper1_cpu) = median_clock(runs["pupper"]), median_clock(runs["pupper1"])
    (plain, plain_cpu), (phys, phys_cpu) = median_clock(runs["plain"]), median_clock(runs["physics"])
    floor = phys / ncpu
    speedup = plain / pupper
    over_floor = pupper / floor
    us = lambda s: s / (NCELL * NSTEP) * 1e6  # noqa: E731

    print()
    print(f"{'way (median of ' + str(repeat) + ')':<36}{'seconds':>9}{'us/step':>9}{'cpu s':>8}{'cpu/wall':>9}")
    rows = [
        ("pupper sweep (threads=0)", pupper, pupper_cpu),
        ("pupper sweep (threads=1)", pupper1, pupper1_cpu),
        ("plain Python loop (serial)", plain, plain_cpu),
        ("physics alone (serial, 1 core)", phys, phys_cpu),
        (f"physics floor (= physics / {ncpu})", floor, None),
    ]
    for name, s, c in rows:
        cpu = f"{c:>8.3f}{c / s:>9.2f}" if c is not None else ""
        print(f"{name:<36}{s:>9.3f}{us(s):>9.2f}{cpu}")
    print()
    ok1 = speedup >= SPEEDUP_TARGET
    ok2 = over_floor <= FLOOR_TARGET
    print(f"speedup vs plain loop  = plain / pupper          = {speedup:6.2f}   "
          f"target >= {SPEEDUP_TARGET}  {'PASS' if ok1 else 'MISS'}")
    print(f"pupper / physics floor = pupper / (physics / {ncpu}) = {over_floor:6.2f}   "
          f"target <= {FLOOR_TARGET} {'PASS' if ok2 else 'MISS'}")
    # the same ratios per repeat (each from back-to-back runs), then their median:
    # steadier than the ratio of medians when the machine's speed drifts
    paired_speedup = statistics.median(
        p.wall / q.wall for p, q in zip(runs["plain"], runs["pupper"]))
    paired_floor = statistics.median(
        q.wall / (f.wall / ncpu) for q, f in zip(runs["pupper"], runs["physics"]))
    print(f"  (median of per-repeat ratios: speedup {paired_speedup:.2f}, "
          f"pupper / floor {paired_floor:.2f})")
    print(f"scaling: pupper threads=1 / threads=0            = {pupper1 / pupper:6.2f}")
    print(f"cores kept busy by pupper threads=0 (cpu/wall)   = {pupper_cpu / pupper:6.2f} of {ncpu}")
    print(f"serial overhead: pupper threads=1 / physics      = {pupper1 / phys:6.2f}")
    print(f"Python per-step cost: (plain - physics) / steps  = {us(plain - phys):6.2f} us")
    print(f"best possible speedup on {ncpu} cores: plain / floor  = {plain / floor:6.2f}")
    print()
    print("correctness (pupper vs plain loop, max abs diff over 16 cells): "
          + ", ".join(f"{n} {v:.3g}" for n, v in maxdiff.items())
          + f"  -> {'OK' if correct else 'FAIL'} (tol {TOL:g})")
    if missing:
        print(f"cells missing from one side: {missing}")

    # other processes on the machine steal cores from the parallel run
    load1 = os.getloadavg()
    others = max(c.others for cs in runs.values() for c in cs)
    busy = not (others <= BUSY_CORES)
    if busy:
        print(f"\nWARNING: other processes kept up to {others:.2f} cores busy during the timings "
              f"(load average {load0[0]:.2f} -> {load1[0]:.2f}), so they are unreliable, the "
              "parallel ones most: rerun on an idle machine.")
    else:
        print(f"machine quiet: other processes used at most {others:.2f} cores during the timings")

    bd = spans = None
    if args.breakdown:
        bd = breakdown(base_model, repeat)
        print()
        print(f"breakdown: bare mujoco.batch.Batch on the 16 cells (median of {repeat})")
        for name, (s, c, o) in bd.items():
            print(f"  {name:<48}{s:>8.3f} s {us(s):>7.2f} us/step  cpu/wall {c / s:.2f}"
                  f"  others {o:.2f} cores")
        # the least disturbed of the repeats estimates each cell's cost best
        cell_min = {k: min(pc[k] for pc in per_cell_runs) for k in per_cell_runs[0]}
        spans = makespans(cell_min, ncpu)
        print(f"load balance of the cells' serial costs (physics way, fastest repeat) over {ncpu} threads:")
        for name, s in spans.items():
            print(f"  {name:<48}{s:>8.3f} s")

    if args.json:
        payload = {
            "cpu_count": ncpu,
            "repeat": repeat,
            "cells": NCELL,
            "steps": NSTEP,
            "load_average": [load0[0], load1[0]],
            "machine_busy": busy,
            "other_processes_max_cores": others,
            "seconds": {
                "pupper": pupper,
                "pupper_threads1": pupper1,
                "plain": plain,
                "physics_serial": phys,
                "physics_floor": floor,
            },
            "cpu_seconds": {
                "pupper": pupper_cpu,
                "pupper_threads1": pupper1_cpu,
                "plain": plain_cpu,
                "physics_serial": phys_cpu,
            },
            "samples": {k: [c.wall for c in v] for k, v in runs.items()},
            "samples_other_cores": {k: [c.others for c in v] for k, v in runs.items()},
            "us_per_step": {
                "pupper": us(pupper),
                "pupper_threads1": us(pupper1),
                "plain": us(plain),
                "physics_serial": us(phys),
                "physics_floor": us(floor),
            },
            "speedup_vs_plain": speedup,
            "speedup_vs_plain_paired_median": paired_speedup,
            "pupper_over_floor_paired_median": paired_floor,
            "speedup_target": SPEEDUP_TARGET,
            "speedup_pass": ok1,
            "pupper_over_floor": over_floor,
            "floor_target": FLOOR_TARGET,
            "floor_pass": ok2,
            "correctness_max_abs_diff": maxdiff,
            "correct": correct,
            "breakdown": None if bd is None else {
                k: {"wall": w, "cpu": c, "other_processes_max_cores": o} for k, (w, c, o) in bd.items()
            },
            "load_balance_seconds": spans,
        }
        with open(args.json, "w") as f:
            json.dump(payload, f, indent=2)
        print(f"\nwrote {args.json}")

    if not correct:
        print("FAIL: pupper's metrics differ from the plain loop's", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
