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
from pupper_core._fit.firmware import Firmware, parse_motor
from pupper_core._fit.jacobian import jacobian_fn, rollouts_per_jacobian
from pupper_core._fit.output import _write_run
from pupper_core._fit.problem import FitResult, _Problem, _problem, _read_logs, _Solution, as_replayed, narrowed
from pupper_core._fit.robot import BUILTINS as BUILTINS
from pupper_core._fit.robot import initial_state as initial_state
from pupper_core._fit.robot import simulate as simulate
from pupper_core._fit.robot import Robot, load_robot, suspended_spec
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
            sol = _solve(sysid, pb, max_iters, begin, _Progress(progress))
            val = validate_logs(sysid, pb, sol, held_out, names, per) if held_out else None
        result = _result(pb, sol, out_dir, time.perf_counter() - started, val, per)
        result.notes = notes
        result.delay_scan = sol.scan
        if out_dir is not None:
            _write_run(out_dir, result, pb, sol, model, names, per, force, plot, val)
    return result


def _log_options(columns: Any, kp: Any, kd: Any, held: Any) -> tuple[ColumnMap | None, dict[str, str | None]]:
    """The column map and the header keys a log may leave to the caller
    (numbers Python's or NumPy's, gains one per joint as a list)."""
    try:
        texts = {k: option_text(k, v, "") for k, v in (("columns", columns), ("kp", kp), ("kd", kd), ("held", held))}
        cmap = read_map(texts["columns"]) if texts["columns"] else None
    except LogError as e:
        raise FitError(str(e)) from None
    return cmap, {"kp": texts["kp"], "kd": texts["kd"], "held": texts["held"]}


def _memory_limit() -> float:
    """The bytes a fit may allocate: a fraction of the machine's memory."""
    try:
        total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        total = 16 * 2**30
    return MEMORY_FRACTION * float(total)


def _check_memory(read: list[JointLog], robot: Robot, n_rollouts: int) -> None:
    """Refuses a fit whose rollouts would not fit in memory, before any is
    allocated: every Jacobian rolls each log out once per perturbed rollout
    (a parameter; per joint, one on every leg at once) and once more,
    keeping the full state and the sensors of every physics step, and sysid
    copies them (MEMORY_COPIES)."""
    import mujoco

    m = suspended_spec(robot, read[0].kp, read[0].kd).compile()
    per_step = 8 * (mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS) + m.nsensordata)
    steps = sum(lg.duration / min(robot.timestep, float(np.mean(np.diff(lg.times)))) + 1 for lg in read)
    need = per_step * steps * (n_rollouts + 1) * MEMORY_COPIES
    limit = _memory_limit()
    if need > limit:
        raise FitError(f"the fit would allocate about {_size(need)} ({len(read)} log(s), {steps:,.0f} physics "
                       f"steps, {n_rollouts + 1} rollouts of each per Jacobian), past {_size(limit)} "
                       f"({MEMORY_FRACTION:.0%} of this machine's memory): fit fewer or shorter logs at once, "
                       "or fewer parameters (--params, --per all)")


def _size(n: float) -> str:
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 else f"{n / 2**20:.0f} MiB"


