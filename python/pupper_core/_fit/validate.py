"""`pupper fit --validate`: logs the fit did not use, replayed through the
nominal and the calibrated model, each beside the log's own behaviour.

Per log and logged joint: the RMS angle error of both models, and the
frequency response (``pupper_core._fit.freq``: stepped sines and chirps)
of the log and of both models, from command to angle: gain and phase per
frequency, the -3 dB bandwidth, the phase at a few frequencies and the
delay the model leaves unexplained (the pure delay that best explains the
log's phase lag behind it). The angle error's mean (a constant offset:
an encoder's zero, a load the model does not hang) apart from its RMS
about that mean (the dynamics). A step command (a square wave) is read as
steps instead of sines: the 90 % rise time and the overshoot of log and
models. Written as ``validation.csv`` (a row per log and joint),
``validation_bode.csv`` (a row per log, joint and frequency) and
``plots/validate_<log>.png`` (Bode plot of log, nominal and calibrated,
and the angle error over time)."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core._fit.freq import (Response, StepResponse, bandwidth, delay_left, jumps, phase_at, response,
                                   step_response)
from pupper_core._fit.problem import _Problem, _problem, _Solution, narrowed
from pupper_core._fit.sysid import _predictions
from pupper_core._fit.terms import FitError
from pupper_core._fit.log import JointLog
from pupper_core._spec import PHASE_AT

MODELS = ("log", "nominal", "calibrated")
#: A validated joint whose angle sits this far (rad) from the calibrated model's on average, and whose
#: mean error is most of its RMS error (its square at least OFFSET_SHARE of the mean square), is warned
#: of: a constant offset the fit's parameters do not model.
OFFSET_RAD = 1e-3
OFFSET_SHARE = 0.5


@dataclass
class Trace:
    """One validated joint of one log: the angles over time (log, nominal
    model, calibrated model) and their frequency responses (None: no sines)."""

    log: str
    actuator: str
    t: np.ndarray
    q: dict[str, np.ndarray]
    response: dict[str, Response | None]


@dataclass
class Validation:
    """``rows``: validation.csv's; ``bode``: validation_bode.csv's."""

    rows: list[dict[str, Any]] = field(default_factory=list)
    bode: list[dict[str, Any]] = field(default_factory=list)
    traces: list[Trace] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: the validated logs: path, sha256
    logs: list[tuple[str, str]] = field(default_factory=list)


def check_apart(fitted: list[JointLog], held_out: list[JointLog]) -> None:
    """Refuses a validation log that is one of the fit's (by content: the samples read)."""
    for v in held_out:
        twin = next((lg for lg in fitted if lg.digest == v.digest), None)
        if twin is not None:
            raise FitError(f"--validate {v.path} has the same content as the fitted log {twin.path}: validate on "
                           "logs the fit does not use")


def validate(sysid: Any, pb: _Problem, sol: _Solution, read: list[JointLog], names: list[str],
             per: str) -> Validation:
    """Replays ``read`` through the nominal model and the calibrated one
    (the fit's values; nominal where the fit left a parameter out)."""
    # the validated logs' own legs of the whole robot (they may cover others than the fit's)
    read, robot = narrowed(read, pb.robot.full)
    # the fit's parameters, whatever the validated logs cover
    vpb = _problem(sysid, robot, read, names, per, pb.firmware, several=pb.several)
    fitted = {label[0]: float(v) for label, v in zip(pb.labels, sol.x)}
    x_cal = np.array([fitted.get(label[0], float(x0)) for label, x0 in zip(vpb.labels, vpb.x_nominal)])
    residual_fn = vpb.residual_fn(sysid, None)
    nominal = _predictions(residual_fn, vpb.pdict, vpb.x_nominal)
    calibrated = _predictions(residual_fn, vpb.pdict, x_cal)
    out = Validation(warnings=[f"--validate: {w}" for w in vpb.warnings], logs=[(str(lg.path), lg.sha256) for lg in read])
    for li, (lg, (t, me, p0), (_, _, p1)) in enumerate(zip(read, nominal, calibrated)):
        rel = lg.times - lg.times[0]
        held = np.clip(np.searchsorted(rel, t + 1e-12, side="right") - 1, 0, len(rel) - 1)
        for col, k in enumerate(vpb.kept_of(li)):
            name = vpb.robot.actuators[k]
            q = {"log": me[:, col], "nominal": p0[:, col], "calibrated": p1[:, col]}
            command = lg.target[held, k]
            # a square wave's is a step response: its cycles are no sine's
            step = jumps(command) is not None
            resp = {m: None if step else response(t, command, q[m]) for m in MODELS}
            steps = {m: step_response(t, command, q[m]) if step else None for m in MODELS}
            out.traces.append(Trace(lg.path.name, name, t, q, resp))
            out.rows.append(_row(lg.path.name, name, q, resp, steps))
            out.bode += _bode(lg.path.name, name, resp)
            out.warnings += _said(lg.path.name, name, out.rows[-1], step, resp["log"] is not None)
    return out


