"""Benchmark: `pupper walk` against the physics floor of its cell-steps.

Run from the repository root, after `make setup`:

    .venv/bin/python benches/bench_walk.py              # 3 repeats, medians
    .venv/bin/python benches/bench_walk.py --repeat 5

The workload is a trot of Pupper v3 at 0.25 m/s over kp 5,10,20 x kd
0.1,0.25,0.5 (9 cells), servo mode, 8 s at dt 0.002 (4000 steps). It is
timed two ways in this one process, each repeated:

  pupper   pupper_core.walk(grid, progress=False): every cell in one batch on
           all cores; the gait and every leg's inverse kinematics give each
           step's targets, the probe measures every step.
  physics  the same 9 walking simulations with no gait, no kinematics and no
           measuring: mujoco.rollout on one thread, each cell's model at its
           gains, from the `home` keyframe, its controls every step the joint
           angles pupper's own run of that cell recorded (so the robot walks
           the same way, feet striking the floor as often). physics /
           os.cpu_count() is the floor: a perfectly parallel runner with no
           overhead.

Ratio: pupper / physics floor, target <= 1.2 (what pupper adds: the gait
and the kinematics of every step, the probe, the bridge). Timings need an
idle machine; compare ratios, not seconds, across runs. On a machine other
work shares, the cores are not the floor's to count on: the CPU seconds of
pupper on one thread against the floor's say what pupper adds all the same
(printed as "cpu ratio").
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

import pupper_core as pc
from pupper_core import render

REPO = Path(__file__).resolve().parent.parent
GRID = {"kp": [5, 10, 20], "kd": [0.1, 0.25, 0.5]}
SECONDS, SPEED = 8.0, 0.25


def cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def run_pupper(out: Path | None = None, threads: int = 0) -> tuple[float, float]:
    """Wall and CPU seconds of the walk."""
    started, used = time.perf_counter(), cpu()
    pc.walk(GRID, speed=SPEED, seconds=SECONDS, progress=False, out=out, threads=threads)
    return time.perf_counter() - started, cpu() - used


def floor_inputs() -> tuple[list[mujoco.MjModel], np.ndarray, np.ndarray]:
    """Per cell: its model at its gains, its initial state and its controls
    (the joint angles its own walk recorded at every step)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "walk"
        run_pupper(out)
        cells = len(GRID["kp"]) * len(GRID["kd"])
        recs = render.record_run(out, list(range(cells)), fps=500)
    m0 = mujoco.MjModel.from_xml_path(str(REPO / "models" / "pupper_v3" / "scene.xml"))
    models, controls = [], []
    qadr = m0.jnt_qposadr[m0.actuator_trnid[:, 0]]
    for rec in recs:
        m = mujoco.MjModel.from_xml_path(str(REPO / "models" / "pupper_v3" / "scene.xml"))
        kp, kd = rec["setup"]["kp"], rec["setup"]["kd"]
        m.actuator_gainprm[:, 0] = kp
        m.actuator_biasprm[:, 1] = -np.asarray(kp)
        m.actuator_biasprm[:, 2] = -np.asarray(kd)
        models.append(m)
        controls.append(np.asarray(rec["qpos"])[1:, qadr])
    d = mujoco.MjData(m0)
    mujoco.mj_resetDataKeyframe(m0, d, m0.key("home").id)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(m0, spec))
    mujoco.mj_getState(m0, d, state, spec)
    return models, np.tile(state, (len(models), 1)), np.stack(controls)


def physics(models: list[mujoco.MjModel], state: np.ndarray, control: np.ndarray) -> tuple[float, float]:
    """Wall and CPU seconds of the floor's rollouts, on one thread."""
    data = mujoco.MjData(models[0])
    started, used = time.perf_counter(), cpu()
    rollout.rollout(models, data, state, control)
    return time.perf_counter() - started, cpu() - used


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    models, state, control = floor_inputs()
    ncpu = os.cpu_count() or 1
    ours, floors, ratios, cpu_ratios = [], [], [], []
    for _ in range(args.repeat):
        p, _ = run_pupper()
        f, f_cpu = physics(models, state, control)
        _, p_cpu = run_pupper(threads=1)
        ours.append(p)
        floors.append(f / ncpu)
        ratios.append(p / (f / ncpu))
        cpu_ratios.append(p_cpu / f_cpu)
    cells, steps = control.shape[0], control.shape[1]
    p, f, r = statistics.median(ours), statistics.median(floors), statistics.median(ratios)
    print(f"walk: {cells} cells x {steps} steps, {ncpu} cores")
    print(f"  pupper          {p:.3f} s  ({cells * steps / p:,.0f} cell-steps/s)")
    print(f"  physics floor   {f:.3f} s  ({cells * steps / f:,.0f} cell-steps/s; serial / {ncpu})")
    print(f"  pupper / floor  {r:.3f}  (median of per-repeat ratios; target <= 1.2: "
          f"{'PASS' if r <= 1.2 else 'MISS'})")
    print(f"  cpu ratio       {statistics.median(cpu_ratios):.3f}  (pupper on one thread / the floor, CPU seconds)")
    load = os.getloadavg()[0]
    if load > 1.5:
        print(f"\nWARNING: the load average is {load:.2f} on {ncpu} cores: other processes take cores the "
              "floor counts on, so the wall ratio is unreliable (the cpu ratio is not): rerun on an idle machine")
    assert np.isfinite(r)


if __name__ == "__main__":
    main()
