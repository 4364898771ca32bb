"""A fit's data (``pupper_core._fit`` solves it): the logs read and
checked, the problem they set (sysid's sequences, the parameters at their
nominal values, the signals compared), where the fit ended, and its result."""

from __future__ import annotations

import math

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core._fit.replay import Firmware
from pupper_core._fit.cover import differ, parameter_sets, sensors_by_log
from pupper_core._fit.robot import Robot, initial_state, narrow, suspended_spec
from pupper_core._fit.sysid import _held, _modifier, _residual_by_log, _residual_fn
from pupper_core._fit.terms import MAX_LOG_SECONDS, PARAMS, STILL_RAD, FitError
from pupper_core._fit.log import JointLog, LogError, read_log
from pupper_core._fit.columns import ColumnMap, read_map
from pupper_core._fit.specs import LogSpec, gains_in_name, log_specs, name_pattern


@dataclass
class FitResult:
    """What `fit` found: ``table`` is fit.csv's rows; ``rms_before`` and
    ``rms_after`` the RMS angle error (rad) of each log, per actuator."""

    table: list[dict[str, Any]]
    rms_before: dict[str, list[float]]
    rms_after: dict[str, list[float]]
    out: Path | None
    seconds: float
    warnings: list[str] = field(default_factory=list)
    #: the actuators fitted (a joint that never moves is left out)
    actuators: list[str] = field(default_factory=list)
    #: the intervals assume NOISE_FLOOR: the residual was below it (noise-free logs)
    floored: bool = False
    #: the residual's correlation time (samples): the intervals are widened by its square root
    correlation_time: float = 1.0
    #: where the intervals come from: "noise" (the residual is the sensors'), "model error" (structure
    #: the model cannot follow: the segments' spread, ``_fit_intervals``), "floored", "none"
    interval_source: str = "noise"
    #: validation.csv's rows: per validated log and joint (``validate``)
    validation: list[dict[str, Any]] = field(default_factory=list)
    #: validation_bode.csv's rows: per validated log, joint and frequency
    bode: list[dict[str, Any]] = field(default_factory=list)
    #: what the replay did with the logs that the user should know (not a doubt about the fit)
    notes: list[str] = field(default_factory=list)
    #: the delay scan the fit started from (``_fit_start``): its grid (s), costs and the starts taken
    delay_scan: dict[str, Any] = field(default_factory=dict)
    #: where the logs cover different actuators: the ones each log's RMS errors are of (else ``actuators``)
    log_actuators: dict[str, list[str]] = field(default_factory=dict)
    #: the robots the logs allow (``robots``): draws from the fit's joint distribution, replayed on the logs
    robots: Any = None
    #: what the fit cost: the rollouts of a log it ran, and one replay of every log (s)
    rollouts: int = 0
    replay_seconds: float = math.nan

    def actuators_of(self, log: str) -> list[str]:
        """The actuators log ``log``'s RMS errors are of."""
        return self.log_actuators.get(log, self.actuators)

    def value(self, name: str) -> float:
        return next(float(r["fitted"]) for r in self.table if r["parameter"] == name)

    def interval(self, name: str) -> tuple[float, float]:
        r = next(r for r in self.table if r["parameter"] == name)
        return float(r["low95"]), float(r["high95"])


