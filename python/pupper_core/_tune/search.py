"""A tune's search (``pupper_core._tune`` runs it): each generation asks
its trials of a sampler seeded from (seed, generation), runs them as one
batch of cells through pupper's runner, tells their values (successive
halving over the replicates, if asked) and is journaled."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pupper_core._run import sweep
from pupper_core._rundir import signals_through
from pupper_core._tune.plan import PENALTY, VARIANTS, _Plan, _sampler, _steps_per_cell
from pupper_core._tune.study import _append_journal, _test_signal
from pupper_core._tune.tables import _best, _finished, _write


def _value(res: Any, i: int, objective: str, aggregate: str, maximize: bool) -> tuple[float, str]:
    """Trial i's value of one objective and its status."""
    worst = -PENALTY if maximize else PENALTY
    table = res.table
    if "failure_fraction" in table:  # replicated: an aggregate over the replicates
        failed = float(table["failure_fraction"][i])
        if aggregate == "fail-rate":
            return failed, "ok" if failed == 0 else "some fell"
        if failed >= 1:
            return worst, "fell"
        if aggregate == "worst":
            reps = res.replicates
            idx = res.table["index"][i]
            xs = [float(v) for v, j, s in zip(reps[objective], reps["index"], reps["status"])
                  if j == idx and s in ("ok", "saturated")]
            v = (min(xs) if maximize else max(xs)) if xs else math.nan
        else:
            v = float(table[f"{aggregate}:{objective}"][i])
        return (v, "ok") if math.isfinite(v) else (worst, "no value")
    status = str(table["status"][i])
    # the sweep's ranking rule: a robot that fell, diverged or chattered at
    # its torque limit (saturated) is never the answer
    if status != "ok":
        return worst, status
    v = float(table[objective][i])
    return (v, status) if math.isfinite(v) else (worst, "no value")


def _want(plan: _Plan, n_done: int, spent: int) -> int:
    """How many trials the next generation asks (0: the study is done)."""
    if plan.trials is not None and n_done >= plan.trials:
        return 0
    if plan.budget is not None and spent >= plan.budget:
        return 0
    want = plan.batch if plan.trials is None else min(plan.batch, plan.trials - n_done)
    if plan.budget is not None:
        # never past the budget: the last generation may be smaller
        want = min(want, (plan.budget - spent) // plan.cell_steps())
    return want


def _search(optuna: Any, study: Any, plan: _Plan, out_dir: Path | None, say: Callable[[str], None]) -> int:
    """Generations until the trials or the budget are spent; the cell-steps spent."""
    done = _finished(study)
    spent = sum(int(t.user_attrs.get("cell_steps", 0)) for t in done)
    generation = max((t.user_attrs["generation"] + 1 for t in done), default=0)
    dists = {d.axis: d.distribution(optuna) for d in plan.dims}
    run = _Cells(plan, set(), say)
    while (want := _want(plan, len(_finished(study)), spent)) > 0:
        study.sampler = _sampler(optuna, plan.sampler, plan.seed, generation, plan.batch, len(plan.objectives) > 1)
        asked = []
        for slot in range(want):
            t = study.ask(dists)
            t.set_user_attr("generation", generation)
            t.set_user_attr("slot", slot)
            asked.append(t)
            _test_signal("ask", generation, slot + 1)
        spent += _tell_halving(study, plan, asked, run) if plan.halving else _tell(study, plan, asked, run)
        if out_dir is not None:
            _append_journal(out_dir, study, generation)
            _test_signal("journal", generation, 0)
        generation += 1
        if out_dir is not None:
            _write(out_dir, plan, study, spent, complete=False)
        best = _best(study, plan)
        ranked = ("best " + ", ".join(f"{o} {v:.6g}" for o, v in zip(plan.objectives, best[0]["values"]))
                  if best else "no trial ranked yet")
        say(f"generation {generation}: {len(_finished(study))} trials, {spent} cell-steps; {ranked}")
    return spent


@dataclass
class _Cells:
    """Runs trials as one batch of cells; each note the runner gives, once
    per study."""

    plan: _Plan
    notes: set[str]
    say: Callable[[str], None]

    def __call__(self, group: Sequence[Any], opts: Mapping[str, Any]) -> list[tuple[list[float], list[str], int]]:
        """The trials' values, statuses and cell-steps."""
        if not group:
            return []
        cells = []
        for t in group:
            cell: dict[str, float | str] = {"name": f"g{t.user_attrs['generation']}s{t.user_attrs['slot']}"}
            for d in self.plan.dims:
                v = t.params[d.axis]
                cell[d.axis] = float(VARIANTS.index(v)) if d.axis == "variant" else float(v)
            cells.append(cell)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with signals_through():
                res = sweep(cells, progress=False, **opts)
        for w in caught:
            text = str(w.message)
            if text not in self.notes:
                self.notes.add(text)
                self.say(f"note: {text}")
        out = []
        for i, t in enumerate(group):
            got = [_value(res, i, o, self.plan.aggregate, self.plan.maximize) for o in self.plan.objectives]
            ran = res.cell_steps[i]
            steps = int(ran) if ran is not None else _steps_per_cell(opts, t.params, self.plan.model_dt)
            out.append(([v for v, _ in got], [st for _, st in got], steps))
        return out


def _status_of(statuses: list[str]) -> str:
    return statuses[0] if len(set(statuses)) == 1 else ",".join(statuses)


def _tell(study: Any, plan: _Plan, asked: list[Any], run: _Cells) -> int:
    """Runs a generation's trials and tells each its values; the cell-steps spent."""
    spent = 0
    for k, (t, (vals, statuses, steps)) in enumerate(zip(asked, run(asked, plan.options)), 1):
        spent += steps
        t.set_user_attr("cell_steps", steps)
        t.set_user_attr("status", _status_of(statuses))
        study.tell(t, vals if len(vals) > 1 else vals[0])
        _test_signal("tell", t.user_attrs["generation"], k)
    return spent


def _tell_halving(study: Any, plan: _Plan, asked: list[Any], run: _Cells) -> int:
    """Successive halving over the replicates: every trial on replicates //
    eta robots (rung 0), then the best 1/eta of them on all (rung 1); the
    others told pruned with their first value. The cell-steps spent."""
    import optuna

    r0 = max(1, int(plan.options.get("replicates", 1)) // plan.halving)
    first = run(asked, {**plan.options, "replicates": r0})
    sign = -1.0 if plan.maximize else 1.0
    order = sorted(range(len(asked)), key=lambda i: (sign * first[i][0][0], asked[i].user_attrs["slot"]))
    up = set(order[:math.ceil(len(asked) / plan.halving)])
    for i, t in enumerate(asked):
        t.set_user_attr("rung", 1 if i in up else 0)
    promoted = [t for t in asked if t.user_attrs["rung"] == 1]
    second = dict(zip((t.number for t in promoted), run(promoted, plan.options)))
    spent = 0
    for k, (t, (vals, statuses, steps)) in enumerate(zip(asked, first), 1):
        t.report(vals[0], step=r0)
        if t.number in second:
            vals, statuses, more = second[t.number]
            steps += more
        spent += steps
        t.set_user_attr("cell_steps", steps)
        if t.number in second:
            t.set_user_attr("status", _status_of(statuses))
            study.tell(t, vals[0])
        else:
            t.set_user_attr("status", "pruned")
            study.tell(t, state=optuna.trial.TrialState.PRUNED)
        _test_signal("tell", t.user_attrs["generation"], k)
    return spent