def _solve(sysid: Any, pb: _Problem, max_iters: int, start: dict[str, float] | None = None,
           say: _Progress | None = None) -> _Solution:
    nu = len(pb.robot.actuators)
    say = say or _Progress(False)
    enabled = pb.enabled(sysid)
    residual_fn = say.counting(_residual_fn(sysid, pb.sequences, enabled, None, pb.firmware), len(pb.logs))
    clock = time.perf_counter()
    _check_finite(residual_fn, pb)
    say.expect(time.perf_counter() - clock, pb, max_iters)
    before = _rms(_predictions(residual_fn, pb.pdict, pb.x_nominal), pb.sensors, nu)
    sink = io.StringIO()
    xs, scan = starts(residual_fn, pb, pb.pdict.as_vector(), start or {})
    if "starts_s" in scan:
        say(f"delay scan: {len(scan['grid_s'])} delays, starts at " +
            ", ".join(f"{d * 1e3:.1f} ms" for d in scan["starts_s"]))
    opt, res = _multistart(sysid, pb, xs, residual_fn, max_iters, sink, say)
    weights = None
    if any(s >= nu for s in pb.sensors):
        # whiten: each kind of signal by its own noise, so the pooled
        # variance of the intervals means something
        weights = _whitening(residual_fn, opt, nu, pb.sensors)
        residual_fn = say.counting(_residual_fn(sysid, pb.sequences, enabled, weights, pb.firmware), len(pb.logs))
        say("whitened by each signal's noise: fitting on from there")
        opt, res = _optimize(sysid, pb, opt, residual_fn, max_iters, sink, say)
    opt, res = _no_delay_if_lower(sysid, pb, residual_fn, opt, res)
    warnings: list[str] = []
    opt, res = _no_worse_than_nominal(sysid, pb, residual_fn, opt, res, max_iters, sink, warnings)
    x = opt.as_vector()
    # the replay where the fit ended, once: its intervals' residual and the error after
    ended = None if res is None else _predictions(residual_fn, opt, x)
    half, corr, source, tau = _intervals(sysid, pb, residual_fn, opt, res, weights, ended)
    after = before if ended is None else _rms(ended, pb.sensors, nu)
    return _Solution(x, half, corr, residual_fn, opt, before, after, source == "floored", warnings, tau, scan,
                     source)


#: Each start runs this many iterations; the best then runs on to the end.
PROBE_ITERS = 4


def _multistart(sysid: Any, pb: _Problem, xs: list[np.ndarray], residual_fn: Any, max_iters: int,
                sink: io.StringIO, say: _Progress) -> tuple[Any, Any]:
    """Levenberg–Marquardt from each start (``_fit_start.starts``): a few
    iterations each, then the lowest cost on to the end."""
    if len(xs) == 1 or max_iters <= PROBE_ITERS:
        best = None
        for k, x in enumerate(xs):
            p = pb.pdict.copy()
            p.update_from_vector(x)
            say.stage = f"start {k + 1} of {len(xs)}" if len(xs) > 1 else ""
            opt, res = _optimize(sysid, pb, p, residual_fn, max_iters, sink, say)
            c = _cost(residual_fn, opt, opt.as_vector())
            if best is None or c < best[0]:
                best = (c, opt, res)
        assert best is not None
        say.stage = ""
        return best[1], best[2]
    probes = []
    for k, x in enumerate(xs):
        p = pb.pdict.copy()
        p.update_from_vector(x)
        say.stage = f"start {k + 1} of {len(xs)}"
        opt, _ = _optimize(sysid, pb, p, residual_fn, PROBE_ITERS, sink, say)
        probes.append((_cost(residual_fn, opt, opt.as_vector()), k, opt))
    c, k, opt = min(probes, key=lambda t: (t[0], t[1]))
    say.stage = f"on from start {k + 1}"
    out = _optimize(sysid, pb, opt, residual_fn, max_iters - PROBE_ITERS, sink, say)
    say.stage = ""
    return out


def _no_delay_if_lower(sysid: Any, pb: _Problem, residual_fn: Any, opt: Any, res: Any) -> tuple[Any, Any]:
    """A delay that ends within one timestep: MuJoCo applies it as a whole
    step, and no start below a step can move (``_fit_start``); no delay at
    all is another replay, which the fit cannot reach by steps. Where every
    such delay at 0 costs less, it is 0 (the Jacobian there is the one at
    the end: the other parameters do not move)."""
    x = opt.as_vector().copy()
    flat = [i for i, label in enumerate(pb.labels)
            if label[1] == "delay" and x[i] <= pb.robot.timestep * (1 + 1e-9)]
    if not flat:
        return opt, res
    x0 = x.copy()
    x0[flat] = 0.0
    if _cost(residual_fn, opt, x0) < _cost(residual_fn, opt, x):
        p = opt.copy()
        p.update_from_vector(x0)
        return p, res
    return opt, res


