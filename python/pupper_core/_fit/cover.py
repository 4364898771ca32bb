"""Logs of different motors in one fit (``pupper_core._fit.problem`` sets
it up): which actuators each log compares, and which parameters such a
fit has.

A bench logs one motor at a time, so the logs of one sitting cover
different actuators. Each log is compared on the actuators it logs (and
moves) alone; the others it holds, as any log does. What the logs share
is the motor: its parameters (the gain scales, the delay, the torque's
lag, the feedback latency, the friction loss, ``MOTOR_KINDS`` of
``judge``) are one per motor type under ``--per all`` (a type: the torque
limit, all a model says of a motor), one per joint group or per joint as
``--per`` says; what belongs to the link (``LINK_KINDS``: the armature
that carries its inertia, its damping) stays per joint. Logs that all
cover the same actuators are set up as they always were."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from pupper_core._fit.log import JointLog
from pupper_core._fit.robot import Robot
from pupper_core._fit.terms import STILL_RAD, FitError

#: The link's own parameters: per joint in a fit of several motors' logs
#: (every other kind is the motor's, shared by motors of one type).
LINK_KINDS = ("armature", "damping")


def differ(read: list[JointLog]) -> bool:
    """Whether the logs cover different actuators."""
    return len({frozenset(lg.logged) for lg in read}) > 1


def type_sets(robot: Robot) -> list[tuple[str, list[int]]]:
    """The actuators by motor type (their torque limit): one set named ""
    where the model has one type, else one per type named by its limit."""
    types: dict[float, list[int]] = {}
    for k, limit in enumerate(robot.limits):
        types.setdefault(float(limit), []).append(k)
    if len(types) == 1:
        return [("", list(range(len(robot.actuators))))]
    return [(f".{t:g}Nm" if math.isfinite(t) else ".unlimited", m) for t, m in sorted(types.items())]


def parameter_sets(robot: Robot, kind: str, per: str, several: bool) -> list[tuple[str, list[int]]]:
    """The sets of actuators that get one value of ``kind`` each: ``per``'s
    (``Robot.members``), or in a fit of several motors (``several``) the
    link's parameters per joint and the motor's per type (--per all)."""
    if not several:
        return robot.members(per)
    if kind in LINK_KINDS or per == "joint":
        return robot.members("joint")
    return robot.members("group") if per == "group" else type_sets(robot)


def _order(lg: JointLog, robot: Robot) -> list[int]:
    return [lg.actuators.index(a) for a in robot.actuators]


def sensors_by_log(robot: Robot, read: list[JointLog], has_qd: bool,
                   has_tau: bool) -> tuple[list[int], list[list[int]], list[str], list[str]]:
    """Each log's compared signals (indices into angles, velocities,
    torques x actuators): its logged actuators' angles where they move, and
    their velocity and torque columns where every log has them and this
    one's are not all zero. Returns every signal some log compares, each
    log's, the warnings (a logged joint still, a column all zero) and a
    note that says who compares what."""
    nu = len(robot.actuators)
    warnings: list[str] = []
    by_log: list[list[int]] = []
    moving: dict[int, list[str]] = {}
    still: dict[int, list[tuple[str, float]]] = {}
    for lg in read:
        order = _order(lg, robot)
        mine = []
        for k, a in enumerate(robot.actuators):
            if a not in lg.logged:
                continue
            if float(np.ptp(lg.q[:, order[k]])) <= STILL_RAD:
                still.setdefault(k, []).append((lg.path.name, float(lg.q[0, order[k]])))
            else:
                mine.append(k)
                moving.setdefault(k, []).append(lg.path.name)
        by_log.append(mine)
    for lg, mine in zip(read, by_log):
        if not mine:
            raise FitError(f"no joint it logs moves in {lg.path.name} (every angle column is constant): it shows "
                           "nothing to fit; leave it out, or log a run where the joints move (pupper excite writes "
                           "its targets)")
    for k, where in sorted(still.items()):
        name, angle = where[0]
        fate = (f"compared only where it moves ({_names(moving[k])})" if k in moving
                else "left out of the fit")
        warnings.append(f"{robot.actuators[k]} never moves in {name} (its angle stays at {angle:.6g} rad): {fate}")
    out: list[list[int]] = []
    for lg, mine in zip(read, by_log):
        order = _order(lg, robot)
        signals = list(mine)
        for block, fld, on in ((1, "qd", has_qd), (2, "tau", has_tau)):
            for k in (k for k in mine if on):
                if not np.any(getattr(lg, fld)[:, order[k]]):
                    warnings.append(f"{lg.path.name}: column '{robot.actuators[k]}.{fld}' is all zero: left out "
                                    "of the fit (drop the column if the servo does not report it)")
                else:
                    signals.append(block * nu + k)
        out.append(signals)
    union = sorted({s for signals in out for s in signals})
    covered = ", ".join(f"{robot.actuators[k]} in {len(moving[k])}" for k in sorted(moving))
    note = (f"the logs cover different actuators: each is compared on those it logs ({covered} of {len(read)}); "
            "the motor's parameters are shared by the motors of one type (or per --per), the link's (armature, "
            "damping) per joint")
    return union, out, warnings, [note]


def _names(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def row_segments(segment_of: Callable[[list[np.ndarray], int, float, float], np.ndarray | None], times: list[np.ndarray], signals: list[int], period: float,
                 tau: float) -> np.ndarray | None:
    """Each residual row's segment where the logs compare different numbers
    of signals (``segment_of``: ``intervals.segments``, which takes one
    count): its segments per sample, each repeated by its own log's count."""
    per_sample = segment_of(times, 1, period, tau)
    if per_sample is None:
        return None
    out, at = [], 0
    for t, n in zip(times, signals):
        out.append(np.repeat(per_sample[at:at + len(t)], n))
        at += len(t)
    return np.concatenate(out)
