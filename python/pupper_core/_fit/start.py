"""Where a fit starts (``pupper_core._fit`` runs Levenberg–Marquardt from
here): no parameter may start where its Jacobian is structurally zero.

The delay's nominal value is 0, and MuJoCo applies any actuator delay up to
one timestep as a whole step: between 0 and a step the replay does not
change, so a finite-difference Jacobian has a zero column there and the
optimizer never moves the delay; it then bends every other parameter to
make up for the delay it cannot see (on a real Pupper log: 20 ms of delay
left at 0, kp scale 0.57, kd scale 0.49, friction ×9). So, before the
least-squares fit, the delay is estimated from the logs themselves: the
replay's cost over a grid of delays (every other parameter at its start),
each grid point one rollout of each log, all in one batched call, its
minimum refined by a parabola through its neighbours. That is the lag that
best aligns the model's response with the log's, through the model's own
dynamics (a cross-correlation of command and angle would count the
joint's own lag as delay). The fit then starts from the best delays found
(the lowest minimum of the grid, the next local minimum where it is
nearly as low, and any start the caller gives) and keeps the lowest cost:
multi-start over what is cheap. A start is never below STEPS_OFF
timesteps, where the delay's column is zero.

A feedback latency (inside the loop) has a narrow basin: its effect
depends on the rotor and the gains it acts through, and from the nominal
values (a lighter rotor, which a latency destabilises more) the first
steps drive it to 0, where the rest bends to make up for it (a stand-in
with 6 ms of latency and 15 ms of delay: latency 0, kp scale 1.33,
friction ×2.3, RMS 8-12 mrad against 3-4 from a start near it). So where
the latency is fitted, the starts are a profile: the latency held at
LATENCY_SHARES of the logs' delay estimate while the rest is fitted for a
few iterations each (the cost over the held latency is smooth once the
rest has followed it), and the lowest goes on with the latency free."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

from pupper_core._fit.problem import _Problem
from pupper_core._fit.terms import PARAMS, FitError

#: The delay grid's points (0 to the delay's upper bound).
GRID = 11
#: A second local minimum of the grid is a start too when its cost is within this factor of the lowest.
SECOND = 1.5
#: A delay starts at least this many timesteps in (below one its Jacobian column is zero).
STEPS_OFF = 1.5
#: Where a feedback latency is held while the rest is fitted (``starts``): shares of the logs' delay
#: estimate (taken with the latency at its own start), the delay starting at the rest of it.
LATENCY_SHARES = (0.0, 0.25, 0.5, 0.75)
#: The logs' delay estimate the shares are of, where no delay is fitted (s).
LATENCY_SPAN = 0.02


def parse_start(start: str | Mapping[str, float] | None, names: list[str]) -> dict[str, float]:
    """--start's text (KIND=VALUE,...) or a mapping: where the fit starts
    each kind of parameter (every parameter of that kind)."""
    if start is None:
        return {}
    items: list[tuple[str, Any]]
    if isinstance(start, str):
        items = []
        for part in (p.strip() for p in start.split(",") if p.strip()):
            key, eq, value = part.partition("=")
            if not eq:
                raise FitError(f"--start item '{part}' is not KIND=VALUE: write e.g. --start delay=0.015")
            items.append((key.strip(), value.strip()))
    else:
        items = list(start.items())
    out: dict[str, float] = {}
    for key, value in items:
        if key not in names:
            raise FitError(f"--start names '{key}', which is not fitted: give one of {', '.join(names)}")
        if key in out:
            raise FitError(f"--start gives '{key}' twice: keep one value")
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise FitError(_not_a_number(key, value)) from None
        _, lo, hi = PARAMS[key]
        if not (math.isfinite(v) and lo <= v <= hi):
            raise FitError(f"--start {key}={value} lies outside {key}'s bounds [{lo:g}, {hi:g}]: give a value "
                           "inside them")
        out[key] = v
    return out


#: Time units a value may be written in by habit (``lag=5ms``), and their factor to s.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}
_WITH_UNIT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\d\s.+-][^\s]*)\s*$")


def _not_a_number(key: str, value: Any) -> str:
    """--start KIND=VALUE's refusal: what the value is in and, where it was
    written with a time unit, the number to write."""
    unit = PARAMS[key][0]
    said = f"{key} is in seconds" if unit == "s" else f"{key} is in {unit}" if unit else f"{key} is a plain ratio"
    m = _WITH_UNIT.match(str(value))
    if m and m.group(2) in TIME_UNITS:
        if unit != "s":
            return (f"--start {key}={value} is not a number: {said}, not a time; write the number alone, e.g. "
                    f"--start {key}={_example(key)}")
        v = float(m.group(1)) * TIME_UNITS[m.group(2)]
        return f"--start {key}={value} is not a number: {said}; write it without the unit: --start {key}={v:g}"
    if m:
        return f"--start {key}={value} is not a number: {said}; write it without the unit: --start {key}={m.group(1)}"
    return f"--start {key}={value} is not a number: {said}; write e.g. --start {key}={_example(key)}"


def _example(key: str) -> str:
    _, lo, hi = PARAMS[key]
    return f"{(lo + hi) / 2 if lo > 0 else hi / 4:g}"


def _delays(pb: _Problem) -> list[int]:
    return [i for i, label in enumerate(pb.labels) if label[1] == "delay"]


def least_delay(pb: _Problem) -> float:
    """The smallest delay a start takes: below it the Jacobian's column is zero."""
    return STEPS_OFF * pb.robot.timestep


