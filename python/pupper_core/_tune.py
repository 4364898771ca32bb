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
"""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import socket
import sys
import tempfile
import time
import warnings
from collections import Counter
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from pupper_core._native import ConfigError, PupperError

if TYPE_CHECKING:
    from pupper_core._native import ErrorCode

__all__ = ["tune", "TuneResult", "parse_space"]

#: The value a trial whose robot fell or diverged (or has no value) is told:
#: worse than any real one, finite so every sampler takes it.
PENALTY = 1e6
STUDY = "pupper-tune"
SAMPLERS = ("tpe", "cmaes", "gp", "random")
AGGREGATES = ("mean", "p95", "worst", "fail-rate")
#: The named bodies of the variant axis, in pupper's order (its values are indices).
VARIANTS = ("original", "long-leg", "heavy")
#: The run directory's lock file, the one pupper's Rust commands take (an
#: flock: the OS drops it when its holder dies, kill -9 included).
LOCK = ".pupper.lock"
#: Finished generations, a JSON line each, appended and fsynced once the
#: whole generation is told: what a resume rebuilds study.db from.
JOURNAL = "journal.jsonl"
#: What a fresh study writes (and --force removes) in its run directory.
STUDY_FILES = ("study.db", "study.db-journal", "study.db-wal", "study.db-shm", JOURNAL, "trials.csv", "best.json",
               "pareto.csv", "manifest.json")
#: Test hook (tests/test_tune_trust.py): ``SIG:POINT:G:K`` makes the process
#: send itself SIGKILL (SIG ``KILL``) or SIGSTOP (``STOP``) after the K-th
#: ask (POINT ``ask``) or tell (``tell``) of generation G, once G is
#: journaled (``journal:G:0``), after a fresh study's first manifest
#: (``start:0:0``), or after a resume's rebuild added its K-th trial
#: (``rebuild:0:K``).
TEST_SIGNAL = "PUPPER_TUNE_TEST_SIGNAL"


class TuneError(ConfigError, ValueError):
    """Bad input to `tune`: one line naming the problem and the fix. A
    `pupper_core.ConfigError` (so a `PupperError`), and a ValueError as it
    always was; ``kind`` is ``config``, or ``run_busy`` for a run directory
    another pupper is writing."""

    kind: ErrorCode = "config"

    def __init__(self, message: str, kind: ErrorCode = "config") -> None:
        super().__init__(message)
        self.kind = kind


def _optuna() -> Any:
    try:
        import optuna
    except ImportError:
        raise TuneError("pupper tune needs Optuna: install the extra with "
                        "`make setup PUPPER_EXTRAS=tune` (or pip install 'pupper_core[tune]')") from None
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna


def _test_signal(point: str, generation: int, k: int) -> None:
    """The test hook (TEST_SIGNAL): a kill or a stop at a named moment."""
    sig, _, at = os.environ.get(TEST_SIGNAL, "").partition(":")
    if at and at == f"{point}:{generation}:{k}":
        os.kill(os.getpid(), getattr(signal, f"SIG{sig}"))


def _num(x: float) -> str:
    # as written (5:200) where that is exact, else every digit: a resume
    # alone reads the space back from this text
    short = f"{x:g}"
    return short if float(short) == x else repr(float(x))


@dataclass(frozen=True)
class Dimension:
    """One searched axis: a float range (log or linear), an int range, or choices."""

    axis: str
    low: float = 0.0
    high: float = 0.0
    log: bool = False
    integer: bool = False
    choices: tuple[Any, ...] = ()

    def distribution(self, optuna: Any) -> Any:
        d = optuna.distributions
        if self.choices:
            return d.CategoricalDistribution(list(self.choices))
        if self.integer:
            return d.IntDistribution(int(self.low), int(self.high), log=self.log)
        return d.FloatDistribution(self.low, self.high, log=self.log)

    def text(self) -> str:
        if self.choices:
            return f"{self.axis}=" + "|".join(str(c) for c in self.choices)
        kind = ":int" if self.integer else (":log" if self.log else "")
        return f"{self.axis}={_num(self.low)}:{_num(self.high)}{kind}"


def parse_space(specs: Sequence[str] | Mapping[str, Any]) -> list[Dimension]:
    """``AXIS=LOW:HIGH[:log|:int]`` or ``AXIS=A|B|C`` (choices), or a dict
    ``{axis: (low, high[, "log"|"int"]) or [choices]}``. Axis names are read
    as the grid reads them (``KP.HFE`` is ``kp.hfe``)."""
    items: list[tuple[str, Any]]
    if isinstance(specs, Mapping):
        items = [(str(k), v) for k, v in specs.items()]
    else:
        items = []
        for s in [specs] if isinstance(specs, str) else specs:
            if "=" not in s:
                raise TuneError(f"--space '{s}' has no '=': write AXIS=LOW:HIGH[:log], e.g. kp=5:200:log")
            name, rest = s.split("=", 1)
            items.append((name, rest.strip()))
    if not items:
        raise TuneError("no --space given: name what to search, e.g. --space kp=5:200:log --space kd=0.05:10:log")
    out: list[Dimension] = []
    for name, v in items:
        axis = name.strip().lower().replace("-", "_")  # as the Rust grid reads an axis name
        if any(d.axis == axis for d in out):
            raise TuneError(f"--space {axis} is given twice: give each axis once")
        out.append(_dimension(axis, v))
    return out


def _dimension(name: str, v: Any) -> Dimension:
    if isinstance(v, str) and "|" in v:
        texts = [c.strip() for c in v.split("|")]
        if "" in texts:
            raise TuneError(f"--space {name}={v} has an empty choice: write A|B|C, e.g. {name}=5|10|20")
        return Dimension(name, choices=tuple(_choice(c) for c in texts))
    if isinstance(v, list) and (len(v) > 3 or v and not isinstance(v[0], (int, float))):
        return Dimension(name, choices=tuple(v))
    parts = v.split(":") if isinstance(v, str) else list(v) if isinstance(v, (list, tuple)) else []
    kind = str(parts[2]) if len(parts) == 3 else ""
    try:
        if len(parts) not in (2, 3):
            raise ValueError
        low, high = float(parts[0]), float(parts[1])
    except (ValueError, TypeError):
        raise TuneError(f"--space {name}={v}: write LOW:HIGH[:log|:int], e.g. {name}=5:200:log") from None
    if not (math.isfinite(low) and math.isfinite(high) and low < high) or kind not in ("", "log", "int"):
        raise TuneError(f"--space {name}={v}: give LOW < HIGH, finite, and :log or :int at most")
    if kind == "log" and low <= 0:
        raise TuneError(f"--space {name}={v}: a log range needs LOW > 0")
    if kind == "int" and not (low.is_integer() and high.is_integer()):
        raise TuneError(f"--space {name}={v}: an :int range needs whole numbers at its ends, e.g. {name}=1:8:int")
    return Dimension(name, low, high, log=kind == "log", integer=kind == "int")


def _choice(text: str) -> Any:
    try:
        return float(text)
    except ValueError:
        return text.strip()


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


def _atomic_write(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    with os.fdopen(fd, "w", newline="") as f:
        f.write(text)
    os.replace(tmp, path)


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


def _steps_per_cell(options: Mapping[str, Any], params: Mapping[str, Any], model_dt: float) -> int:
    seconds = float(options.get("seconds", 10.0))
    dt = float(params.get("timestep", model_dt))
    reps = max(1, int(options.get("replicates", 1)))
    return int(round(seconds / dt)) * reps


def _sampler(optuna: Any, name: str, seed: int, generation: int, batch: int, multi: bool) -> Any:
    # one sampler per generation, seeded from (seed, generation): what it
    # proposes depends on the seed and the finished trials alone
    s = (seed * 1_000_003 + generation) % (2**32)
    if name == "tpe":
        return optuna.samplers.TPESampler(seed=s, constant_liar=True, multivariate=not multi)
    if name == "random":
        return optuna.samplers.RandomSampler(seed=s)
    if name == "cmaes":
        if multi:
            raise TuneError("--sampler cmaes takes one objective: use tpe or random for several")
        try:
            import cmaes  # type: ignore[import-untyped]  # noqa: F401
        except ImportError:
            raise TuneError("--sampler cmaes needs the cmaes package: `make setup PUPPER_EXTRAS=tune`") from None
        return optuna.samplers.CmaEsSampler(seed=s, popsize=batch, warn_independent_sampling=False)
    if name == "gp":
        try:
            import torch  # type: ignore[import-not-found,unused-ignore]  # noqa: F401
        except ImportError:
            raise TuneError("--sampler gp needs torch (Optuna's GP sampler runs on it), which the tune extra "
                            "leaves out: pip install torch, or use tpe, cmaes or random") from None
        return optuna.samplers.GPSampler(seed=s)
    raise TuneError(f"--sampler {name} is unknown: use one of {', '.join(SAMPLERS)}")


#: Options that change how a study runs, never its numbers: a resume may
#: change them.
RUN_ONLY = ("threads", "chunk_cells", "ray")
#: The inputs a tune's manifest holds (what a resume alone reads back).
INPUT_KEYS = ("space", "objectives", "maximize", "batch", "sampler", "seed", "aggregate", "options")


def _compared(inputs: Mapping[str, Any]) -> dict[str, Any]:
    """The inputs a resume must repeat: all but the run-only options."""
    out = dict(inputs)
    out["options"] = {k: v for k, v in dict(inputs.get("options", {})).items() if k not in RUN_ONLY}
    return out


@dataclass
class _Plan:
    """A study's inputs, every one checked."""

    dims: list[Dimension]
    objectives: list[str]
    maximize: bool
    trials: int | None
    budget: int | None
    batch: int
    sampler: str
    seed: int
    aggregate: str
    halving: int
    options: dict[str, Any]
    model_dt: float

    @property
    def inputs(self) -> dict[str, Any]:
        out = {"space": [d.text() for d in self.dims], "objectives": self.objectives, "maximize": self.maximize,
               "batch": self.batch, "sampler": self.sampler, "seed": self.seed, "aggregate": self.aggregate,
               "options": dict(self.options)}
        if self.halving:
            out["halving"] = self.halving
        return out

    @property
    def directions(self) -> list[str]:
        return ["maximize" if self.maximize else "minimize"] * len(self.objectives)

    @property
    def stop(self) -> dict[str, int | None]:
        return {"trials": self.trials, "budget": self.budget}

    def cell_steps(self, params: Mapping[str, Any] | None = None) -> int:
        """One trial's cell-steps at full length (``params`` may set the timestep)."""
        return _steps_per_cell(self.options, params or {}, self.model_dt)