def _optimize(sysid: Any, pb: _Problem, start: Any, residual_fn: Any, max_iters: int,
              sink: io.StringIO, say: _Progress | None = None) -> tuple[Any, Any]:
    # legs do not interact: one rollout perturbs a parameter on each (a per-joint fit costs a per-group one)
    jac = jacobian_fn(residual_fn, start, pb)

    def callback(trace: list[Any]) -> None:
        if say is not None:
            say.iteration(trace)
        else:
            _lean(trace)
        _stop_when_flat(trace)

    try:
        opt, res = sysid.optimize(start, residual_fn, optimizer="mujoco", verbose=False, max_iters=max_iters,
                                  x_scale="jac", output=sink, iter_callback=callback,
                                  **({"jacobian": jac} if jac is not None else {}))
        return opt, res
    except _Flat as flat:
        return _ended_at(start, residual_fn, flat.x, jac)
    except np.linalg.LinAlgError as e:
        raise FitError(f"the fit's linear algebra failed ({e}): the logs do not determine the parameters; "
                       "fit fewer (--params) or give logs where every joint moves") from None


#: The optimizer stops when FLAT_ITERS iterations in a row each lower the cost by less than this fraction of it.
FTOL = 1e-5
FLAT_ITERS = 2


class _Flat(Exception):
    """The cost stopped falling (``_stop_when_flat``): the fit ends at ``x``."""

    def __init__(self, x: np.ndarray) -> None:
        super().__init__()
        self.x = x


def _stop_when_flat(trace: list[Any]) -> None:
    """mujoco.minimize stops on a small step or gradient only: along a
    valley the logs do not determine (damping against kd scale, which
    angles show only as a sum) it went on for 20 more iterations of
    steps that moved the cost in its seventh digit (a real log: twice the
    fit's time). Stops once the cost falls by less than FTOL of itself
    FLAT_ITERS iterations in a row."""
    steps = [t for t in trace if t.step is not None]
    if len(steps) < FLAT_ITERS:
        return
    last = steps[-FLAT_ITERS:]
    if all(0 <= float(t.reduction) <= FTOL * float(t.objective) for t in last):
        x = np.asarray(last[-1].candidate + last[-1].step).ravel()
        raise _Flat(x)


def _ended_at(start: Any, residual_fn: Any, x: np.ndarray, jac: Any) -> tuple[Any, Any]:
    """The optimizer's outcome at ``x`` where the fit stopped it: the
    parameters and the Jacobian there (the intervals' own)."""
    from mujoco import minimize
    from scipy.optimize import OptimizeResult

    opt = start.copy()
    opt.update_from_vector(x)
    lo, hi = (np.asarray(b, dtype=float).reshape(-1, 1) for b in opt.get_bounds())

    def residual(xv: np.ndarray) -> np.ndarray:
        r, _, _ = residual_fn(xv if xv.ndim == 1 or xv.shape[1] > 1 else xv[:, 0], opt.copy())
        return np.concatenate(r).reshape(-1, 1) if xv.ndim == 2 and xv.shape[1] == 1 else np.concatenate(r)

    xc = x.reshape(-1, 1)
    r = residual(xc)
    if jac is not None:
        J = jac(xc, r)
    else:
        J, _ = minimize.jacobian_fd(residual, xc, r, np.float64(np.finfo(np.float64).eps ** 0.5), 0, [lo, hi])
    return opt, OptimizeResult(x=x, jac=J, grad=None, extras={})


