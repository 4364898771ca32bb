"""`pupper fit` and `pupper excite`: the model calibrated to a robot's joint
logs with MuJoCo's system-identification toolbox (`mujoco.sysid`).

`excite` writes a trajectory to play on the hardware (per joint group a
multisine or chirp around the rest pose, inside the joint ranges and under
velocity and torque limits, with holds between) and the nominal model's
response to it, in the joint-log format (`pupper_core._fit.log`).

`fit` replays each log's targets, at the log's gains, through the robot
hung in the air (the free joint removed, contacts off), and fits joint
armature, damping and friction loss, the servo's kp and kd scales and its
command delay to the logged angles (and torques, where logged) by
`mujoco.sysid`'s bounded Levenberg–Marquardt, every rollout of a Jacobian
in one batch on all cores. Intervals are sysid's Gauss–Newton 95 % ones,
their residual noise floored at NOISE_FLOOR (noise-free logs). What cannot
be trusted is said as a warning: a parameter on a bound, an interval that
is infinite or below 0, confounded parameters, a log made worse, a joint
that never moves (left out); a fit that ends worse than the nominal values
restarts from them, and keeps them if it cannot do better.

Outputs (a run directory): ``fit.csv``, ``calibrated.xml`` (the model with
the fitted values, written through `MjSpec`; every command loads it with
``--model``), ``residuals.csv``, ``manifest.json``, ``warnings.csv`` (when
there are warnings) and, with ``plot``, ``plots/fit_<log>.png`` (measured
against simulated angle per joint, before and after, each joint's residual
beneath).

The code is split by concern: the terms and the error in ``terms``, the
robot in ``robot``, excite in ``excitation``, the logs in ``log``,
``columns`` and ``specs``, the problem they set in ``problem``, where a
fit starts in ``start``, `mujoco.sysid`'s side in ``sysid``, the
intervals in ``intervals``, the run directory in ``output``; this module
solves a fit, judges it and is the CLI's entry.
"""

from __future__ import annotations

import io
import json
import math
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core._rundir import flush_stdout, printing, say
from pupper_core._fit.excitation import _excite, excite
from pupper_core._fit.judge import _judge, disagreements, fit_entries, motor_types
from pupper_core._fit.solve import _check_memory, _Progress, _solve
from pupper_core._fit.replay import Firmware, parse_motor
from pupper_core._fit.jacobian import jacobian_fn, rollouts_per_jacobian
from pupper_core._fit.output import _write_run
from pupper_core._fit.problem import FitResult, _Problem, _problem, _read_logs, _Solution, as_replayed, narrowed
from pupper_core._fit.robot import BUILTINS as BUILTINS
from pupper_core._fit.robot import initial_state as initial_state
from pupper_core._fit.robot import simulate as simulate
from pupper_core._fit.robot import Robot, load_robot, suspended_spec
from pupper_core._fit.robots import robots as drawn_robots
from pupper_core._fit.start import GRID, parse_start, starts
from pupper_core._fit.sysid import (
    Predictions,
    _correlation_time,
    _information_shares,
    _interval_residuals,
    _predictions,
    _residual_fn,
    _rms,
    _sysid,
    _whitening,
)
from pupper_core._fit.validate import Validation, check_apart, print_table
from pupper_core._fit.validate import validate as validate_logs
from pupper_core._fit.terms import GROUPS as GROUPS
from pupper_core._fit.terms import MAX_LOG_SECONDS as MAX_LOG_SECONDS
from pupper_core._fit.terms import NOISE_FLOOR as NOISE_FLOOR
from pupper_core._fit.terms import RUN_FILES as RUN_FILES
from pupper_core._fit.terms import SCALE_NUMERIC as SCALE_NUMERIC
from pupper_core._fit.terms import STILL_RAD as STILL_RAD
from pupper_core._fit.terms import (
    CONFOUNDED,
    DEFAULT_PARAMS,
    MEMORY_COPIES,
    MEMORY_FRACTION,
    PARAMS,
    FIRMWARE_ONLY,
    lag_matters,
    PER,
    FitError,
)
from pupper_core._fit.columns import LogError
from pupper_core._fit.log import JointLog
from pupper_core._fit.columns import ColumnMap, read_map
from pupper_core._types import exported_from
from pupper_core._fit.specs import option_text, path_list
from pupper_core._rundir import stop_on_signals