@dataclass
class _Problem:
    """A fit set up: the logs as sysid sequences, what is fitted, the
    parameters at their nominal values and what was left out (said)."""

    robot: Robot
    logs: list[JointLog]
    sequences: list[Any]
    pdict: Any
    labels: list[tuple[str, str, list[int], float]]
    x_nominal: np.ndarray
    #: the enabled sensors, as indices into (angles, velocities, torques) x actuators
    sensors: list[int]
    gains: dict[int, tuple[np.ndarray, np.ndarray]]
    warnings: list[str] = field(default_factory=list)
    #: the servo firmware the replay runs through (--motor); None: MuJoCo's servo
    firmware: Firmware | None = None
    #: each log's compared signals where the logs cover different actuators (``cover``); empty: every
    #: log compares ``sensors``
    by_log: list[list[int]] = field(default_factory=list)
    #: the parameters of a fit of several motors' logs (``cover.parameter_sets``)
    several: bool = False
    #: what the set-up did that the user should know (not a doubt about the fit)
    notes: list[str] = field(default_factory=list)

    @property
    def kept(self) -> list[int]:
        """The actuators whose angle is fitted."""
        nu = len(self.robot.actuators)
        return [s for s in self.sensors if s < nu]

    def sensors_of(self, log: int) -> list[int]:
        """The signals log ``log`` compares."""
        return self.by_log[log] if self.by_log else self.sensors

    def kept_of(self, log: int) -> list[int]:
        """The actuators whose angle log ``log`` compares."""
        nu = len(self.robot.actuators)
        return [s for s in self.sensors_of(log) if s < nu]

    def enabled(self, sysid: Any, log: int | None = None) -> list[Any]:
        """The enabled sensors (of one log, or of all) as sysid's observations, in the model's order."""
        names = [x.name for x in self.sequences[0].spec.sensors]
        on = self.sensors if log is None else self.sensors_of(log)
        return [(s.name, sysid.SignalType.MjSensor) for s in self.sequences[0].spec.sensors
                if names.index(s.name) in on]

    def residual_fn(self, sysid: Any, weights: np.ndarray | None, firmware: Firmware | None = None) -> Any:
        """sysid's residual over every log (``weights``: by position among
        ``sensors``), through ``firmware`` (default the problem's): each log
        on its own signals where they differ."""
        fw = firmware if firmware is not None else self.firmware
        if not self.by_log:
            return _residual_fn(sysid, self.sequences, self.enabled(sysid), weights, fw)
        at = {s: p for p, s in enumerate(self.sensors)}
        own = [None if weights is None else np.asarray(weights)[[at[s] for s in mine]] for mine in self.by_log]
        return _residual_by_log(sysid, self.sequences, [self.enabled(sysid, i) for i in range(len(self.logs))],
                                own, fw)


@dataclass
class _Solution:
    """Where the fit ended: the values, the interval half-widths (NaN where
    not meaningful), the correlations, the RMS angle errors."""

    x: np.ndarray
    half: np.ndarray
    corr: np.ndarray | None
    residual_fn: Any
    params: Any
    before: list[list[float]]
    after: list[list[float]]
    floored: bool
    warnings: list[str]
    #: the residual's correlation time (samples) the intervals were widened by
    tau: float = 1.0
    #: the delay scan before the fit (``_fit_start``): its grid, costs and the starts taken
    scan: dict[str, Any] = field(default_factory=dict)
    #: where the intervals come from: "noise", "model error" (``_fit_intervals``), "floored", "none"
    source: str = "noise"
    #: the residual's Jacobian where the fit ended (None where it kept the nominal values)
    jac: np.ndarray | None = None


def _read_logs(paths: Sequence[Any], robot: Robot, columns: ColumnMap | None = None,
               defaults: dict[str, str | None] | None = None, *, pattern: str | None = None,
               role: str = "fit") -> list[JointLog]:
    """Reads and checks every log (``_log_specs``: a path, LOG::OPTIONS,
    @LIST; through its column map, with the header keys ``defaults`` and
    the gains its name states by ``pattern``, for a log that does not say
    them), widens each to the model's actuators, and refuses the same
    recording given twice. ``role``: "fit", or "validate", whose logs run
    at gains of their own: --kp and --kd are not theirs."""
    flag = "--validate" if role == "validate" else "LOG"
    try:
        specs = log_specs(paths, flag)
        rx = name_pattern(pattern) if pattern else None
    except LogError as e:
        raise FitError(str(e)) from None
    read: list[JointLog] = []
    for spec in specs:
        try:
            lg = read_log(spec.path, robot.ranges, **_sources(spec, columns, defaults or {}, rx, pattern, role))
        except LogError as e:
            raise FitError(str(e)) from None
        _check_log(lg, robot)
        lg = _widen(lg, robot)
        twin = next((x for x in read if x.digest == lg.digest), None)
        if twin is not None:
            # a copy adds no information, yet would narrow every interval: by the samples read, so
            # that the same recording compressed, with a BOM or CRLF, or other columns, is one
            how = (f"sha256 {lg.sha256[:12]}" if twin.sha256 == lg.sha256
                   else "the same samples in other bytes")
            raise FitError(f"{lg.path} has the same content as {twin.path} ({how}): give each log once")
        read.append(lg)
    return read


