"""A tune's inputs (``pupper_core._tune`` runs the study): the searched
space, the objectives, the sampler of each generation, the stopping rule,
every one checked (by the Rust grid's own checks where they are an axis's)
before anything is written."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from pupper_core import _native
from pupper_core._run import info
from pupper_core._native import ConfigError, GridError, PupperError
from pupper_core._types import exported_from

if TYPE_CHECKING:
    from pupper_core._native import ErrorCode

#: The value a trial whose robot fell or diverged (or has no value) is told:
#: worse than any real one, finite so every sampler takes it.
PENALTY = 1e6
STUDY = "pupper-tune"
SAMPLERS = ("tpe", "cmaes", "gp", "random")
AGGREGATES = ("mean", "p95", "worst", "fail-rate")
#: The named bodies of the variant axis, in pupper's order (its values are indices).
VARIANTS: tuple[str, ...] = tuple(_native.VARIANTS)


@exported_from("pupper_core._tune")
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


def _num(x: float) -> str:
    # as written (5:200) where that is exact, else every digit: a resume
    # alone reads the space back from this text
    short = f"{x:g}"
    return short if float(short) == x else repr(float(x))


#: How close to an end of a searched range (a share of its span) a best
#: value is said to lie on its edge.
EDGE = 0.05


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

    def edge(self, value: Any, fraction: float = EDGE) -> str | None:
        """"the largest" or "the smallest" when ``value`` lies within
        ``fraction`` of this range's span (on a log axis, of its log span)
        from an end: the best may lie beyond what was searched. None inside,
        and for choices."""
        if self.choices or not isinstance(value, (int, float)) or self.high <= self.low:
            return None
        f = math.log if self.log else float
        lo, hi, v = f(self.low), f(self.high), f(value)
        span = hi - lo
        if v >= hi - fraction * span:
            return "the largest"
        if v <= lo + fraction * span:
            return "the smallest"
        return None

    def text(self) -> str:
        if self.choices:
            return f"{self.axis}=" + "|".join(str(c) for c in self.choices)
        kind = ":int" if self.integer else (":log" if self.log else "")
        return f"{self.axis}={_num(self.low)}:{_num(self.high)}{kind}"


@exported_from("pupper_core._tune")
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
    from pupper_core import _native
    from pupper_core._spec import sweep_options

    given = sweep_options(options)
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
            _native.sweep({d.axis: values}, **{**given, "max_cells": 0})
        except GridError as e:
            if "over the limit of 0" not in str(e):
                raise TuneError(f"--space {d.text()}: {str(e).removesuffix('; fix the value list')}") from None
        except PupperError as e:
            raise TuneError(str(e)) from None


def _plan(space: Sequence[str] | Mapping[str, Any], objective: str | Sequence[str], maximize: bool,
          trials: int | None, budget: int | None, batch: int, sampler: str, seed: int, aggregate: str,
          halving: int, options: dict[str, Any]) -> _Plan:
    """Every input checked, before anything is written."""
    from pupper_core import _native
    from pupper_core._spec import METRICS

    optuna = _optuna()
    dims = parse_space(space)
    objectives = _objectives(objective)
    _check_counts(trials, budget, batch, sampler, aggregate, halving)
    try:
        _native.check_axes([d.axis for d in dims])
    except GridError as e:
        raise TuneError(f"--space: {e}") from None
    known = set(METRICS) - {"status"}
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
        model_dt = float(info(options.get("model", "pupper_v3"))["timestep"])
    except PupperError as e:
        raise TuneError(str(e)) from None
    plan = _Plan(dims, objectives, maximize, trials, budget, batch, sampler, seed, aggregate, halving, options,
                 model_dt)
    if budget is not None and budget < batch * plan.cell_steps():
        raise TuneError(f"--budget {budget} is below one generation ({batch} trials x "
                        f"{plan.cell_steps()} cell-steps): raise it or lower --batch")
    return plan
