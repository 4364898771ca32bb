"""`pupper recommend`'s plan (``inputs`` checks the keywords into one): the
model's joint groups and their own gains, the searched ranges, the robots
drawn from what the model does not know, the firmware, the constraints.

Everything model-specific comes from the model: the groups and each
actuator's own gains (the search spans a decade below and a factor of 20
above them, capped by the model's `pupper:kp_max:ACT` / `pupper:kd_max:ACT`
custom numerics or --kp-max / --kd-max), its timestep and torque limits.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

from pupper_core._native import ConfigError

#: The spread a robot owner's Pupper plausibly differs from its model by,
#: when no fit says better: battery and payload, leg parts, what each motor
#: delivers of its gains, the floor, and the encoder's noise (rad). The
#: sensing latency (whole steps, from --sensing-delay) is added to it.
DEFAULT_SPREAD = ("torso_mass=±15%", "leg_mass=±10%", "motor_gain=±10%", "friction=0.6:1.2",
                  "q_noise=N(0,0.001)")
#: The firmware: the PD updated at 500 Hz (Pupper v3's control rate) on a
#: 14-bit encoder, its derivative the encoder's difference over a period.
DEFAULT_MOTOR = "rate=500,counts=16384"
#: Robots drawn from a fit's intervals: joint models, each run on an equal
#: share of the robots.
FIT_MODELS = 8
#: A neighbour of the pick, per group: its kp or kd times or over this.
NEIGHBOUR = 1.25


class RecommendError(ConfigError, ValueError):
    """Bad input to `recommend`: one line naming the problem and the fix."""


class Task:
    """What the gains are ranked for (`--task`), and all that changes with
    it: the measure the rule ranks (lower wins), the run each candidate
    makes on the robots, the words of the card. The stand task (a push,
    its worst-side dip) is `stand.Stand`; each task is a row of
    `inputs.TASKS`. A candidate here is a `search.Candidate`, a result a
    `result.Recommendation` (the layers above)."""

    #: its name, as --task gives it, and what it ranks by in a few words
    name = "stand"
    about = "a push"
    #: what the rule ranks: in words, as trials.csv names it, and its unit
    objective = "p95 push dip"
    column = "p95_push_dip_mm"
    unit = "mm"
    #: simulated seconds per robot unless --seconds says
    seconds = 4.0
    #: recommend()'s keywords that set the task (one of another task's is
    #: refused)
    options: tuple[str, ...] = ()

    @classmethod
    def of(cls, options: Mapping[str, Any]) -> Task:
        """The task set by its keywords (those given), each checked."""
        return cls(**options)

    def value(self, v: float) -> str:
        """A ranked value with its unit: "2.631 mm"."""
        return f"{v:.4g} {self.unit}"

    def says(self, v: float) -> str:
        """A ranked value, named: "p95 push dip 2.631 mm"."""
        return f"{self.objective} {self.value(v)}"

    @property
    def measure(self) -> str:
        """What is measured, without its statistic: "push dip"."""
        return self.objective.removeprefix("p95 ")

    def check_run(self, seconds: float, push_force: float | None) -> None:
        """Refuses, in one line and before the model is read, a run the
        task cannot measure: too short, or pushed when it has no push."""

    def check(self, plan: Plan) -> None:
        """Refuses, in one line, a plan the task cannot rank (once every
        input is read)."""

    def inputs(self) -> dict[str, Any]:
        """What the manifest records of the task (beside the plan's)."""
        return {}

    def heading(self) -> str:
        """The card's first line names what the gains hold for: "" (the
        stand), or " for a trot at 2 Hz and 0.25 m/s"."""
        return ""

    def constraints(self) -> str:
        """The task's own constraints, in words, as the card lists them."""
        return ""

    def simulate(self, plan: Plan, cands: Sequence[Any], robot_models: Sequence[str],
                 say: Callable[[str], None], own_gains: bool = False) -> None:
        """Runs the candidates on every drawn robot and judges each: its
        score (what the rule ranks), falls, saturation, peak torque, sag."""
        raise NotImplementedError

    def row(self, c: Any) -> dict[str, Any]:
        """A candidate's figures of the task, as trials.csv has them."""
        raise NotImplementedError

    def card_line(self, plan: Plan, pick: Any, searched: Any) -> str:
        """The card's line of the pick's figures (before its torque)."""
        raise NotImplementedError

    def card_columns(self, plan: Plan, pick: Any) -> dict[str, Any]:
        """The task's columns of recommend.csv, beside each group's card."""
        return {}

    def reproduce(self, plan: Plan, d: Path) -> str:
        """The command that gives the card's figures again ("" where none
        can: robots drawn from a fit)."""
        raise NotImplementedError

    def after(self, rec: Any, models: Sequence[str], say: Callable[[str], None], wins: Mapping[str, Any]) -> None:
        """What the task adds once the card is made (the walk task: the
        pick beside --task stand's)."""

    def lines(self, rec: Any) -> list[str]:
        """The card's closing lines of the task."""
        return []

    def unanswered(self, rec: Any, models: Sequence[str], say: Callable[[str], None]) -> list[str]:
        """With no gains named: what the task finds the best available can
        still do (the walk task: the gait they walk best), as card lines."""
        return []

    def manifest(self, rec: Any) -> dict[str, Any]:
        """What the manifest records of the task's own findings."""
        return {}


class Loop(NamedTuple):
    """One joint's servo loop, as the margins close it: what its motor
    delivers of a commanded kp and kd, its reflected inertia (kg·m²) and
    viscous damping (N·m·s/rad), and its fitted torque lag and feedback
    latency (s; 0 on a model no fit calibrated)."""

    kp_scale: float
    kd_scale: float
    inertia: float
    damping: float = 0.0
    lag: float = 0.0
    latency: float = 0.0


@dataclass(frozen=True)
class Group:
    """A joint group: its actuators (indices in the model's order), the
    searched ranges, its joints' reflected inertia (the smallest: the
    loop with the least inertia crosses over highest)."""

    name: str
    actuators: tuple[int, ...]
    kp_range: tuple[float, float]
    kd_range: tuple[float, float]
    #: the least and most reflected inertia its joints may have (kg·m²)
    inertia: tuple[float, float]
    #: the smallest torque limit of its actuators (N·m): the force range,
    #: else (a motor) the control range, as the runs take it
    torque_limit: float
    #: its joints' loops the margins are checked on (``Loop``): each kind of
    #: motor's scales (the model's gain scales, `pupper:kp_scale:ACT`: a
    #: fit's; (1, 1) on an uncalibrated model) on its joints' least and most
    #: inertia, or with a fit every drawn robot's joints as the logs allow
    #: them. The loop is closed on the delivered gains.
    loops: tuple[Loop, ...] = ()

    @property
    def scales(self) -> tuple[tuple[float, float], ...]:
        return tuple(dict.fromkeys((lp.kp_scale, lp.kd_scale) for lp in self.loops)) or ((1.0, 1.0),)

    @property
    def scaled(self) -> bool:
        """Whether its motors deliver other gains than they are told."""
        return self.scales != ((1.0, 1.0),)

    @property
    def kp_scale(self) -> tuple[float, float]:
        """The least and most of a commanded kp its motors deliver."""
        return min(s[0] for s in self.scales), max(s[0] for s in self.scales)

    @property
    def kd_scale(self) -> tuple[float, float]:
        return min(s[1] for s in self.scales), max(s[1] for s in self.scales)


@dataclass
class Plan:
    model: str
    actuators: list[str]
    groups: list[Group]
    timestep: float
    motor: str
    #: the feedback latency given (--sensing-delay, s); None: the model's
    #: own (a fit's, per robot; none on an uncalibrated model)
    sensing_delay: float | None
    command_delay: float
    spread: list[str]
    #: the least and most of a commanded kp and kd the motors deliver,
    #: relative to the model's own gain scales (the spread's motor_gain, or
    #: a fit's intervals about its fitted scales); `Group.kp_scale` are those
    kp_factors: tuple[float, float]
    kd_factors: tuple[float, float]
    robots: int
    trials: int
    batch: int
    seed: int
    seconds: float
    push_force: float | None
    #: degrees and decibels every group's loop must keep
    min_phase_margin: float
    min_gain_margin: float
    max_saturation: float
    joint_order: list[str]
    controller: str
    #: how many times the pick may move to a better neighbour
    polish: int
    #: the most a robot may sag below its stance height (a share of it)
    max_sag: float
    #: the stance height (m): the base height with the lowest foot on the
    #: floor in the start pose (NaN for a fixed base: no sag constraint)
    stance: float
    from_fit: Path | None
    #: the fitted values and intervals (rows of fit.csv)
    fit_rows: list[dict[str, str]] = field(default_factory=list)
    #: with a fit: the robots its logs allow (its robots.csv), each one's value of every fit row
    fit_robots: list[list[float]] = field(default_factory=list)
    #: with a fit: how far the worst drawn robot is from the logs (its RMS error over the fit's)
    fit_robots_worst: float = math.nan
    #: the gains the robot runs today, per group, set beside the pick on the
    #: card (empty: none known), and where they came from
    current: dict[str, tuple[float, float]] = field(default_factory=dict)
    current_from: str = ""
    #: whether motor caps (--kp-max and --kd-max, or the model's numerics)
    #: bound every group's search, rather than the defaults' x20 and x50
    caps: bool = False
    #: with a fit: which latencies the margins and robots assumed, and where each came from
    latency_from: str = ""
    #: several fit runs merged into one model (``fits.merged``): the runs, and the model's MJCF, which the
    #: run directory keeps as calibrated.xml (``model`` is that file once the run starts)
    fit_runs: list[Path] = field(default_factory=list)
    merged_xml: str = ""
    #: what the gains are ranked for (--task)
    task: Task = field(kw_only=True)

    @property
    def calibrated(self) -> bool:
        """Whether the robot is a calibrated model (a fit's, or a model with
        fitted gain scales or servo times): never "the nominal robot"."""
        return bool(self.fit_rows) or any(lp.lag or lp.latency or (lp.kp_scale, lp.kd_scale) != (1.0, 1.0)
                                          for g in self.groups for lp in g.loops)

    def latency_words(self) -> str:
        """The feedback latency the margins assume, in a few words."""
        if self.sensing_delay is not None:
            return f"sensing delay {self.sensing_delay:g} s"
        return "the fit's own latency" if self.fit_rows else "the model's own latency"

    def sags(self, height: float) -> bool:
        """Whether a robot whose lowest final base height is `height` (m)
        sags past the limit (never, on a fixed base)."""
        return math.isfinite(self.stance) and not height >= (1 - self.max_sag) * self.stance

    @property
    def per_model(self) -> int:
        """Robots per joint model: all on the one model, or an equal share
        of each drawn from a fit."""
        return self.robots // max(1, len(self.fit_robots))

    def sweep_options(self) -> dict[str, Any]:
        """The sweep every candidate runs: torque mode through the firmware,
        the robots drawn alike for every candidate (common draws)."""
        opts: dict[str, Any] = {"mode": "torque", "motor": self.motor, "seconds": self.seconds,
                                "seed": self.seed, "randomize": list(self.spread), "common_draws": True}
        if self.push_force is not None:
            opts["push_force"] = self.push_force
        return opts

    def inputs(self) -> dict[str, Any]:
        """What the manifest records."""
        return {
            "model": self.model, "robots": self.robots, "trials": self.trials, "batch": self.batch,
            "seed": self.seed, "seconds": self.seconds, "push_force": self.push_force, "motor": self.motor,
            "sensing_delay": self.sensing_delay, "command_delay": self.command_delay, "spread": self.spread,
            "kp_factors": list(self.kp_factors), "kd_factors": list(self.kd_factors),
            "inertia": {g.name: list(g.inertia) for g in self.groups}, "min_phase_margin_deg": self.min_phase_margin,
            "min_gain_margin_db": self.min_gain_margin, "max_saturation": self.max_saturation,
            "max_sag": self.max_sag, "stance_m": self.stance,
            "ranges": {g.name: {"kp": list(g.kp_range), "kd": list(g.kd_range)} for g in self.groups},
            "joint_order": self.joint_order, "controller": self.controller, "polish": self.polish,
            "from_fit": ([os.fspath(d) for d in self.fit_runs] if self.fit_runs else
                         None if self.from_fit is None else os.fspath(self.from_fit)),
            "fit_robots": {"values": self.fit_robots, "worst_rms_over_fitted": self.fit_robots_worst,
                           "from": "the fit's robots.csv: draws from its joint distribution"}
            if self.fit_robots else None,
            # what the motors deliver of a commanded gain, per group: the loop is closed on it
            "delivered": {g.name: {"kp": [self.kp_factors[0] * g.kp_scale[0], self.kp_factors[1] * g.kp_scale[1]],
                                   "kd": [self.kd_factors[0] * g.kd_scale[0], self.kd_factors[1] * g.kd_scale[1]]}
                          for g in self.groups},
            "current": {g: list(v) for g, v in self.current.items()}, "current_from": self.current_from,
            **({"latency_from": self.latency_from} if self.latency_from else {}),
            **self.task.inputs(),
        }
