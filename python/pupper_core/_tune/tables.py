"""What a study writes in its run directory (``pupper_core._tune`` runs
it): trials.csv (a row per finished trial, in the order they were asked),
best.json, pareto.csv for several objectives, and manifest.json, each
replaced whole."""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pupper_core import _native
from pupper_core._rundir import atomic_write_text
from pupper_core._tune.plan import PENALTY, Dimension, _Plan


def _finished(study: Any) -> list[Any]:
    import optuna

    told = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)
    return sorted((t for t in study.get_trials(deepcopy=False) if t.state in told),
                  key=lambda t: (t.user_attrs["generation"], t.user_attrs["slot"]))


def _spent(study: Any) -> int:
    return sum(int(t.user_attrs.get("cell_steps", 0)) for t in _finished(study))


def _rows(done: Sequence[Any], dims: Sequence[Dimension], objectives: Sequence[str]) -> list[dict[str, Any]]:
    rows = []
    for k, t in enumerate(done):
        r: dict[str, Any] = {"trial": k, "generation": t.user_attrs["generation"], "slot": t.user_attrs["slot"]}
        r.update({d.axis: t.params[d.axis] for d in dims})
        # a pruned trial's value is its first rung's
        vals = t.values if t.values is not None else [t.intermediate_values[max(t.intermediate_values)]]
        r.update({o: v for o, v in zip(objectives, vals)})
        r["rung"] = t.user_attrs.get("rung", 0)
        r["status"] = t.user_attrs.get("status", "")
        r["cell_steps"] = t.user_attrs.get("cell_steps", 0)
        rows.append(r)
    return rows


def _best(study: Any, plan: _Plan) -> list[dict[str, Any]]:
    """The best trial(s), never one told the penalty: a study whose every
    trial fell, diverged, saturated or had no value has none."""
    try:
        best = study.best_trials
    except ValueError:
        return []
    worst = -PENALTY if plan.maximize else PENALTY
    out = []
    for t in sorted(best, key=lambda t: (t.user_attrs["generation"], t.user_attrs["slot"])):
        if worst in t.values:
            continue
        out.append({"generation": t.user_attrs["generation"], "slot": t.user_attrs["slot"],
                    "params": dict(t.params), "values": list(t.values), "objectives": list(plan.objectives),
                    "status": t.user_attrs.get("status", "")})
    return out


def _write(out: Path, plan: _Plan, study: Any, spent: int, complete: bool) -> None:
    """trials.csv, best.json, pareto.csv (several objectives) and
    manifest.json, each replaced whole (``study`` None: none yet)."""
    import io

    dims, objectives = plan.dims, plan.objectives
    rows = _rows(_finished(study), dims, objectives) if study is not None else []
    buf = io.StringIO()
    header = ["trial", "generation", "slot", *[d.axis for d in dims], *objectives, "status", "rung", "cell_steps"]
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for r in rows:
        w.writerow([repr(r[h]) if isinstance(r[h], float) else r[h] for h in header])
    atomic_write_text(out / "trials.csv", buf.getvalue())
    best = _best(study, plan) if study is not None else []
    atomic_write_text(out / "best.json", json.dumps(best, indent=2) + "\n")
    if len(objectives) > 1:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["generation", "slot", *[d.axis for d in dims], *objectives])
        for b in best:
            w.writerow([b["generation"], b["slot"], *[b["params"][d.axis] for d in dims],
                        *[repr(float(v)) for v in b["values"]]])
        atomic_write_text(out / "pareto.csv", buf.getvalue())
    _write_manifest(out, plan, len(rows), spent, complete)


def _write_manifest(out: Path, plan: _Plan, trials: int, spent: int, complete: bool) -> None:
    import optuna

    manifest = {"inputs": plan.inputs, "optuna_version": optuna.__version__, "stop": plan.stop, "trials": trials,
                "cell_steps": spent, "complete": complete,
                "study": "study.db (optuna-dashboard sqlite:///study.db)"}
    _native.write_manifest(os.fspath(out), "tune", manifest)
