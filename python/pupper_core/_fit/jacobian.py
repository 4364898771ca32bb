"""A fit's Jacobian by legs (``pupper_core._fit`` hands it to the
optimizer): the robot hangs from a welded base, so its legs do not
interact, and a parameter of one leg moves that leg's signals only. One
rollout then perturbs a parameter on every leg at once (a "colour": at
most one parameter per leg), and each leg's rows of the residual give
that leg's parameter its column. A per-joint fit's 72 parameters take 18
perturbed rollouts, as a per-group fit's 18 do; a parameter spanning legs
(per all, per group) is a colour of its own."""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from pupper_core._fit.problem import _Problem
from pupper_core._fit.robot import Robot


def _leg(pb: _Problem, members: list[int]) -> int | None:
    """The one leg a parameter's joints are on; None where they span legs
    (or the model names none)."""
    mine = {pb.robot.legs[i] for i in members} if pb.robot.legs else {-1}
    return next(iter(mine)) if len(mine) == 1 and -1 not in mine else None


def colours(pb: _Problem) -> list[list[int]]:
    """The parameters (indices into ``pb.labels``) perturbed together."""
    out: list[list[int]] = []
    used: list[set[int | None]] = []
    for p, (_, _, members, _) in enumerate(pb.labels):
        leg = _leg(pb, members)
        spot = next((c for c, seen in enumerate(used) if leg is not None and None not in seen and leg not in seen),
                    None)
        if spot is None:
            out.append([p])
            used.append({leg})
        else:
            out[spot].append(p)
            used[spot].add(leg)
    return out


def rollouts_per_jacobian(robot: Robot, per: str, kinds: int) -> int:
    """The perturbed rollouts of a Jacobian, before the problem is set:
    per joint, a parameter of each kind for the most joints a leg has; else
    one per parameter."""
    sets = robot.members(per)
    if per != "joint" or not robot.legs or -1 in robot.legs:
        return kinds * len(sets)
    return kinds * max(robot.legs.count(leg) for leg in set(robot.legs))


def jacobian_fn(residual_fn: Any, params: Any, pb: _Problem, eps: float = float(np.finfo(np.float64).eps) ** 0.5
                ) -> Callable[[np.ndarray, np.ndarray], np.ndarray] | None:
    """The Jacobian by colours (as mujoco.minimize's finite differences
    step: forward, away from the nearer bound, the step scaled by |x|), or
    None where no two parameters share a colour (the optimizer's own is
    the same then)."""
    groups = colours(pb)
    if len(groups) == len(pb.labels):
        return None
    nu = len(pb.robot.actuators)
    legs = pb.robot.legs
    # each residual row's signal: every log's block is its samples times its signals, signal fastest
    signal_leg = [np.array([legs[s % nu] for s in pb.sensors_of(i)]) for i in range(len(pb.logs))]
    param_leg = [_leg(pb, members) for _, _, members, _ in pb.labels]
    lo, hi = (np.asarray(b, dtype=float).reshape(-1, 1) for b in params.get_bounds())
    start = params.copy()

    def residual(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r, _, _ = residual_fn(x, start)
        return np.concatenate(r), np.concatenate([np.resize(sl, len(ri)) for sl, ri in zip(signal_leg, r)])

    def jacobian(x: np.ndarray, r: np.ndarray) -> np.ndarray:
        n = x.shape[0]
        step = np.where((x > 0.5 * (lo + hi)) | (x == hi), -eps, eps) * np.maximum(1.0, np.abs(x))
        xh = np.tile(x, (1, len(groups)))
        for c, members in enumerate(groups):
            xh[members, c] += step[members, 0]
        np.clip(xh, lo, hi, out=xh)
        rh, rows = residual(xh)
        jac = np.zeros((r.shape[0], n))
        for c, members in enumerate(groups):
            d = rh[:, c] - r[:, 0]
            for p in members:
                h = xh[p, c] - x[p, 0]
                on = slice(None) if param_leg[p] is None else rows == param_leg[p]
                jac[on, p] = d[on] / h
        return jac

    return jacobian
