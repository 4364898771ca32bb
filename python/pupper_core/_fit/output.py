"""A fit's run directory (``pupper_core._fit`` writes it): fit.csv,
residuals.csv, warnings.csv, calibrated.xml, manifest.json and the plots,
written beside it and moved in whole."""

from __future__ import annotations

import csv
import hashlib
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core import _native
from pupper_core._rundir import clear_run, refuse_non_regular
from pupper_core._fit.cover import LINK_KINDS, type_sets
from pupper_core._fit.problem import FitResult, _Problem, _Solution
from pupper_core._fit.robot import Robot, _history_samples
from pupper_core._fit.sysid import _predictions
from pupper_core._fit.terms import GROUPS, NOISE_FLOOR, SCALE_NUMERIC, FitError
from pupper_core._fit.validate import Validation
from pupper_core._fit.validate import write as write_validation


def _write_run(out: Path, res: FitResult, pb: _Problem, sol: _Solution, model: Any, names: list[str], per: str,
               force: bool, plot: bool, val: Validation | None = None) -> None:
    """The run directory, written beside it first and moved in at the end:
    a run stopped or failing while it writes leaves the directory as it was
    (a --force run's earlier files too), or none if it made it."""
    made = not out.exists()
    stage = out.parent / f".{out.name}.partial{os.getpid()}"
    try:
        shutil.rmtree(stage, ignore_errors=True)
        stage.mkdir(parents=True)
        _write(stage, res, pb, sol.x, model, names, per, val)
        if plot:
            _plot(stage, pb, sol)
        if val is not None:
            write_validation(stage, val)
        out.mkdir(parents=True, exist_ok=True)
        # nothing of an older run (--force, of any kind) outlives this one
        clear_run(out)
        staged = [f for f in sorted(stage.rglob("*")) if f.is_file()]
        # none moved over a FIFO or a device: all refused before any moves
        for f in staged:
            refuse_non_regular(out / f.relative_to(stage))
        for f in staged:
            dest = out / f.relative_to(stage)
            dest.parent.mkdir(parents=True, exist_ok=True)
            os.replace(f, dest)
        from pupper_core import _report

        _report.report(out)
    except BaseException as e:
        if made:
            shutil.rmtree(out, ignore_errors=True)
        if isinstance(e, OSError):
            raise FitError(f"cannot write the run directory {out} ({e.strerror or e}): check the path, its "
                           "permissions and the free space") from None
        raise
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _write(out: Path, res: FitResult, pb: _Problem, x: np.ndarray, model: Any, names: list[str], per: str,
           val: Validation | None) -> None:
    import mujoco

    from pupper_core._rundir import atomic_write

    robot, logs = pb.robot, pb.logs

    def table(tmp: Path) -> None:
        with tmp.open("w", newline="", errors="surrogateescape") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["parameter", "actuators", "nominal", "fitted", "low95", "high95", "unit"])
            for r in res.table:
                w.writerow([r["parameter"], r["actuators"], repr(r["nominal"]), repr(r["fitted"]),
                            repr(r["low95"]), repr(r["high95"]), r["unit"]])

    atomic_write(out / "fit.csv", table)

    def residuals(tmp: Path) -> None:
        with tmp.open("w", newline="", errors="surrogateescape") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["log", "actuator", "rms_before_rad", "rms_after_rad"])
            for lg in logs:
                for k, a in enumerate(res.actuators_of(lg.path.name)):
                    w.writerow([lg.path.name, a, repr(res.rms_before[lg.path.name][k]),
                                repr(res.rms_after[lg.path.name][k])])

    atomic_write(out / "residuals.csv", residuals)
    if res.robots is not None:
        _write_robots(out, res)
    _write_warnings(out, res)
    xml = _calibrated_xml(robot.full, _whole_labels(robot, pb.labels, per), x)
    atomic_write(out / "calibrated.xml", lambda tmp: _write_text(tmp, xml))
    manifest = {
        "command": "fit",
        "inputs": {"model": str(model), "logs": [{"path": str(lg.path), "sha256": lg.sha256} for lg in logs],
                   "params": names, "per": per,
                   "motor": pb.firmware.spec() if pb.firmware is not None else "ideal",
                   "validate": [{"path": str(t), "sha256": s} for t, s in (val.logs if val else [])]},
        "fit": {r["parameter"]: {"nominal": r["nominal"], "fitted": r["fitted"], "low95": r["low95"],
                                 "high95": r["high95"], "unit": r["unit"]} for r in res.table},
        "rms_before_rad": res.rms_before, "rms_after_rad": res.rms_after,
        # logs of different motors: the actuators each log's errors are of
        **({"log_actuators": res.log_actuators} if res.log_actuators else {}),
        "warnings": res.warnings, "notes": res.notes, "delay_scan": res.delay_scan, "seconds": res.seconds,
        "validation": res.validation,
        "intervals": {"noise_floor": dict(zip(("angle_rad", "velocity_rad_s", "torque_nm"), NOISE_FLOOR)),
                      "floored": res.floored, "correlation_time_samples": res.correlation_time,
                      "source": res.interval_source},
        **({"robots": res.robots.manifest()} if res.robots is not None else {}),
        # the bytes of what a reader believes (recommend and gains --from-fit check them)
        "outputs": {n: hashlib.sha256((out / n).read_bytes()).hexdigest()
                    for n in ("fit.csv", "calibrated.xml", "robots.csv") if (out / n).is_file()},
    }
    _native.write_manifest(os.fspath(out), "fit", manifest)