class _Progress:
    """What a fit says while it runs (on stderr where it is a terminal, or
    to a callable): its expected time, the delay scan, each iteration's
    cost, the rollouts so far."""

    def __init__(self, progress: bool | Callable[[str], None]) -> None:
        if callable(progress):
            self.say: Callable[[str], None] | None = progress
        elif progress and sys.stderr.isatty():
            self.say = say
        else:
            self.say = None
        self.rollouts = 0
        self.started = time.perf_counter()
        self.stage = ""

    def __call__(self, line: str) -> None:
        if self.say is not None:
            self.say(f"fit: {line}")

    def counting(self, residual_fn: Any, logs: int) -> Any:
        """``residual_fn``, counting its rollouts (a column of x per log)."""
        def counted(x: np.ndarray, params: Any, **kw: Any) -> Any:
            self.rollouts += logs * (1 if np.ndim(x) == 1 else int(np.shape(x)[1]))
            return residual_fn(x, params, **kw)
        return counted

    def expect(self, once: float, pb: _Problem, max_iters: int) -> None:
        """The expected time, from one replay of every log (``once`` s): a
        Levenberg–Marquardt iteration replays them about (parameters + 2)
        times, and a fit takes TYPICAL_ITERS iterations or so."""
        n = len(pb.labels)
        per_iter = once * (n + 2)
        typical = once * GRID + per_iter * min(TYPICAL_ITERS, max_iters)
        self(f"{len(pb.logs)} log(s), {len(pb.labels)} parameter(s), {len(pb.robot.actuators)} joint(s) "
             f"stepped; one replay of the logs takes {once:.2f} s: expect about {typical:.0f} s "
             f"(at most {once * GRID + per_iter * (max_iters + PROBE_ITERS * 2):.0f} s at --max-iters {max_iters})")

    def iteration(self, trace: list[Any]) -> None:
        _lean(trace)
        if self.say is None:
            return
        stage = f" ({self.stage})" if self.stage else ""
        self(f"iteration {len(trace)}{stage}: cost {float(trace[-1].objective):.6g}, {self.rollouts} rollouts, "
             f"{time.perf_counter() - self.started:.0f} s")


#: The iterations a fit typically takes (for its expected time).
TYPICAL_ITERS = 15


def _lean(trace: list[Any]) -> None:
    """Keeps the Jacobian and residual of the optimizer's last iteration
    only (the intervals need it; each earlier one would hold another
    samples x parameters matrix: 1 GB over a per-joint fit of two 20 s logs)."""
    import dataclasses

    if len(trace) > 1 and trace[-2].jacobian is not None:
        trace[-2] = dataclasses.replace(trace[-2], jacobian=None, residual=None)


def _check_finite(residual_fn: Any, pb: _Problem) -> None:
    """Refuses logs the nominal model cannot replay (it diverges)."""
    p = pb.pdict.copy()
    p.update_from_vector(pb.x_nominal)
    r, _, _ = residual_fn(pb.x_nominal, p)
    for lg, ri in zip(pb.logs, r):
        if not np.all(np.isfinite(ri)):
            raise FitError(f"{lg.path}: the model's replay of it is not finite at the nominal values (it "
                           f"diverges at the log's gains, kp up to {lg.kp.max():g}, kd up to {lg.kd.max():g}): "
                           "check the gains in its header")


def _cost(residual_fn: Any, params: Any, x: np.ndarray) -> float:
    p = params.copy()
    p.update_from_vector(x)
    r, _, _ = residual_fn(x, p)
    return float(sum(np.sum(np.square(ri)) for ri in r))


def _no_worse_than_nominal(sysid: Any, pb: _Problem, residual_fn: Any, opt: Any, res: Any, max_iters: int,
                           sink: io.StringIO, warnings: list[str]) -> tuple[Any, Any]:
    """A fit that ends worse than the nominal values (it started from them
    with those on a bound moved inside, and can stall in a flat valley or a
    step, like the delay's below one timestep) is restarted from them
    exactly; if it still ends worse, the nominal values are kept (``res``
    None: no interval means anything there)."""
    nominal = _cost(residual_fn, pb.pdict, pb.x_nominal)
    ended = _cost(residual_fn, opt, opt.as_vector())
    if ended <= nominal:
        return opt, res
    start = pb.pdict.copy()
    start.update_from_vector(pb.x_nominal)
    opt2, res2 = _optimize(sysid, pb, start, residual_fn, max_iters, sink)
    again = _cost(residual_fn, opt2, opt2.as_vector())
    if again <= nominal:
        warnings.append(f"the fit ended worse than the nominal values (cost {ended:.4g} against {nominal:.4g}): "
                        "restarted from them")
        return opt2, res2
    warnings.append(f"the fit ended worse than the nominal values (cost {ended:.4g}, restarted from them "
                    f"{again:.4g}, against {nominal:.4g}): the nominal values are kept and no interval is "
                    "meaningful; check the logs (an angle offset, the gains in the header, a joint's columns "
                    "under another's name)")
    return start, None


