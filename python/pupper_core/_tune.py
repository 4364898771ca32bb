"""`pupper tune` (`pupper_core.tune`): the grid's answer with less simulation, by Optuna's
ask/tell interface. Each generation asks ``batch`` trials, runs them as one
batch of cells through pupper's runner, and tells the results.

The study lives in the run directory: Optuna's SQLite storage
(``study.db``; ``optuna-dashboard sqlite:///DIR/study.db`` shows it),
``trials.csv`` (a row per finished trial, in the order they were asked),
``best.json``, ``pareto.csv`` for several objectives, and
``manifest.json`` (the inputs and the cell-steps spent).

Determinism: the sampler of generation ``g`` is seeded from ``(seed, g)``
and sees only the finished trials, so the same inputs give the same trials
in the same order at any thread count and after a resume (``--resume``
re-runs the trials a kill left unfinished, with the parameters they were
asked with).
"""

from __future__ import annotations

import csv
import json
import math
import os
import sys
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["tune", "TuneResult", "parse_space"]

#: The value a trial whose robot fell or diverged (or has no value) is told:
#: worse than any real one, finite so every sampler takes it.
PENALTY = 1e6
STUDY = "pupper-tune"
SAMPLERS = ("tpe", "cmaes", "gp", "random")
AGGREGATES = ("mean", "p95", "worst", "fail-rate")
#: The named bodies of the variant axis, in pupper's order (its values are indices).
VARIANTS = ("original", "long-leg", "heavy")


class TuneError(ValueError):
    """Bad input to `tune`: one line naming the problem and the fix."""


def _optuna() -> Any:
    try:
        import optuna
    except ImportError:
        raise TuneError("pupper tune needs Optuna: install the extra with "
                        "`make setup PUPPER_EXTRAS=tune` (or pip install 'pupper_core[tune]')") from None
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna


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
        return f"{self.axis}={self.low:g}:{self.high:g}{kind}"


def parse_space(specs: Sequence[str] | Mapping[str, Any]) -> list[Dimension]:
    """``AXIS=LOW:HIGH[:log|:int]`` or ``AXIS=A|B|C`` (choices), or a dict
    ``{axis: (low, high[, "log"|"int"]) or [choices]}``."""
    items: list[tuple[str, Any]]
    if isinstance(specs, Mapping):
        items = list(specs.items())
    else:
        items = []
        for s in [specs] if isinstance(specs, str) else specs:
            if "=" not in s:
                raise TuneError(f"--space '{s}' has no '=': write AXIS=LOW:HIGH[:log], e.g. kp=5:200:log")
            name, rest = s.split("=", 1)
            items.append((name.strip(), rest.strip()))
    if not items:
        raise TuneError("no --space given: name what to search, e.g. --space kp=5:200:log --space kd=0.05:10:log")
    out: list[Dimension] = []
    for name, v in items:
        if any(d.axis == name for d in out):
            raise TuneError(f"--space {name} is given twice: give each axis once")
        if isinstance(v, str) and "|" in v:
            out.append(Dimension(name, choices=tuple(_choice(c) for c in v.split("|"))))
            continue
        if isinstance(v, (list,)) and v and not isinstance(v[0], (int, float)) or (
                isinstance(v, list) and len(v) > 3):
            out.append(Dimension(name, choices=tuple(v)))
            continue
        parts = v.split(":") if isinstance(v, str) else list(v)
        kind = str(parts[2]) if len(parts) == 3 else ""
        try:
            low, high = float(parts[0]), float(parts[1])
        except (ValueError, IndexError):
            raise TuneError(f"--space {name}={v}: write LOW:HIGH[:log|:int], e.g. {name}=5:200:log") from None
        if not (math.isfinite(low) and math.isfinite(high) and low < high) or kind not in ("", "log", "int"):
            raise TuneError(f"--space {name}={v}: give LOW < HIGH, finite, and :log or :int at most")
        if kind == "log" and low <= 0:
            raise TuneError(f"--space {name}={v}: a log range needs LOW > 0")
        out.append(Dimension(name, low, high, log=kind == "log", integer=kind == "int"))
    return out


def _choice(text: str) -> Any:
    try:
        return float(text)
    except ValueError:
        return text.strip()