def _said(log: str, actuator: str, row: dict[str, Any], step: bool, sines: bool) -> list[str]:
    """What a validated joint's row needs said: no response to read, or an
    error that is mostly a constant offset."""
    said = []
    if not step and not sines:
        said.append(f"{log}: {actuator}'s command holds no sine cycles (a multisine, or no motion): no frequency "
                    "response; validate on stepped sines or chirps (or steps: a square wave)")
    if step and math.isnan(row["rise_time_s_log"]):
        said.append(f"{log}: {actuator}'s command is a step command, but the joint follows none of its jumps: no "
                    "step response")
    off, rms = row["offset_calibrated_rad"], row["rms_calibrated_rad"]
    if abs(off) >= OFFSET_RAD and off ** 2 >= OFFSET_SHARE * rms ** 2:
        said.append(f"{log}: {actuator}'s angle sits {off * 1e3:+.3g} mrad off the calibrated model's on average, "
                    f"most of its {rms * 1e3:.3g} mrad RMS error ({row['rms_dynamic_calibrated_rad'] * 1e3:.3g} mrad "
                    "about the mean): a constant offset the fit does not model (the encoder's zero, or the pose the "
                    "log starts from); validation.csv's offset_* and rms_dynamic_* columns hold both")
    return said


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def _row(log: str, actuator: str, q: dict[str, np.ndarray], resp: dict[str, Response | None],
         steps: dict[str, StepResponse | None]) -> dict[str, Any]:
    """validation.csv's row: the columns of before, then (added at the end,
    for readers of the old ones) the offset, and the step response."""
    row: dict[str, Any] = {"log": log, "actuator": actuator,
                           "rms_nominal_rad": _rms(q["log"], q["nominal"]),
                           "rms_calibrated_rad": _rms(q["log"], q["calibrated"])}
    for m in MODELS:
        r = resp[m]
        row[f"bandwidth_hz_{m}"] = bandwidth(r) if r is not None else math.nan
    for f in PHASE_AT:
        for m in MODELS:
            r = resp[m]
            row[f"phase_{f:g}hz_deg_{m}"] = phase_at(r, f) if r is not None else math.nan
    for m in ("nominal", "calibrated"):
        r, lr = resp[m], resp["log"]
        row[f"delay_left_s_{m}"] = delay_left(lr, r) if r is not None and lr is not None else math.nan
    # the error's mean (measured - simulated) and what is left about it: RMS^2 = mean^2 + dynamic^2
    for m in ("nominal", "calibrated"):
        row[f"offset_{m}_rad"] = float(np.mean(q["log"] - q[m]))
    for m in ("nominal", "calibrated"):
        row[f"rms_dynamic_{m}_rad"] = float(np.std(q["log"] - q[m]))
    for m in MODELS:
        row[f"rise_time_s_{m}"] = sr.rise_time if (sr := steps[m]) is not None else math.nan
    for m in MODELS:
        row[f"overshoot_pct_{m}"] = sr.overshoot_pct if (sr := steps[m]) is not None else math.nan
    return row


def _bode(log: str, actuator: str, resp: dict[str, Response | None]) -> list[dict[str, Any]]:
    r0 = resp["log"]
    if r0 is None:
        return []
    rows = []
    for i, f in enumerate(r0.freq):
        row: dict[str, Any] = {"log": log, "actuator": actuator, "frequency_hz": float(f)}
        for m in MODELS:
            r = resp[m]
            row[f"gain_{m}"] = float(r.gain[i]) if r is not None else math.nan
            row[f"phase_deg_{m}"] = float(r.phase[i]) if r is not None else math.nan
        rows.append(row)
    return rows


def is_step(row: dict[str, Any]) -> bool:
    """A row of a step command's log: its step response read, no sines."""
    return math.isfinite(row.get("rise_time_s_log", math.nan)) and math.isnan(row["bandwidth_hz_log"])


