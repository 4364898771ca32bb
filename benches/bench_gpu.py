"""Benchmark: the warp backend against a bare MuJoCo Warp loop and the cpu backend.

Run from the repository root after `make setup PUPPER_EXTRAS=gpu` (or `make
bench-gpu`), on a machine with an NVIDIA GPU:

    .venv/bin/python benches/bench_gpu.py                       # 4,096 / 16,384 / 65,536 cells
    .venv/bin/python benches/bench_gpu.py --device cpu          # Warp's CPU device, small sizes
    .venv/bin/python benches/bench_gpu.py --sizes 1024 --seconds 2 --json out.json

The workload is the chapter's servo schedule (10 s per cell at dt 0.002, push
-25 N world z on the base from 2.0 s to 2.25 s, from the `home` keyframe) on
a square log grid kp=1:120:S:log x kd=0.01:5:S:log of S*S cells. Timed in
this one process, after one small warm-up run that compiles Warp's kernels:

  pupper  pupper_core.sweep(grid, backend="warp", device=DEV): everything a
          sweep does (models, worlds, per-world gains, recording qpos and
          actuator forces every step, copying them back in blocks, the Rust
          metrics, the summary table).
  bare    the same cells as a hand-written MuJoCo Warp loop: one model with
          per-world gain/bias (put_model batch_sizes), one data of N worlds,
          one step captured as a graph and launched 5000 times, the push
          written into xfrc_applied between launches; nothing recorded. Its
          final base z must equal pupper's bit for bit (float32, same kernels).
  cpu     pupper's cpu backend (all cores) on --cpu-cells cells of the same
          grid (its cell-steps/s does not depend on the grid's size).

Ratios and targets (on an H100-class GPU): pupper / bare <= 1.2; pupper
>= 4 M cell-steps/s at 65,536 cells; pupper >= 10x the cpu backend. PASS/MISS
is printed per target; the exit status is 1 only when the bare loop and
pupper disagree.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np

import pupper_core as pc
from pupper_core import _native


def grid_of(cells: int) -> dict[str, str]:
    side = math.isqrt(cells)
    if side * side != cells:
        sys.exit(f"--sizes: {cells} is not a square number of cells (side x side)")
    return {"kp": f"1:120:{side}:log", "kd": f"0.01:5:{side}:log"}


def pupper_run(cells: int, seconds: float, **kw) -> tuple[float, pc.SweepResult]:
    t = time.perf_counter()
    r = pc.sweep(grid_of(cells), seconds=seconds, progress=False, **kw)
    return time.perf_counter() - t, r


def bare_run(cells: int, seconds: float, device: str,
             gains: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[float, np.ndarray]:
    """The hand-written MuJoCo Warp loop; its final base z per world. `gains`
    (kp, kd per cell) default to the grid's log axes; given pupper's own
    values, the two runs do bit for bit the same float32 physics."""
    import mujoco
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    import mujoco_warp as mjw

    side = math.isqrt(cells)
    kp_axis = np.geomspace(1, 120, side)
    kd_axis = np.geomspace(0.01, 5, side)
    kp = np.repeat(kp_axis, side)  # the last axis varies fastest
    kd = np.tile(kd_axis, side)
    if gains is not None:
        kp, kd = gains
    t0 = time.perf_counter()
    m = _native.builtin_model("pupper_v3")
    m.actuator_gaintype[:] = 0
    m.actuator_biastype[:] = 1
    m.actuator_dyntype[:] = 0
    m.actuator_forcelimited[:] = 1
    d = mujoco.MjData(m)
    key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "home")
    mujoco.mj_resetDataKeyframe(m, d, key)
    base = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "base_link")
    dt = m.opt.timestep
    # the chapter's loop: `while time < T`, pushed while 2.0 <= time < 2.25,
    # time summed step by step (so the push lasts 126 steps, not 125)
    pushed, t = [], 0.0
    while t < seconds:
        pushed.append(2.0 <= t < 2.25)
        t += dt
    steps = len(pushed)
    push = (pushed.index(True), len(pushed) - pushed[::-1].index(True)) if any(pushed) else (-1, -1)
    with wp.ScopedDevice(device):
        mw = mjw.put_model(m, batch_sizes={"actuator_gainprm": cells, "actuator_biasprm": cells})
        mw.opt.deterministic = int(mjw.DeterminismType.ALL)
        mw.opt.warn_overflow = 0
        g = np.repeat(m.actuator_gainprm[None].astype(np.float32), cells, 0)
        b = np.repeat(m.actuator_biasprm[None].astype(np.float32), cells, 0)
        g[:, :, 0] = kp[:, None]
        b[:, :, 1] = -kp[:, None]
        b[:, :, 2] = -kd[:, None]
        mw.actuator_gainprm.assign(g)
        mw.actuator_biasprm.assign(b)
        dw = mjw.put_data(m, d, nworld=cells)
        with wp.ScopedCapture() as cap:
            mjw.step(mw, dw)
        xf = np.zeros((cells, m.nbody, 6), dtype=np.float32)
        for k in range(steps):
            if k == push[0] or k == push[1]:
                xf[:, base, 2] = -25.0 if k == push[0] else 0.0
                dw.xfrc_applied.assign(xf)
            wp.capture_launch(cap.graph)
        z = dw.qpos.numpy()[:, 2].copy()
    return time.perf_counter() - t0, z


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--device", default="cuda:0", help="Warp device (cuda:0, or cpu)")
    ap.add_argument("--sizes", default=None,
                    help="cells per run, square numbers (default 4096,16384,65536; cpu: 16,64)")
    ap.add_argument("--seconds", type=float, default=None,
                    help="simulated seconds per cell (default 10; cpu device: 3)")
    ap.add_argument("--cpu-cells", type=int, default=256, help="cells of the cpu-backend run")
    ap.add_argument("--json", help="also write the results here")
    a = ap.parse_args()
    on_gpu = a.device.startswith("cuda")
    sizes = [int(s) for s in (a.sizes or ("4096,16384,65536" if on_gpu else "16,64")).split(",")]
    seconds = a.seconds or (10.0 if on_gpu else 3.0)
    steps = round(seconds / 0.002)
    print(f"device {a.device}, {seconds:g} s per cell ({steps} steps), {os.cpu_count()} CPU cores")

    # warm-up: Warp compiles its kernels once (cached on disk afterwards)
    pupper_run(4, 0.1, backend="warp", device=a.device)
    bare_run(4, 0.1, a.device)

    cpu_cells = a.cpu_cells if math.isqrt(a.cpu_cells) ** 2 == a.cpu_cells else 256
    t_cpu, _ = pupper_run(cpu_cells, seconds)
    cpu_rate = cpu_cells * steps / t_cpu
    print(f"cpu backend  {cpu_cells:>6} cells  {t_cpu:8.2f} s  {cpu_rate / 1e3:9.0f} k cell-steps/s")

    rows, ok = [], True
    for n in sizes:
        t_p, r = pupper_run(n, seconds, backend="warp", device=a.device)
        gains = (np.asarray(r["kp"], dtype=float), np.asarray(r["kd"], dtype=float))
        t_b, z = bare_run(n, seconds, a.device, gains)
        zp = np.asarray(r["final_z"], dtype=float)
        alive = np.isfinite(zp)
        diff = float(np.max(np.abs(zp[alive] - z[alive]))) if alive.any() else 0.0
        same = diff == 0.0
        ok &= same
        rate_p, rate_b = n * steps / t_p, n * steps / t_b
        row = {"cells": n, "pupper_s": t_p, "bare_s": t_b, "pupper_rate": rate_p,
               "bare_rate": rate_b, "ratio": t_p / t_b, "vs_cpu": rate_p / cpu_rate,
               "max_final_z_diff": diff}
        rows.append(row)
        print(f"warp  {n:>6} cells  pupper {t_p:8.2f} s {rate_p / 1e6:6.2f} M/s   bare {t_b:8.2f} s "
              f"{rate_b / 1e6:6.2f} M/s   pupper/bare {t_p / t_b:5.2f}   vs cpu {rate_p / cpu_rate:6.1f}x"
              f"   final z {'equal' if same else 'DIFFERS'} ({diff:.1e})")
    if on_gpu and rows:
        last = rows[-1]
        verdict = lambda good: "PASS" if good else "MISS"  # noqa: E731
        print(f"pupper / bare at {last['cells']} cells: {last['ratio']:.2f} (target <= 1.2) "
              f"{verdict(last['ratio'] <= 1.2)}")
        print(f"pupper at {last['cells']} cells: {last['pupper_rate'] / 1e6:.2f} M cell-steps/s "
              f"(target >= 4 at 65,536) {verdict(last['pupper_rate'] >= 4e6)}")
        print(f"pupper vs cpu backend: {last['vs_cpu']:.1f}x (target >= 10) {verdict(last['vs_cpu'] >= 10)}")
    else:
        print("(Warp's CPU device: targets are for a GPU; these figures show the bench runs)")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"device": a.device, "seconds": seconds, "cpu_rate": cpu_rate, "runs": rows}, f,
                      indent=2)
    if not ok:
        print("ERROR: the bare loop and pupper disagree on final z", file=sys.stderr)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
