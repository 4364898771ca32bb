"""Benchmark: `pupper recommend` against a grid that answers the same question.

Run from the repository root, after `make setup PUPPER_EXTRAS=tune`:

    .venv/bin/python benches/bench_recommend.py              # defaults: 48 trials, an 8x8 grid per group
    .venv/bin/python benches/bench_recommend.py --side 6     # a coarser grid

    .venv/bin/python benches/bench_recommend.py --from-fit   # recommend --from-fit on the real logs' fit

The question is recommend's own: kp and kd per joint group on the built-in
Pupper v3, 32 robots drawn from the default spread (common draws), the
default firmware (rate=500,counts=16384, 2 ms sensing delay), every
constraint on every robot (none falls, saturation under 5 %, each group's
phase margin >= 30 deg and gain margin >= 6 dB at the spread's corners),
the lowest p95 push dip winning. The grid: --side log-spaced kp x --side
kd per group over recommend's ranges, each group's feasible (kp, kd) pairs
kept (the margins are per group), and every combination of the groups'
feasible pairs capped at --cap cells (an even subsample), run on the same
robots in one sweep. Both answers' p95 push dip, cell-steps and wall time
are printed, as a ratio, in this one process.

--from-fit [DIR]: the cost a Pupper owner waits for (issue 59: under 3
minutes on 2 cores): `recommend --from-fit` with its defaults, the robot's
caps (kp <= 10, kd <= 1) and the gains in use (5, 0.25), for standing, on
a fit run DIR, or (no DIR) on one default fit of ../shared/real_logs made
here first (its time printed apart). Beside it, in the same process, the
same recommend on the nominal model (no fit) as the baseline.
"""

from __future__ import annotations

import argparse
import itertools
import tempfile
import time
from pathlib import Path

import numpy as np

import pupper_core as pc
from pupper_core._recommend import plan_for as make_plan
from pupper_core._recommend.search import Candidate, best_of, check_margins, margins, simulate


def grid_answer(side: int, cap: int) -> tuple[Candidate | None, int, float, int]:
    """The grid's pick, its cell-steps, wall time and size."""
    plan = make_plan()
    started = time.perf_counter()
    feasible: dict[str, list[tuple[float, float]]] = {}
    for g in plan.groups:
        pairs = [(float(f"{kp:.4g}"), float(f"{kd:.4g}")) for kp in np.geomspace(*g.kp_range, side)
                 for kd in np.geomspace(*g.kd_range, side)]
        # the margins are per group: a pair is kept where its group's loop holds
        feasible[g.name] = [(kp, kd) for kp, kd in pairs
                            if (m := margins(plan, g, kp, kd))[0] >= plan.min_phase_margin and m[1] >= plan.min_gain_margin]
    combos = list(itertools.product(*(feasible[g.name] for g in plan.groups)))
    if len(combos) > cap:
        combos = [combos[i] for i in np.linspace(0, len(combos) - 1, cap).round().astype(int)]
    cands = [Candidate({g.name: pair for g, pair in zip(plan.groups, combo)}, number=i)
             for i, combo in enumerate(combos)]
    for c in cands:
        check_margins(plan, c)
    simulate(plan, cands, [plan.model], lambda s: None)
    return best_of(plan, cands), sum(c.cell_steps for c in cands), time.perf_counter() - started, len(cands)


#: Where the real bench logs live (not part of the project).
REAL = Path(__file__).resolve().parents[2] / "shared" / "real_logs"
#: The robot's caps and the gains it ran on the bench.
CAPS = {"kp_max": 10.0, "kd_max": 1.0, "current": "5,0.25"}
#: What an owner waits for, at most (s).
TARGET_S = 180.0


def from_fit(fit_dir: Path | None) -> None:
    """Times recommend --from-fit with its defaults (and the nominal
    recommend beside it) and says whether it keeps the target."""
    with tempfile.TemporaryDirectory() as tmp:
        if fit_dir is None:
            logs = sorted(REAL.glob("*.csv.gz"))
            if not logs:
                raise SystemExit(f"no real logs in {REAL}: give a fit run directory, --from-fit DIR")
            started = time.perf_counter()
            pc.fit(logs, gains_from_name="kp_{kp}_kd_{kd}", out=Path(tmp) / "fit", progress=False)
            print(f"fit of {len(logs)} real logs (made first, not timed below): {time.perf_counter() - started:.1f} s")
            fit_dir = Path(tmp) / "fit"
        timed = {}
        for name, extra in (("recommend --from-fit", {"from_fit": fit_dir}), ("recommend (nominal model)", {})):
            started = time.perf_counter()
            rec = pc.recommend(**CAPS, **extra, out=Path(tmp) / name.split()[-1].strip("()-"), progress=False)
            timed[name] = (time.perf_counter() - started, rec)
        print("run                          wall s   robots   candidates   gains (kp/kd haa, hfe, kfe)")
        for name, (wall, rec) in timed.items():
            c = rec.pick
            gains = "  ".join(f"{c.gains[g][0]:.4g}/{c.gains[g][1]:.4g}" for g in ("haa", "hfe", "kfe")) if c else "-"
            print(f"{name:<27} {wall:>8.1f} {rec.plan.robots:>8} {len(rec.candidates):>12}   {gains}")
        wall = timed["recommend --from-fit"][0]
        print(f"from-fit / nominal: wall {wall / timed['recommend (nominal model)'][0]:.2f}; "
              f"recommend --from-fit {wall:.0f} s, target {TARGET_S:.0f} s: {'met' if wall <= TARGET_S else 'MISSED'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--side", type=int, default=8, help="grid points per axis per group")
    ap.add_argument("--cap", type=int, default=512, help="most grid cells (an even subsample)")
    ap.add_argument("--trials", type=int, default=48)
    ap.add_argument("--polish", type=int, default=4)
    ap.add_argument("--from-fit", nargs="?", const="", default=None, metavar="DIR",
                    help="time recommend --from-fit (on DIR, or on a fit of ../shared/real_logs made first)")
    args = ap.parse_args()
    if args.from_fit is not None:
        from_fit(Path(args.from_fit) if args.from_fit else None)
        return
    started = time.perf_counter()
    rec = pc.recommend(trials=args.trials, polish=args.polish, progress=False)
    rec_wall = time.perf_counter() - started
    rec_steps = sum(c.cell_steps for c in rec.candidates)
    grid, grid_steps, grid_wall, n = grid_answer(args.side, args.cap)
    print("run                       p95 push dip mm   cell-steps     wall s   gains (kp/kd haa, hfe, kfe)")

    def row(name: str, c: Candidate | None, steps: int, wall: float) -> None:
        gains = "  ".join(f"{c.gains[g][0]:.4g}/{c.gains[g][1]:.4g}" for g in ("haa", "hfe", "kfe")) if c else "-"
        dip = f"{c.p95_dip_mm:.4f}" if c else "-"
        print(f"{name:<25} {dip:>15} {steps:>12,} {wall:>10.1f}   {gains}")

    row(f"recommend ({args.trials}+polish {args.polish})", rec.pick, rec_steps, rec_wall)
    row(f"grid ({n} cells)", grid, grid_steps, grid_wall)
    if rec.pick and grid:
        print(f"recommend / grid: p95 dip {rec.pick.p95_dip_mm / grid.p95_dip_mm:.3f}, cell-steps "
              f"{rec_steps / grid_steps:.3f}, wall {rec_wall / grid_wall:.3f}")


if __name__ == "__main__":
    main()