def _sources(spec: LogSpec, columns: ColumnMap | None, defaults: dict[str, str | None], rx: Any,
             pattern: str | None, role: str) -> dict[str, Any]:
    """read_log's keywords for one log: its column map (its own
    ``columns=`` in place of --columns), what states its gains and held
    angles (its own options, its name, the flags: each must agree with the
    log's header), and what to say when none does."""
    own = spec.options
    cmap = read_map(own["columns"], spec.base, f"{spec.given}::columns") if "columns" in own else columns
    stated: dict[str, list[tuple[str, str]]] = {}
    for key in ("kp", "kd", "held"):
        if key in own:
            stated.setdefault(key, []).append((own[key], f"{spec.given}::{key}={own[key]}"))
    in_name = gains_in_name(rx, str(pattern), spec.path.name) if rx is not None else {}
    for key, v in in_name.items():
        stated.setdefault(key, []).append((v, f"{key} {v} in its name (--gains-from-name '{pattern}')"))
    for key, flag in defaults.items():
        # --kp/--kd are the fitted logs' gains; a validation log runs at its own
        if flag is None or (role == "validate" and key in ("kp", "kd")) or (key == "held" and "held" in own):
            continue
        stated.setdefault(key, []).append((flag, f"--{key} {flag}"))
    by_name = (f" (its name does not match --gains-from-name '{pattern}')" if rx is not None
               else ", or --gains-from-name 'kp_{kp}_kd_{kd}' to read them from its name")
    if role == "validate":
        advice = (f"a --validate log runs at gains of its own (--kp and --kd are the fitted logs'): give "
                  f"'{spec.given}::kp=K,kd=D', '# kp:' and '# kd:' lines above its header{by_name}")
    else:
        advice = (f"give --kp K --kd D (every log), '{spec.given}::kp=K,kd=D' (this one), '# kp:' and '# kd:' "
                  f"lines above its header{by_name}")
    return {"columns": cmap, "stated": stated, "advice": advice}


def _widen(lg: JointLog, robot: Robot) -> JointLog:
    """The log over every actuator of the model, in its order: one it does
    not cover holds the angle ``held`` gives (else the model's rest pose)
    at the log's gains (their median where they differ), its columns
    constant; ``logged`` names the ones the file covers."""
    n, nu = len(lg.times), len(robot.actuators)
    cols = {a: k for k, a in enumerate(lg.actuators)}

    def wide(values: np.ndarray | None, other: np.ndarray) -> np.ndarray | None:
        if values is None:
            return None
        out = np.tile(other, (n, 1))
        for i, a in enumerate(robot.actuators):
            if a in cols:
                out[:, i] = values[:, cols[a]]
        return out

    rest = np.array([lg.held.get(a, lg.held.get("", robot.rest[i])) for i, a in enumerate(robot.actuators)])
    gain = [np.array([g[cols[a]] if a in cols else float(np.median(g)) for a in robot.actuators])
            for g in (lg.kp, lg.kd)]
    target, q = wide(lg.target, rest), wide(lg.q, rest)
    assert target is not None and q is not None
    return JointLog(lg.path, lg.times, list(robot.actuators), target, q, wide(lg.qd, np.zeros(nu)),
                    wide(lg.tau, np.zeros(nu)), gain[0], gain[1], lg.mode, lg.base, lg.sha256, lg.held,
                    [a for a in robot.actuators if a in cols], digest=lg.digest)


def narrowed(read: list[JointLog], robot: Robot) -> tuple[list[JointLog], Robot]:
    """The logs and the robot the replay steps: only the legs some log
    covers (``_fit_robot.narrow``), each log's columns of those."""
    from dataclasses import replace

    part = narrow(robot, {a for lg in read for a in lg.logged})
    if part is robot:
        return read, robot
    out = []
    for lg in read:
        cols = [lg.actuators.index(a) for a in part.actuators]
        out.append(replace(lg, actuators=list(part.actuators), target=lg.target[:, cols], q=lg.q[:, cols],
                           qd=None if lg.qd is None else lg.qd[:, cols], tau=None if lg.tau is None else lg.tau[:, cols],
                           kp=lg.kp[cols], kd=lg.kd[cols], logged=[a for a in lg.logged if a in part.actuators]))
    return out, part