def _write_text(path: Path, text: str) -> None:
    # a log's name that is not UTF-8 keeps its bytes
    path.write_text(text, errors="surrogateescape")


def _write_robots(out: Path, res: FitResult) -> None:
    """robots.csv: the robots the logs allow (``robots``), a row each with
    its value of every fit.csv parameter and its RMS angle error over the
    logs."""
    from pupper_core._rundir import atomic_write

    drawn = res.robots
    names = [str(r["parameter"]) for r in res.table]

    def write(tmp: Path) -> None:
        with tmp.open("w", newline="") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["robot", *names, "rms_rad"])
            for k, (x, rms) in enumerate(zip(drawn.x, drawn.rms)):
                w.writerow([k, *(repr(float(v)) for v in x), repr(float(rms))])

    atomic_write(out / "robots.csv", write)


def _write_warnings(out: Path, res: FitResult) -> None:
    """warnings.csv: one row per warning (the parameter it is about, if
    one), only when there are any (a stale one from --force goes)."""
    from pupper_core._rundir import atomic_write

    path = out / "warnings.csv"
    if not res.warnings:
        path.unlink(missing_ok=True)
        return
    names = sorted((r["parameter"] for r in res.table), key=len, reverse=True)

    def write(tmp: Path) -> None:
        with tmp.open("w", newline="", errors="surrogateescape") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["parameter", "warning"])
            for text in res.warnings:
                w.writerow([next((n for n in names if text.startswith(n)), ""), text])

    atomic_write(path, write)


def _whole_labels(robot: Robot, labels: list[tuple[str, str, list[int], float]],
                  per: str) -> list[tuple[str, str, list[int], float]]:
    """The labels over the whole robot where the fit stepped a part of it
    (``robot.narrow``): a value per all or per group goes to every
    joint of the whole robot it stands for, as if every leg were stepped."""
    if robot.whole is None:
        return _alike_joints(robot, labels)
    # a fit of several motors' logs shares the motor's parameters by type (``cover.type_sets``)
    whole = {**dict(type_sets(robot.full)), **dict(robot.full.members(per))}
    return _alike_joints(robot, [(name, kind, whole.get(name[len(kind):], [robot.full.actuators.index(
        robot.actuators[i]) for i in members]), nom) for name, kind, members, nom in labels])