def with_start(pb: _Problem, x: np.ndarray, start: dict[str, float]) -> np.ndarray:
    """``x`` with the caller's start values, a delay moved off its flat first step."""
    x = x.copy()
    for i, (_, kind, _, _) in enumerate(pb.labels):
        if kind in start:
            x[i] = start[kind]
        if kind == "delay":
            x[i] = max(x[i], least_delay(pb))
        elif kind in ("lag", "latency"):
            # an exact filter's response is flat in a time constant far below a step
            x[i] = max(x[i], pb.robot.timestep)
    return x


def costs(residual_fn: Any, params: Any, xs: np.ndarray) -> np.ndarray:
    """The cost at each column of ``xs``, every column in one batched rollout."""
    r, _, _ = residual_fn(xs, params.copy())
    out = np.zeros(xs.shape[1])
    for ri in r:
        ri = np.asarray(ri).reshape(-1, xs.shape[1])
        out += np.sum(np.square(ri), axis=0)
    return np.where(np.isfinite(out), out, np.inf)


def delay_scan(residual_fn: Any, pb: _Problem, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The grid of delays and the cost at each (every delay of the fit set
    to the grid's value, the rest at ``x``)."""
    hi = float(pb.pdict.get_bounds()[1][_delays(pb)[0]])
    grid = np.linspace(0.0, hi, GRID)
    xs = np.tile(x.reshape(-1, 1), (1, GRID))
    for i in _delays(pb):
        xs[i, :] = grid
    return grid, costs(residual_fn, pb.pdict, xs)


def _refine(grid: np.ndarray, cost: np.ndarray, k: int) -> float:
    """The grid's minimum at k refined by the parabola through it and its neighbours."""
    if 0 < k < len(grid) - 1 and np.all(np.isfinite(cost[k - 1:k + 2])):
        c0, c1, c2 = cost[k - 1:k + 2]
        den = c0 - 2 * c1 + c2
        if den > 0:
            h = grid[1] - grid[0]
            return float(grid[k] + 0.5 * h * (c0 - c2) / den)
    return float(grid[k])


def starts(residual_fn: Any, pb: _Problem, x0: np.ndarray,
           start: dict[str, float]) -> tuple[list[np.ndarray], dict[str, Any]]:
    """The start vectors the fit runs from, and what the scan found (for the
    manifest): without a delay to fit, the one start ``x0`` (the caller's
    values in it); with a feedback latency, its profile first (the latency
    held at each of ``latency_profile_s`` while that start probes)."""
    xs, scan = _delay_starts(residual_fn, pb, x0, start)
    return _latency_profile(pb, xs, scan, start)


def latencies(pb: _Problem) -> list[int]:
    return [i for i, label in enumerate(pb.labels) if label[1] == "latency"]


def _latency_profile(pb: _Problem, xs: list[np.ndarray], scan: dict[str, Any],
                     start: dict[str, float]) -> tuple[list[np.ndarray], dict[str, Any]]:
    """The starts with the feedback latency held at LATENCY_SHARES of the
    best delay start's total delay (its own start's share included), the
    delay at the rest; the other delay starts (the scan's second minimum,
    the caller's delay) run free after them, and with a latency the caller
    starts, so does the best."""
    held = latencies(pb)
    if not held:
        return xs, scan
    delays = _delays(pb)
    best = xs[0]
    floor = pb.robot.timestep
    total = float(best[delays[0]]) + float(best[held[0]]) if delays else LATENCY_SPAN
    out = []
    for share in LATENCY_SHARES:
        x = best.copy()
        x[held] = max(share * total, floor)
        if delays:
            x[delays] = max(total - float(x[held[0]]), least_delay(pb))
        out.append(x)
    values = [float(x[held[0]]) for x in out]
    # every delay start the scan lists runs (the lowest cost of all is kept);
    # the best's own split of the delay only where the caller gave a latency
    free = xs if "latency" in start else xs[1:]
    return out + free, {**scan, "latency_profile_s": values}


def _delay_starts(residual_fn: Any, pb: _Problem, x0: np.ndarray,
                  start: dict[str, float]) -> tuple[list[np.ndarray], dict[str, Any]]:
    """The delay's starts: its scan's minima, and the caller's own."""
    base = with_start(pb, x0, start)
    delays = _delays(pb)
    if not delays:
        return [base], {}
    grid, cost = delay_scan(residual_fn, pb, base)
    if not np.any(np.isfinite(cost)):
        return [base], {"grid_s": grid.tolist(), "cost": cost.tolist()}
    # the grid's local minima, lowest first
    interior = [k for k in range(len(grid)) if np.isfinite(cost[k])
                and (k == 0 or cost[k] <= cost[k - 1]) and (k == len(grid) - 1 or cost[k] <= cost[k + 1])]
    interior.sort(key=lambda k: cost[k])
    found = [interior[0]] + [k for k in interior[1:2] if cost[k] <= SECOND * cost[interior[0]]]
    lo = least_delay(pb)
    out: list[np.ndarray] = []
    for k in found:
        x = base.copy()
        x[delays] = max(_refine(grid, cost, k), lo)
        out.append(x)
    if "delay" in start and not any(abs(float(x[delays[0]]) - base[delays[0]]) < 1e-12 for x in out):
        # the caller's own start runs too: the lowest cost of all is kept
        out.append(base)
    return out, {"grid_s": grid.tolist(), "cost": cost.tolist(),
                 "starts_s": [float(x[delays[0]]) for x in out]}