def print_table(rows: list[dict[str, Any]]) -> None:
    """The validation tables: the sines' (frequency response), then the
    steps' (rise time, overshoot), a line per log and joint."""
    if sines := [r for r in rows if not is_step(r)]:
        _print_sines(sines)
    if steps := [r for r in rows if is_step(r)]:
        _print_steps(steps)


def _print_steps(rows: list[dict[str, Any]]) -> None:
    log_w = max([len("step log")] + [len(r["log"]) for r in rows])
    act_w = max([len("joint")] + [len(r["actuator"]) for r in rows])
    print(f"{'step log':<{log_w}}  {'joint':<{act_w}}  {'RMS error (mrad)':>18}  {'offset (mrad)':>17}  "
          f"{'rise time (ms)':>20}  {'overshoot (%)':>20}")
    print(f"{'':<{log_w}}  {'':<{act_w}}  {'nominal':>8} {'calib.':>9}  {'nominal':>8} {'calib.':>8}  "
          f"{'log':>6} {'nom.':>6} {'calib.':>6}  {'log':>6} {'nom.':>6} {'calib.':>6}")
    for r in rows:
        print(f"{r['log']:<{log_w}}  {r['actuator']:<{act_w}}  {r['rms_nominal_rad'] * 1e3:>8.2f} "
              f"{r['rms_calibrated_rad'] * 1e3:>9.2f}  {r['offset_nominal_rad'] * 1e3:>8.2f} "
              f"{r['offset_calibrated_rad'] * 1e3:>8.2f}  "
              + " ".join(f"{r[f'rise_time_s_{m}'] * 1e3:>6.1f}" for m in MODELS) + "  "
              + " ".join(f"{r[f'overshoot_pct_{m}']:>6.1f}" for m in MODELS))


def _print_sines(rows: list[dict[str, Any]]) -> None:
    log_w = max([len("validated log")] + [len(r["log"]) for r in rows])
    act_w = max([len("joint")] + [len(r["actuator"]) for r in rows])
    print(f"{'validated log':<{log_w}}  {'joint':<{act_w}}  {'RMS error (mrad)':>18}  "
          f"{'-3 dB (Hz)':>20}  {'phase at 10 Hz (deg)':>22}  {'delay left (ms)':>17}")
    print(f"{'':<{log_w}}  {'':<{act_w}}  {'nominal':>8} {'calib.':>9}  {'log':>6} {'nom.':>6} {'calib.':>6}  "
          f"{'log':>6} {'nom.':>7} {'calib.':>7}  {'nom.':>8} {'calib.':>8}")
    for r in rows:
        print(f"{r['log']:<{log_w}}  {r['actuator']:<{act_w}}  {r['rms_nominal_rad'] * 1e3:>8.2f} "
              f"{r['rms_calibrated_rad'] * 1e3:>9.2f}  {r['bandwidth_hz_log']:>6.2f} {r['bandwidth_hz_nominal']:>6.2f} "
              f"{r['bandwidth_hz_calibrated']:>6.2f}  {r['phase_10hz_deg_log']:>6.1f} "
              f"{r['phase_10hz_deg_nominal']:>7.1f} {r['phase_10hz_deg_calibrated']:>7.1f}  "
              f"{r['delay_left_s_nominal'] * 1e3:>8.2f} {r['delay_left_s_calibrated'] * 1e3:>8.2f}")


def write(out: Path, v: Validation) -> None:
    """validation.csv, validation_bode.csv and the Bode plots."""
    from pupper_core._rundir import atomic_write

    for name, rows in (("validation.csv", v.rows), ("validation_bode.csv", v.bode)):
        if not rows:
            continue

        def table(tmp: Path, rows: list[dict[str, Any]] = rows) -> None:
            with tmp.open("w", newline="", errors="surrogateescape") as f:
                w = csv.writer(f, lineterminator="\n")
                w.writerow(list(rows[0]))
                for r in rows:
                    w.writerow([repr(float(x)) if isinstance(x, float) else x for x in r.values()])

        atomic_write(out / name, table)
    _plot(out, v)


def _plot(out: Path, v: Validation) -> None:
    """plots/validate_<log>.png: per joint, the gain and phase of log,
    nominal and calibrated against frequency, and both models' angle error
    over time (``pupper_core.plots.fit`` draws them)."""
    from pupper_core.plots.fit import write_validation

    write_validation(out, v.traces)
