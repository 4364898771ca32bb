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

--six adds the second question: tune over kp and kd per joint group (six
axes, the same ranges) with the grid's whole budget, which must beat the
grid's best. --replicates 8 asks both with 8 robots per cell (torso and
leg masses +-10 %, motor gains +-5 %) and the worse-side 95th percentile.
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
    ap.add_argument("--six", action="store_true", help="also search kp, kd per joint group")
    ap.add_argument("--replicates", type=int, default=1)
    args = ap.parse_args()
    options: dict = dict(OPTIONS)
    objective = OBJECTIVE
    aggregate = "mean"
    if args.replicates > 1:
        options.update(replicates=args.replicates,
                       randomize=["torso_mass=±10%", "leg_mass=±10%", "motor_gain=±5%"])
        objective, aggregate = f"p95:{OBJECTIVE}", "p95"
    started = time.perf_counter()
    grid = pc.sweep({"kp": f"5:200:{args.side}:log", "kd": f"0.05:10:{args.side}:log"}, **options)
    grid_wall = time.perf_counter() - started
    # what the runner really stepped (the schedule's clock gives 2001 steps to 4 s)
    grid_steps = sum(grid.cell_steps)
    if args.replicates > 1:
        ok = (grid["failure_fraction"] == 0) & (grid["p95:saturation_frac"] < 0.05)
    else:
        ok = np.array([s == "ok" for s in grid["status"]])
    values = np.where(ok, grid[objective], np.inf)
    grid_best = float(np.nanmin(values))
    print(f"{'run':<10} {'best ' + objective:>22} {'cell-steps':>12} {'wall s':>8}")
    print(f"{'grid':<10} {grid_best:>22.6g} {grid_steps:>12} {grid_wall:>8.1f}")

    def search(space: list[str], budget: int, label: str) -> tuple[list[float], list[int]]:
        bests, spent = [], []
        for seed in range(args.seeds):
            started = time.perf_counter()
            res = pc.tune(space, objective=OBJECTIVE, aggregate=aggregate, budget=budget, batch=args.batch,
                          seed=seed, **options)
            wall = time.perf_counter() - started
            # told values: a fallen or chattering trial was told the penalty
            best = min(t[OBJECTIVE] for t in res.trials)
            bests.append(best)
            spent.append(res.cell_steps)
            print(f"{label + ' s' + str(seed):<10} {best:>22.6g} {res.cell_steps:>12} {wall:>8.1f}")
        return bests, spent

    bests, spent = search(["kp=5:200:log", "kd=0.05:10:log"], grid_steps // 10, "tune")
    gap = statistics.median(bests) / grid_best - 1
    frac = statistics.median(spent) / grid_steps
    print(f"median tune best vs grid best: {100 * gap:+.2f} % (target within 1 %: "
          f"{'PASS' if gap <= 0.01 else 'MISS'}); cell-steps {frac:.3f} of the grid's "
          f"({'PASS' if frac <= 0.1 else 'MISS'})")
    if args.six:
        six = [f"{g}.{j}={r}" for g, r in (("kp", "5:200:log"), ("kd", "0.05:10:log")) for j in ("haa", "hfe", "kfe")]
        bests, spent = search(six, grid_steps, "six")
        med = statistics.median(bests)
        print(f"six axes: median best {med:.6g} vs the grid's {grid_best:.6g} "
              f"({'PASS' if med < grid_best else 'MISS'}: must beat it), cell-steps "
              f"{statistics.median(spent) / grid_steps:.3f} of the grid's")


if __name__ == "__main__":
    main()
