"""`pupper tune` (`pupper_core.tune`): the grid's answer with less simulation, by Optuna's
ask/tell interface. Each generation asks ``batch`` trials, runs them as one
batch of cells through pupper's runner, and tells the results.

The study lives in the run directory: Optuna's SQLite storage
(``study.db``; ``optuna-dashboard sqlite:///DIR/study.db`` shows it),
``journal.jsonl`` (a line per finished generation: what a resume rebuilds
study.db from), ``trials.csv`` (a row per finished trial, in the order they
were asked), ``best.json``, ``pareto.csv`` for several objectives, and
``manifest.json`` (the inputs and the cell-steps spent). A tune holds the
directory's lock (``.pupper.lock``, the one pupper's other commands take)
while it runs.

Determinism: the sampler of generation ``g`` is seeded from ``(seed, g)``
and sees only the finished trials, so the same inputs give the same trials
in the same order at any thread count and after a resume (``--resume``
rebuilds the study from the generations the journal holds, each told
whole, and runs the rest again).

The code is split by concern: the inputs in ``_tune_plan``, the run
directory and its journal in ``_tune_study``, the search in
``_tune_search``, the files a study writes in ``_tune_tables``, its figures
in ``_tune_figures``; this module runs a study and is the CLI's entry.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pupper_core._rundir import atomic_write_text, printing
from pupper_core._native import PupperError
from pupper_core._types import exported_from
from pupper_core._rundir import held_signals, locked, sayer, stop_on_signals
from pupper_core._tune.figures import progress_figure as progress_figure
from pupper_core._tune.figures import trials_figure as trials_figure
from pupper_core._tune.figures import write_plots
from pupper_core._tune.plan import AGGREGATES as AGGREGATES
from pupper_core._tune.plan import INPUT_KEYS as INPUT_KEYS
from pupper_core._tune.plan import PENALTY as PENALTY
from pupper_core._tune.plan import SAMPLERS as SAMPLERS
from pupper_core._tune.plan import Dimension as Dimension
from pupper_core._tune.plan import TuneError as TuneError
from pupper_core._tune.plan import RUN_ONLY, STUDY, VARIANTS, _optuna, _Plan, _plan, parse_space
from pupper_core._tune.search import _search
from pupper_core._tune.study import JOURNAL as JOURNAL
from pupper_core._rundir import LOCK as LOCK
from pupper_core._tune.study import STUDY_FILES as STUDY_FILES
from pupper_core._tune.study import TEST_SIGNAL as TEST_SIGNAL
from pupper_core._tune.study import _check_fresh, _check_resume, _discard, _manifest, _resumed, _started
from pupper_core._tune.tables import _best, _finished, _rows, _write
from pupper_core._spec import DEFAULT_METRIC

__all__ = ["tune", "TuneResult", "parse_space"]


@dataclass
class TuneResult:
    """What a tune leaves: the Optuna study, the finished trials (as
    trials.csv has them), the best trial(s) (none when no trial could be
    ranked: each was told the penalty), and the run directory."""

    study: Any
    trials: list[dict[str, Any]]
    best: list[dict[str, Any]]
    out: Path | None
    cell_steps: int
    objectives: list[str] = field(default_factory=list)

    def to_pandas(self) -> Any:
        """The trials as a pandas DataFrame, a row per trial with the columns
        of trials.csv (pandas is imported here, not by pupper)."""
        try:
            import pandas as pd
        except ImportError as e:
            raise ImportError("TuneResult.to_pandas needs pandas: pip install pandas") from e
        return pd.DataFrame(self.trials)

    def __repr__(self) -> str:
        b = self.best[0] if self.best else {}
        return (f"TuneResult({len(self.trials)} trials, {self.cell_steps} cell-steps, "
                f"best {b.get('params')} -> {b.get('values')})")


@exported_from("pupper_core")
def tune(
    space: Sequence[str] | Mapping[str, Any],
    *,
    objective: str | Sequence[str] = DEFAULT_METRIC,
    maximize: bool = False,
    trials: int | None = None,
    budget: int | None = None,
    batch: int = 8,
    sampler: str = "tpe",
    seed: int = 0,
    aggregate: str = "mean",
    halving: int = 0,
    out: str | os.PathLike[str] | None = None,
    resume: bool = False,
    force: bool = False,
    progress: bool | Callable[[str], None] = True,
    **options: Any,
) -> TuneResult:
    """Search gains (or any grid axis) for the best ``objective``: each
    generation asks ``batch`` trials of Optuna's ``sampler`` (tpe with a
    constant liar, cmaes with population ``batch``, gp, random), runs them
    as one batch of cells and tells the results, until ``trials`` trials or
    ``budget`` cell-steps (never more: the last generation may be
    smaller). ``space``: ``["kp=5:200:log", "kd=0.05:10:log"]``
    (``:int`` for integers, ``A|B`` for choices). ``objective``: a
    summary.csv column, or several (a Pareto front). A trial whose robot
    fell, diverged or chattered at its torque limit (saturated: what the
    sweep's ranking never picks) is told a penalty (1e6, the worst), keeps
    its status, and is never a best (``best`` is empty when every trial
    was). With replicates the value is ``aggregate`` over them: mean, p95
    (the worse side), worst, or fail-rate. ``halving`` (an integer eta >=
    2, with replicates; 0, the default, is none): successive halving over
    the replicates — each generation runs every trial on replicates // eta
    robots first, and only the best 1/eta of them (by that value) on all (a
    replicate is drawn from its index, so the first rung's robots run again
    with the rest: a generation costs 2/eta of its full cost); the others
    are told pruned with their first value. ``out``: the run directory
    (``resume=True`` continues its study after an interrupt or a kill,
    ``force=True`` starts it anew); the tune holds its lock, so a second
    pupper there is refused. Every input is checked before anything is
    written. Other keywords are `pupper_core.sweep`'s (model, mode,
    seconds, push, replicates, ...).
    """
    optuna = _optuna()
    plan = _plan(space, objective, maximize, trials, budget, batch, sampler, seed, aggregate, halving,
                 dict(options))
    say = sayer(progress)
    if out is None and resume:
        raise TuneError("resume=True needs the run directory to continue: give out (or --resume DIR)")
    if out is None:
        study = optuna.create_study(study_name=STUDY, directions=plan.directions)
        spent = _search(optuna, study, plan, None, say)
        return _result(study, plan, None, spent)
    # a stop waits out the study's queries and is taken between batches
    with held_signals():
        return _tune_in(optuna, plan, Path(out), resume, force, say)


def _tune_in(optuna: Any, plan: _Plan, out_dir: Path, resume: bool, force: bool, say: Callable[[str], None]) -> TuneResult:
    """`tune` writing its study to ``out_dir``."""
    if resume:
        _check_resume(out_dir, plan)
    else:
        _check_fresh(out_dir, force)
    made = not out_dir.exists()
    with locked(out_dir, TuneError):
        if not resume:
            # again under the lock: a tune that ended between the first
            # check and the lock has left a study here
            _check_fresh(out_dir, force)
        study = _resumed(optuna, out_dir, plan) if resume else _started(optuna, out_dir, plan, force)
        try:
            spent = _search(optuna, study, plan, out_dir, say)
        except PupperError:
            # the runner refused what only a model shows (a pose's length,
            # a keyframe) before a trial finished: nothing is left behind
            if not resume and not _finished(study):
                _discard(out_dir, made)
            raise
        _write(out_dir, plan, study, spent, complete=True)
        from pupper_core import _report

        _report.report(out_dir)
    return _result(study, plan, out_dir, spent)


def _result(study: Any, plan: _Plan, out_dir: Path | None, spent: int) -> TuneResult:
    return TuneResult(study=study, trials=_rows(_finished(study), plan.dims, plan.objectives),
                      best=_best(study, plan), out=out_dir, cell_steps=spent, objectives=plan.objectives)


def _unranked(res: TuneResult) -> str:
    """Why a study has no best: its trials counted by status."""
    def said(status: str) -> str:
        return f"{status} ({'/'.join(res.objectives)} empty)" if status == "no value" else status

    counts = Counter(str(r["status"]) for r in res.trials)
    by_status = ", ".join(f"{n} {said(s)}" for s, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))
    return (f"no trial could be ranked: {by_status}; each was told the penalty, so none is a best and "
            "best.json is empty: search where the robot stands, off the torque limits and inside the "
            f"stability bound (a trial that fell, diverged, saturated or lay past the bound is never ranked), with a schedule that measures {'/'.join(res.objectives)}")


def _resume_args(a: dict[str, Any]) -> dict[str, Any]:
    """`--resume DIR` alone: the study's own inputs, with the flags a resume
    may change."""
    manifest = _manifest(Path(a["out"]))
    inputs = dict(manifest["inputs"])
    kept = {k: a[k] for k in ("out", "resume", "progress", "trials", "budget", *RUN_ONLY) if a.get(k) is not None}
    # what decides numbers comes from the study; a flag that says otherwise is refused
    for k in ("backend", "device"):
        if a.get(k) is not None and a[k] != inputs["options"].get(k):
            raise TuneError(f"cannot resume {a['out']}: it ran with {k} {inputs['options'].get(k) or 'cpu'}, "
                            f"not {a[k]}; drop --{k}, or use a new -o")
    if "trials" not in kept and "budget" not in kept:
        kept.update({k: v for k, v in dict(manifest.get("stop") or {}).items() if v is not None})
    return {**inputs.pop("options"), **{k: v for k, v in inputs.items() if k != "objectives"},
            "objective": inputs["objectives"], **kept}


def edge_line(dims: Sequence[Dimension], params: Mapping[str, Any]) -> str | None:
    """The line saying which of the best trial's values lie on the edge of
    their searched range (within 5 % of its span from an end), or None."""
    said = [f"{d.axis} {params[d.axis]:.6g}, {where} of {d.text()}"
            for d in dims if d.axis in params and (where := d.edge(params[d.axis]))]
    if not said:
        return None
    return ("the best trial lies on the edge of the searched range (" + "; ".join(said)
            + "): the best may lie beyond it; widen --space there")


def _cli(args_json: str) -> list[str]:
    """`pupper tune`: the CLI's parsed flags as JSON; prints the best trial(s)."""
    a = json.loads(args_json)
    plot = bool(a.pop("plot", False))
    compare = a.pop("compare", None)
    if a.get("resume") and not a.get("space"):
        a = _resume_args(a)
    space = a.pop("space")
    # SIGINT and SIGTERM stop the study as Ctrl-C stops Python (the CLI's own
    # handler only sets a flag that Rust's loops read, and a study is Python's)
    kept = (f"the trials finished so far are kept; continue with: pupper tune --resume {a['out']}" if a.get("out")
            else "nothing written")
    with stop_on_signals("tune", kept):
        res = tune(space, **a)
    lines = []
    for b in res.best:
        params = "  ".join(f"{k} {v:.6g}" if isinstance(v, float) else f"{k} {v}" for k, v in b["params"].items())
        values = "  ".join(f"{o} {v:.6g}" for o, v in zip(b["objectives"], b["values"]))
        lines.append(f"best (generation {b['generation']}, slot {b['slot']}): {params}  ->  {values}")
    if len(res.best) == 1 and (edge := edge_line(parse_space(space), res.best[0]["params"])):
        lines.append(edge)
    if not res.best:
        lines.append(_unranked(res))
    lines.append(f"{len(res.trials)} trials, {res.cell_steps} cell-steps")
    wrote = [str(res.out / "trials.csv")] if res.out else []
    if plot and res.out:
        wrote += [str(p) for p in write_plots(res.out, compare)]
        from pupper_core import _report

        _report.report(res.out)  # again, now with the plots beside it
    if res.out:
        wrote.append(str(res.out / "report.html"))
    # printed last: a stdout that cannot take it (a full disk) leaves the run whole
    with printing():
        for line in lines:
            print(line)
    return wrote