def _objectives(objective: str | Sequence[str]) -> list[str]:
    given = [objective] if isinstance(objective, str) else list(objective)
    names = [o.strip() for obj in given for o in obj.split(",") if o.strip()]
    if not names:
        raise TuneError("--objective is empty: name a summary.csv column, e.g. --objective last_1s_std_mm")
    for o in names:
        if names.count(o) > 1:
            raise TuneError(f"--objective names {o} twice: give each objective once")
    return names


def _check_counts(trials: int | None, budget: int | None, batch: int, sampler: str, aggregate: str,
                  halving: int) -> None:
    if sampler not in SAMPLERS:
        raise TuneError(f"--sampler {sampler} is unknown: use one of {', '.join(SAMPLERS)}")
    if aggregate not in AGGREGATES:
        raise TuneError(f"--aggregate {aggregate} is unknown: use one of {', '.join(AGGREGATES)}")
    if batch < 1:
        raise TuneError(f"--batch {batch}: give at least 1 trial per generation")
    if (trials is None) == (budget is None):
        raise TuneError("give --trials N or --budget CELL_STEPS (one of them): how long to search")
    if trials is not None and trials < 1 or budget is not None and budget < 1:
        raise TuneError("--trials and --budget must be at least 1")
    # 0 is no halving (the default); 1 would promote every trial
    if halving and halving < 2:
        raise TuneError(f"--halving {halving}: give an eta of 2 or more (the share promoted is 1/eta), "
                        "or 0 for none")


