"""Benchmark: `pupper tune` against a grid on the default push-rejection question.

Run from the repository root, after `make setup PUPPER_EXTRAS=tune`:

    .venv/bin/python benches/bench_tune.py                 # 32x32 grid, 5 seeds
    .venv/bin/python benches/bench_tune.py --side 16 --seeds 3   # quicker

The question: the push dip (push_dip_mm, the default -25 N push at 2 s) of
Pupper v3 in servo mode over kp 5-200 x kd 0.05-10 (log), 4 s per cell
(the push and the 1.5 s after it). The grid is --side x --side log-spaced
cells in one sweep; tune runs TPE (batch 16) with a tenth of the grid's
cell-steps, once per seed. The table gives each run's best objective,
cell-steps and wall time; the target is tune's best within 1 % of the
grid's, median over the seeds, with at most 1/10 of its cell-steps.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import pupper_core as pc

OPTIONS = dict(seconds=4.0, progress=False)
OBJECTIVE = "push_dip_mm"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--side", type=int, default=32)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--batch", type=int, default=16)
    args = ap.parse_args()
    started = time.perf_counter()
    grid = pc.sweep({"kp": f"5:200:{args.side}:log", "kd": f"0.05:10:{args.side}:log"}, **OPTIONS)
    grid_wall = time.perf_counter() - started
    # what the runner really stepped (the schedule's clock gives 2001 steps to 4 s)
    grid_steps = sum(grid.cell_steps)
    ok = np.array([s in ("ok", "saturated") for s in grid["status"]]) & (grid["saturation_frac"] < 0.05)
    values = np.where(ok, grid[OBJECTIVE], np.inf)
    grid_best = float(np.nanmin(values))
    print(f"{'run':<10} {'best ' + OBJECTIVE:>18} {'cell-steps':>12} {'wall s':>8}")
    print(f"{'grid':<10} {grid_best:>18.6g} {grid_steps:>12} {grid_wall:>8.1f}")
    bests, spent = [], []
    for seed in range(args.seeds):
        started = time.perf_counter()
        res = pc.tune(["kp=5:200:log", "kd=0.05:10:log"], objective=OBJECTIVE, budget=grid_steps // 10,
                      batch=args.batch, seed=seed, **OPTIONS)
        wall = time.perf_counter() - started
        # the same eligibility as the grid's: no chattering trial counts
        best = min((t[OBJECTIVE] for t in res.trials if t["status"] == "ok"), default=float("inf"))
        bests.append(best)
        spent.append(res.cell_steps)
        print(f"{'tune s' + str(seed):<10} {best:>18.6g} {res.cell_steps:>12} {wall:>8.1f}")
    gap = statistics.median(bests) / grid_best - 1
    frac = statistics.median(spent) / grid_steps
    print(f"median tune best vs grid best: {100 * gap:+.2f} % (target within 1 %: "
          f"{'PASS' if gap <= 0.01 else 'MISS'}); cell-steps {frac:.3f} of the grid's "
          f"({'PASS' if frac <= 0.1 else 'MISS'})")


if __name__ == "__main__":
    main()