@dataclass
class TuneResult:
    """What a tune leaves: the Optuna study, the finished trials (as
    trials.csv has them), the best trial(s), and the run directory."""

    study: Any
    trials: list[dict[str, Any]]
    best: list[dict[str, Any]]
    out: Path | None
    cell_steps: int
    objectives: list[str] = field(default_factory=list)

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
            import cmaes  # noqa: F401
        except ImportError:
            raise TuneError("--sampler cmaes needs the cmaes package: `make setup PUPPER_EXTRAS=tune`") from None
        return optuna.samplers.CmaEsSampler(seed=s, popsize=batch, warn_independent_sampling=False)
    if name == "gp":
        try:
            import torch  # noqa: F401
        except ImportError:
            raise TuneError("--sampler gp needs torch (Optuna's GP sampler runs on it), which the tune extra "
                            "leaves out: pip install torch, or use tpe, cmaes or random") from None
        return optuna.samplers.GPSampler(seed=s)
    raise TuneError(f"--sampler {name} is unknown: use one of {', '.join(SAMPLERS)}")


#: Options that change how a study runs, never its numbers: a resume may
#: change them.
RUN_ONLY = ("threads", "chunk_cells", "ray")


def _compared(inputs: Mapping[str, Any]) -> dict[str, Any]:
    """The inputs a resume must repeat: all but the run-only options."""
    out = dict(inputs)
    out["options"] = {k: v for k, v in dict(inputs.get("options", {})).items() if k not in RUN_ONLY}
    return out


