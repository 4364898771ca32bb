"""The stand task (`--task stand`, the default): every candidate stands on
each drawn robot and takes the push; the worst-side (p95) push dip over
the robots ranks it."""

from __future__ import annotations

import math
import shlex
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core._recommend.plan import Plan, RecommendError, Task
from pupper_core._recommend.search import Candidate, _cell, judge


class Stand(Task):
    """The stand task: `Task`'s words are its own."""

    def simulate(self, plan: Plan, cands: Sequence[Candidate], robot_models: Sequence[str],
                 say: Callable[[str], None], own_gains: bool = False) -> None:
        """One sweep per joint model, the robots drawn alike for every
        candidate; each one's p95 dip, falls, saturation and peak torque."""
        import warnings

        from pupper_core._run import sweep

        if not cands:
            return
        # own_gains: one candidate, the gains its model's actuators hold (an export)
        cells: Any = None if own_gains else [_cell(plan, c.gains, f"c{i}") for i, c in enumerate(cands)]
        dips: list[list[float]] = [[] for _ in cands]
        peaks: list[list[float]] = [[] for _ in cands]
        heights: list[list[float]] = [[] for _ in cands]
        for model in robot_models:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                res = sweep(cells, model=model, replicates=plan.per_model, progress=False, **plan.sweep_options())
            for w in caught:
                say(f"note: {w.message}")
            # one robot with nothing drawn is a plain sweep: its table is the robots'
            reps = res.replicates if res.replicates is not None else res
            for i, status, dip, sat, peak, z in zip(reps["index"], reps["status"], reps["push_dip_mm"],
                                                    reps["saturation_frac"], reps["peak_torque"], reps["final_z"]):
                c = cands[int(i)]
                c.robots += 1
                if status not in ("ok", "saturated"):
                    c.fell += 1
                    continue
                c.max_saturation = float(np.nanmax([c.max_saturation, float(sat)]))
                dips[int(i)].append(float(dip))
                peaks[int(i)].append(float(peak))
                heights[int(i)].append(float(z))
            for i, steps in enumerate(res.cell_steps):
                cands[i].cell_steps += int(steps or 0)
        for c, d, p, h in zip(cands, dips, peaks, heights):
            c.p95_dip_mm = float(np.percentile(d, 95)) if d and all(math.isfinite(x) for x in d) else math.nan
            c.p95_peak_torque = float(np.percentile(p, 95)) if p else math.nan
            c.min_height_m = min(h) if h else math.nan
            c.score = c.p95_dip_mm
            judge(plan, c, "no push dip measured (the run ends too early)")

    def check_run(self, seconds: float, push_force: float | None) -> None:
        """A run that ends before the push's dip is known measures no push
        dip, so no candidate could hold: said before anything runs."""
        from pupper_core._native import DIP_AFTER, sweep_defaults

        d = sweep_defaults()
        need = float(d["push_at"]) + float(d["push_duration"]) + DIP_AFTER
        if seconds < need - 1e-9:
            raise RecommendError(f"--seconds {seconds:g} ends before the push (at {d['push_at']:g} s, for "
                                 f"{d['push_duration']:g} s) and the {DIP_AFTER:g} s after it, where its dip is "
                                 f"measured, are over: give --seconds {need:g} or more")

    def row(self, c: Candidate) -> dict[str, Any]:
        return {self.column: c.p95_dip_mm}

    def card_line(self, plan: Plan, pick: Candidate, searched: Candidate | None) -> str:
        also = (f" (on the exported MJCF, whose numbers MjSpec writes to six digits; {searched.p95_dip_mm:.4g} mm in "
                "the search)" if searched and f"{searched.p95_dip_mm:.4g}" != f"{pick.p95_dip_mm:.4g}" else "")
        return f"p95 push dip {pick.p95_dip_mm:.4g} mm{also}"

    def reproduce(self, plan: Plan, d: Path) -> str:
        """The sweep that gives the card's push dip again, to the digit."""
        if plan.fit_robots:
            return ""
        args = ["pupper", "sweep", "--model", str(d / "recommended.xml"), "--mode", "torque", "--motor", plan.motor,
                "--seconds", f"{plan.seconds:g}", "--replicates", str(plan.robots), "--seed", str(plan.seed),
                "--common-draws"]
        for r in plan.spread:
            args += ["--randomize", r]
        if plan.push_force is not None:
            args += ["--push-force", f"{plan.push_force:g}"]
        return shlex.join(args)
