"""Solving a fit: the memory a rollout batch may take, the starts (the
delay's grid, the user's), Levenberg-Marquardt until the cost is flat,
and its progress on a terminal."""

from __future__ import annotations

import copy
import io
import os
import time
from typing import Any

import numpy as np

from pupper_core._fit.judge import _intervals
from pupper_core._fit.problem import _Problem, _Solution
from pupper_core._fit.robot import Robot, suspended_spec
from pupper_core._fit.optimize import FTOL, PROBE_ITERS, ROUGH_FTOL, _optimize, _Progress
from pupper_core._fit.start import latencies, starts
from pupper_core._fit.sysid import _predictions, _rms, _whitening
from pupper_core._fit.terms import MEMORY_COPIES, MEMORY_FRACTION, FitError
from pupper_core._fit.log import JointLog


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
    by_log = [pb.sensors_of(i) for i in range(len(pb.logs))]
    residual_fn = say.counting(pb.residual_fn(sysid, None), len(pb.logs))
    clock = time.perf_counter()
    _check_finite(residual_fn, pb)
    say.expect(time.perf_counter() - clock, pb, max_iters)
    before = _rms(_predictions(residual_fn, pb.pdict, pb.x_nominal), by_log, nu)
    sink = io.StringIO()
    xs, scan = starts(residual_fn, pb, pb.pdict.as_vector(), start or {})
    if "starts_s" in scan:
        say(f"delay scan: {len(scan['grid_s'])} delays, starts at " +
            ", ".join(f"{d * 1e3:.1f} ms" for d in scan["starts_s"]))
    # a fit whitened after it (a velocity or torque column) only needs to come near from here: the
    # whitened fit goes on to the end (two real 20 s logs: 3 of its 8 iterations spared)
    whitened = any(s >= nu for s in pb.sensors)
    opt, res = _multistart(sysid, pb, xs, residual_fn, max_iters, sink, say, scan,
                           ROUGH_FTOL if whitened else FTOL)
    weights = None
    if any(s >= nu for s in pb.sensors):
        # whiten: each kind of signal by its own noise, so the pooled
        # variance of the intervals means something
        weights = _whitening(residual_fn, opt, nu, pb.sensors, by_log)
        residual_fn = say.counting(pb.residual_fn(sysid, weights), len(pb.logs))
        say("whitened by each signal's noise: fitting on from there")
        opt, res = _optimize(sysid, pb, opt, residual_fn, max_iters, sink, say)
    opt, res = _no_delay_if_lower(sysid, pb, residual_fn, opt, res)
    warnings: list[str] = []
    opt, res = _no_worse_than_nominal(sysid, pb, residual_fn, opt, res, max_iters, sink, warnings)
    x = opt.as_vector()
    # the replay where the fit ended, once: its intervals' residual and the error after
    ended = None if res is None else _predictions(residual_fn, opt, x)
    half, corr, source, tau = _intervals(sysid, pb, residual_fn, opt, res, weights, ended)
    after = before if ended is None else _rms(ended, by_log, nu)
    return _Solution(x, half, corr, residual_fn, opt, before, after, source == "floored", warnings, tau, scan,
                     source, None if res is None else np.asarray(res.jac))



def _multistart(sysid: Any, pb: _Problem, xs: list[np.ndarray], residual_fn: Any, max_iters: int,
                sink: io.StringIO, say: _Progress, scan: dict[str, Any] | None = None,
                ftol: float | None = None) -> tuple[Any, Any]:
    """Levenberg–Marquardt from each start (``_fit_start.starts``): a few
    iterations each (PROFILE_ITERS with the feedback latency held, in the
    starts of its profile: the first ``latency_profile_s``), then the
    lowest cost on to the end."""
    scan = scan or {}
    held, count = latencies(pb), len(scan.get("latency_profile_s", []))
    # a probe's iterations count towards --max-iters: the best goes on for the rest
    used = [PROFILE_ITERS if k < count else PROBE_ITERS for k in range(len(xs))]
    if len(xs) == 1 or max_iters <= max(used):
        best = None
        for k, x in enumerate(xs):
            p = pb.pdict.copy()
            p.update_from_vector(x)
            say.stage = f"start {k + 1} of {len(xs)}" if len(xs) > 1 else ""
            opt, res = _optimize(sysid, pb, p, residual_fn, max_iters, sink, say, ftol)
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
        if k < count:
            say.stage = f"start {k + 1} of {len(xs)}, latency held at {x[held[0]] * 1e3:.1f} ms"
            opt = _held_probe(sysid, pb, p, residual_fn, held, PROFILE_ITERS, sink, say)
        else:
            say.stage = f"start {k + 1} of {len(xs)}"
            opt, _ = _optimize(sysid, pb, p, residual_fn, PROBE_ITERS, sink, say)
        probes.append((_cost(residual_fn, opt, opt.as_vector()), k, opt))
    c, k, opt = min(probes, key=lambda t: (t[0], t[1]))
    say.stage = f"on from start {k + 1}"
    out = _optimize(sysid, pb, opt, residual_fn, max_iters - used[k], sink, say, ftol)
    say.stage = ""
    return out



#: Iterations of each start with the feedback latency held (``_fit_start``'s profile): fewer than
#: this ranked the profile wrong on the stand-in (4: the 0 ms start, whose basin is not the truth's, lowest).
PROFILE_ITERS = 6



def _held_probe(sysid: Any, pb: _Problem, start: Any, residual_fn: Any, held: list[int], iters: int,
                sink: io.StringIO, say: _Progress) -> Any:
    """Levenberg–Marquardt on every parameter but those at ``held``, which
    stay at ``start``'s values; the parameters where it ended (all of them)."""
    import dataclasses

    x_all = start.as_vector()
    keep = [i for i in range(len(pb.labels)) if i not in held]
    names = [pb.labels[i][0] for i in keep]
    part = type(start)()
    for n in names:
        part.add(copy.deepcopy(start[n]))

    def fixed(x: np.ndarray, params: Any, **kw: Any) -> Any:
        x = np.asarray(x, dtype=float)
        full = np.repeat(x_all.reshape(-1, 1), 1 if x.ndim == 1 else x.shape[1], axis=1)
        full[keep] = x.reshape(len(keep), -1)
        return residual_fn(full[:, 0] if x.ndim == 1 else full, start.copy(), **kw)

    sub = dataclasses.replace(pb, pdict=part, labels=[pb.labels[i] for i in keep])
    opt, _ = _optimize(sysid, sub, part, fixed, iters, sink, say)
    out = start.copy()
    x = x_all.copy()
    x[keep] = opt.as_vector()
    out.update_from_vector(x)
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