def _check_domains(dims: Sequence[Dimension], options: Mapping[str, Any]) -> None:
    """Each range's ends (each choice) checked as grid values of its axis,
    with the study's options, by the Rust grid's own checks, which know
    every axis's domain: what the runner would refuse at a trial is refused
    before anything is written. (A grid that passes them is then refused
    for its size, max_cells=0, before anything runs.)"""
    import pupper_core as pc
    from pupper_core import _native

    sweep_options = pc._options(options)
    for d in dims:
        values: Any
        if d.axis == "variant":
            if not d.choices or not all(isinstance(c, str) for c in d.choices):
                raise TuneError(f"--space {d.text()}: the variant axis takes names: write e.g. "
                                f"variant={'|'.join(VARIANTS)}")
            values = ",".join(d.choices)
        elif d.choices:
            if not all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in d.choices):
                raise TuneError(f"--space {d.text()}: {d.axis} takes numbers: write e.g. {d.axis}=5|10|20, "
                                "or a range LOW:HIGH")
            values = [float(c) for c in d.choices]
        else:
            values = [d.low, d.high]
        try:
            _native.sweep({d.axis: values}, **{**sweep_options, "max_cells": 0})
        except pc.GridError as e:
            if "over the limit of 0" not in str(e):
                raise TuneError(f"--space {d.text()}: {str(e).removesuffix('; fix the value list')}") from None
        except pc.PupperError as e:
            raise TuneError(str(e)) from None


def _plan(space: Sequence[str] | Mapping[str, Any], objective: str | Sequence[str], maximize: bool,
          trials: int | None, budget: int | None, batch: int, sampler: str, seed: int, aggregate: str,
          halving: int, options: dict[str, Any]) -> _Plan:
    """Every input checked, before anything is written."""
    import pupper_core as pc
    from pupper_core import _native

    optuna = _optuna()
    dims = parse_space(space)
    objectives = _objectives(objective)
    _check_counts(trials, budget, batch, sampler, aggregate, halving)
    try:
        _native.check_axes([d.axis for d in dims])
    except pc.GridError as e:
        raise TuneError(f"--space: {e}") from None
    known = set(pc.METRICS) - {"status"}
    for o in objectives:
        if o not in known:
            raise TuneError(f"--objective {o} is not a metric: use one of {', '.join(sorted(known))}")
    reps = int(options.get("replicates", 1))
    if halving and reps < halving:
        raise TuneError(f"--halving {halving} halves over the replicates: give --replicates {halving} or more")
    if halving and len(objectives) > 1:
        raise TuneError("--halving takes one objective: drop the others, or --halving")
    # a fallen robot stops stepping: its cell-steps are saved for trials
    options.setdefault("stop_fallen", True)
    if reps > 1:
        options.setdefault("seed", seed)
    # the sampler is made per generation: made once now, its refusals come first
    _sampler(optuna, sampler, seed, 0, batch, len(objectives) > 1)
    _check_domains(dims, options)
    # the model's timestep, for the cell-steps spent (and an early check of the model)
    try:
        model_dt = float(pc.info(options.get("model", "pupper_v3"))["timestep"])
    except pc.PupperError as e:
        raise TuneError(str(e)) from None
    plan = _Plan(dims, objectives, maximize, trials, budget, batch, sampler, seed, aggregate, halving, options,
                 model_dt)
    if budget is not None and budget < batch * plan.cell_steps():
        raise TuneError(f"--budget {budget} is below one generation ({batch} trials x "
                        f"{plan.cell_steps()} cell-steps): raise it or lower --batch")
    return plan