__all__ = ["fit", "excite", "FitResult", "FitError", "PARAMS"]


def _parse_params(params: str | Sequence[str]) -> list[str]:
    names = [p.strip() for p in (params.split(",") if isinstance(params, str) else params) if p.strip()]
    if not names:
        raise FitError("--params is empty: name some of " + ", ".join(PARAMS))
    for n in names:
        if n not in PARAMS:
            raise FitError(f"--params names '{n}', which fit does not know: use any of {', '.join(PARAMS)}")
    if len(set(names)) != len(names):
        raise FitError("--params names a parameter twice: keep one")
    return names



@exported_from("pupper_core")
def fit(logs: Sequence[str | os.PathLike[str] | tuple[str | os.PathLike[str], Mapping[str, Any]]], *,
        model: str | os.PathLike[str] = "pupper_v3",
        params: str | Sequence[str] = DEFAULT_PARAMS, per: str = "all", out: str | os.PathLike[str] | None = None,
        force: bool = False, max_iters: int = 50, plot: bool = False, progress: bool | Callable[[str], None] = True,
        columns: str | os.PathLike[str] | None = None, kp: float | str | Sequence[float] | None = None,
        kd: float | str | Sequence[float] | None = None, held: float | str | Mapping[str, float] | None = None,
        validate: Sequence[str | os.PathLike[str]] | str | os.PathLike[str] = (), motor: str | None = None,
        gains_from_name: str | None = None, start: str | Mapping[str, float] | None = None) -> FitResult:
    """Fits ``params`` (per ``all`` actuators, joint ``group`` or ``joint``)
    to the joint ``logs`` and, with ``out``, writes the run directory.
    A log is a path (plain or gzip/bzip2/xz-compressed), ``"LOG::kp=5,kd=0.25"``
    (its own gains, and held=, columns=), ``"@LIST"`` (a file naming such
    logs, one per line), or (path, {"kp": 5, "kd": 0.25}).
    ``columns``: a column map (KEY=COLUMN[:UNIT],...) or its file, over
    each log's own; ``kp``, ``kd`` (one value, or one per logged joint),
    ``held``: for a fitted log that does not say them in its header (a
    header that says other values is refused); ``gains_from_name``: a
    pattern with {kp} and {kd} that reads each log's gains from its file
    name. ``validate``: logs not fitted (one path, or a list; each states
    its own gains), replayed through the
    nominal and the calibrated model (``FitResult.validation``). ``motor``:
    the servo firmware to replay through (rate, filter, counts, noload, as
    --motor takes them; default MuJoCo's ideal servo). ``start``: where
    the fit starts a kind of parameter (KIND=VALUE,... or a mapping; the
    delay is also estimated from the logs, and the lowest cost of every
    start is kept). ``progress``: True says what the fit does on stderr
    where it is a terminal; or a callable given each line. SIGINT and
    SIGTERM stop it (KeyboardInterrupt) with nothing written."""
    names = _parse_params(params)
    begin = parse_start(start, names)
    try:
        logs, validate = path_list(logs, "logs"), path_list(validate, "validate")
    except LogError as e:
        raise FitError(str(e)) from None
    if per not in PER:
        raise FitError(f"--per {per} is unknown: use all, group or joint")
    if not logs:
        raise FitError("no log given: pupper fit LOG.csv [LOG.csv ...] (pupper excite writes one)")
    if max_iters < 1:
        raise FitError("--max-iters must be >= 1")
    out_dir = Path(out) if out is not None else None
    if out_dir is not None and out_dir.exists() and not out_dir.is_dir():
        raise FitError(f"--out {out_dir} is a file: give a directory for the run (e.g. runs/fit)")
    if out_dir is not None and out_dir.exists() and any(out_dir.iterdir()) and not force:
        raise FitError(f"{out_dir} exists and is not empty: give another --out, or --force")
    with stop_on_signals("fit"):
        robot = load_robot(model)
        firmware = parse_motor(motor, robot.timestep)
        if firmware is None and any(n in FIRMWARE_ONLY for n in names):
            # the torque's lag and the PD's latency live in the firmware's loop: its replay, ideal otherwise
            firmware = Firmware()
        options = _log_options(columns, kp, kd, held)
        read = _read_logs(logs, robot, *options, pattern=gains_from_name)
        held_out = _read_logs(validate, robot, *options, pattern=gains_from_name, role="validate") if validate else []
        check_apart(read, held_out)
        # only the legs the logs move are stepped (the others, hung from a welded base, do nothing)
        read, robot = narrowed(read, robot)
        read, notes = as_replayed(read, robot.timestep)
        held_out, held_notes = as_replayed(held_out, robot.timestep)
        notes += [f"--validate: {n}" for n in held_notes]
        _check_memory(read, robot, rollouts_per_jacobian(robot, per, len(names)))
        sysid = _sysid()
        started = time.perf_counter()
        # sysid's linear algebra on a degenerate problem divides by zero: the
        # outcome is checked and said below, numpy's warnings would only leak
        with np.errstate(all="ignore"):
            pb = _problem(sysid, robot, read, names, per, firmware)
            told = _Progress(progress)
            sol = _solve(sysid, pb, max_iters, begin, told)
            val = validate_logs(sysid, pb, sol, held_out, names, per) if held_out else None
            drawn = drawn_robots(pb, sol)
        result = _result(pb, sol, out_dir, time.perf_counter() - started, val, per)
        result.robots = drawn
        result.rollouts, result.replay_seconds = told.rollouts, told.once
        result.notes = (notes + pb.notes + _lag_notes(result.table, pb.robot.timestep)
                        + _timing_note(result.table, names, pb.logs, pb.robot.timestep))
        result.delay_scan = sol.scan
        if out_dir is not None:
            _write_run(out_dir, result, pb, sol, model, names, per, force, plot, val)
    return result



