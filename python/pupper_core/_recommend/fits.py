"""The `pupper fit` runs `recommend --from-fit` draws its robot from: one
run, or several merged into one model.

A fit's rows (fit.csv) each calibrate a parameter of some actuators (a
``--per all`` value every actuator of the robot, ``--per joint`` one).
Several runs merge where they calibrate different actuators, each
actuator's parameters taken from the run that fitted it: the model is the
first run's calibrated.xml with every run's values written over it. Two
runs that give one actuator's parameter different values contradict each
other, and no rule says which one the robot is: that is refused (fit the
runs' logs together instead: one fit takes logs of several motors)."""

from __future__ import annotations

import csv
import math
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core import _native
from pupper_core._native import PupperError
from pupper_core._recommend.plan import Loop, RecommendError

#: What ``from_fit`` takes: a run directory, or a list of them.
FitRuns = str | os.PathLike[str] | Sequence[str | os.PathLike[str]] | None


def fit_runs(from_fit: FitRuns) -> list[Path]:
    """``from_fit`` as the runs it names: None, one path, or a list of
    them; the same run twice is refused."""
    if from_fit is None:
        return []
    items = [from_fit] if isinstance(from_fit, (str, os.PathLike)) else list(from_fit)
    runs = [Path(p) for p in items]
    seen: dict[Path, Path] = {}
    for d in runs:
        key = d.resolve()
        if key in seen:
            also = f" (as {d})" if str(d) != str(seen[key]) else ""
            raise RecommendError(f"--from-fit names {seen[key]} twice{also}: give each fit run once")
        seen[key] = d
    return runs