def lab_tune(
    variants: Sequence[str] = VARIANTS,
    *,
    space: Sequence[str] = ("kp=10:120:log", "kd=0.5:5:log"),
    objective: str = DEFAULT_METRIC,
    trials: int = 64,
    batch: int = 16,
    sampler: str = "tpe",
    seed: int = 0,
    out: str | os.PathLike[str] | None = None,
    progress: bool | Callable[[str], None] = True,
    seconds: float = 6.0,
    sine: Sequence[float] = (2.0, 1.2),
    **options: Any,
) -> dict[str, TuneResult]:
    """`pupper lab --tune`: the lab's question (torque mode, each body from
    its own stand pose under the vertical sine, no push) answered per body
    by a search instead of the 4x4 grid: a study per body in
    ``<out>/<body>/``, and ``<out>/best.csv`` with each body's best gains."""
    results: dict[str, TuneResult] = {}
    root = Path(out) if out is not None else None
    for body in variants:
        results[body] = tune(list(space), objective=objective, trials=trials, batch=batch, sampler=sampler,
                             seed=seed, out=None if root is None else root / body, progress=progress,
                             variant=body, mode="torque", pose="auto", push=False, seconds=seconds,
                             sine=list(sine), **options)
    if root is not None:
        import io

        axes = [d.axis for d in parse_space(list(space))]
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["variant", *axes, objective, "trials", "cell_steps"])
        for body, r in results.items():
            b: dict[str, Any] = r.best[0] if r.best else {"params": {}, "values": [math.nan]}
            w.writerow([body, *[repr(float(b["params"].get(a, math.nan))) for a in axes],
                        repr(float(b["values"][0])), len(r.trials), r.cell_steps])
        atomic_write_text(root / "best.csv", buf.getvalue())
    return results


def _lab_cli(args_json: str) -> list[str]:
    """`pupper lab --tune`: the CLI's parsed flags as JSON; a line per body."""
    a = json.loads(args_json)
    with stop_on_signals("lab --tune", "each body's trials finished so far are kept in its own directory"):
        res = lab_tune(a.pop("variants"), **a)
    with printing():
        for body, r in res.items():
            b = r.best[0] if r.best else None
            if b is None:
                print(f"{body:<10} no trial stood")
                continue
            params = "  ".join(f"{k} {v:.4g}" for k, v in b["params"].items())
            print(f"{body:<10} {params}  ->  {r.objectives[0]} {b['values'][0]:.6g}  "
                  f"({len(r.trials)} trials, {r.cell_steps} cell-steps)")
    return [str(Path(a["out"]) / "best.csv")] if a.get("out") else []