def _lag_notes(table: list[dict[str, Any]], timestep: float) -> list[str]:
    """Where the fit found a torque lag: how it reaches a simulation (the
    firmware's, not MuJoCo's servo: that has none to set)."""
    lags = [r for r in table if str(r["parameter"]).partition(".")[0] == "lag"
            and lag_matters(float(r["fitted"]), timestep)]
    if not lags:
        return []
    each = ", ".join(f"{r['parameter']} {float(r['fitted']) * 1e3:.3g} ms" for r in lags)
    return [f"the servo's torque lag ({each}) is in calibrated.xml (pupper:lag numerics): torque mode runs it "
            "(--mode torque), and gains and recommend close the loop through it; MuJoCo's servo (servo mode) has "
            "none"]


def _timing_note(table: list[dict[str, Any]], names: Sequence[str], logs: Sequence[JointLog],
                 timestep: float) -> list[str]:
    """Where the fit read the logs' timing as a command delay alone: at one
    kp a feedback latency (which costs the loop phase) looks the same in
    the logs, so the loop's margins depend on a reading they cannot make."""
    delays = [float(r["fitted"]) for r in table if str(r["parameter"]).partition(".")[0] == "delay"]
    if "latency" in names or not delays or max(delays) <= timestep:
        return []
    kps = {round(float(v), 9) for lg in logs for v in np.ravel(lg.kp)}
    how = ("logs at one kp cannot tell it from a feedback latency, which costs the loop phase (recommend states "
           "the margins under both readings); logs at two kps and --params ...,latency tell them apart"
           if len(kps) < 2 else "add latency to --params: the logs, at two kps, can tell a feedback latency apart")
    return [f"the logs' timing is fitted as a command delay ({max(delays) * 1e3:.3g} ms): {how}"]


def _log_options(columns: Any, kp: Any, kd: Any, held: Any) -> tuple[ColumnMap | None, dict[str, str | None]]:
    """The column map and the header keys a log may leave to the caller
    (numbers Python's or NumPy's, gains one per joint as a list)."""
    try:
        texts = {k: option_text(k, v, "") for k, v in (("columns", columns), ("kp", kp), ("kd", kd), ("held", held))}
        cmap = read_map(texts["columns"]) if texts["columns"] else None
    except LogError as e:
        raise FitError(str(e)) from None
    return cmap, {"kp": texts["kp"], "kd": texts["kd"], "held": texts["held"]}



