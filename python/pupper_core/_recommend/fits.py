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
import json
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from pupper_core._recommend.plan import RecommendError

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
    f = d / "fit.csv"
    if not (f.is_file() and (d / "calibrated.xml").is_file()):
        raise RecommendError(f"--from-fit {d}: no fit there (fit.csv and calibrated.xml): give a `pupper fit` "
                             "run directory")
    with open(f, newline="") as fh:
        return list(csv.DictReader(fh))


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
        return str(json.loads((d / "manifest.json").read_text())["inputs"]["model"])
    except (OSError, ValueError, KeyError, TypeError):
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