def tune(
    space: Sequence[str] | Mapping[str, Any],
    *,
    objective: str | Sequence[str] = "last_1s_std_mm",
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
    say = _sayer(progress)
    if out is None and resume:
        raise TuneError("resume=True needs the run directory to continue: give out (or --resume DIR)")
    if out is None:
        study = optuna.create_study(study_name=STUDY, directions=plan.directions)
        spent = _search(optuna, study, plan, None, say)
        return _result(study, plan, None, spent)
    out_dir = Path(out)
    if resume:
        _check_resume(out_dir, plan)
    else:
        _check_fresh(out_dir, force)
    made = not out_dir.exists()
    with _locked(out_dir):
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


def _sayer(progress: bool | Callable[[str], None]) -> Callable[[str], None]:
    if callable(progress):
        return progress
    if progress:
        return lambda line: print(line, file=sys.stderr, flush=True)
    return lambda line: None


def _result(study: Any, plan: _Plan, out_dir: Path | None, spent: int) -> TuneResult:
    return TuneResult(study=study, trials=_rows(_finished(study), plan.dims, plan.objectives),
                      best=_best(study, plan), out=out_dir, cell_steps=spent, objectives=plan.objectives)


# -- the run directory: its lock, a fresh start, a resume -------------------


def _is_ours_to_ignore(name: str) -> bool:
    """The lock, and the temporary files a killed writer left: not a study."""
    # atomic_write's temporary files are `.NAME.tmpPID`
    return name == LOCK or name.startswith(".") and ".tmp" in name


def _check_fresh(out_dir: Path, force: bool) -> None:
    if out_dir.exists() and not out_dir.is_dir():
        raise TuneError(f"output directory '{out_dir}' is a file: choose another -o")
    if out_dir.is_dir() and not force and not all(_is_ours_to_ignore(p.name) for p in out_dir.iterdir()):
        raise TuneError(f"output directory '{out_dir}' already exists: choose another -o, "
                        "add --force to overwrite it, or --resume it")


def _manifest(out_dir: Path) -> dict[str, Any]:
    """A tune's manifest.json, or one line saying why there is none to resume."""
    path = out_dir / "manifest.json"
    if not path.is_file():
        raise TuneError(f"--resume {out_dir}: no tune there (no manifest.json); start it without --resume")
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError):
        raise TuneError(f"cannot resume {out_dir}: its manifest.json is not valid JSON (damaged?): "
                        "start the study anew with --force, or use a new -o") from None
    if not isinstance(manifest, dict) or manifest.get("kind") != "tune":
        from pupper_core import _report

        what = _report._kind(manifest) if isinstance(manifest, dict) else "damaged"
        raise TuneError(f"cannot resume {out_dir}: it is a {what}'s run directory, not a tune's: "
                        "give --resume a tune's directory, or start the tune with a new -o")
    inputs = manifest.get("inputs")
    if not (isinstance(inputs, dict) and all(k in inputs for k in INPUT_KEYS)
            and isinstance(inputs["options"], dict) and isinstance(inputs["space"], list)):
        raise TuneError(f"cannot resume {out_dir}: its manifest.json has no tune's inputs (damaged?): "
                        "start the study anew with --force, or use a new -o")
    return manifest


def _check_resume(out_dir: Path, plan: _Plan) -> None:
    """The study in out_dir is a tune's, of these inputs (run-only options aside)."""
    old = _manifest(out_dir)
    was, now = _compared(old["inputs"]), _compared(json.loads(json.dumps(plan.inputs)))
    if was != now:
        diff = [k for k in sorted(set(was) | set(now)) if k != "options" and was.get(k) != now.get(k)]
        options = set(was["options"]) | set(now["options"])
        diff += [k for k in sorted(options) if was["options"].get(k) != now["options"].get(k)]
        raise TuneError(f"cannot resume {out_dir}: this command differs in {', '.join(diff)}; "
                        "rerun the original command with --resume, or use a new -o", kind="resume_mismatch")