def _alike_joints(robot: Robot, labels: list[tuple[str, str, list[int], float]]
                  ) -> list[tuple[str, str, list[int], float]]:
    """The labels with a joint's own values (the link's: armature and
    damping, fitted per joint) given to the same joint of every leg the
    logs did not cover: the legs are built alike, and one leg's bench logs
    calibrate the robot's (a value per joint of an unlogged leg would stay
    nominal). A joint some label of its kind covers keeps its own; of
    several logged joints of a group, the first label's goes to the rest."""
    full = robot.full
    covered: dict[str, set[int]] = {}
    for _, kind, members, _ in labels:
        covered.setdefault(kind, set()).update(members)
    out = []
    for name, kind, members, nom in labels:
        if kind in LINK_KINDS and len(members) == 1 and full.groups[members[0]] in GROUPS:
            group = full.groups[members[0]]
            alike = [k for k, g in enumerate(full.groups) if g == group and k not in covered[kind]]
            covered[kind].update(alike)
            members = members + alike
        out.append((name, kind, members, nom))
    return out


def _calibrated_xml(robot: Robot, labels: list[tuple[str, str, list[int], float]], x: np.ndarray,
                    name: str = "calibrated") -> str:
    """The whole robot with the fitted values, written through MjSpec
    (its model name ``name`` after its own); a scale the model already
    holds (a calibrated model's, recommend merging fits) takes the new value."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(robot.file))
    # assets stay where the original's are
    base = robot.file.parent
    spec.meshdir = str((base / spec.meshdir).resolve()) if spec.meshdir else str(base)
    spec.texturedir = str((base / spec.texturedir).resolve()) if spec.texturedir else str(base)
    if robot.fixed_base:
        # the model fitted had its base welded: so has its calibration
        for j in [j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_FREE]:
            spec.delete(j)
        for k in list(spec.keys):
            spec.delete(k)
    scales: dict[tuple[str, int], float] = {}
    n = _history_samples(robot)
    for (name, kind, members, _), v in zip(labels, x):
        for i in members:
            if kind in ("armature", "frictionloss"):
                setattr(spec.joint(robot.joints[i]), kind, float(v))
            elif kind == "damping":
                spec.joint(robot.joints[i]).damping[0] = float(v)
            elif kind == "torque_limit":
                act = spec.actuator(robot.actuators[i])
                act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
                act.forcerange[0], act.forcerange[1] = -float(v), float(v)
            elif kind == "delay":
                act = spec.actuator(robot.actuators[i])
                act.delay = float(v)
                act.nsample = n
                act.interp = 1
            else:
                scales[(kind, i)] = float(v)
    held = {n.name: n for n in spec.numerics}
    for (kind, i), v in sorted(scales.items()):
        numeric = SCALE_NUMERIC.format(kind=kind, actuator=robot.actuators[i])
        if numeric in held:
            held[numeric].data = [v]
        else:
            spec.add_numeric(name=numeric, data=[v])
    if name:
        spec.modelname = f"{spec.modelname}_{name}" if spec.modelname else name
    return str(spec.to_xml())


def _plot(out: Path, pb: _Problem, sol: _Solution) -> list[Path]:
    """Per log, measured against simulated angle of each fitted joint, at
    the nominal and the fitted values, each with its residual beneath
    (``pupper_core.plots.fit`` draws them)."""
    from pupper_core.plots.fit import fit_figure, save

    first = _predictions(sol.residual_fn, pb.pdict, pb.x_nominal)
    last = _predictions(sol.residual_fn, sol.params, sol.x)
    # the predictions' first columns are the fitted joints' angles
    return [save(fit_figure(lg.path.name, t, me, p0, p1, [pb.robot.actuators[k] for k in pb.kept_of(i)]),
                 out / "plots" / f"fit_{lg.path.stem}.png")
            for i, (lg, (t, me, p0), (_, _, p1)) in enumerate(zip(pb.logs, first, last))]