def fit_rows(d: Path) -> list[dict[str, str]]:
    """A fit run's fit.csv rows, the run checked against its manifest first
    (``_native.fit_run``: a fit's, its files the ones it wrote)."""
    from pupper_core._native import ConfigError, fit_run

    try:
        fit_run(d)
    except ConfigError as e:
        raise RecommendError(str(e)) from None
    with open(d / "fit.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    for r in rows:
        _believable(d, r)
    return rows


def _believable(d: Path, r: Mapping[str, str]) -> None:
    """A fit.csv row a fit could have written: a kind it fits, its value a
    number inside that kind's bounds, its interval numbers (or empty where
    not meaningful); else one line (a run made before the fit recorded its
    files' hashes is read as it is, so its values are checked here)."""
    from pupper_core._fit.terms import PARAMS

    k = kind(r)
    if k not in PARAMS:
        raise RecommendError(f"--from-fit {d}: fit.csv names '{r.get('parameter')}', no parameter a fit gives: "
                             "run `pupper fit` again")
    unit, lo, hi = PARAMS[k]
    try:
        v = float(r["fitted"])
        # the interval: numbers, infinite where the logs do not place it, NaN where not meaningful
        for c in ("low95", "high95"):
            float(r[c]) if str(r.get(c, "")).strip() else math.nan
    except (KeyError, TypeError, ValueError):
        raise RecommendError(f"--from-fit {d}: fit.csv's {r.get('parameter')} is not a number: the file was edited "
                             "or is not a fit's; run `pupper fit` again") from None
    if not (math.isfinite(v) and lo <= v <= hi):
        raise RecommendError(f"--from-fit {d}: fit.csv's {r['parameter']} is {v:g}{(' ' + unit) if unit else ''}, "
                             f"outside the {lo:g} to {hi:g} a fit gives it: the file was edited or is not a fit's; "
                             "run `pupper fit` again")


def kind(row: Mapping[str, str]) -> str:
    """What a fit.csv row calibrates (``kp_scale`` of ``kp_scale.leg_front_r_3``)."""
    return str(row.get("parameter", "")).partition(".")[0]


def actuators(row: Mapping[str, str]) -> list[str]:
    """The actuators a fit.csv row's value goes to."""
    return [a for a in re.split(r"[ ;|]+", row.get("actuators", "").strip()) if a]


def _fitted(d: Path, row: Mapping[str, str]) -> float:
    try:
        return float(row["fitted"])
    except (KeyError, ValueError):
        raise RecommendError(f"--from-fit {d}: fit.csv row {dict(row)} is not a fit's: give a `pupper fit` run "
                             "directory") from None


def _fitted_on(d: Path) -> str | None:
    """The model a run was fitted on, as its manifest names it."""
    try:
        return str(_native.read_manifest(os.fspath(d))["inputs"]["model"])
    except (OSError, PupperError, KeyError, TypeError):
        return None


def merged(runs: Sequence[Path]) -> tuple[list[dict[str, str]], str]:
    """Every run's rows and the merged model's MJCF; refused where two runs
    calibrate one actuator's parameter to different values, or were fitted
    on different models."""
    from pupper_core._fit.output import _calibrated_xml
    from pupper_core._fit.robot import load_robot
    from pupper_core._fit.terms import FitError

    models = {d: _fitted_on(d) for d in runs}
    named = [(d, m) for d, m in models.items() if m is not None]
    if len({m for _, m in named}) > 1:
        (d1, m1), (d2, m2) = named[0], next((d, m) for d, m in named if m != named[0][1])
        raise RecommendError(f"--from-fit {d1} and {d2} were fitted on different models ({m1}, {m2}): merge runs "
                             "of one robot's model")
    rows: list[dict[str, str]] = []
    claims: dict[tuple[str, str], tuple[float, Path, str]] = {}
    for d in runs:
        for r in fit_rows(d):
            v = _fitted(d, r)
            for a in actuators(r):
                had = claims.setdefault((kind(r), a), (v, d, r["parameter"]))
                if had[0] != v:
                    raise RecommendError(
                        f"--from-fit {had[1]} and {d} calibrate {a}'s {kind(r)} to different values ({had[2]} "
                        f"{had[0]:.6g}, {r['parameter']} {v:.6g}): recommend from one of them, or fit both runs' "
                        "logs in one `pupper fit` (it fits logs of several motors together)")
            rows.append(r)
    try:
        robot = load_robot(runs[0] / "calibrated.xml")
    except FitError as e:
        raise RecommendError(f"--from-fit {runs[0]}: {e}") from None
    labels, x = [], []
    for r in rows:
        unknown = [a for a in actuators(r) if a not in robot.actuators]
        if unknown:
            raise RecommendError(f"--from-fit: fit.csv's {r['parameter']} names {unknown[0]}, which "
                                 f"{runs[0] / 'calibrated.xml'} does not have: merge runs of one robot's model")
        labels.append((r["parameter"], kind(r), [robot.actuators.index(a) for a in actuators(r)], 0.0))
        x.append(float(r["fitted"]))
    # the first run's calibration, every run's values written over it (it is named calibrated already)
    return rows, _calibrated_xml(robot, labels, np.array(x), name="")


def robot_of(runs: Sequence[Path]) -> tuple[list[dict[str, str]], str, Path | None]:
    """What the runs say of the robot: their fit.csv rows, the merged
    model's MJCF (several runs; else ""), and the model's file (None
    without a run). Several runs' model is written to a scratch folder for
    the plan to read (removed at exit; the run keeps its own copy)."""
    if not runs:
        return [], "", None
    if len(runs) == 1:
        return fit_rows(runs[0]), "", runs[0] / "calibrated.xml"
    rows, xml = merged(runs)
    return rows, xml, _scratch_model(xml)


#: The scratch folder's name starts so (``_recommend._keep_merged`` removes it once the run keeps the model).
SCRATCH = "pupper-fits-"


def _scratch_model(xml: str) -> Path:
    import atexit
    import shutil
    import tempfile

    d = Path(tempfile.mkdtemp(prefix=SCRATCH))
    atexit.register(shutil.rmtree, d, True)
    path = d / "calibrated.xml"
    path.write_text(xml)
    return path


def fit_motor(runs: Sequence[Path]) -> str:
    """The firmware the runs' fits replayed through (their manifests'
    --motor; "" for the ideal servo), as torque mode's --motor takes it: the
    encoder noise a fit replays is the robots' q_noise here. Runs that
    replayed different firmwares are refused."""
    specs: dict[str, Path] = {}
    for d in runs:
        try:
            spec = str(_native.read_manifest(os.fspath(d))["inputs"].get("motor") or "ideal")
        except (OSError, PupperError, KeyError, TypeError, AttributeError):
            spec = "ideal"
        kept = ",".join(p for p in spec.split(",") if p.strip() and not p.strip().startswith("noise="))
        specs.setdefault("" if kept in ("", "ideal") else kept, d)
    if len(specs) > 1:
        (a, da), (b, db) = list(specs.items())[:2]
        raise RecommendError(f"--from-fit {da} and {db} replayed different firmwares ({a or 'ideal'}, {b or 'ideal'}):"
                             " merge runs fitted through one firmware")
    return next(iter(specs), "")


def fit_robots(runs: Sequence[Path], rows: Sequence[Mapping[str, str]]) -> tuple[list[list[float]], float]:
    """The robots the runs' logs allow (each run's robots.csv: draws from
    its fit's joint distribution), each as its value of every row of
    ``rows`` (the runs' fit.csv rows in order), and the worst one's RMS
    error over its fit's; robot k of several runs is each run's robot k.
    A run without robots.csv (a fit older than the draws) is refused."""
    per_run: list[list[list[float]]] = []
    worst = 0.0
    for d in runs:
        f = d / "robots.csv"
        if not f.is_file():
            raise RecommendError(f"--from-fit {d}: no robots.csv, the robots its logs allow (a fit made before "
                                 "pupper drew them): run its `pupper fit` again")
        names = [r["parameter"] for r in fit_rows(d)]
        try:
            with open(f, newline="") as fh:
                table = list(csv.DictReader(fh))
            per_run.append([[float(t[n]) for n in names] for t in table])
            manifest = _native.read_manifest(os.fspath(d))
            worst = max(worst, float(manifest["robots"]["worst_over_fitted"]))
        except (OSError, ValueError, PupperError, KeyError, TypeError) as e:
            raise RecommendError(f"--from-fit {d}: robots.csv does not hold its fit.csv's parameters "
                                 f"({type(e).__name__}: {e}): run its `pupper fit` again") from None
        if not per_run[-1] or any(not all(math.isfinite(v) for v in x) for x in per_run[-1]):
            raise RecommendError(f"--from-fit {d}: robots.csv holds no robot, or a value that is not a number: "
                                 "run its `pupper fit` again")
    count = min(len(p) for p in per_run)
    robots = [[v for p in per_run for v in p[k]] for k in range(count)]
    if len(robots[0]) != len(rows):
        raise RecommendError("--from-fit: robots.csv and fit.csv disagree on the parameters: run the fits again")
    return robots, worst


def robot_xml(model: str, rows: Sequence[Mapping[str, str]], values: Sequence[float]) -> str:
    """The calibrated ``model`` with one robot's values of ``rows`` written
    over it, by the writer calibrated.xml itself comes from."""
    from pupper_core._fit.output import _calibrated_xml
    from pupper_core._fit.robot import load_robot

    robot = load_robot(model)
    labels = [(r["parameter"], kind(r), [robot.actuators.index(a) for a in actuators(r) if a in robot.actuators], 0.0)
              for r in rows]
    return _calibrated_xml(robot, labels, np.asarray(values, dtype=float), name="")


#: What each kind of fit row sets of a joint's loop (``plan.Loop``'s fields).
LOOP_KINDS = {"kp_scale": "kp_scale", "kd_scale": "kd_scale", "damping": "damping", "lag": "lag",
              "latency": "latency"}


def robot_loops(base: Sequence[Loop], armature: Sequence[float], rows: Sequence[Mapping[str, str]],
                values: Sequence[float], names: Sequence[str]) -> list[Loop]:
    """Each actuator's loop on one robot: its calibrated model's (``base``,
    whose inertia holds the model's ``armature``) with the robot's values of
    the fit's rows written over it."""
    out = list(base)
    for r, v in zip(rows, values):
        k = kind(r)
        for a in actuators(r):
            if a not in names:
                continue
            i = names.index(a)
            if k == "armature":
                out[i] = out[i]._replace(inertia=max(out[i].inertia - armature[i] + v, 1e-9))
            elif k in LOOP_KINDS:
                out[i] = out[i]._replace(**{LOOP_KINDS[k]: max(v, 0.0)})
    return out


def delay_as_latency(plan: Any, gains: Mapping[str, tuple[float, float]]) -> dict[str, float] | None:
    """Each group's worst phase margin (deg) if the fit's command delay were
    feedback latency instead, the other reading of logs at one kp (they
    cannot tell the two apart); None where the fit placed its latency
    itself, or found no delay."""
    from pupper_core._native import loop_margins

    rows = plan.fit_rows
    delays = [float(r["fitted"]) for r in rows if kind(r) == "delay"]
    placed = [r for r in rows if kind(r) == "latency"
              and all(math.isfinite(float(r[k] or "nan")) for k in ("low95", "high95"))]
    if not rows or placed or plan.sensing_delay is not None or not delays or max(delays) <= plan.timestep:
        return None
    late = max(delays)
    out = {}
    for g in plan.groups:
        kp, kd = gains[g.name]
        out[g.name] = min(loop_margins(lp.inertia, kp * lp.kp_scale, kd * lp.kd_scale, motor=plan.motor,
                                       timestep=plan.timestep, damping=lp.damping, lag=lp.lag,
                                       latency=lp.latency + late, fitted=True)[0] for lp in g.loops)
    return out


def readings_line(plan: Any, pick: Mapping[str, tuple[float, float]] | None,
                  current: Mapping[str, tuple[float, float]] | None, label: str = "the pick") -> str:
    """The card's line on the other reading of the fit's delay (as feedback
    latency): the worst loop of the pick and of the gains in use under it,
    and whether the gains the robot runs today rule it out."""
    said = []
    ruled_out = False
    for label, gains in ((label, pick), ("the gains in use", current)):
        if not gains:
            continue
        pms = delay_as_latency(plan, gains)
        if pms is None:
            return ""
        g = min(pms, key=lambda k: pms[k])
        said.append(f"{label}'s worst loop {g} phase {pms[g]:.0f}°")
        ruled_out = ruled_out or (label == "the gains in use" and pms[g] < 0)
    if not said:
        return ""
    delay = max(float(r["fitted"]) for r in plan.fit_rows if kind(r) == "delay")
    return (f"if the fit's {delay * 1e3:.3g} ms delay were feedback latency instead (logs at one kp cannot tell "
            f"the two apart): {', '.join(said)}" + ("; a reading the gains the robot runs today, unstable under "
                                                    "it, rule out" if ruled_out else
                                                    "; fit logs at two kps with --params ...,latency to tell"))
