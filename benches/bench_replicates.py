"""Benchmark: a 16-cell x 32-replicate randomized sweep (the README's,
3 s per simulation) against physics alone.

    .venv/bin/python benches/bench_replicates.py [--repeat 3] [--seconds 3]

  pupper   pupper_core.sweep(Kp 10,30,60,120 x Kd 0.5,1,2,5, torque mode,
           32 replicates drawing torso mass ±15 %, friction 0.5:1.2 and
           0..2 control steps of latency, seed 7), all cores: 512
           simulations, the delayed PD computed in Rust every step.
  physics  the time spent inside mj_step by the same 512 robots (each
           replicate's drawn torso mass, friction and latency, from
           replicates.csv) stepped one by one by a hand-written delayed PD
           loop, serial, one core; the loop's own Python is not counted.
           The loop's final heights must equal pupper's (printed), so both
           did the same physics (latency makes chattering robots costlier to
           step: a floor without it would not be the same work).
           physics / os.cpu_count() is the floor a perfectly parallel
           runner with zero overhead would reach here.

Ratio: pupper / (physics / cores), target <= 1.15. Medians of --repeat
runs, in one process. Compare ratios, not seconds, across machines.
"""

from __future__ import annotations

import argparse
import copy
import os
import statistics
import time

import mujoco
import numpy as np

import pupper_core as pc

TARGET = 1.15
GRID = {"kp": [10, 30, 60, 120], "kd": [0.5, 1, 2, 5]}
RANDOMIZE = ["torso_mass=±15%", "friction=0.5:1.2", "delay=0:2"]


def pupper(seconds: float) -> tuple[float, pc.SweepResult]:
    t = time.perf_counter()
    res = pc.sweep(GRID, mode="torque", seconds=seconds, replicates=32, randomize=RANDOMIZE,
                   seed=7, progress=False)
    took = time.perf_counter() - t
    assert len(res) == 16 and res.replicates is not None and len(res.replicates) == 512
    return took, res


def physics(res: pc.SweepResult, seconds: float) -> tuple[float, float]:
    """Seconds inside mj_step for the same 512 simulations, serial, and the
    largest |final_z| difference from pupper's (so both did the same work)."""
    base = pc._native.builtin_model("pupper_v3")
    reps = res.replicates
    assert reps is not None
    colliding = [g for g in range(base.ngeom) if base.geom_contype[g] or base.geom_conaffinity[g]]
    body = mujoco.mj_name2id(base, mujoco.mjtObj.mjOBJ_BODY, "base_link")
    joints = base.actuator_trnid[:, 0]
    qadr, vadr = base.jnt_qposadr[joints], base.jnt_dofadr[joints]
    stepping, worst = 0.0, 0.0
    for i in range(len(reps)):
        row = reps.row(i)
        # the model as pupper prepares it: direct torque inputs clipped at
        # 3 N·m, the drawn torso mass (constants recomputed), the friction
        m = copy.copy(base)
        m.actuator_gaintype[:] = 0
        m.actuator_biastype[:] = 1
        m.actuator_dyntype[:] = 0
        m.actuator_forcelimited[:] = 1
        m.actuator_ctrllimited[:] = 0
        m.body_mass[body] *= row["torso_mass"]
        m.body_inertia[body] *= row["torso_mass"]
        d = mujoco.MjData(m)
        mujoco.mj_setConst(m, d)
        m.stat.meaninertia = sum(float(x) for x in m.dof_M0) / m.nv
        m.stat.meanmass = sum(float(x) for x in m.body_mass[1:]) / (m.nbody - 1)
        m.actuator_gainprm[:, :] = 0
        m.actuator_gainprm[:, 0] = 1.0
        m.actuator_biasprm[:, :] = 0
        m.actuator_forcerange[:] = [-3.0, 3.0]
        m.geom_friction[colliding, 0] = row["friction"]
        mujoco.mj_resetDataKeyframe(m, d, 0)
        target = m.key_ctrl[0].copy()
        kp, kd, delay = row["kp"], row["kd"], int(row["delay"])
        history: list[tuple[np.ndarray, np.ndarray]] = []
        while d.time < seconds:
            history.append((d.qpos[qadr].copy(), d.qvel[vadr].copy()))
            if len(history) > delay + 1:
                history.pop(0)
            q, v = history[0]
            d.ctrl[:] = np.clip(kp * (target - q) - kd * v, -3.0, 3.0)
            d.xfrc_applied[body, 2] = -25.0 if 2.0 <= d.time < 2.25 else 0.0
            t = time.perf_counter()
            mujoco.mj_step(m, d)
            stepping += time.perf_counter() - t
        if row["status"] == "ok":
            worst = max(worst, abs(d.qpos[2] - row["final_z"]))
    return stepping, worst

def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=3.0)
    args = ap.parse_args()
    ncpu = os.cpu_count() or 1
    _, res = pupper(args.seconds)  # warm-up: imports, first compile
    ours, phys = [], []
    for i in range(args.repeat):
        ours.append(pupper(args.seconds)[0])
        took, worst = physics(res, args.seconds)
        phys.append(took)
        print(f"  repeat {i + 1}/{args.repeat}: pupper {ours[-1]:.3f} s, physics {phys[-1]:.3f} s"
              f"  (final z differs by at most {worst:.1e} m)")
        assert worst < 1e-9, "the hand loop did other physics than pupper"
    ours_s, phys_s = statistics.median(ours), statistics.median(phys)
    ratio = ours_s / (phys_s / ncpu)
    print(f"\npupper (16 cells x 32 replicates x {args.seconds:g} s)  {ours_s:7.3f} s")
    print(f"physics alone (serial, 1 core)          {phys_s:7.3f} s")
    print(f"physics floor (/ {ncpu} cores)              {phys_s / ncpu:7.3f} s")
    print(f"pupper / physics floor = {ratio:.2f}   target <= {TARGET}  {'PASS' if ratio <= TARGET else 'MISS'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