@contextmanager
def _locked(out_dir: Path) -> Iterator[None]:
    """The run directory's lock for the study's whole life: an flock on
    .pupper.lock, the file pupper's Rust commands lock, so a second tune or
    a sweep there is refused; the OS drops it when this process dies, kill
    -9 included, so a resume after a kill finds it free."""
    import fcntl

    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        f = open(out_dir / LOCK, "a+")
    except OSError as e:
        raise TuneError(f"cannot write the run directory '{out_dir}' ({e.strerror}): choose another -o") from None
    with f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            f.seek(0)
            holder = f.read().strip() or "a process starting up"
            raise TuneError(f"run directory '{out_dir}' is being written by another pupper ({holder}): "
                            "wait for it to end, or choose another -o",
                            kind=cast("ErrorCode", "run_busy")) from None  # (the stub's ErrorCode lacks it)
        f.truncate(0)
        f.write(f"pid {os.getpid()} on {socket.gethostname()}, since unix time {int(time.time())}")
        f.flush()
        # a killed writer's temporary files (we hold the lock: no live writer owns them)
        for p in out_dir.iterdir():
            if p.name != LOCK and _is_ours_to_ignore(p.name):
                p.unlink(missing_ok=True)
        yield


def _discard(out_dir: Path, made: bool) -> None:
    """A fresh study's files, and its directory if this tune made it."""
    for name in (*STUDY_FILES, "report.html"):
        (out_dir / name).unlink(missing_ok=True)
    if made:
        (out_dir / LOCK).unlink(missing_ok=True)
        try:
            out_dir.rmdir()
        except OSError:
            pass  # something else was put there meanwhile: it stays


def _started(optuna: Any, out_dir: Path, plan: _Plan, force: bool) -> Any:
    if force:
        for name in (*STUDY_FILES, "report.html"):
            (out_dir / name).unlink(missing_ok=True)
    # the manifest first: a kill before it leaves no file but the lock, and
    # the same command starts again; a kill at any later moment leaves a
    # study to resume (without a journal yet, from no generation)
    _write_manifest(out_dir, plan, 0, 0, complete=False)
    _test_signal("start", 0, 0)
    (out_dir / JOURNAL).write_bytes(b"")
    _write(out_dir, plan, None, 0, complete=False)
    storage = optuna.storages.RDBStorage(f"sqlite:///{(out_dir / 'study.db').resolve()}")
    return optuna.create_study(study_name=STUDY, storage=storage, directions=plan.directions, load_if_exists=True)


def _resumed(optuna: Any, out_dir: Path, plan: _Plan) -> Any:
    """The study as its journal left it: study.db rebuilt from the
    generations told whole; a generation a kill cut (half asked, half
    told) runs again, its sampler seeing what it saw the first time."""
    records = _read_journal(out_dir)
    if records is None:
        # an earlier pupper's run directory: the journal from its study.db
        records = _records_from_study(optuna, out_dir)
    _rebuild(optuna, out_dir, plan, records)
    # the journal without a torn last line, or made from study.db (a kill
    # before this leaves the old one, from which the next resume rebuilds)
    text = "".join(_journal_line(r) for r in records)
    if not (out_dir / JOURNAL).is_file() or (out_dir / JOURNAL).read_bytes() != text.encode():
        _atomic_write(out_dir / JOURNAL, text)
    storage = optuna.storages.RDBStorage(f"sqlite:///{(out_dir / 'study.db').resolve()}")
    study = optuna.load_study(study_name=STUDY, storage=storage)
    _write(out_dir, plan, study, _spent(study), complete=False)
    return study


# -- the journal: finished generations, what a resume rebuilds ---------------


def _trial_record(t: Any) -> dict[str, Any]:
    """A finished trial as the storage holds it: the samplers' own system
    attributes too (CMA-ES keeps its optimizer there)."""
    return {"number": t.number, "state": t.state.name, "params": t.params, "values": t.values,
            "intermediate_values": {str(k): v for k, v in t.intermediate_values.items()},
            "user_attrs": t.user_attrs, "system_attrs": t.system_attrs}


def _journal_line(record: Mapping[str, Any]) -> str:
    return json.dumps(record, separators=(",", ":")) + "\n"


