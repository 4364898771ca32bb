"""The robots a fit's logs allow (``pupper_core._fit`` draws them,
`recommend --from-fit` stands every candidate on them and closes their
loops): draws from the fit's joint distribution that still follow its
logs, each replayed on them.

Logs of angles pin combinations of parameters, not each alone: the
natural frequency (the delivered kp over the joint's inertia) is known far
better than the kp scale or the armature, whose intervals reach below 0
on a real Pupper v3 knee. The corners of independent intervals (the least
inertia with the most kp) are robots the logs rule out. A draw from the
fit's covariance (its correlations with each parameter's interval as its
spread: ``Σ = S·C·S``, ``S`` the half-widths over 1.96) keeps the
combinations the noise pins; but where the intervals are widened for
model error (a real motor's), such draws also step across the valley the
logs pin, and replayed on them erred 2 to 6 times the fit's residual. So
each draw is then drawn back towards the fit along its own direction
until the Gauss–Newton model of the cost (``|J·δ|²`` over the fit's own)
says its RMS error is within ``RATIO`` of the fit's: along the valley a
draw keeps its whole spread, across it only what the logs allow. Draws
come in antithetic pairs (a draw and its mirror about the fit), each value
inside its parameter's bounds; a parameter the logs do not determine (an
infinite interval) stays at its fitted value.

Each robot is replayed on the fit's logs: its RMS angle error beside the
fit's says how far from the logs the worst robot really is (manifest.json's
``robots``, robots.csv); one that the quadratic model misjudged is drawn
back once more by what the replay measured."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pupper_core._fit.terms import PARAMS

#: Robots a fit draws (recommend's joint models: an equal share of its robots each).
ROBOTS = 8
#: A 95 % interval's half-width in standard deviations.
Z95 = 1.959963984540054
#: The seed of the draws: the same fit draws the same robots.
SEED = 0
#: A robot the logs allow errs on them by at most this much more than the
#: fit (RMS): about the spread between one motor's logs at two gains (the
#: real hip's kp 7.5 log, fitted with its kp 5 one: 7.7 against 6.1 mrad).
RATIO = 1.25
#: At most this many replays draw one robot back where the quadratic model misjudged it.
REPLAYS = 4


@dataclass
class Drawn:
    """The drawn robots: their values (robots x parameters), each one's RMS
    angle error over the logs (rad, the mean over logs and joints, as the
    fit's is), the fit's own, and the parameters held at the fitted value."""

    x: np.ndarray
    rms: list[float]
    fitted_rms: float
    held: list[str] = field(default_factory=list)

    @property
    def worst_ratio(self) -> float:
        """The worst robot's RMS error over the fit's."""
        return max(self.rms) / self.fitted_rms if self.rms and self.fitted_rms > 0 else math.nan

    def manifest(self) -> dict[str, Any]:
        return {"count": len(self.rms), "how": "the fit's joint distribution: its correlations with each "
                "parameter's 95 % interval as its spread (Σ = S·C·S, S the half-widths over 1.96), in antithetic "
                f"pairs, each draw drawn back towards the fit until the cost's Gauss-Newton model puts its RMS "
                f"error within {RATIO:g} of the fit's (then by the replay's own measure), each value inside "
                "its parameter's bounds; a parameter the logs do not determine held at its fitted value",
                "seed": SEED, "ratio": RATIO, "held": self.held, "rms_rad": self.rms,
                "fitted_rms_rad": self.fitted_rms, "worst_over_fitted": self.worst_ratio}


def covariance(half: np.ndarray, corr: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """The covariance the intervals and correlations say over the parameters
    the logs determine, and which those are (a mask)."""
    free = np.isfinite(half) & (half > 0)
    s = np.where(free, half, 0.0) / Z95
    c = np.eye(len(half)) if corr is None or corr.shape != (len(half), len(half)) else np.nan_to_num(corr)
    np.fill_diagonal(c, 1.0)
    cov = s[:, None] * c * s[None, :]
    return cov[np.ix_(free, free)], free


def draws(x: np.ndarray, half: np.ndarray, corr: np.ndarray | None, kinds: list[str],
          count: int = ROBOTS, seed: int = SEED) -> np.ndarray:
    """``count`` steps (rows) about the fit ``x``: antithetic pairs from the
    covariance (``covariance``); the parameters the logs do not determine
    do not move."""
    cov, free = covariance(half, corr)
    # a square root of a covariance that round-off left a hair indefinite
    w, v = np.linalg.eigh(cov) if free.any() else (np.zeros(0), np.zeros((0, 0)))
    root = v * np.sqrt(np.clip(w, 0.0, None))[None, :]
    rng = np.random.default_rng(seed)
    z = rng.standard_normal((count // 2 + count % 2, int(free.sum())))
    z = np.concatenate([z, -z])[:count]
    steps = np.zeros((count, len(x)))
    steps[:, free] = z @ root.T
    return steps


def bounded(x: np.ndarray, kinds: list[str]) -> np.ndarray:
    """``x`` (rows of values) inside each kind's bounds (``PARAMS``)."""
    lo = np.array([PARAMS[k][1] for k in kinds])
    hi = np.array([PARAMS[k][2] for k in kinds])
    return np.asarray(np.clip(x, lo, hi))


def drawn_back(steps: np.ndarray, jac: np.ndarray | None, cost: float, ratio: float = RATIO) -> np.ndarray:
    """Each step shortened along itself until the Gauss–Newton model of the
    cost rise, |J·δ|², keeps the RMS error within ``ratio`` of the fit's
    (``cost``: the fit's sum of squares); steps already inside kept whole."""
    if jac is None or not np.all(np.isfinite(jac)) or cost <= 0:
        return steps
    room = (ratio ** 2 - 1) * cost
    rise = np.sum(np.square(steps @ jac.T), axis=1)
    scale = np.where(rise > room, np.sqrt(room / np.maximum(rise, 1e-300)), 1.0)
    return np.asarray(steps * scale[:, None])


def robots(pb: Any, sol: Any, count: int = ROBOTS) -> Drawn | None:
    """The robots of a fit (``pb``, its problem; ``sol``, where it ended),
    each replayed on its logs; None where the fit has no intervals (it kept
    the nominal values) or no log replays."""
    from pupper_core._fit.sysid import _predictions, _rms

    if sol.jac is None or not np.any(np.isfinite(sol.half)):
        return None
    kinds = [label[1] for label in pb.labels]
    x0 = np.asarray(sol.x, dtype=float)
    r, _, _ = sol.residual_fn(x0, sol.params)
    cost = float(sum(np.sum(np.square(ri)) for ri in r))
    steps = drawn_back(draws(x0, np.asarray(sol.half, dtype=float), sol.corr, kinds, count), sol.jac, cost)
    nu = len(pb.robot.actuators)
    by_log = [pb.sensors_of(i) for i in range(len(pb.logs))]

    def mean_rms(x: np.ndarray) -> float:
        per_log = _rms(_predictions(sol.residual_fn, sol.params, x), by_log, nu)
        return float(np.mean([np.mean(r) for r in per_log if r]))

    fitted = mean_rms(x0)
    xs = bounded(x0[None, :] + steps, kinds)
    rms = [mean_rms(x) for x in xs]
    for k in range(len(xs)):
        # where the quadratic model misjudged it: drawn back by what the
        # replay measured (the cost rise taken as quadratic along the step)
        f = 1.0
        for _ in range(REPLAYS):
            if not (fitted > 0 and rms[k] > RATIO * fitted):
                break
            f *= math.sqrt((RATIO ** 2 - 1) / max((rms[k] / fitted) ** 2 - 1, 1e-12)) * 0.98
            xs[k] = bounded(x0 + steps[k] * f, kinds)
            rms[k] = mean_rms(xs[k])
    held = [pb.labels[i][0] for i in np.flatnonzero(~(np.isfinite(sol.half) & (sol.half > 0)))]
    return Drawn(xs, rms, fitted, held)
