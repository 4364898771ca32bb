"""What `recommend` found (`pupper_core.Recommendation`) and a joint
group's card in it."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pupper_core._recommend.plan import Plan
from pupper_core._recommend.search import Candidate


@dataclass
class Recommendation:
    """What `recommend` found: the pick (None when no candidate held every
    constraint), its card per group, every candidate, the run directory."""

    pick: Candidate | None
    cards: list[Card]
    candidates: list[Candidate]
    plan: Plan
    out: Path | None
    yaml: str = ""
    mjcf: str = ""
    neighbours: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: the pick as the search measured it (on the model it read; the card's
    #: numbers are the exported MJCF's)
    searched: Candidate | None = None
    #: the gains the robot runs today (`Plan.current`) on the same robots
    current: Candidate | None = None
    #: the groups whose loop margins hold nowhere in their searched ranges
    #: (then no candidate is asked at all)
    no_window: list[str] = field(default_factory=list)
    #: with no pick: the best available gains (``short``), and how they fall short
    nearest: Candidate | None = None
    #: with no pick: what the task finds the best available can still do (``Task.unanswered``)
    short_lines: list[str] = field(default_factory=list)
    #: what the task found beside the pick (`Task.after`; the walk task:
    #: the pick beside --task stand's); None for the stand task
    beside: Any = None

    @property
    def gains(self) -> dict[str, tuple[float, float]]:
        """The recommended (kp, kd) per joint group; empty without a pick."""
        return dict(self.pick.gains) if self.pick else {}

    def to_pandas(self) -> Any:
        """Every candidate as a pandas DataFrame (trials.csv's columns)."""
        try:
            import pandas as pd
        except ImportError as e:
            raise ImportError("Recommendation.to_pandas needs pandas: pip install pandas") from e
        return pd.DataFrame([c.row(self.plan.groups, self.plan.task) for c in self.candidates])

    def __repr__(self) -> str:
        if not self.pick:
            return f"Recommendation(no pick over {len(self.candidates)} candidates)"
        g = ", ".join(f"{k} kp {p:.4g} kd {d:.4g}" for k, (p, d) in self.pick.gains.items())
        return f"Recommendation({g}; {self.plan.task.says(self.pick.score)} on {self.plan.robots} robots)"


@dataclass
class Card:
    """One joint group's recommendation."""

    group: str
    kp: float
    kd: float
    phase_margin_deg: float
    gain_margin_db: float
    rise_time_s: float
    overshoot_pct: float
    settling_time_s: float
    p95_push_dip_mm: float
    p95_peak_torque: float
    torque_limit: float
    torque_headroom_pct: float
    #: what the motors deliver of kp and kd (the model's gain scales, a
    #: fit's; None where they are 1): the margins are of these
    motor_kp: float | None = None
    motor_kd: float | None = None