def _append_journal(out_dir: Path, study: Any, generation: int) -> None:
    """Generation `generation`, told whole, as one line, fsynced: a kill
    before its last byte leaves a torn line, which a resume drops."""
    trials = sorted((t for t in study.get_trials(deepcopy=False) if t.user_attrs.get("generation") == generation),
                    key=lambda t: t.number)
    data = _journal_line({"generation": generation, "trials": [_trial_record(t) for t in trials]}).encode()
    fd = os.open(out_dir / JOURNAL, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        while data:
            data = data[os.write(fd, data):]
        os.fsync(fd)
    finally:
        os.close(fd)


def _read_journal(out_dir: Path) -> list[dict[str, Any]] | None:
    """The journal's generations (None without a journal). A last line
    without its newline is one a kill tore: dropped."""
    try:
        lines = (out_dir / JOURNAL).read_bytes().split(b"\n")
    except FileNotFoundError:
        return None
    records = []
    for k, line in enumerate(lines[:-1]):
        try:
            record = json.loads(line)
            sound = (isinstance(record, dict) and record.get("generation") == k
                     and isinstance(record.get("trials"), list))
        except ValueError:
            sound = False
        if not sound:
            raise TuneError(f"cannot resume {out_dir}: its {JOURNAL} line {k + 1} is damaged: "
                            "start the study anew with --force, or use a new -o")
        records.append(record)
    return records


def _records_from_study(optuna: Any, out_dir: Path) -> list[dict[str, Any]]:
    """The generations of an earlier pupper's study.db told whole (every
    trial complete or pruned), from the first: a half told one and those
    after it run again."""
    path = out_dir / "study.db"
    if not path.is_file():
        return []
    from sqlalchemy.exc import SQLAlchemyError

    try:
        storage = optuna.storages.RDBStorage(f"sqlite:///{path.resolve()}")
        try:
            trials = optuna.load_study(study_name=STUDY, storage=storage).get_trials(deepcopy=False)
        finally:
            storage.engine.dispose()
    except (SQLAlchemyError, KeyError, RuntimeError, ValueError) as e:
        raise TuneError(f"cannot resume {out_dir}: its study.db cannot be read ({type(e).__name__}) and there "
                        f"is no {JOURNAL} to rebuild it from: start the study anew with --force, or use a new -o"
                        ) from None
    by_generation: dict[Any, list[Any]] = {}
    for t in trials:
        by_generation.setdefault(t.user_attrs.get("generation"), []).append(t)
    told = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)
    records: list[dict[str, Any]] = []
    while len(records) in by_generation and all(t.state in told for t in by_generation[len(records)]):
        g = len(records)
        records.append({"generation": g, "trials": [_trial_record(t) for t in
                                                    sorted(by_generation[g], key=lambda t: t.number)]})
    return records


def _rebuild(optuna: Any, out_dir: Path, plan: _Plan, records: Sequence[Mapping[str, Any]]) -> None:
    """study.db anew from the journal's generations, each trial added as it
    was told (its number, parameters, values, attributes, the samplers' own
    ones): the study the next generation's sampler sees is the
    uninterrupted one's. Built in a temporary file moved into place at the
    end: a kill during it leaves the journal, and the next resume starts
    again."""
    dists = {d.axis: d.distribution(optuna) for d in plan.dims}
    states = optuna.trial.TrialState
    fd, tmp = tempfile.mkstemp(dir=out_dir, prefix=".study.db.", suffix=".tmp")
    os.close(fd)

    def unsynced() -> Any:
        # no fsync per added trial (a file replaced whole at the end, fsynced
        # once): a resume of a long study takes a moment, not a minute
        import sqlite3

        con = sqlite3.connect(tmp, check_same_thread=False)
        con.execute("PRAGMA synchronous=OFF")
        return con

    storage = optuna.storages.RDBStorage(f"sqlite:///{Path(tmp).resolve()}", engine_kwargs={"creator": unsynced})
    try:
        study = optuna.create_study(study_name=STUDY, storage=storage, directions=plan.directions)
        n = 0
        for g, record in enumerate(records):
            try:
                if not all(t["state"] in ("COMPLETE", "PRUNED") for t in record["trials"]):
                    raise ValueError("a journal holds finished trials only")
                frozen = [optuna.trial.create_trial(
                    state=states[t["state"]], params=t["params"], distributions=dists, values=t["values"],
                    user_attrs=t["user_attrs"], system_attrs=t["system_attrs"],
                    intermediate_values={int(k): v for k, v in t["intermediate_values"].items()})
                    for t in record["trials"]]
            except (KeyError, TypeError, ValueError, AttributeError):
                raise TuneError(f"cannot resume {out_dir}: its {JOURNAL} line {g + 1} is damaged (or its space "
                                "differs): start the study anew with --force, or use a new -o") from None
            for t in frozen:
                study.add_trial(t)
                n += 1
                _test_signal("rebuild", 0, n)
    except BaseException:
        storage.engine.dispose()
        os.unlink(tmp)
        raise
    storage.engine.dispose()
    with open(tmp, "rb") as f:
        os.fsync(f.fileno())
    # SQLite's rollback journal of the old study.db would be played into the new one
    for side in ("study.db-journal", "study.db-wal", "study.db-shm"):
        (out_dir / side).unlink(missing_ok=True)
    os.replace(tmp, out_dir / "study.db")


# -- the search: a generation asked, run, told, journaled ---------------------


def _finished(study: Any) -> list[Any]:
    import optuna

    told = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)
    return sorted((t for t in study.get_trials(deepcopy=False) if t.state in told),
                  key=lambda t: (t.user_attrs["generation"], t.user_attrs["slot"]))


def _spent(study: Any) -> int:
    return sum(int(t.user_attrs.get("cell_steps", 0)) for t in _finished(study))


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
        import pupper_core as pc

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
            res = pc.sweep(cells, progress=False, **opts)
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


# -- what a study writes ------------------------------------------------------


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
    _atomic_write(out / "trials.csv", buf.getvalue())
    best = _best(study, plan) if study is not None else []
    _atomic_write(out / "best.json", json.dumps(best, indent=2) + "\n")
    if len(objectives) > 1:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["generation", "slot", *[d.axis for d in dims], *objectives])
        for b in best:
            w.writerow([b["generation"], b["slot"], *[b["params"][d.axis] for d in dims],
                        *[repr(float(v)) for v in b["values"]]])
        _atomic_write(out / "pareto.csv", buf.getvalue())
    _write_manifest(out, plan, len(rows), spent, complete)


