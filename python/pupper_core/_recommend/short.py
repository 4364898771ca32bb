"""When no gains hold every constraint: the best available, and by how
much it falls short (``_recommend`` names it beside the gains in use,
prints it and exits with NO_ANSWER).

Where a group's loop margins hold nowhere in its searched range, the best
available is each group's gains with the best worst-case margins there (a
kp × kd map, the margins' slack: a decibel weighs as five degrees);
where candidates ran on the robots and none held, it is the one that came
closest (the fewest robots failing, then the best slack)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from pupper_core._recommend.plan import Plan
from pupper_core._recommend.search import MAP_POINTS, Candidate, check_margins, margins, rounded

#: The exit status of a recommend that names no gains: none held every
#: constraint (0: gains named; 1: an internal error; 2: bad input).
NO_ANSWER = 3


def _slack(plan: Plan, pm: float, gm: float) -> float:
    return min(pm - plan.min_phase_margin, 5 * (gm - plan.min_gain_margin))


def best_margins(plan: Plan) -> Candidate:
    """Each group's gains with the best worst-case loop margins over its
    searched range (a MAP_POINTS² log grid), their margins filled."""
    gains = {}
    for g in plan.groups:
        best, where = -math.inf, (g.kp_range[0], g.kd_range[0])
        for kp in np.geomspace(*g.kp_range, MAP_POINTS):
            for kd in np.geomspace(*g.kd_range, MAP_POINTS):
                s = _slack(plan, *margins(plan, g, float(kp), float(kd)))
                if s > best:
                    best, where = s, rounded(float(kp), float(kd))
        gains[g.name] = where
    c = Candidate(gains, stage="the best worst-case loop margins in the searched range")
    check_margins(plan, c)
    return c


def deficit(plan: Plan, c: Candidate) -> float:
    """How far a simulated candidate falls short of the constraints it
    breaks on the robots, each as a share of its limit: the sag below the
    stance height allowed, the saturation past its limit (0: none)."""
    out = 0.0
    if math.isfinite(plan.stance) and math.isfinite(c.min_height_m):
        out += max(0.0, (1 - plan.max_sag) - c.min_height_m / plan.stance)
    if math.isfinite(c.max_saturation):
        out += max(0.0, c.max_saturation - plan.max_saturation) / plan.max_saturation
    return out


def closest(plan: Plan, cands: Sequence[Candidate]) -> Candidate | None:
    """The candidate that ran on the robots and came closest to holding:
    the fewest robots failing, then the least short of the constraints it
    breaks (``deficit``), then the best worst-group margin slack."""
    ran = [c for c in cands if c.robots]
    if not ran:
        return None

    def key(c: Candidate) -> tuple[float, float, float]:
        slack = min(_slack(plan, c.phase_deg[g.name], c.gain_db[g.name]) for g in plan.groups)
        return (c.fell, deficit(plan, c), -slack)

    import dataclasses

    return dataclasses.replace(min(ran, key=key), stage="the candidate that came closest to holding")


def shortfall(plan: Plan, c: Candidate) -> str:
    """How the best available falls short, in words: each margin below
    its threshold ("below the threshold: 24.3° where 30° was asked"), else
    the constraint it breaks on the robots."""
    parts = []
    for g in plan.groups:
        pm, gm = c.phase_deg[g.name], c.gain_db[g.name]
        if not pm >= plan.min_phase_margin:
            parts.append(f"{g.name} phase margin {pm:.1f}° where {plan.min_phase_margin:g}° was asked")
        if not gm >= plan.min_gain_margin:
            parts.append(f"{g.name} gain margin {gm:.1f} dB where {plan.min_gain_margin:g} dB was asked")
    if parts:
        return "below the threshold: " + "; ".join(parts)
    if c.failed.startswith("sags") and math.isfinite(plan.stance):
        short = ((1 - plan.max_sag) * plan.stance - c.min_height_m) * 1000
        return (f"{c.failed}: {short:.1f} mm short of it; stiffer gains hold the robot higher (raise --kp-max if "
                "the motors take more), or --max-sag accepts the sag")
    return c.failed or "it broke no constraint the search checks"


def line(plan: Plan, c: Candidate) -> str:
    """The best available gains in a line, and how they fall short."""
    gains = ", ".join(f"{g} kp {kp:.4g} kd {kd:.4g}" for g, (kp, kd) in c.gains.items())
    worst = min(plan.groups, key=lambda g: c.phase_deg[g.name])
    return (f"best available ({c.stage}): {gains}; worst loop {worst.name} phase {c.phase_deg[worst.name]:.1f}°, "
            f"gain {min(c.gain_db.values()):.1f} dB; {shortfall(plan, c)}")
