"""`pupper recommend` (`pupper_core.recommend`): gains per joint group a
robot owner can put on the robot. Every candidate must hold on every robot
drawn from what the model does not know (none falls, none saturates past
the limit, each group's loop keeps its phase and gain margins as the
firmware closes it); among those, the lowest worst-side push dip wins.

The inputs are in ``plan``, the search in ``search``, what it found in
``result``, the card and the files in ``card``; this module runs it and is
the CLI's entry.
"""

from __future__ import annotations

import inspect
import json
import os
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from pupper_core._native import MAX_SATURATION
from pupper_core._rundir import printing
from pupper_core._recommend.card import card_of, in_use, print_card, write_outputs, write_trials
from pupper_core._types import exported_from
from pupper_core._recommend.fits import SCRATCH, FitRuns
from pupper_core._recommend.inputs import plan as make_plan
from pupper_core._recommend.plan import Plan, RecommendError
from pupper_core._recommend.search import best_of, robot_model_files, windows
from pupper_core._recommend.search import search as search_candidates
from pupper_core._recommend.search import polish as polish_pick
from pupper_core._recommend.result import Recommendation
from pupper_core._recommend.short import NO_ANSWER, best_margins, closest
from pupper_core._rundir import clear_run, is_ours_to_ignore, locked, sayer, stop_on_signals

__all__ = ["recommend", "Recommendation", "RecommendError"]