def _write_manifest(out: Path, plan: _Plan, trials: int, spent: int, complete: bool) -> None:
    import optuna

    import pupper_core as pc

    manifest = {"kind": "tune", "inputs": plan.inputs, "pupper_version": pc.__version__,
                "optuna_version": optuna.__version__, "stop": plan.stop, "trials": trials, "cell_steps": spent,
                "complete": complete, "study": "study.db (optuna-dashboard sqlite:///study.db)"}
    _atomic_write(out / "manifest.json", json.dumps(manifest, indent=2) + "\n")


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


def _cli(args_json: str) -> list[str]:
    """`pupper tune`: the CLI's parsed flags as JSON; prints the best trial(s)."""
    a = json.loads(args_json)
    plot = bool(a.pop("plot", False))
    compare = a.pop("compare", None)
    if a.get("resume") and not a.get("space"):
        a = _resume_args(a)
    res = tune(a.pop("space"), **a)
    for b in res.best:
        params = "  ".join(f"{k} {v:.6g}" if isinstance(v, float) else f"{k} {v}" for k, v in b["params"].items())
        values = "  ".join(f"{o} {v:.6g}" for o, v in zip(b["objectives"], b["values"]))
        print(f"best (generation {b['generation']}, slot {b['slot']}): {params}  ->  {values}")
    if not res.best:
        print(_unranked(res))
    print(f"{len(res.trials)} trials, {res.cell_steps} cell-steps")
    wrote = [str(res.out / "trials.csv")] if res.out else []
    if plot and res.out:
        wrote += [str(p) for p in write_plots(res.out, compare)]
        from pupper_core import _report

        _report.report(res.out)  # again, now with the plots beside it
    if res.out:
        wrote.append(str(res.out / "report.html"))
    # the embedding pupper binary exits without finalizing Python: a pipe's
    # buffered lines must leave now
    sys.stdout.flush()
    return wrote


def _study_table(out: Path) -> tuple[dict[str, Any], list[dict[str, str]]]:
    manifest = json.loads((out / "manifest.json").read_text())
    with (out / "trials.csv").open(newline="") as f:
        return manifest["inputs"], list(csv.DictReader(f))


def _grid_table(grid: str | os.PathLike[str], objective: str, maximize: bool) -> tuple[list[dict[str, str]], Any]:
    """A grid run's rows and their objective, ineligible cells (not ok)
    as NaN: what a search is compared with."""
    import numpy as np

    with (Path(grid) / "summary.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows or objective not in rows[0]:
        raise TuneError(f"--compare {grid}: its summary.csv has no column {objective}: give a sweep of the same question")
    v = np.array([float(r[objective]) if r[objective] and r.get("status", "ok") == "ok" else np.nan for r in rows])
    return rows, v


def progress_figure(out: str | os.PathLike[str], grid: str | os.PathLike[str] | None = None) -> Any:
    """The best objective so far against the cell-steps spent, each trial a
    dot (those told the penalty — fallen, chattering — as red crosses at
    the top); with ``grid`` (a sweep's
    run directory of the same question) the grid's own best-so-far curve,
    its cells taken in grid order. A matplotlib Figure."""
    import numpy as np

    from pupper_core import plots

    inputs, rows = _study_table(Path(out))
    objective, maximize = inputs["objectives"][0], bool(inputs["maximize"])
    values = np.array([float(r[objective]) for r in rows])
    bad = values <= -PENALTY if maximize else values >= PENALTY
    spent = np.cumsum([int(r["cell_steps"]) for r in rows])
    good = np.where(bad, np.nan, values)
    worst = -np.inf if maximize else np.inf
    best = (np.fmax if maximize else np.fmin).accumulate(np.where(np.isnan(good), worst, good))
    with plots._style():
        fig = plots._new_figure((7.5, 4.4))
        ax = fig.subplots()
        ax.plot(spent[~bad], values[~bad], "o", ms=4, alpha=0.5, color="#4e79a7", label="a trial")
        if bad.any():
            top = float(np.nanmax(good)) if np.isfinite(good).any() else 1.0
            ax.plot(spent[bad], np.full(int(bad.sum()), top), "x", color="red", ms=6, label="fell, chattered or no value")
        ax.step(spent, best, where="post", color="black", lw=1.6, label="best so far")
        if grid is not None:
            grows, gv = _grid_table(grid, objective, maximize)
            per = json.loads((Path(grid) / "manifest.json").read_text())["config"]["schedule"]["duration"]
            steps = round(float(per) / 0.002)
            gbest = (np.fmax if maximize else np.fmin).accumulate(np.where(np.isnan(gv), worst, gv))
            ax.step(steps * np.arange(1, len(gv) + 1), gbest, where="post", color="tab:orange", lw=1.4,
                    label=f"grid's best so far ({len(gv)} cells)")
            ax.set_xscale("log")
        if np.all(values[~bad] > 0):
            ax.set_yscale("log")
        ax.set_xlabel("cell-steps spent")
        ax.set_ylabel(plots.label_of(objective))
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=9)
        fig.suptitle(f"{inputs['sampler']} search, batch {inputs['batch']}: {len(rows)} trials", fontsize=12)
        return fig


