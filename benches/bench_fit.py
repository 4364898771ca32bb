"""Benchmark: `pupper fit` on 12 joints x 30 s of log at 500 Hz, and the
share of its time spent in rollouts.

Run from the repository root, after `make setup PUPPER_EXTRAS=fit`:

    .venv/bin/python benches/bench_fit.py              # one log, the six parameters
    .venv/bin/python benches/bench_fit.py --per group  # 18 parameters
    .venv/bin/python benches/bench_fit.py --compare    # issue 38: per group against per joint
                                                       # on two 20 s logs at 250 Hz

`--compare` fits two 20 s logs of the 12 joints at 250 Hz (excite --rate
250, kd 0.1 and 0.3) per group (18 parameters) and per joint (72), each in
a process of its own, and prints each fit's time and the process's peak
memory, and their ratio.

The log: `pupper excite` (multisine, 0.75 s holds, 9 s per joint group:
30 s, 15,001 samples of 12 joints) played on the built-in robot with known
changes (armature x1.3, damping 0.02, friction loss 0.05, kp x0.9, a 10 ms
command delay), angles with 1e-3 rad noise. Timed in this one process:

  fit       pupper_core.fit(log): mujoco.sysid's Levenberg-Marquardt, every
            rollout of a Jacobian in one mujoco.rollout call on all cores.
  rollouts  the time inside mujoco.rollout.rollout during that fit (wrapped
            with a timer): its share of the fit is what more cores speed up;
            the rest is sysid's residuals, interpolation and linear algebra.

Also printed: one serial rollout of the log (the physics of one candidate),
so the fit's cost reads as a count of rollouts.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import mujoco.rollout as mj_rollout
import numpy as np

import pupper_core as pc
from pupper_core import _fit
from pupper_core._fit import log as joint_log

TRUE = dict(armature=0.0016 * 1.3, damping=0.02, frictionloss=0.05, kp_scale=0.9, delay=0.010)


def hardware_log(directory: Path, seconds: float = 9.0, rate: float | None = None, kd: float | None = None,
                 name: str = "robot") -> Path:
    ex = pc.excite(out=directory / f"excite_{name}.csv", seconds=seconds, hold=0.75, rate=rate, kd=kd)
    robot = _fit.load_robot("pupper_v3")
    lg = joint_log.read_log(ex, robot.ranges)
    spec = _fit.suspended_spec(robot, lg.kp * TRUE["kp_scale"], lg.kd)
    for j in robot.joints:
        spec.joint(j).armature = TRUE["armature"]
        spec.joint(j).damping[0] = TRUE["damping"]
        spec.joint(j).frictionloss = TRUE["frictionloss"]
    for a in robot.actuators:
        spec.actuator(a).delay = TRUE["delay"]
    sens = _fit.simulate(spec, robot, lg.times, lg.target)
    nu = len(robot.actuators)
    q = sens[:, :nu] + 1e-3 * np.random.default_rng(0).standard_normal((len(lg.times), nu))
    out = directory / f"{name}.csv"
    joint_log.write_log(out, lg.times, robot.actuators, target=lg.target, q=q, kp=lg.kp, kd=lg.kd)
    return out


def compare() -> None:
    """Per group against per joint on two 20 s logs at 250 Hz, each fit in
    a process of its own (its peak memory is its own)."""
    import subprocess

    got = {}
    for per in ("group", "joint"):
        p = subprocess.run([sys.executable, __file__, "--per", per, "--two-logs"], capture_output=True, text=True,
                           check=True)
        print(p.stdout, end="")
        line = next(ln for ln in p.stdout.splitlines() if ln.startswith("fit: "))
        peak = next(ln for ln in p.stdout.splitlines() if ln.startswith("peak memory: "))
        got[per] = (float(line.split()[1]), float(peak.split()[2]))
    (tg, mg), (tj, mj) = got["group"], got["joint"]
    print(f"per joint / per group: time {tj / tg:.2f}x ({tj:.1f} s / {tg:.1f} s), peak memory "
          f"{mj:.2f} GB / {mg:.2f} GB")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--per", default="all", choices=_fit.PER)
    ap.add_argument("--compare", action="store_true", help="per group against per joint, two 20 s logs at 250 Hz")
    ap.add_argument("--two-logs", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.compare:
        compare()
        return
    if a.two_logs:
        two_logs(a.per)
        return
    with tempfile.TemporaryDirectory() as tmp:
        log = hardware_log(Path(tmp))
        robot = _fit.load_robot("pupper_v3")
        lg = joint_log.read_log(log, robot.ranges)
        # one serial rollout of the log on the nominal model
        m = _fit.suspended_spec(robot, lg.kp, lg.kd).compile()
        x0 = _fit.initial_state(m, robot, lg.q[0], np.zeros(m.nu), lg.target[0])
        t0 = time.perf_counter()
        mj_rollout.rollout(m, mujoco.MjData(m), x0, lg.target)
        one = time.perf_counter() - t0

        spent = [0.0, 0]
        inner = mj_rollout.rollout

        def timed(*args, **kw):
            t = time.perf_counter()
            try:
                return inner(*args, **kw)
            finally:
                spent[0] += time.perf_counter() - t
                spent[1] += 1

        mj_rollout.rollout = timed
        try:
            t0 = time.perf_counter()
            res = pc.fit(log, per=a.per)
            total = time.perf_counter() - t0
        finally:
            mj_rollout.rollout = inner
    print(f"log: {len(lg.times)} samples x {len(lg.actuators)} joints ({lg.duration:.1f} s at "
          f"{1 / np.mean(np.diff(lg.times)):.0f} Hz); {os.cpu_count()} cores; per {a.per}")
    print(f"one serial rollout of the log: {one:.3f} s")
    print(f"fit: {total:.1f} s; in mujoco.rollout: {spent[0]:.1f} s ({100 * spent[0] / total:.0f} %) "
          f"over {spent[1]} calls")
    for r in res.table:
        print(f"  {r['parameter']:<22} fitted {r['fitted']:.5g}  [{r['low95']:.5g}, {r['high95']:.5g}]")
    print(f"RMS angle error {np.mean(res.rms_before['robot.csv']) * 1e3:.3f} -> "
          f"{np.mean(res.rms_after['robot.csv']) * 1e3:.3f} mrad")
    sys.stdout.flush()


def two_logs(per: str) -> None:
    """One fit of two 20 s logs at 250 Hz (kd 0.1 and 0.3), timed, and this
    process's peak memory."""
    import resource

    with tempfile.TemporaryDirectory() as tmp:
        # 3 groups of 5.67 s with 0.75 s holds: 20 s
        logs = [hardware_log(Path(tmp), seconds=5.67, rate=250, kd=kd, name=f"robot_kd{kd}") for kd in (0.1, 0.3)]
        t0 = time.perf_counter()
        res = pc.fit(logs, per=per, progress=False)
        total = time.perf_counter() - t0
    lg = res.rms_after
    print(f"per {per}: {len(res.table)} parameters, two logs of 20 s at 250 Hz; {os.cpu_count()} cores")
    print(f"fit: {total:.1f} s")
    print(f"peak memory: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20:.2f} GB")
    print("RMS angle error after: " + ", ".join(f"{k} {np.mean(v) * 1e3:.3f} mrad" for k, v in lg.items()))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