#: Rows whose angles interpolate at least this much better evenly spaced than at their stamps were
#: taken evenly (the stamps are the logger's clock, jittered).
EVEN_RATIO = 0.5
#: A velocity column lags its angles' derivative by at least this fraction of a sample to be advanced.
LAG_SAMPLES = 0.5
#: ... and matches the shifted derivative within this RMS fraction of its own size.
LAG_FIT = 0.3


def as_replayed(read: list[JointLog], dt: float) -> tuple[list[JointLog], list[str]]:
    """The logs as the replay reads them, and a note for what it changed:
    rows taken evenly where their angles say so (``_even``), a velocity
    column advanced by the lag it shows behind its angles
    (``_velocity_lag``); ``dt``: the model's timestep."""
    from dataclasses import replace

    out: list[JointLog] = []
    evened: list[tuple[str, float, float]] = []
    lagged: list[tuple[str, float]] = []
    for lg in read:
        even = _even(lg)
        if even is not None:
            t, jitter = even
            evened.append((lg.path.name, jitter, float(np.mean(np.diff(lg.times)))))
            lg = replace(lg, times=t)
        lag = _velocity_lag(lg, dt)
        if lag and lg.qd is not None:
            t = lg.times
            qd = np.stack([np.interp(t + lag, t, lg.qd[:, k]) for k in range(lg.qd.shape[1])], axis=1)
            lagged.append((lg.path.name, lag))
            lg = replace(lg, qd=qd)
        out.append(lg)
    notes = []
    if evened:
        jitter = _span([j * 1e3 for _, j, _ in evened])
        period = _span([p * 1e3 for _, _, p in evened], ".2f")
        notes.append(f"{_names([n for n, _, _ in evened])}: the angles change smoothly from row to row but not at "
                     f"their time stamps (which jitter by {jitter} ms RMS about an even {period} ms): the rows are "
                     "replayed evenly spaced, the stamps taken as the logger's clock")
    if lagged:
        notes.append(f"{_names([n for n, _ in lagged])}: the velocity runs {_span([g * 1e3 for _, g in lagged])} ms "
                     "behind the angles' own derivative (an estimate from older samples): it is compared with the "
                     "model's velocity that much earlier")
    return out, notes