def trials_figure(out: str | os.PathLike[str], grid: str | os.PathLike[str] | None = None) -> Any:
    """The trials over the two searched axes, coloured by the objective, the
    best starred; with ``grid`` (a sweep over the same two axes) over that
    grid's heatmap. None unless exactly two numeric axes were searched."""
    import numpy as np

    from pupper_core import plots

    inputs, rows = _study_table(Path(out))
    dims = parse_space(inputs["space"])
    if len(dims) != 2 or any(d.choices for d in dims):
        return None
    objective, maximize = inputs["objectives"][0], bool(inputs["maximize"])
    values = np.array([float(r[objective]) for r in rows])
    bad = values <= -PENALTY if maximize else values >= PENALTY
    x, y = dims
    xs = np.array([float(r[x.axis]) for r in rows])
    ys = np.array([float(r[y.axis]) for r in rows])
    with plots._style():
        fig = plots._new_figure((6.5, 5.0))
        ax = fig.subplots()
        from matplotlib.colors import LogNorm, Normalize

        shown = values[~bad]
        # no trial ranked: the crosses alone, on a unit colour scale
        lo, hi = (float(np.min(shown)), float(np.max(shown))) if shown.size else (1.0, 2.0)
        if grid is not None:
            grows, gv = _grid_table(grid, objective, maximize)
            gx = sorted({float(r[x.axis]) for r in grows})
            gy = sorted({float(r[y.axis]) for r in grows})
            z = np.full((len(gy), len(gx)), np.nan)
            for r, v in zip(grows, gv):
                z[gy.index(float(r[y.axis])), gx.index(float(r[x.axis]))] = v
            lo, hi = min(lo, float(np.nanmin(gv))), max(hi, float(np.nanmax(gv)))
        norm = LogNorm(lo, hi) if lo > 0 else Normalize(lo, hi)
        cmap = "viridis" if maximize else "viridis_r"
        if grid is not None:
            ax.pcolormesh(gx, gy, z, cmap=cmap, norm=norm, shading="nearest", alpha=0.55)
        sc = ax.scatter(xs[~bad], ys[~bad], c=shown, cmap=cmap, norm=norm, s=28, edgecolors="white",
                        linewidths=0.5)
        if bad.any():
            ax.plot(xs[bad], ys[bad], "x", color="red", ms=6, label="fell, chattered or no value")
        if shown.size:
            good = np.where(bad, np.nan, values)
            k = int(np.nanargmax(good) if maximize else np.nanargmin(good))
            ax.plot([xs[k]], [ys[k]], "*", color="black", ms=16, mfc="none", mew=1.5, label="best")
        ax.set_xscale("log" if x.log else "linear")
        ax.set_yscale("log" if y.log else "linear")
        ax.set_xlabel(plots.label_of(x.axis))
        ax.set_ylabel(plots.label_of(y.axis))
        fig.colorbar(sc, ax=ax).set_label(plots.label_of(objective))
        ax.legend(loc="best", fontsize=9)
        fig.suptitle("The trials over the searched plane", fontsize=12)
        return fig


def write_plots(out: str | os.PathLike[str], grid: str | os.PathLike[str] | None = None) -> list[Path]:
    """A study's figures into ``<out>/plots/``: ``tune_progress.png`` and,
    for two searched axes, ``tune_trials.png``; with ``grid`` (a sweep of
    the same question) beside that grid's curve and over its heatmap."""
    from pupper_core import plots

    d = Path(out)
    (d / "plots").mkdir(exist_ok=True)
    written = [plots._save(progress_figure(d, grid), d / "plots" / "tune_progress.png")]
    fig = trials_figure(d, grid)
    if fig is not None:
        written.append(plots._save(fig, d / "plots" / "tune_trials.png"))
    return written


def lab_tune(
    variants: Sequence[str] = VARIANTS,
    *,
    space: Sequence[str] = ("kp=10:120:log", "kd=0.5:5:log"),
    objective: str = "last_1s_std_mm",
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
        _atomic_write(root / "best.csv", buf.getvalue())
    return results


def _lab_cli(args_json: str) -> list[str]:
    """`pupper lab --tune`: the CLI's parsed flags as JSON; a line per body."""
    a = json.loads(args_json)
    res = lab_tune(a.pop("variants"), **a)
    for body, r in res.items():
        b = r.best[0] if r.best else None
        if b is None:
            print(f"{body:<10} no trial stood")
            continue
        params = "  ".join(f"{k} {v:.4g}" for k, v in b["params"].items())
        print(f"{body:<10} {params}  ->  {r.objectives[0]} {b['values'][0]:.6g}  "
              f"({len(r.trials)} trials, {r.cell_steps} cell-steps)")
    sys.stdout.flush()  # see _cli
    return [str(Path(a["out"]) / "best.csv")] if a.get("out") else []
