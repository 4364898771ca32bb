"""Benchmark: `pupper lab` (48 cells x 6 s: three bodies x Kp x Kd, torque
mode, sine force, each body from its own stand pose) against physics alone.

    .venv/bin/python benches/bench_lab.py [--repeat 3]

  lab      pupper_core.lab(progress=False, threads=0): every cell in one
           batch, the PD computed in Rust each step, all cores.
  physics  the same 48 bodies, gains and start states with no per-step
           Python and no controller call: the PD as MuJoCo's own affine
           actuator (the same law, clipped at the same 3 N·m), the sine force
           left out, mj_step(m, d, 3000) per cell, serial, one core.
           physics / os.cpu_count() is the floor a perfectly parallel runner
           with zero overhead would reach here.

Ratio: lab / (physics / cores), target <= 1.2. Medians of --repeat runs,
in one process. Compare ratios, not seconds, across machines.
"""

from __future__ import annotations

import argparse
import copy
import os
import statistics
import time

import mujoco

import pupper_core as pc

TARGET = 1.2


def bodies() -> dict[str, tuple[mujoco.MjModel, list]]:
    """Each body's compiled model and start state, from pupper's own runner
    (one recorded frame: the auto stand pose)."""
    recs = pc.render.record({"variant": ["original", "long-leg", "heavy"]}, mode="torque",
                            pose="auto", push=False, seconds=0.01, fps=100)
    return {r["values"]["variant"]: (r["model"], r["qpos"][0].copy()) for r in recs}


def physics(models: dict, nstep: int) -> float:
    t = time.perf_counter()
    for model, qpos in models.values():
        for kp in (10, 30, 60, 120):
            for kd in (0.5, 1, 2, 5):
                m = copy.copy(model)
                m.actuator_gainprm[:, 0] = kp
                m.actuator_biasprm[:, :3] = [0.0, -kp, -kd]
                m.actuator_forcerange[:] = [-3.0, 3.0]
                d = mujoco.MjData(m)
                d.qpos[:] = qpos
                d.ctrl[:] = [qpos[m.jnt_qposadr[m.actuator_trnid[a, 0]]] for a in range(m.nu)]
                mujoco.mj_step(m, d, nstep)
    return time.perf_counter() - t


def lab() -> float:
    t = time.perf_counter()
    res = pc.lab(progress=False)
    assert len(res) == 48 and res.complete
    return time.perf_counter() - t


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    ncpu = os.cpu_count() or 1
    models = bodies()
    lab()  # warm-up: imports, first compile
    nstep = round(6.0 / 0.002)
    labs, phys = [], []
    for i in range(args.repeat):
        labs.append(lab())
        phys.append(physics(models, nstep))
        print(f"  repeat {i + 1}/{args.repeat}: lab {labs[-1]:.3f} s, physics {phys[-1]:.3f} s")
    lab_s, phys_s = statistics.median(labs), statistics.median(phys)
    ratio = lab_s / (phys_s / ncpu)
    print(f"\nlab (48 cells x 6 s, threads=0)   {lab_s:7.3f} s")
    print(f"physics alone (serial, 1 core)    {phys_s:7.3f} s")
    print(f"physics floor (/ {ncpu} cores)        {phys_s / ncpu:7.3f} s")
    print(f"lab / physics floor = {ratio:.2f}   target <= {TARGET}  {'PASS' if ratio <= TARGET else 'MISS'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