def _intervals(sysid: Any, pb: _Problem, residual_fn: Any, opt: Any, res: Any, weights: np.ndarray | None,
               ended: Predictions | None) -> tuple[np.ndarray, np.ndarray | None, str, float]:
    """sysid's Gauss-Newton 95 % half-widths (infinite where the logs do not
    determine a parameter), widened by the square root of the residual's
    correlation time (returned; 1 where the noise was floored), the
    correlations, and whether the residual noise behind them was floored
    at NOISE_FLOOR; ``ended``: the predictions at ``opt``. Through a
    noisy firmware (--motor noise=), each kind of signal's correlation time
    counts by its share of the information, and the spread of the fit's end
    over other draws of the replay's noise (``_draw_spread``) is added."""
    n = len(pb.labels)
    if res is None or ended is None:
        return np.full(n, math.nan), None, "none", 1.0
    r_star, _, _ = residual_fn(opt.as_vector(), opt.copy())
    r_iv, floored = _interval_residuals(r_star, ended, weights, pb.sensors, len(pb.robot.actuators))
    try:
        cov, half = sysid.calculate_intervals(r_iv, res.jac, alpha=0.05)
    except (np.linalg.LinAlgError, ValueError):
        return np.full(n, math.inf), None, "floored" if floored else "noise", 1.0
    # a noise-free log's residual is round-off, not noise: its floor stands for independent noise
    nu = len(pb.robot.actuators)
    kinds = [s // nu for s in pb.sensors]
    # through the firmware, each kind of signal's correlation time counts by what it tells
    shares = (_information_shares(res.jac, [int(np.size(r)) for r in r_star], kinds)
              if pb.firmware is not None and len(set(kinds)) > 1 else None)
    tau = 1.0 if floored else _correlation_time(ended, shares, kinds)
    half = np.where(np.isnan(half), math.inf, half * math.sqrt(tau))
    if pb.firmware is not None and pb.firmware.noise and not floored:
        # the replay reads one draw of the noise, the fit follows it: its spread over other draws joins
        # the hardware's noise in the intervals
        spread = _draw_spread(sysid, pb, opt, res.jac, r_star, weights)
        if spread is not None:
            from scipy.special import stdtrit

            q = float(stdtrit(sum(int(np.size(r)) for r in r_star) - n, 0.975))
            half = np.sqrt(half ** 2 + q ** 2 * np.diag(spread))
            cov = cov * tau + spread
    sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    corr = cov / np.outer(sd, sd)
    source = "floored" if floored else "noise"
    if not floored:
        half, source = _model_error(pb, res.jac, r_star, ended, tau, half)
    return half, (corr if np.all(np.isfinite(corr)) else None), source, tau


def _model_error(pb: _Problem, jac: np.ndarray, r_star: list[np.ndarray], ended: Predictions, tau: float,
                 half: np.ndarray) -> tuple[np.ndarray, str]:
    """The intervals where the residual is structure the model cannot
    follow (``_fit_intervals``): the wider of the noise's and the segments'
    spread for each parameter, and which one they come from."""
    from pupper_core._fit import intervals as fi

    noise, source = half, "noise"
    period = float(np.mean([np.mean(np.diff(t)) for t, _, _ in ended]))
    seg = fi.segments([t for t, _, _ in ended], len(pb.sensors), period, tau)
    got = fi.sandwich(jac, np.concatenate(r_star), seg) if seg is not None else None
    if got is not None and fi.model_error(noise, got[1]):
        half, source = np.where(np.isfinite(half), np.maximum(half, got[1]), half), "model error"
    shifts = fi.per_log_shifts(jac, np.concatenate(r_star), [int(np.size(r)) for r in r_star])
    if shifts is not None:
        spread = np.max(np.abs(shifts), axis=0)
        if fi.model_error(noise, spread):
            # the logs disagree past their noise: each interval holds every log's own fit
            half, source = np.where(np.isfinite(half), np.maximum(half, spread), half), "model error"
    return half, source


def _draw_spread(sysid: Any, pb: _Problem, opt: Any, jac: np.ndarray, r_star: list[np.ndarray],
                 weights: np.ndarray | None) -> np.ndarray | None:
    """The covariance of where the fit would end over the replay's draws of
    the encoder's noise (--motor noise=): the fit's end replayed through
    DRAWS others, each moved to its own optimum by one Gauss-Newton step
    (their spread about the fit's own, which counts as one of them). The
    pair of a draw and its negative cancels the joint's response to the
    noise to first order only: what the rest does (a draw loosens the
    friction more here than there) differs from draw to draw, and moved two
    logs' damping by 0.9 % (1 sigma) against the hardware's noise's 1.3 %."""
    from dataclasses import replace

    from pupper_core._fit.firmware import DRAWS

    assert pb.firmware is not None
    x = opt.as_vector()
    try:
        hinv = np.linalg.pinv(jac.T @ jac)
    except np.linalg.LinAlgError:
        return None
    shifts = [-(hinv @ (jac.T @ np.concatenate(r_star)))]
    enabled = pb.enabled(sysid)
    for seed in range(pb.firmware.seed + 1, pb.firmware.seed + 1 + DRAWS):
        fn = _residual_fn(sysid, pb.sequences, enabled, weights, replace(pb.firmware, seed=seed))
        r, _, _ = fn(x, opt.copy())
        r = np.concatenate(r)
        if r.shape[0] != jac.shape[0] or not np.all(np.isfinite(r)):
            return None
        shifts.append(-(hinv @ (jac.T @ r)))
    spread = np.atleast_2d(np.cov(np.stack(shifts), rowvar=False))
    return spread if np.all(np.isfinite(spread)) else None


def _judge(pb: _Problem, sol: _Solution, table: list[dict[str, Any]]) -> list[str]:
    """What the user must know of each parameter (``table``: fit.csv's rows,
    its intervals): on a bound, undetermined, an interval past a physical
    bound (every parameter is >= 0), a delay under one timestep, confounded
    pairs; and logs the fit made worse."""
    out: list[str] = []
    lo_b, hi_b = pb.pdict.get_bounds()
    for i, (name, kind, _, _) in enumerate(pb.labels):
        x, h, unit = float(sol.x[i]), float(sol.half[i]), PARAMS[kind][0]
        low, high = table[i]["low95"], table[i]["high95"]
        u = f" {unit}" if unit else ""
        span = float(hi_b[i] - lo_b[i])
        bound = next(((side, b) for side, b in (("lower", float(lo_b[i])), ("upper", float(hi_b[i])))
                      if abs(x - b) <= 1e-6 * span), None)
        if bound is not None:
            # a Gauss-Newton interval assumes a minimum inside the bounds
            out.append(f"{name} ends on its {bound[0]} bound ({bound[1]:g}{u}): its interval is not meaningful; "
                       "the logs ask for a value the fit does not allow, or show none")
        if kind == "delay" and 0 < x < pb.robot.timestep * (1 - 1e-9):
            out.append(f"{name} ends at {x:.3g} s, under one timestep ({pb.robot.timestep:g} s): MuJoCo applies "
                       "any delay up to a timestep as a whole step, so the logs cannot place it there; read it "
                       f"as 0 or {pb.robot.timestep:g} s")
        if math.isinf(h):
            out.append(f"{name}: the logs do not determine it (its 95 % interval is infinite): leave it out "
                       "of --params, or give logs that excite it")
        elif bound is None and math.isfinite(h) and low < 0:
            out.append(f"{name}'s 95 % interval [{low:.4g}, {high:.4g}]{u} reaches below 0, which it cannot "
                       "be: the logs show it poorly or it is near 0; read its upper end as a bound")
    kinds = {label[1]: i for i, label in enumerate(pb.labels)}
    if "latency" in kinds and "delay" in kinds and (math.isinf(float(sol.half[kinds["latency"]]))
                                                   or math.isnan(float(sol.half[kinds["latency"]]))):
        out.append("latency and delay: the logs cannot tell the feedback latency (inside the loop: it changes "
                   "the resonance) from the command delay (outside it: a pure lag); add a log at another kp or kd, "
                   "or fit one of them")
    if sol.source == "model error":
        rms = float(np.mean([np.mean(a) for a in sol.after])) * 1e3
        out.append(f"the residual ({rms:.3g} mrad RMS) is structure the model cannot follow, not noise: each "
                   "interval is the widest of the noise's, the spread over the logs' segments (a block "
                   "sandwich, what leaving segments in or out would move) and, with several logs, each log's "
                   "own fit; it says how far the model's error lets the logs place each value, not a sensor's "
                   "precision" + ("" if {"lag", "latency"} & set(kinds) else
                                  "; a servo's torque lag is a common cause on real motors: try --params "
                                  + ",".join(dict.fromkeys([*kinds, "lag"]))))
    out += _confounded(pb, sol)
    for lg, rms0, rms1 in zip(pb.logs, sol.before, sol.after):
        # by more than 1 % and a micro-radian: not round-off
        if np.mean(rms1) > 1.01 * np.mean(rms0) + 1e-6:
            out.append(f"{lg.path.name}: the RMS angle error rose ({np.mean(rms0) * 1e3:.3f} -> "
                       f"{np.mean(rms1) * 1e3:.3f} mrad): the fitted model explains it worse than the nominal one; "
                       "check the log (an angle offset, the gains in its header)")
    return out


#: A correlation past which the feedback latency and the command delay are said to be one to the logs.
APART = 0.9


def _confounded(pb: _Problem, sol: _Solution) -> list[str]:
    out: list[str] = []
    if sol.corr is None:
        return out
    for i, (a_name, a_kind, a_mem, _) in enumerate(pb.labels):
        for j, (b_name, b_kind, b_mem, _) in enumerate(pb.labels):
            c = float(sol.corr[i, j])
            if i >= j or abs(c) <= 0.95:
                continue
            if a_mem == b_mem and {a_kind, b_kind} == {"delay", "latency"} and abs(c) > APART:
                out.append(f"{a_name} and {b_name} are confounded (correlation {c:+.2f}): the logs cannot tell "
                           "the feedback latency (inside the loop: it changes the resonance) from the command "
                           "delay (outside it: a pure lag); add a log at another kp or kd, or fit one of them")
            elif a_mem == b_mem and {a_kind, b_kind} == {"damping", "kd_scale"}:
                out.append(f"{a_name} and {b_name} are confounded (correlation {c:+.2f}): the logs "
                           "show only their sum; add a log at another kd (pupper excite --kd) or a torque column")
            elif abs(c) > CONFOUNDED:
                out.append(f"{a_name} and {b_name} are confounded (correlation {c:+.3f}): the logs cannot tell "
                           "them apart; leave one out of --params, or add logs that separate them")
    return out


#: The parameters of the motor itself, which motors of one type share (the link's own, armature and
#: damping, stay per joint: they carry the link's inertia and losses).
MOTOR_KINDS = ("kp_scale", "kd_scale", "delay", "lag", "latency", "frictionloss")
#: What each motor parameter's disagreement puts in doubt: the part of the model it stands for.
_SUSPECT = {
    "gain": "the motor model's gain structure (a gain scale stands in for what differs from joint to joint "
            "and the model leaves out: the link's inertia or load, a transmission, the torque limit at speed)",
    "timing": "the motor model's timing structure (a command delay and a first-order torque lag: the logs' "
              "time stamps or loop rate differ, or the servo's lag is not first-order)",
    "friction": "the friction model (Coulomb friction loss alone: the joints' own friction, seals or cables, "
                "differs, or friction varies with speed, viscous or Stribeck)",
}
_PART = {"kp_scale": "gain", "kd_scale": "gain", "delay": "timing", "lag": "timing", "latency": "timing",
         "frictionloss": "friction"}


def fit_entries(res: FitResult, label: str = "") -> list[tuple[str, str, float, float, float]]:
    """A fit's motor parameters as (kind, motors, value, low, high): the
    motors are the logged actuators a value stands for (fit.csv lists every
    actuator it goes to), ``label`` said after them (a fit's run)."""
    out = []
    for r in res.table:
        if r["kind"] not in MOTOR_KINDS:
            continue
        motors = [a for a in r["actuators"].split() if a in res.actuators]
        _, lo, hi = PARAMS[r["kind"]]
        # a value on its bound has no meaningful interval (the fit warns of it): nothing to compare
        on_bound = min(abs(r["fitted"] - lo), abs(r["fitted"] - max(hi, 4 * r["nominal"]))) <= 1e-6 * (hi - lo)
        if motors and not on_bound:
            out.append((r["kind"], " ".join(motors) + (f" ({label})" if label else ""), float(r["fitted"]),
                        float(r["low95"]), float(r["high95"])))
    return out


def disagreements(entries: Sequence[tuple[str, str, float, float, float]],
                  type_of: Mapping[str, float]) -> list[str]:
    """Warnings for motors of one type (``type_of``: an actuator's torque
    limit, its type) whose motor parameter comes out with disjoint 95 %
    intervals (``entries``: ``fit_entries``' rows, of one fit per joint or
    of several fits): each names the parameter, the motors, their values
    and intervals, and the part of the model it suspects: motors of one
    type are one motor, so a parameter that differs while the others agree
    points at the model's structure for that part, not at the motors. An
    interval not meaningful (NaN) or infinite is never disjoint."""
    def kind_of(motors: str) -> float | None:
        types = {type_of.get(a) for a in motors.split(" (")[0].split()}
        return types.pop() if len(types) == 1 else None

    groups: dict[tuple[str, float], list[tuple[str, float, float, float]]] = {}
    for kind, motors, x, lo, hi in entries:
        t = kind_of(motors)
        if t is not None and math.isfinite(lo) and math.isfinite(hi):
            groups.setdefault((kind, t), []).append((motors, x, lo, hi))
    split: dict[tuple[str, float], list[tuple[int, int]]] = {}
    for key, rows in groups.items():
        pairs = [(i, j) for i in range(len(rows)) for j in range(i + 1, len(rows))
                 if rows[i][3] < rows[j][2] or rows[j][3] < rows[i][2]]
        if pairs:
            split[key] = pairs
    out = []
    for (kind, t), pairs in split.items():
        rows = groups[(kind, t)]
        apart = sorted({k for p in pairs for k in p})
        said = ", ".join(f"{rows[k][0]} {rows[k][1]:.4g} [{rows[k][2]:.4g}, {rows[k][3]:.4g}]" for k in apart)
        agree = sorted(k2 for (k2, t2), rs in groups.items() if t2 == t and len(rs) > 1 and (k2, t2) not in split)
        limit = f"torque limit {t:g} N·m" if math.isfinite(t) else "no torque limit"
        unit = PARAMS[kind][0]
        text = (f"{kind} disagrees between motors of one type ({limit}): {said}{' ' + unit if unit else ''}, "
                "intervals disjoint")
        if agree:
            text += f", while {', '.join(agree)} agree{'s' if len(agree) == 1 else ''}"
        others = {k2 for k2, t2 in split if t2 == t} - {kind}
        if others and not agree:
            text += (f"; {', '.join(sorted(others))} disagree too: the motors themselves may differ (a worn "
                     "or another motor), or the joints' model (link inertia, load) is wrong")
        else:
            also = f" ({', '.join(sorted(others))} disagree{'s' if len(others) == 1 else ''} too)" if others else ""
            text += f": suspect {_SUSPECT[_PART[kind]]}{also}, not the motors"
        out.append(text)
    return out


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
    # per joint or group, motors of one type get a value each: they should agree
    res.warnings += disagreements(fit_entries(res), motor_types(pb.robot.full))
    return res


def motor_types(robot: Robot) -> dict[str, float]:
    """Each actuator's type: its torque limit (the model says no more of a motor)."""
    return {a: float(robot.limits[k]) for k, a in enumerate(robot.actuators)}


# ---------------------------------------------------------------------- CLI


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
            n = len(res.actuators)
            print(f"{name}: RMS angle error {b:.3f} -> {f:.3f} mrad (mean over {n} joint{'s' if n > 1 else ''})")
        if res.validation:
            print_table(res.validation)
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
