"""One Levenberg–Marquardt run of a fit (``_optimize``: mujoco.sysid's,
stopped where its cost is flat) and what a fit says while it runs
(``_Progress``): used by the fit's own solve and by each log's own fit
behind the intervals (``judge``)."""

from __future__ import annotations

import math

import io
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from pupper_core._rundir import say
from pupper_core._run.progress import EVERY_S, FIRST_S, clock
from pupper_core._fit.jacobian import jacobian_fn
from pupper_core._fit.problem import _Problem
from pupper_core._fit.start import GRID
from pupper_core._fit.terms import FitError


#: Each start runs this many iterations; the best then runs on to the end.
PROBE_ITERS = 4



def _optimize(sysid: Any, pb: _Problem, start: Any, residual_fn: Any, max_iters: int,
              sink: io.StringIO, say: _Progress | None = None, ftol: float | None = None) -> tuple[Any, Any]:
    ftol = FTOL if ftol is None else ftol
    # legs do not interact: one rollout perturbs a parameter on each (a per-joint fit costs a per-group one)
    jac = jacobian_fn(residual_fn, start, pb)
    # candidates tried since the last iteration, and where that iteration ended if it was flat
    seen: dict[str, Any] = {"tries": 0, "flat": None}

    def tried(x: np.ndarray, params: Any, **kw: Any) -> Any:
        if np.ndim(x) == 1 or np.shape(x)[1] == 1:
            seen["tries"] += 1
            if seen["flat"] is not None and seen["tries"] > REJECTS:
                raise _Flat(seen["flat"])
        return residual_fn(x, params, **kw)

    def callback(trace: list[Any]) -> None:
        if say is not None:
            say.iteration(trace)
        else:
            _lean(trace)
        seen["tries"], last = 0, trace[-1]
        flat = last.step is not None and 0 <= float(last.reduction) <= ftol * float(last.objective)
        seen["flat"] = np.asarray(last.candidate + last.step).ravel() if flat else None
        _stop_when_flat(trace, ftol)

    try:
        opt, res = sysid.optimize(start, tried, optimizer="mujoco", verbose=False, max_iters=max_iters,
                                  x_scale="jac", output=sink, iter_callback=callback,
                                  **({"jacobian": jac} if jac is not None else {}))
        return opt, res
    except _Flat as flat:
        return _ended_at(start, residual_fn, flat.x, jac)
    except np.linalg.LinAlgError as e:
        raise FitError(f"the fit's linear algebra failed ({e}): the logs do not determine the parameters; "
                       "fit fewer (--params) or give logs where every joint moves") from None



#: After an iteration that lowered the cost by less than FTOL of it, this many rejected candidates in a
#: row end the fit there: the optimizer otherwise raises its damping step by step to its ceiling, each
#: step a rollout of every log (on two real 20 s logs through the firmware, 75 rollouts: a third of the fit).
REJECTS = 8



#: The optimizer stops when FLAT_ITERS iterations in a row each lower the cost by less than this fraction of it.
FTOL = 1e-5



#: ... and where a whitened fit goes on from its end, this fraction (``_solve``).
ROUGH_FTOL = 1e-3



FLAT_ITERS = 2



class _Flat(Exception):
    """The cost stopped falling (``_stop_when_flat``): the fit ends at ``x``."""

    def __init__(self, x: np.ndarray) -> None:
        super().__init__()
        self.x = x



def _stop_when_flat(trace: list[Any], ftol: float = FTOL) -> None:
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
    if all(0 <= float(t.reduction) <= ftol * float(t.objective) for t in last):
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
        # off a terminal (nohup, CI, a pipe): a plain line now and then, as
        # build tools print; a fit shorter than FIRST_S prints none
        self.plain = bool(progress) and not callable(progress) and self.say is None
        self.rollouts = 0
        #: one replay of every log (s), timed before the fit starts
        self.once = math.nan
        self.started = time.perf_counter()
        self.stage = ""
        self.expected = ""
        self.due = FIRST_S

    def __call__(self, line: str) -> None:
        if self.say is not None:
            self.say(f"fit: {line}")
        elif self.plain:
            self.tick(line)

    def tick(self, line: str | None = None) -> None:
        """Off a terminal: ``line`` (or where the fit stands) on stderr once
        FIRST_S seconds have passed, then every EVERY_S; the first says
        what the fit is and how long it should take."""
        spent = time.perf_counter() - self.started
        if line is not None and not self.expected:
            self.expected = line  # the first line a fit says: its expected time
        if not self.plain or spent < self.due:
            return
        now = line or f"{self.rollouts} rollouts{f' ({self.stage})' if self.stage else ''}"
        if self.due == FIRST_S:
            head = f"running for {clock(spent)}: {self.expected}; " if self.expected != now else ""
            say(f"progress: fit {head}{now}; a line every {EVERY_S:.0f} s")
        else:
            say(f"progress: fit {now}, {clock(spent)}")
        self.due = spent + EVERY_S

    def counting(self, residual_fn: Any, logs: int) -> Any:
        """``residual_fn``, counting its rollouts (a column of x per log)."""
        def counted(x: np.ndarray, params: Any, **kw: Any) -> Any:
            self.rollouts += logs * (1 if np.ndim(x) == 1 else int(np.shape(x)[1]))
            self.tick()
            return residual_fn(x, params, **kw)
        return counted

    def expect(self, once: float, pb: _Problem, max_iters: int) -> None:
        """The expected time, from one replay of every log (``once`` s): a
        Levenberg–Marquardt iteration replays them about (parameters + 2)
        times, and a fit takes TYPICAL_ITERS iterations or so."""
        self.once = once
        n = len(pb.labels)
        per_iter = once * (n + 2)
        typical = once * GRID + per_iter * min(TYPICAL_ITERS, max_iters)
        self(f"{len(pb.logs)} log(s), {len(pb.labels)} parameter(s), {len(pb.robot.actuators)} joint(s) "
             f"stepped; one replay of the logs takes {once:.2f} s: expect about {typical:.0f} s "
             f"(at most {once * GRID + per_iter * (max_iters + PROBE_ITERS * 2):.0f} s at --max-iters {max_iters})")

    def iteration(self, trace: list[Any]) -> None:
        _lean(trace)
        if self.say is None and not self.plain:
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