def _names(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def _span(values: list[float], fmt: str = ".1f") -> str:
    lo, hi = f"{min(values):{fmt}}", f"{max(values):{fmt}}"
    return lo if lo == hi else f"{lo} to {hi}"


def _moving(lg: JointLog) -> list[int]:
    cols = [lg.actuators.index(a) for a in (lg.logged or lg.actuators)]
    return [c for c in cols if float(np.ptp(lg.q[:, c])) > STILL_RAD]


def _even(lg: JointLog) -> tuple[np.ndarray, float] | None:
    """Even times for a log whose rows were taken evenly though stamped
    unevenly, and the stamps' RMS jitter; None where the stamps are even or
    the angles follow them. Each angle between its neighbours is
    interpolated by the stamps and by the rows' order: a loop that samples
    its motors on time but stamps late (a ROS clock read when the callback
    runs) gives angles smooth in rows, not in stamps (a Pupper's bench
    log: a third of the error in rows)."""
    t = lg.times
    steps = np.diff(t)
    if len(t) < 10 or float(np.ptp(steps)) <= 1e-6 * float(np.mean(steps)):
        return None
    cols = _moving(lg)
    if not cols:
        return None
    q = lg.q[:, cols]
    a, b, c = q[:-2], q[1:-1], q[2:]
    frac = ((t[1:-1] - t[:-2]) / (t[2:] - t[:-2]))[:, None]
    stamped = float(np.sum((b - (a + (c - a) * frac)) ** 2))
    rows = float(np.sum((b - 0.5 * (a + c)) ** 2))
    if not rows < EVEN_RATIO ** 2 * stamped:
        return None
    even = np.linspace(t[0], t[-1], len(t))
    return even, float(np.sqrt(np.mean((t - even) ** 2)))


def _velocity_lag(lg: JointLog, dt: float) -> float:
    """How far (s) the velocity column runs behind the model's velocity:
    its lag behind the angles' central derivative, less the half step by
    which MuJoCo's velocity (the last step's difference) runs behind it
    too; 0 where that is under LAG_SAMPLES of a sample or the column does
    not match the shifted derivative within LAG_FIT. One lag for every
    column of the log (the loop's estimate is the same for each motor)."""
    if lg.qd is None:
        return 0.0
    cols = _moving(lg)
    if not cols:
        return 0.0
    t = lg.times
    period = float(np.mean(np.diff(t)))
    dq = np.stack([np.gradient(lg.q[:, c], t) for c in cols], axis=1)
    qd = lg.qd[:, cols]
    size = float(np.sum(qd ** 2))
    if not size > 0:
        return 0.0
    shifts = np.arange(0.0, 6 * period, period / 20)

    def err(s: float) -> float:
        moved = np.stack([np.interp(t - s, t, dq[:, k]) for k in range(dq.shape[1])], axis=1)
        return float(np.sum((qd - moved) ** 2))

    errs = np.array([err(float(s)) for s in shifts])
    k = int(np.argmin(errs))
    lag = float(shifts[k]) - 0.5 * dt
    if lag < LAG_SAMPLES * period or errs[k] > LAG_FIT ** 2 * size:
        return 0.0
    return lag


def _check_log(lg: JointLog, robot: Robot) -> None:
    if lg.base != "suspended":
        raise FitError(f"{lg.path}: '# base: {lg.base}': fit replays logs of the robot hung in "
                       "the air (base: suspended); standing logs are not supported yet")
    if lg.duration <= PARAMS["delay"][2] * 4:
        raise FitError(f"{lg.path}: the log spans {lg.duration:g} s, too short for the delay "
                       f"range (0 to {PARAMS['delay'][2]:g} s): log at least a few seconds")
    # uneven samples are replayed at their own instants: the mean spacing is the rate
    spacing = float(np.mean(np.diff(lg.times)))
    # samples a second or more apart, which in ms would be a servo's rate
    ms = (f" (its samples are {spacing:g} apart: the time column looks like milliseconds; divide it "
          "by 1000)") if 1e-4 <= spacing / 1000 <= 0.1 and spacing >= 0.5 else ""
    if lg.duration > MAX_LOG_SECONDS:
        raise FitError(f"{lg.path}: the log spans {lg.duration:.4g} s, past the {MAX_LOG_SECONDS:g} s "
                       f"fit takes{ms}: times are in s; split a longer recording")
    idx = [robot.actuators.index(a) for a in lg.actuators]
    hz = np.asarray(robot.inertia)[idx]
    hz = np.sqrt(lg.kp / hz) / (2 * np.pi)
    k = int(np.argmax(hz))
    if 1 / spacing < 2 * hz[k]:
        # the samples cannot show a motion faster than half their rate
        raise FitError(f"{lg.path}: sampled at {1 / spacing:.3g} Hz, too slow for the joints' dynamics{ms}: "
                       f"at the log's kp {lg.kp[k]:g} {lg.actuators[k]} swings at {hz[k]:.3g} Hz, "
                       f"past half the sample rate; log at {10 * hz[k]:.0f} Hz or more")


def _problem(sysid: Any, robot: Robot, read: list[JointLog], names: list[str], per: str,
             firmware: Firmware | None = None, several: bool | None = None) -> _Problem:
    """The problem ``read`` sets; ``several``: the parameters of a fit of
    several motors' logs (``cover``; default: where the logs cover
    different actuators, as a validation of such a fit is given)."""
    nu = len(robot.actuators)
    has_tau = all(lg.tau is not None for lg in read)
    has_qd = all(lg.qd is not None for lg in read)
    by_log: list[list[int]] = []
    notes: list[str] = []
    if differ(read):
        # each log on the actuators it logs
        sensors, by_log, warnings, notes = sensors_by_log(robot, read, has_qd, has_tau)
    else:
        sensors, warnings = _enabled_sensors(robot, read, has_qd, has_tau)
    several = differ(read) if several is None else several
    # one spec per gain setting: its actuators run at the logged gains
    specs: dict[tuple[bytes, bytes], Any] = {}
    gains: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    sequences = []
    for li, lg in enumerate(read):
        order = _order(lg, robot)
        kp, kd = lg.kp[order], lg.kd[order]
        key = (kp.tobytes(), kd.tobytes())
        if key not in specs:
            spec = suspended_spec(robot, kp, kd, firmware=firmware is not None)
            specs[key] = spec
            gains[id(spec)] = (kp, kd)
        spec = specs[key]
        # the model steps at its own timestep; sysid resamples the logged
        # targets to it and the predictions to the log's times
        m = spec.compile()
        t = lg.times - lg.times[0]
        target = lg.target[:, order]
        q = lg.q[:, order]
        cols = [q, lg.qd[:, order] if lg.qd is not None and has_qd else np.zeros_like(q),
                lg.tau[:, order] if lg.tau is not None and has_tau else np.zeros_like(q)]
        y = np.hstack(cols)
        # the start: where the robot rests when the log begins on a hold
        # (the mean of its first samples, less noise than one)
        held = int(np.argmax(np.any(target != target[0], axis=1))) or len(target)
        n0 = max(1, min(held, round(0.01 / float(np.mean(np.diff(t))))))
        q0 = q[:n0].mean(axis=0) if held >= n0 and not has_qd else q[0]
        qd0 = cols[1][0] if has_qd else np.zeros(nu)
        x0 = initial_state(m, robot, q0, qd0, target[0])
        unlogged = [k for k, a in enumerate(robot.actuators) if a not in lg.logged]
        if unlogged and len(unlogged) < nu:
            # through the firmware the actuators are torque motors: the joints settle under a servo at the
            # log's gains (a torque of the target's value let them hang limp, and jump at the log's start)
            servo = suspended_spec(robot, kp, kd).compile() if firmware is not None else m
            x0 = _settled(m, x0, robot, [k for k in range(nu) if k not in unlogged], q0, qd0, target[0], servo)
        control = sysid.TimeSeries.from_control_names(*_held(t, target, m.opt.timestep), m)
        measured = sysid.TimeSeries.from_names(t, y, m)
        sequences.append(sysid.ModelSequences(f"log{li}", spec, lg.path.stem, x0, control, measured))
    kept = {s for s in sensors if s < nu}
    logged = _logged(robot, read, every=not by_log)
    pdict, labels, x_nominal = _parameters(sysid, robot, names, per, gains, kept, logged, warnings,
                                           firmware is not None, several)
    return _Problem(robot, read, sequences, pdict, labels, x_nominal, sensors, gains, warnings, firmware, by_log,
                    several, notes)


#: How long (s) the joints a log does not cover settle at their targets before it starts.
SETTLE_S = 1.0


def _settled(m: Any, x0: np.ndarray, robot: Robot, logged: list[int], q0: np.ndarray, qd0: np.ndarray,
             target0: np.ndarray, servo: Any = None) -> np.ndarray:
    """The start with the joints a log does not cover where they rest: held
    at their targets, they sag under gravity (mrad at kp 5), and started at
    the targets themselves they sagged during the log and moved the logged
    joints with them (5 µrad off a noise-free log's own replay, past the
    intervals' noise floor). They settle for SETTLE_S with the first target
    held by ``servo`` (the robot with servo actuators at the log's gains:
    ``m`` itself, unless its actuators are the firmware's torque motors);
    the logged joints then start where the log says."""
    import mujoco
    from mujoco import rollout

    servo = m if servo is None else servo
    start = x0 if servo is m else initial_state(servo, robot, q0, qd0, target0)
    hold = np.tile(target0, (max(int(round(SETTLE_S / servo.opt.timestep)), 1), 1))
    state, _ = rollout.rollout(servo, mujoco.MjData(servo), start, hold)
    d = mujoco.MjData(servo)
    mujoco.mj_setState(servo, d, np.asarray(state[0, -1]), mujoco.mjtState.mjSTATE_FULLPHYSICS)
    q, qd = np.array(q0, dtype=float), np.array(qd0, dtype=float)
    for k, j in enumerate(robot.joints):
        if k not in logged:
            jid = mujoco.mj_name2id(servo, mujoco.mjtObj.mjOBJ_JOINT, j)
            q[k], qd[k] = d.qpos[servo.jnt_qposadr[jid]], d.qvel[servo.jnt_dofadr[jid]]
    # a fresh start there (time 0, the command history holding the first target)
    return initial_state(m, robot, q, qd, target0)


def _order(lg: JointLog, robot: Robot) -> list[int]:
    """A log's columns in the model's actuator order (a widened log's are)."""
    return [lg.actuators.index(a) for a in robot.actuators]


def _logged(robot: Robot, read: list[JointLog], every: bool = True) -> set[int]:
    """The actuators every log covers (or, not ``every``, some log)."""
    test = all if every else any
    return {k for k, a in enumerate(robot.actuators) if test(a in lg.logged for lg in read)}


def _enabled_sensors(robot: Robot, read: list[JointLog], has_qd: bool,
                     has_tau: bool) -> tuple[list[int], list[str]]:
    """The signals the fit compares, where every log covers the same
    actuators (``cover.sensors_by_log`` where they differ): a joint whose
    angle never moves shows nothing (and sysid, which divides each signal
    by its size, would divide by zero), so it is left out, as is a velocity
    or torque column that is all zero; each is said. Refuses a fit with
    nothing left."""
    nu = len(robot.actuators)
    warnings: list[str] = []
    logged = _logged(robot, read)
    still: dict[int, JointLog] = {}
    for lg in read:
        for k, c in enumerate(_order(lg, robot)):
            if k in logged and k not in still and float(np.ptp(lg.q[:, c])) <= STILL_RAD:
                still[k] = lg
    for k, lg in sorted(still.items()):
        warnings.append(f"{robot.actuators[k]} never moves in {lg.path.name} (its angle stays at "
                        f"{lg.q[0, _order(lg, robot)[k]]:.6g} rad): left out of the fit")
    if len(still) == len(logged):
        raise FitError(f"no joint moves in {', '.join(sorted({lg.path.name for lg in still.values()}))} "
                       "(every angle column is constant): nothing to fit; log a run where the joints "
                       "move (pupper excite writes its targets)")
    sensors = [k for k in range(nu) if k in logged and k not in still]
    for block, fld, on in ((1, "qd", has_qd), (2, "tau", has_tau)):
        for k in (k for k in range(nu) if on and k in logged and k not in still):
            zero = next((lg for lg in read if not np.any(getattr(lg, fld)[:, _order(lg, robot)[k]])), None)
            if zero is not None:
                warnings.append(f"{zero.path.name}: column '{robot.actuators[k]}.{fld}' is all zero: left "
                                "out of the fit (drop the column if the servo does not report it)")
            else:
                sensors.append(block * nu + k)
    return sensors, warnings


def _parameters(sysid: Any, robot: Robot, names: list[str], per: str, gains: dict[int, tuple[np.ndarray, np.ndarray]],
                kept: set[int], logged: set[int], warnings: list[str], firmware: bool = False,
                several: bool = False) -> tuple[Any, list[tuple[str, str, list[int], float]], np.ndarray]:
    """The parameters at their nominal values (the vector returned, before
    sysid moves those on a bound inside for its start); a set of joints no
    log covers is not fitted, silently (the logs say what they cover).
    ``several``: a fit of several motors' logs (``cover.parameter_sets``)."""
    pdict = sysid.ParameterDict()
    nominal = {"armature": robot.armature, "damping": robot.damping, "frictionloss": robot.frictionloss,
               "torque_limit": robot.limits}
    labels: list[tuple[str, str, list[int], float]] = []
    for kind in names:
        for suffix, members in parameter_sets(robot, kind, per, several):
            if not kept.intersection(members):
                if not logged.intersection(members):
                    continue
                warnings.append(f"{kind + suffix} is not fitted: none of its joints moves")
                continue
            if kind in nominal:
                values = nominal[kind][members]
                nom = float(values[0]) if np.all(values == values[0]) else float(np.mean(values))
            else:
                nom = 1.0 if "scale" in kind else 0.0
            _, lo, hi = PARAMS[kind]
            modifier = _modifier(kind, members, robot, gains, firmware)
            pdict.add(sysid.Parameter(kind + suffix, nom, lo, max(hi, 4 * nom), modifier=modifier))
            labels.append((kind + suffix, kind, members, nom))
    x_nominal = pdict.as_vector().copy()
    pdict.move_off_bounds()
    return pdict, labels, x_nominal