def _result(pb: _Problem, sol: _Solution, out_dir: Path | None, seconds: float,
            val: Validation | None = None, per: str = "all") -> FitResult:
    from pupper_core._fit.output import _whole_labels

    table = []
    # the actuators each value goes to in calibrated.xml: the whole robot's, where only some legs were stepped
    for i, (name, kind, members, nom) in enumerate(_whole_labels(pb.robot, pb.labels, per)):
        x, h = float(sol.x[i]), float(sol.half[i])
        table.append({"parameter": name, "kind": kind,
                      "actuators": " ".join(pb.robot.full.actuators[k] for k in members),
                      "nominal": nom, "fitted": x, "low95": x - h, "high95": x + h, "unit": PARAMS[kind][0]})
    kept = pb.kept
    res = FitResult(table, {lg.path.name: v for lg, v in zip(pb.logs, sol.before)},
                    {lg.path.name: v for lg, v in zip(pb.logs, sol.after)}, out_dir, seconds,
                    pb.warnings + sol.warnings + _judge(pb, sol, table) + (val.warnings if val else []),
                    [pb.robot.actuators[k] for k in kept], floored=sol.floored, correlation_time=sol.tau,
                    interval_source=sol.source,
                    validation=val.rows if val else [], bode=val.bode if val else [])
    if pb.by_log:
        res.log_actuators = {lg.path.name: [pb.robot.actuators[k] for k in pb.kept_of(i)]
                             for i, lg in enumerate(pb.logs)}
    # per joint or group, motors of one type get a value each: they should agree
    res.warnings += disagreements(fit_entries(res), motor_types(pb.robot.full))
    return res



def _cli_fit(args_json: str) -> list[str]:
    a = json.loads(args_json)
    res = fit(a.pop("logs"), **a)
    # the run directory is whole by now: a stdout that cannot take the table
    # (a full disk) is one line
    with printing():
        width = max(len(r["parameter"]) for r in res.table)
        print(f"{'parameter':<{width}}  {'nominal':>10}  {'fitted':>10}  {'95 % interval':>25}  unit")
        for r in res.table:
            interval = (f"[{r['low95']:>10.4g}, {r['high95']:>10.4g}]" if not math.isnan(r["low95"])
                        else f"{'(not meaningful)':>25}")
            print(f"{r['parameter']:<{width}}  {r['nominal']:>10.4g}  {r['fitted']:>10.4g}  {interval}  {r['unit']}")
        for name in res.rms_before:
            b, f = np.mean(res.rms_before[name]) * 1e3, np.mean(res.rms_after[name]) * 1e3
            n = len(res.actuators_of(name))
            print(f"{name}: RMS angle error {b:.3f} -> {f:.3f} mrad (mean over {n} joint{'s' if n > 1 else ''})")
        if res.validation:
            print_table(res.validation)
        if res.robots is not None:
            r = res.robots
            print(f"robots the logs allow: {len(r.rms)} drawn from the fit's joint distribution (robots.csv); "
                  f"replayed on the logs, the worst's RMS angle error is {max(r.rms) * 1e3:.3f} mrad against the "
                  f"fit's {r.fitted_rms * 1e3:.3f} (x{r.worst_ratio:.2f})")
        for note in res.notes:
            say(f"note: {note}")
        for w in res.warnings:
            say(f"warning: {w}")
        print(f"fitted in {res.seconds:.1f} s")
    if res.out is None:
        return []
    wrote = [str(res.out / n) for n in ("fit.csv", "residuals.csv", "calibrated.xml")]
    if res.validation:
        wrote += [str(res.out / n) for n in ("validation.csv", "validation_bode.csv") if (res.out / n).is_file()]
    if res.robots is not None:
        wrote.append(str(res.out / "robots.csv"))
    if res.warnings:
        wrote.append(str(res.out / "warnings.csv"))
    if (res.out / "plots").is_dir():
        wrote += [str(p) for p in sorted((res.out / "plots").glob("fit_*.png"))]
        wrote += [str(p) for p in sorted((res.out / "plots").glob("validate_*.png"))]
    return wrote + [str(res.out / "report.html")]



def _cli_excite(args_json: str) -> list[str]:
    a = json.loads(args_json)
    path, notes = _excite(a.pop("model", "pupper_v3"), **a)
    for note in notes:
        say(f"note: {note}")
    flush_stdout()
    return [str(path)]