def _inputs(space: list[Dimension], objectives: list[str], maximize: bool, batch: int, sampler: str,
            seed: int, aggregate: str, options: Mapping[str, Any]) -> dict[str, Any]:
    return {"space": [d.text() for d in space], "objectives": objectives, "maximize": maximize, "batch": batch,
            "sampler": sampler, "seed": seed, "aggregate": aggregate, "options": dict(options)}


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
    sweep's ranking never picks) is told a penalty (1e6, the worst) and
    keeps its status. With replicates the value is ``aggregate`` over them: mean,
    p95 (the worse side), worst, or fail-rate. ``halving`` (an integer
    eta >= 2, with replicates): successive halving over the replicates —
    each generation runs every trial on replicates // eta robots first, and
    only the best 1/eta of them (by that value) on all (a replicate is drawn
    from its index, so the first rung's robots run again with the rest:
    a generation costs 2/eta of its full cost); the others are told pruned
    with their first value. Other keywords are
    `pupper_core.sweep`'s (model, mode, seconds, push, replicates, ...).
    """
    import pupper_core as pc

    optuna = _optuna()
    dims = parse_space(space)
    objectives = [objective] if isinstance(objective, str) else list(objective)
    objectives = [o.strip() for obj in objectives for o in obj.split(",") if o.strip()]
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
    from pupper_core import _native

    try:
        _native.check_axes([d.axis for d in dims])
    except pc.GridError as e:
        raise TuneError(f"--space: {e}") from None
    known = set(pc.METRICS) - {"status"}
    for o in objectives:
        if o not in known:
            raise TuneError(f"--objective {o} is not a metric: use one of {', '.join(sorted(known))}")
    options = dict(options)
    reps = int(options.get("replicates", 1))
    if halving:
        if halving < 2:
            raise TuneError(f"--halving {halving}: give an eta of 2 or more (the share promoted is 1/eta)")
        if reps < halving:
            raise TuneError(f"--halving {halving} halves over the replicates: give --replicates {halving} or more")
        if len(objectives) > 1:
            raise TuneError("--halving takes one objective: drop the others, or --halving")
    # a fallen robot stops stepping: its cell-steps are saved for trials
    options.setdefault("stop_fallen", True)
    if int(options.get("replicates", 1)) > 1:
        options.setdefault("seed", seed)
    inputs = _inputs(dims, objectives, maximize, batch, sampler, seed, aggregate, options)
    if halving:
        inputs["halving"] = halving
    say: Callable[[str], None]
    if callable(progress):
        say = progress
    elif progress:
        say = lambda line: print(line, file=sys.stderr, flush=True)  # noqa: E731
    else:
        say = lambda line: None  # noqa: E731
    # the model's timestep, for the cell-steps spent (and an early check of the model)
    try:
        model_dt = float(pc.info(options.get("model", "pupper_v3"))["timestep"])
    except pc.PupperError as e:
        raise TuneError(str(e)) from None
    if budget is not None and budget < batch * _steps_per_cell(options, {}, model_dt):
        raise TuneError(f"--budget {budget} is below one generation ({batch} trials x "
                        f"{_steps_per_cell(options, {}, model_dt)} cell-steps): raise it or lower --batch")
    out_dir = Path(out) if out is not None else None
    storage: Any = None
    if out_dir is not None:
        manifest_path = out_dir / "manifest.json"
        if resume:
            if not manifest_path.exists():
                raise TuneError(f"--resume {out_dir}: no tune there (no manifest.json); start it without --resume")
            old = json.loads(manifest_path.read_text())
            was, now = _compared(old.get("inputs", {})), _compared(json.loads(json.dumps(inputs)))
            if was != now:
                diff = [k for k in sorted(set(was) | set(now)) if k != "options" and was.get(k) != now.get(k)]
                options = set(was["options"]) | set(now["options"])
                diff += [k for k in sorted(options) if was["options"].get(k) != now["options"].get(k)]
                raise TuneError(f"cannot resume {out_dir}: this command differs in {', '.join(diff)}; "
                                "rerun the original command with --resume, or use a new -o")
        elif out_dir.exists() and any(out_dir.iterdir()):
            if not force:
                raise TuneError(f"output directory '{out_dir}' already exists: choose another -o, "
                                "add --force to overwrite it, or --resume it")
            for name in ("study.db", "trials.csv", "best.json", "pareto.csv", "manifest.json"):
                (out_dir / name).unlink(missing_ok=True)
        out_dir.mkdir(parents=True, exist_ok=True)
        storage = optuna.storages.RDBStorage(f"sqlite:///{(out_dir / 'study.db').resolve()}")
    directions = ["maximize" if maximize else "minimize"] * len(objectives)
    study = optuna.create_study(study_name=STUDY, storage=storage, directions=directions, load_if_exists=True)
    dists = {d.axis: d.distribution(optuna) for d in dims}
    TS = optuna.trial.TrialState

    # A kill left trials running. They are told failed (no sampler learns
    # from a failed trial). If their generation had begun to be told, its
    # other trials were all asked: they are enqueued with their parameters.
    # Otherwise the generation is asked afresh: its seeded sampler, seeing
    # the same finished trials, proposes the same parameters again.
    unfinished = [t for t in study.get_trials(deepcopy=False) if t.state == TS.RUNNING]
    told = {t.user_attrs.get("generation")
            for t in study.get_trials(deepcopy=False, states=(TS.COMPLETE, TS.PRUNED))}
    for t in sorted(unfinished, key=lambda t: t.user_attrs.get("slot", 0)):
        study.tell(t.number, state=TS.FAIL)
        g = t.user_attrs.get("generation")
        if g is not None and g in told:
            # with its rung: the generation's promotion was decided before any tell
            keep = {k: t.user_attrs[k] for k in ("generation", "slot", "rung") if k in t.user_attrs}
            study.enqueue_trial(t.params, user_attrs=keep)

    def finished() -> list[Any]:
        return sorted((t for t in study.get_trials(deepcopy=False) if t.state in (TS.COMPLETE, TS.PRUNED)),
                      key=lambda t: (t.user_attrs["generation"], t.user_attrs["slot"]))

    said: set[str] = set()
    if out_dir is not None:
        # the manifest first: a kill at any moment leaves a study to resume
        _write(out_dir, study, finished(), dims, objectives, inputs,
               sum(int(t.user_attrs.get("cell_steps", 0)) for t in finished()), complete=False,
               stop={"trials": trials, "budget": budget})
    done = finished()
    spent = sum(int(t.user_attrs.get("cell_steps", 0)) for t in done)
    generation = max((t.user_attrs["generation"] + 1 for t in done), default=0)
    pending = study.get_trials(deepcopy=False, states=(TS.WAITING,))
    if pending:
        generation = pending[0].user_attrs.get("generation", generation)
    while True:
        n_done = len(finished())
        if trials is not None and n_done >= trials:
            break
        if budget is not None and spent >= budget:
            break
        want = batch if trials is None else min(batch, trials - n_done)
        if budget is not None:
            # never past the budget: the last generation may be smaller
            want = min(want, (budget - spent) // _steps_per_cell(options, {}, model_dt))
        waiting = study.get_trials(deepcopy=False, states=(TS.WAITING,))
        if waiting:
            want = len(waiting)
        if want <= 0:
            break
        study.sampler = _sampler(optuna, sampler, seed, generation, batch, len(objectives) > 1)
        asked = []
        for slot in range(want):
            t = study.ask(dists)
            if "generation" not in t.user_attrs:
                t.set_user_attr("generation", generation)
                t.set_user_attr("slot", slot)
            asked.append(t)
        asked.sort(key=lambda t: t.user_attrs["slot"])
        import warnings

        def evaluate(group: list[Any], opts: Mapping[str, Any]) -> list[tuple[list[float], list[str], int]]:
            """Runs trials as one batch of cells: their values, statuses, cell-steps."""
            if not group:
                return []
            cells = []
            for t in group:
                cell: dict[str, float | str] = {"name": f"g{t.user_attrs['generation']}s{t.user_attrs['slot']}"}
                for d in dims:
                    v = t.params[d.axis]
                    cell[d.axis] = float(VARIANTS.index(v)) if d.axis == "variant" else float(v)
                cells.append(cell)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                res = pc.sweep(cells, progress=False, **opts)
            for w in caught:  # each note once per study, not once per generation
                text = str(w.message)
                if text not in said:
                    said.add(text)
                    say(f"note: {text}")
            out = []
            for i, t in enumerate(group):
                got = [_value(res, i, o, aggregate, maximize) for o in objectives]
                ran = res.cell_steps[i]
                steps = int(ran) if ran is not None else _steps_per_cell(opts, t.params, model_dt)
                out.append(([v for v, _ in got], [st for _, st in got], steps))
            return out

        def status_of(statuses: list[str]) -> str:
            return statuses[0] if len(set(statuses)) == 1 else ",".join(statuses)

        if not halving:
            for t, (vals, statuses, steps) in zip(asked, evaluate(asked, options)):
                spent += steps
                t.set_user_attr("cell_steps", steps)
                t.set_user_attr("status", status_of(statuses))
                study.tell(t, vals if len(vals) > 1 else vals[0])
        else:
            # rung 0: every trial on replicates // eta robots
            r0 = max(1, reps // halving)
            first = evaluate(asked, {**options, "replicates": r0})
            if any("rung" not in t.user_attrs for t in asked):
                sign = -1.0 if maximize else 1.0
                order = sorted(range(len(asked)),
                               key=lambda i: (sign * first[i][0][0], asked[i].user_attrs["slot"]))
                up = set(order[:math.ceil(len(asked) / halving)])
                for i, t in enumerate(asked):
                    t.set_user_attr("rung", 1 if i in up else 0)
            promoted = [t for t in asked if t.user_attrs["rung"] == 1]
            second = dict(zip((t.number for t in promoted), evaluate(promoted, options)))
            for t, (vals, statuses, steps) in zip(asked, first):
                t.report(vals[0], step=r0)
                if t.number in second:
                    vals, statuses, more = second[t.number]
                    steps += more
                spent += steps
                t.set_user_attr("cell_steps", steps)
                if t.number in second:
                    t.set_user_attr("status", status_of(statuses))
                    study.tell(t, vals[0])
                else:
                    t.set_user_attr("status", "pruned")
                    study.tell(t, state=TS.PRUNED)
        generation += 1
        done = finished()
        if out_dir is not None:
            _write(out_dir, study, done, dims, objectives, inputs, spent, complete=False,
                   stop={"trials": trials, "budget": budget})
        best = _best(study, objectives)
        say(f"generation {generation}: {len(done)} trials, {spent} cell-steps; best "
            + ", ".join(f"{o} {v:.6g}" for o, v in zip(objectives, best[0]["values"])) if best else "")
    done = finished()
    if out_dir is not None:
        _write(out_dir, study, done, dims, objectives, inputs, spent, complete=True,
               stop={"trials": trials, "budget": budget})
        from pupper_core import _report

        _report.report(out_dir)
    return TuneResult(study=study, trials=_rows(done, dims, objectives), best=_best(study, objectives),
                      out=out_dir, cell_steps=spent, objectives=objectives)


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


def _best(study: Any, objectives: Sequence[str]) -> list[dict[str, Any]]:
    try:
        best = study.best_trials
    except ValueError:
        return []
    out = []
    for t in sorted(best, key=lambda t: (t.user_attrs["generation"], t.user_attrs["slot"])):
        out.append({"generation": t.user_attrs["generation"], "slot": t.user_attrs["slot"],
                    "params": dict(t.params), "values": list(t.values), "objectives": list(objectives),
                    "status": t.user_attrs.get("status", "")})
    return out


def _write(out: Path, study: Any, done: Sequence[Any], dims: Sequence[Dimension], objectives: Sequence[str],
           inputs: Mapping[str, Any], spent: int, complete: bool, stop: Mapping[str, Any]) -> None:
    import io

    import pupper_core as pc
    import optuna

    rows = _rows(done, dims, objectives)
    buf = io.StringIO()
    header = ["trial", "generation", "slot", *[d.axis for d in dims], *objectives, "status", "rung", "cell_steps"]
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for r in rows:
        w.writerow([repr(r[h]) if isinstance(r[h], float) else r[h] for h in header])
    _atomic_write(out / "trials.csv", buf.getvalue())
    best = _best(study, objectives)
    _atomic_write(out / "best.json", json.dumps(best, indent=2) + "\n")
    if len(objectives) > 1:
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["generation", "slot", *[d.axis for d in dims], *objectives])
        for b in best:
            w.writerow([b["generation"], b["slot"], *[b["params"][d.axis] for d in dims],
                        *[repr(float(v)) for v in b["values"]]])
        _atomic_write(out / "pareto.csv", buf.getvalue())
    manifest = {"kind": "tune", "inputs": inputs, "pupper_version": pc.__version__,
                "optuna_version": optuna.__version__, "stop": dict(stop), "trials": len(rows), "cell_steps": spent,
                "complete": complete, "study": "study.db (optuna-dashboard sqlite:///study.db)"}
    _atomic_write(out / "manifest.json", json.dumps(manifest, indent=2) + "\n")


def _cli(args_json: str) -> list[str]:
    """`pupper tune`: the CLI's parsed flags as JSON; prints the best trial(s)."""
    a = json.loads(args_json)
    plot = bool(a.pop("plot", False))
    compare = a.pop("compare", None)
    if a.get("resume") and not a.get("space"):
        # `--resume DIR` alone: the study's own inputs
        path = Path(a["out"]) / "manifest.json"
        if not path.exists():
            raise TuneError(f"--resume {a['out']}: no tune there (no manifest.json); start it without --resume")
        manifest = json.loads(path.read_text())
        inputs = manifest["inputs"]
        kept = {k: a[k] for k in ("out", "resume", "progress", "trials", "budget", *RUN_ONLY)
                if a.get(k) is not None}
        # what decides numbers comes from the study; a flag that says otherwise is refused
        for k in ("backend", "device"):
            if a.get(k) is not None and a[k] != inputs["options"].get(k):
                raise TuneError(f"cannot resume {a['out']}: it ran with {k} {inputs['options'].get(k) or 'cpu'}, "
                                f"not {a[k]}; drop --{k}, or use a new -o")
        if "trials" not in kept and "budget" not in kept:
            kept.update({k: v for k, v in manifest.get("stop", {}).items() if v is not None})
        a = {**inputs.pop("options"), **{k: v for k, v in inputs.items() if k != "objectives"},
             "objective": inputs["objectives"], **kept}
        a["space"] = inputs["space"]
    res = tune(a.pop("space"), **a)
    for b in res.best:
        params = "  ".join(f"{k} {v:.6g}" if isinstance(v, float) else f"{k} {v}" for k, v in b["params"].items())
        values = "  ".join(f"{o} {v:.6g}" for o, v in zip(b["objectives"], b["values"]))
        print(f"best (generation {b['generation']}, slot {b['slot']}): {params}  ->  {values}")
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
        lo, hi = float(np.min(shown)), float(np.max(shown))
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
