"""Benchmark: pupper's batched sweep vs a hand-written Python loop vs bare physics.

Run from the repository root, after `maturin develop` into the project venv:

    .venv/bin/python benches/bench_sweep.py               # 3 repeats, medians
    .venv/bin/python benches/bench_sweep.py --repeat 5 --json /tmp/bench.json
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
  pupper / physics floor                        target <= 1.15 (overhead of
      recording, metrics and the Python/Rust bridge over pure stepping)
Per-step figures are seconds / (16 * 5000) in microseconds (wall time per
cell-step, so a parallel run's figure is below its per-core cost).

PASS/MISS is printed per target; the exit status is 0 regardless, except when
the correctness check fails: pupper's final_z, last_1s_std_mm and push_dip_mm
must equal the plain loop's to 1e-9 (exit 1 otherwise).

--breakdown additionally times bare mujoco.batch.Batch calls on the same 16
cells (rollout recording qpos+actuator_force vs plain step, in one call and in
pupper's 250-step chunks), to show where pupper's time goes.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import statistics
import sys
import time

import numpy as np

import mujoco
import pupper_core
from pupper_core import _native

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


def load_model() -> tuple[mujoco.MjModel, int]:
    model = mujoco.MjModel.from_xml_string(_native.builtin_xml("pupper_v3"))
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


def run_pupper(threads: int) -> tuple[float, dict]:
    t0 = time.perf_counter()
    res = pupper_core.sweep({"kp": KP, "kd": KD}, seconds=SECONDS, progress=False, threads=threads)
    wall = time.perf_counter() - t0
    cells = {}
    for i in range(len(res)):
        r = res.row(i)
        cells[(r["kp"], r["kd"])] = (r["final_z"], r["last_1s_std_mm"], r["push_dip_mm"])
    return wall, cells


def run_plain(base_model: mujoco.MjModel, base: int) -> tuple[float, dict]:
    t0 = time.perf_counter()
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
    return time.perf_counter() - t0, cells


def run_physics(base_model: mujoco.MjModel, base: int) -> float:
    t0 = time.perf_counter()
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
    return time.perf_counter() - t0


# --- optional: where does pupper's time go? ---------------------------------


def batch_for_grid(base_model: mujoco.MjModel, nthread: int):
    import mujoco.batch

    b = mujoco.batch.Batch(base_model, NCELL, nthread)
    g, bias = b.expand("actuator_gainprm"), b.expand("actuator_biasprm")
    for i, (kp, kd) in enumerate((kp, kd) for kp in KP for kd in KD):
        g[i, :, 0] = kp
        bias[i, :, 1] = -kp
        bias[i, :, 2] = -kd
    b.reset(keyframe=0, stage=0)
    return b


def breakdown(base_model: mujoco.MjModel, base: int, repeat: int) -> dict[str, float]:
    """Bare Batch timings on the 16 cells (no push: it does not change the cost)."""
    rec = ("qpos", "actuator_force")

    def chunks():
        k = 0
        while k < NSTEP:
            end = min(k + 250, NSTEP)
            for bnd in (PRE_PUSH, PRE_PUSH + PUSH_STEPS):
                if k < bnd < end:
                    end = bnd
            yield end - k
            k = end

    cases = {
        "batch.step(nstep=5000), all threads": lambda b: b.step(nstep=NSTEP),
        "batch.rollout(5000, record=qpos+act), all threads": lambda b: b.rollout(NSTEP, record=rec),
        "batch.rollout in pupper's 250-step chunks, all threads": lambda b: [
            b.rollout(n, record=rec) for n in chunks()
        ],
        "batch.step(nstep=5000), 1 thread": lambda b: b.step(nstep=NSTEP),
    }
    out = {}
    for name, fn in cases.items():
        nthread = 1 if name.endswith("1 thread") else 0
        times = []
        for _ in range(repeat):
            b = batch_for_grid(base_model, nthread)
            t0 = time.perf_counter()
            fn(b)
            times.append(time.perf_counter() - t0)
        out[name] = statistics.median(times)
    return out


# --- main -------------------------------------------------------------------


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="repeats per way (median taken)")
    ap.add_argument("--json", metavar="FILE", help="write the numbers as JSON to FILE")
    ap.add_argument("--breakdown", action="store_true", help="also time bare Batch calls")
    args = ap.parse_args()
    repeat = max(1, args.repeat)
    ncpu = os.cpu_count() or 1

    base_model, base = load_model()
    print(
        f"pupper_core {pupper_core.__version__}, mujoco {mujoco.__version__}, "
        f"os.cpu_count() = {ncpu}, {NCELL} cells x {NSTEP} steps, repeat {repeat}",
        flush=True,
    )

    # warm-up: imports, thread pools, caches
    pupper_core.sweep({"kp": [10.0], "kd": [1.0]}, seconds=0.2, progress=False)
    m = servo_model(base_model, 10.0, 1.0)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_step(m, d, 200)

    t_pupper, t_pupper1, t_plain, t_phys = [], [], [], []
    pupper_cells = plain_cells = None
    for r in range(repeat):
        # interleaved so that drift in the machine's speed hits every way alike
        w, pupper_cells = run_pupper(threads=0)
        t_pupper.append(w)
        w, _ = run_pupper(threads=1)
        t_pupper1.append(w)
        w, plain_cells = run_plain(base_model, base)
        t_plain.append(w)
        t_phys.append(run_physics(base_model, base))
        print(
            f"  repeat {r + 1}/{repeat}: pupper {t_pupper[-1]:.3f} s, pupper threads=1 "
            f"{t_pupper1[-1]:.3f} s, plain {t_plain[-1]:.3f} s, physics {t_phys[-1]:.3f} s",
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
            diff = abs(a - b) if (np.isfinite(a) and np.isfinite(b)) else (
                0.0 if (np.isnan(a) and np.isnan(b)) else float("inf")
            )
            maxdiff[n] = max(maxdiff[n], diff)
    worst = max(maxdiff.values())
    correct = worst <= TOL and not missing

    pupper = statistics.median(t_pupper)
    pupper1 = statistics.median(t_pupper1)
    plain = statistics.median(t_plain)
    phys = statistics.median(t_phys)
    floor = phys / ncpu
    speedup = plain / pupper
    over_floor = pupper / floor
    us = lambda s: s / (NCELL * NSTEP) * 1e6  # noqa: E731

    print()
    print(f"{'way':<34}{'seconds':>10}{'us/step':>10}")
    rows = [
        ("pupper sweep (threads=0)", pupper),
        ("pupper sweep (threads=1)", pupper1),
        ("plain Python loop (serial)", plain),
        ("physics alone (serial, 1 core)", phys),
        (f"physics floor (= physics / {ncpu})", floor),
    ]
    for name, s in rows:
        print(f"{name:<34}{s:>10.3f}{us(s):>10.2f}")
    print()
    ok1 = speedup >= SPEEDUP_TARGET
    ok2 = over_floor <= FLOOR_TARGET
    print(f"speedup vs plain loop  = plain / pupper        = {speedup:6.2f}   "
          f"target >= {SPEEDUP_TARGET}  {'PASS' if ok1 else 'MISS'}")
    print(f"pupper / physics floor = pupper / (phys/{ncpu})   = {over_floor:6.2f}   "
          f"target <= {FLOOR_TARGET} {'PASS' if ok2 else 'MISS'}")
    print(f"pupper threads=1 / threads=0 (scaling)         = {pupper1 / pupper:6.2f}")
    print(f"pupper threads=1 / physics (serial overhead)   = {pupper1 / phys:6.2f}")
    print()
    print("correctness (pupper vs plain loop, max abs diff over 16 cells): "
          + ", ".join(f"{n} {v:.3g}" for n, v in maxdiff.items())
          + f"  -> {'OK' if correct else 'FAIL'} (tol {TOL:g})")
    if missing:
        print(f"cells missing from one side: {missing}")

    bd = None
    if args.breakdown:
        bd = breakdown(base_model, base, repeat)
        print()
        print("breakdown: bare mujoco.batch.Batch on the 16 cells (median)")
        for name, s in bd.items():
            print(f"  {name:<56}{s:>8.3f} s {us(s):>7.2f} us/step")

    if args.json:
        payload = {
            "cpu_count": ncpu,
            "repeat": repeat,
            "cells": NCELL,
            "steps": NSTEP,
            "seconds": {
                "pupper": pupper,
                "pupper_threads1": pupper1,
                "plain": plain,
                "physics_serial": phys,
                "physics_floor": floor,
            },
            "samples": {
                "pupper": t_pupper,
                "pupper_threads1": t_pupper1,
                "plain": t_plain,
                "physics_serial": t_phys,
            },
            "us_per_step": {
                "pupper": us(pupper),
                "pupper_threads1": us(pupper1),
                "plain": us(plain),
                "physics_serial": us(phys),
                "physics_floor": us(floor),
            },
            "speedup_vs_plain": speedup,
            "speedup_target": SPEEDUP_TARGET,
            "speedup_pass": ok1,
            "pupper_over_floor": over_floor,
            "floor_target": FLOOR_TARGET,
            "floor_pass": ok2,
            "correctness_max_abs_diff": maxdiff,
            "correct": correct,
            "breakdown_seconds": bd,
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
