"""`pupper recommend` (`pupper_core.recommend`): gains per joint group a
robot owner can put on the robot. Every candidate must hold on every robot
drawn from what the model does not know (none falls, none saturates past
the limit, each group's loop keeps its phase and gain margins as the
firmware closes it); among those, the lowest worst-side push dip wins.

The inputs are in ``_recommend_plan``, the search in ``_recommend_search``,
the card and the files in ``_recommend_card``; this module runs it and is
the CLI's entry.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pupper_core._files import printing
from pupper_core._recommend_card import Card, card_of, in_use, print_card, write_outputs, write_trials
from pupper_core._recommend_plan import Plan, RecommendError, plan as make_plan
from pupper_core._recommend_search import Candidate, best_of, robot_model_files, search, windows
from pupper_core._recommend_search import polish as polish_pick
from pupper_core._signals import _stop_on_signals
from pupper_core._tune import _sayer

__all__ = ["recommend", "Recommendation", "RecommendError"]


@dataclass
class Recommendation:
    """What `recommend` found: the pick (None when no candidate held every
    constraint), its card per group, every candidate, the run directory."""

    pick: Candidate | None
    cards: list[Card]
    candidates: list[Candidate]
    plan: Plan
    out: Path | None
    yaml: str = ""
    mjcf: str = ""
    neighbours: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: the pick as the search measured it (on the model it read; the card's
    #: numbers are the exported MJCF's)
    searched: Candidate | None = None
    #: the gains the robot runs today (`Plan.current`) on the same robots
    current: Candidate | None = None
    #: the groups whose loop margins hold nowhere in their searched ranges
    #: (then no candidate is asked at all)
    no_window: list[str] = field(default_factory=list)

    @property
    def gains(self) -> dict[str, tuple[float, float]]:
        """The recommended (kp, kd) per joint group; empty without a pick."""
        return dict(self.pick.gains) if self.pick else {}

    def to_pandas(self) -> Any:
        """Every candidate as a pandas DataFrame (trials.csv's columns)."""
        try:
            import pandas as pd
        except ImportError as e:
            raise ImportError("Recommendation.to_pandas needs pandas: pip install pandas") from e
        return pd.DataFrame([c.row(self.plan.groups) for c in self.candidates])

    def __repr__(self) -> str:
        if not self.pick:
            return f"Recommendation(no pick over {len(self.candidates)} candidates)"
        g = ", ".join(f"{k} kp {p:.4g} kd {d:.4g}" for k, (p, d) in self.pick.gains.items())
        return f"Recommendation({g}; p95 push dip {self.pick.p95_dip_mm:.4g} mm on {self.plan.robots} robots)"


def recommend(
    model: str | os.PathLike[str] = "pupper_v3",
    *,
    # the search
    robots: int = 32, trials: int = 48, batch: int = 16, seed: int = 0, polish: int = 4,
    # the robots, their firmware and their push
    seconds: float = 4.0, push_force: float | None = None, motor: str | None = None,
    sensing_delay: float | None = None,
    command_delay: float = 0.0, spread: Sequence[str] | None = None, from_fit: str | os.PathLike[str] | None = None,
    # the constraints and the motors' limits
    min_phase_margin: float = 30.0, min_gain_margin: float = 6.0, max_saturation: float = 0.05, max_sag: float = 0.1,
    kp_max: float | None = None, kd_max: float | None = None, current: Sequence[float] | str | None = None,
    robot_config: str | os.PathLike[str] | None = None,
    # the exports and the run directory
    joint_order: Sequence[str] | str | None = None, controller: str = "neural_controller",
    out: str | os.PathLike[str] | None = None, force: bool = False, progress: bool | Callable[[str], None] = True,
) -> Recommendation:
    """Gains per joint group (kp, kd) to put on the robot: the lowest
    worst-side (95th percentile) push dip among candidates that hold on
    every one of ``robots`` robots drawn from what the model does not know.

    Constraints, each checked on every robot: none falls, diverges or lies
    past the stability bound; none saturates its torque limit on more than
    ``max_saturation`` of its steps; none ends lower than ``max_sag`` of its
    stance height (the base height with the lowest foot on the floor in the
    start pose) below it, so a crouch that barely dips is no answer; and
    each group's loop, as the firmware
    ``motor`` (default ``rate=500,counts=16384``) closes it with
    ``sensing_delay`` s old measurements (default 0.002, or with
    ``from_fit`` the upper end of a fitted feedback ``latency``; the card
    says which; drawn 0 to it in whole steps on
    the robots), keeps ``min_phase_margin`` degrees and ``min_gain_margin``
    dB at the spread's worst corner (what the motors deliver of the gains,
    the joints' least and most inertia). A ``command_delay`` (s) is not in
    that loop: it shifts the predicted step response instead.

    ``spread``: ``--randomize`` specs of what differs between robots
    (default ``DEFAULT_SPREAD``: torso ±15 %, legs ±10 %, motor gains
    ±10 %, floor friction 0.6-1.2, 1 mrad encoder noise); ``from_fit``: a
    `pupper fit` run directory whose calibrated model is the robot and whose
    intervals are the spread (8 joint models drawn inside them, the gain
    scales and the fitted delay drawn per robot). The search's best then
    moves to a better neighbour (a group's kp or kd ×/÷ 1.25, or its kp
    with kd along its margin window) up to ``polish`` times. The search
    starts from each group as stiff as its margins allow. It spans each
    group's own gains /10 to x20 (x50 for kd), capped by the model's
    ``pupper:kp_max:ACT``/``pupper:kd_max:ACT`` numerics or ``kp_max``/``kd_max``.

    The gains are what to command. On a calibrated model (its gain scales,
    a fit's ``pupper:kp_scale:ACT``) the motors deliver other gains, and
    every margin is of those. ``current``: the gains the robot runs today
    (``(kp, kd)`` for every group; default the model's own servo gains),
    run on the same robots and set beside the pick on the card.
    ``robot_config``: the robot's controller configuration (a ROS 2
    parameter file): the ``controller`` node's ``joint_names`` are the
    default ``joint_order`` and its ``kps``/``kds`` (or ``init_kps``/
    ``init_kds``) the default ``current``.

    ``out``: the run directory (recommend.csv: a card per group;
    trials.csv; tradeoffs.csv: the candidates no other beats at once on push
    dip, tracking speed and stand height; recommended.yaml: a ROS 2 parameter file with ``kps`` and
    ``kds`` for ``controller`` in ``joint_order``; recommended.xml: the
    model with the gains in its actuators; report.html; manifest.json).
    """
    # every keyword but these four is the plan's, checked there
    options = {k: v for k, v in locals().items() if k not in ("model", "out", "force", "progress")}
    say = _sayer(progress)
    try:
        import optuna  # noqa: F401  (the search's sampler)
    except ImportError:
        raise RecommendError("pupper recommend needs Optuna: install the extra with `make setup PUPPER_EXTRAS=tune` "
                             "(or pip install 'pupper_core[tune]')") from None
    p = make_plan(model, **options)
    out_dir = None if out is None else Path(out)
    if out_dir is None:
        with tempfile.TemporaryDirectory(prefix="pupper-recommend-") as tmp, _stop_on_signals("recommend"):
            return _run(p, Path(tmp), say, keep=False)
    from pupper_core._tune_study import _is_ours_to_ignore, _locked

    if out_dir.exists() and not out_dir.is_dir():
        raise RecommendError(f"output directory '{out_dir}' is a file: choose another -o")
    if out_dir.is_dir() and not force and not all(_is_ours_to_ignore(f.name) for f in out_dir.iterdir()):
        raise RecommendError(f"output directory '{out_dir}' already exists: choose another -o, or add --force "
                             "to overwrite it")
    made = not out_dir.exists()
    try:
        # Ctrl-C and SIGTERM stop it between sweeps too; the candidates run so
        # far stay in trials.csv (written after every generation)
        kept = f"the candidates run so far, if any, are in {out_dir / 'trials.csv'}"
        with _locked(out_dir, RecommendError), _stop_on_signals("recommend", kept):
            if not made:
                _clear(out_dir)
            try:
                return _run(p, out_dir, say, keep=True)
            except KeyboardInterrupt as e:
                # a signal inside a sweep stops it with the sweep's words
                # (resume, finished cells): recommend's are these
                if str(e).startswith("recommend stopped"):
                    raise
                raise KeyboardInterrupt(f"recommend stopped: {kept}") from None
    except BaseException:
        if made and not (out_dir / "trials.csv").exists():
            import shutil

            shutil.rmtree(out_dir, ignore_errors=True)
        raise


#: What a recommend run writes in its directory (robots/ too, with --from-fit).
OUTPUTS = ("recommend.csv", "trials.csv", "tradeoffs.csv", "recommended.yaml", "recommended.xml", "manifest.json",
           "report.html")


def _clear(d: Path) -> None:
    """An existing run directory (--force), before anything runs: every
    file a run writes there refused if it is not a regular file, then the
    older run's removed, so none of its answer (its candidates, its report)
    outlives it whatever the new run finds."""
    from pupper_core._files import refuse_non_regular

    robots = sorted((d / "robots").glob("robot_*.xml")) if (d / "robots").is_dir() else []
    for f in [d / n for n in OUTPUTS] + robots:
        refuse_non_regular(f)
    for f in [d / n for n in OUTPUTS] + robots:
        f.unlink(missing_ok=True)


def _run(p: Plan, d: Path, say: Callable[[str], None], keep: bool) -> Recommendation:
    """The search, the polish, the card and the files."""
    started = time.time()
    models = robot_model_files(p, d / "robots")
    wins = windows(p)
    every = search(p, models, say, lambda cands: write_trials(d, p, cands) if keep else None, wins)
    best = best_of(p, every)
    rec = Recommendation(None, [], every, p, d if keep else None)
    rec.no_window = [g.name for g in p.groups if wins[g.name].kp_span() is None]
    if best is not None:
        pick, near = polish_pick(p, best, models, say, every, wins)
        rec.searched = pick
        rec.current = in_use(p, models, say)
        rec.cards, rec.neighbours, rec.warnings, rec.pick = card_of(p, pick, near, d, say)
    if keep:
        write_trials(d, p, every)
    rec.yaml, rec.mjcf = write_outputs(rec, d, keep, time.time() - started)
    return rec


def _cli(args_json: str) -> list[str]:
    """`pupper recommend`: the CLI's parsed flags as JSON; prints the card."""
    a = json.loads(args_json)
    model = a.pop("model")
    rec = recommend(model, **a)
    # printed after every file is written: a stdout that cannot take the
    # card (a full disk) leaves the run whole, and says so in one line
    with printing():
        print_card(rec)
    if rec.out is None:
        return []
    return [str(rec.out / f) for f in ("recommend.csv", "trials.csv", "tradeoffs.csv", "recommended.yaml",
                                       "recommended.xml", "report.html") if (rec.out / f).exists()]