@exported_from("pupper_core")
def recommend(
    model: str | os.PathLike[str] = "pupper_v3",
    *,
    # the search
    robots: int = 32, trials: int = 48, batch: int = 16, seed: int = 0, polish: int = 4,
    # the robots, their firmware and their push
    seconds: float | None = None, push_force: float | None = None, motor: str | None = None,
    sensing_delay: float | None = None,
    command_delay: float = 0.0, spread: Sequence[str] | None = None, from_fit: FitRuns = None,
    # the constraints, the motors' limits, the gains in use; what the gains are ranked for (standing, walking)
    min_phase_margin: float = 30.0, min_gain_margin: float = 6.0, max_saturation: float = MAX_SATURATION, max_sag: float = 0.1,
    kp_max: float | None = None, kd_max: float | None = None, current: Sequence[float] | str | None = None,
    robot_config: str | os.PathLike[str] | None = None, task: str = "stand",
    gait: str | None = None, speed: float | None = None, frequency: float | None = None, max_tilt: float | None = None,
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
    intervals are the spread (8 joint models drawn inside them, the gain scales and the fitted
    delay per robot), or several runs merged (``fits``; out/calibrated.xml). The search's best then
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

    ``task="walk"``: the lowest p95 speed error of `pupper walk` at ``gait``, ``frequency`` and ``speed``, every
    robot's roll and pitch RMS under ``max_tilt``°; the card sets it beside ``task="stand"``'s (docs/recommend.md).
    """
    say = sayer(progress)
    _need_optuna()
    p = make_plan(model, robots=robots, trials=trials, batch=batch, seed=seed, polish=polish, seconds=seconds,
                  push_force=push_force, motor=motor, sensing_delay=sensing_delay, command_delay=command_delay,
                  spread=spread, from_fit=from_fit, min_phase_margin=min_phase_margin,
                  min_gain_margin=min_gain_margin, max_saturation=max_saturation, max_sag=max_sag, kp_max=kp_max,
                  kd_max=kd_max, current=current, robot_config=robot_config, joint_order=joint_order,
                  controller=controller, task=task, gait=gait, speed=speed, frequency=frequency, max_tilt=max_tilt)
    if out is None:
        with tempfile.TemporaryDirectory(prefix="pupper-recommend-") as tmp, stop_on_signals("recommend"):
            return _run(p, Path(tmp), say, keep=False)
    return _run_in(p, Path(out), force, say)


def _need_optuna() -> None:
    try:
        import optuna  # noqa: F401  (the search's sampler)
    except ImportError:
        raise RecommendError("pupper recommend needs Optuna: install the extra with `make setup PUPPER_EXTRAS=tune` "
                             "(or pip install 'pupper_core[tune]')") from None


def plan_for(model: str | os.PathLike[str] = "pupper_v3", **changes: Any) -> Plan:
    """The plan `recommend` makes of ``model`` with these keywords and its
    own defaults for the rest (tests and benches look at a plan alone)."""
    kw = {k: p.default for k, p in inspect.signature(recommend).parameters.items()
          if k not in ("model", "out", "force", "progress")}
    return make_plan(model, **{**kw, **changes})


def _run_in(p: Plan, out_dir: Path, force: bool, say: Callable[[str], None]) -> Recommendation:
    """The run in its directory: refused if another run's is there (unless
    --force), locked, and removed again if stopped before any candidate."""
    if out_dir.exists() and not out_dir.is_dir():
        raise RecommendError(f"output directory '{out_dir}' is a file: choose another -o")
    if out_dir.is_dir() and not force and not all(is_ours_to_ignore(f.name) for f in out_dir.iterdir()):
        raise RecommendError(f"output directory '{out_dir}' already exists: choose another -o, or add --force "
                             "to overwrite it")
    made = not out_dir.exists()
    try:
        # Ctrl-C and SIGTERM stop it between sweeps too; the candidates run so
        # far stay in trials.csv (written after every generation)
        kept = f"the candidates run so far, if any, are in {out_dir / 'trials.csv'}"
        with locked(out_dir, RecommendError), stop_on_signals("recommend", kept):
            if not made:
                clear_run(out_dir)
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


def _run(p: Plan, d: Path, say: Callable[[str], None], keep: bool) -> Recommendation:
    """The search, the polish, the card and the files."""
    started = time.time()
    if p.merged_xml:
        _keep_merged(p, d)
    models = robot_model_files(p, d / "robots")
    wins = windows(p)
    every = search_candidates(p, models, say, lambda cands: write_trials(d, p, cands) if keep else None, wins)
    best = best_of(p, every)
    rec = Recommendation(None, [], every, p, d if keep else None)
    rec.no_window = [g.name for g in p.groups if wins[g.name].kp_span() is None]
    if best is not None:
        pick, near = polish_pick(p, best, models, say, every, wins)
        rec.searched = pick
        rec.current = in_use(p, models, say)
        rec.cards, rec.neighbours, rec.warnings, rec.pick = card_of(p, pick, near, d, say)
        p.task.after(rec, models, say, wins)
    else:
        # no answer: the best available, and the gains in use beside it
        rec.nearest = closest(p, every) or best_margins(p)
        rec.current = in_use(p, models, say)
        rec.short_lines = p.task.unanswered(rec, models, say)
    if keep:
        write_trials(d, p, every)
    rec.yaml, rec.mjcf = write_outputs(rec, d, keep, time.time() - started)
    return rec


def _keep_merged(p: Plan, d: Path) -> None:
    """The model merged from several fit runs, into the run directory
    (calibrated.xml): the robots, the exports and the manifest read it
    there, where the run keeps it."""
    import shutil

    from pupper_core._rundir import atomic_write_text

    scratch = Path(p.model)
    d.mkdir(parents=True, exist_ok=True)
    atomic_write_text(d / "calibrated.xml", p.merged_xml)
    p.model = os.fspath(d / "calibrated.xml")
    if scratch.name == "calibrated.xml" and scratch.parent.name.startswith(SCRATCH):
        shutil.rmtree(scratch.parent, ignore_errors=True)


def _cli(args_json: str) -> list[str]:
    """`pupper recommend`: the CLI's parsed flags as JSON; prints the card."""
    a = json.loads(args_json)
    model = a.pop("model")
    rec = recommend(model, **a)
    # printed after every file is written: a stdout that cannot take the
    # card (a full disk) leaves the run whole, and says so in one line
    with printing():
        print_card(rec)
    # no gains named is its own exit status (after the files, as they are written)
    status = [] if rec.pick is not None else [f"status:{NO_ANSWER}"]
    if rec.out is None:
        return status
    merged = ("calibrated.xml",) if rec.plan.merged_xml else ()
    return [str(rec.out / f) for f in (*merged, "recommend.csv", "trials.csv", "tradeoffs.csv", "recommended.yaml",
                                       "recommended.xml", "report.html") if (rec.out / f).exists()] + status
