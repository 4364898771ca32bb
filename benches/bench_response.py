"""Benchmark: `pupper response` against the physics floor of its cell-steps.

Run from the repository root, after `make setup`:

    .venv/bin/python benches/bench_response.py              # 3 repeats, medians
    .venv/bin/python benches/bench_response.py --repeat 5

The workload is the step response of every joint of Pupper v3 over
kp 5,20,60 x kd 0.1,0.5,2 (9 cells x 12 joints = 108 simulations), servo
mode, 3 s at dt 0.002 (1500 steps; the step at 0.5 s), on the robot hung in
the air. It is timed two ways in this one process, each repeated:

  pupper   pupper_core.response(grid, progress=False): every (cell, joint)
           in one batch on all cores, the targets written every step.
  physics  the same 108 simulations with no per-step Python: per simulation,
           mj_step(m, d, 250), the excited joint's target moved by 0.2 rad,
           mj_step(m, d, 1250); serial, one core, on the same suspended model
           (the scene's free joint deleted through MjSpec, contacts off), from
           the `home` keyframe's joint angles. physics / os.cpu_count() is the
           floor: a perfectly parallel runner with no overhead.

Ratio: pupper / physics floor, target <= 1.15 (what pupper adds: the
per-step targets, recording every excited joint, the figures, the bridge).
Timings need an idle machine; compare ratios, not seconds, across runs.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import mujoco
import numpy as np

import pupper_core as pc

REPO = Path(__file__).resolve().parent.parent
GRID = {"kp": [5, 20, 60], "kd": [0.1, 0.5, 2]}
SECONDS, HOLD, AMPLITUDE = 3.0, 0.5, 0.2


def suspended_model() -> mujoco.MjModel:
    spec = mujoco.MjSpec.from_file(str(REPO / "models" / "pupper_v3" / "scene.xml"))
    free = spec.joints[0]
    assert free.type == mujoco.mjtJoint.mjJNT_FREE
    spec.delete(free)
    for key in spec.keys:
        key.qpos = list(key.qpos)[7:]
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    return spec.compile()


def physics(m: mujoco.MjModel) -> float:
    d = mujoco.MjData(m)
    key = m.key("home").id
    hold = round(HOLD / m.opt.timestep)
    rest = round(SECONDS / m.opt.timestep) - hold
    started = time.perf_counter()
    for kp in GRID["kp"]:
        for kd in GRID["kd"]:
            m.actuator_gainprm[:, 0] = kp
            m.actuator_biasprm[:, 1:3] = (-kp, -kd)
            for joint in range(m.nu):
                mujoco.mj_resetDataKeyframe(m, d, key)
                d.ctrl[:] = d.qpos[m.jnt_qposadr[m.actuator_trnid[:, 0]]]
                mujoco.mj_step(m, d, hold)
                d.ctrl[joint] += AMPLITUDE
                mujoco.mj_step(m, d, rest)
    return time.perf_counter() - started


def run_pupper() -> float:
    started = time.perf_counter()
    pc.response(GRID, seconds=SECONDS, hold=HOLD, amplitude=AMPLITUDE, progress=False)
    return time.perf_counter() - started


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    m = suspended_model()
    ncpu = os.cpu_count() or 1
    run_pupper()  # warm: imports, first compile
    ours, floors, ratios = [], [], []
    for _ in range(args.repeat):
        p = run_pupper()
        f = physics(m) / ncpu
        ours.append(p)
        floors.append(f)
        ratios.append(p / f)
    cells = len(GRID["kp"]) * len(GRID["kd"]) * m.nu
    steps = round(SECONDS / m.opt.timestep)
    print(f"response: {cells} simulations x {steps} steps, {ncpu} cores")
    print(f"  pupper          {statistics.median(ours):.3f} s")
    print(f"  physics floor   {statistics.median(floors):.3f} s  (serial / {ncpu})")
    r = statistics.median(ratios)
    print(f"  pupper / floor  {r:.3f}  (median of per-repeat ratios; target <= 1.15: "
          f"{'PASS' if r <= 1.15 else 'MISS'})")
    print(f"  per cell-step   {1e6 * statistics.median(ours) / (cells * steps):.2f} us wall")
    assert np.isfinite(r)


if __name__ == "__main__":
    main()
