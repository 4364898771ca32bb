"""`pupper recommend --task walk`: the candidates are ranked by how the
drawn robots walk (`pupper walk`'s figures over its steady window, at the
task's gait and speed) instead of how they dip under a push; the margins,
the saturation, sag and fall constraints are recommend's own. The card
then sets the pick beside `--task stand`'s (the same robots, trials and
seed, its push test) and says how and why they differ."""

from __future__ import annotations

import math
import shlex
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core._recommend.plan import Plan, RecommendError, Task
from pupper_core._recommend.search import Candidate, Window, _cell, best_of, gains_key, judge, polish, search, simulate
from pupper_core._recommend.stand import Stand

#: The gaits `pupper walk` walks.
GAITS = ("trot", "walk", "pace", "bound")

#: The walk's figures a candidate keeps, each its worst side over the robots:
#: the ranked speed error (p95), the slowest robot's speed (p5), roll and
#: pitch (p95), the joints' response at the gait frequency (amplitude p5,
#: lag p95), the feet's slip (p95), and the largest roll or pitch RMS of any robot (the tilt
#: constraint).
WALK_FIGURES = ("p95_speed_error_pct", "p5_speed_ms", "p95_roll_rms_deg", "p95_pitch_rms_deg",
                "p5_amplitude_ratio", "p95_lag_ms", "p95_slip_mm_s", "max_tilt_rms_deg")

#: Per robot: the walk's columns the figures come from.
_COLUMNS = ("speed_error_pct", "speed_ms", "roll_rms_deg", "pitch_rms_deg", "amplitude_ratio", "lag_ms",
            "slip_mm_s", "peak_torque", "final_z", "saturation_frac")


def _pct(xs: Sequence[float], q: float) -> float:
    return float(np.percentile(xs, q)) if xs and all(math.isfinite(x) for x in xs) else math.nan


def simulate_walk(task: WalkTask, plan: Plan, cands: Sequence[Candidate], robot_models: Sequence[str],
                  say: Callable[[str], None], own_gains: bool = False, step_height: float | None = None) -> None:
    """Walks the candidates (margins already checked) on every drawn robot,
    the robots drawn alike for every candidate, and judges each: falls,
    saturation, sag (the final base height against the stance), tilt; its
    score the p95 speed error."""
    import warnings

    from pupper_core._run import walk

    if not cands:
        return
    cells: Any = None if own_gains else [_cell(plan, c.gains, f"c{i}") for i, c in enumerate(cands)]
    got: list[dict[str, list[float]]] = [{k: [] for k in _COLUMNS} for _ in cands]
    for model in robot_models:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = walk(cells, model=model, replicates=plan.per_model, progress=False, step_height=step_height,
                       **task.run_options(plan))
        for w in caught:
            say(f"note: {w.message}")
        reps = res.replicates if res.replicates is not None else res
        cols = {k: reps[k] for k in _COLUMNS}
        for n, (i, status) in enumerate(zip(reps["index"], reps["status"])):
            c = cands[int(i)]
            c.robots += 1
            if status not in ("ok", "saturated"):
                c.fell += 1
                continue
            for k in _COLUMNS:
                got[int(i)][k].append(float(cols[k][n]))
        for i, steps in enumerate(res.cell_steps):
            cands[i].cell_steps += int(steps or 0)
    for c, g in zip(cands, got):
        c.max_saturation = max(g["saturation_frac"], default=math.nan)
        c.p95_peak_torque = _pct(g["peak_torque"], 95)
        c.min_height_m = min(g["final_z"], default=math.nan)
        tilt = [max(r, p) for r, p in zip(g["roll_rms_deg"], g["pitch_rms_deg"])]
        c.figures = {"p95_speed_error_pct": _pct(g["speed_error_pct"], 95), "p5_speed_ms": _pct(g["speed_ms"], 5),
                  "p95_roll_rms_deg": _pct(g["roll_rms_deg"], 95), "p95_pitch_rms_deg": _pct(g["pitch_rms_deg"], 95),
                  "p5_amplitude_ratio": _pct(g["amplitude_ratio"], 5), "p95_lag_ms": _pct(g["lag_ms"], 95),
                  "p95_slip_mm_s": _pct(g["slip_mm_s"], 95),
                  "max_tilt_rms_deg": max(tilt, default=math.nan)}
        c.score = c.figures["p95_speed_error_pct"]
        judge(plan, c, "no speed error measured (the run holds no steady gait cycle)")
        if not c.failed and not c.figures["max_tilt_rms_deg"] <= task.max_tilt:
            c.failed = (f"rolls or pitches {c.figures['max_tilt_rms_deg']:.1f}° RMS on its worst robot "
                        f"(limit {task.max_tilt:g}°)")


def check_walk(task: WalkTask, plan: Plan) -> None:
    """One short walk of the nominal model, each group mid-range: the gait,
    its reach and the run's length checked by the Rust core (its own
    words) before the margin maps are spent."""
    from pupper_core._native import ConfigError
    from pupper_core._run import walk

    mid = {g.name: (math.sqrt(g.kp_range[0] * g.kp_range[1]), math.sqrt(g.kd_range[0] * g.kd_range[1]))
           for g in plan.groups}
    opts = {k: v for k, v in task.run_options(plan).items() if k not in ("randomize", "common_draws")}
    try:
        cells: Any = [_cell(plan, mid, "check")]
        walk(cells, model=plan.model, progress=False, **opts)
    except ConfigError as e:
        raise RecommendError(f"--task walk: {e}") from None


#: The gaits the best available gains walk when none holds: the gait frequency (Hz) and the step
#: height (m), slower than the classical 2 Hz trot, with lower and higher steps than its 6 cm (on the
#: nominal model at kp 5, a 1.25 Hz trot with a 7 cm step halves the 2 Hz trot's shortfall).
GAIT_FREQUENCIES = (1.0, 1.25, 1.5, 2.0)
STEP_HEIGHTS = (0.04, 0.06, 0.08)


def gait_search(task: WalkTask, plan: Plan, c: Candidate, models: Sequence[str],
                say: Callable[[str], None]) -> list[str]:
    """The best available gains ``c`` walking each gait of GAIT_FREQUENCIES
    x STEP_HEIGHTS on the same robots: the card's lines on the one that
    walks best (the lowest p95 speed error among those every robot walks
    without falling, else the least short), beside the gait asked."""
    say(f"no gains walk the {task.frequency:g} Hz {task.gait}: the best available walking "
        f"{len(GAIT_FREQUENCIES) * len(STEP_HEIGHTS)} gaits (slower, lower or higher steps) on the same robots")
    tried = []
    for hz in GAIT_FREQUENCIES:
        for h in STEP_HEIGHTS:
            g = replace(task, frequency=hz)
            cand = Candidate(dict(c.gains), dict(c.phase_deg), dict(c.gain_db), stage="gait")
            simulate_walk(g, plan, [cand], models, say, step_height=h)
            tried.append((hz, h, cand))
    ok = [t for t in tried if not t[2].fell and math.isfinite(t[2].score)]
    if not ok:
        return [f"at the best available gains no gait of {GAIT_FREQUENCIES[0]:g} to {GAIT_FREQUENCIES[-1]:g} Hz "
                f"with a {STEP_HEIGHTS[0] * 100:g} to {STEP_HEIGHTS[-1] * 100:g} cm step walks on every robot "
                "without a fall: these motors need stiffer gains (--kp-max) to walk"]
    hz, h, best = min(ok, key=lambda t: (bool(t[2].failed), t[2].score))
    held = ("holds every constraint walking it" if not best.failed else f"still breaks one: {best.failed}")
    w = best.figures
    asked = next((t[2] for t in tried if t[0] == task.frequency and abs(t[1] - 0.06) < 1e-9), None)
    than = (f" (the {task.frequency:g} Hz, 6 cm trot asked: {asked.score:.3g} %)"
            if asked is not None and math.isfinite(asked.score) else "")
    return [f"the gait these gains walk best on the same robots: a {task.gait} at {hz:g} Hz, its steps "
            f"{h * 100:g} cm high, p95 speed error {best.score:.3g} % of the {task.speed:g} m/s{than}, lowest robot "
            f"{best.min_height_m * 1000:.1f} mm, p95 pitch {w.get('p95_pitch_rms_deg', math.nan):.3g}°; it "
            f"{held}: where the motors keep the gains soft, the gait is what can still change "
            f"(pupper walk --frequency {hz:g} --step-height {h:g})"]


@dataclass
class Comparison:
    """The walk pick beside `--task stand`'s: each scored on both tasks."""

    stand: Candidate | None
    #: the stand pick walked on the walk task's robots
    stand_walking: Candidate | None
    #: the walk pick under the stand task's push
    walk_standing: Candidate | None
    lines: list[str] = field(default_factory=list)


def stand_plan(plan: Plan) -> Plan:
    """`--task stand` on the same robots, trials and seed: its own push
    test and length."""
    return replace(plan, task=Stand(), seconds=Stand.seconds)


def compare(task: WalkTask, plan: Plan, pick: Candidate, models: Sequence[str], say: Callable[[str], None],
            wins: Mapping[str, Window]) -> Comparison:
    """`--task stand`'s search and polish (its margin maps are the walk's),
    then each pick scored on the other task; the card's lines."""
    sp = stand_plan(plan)
    say("--task stand's pick, to set beside the walk's:")
    every = search(sp, models, say, lambda _: None, wins)
    best = best_of(sp, every)
    if best is None:
        return Comparison(None, None, None, ["--task stand finds no gains that hold under its push on these "
                                             "robots: the walk's pick has nothing to differ from"])
    stand, _ = polish(sp, best, models, say, every, wins)
    same = gains_key(stand.gains) == gains_key(pick.gains)
    walking = pick if same else _scored(plan, stand, models, say)
    standing = stand if same else _scored(sp, pick, models, say)
    cmp = Comparison(stand, walking, standing)
    cmp.lines = _lines(task, plan, pick, cmp, same)
    return cmp


def _scored(plan: Plan, c: Candidate, models: Sequence[str], say: Callable[[str], None]) -> Candidate:
    """A candidate's gains scored afresh on `plan`'s task."""
    again = Candidate(dict(c.gains), dict(c.phase_deg), dict(c.gain_db), number=c.number, stage=c.stage)
    simulate(plan, [again], models, say)
    return again


def _hz(plan: Plan, c: Candidate, group: str) -> float:
    """A group's natural frequency sqrt(kp/J) (Hz), at its most inertia, on
    the kp its motors deliver (the least of it), as `search.slowest_hz`."""
    g = next(g for g in plan.groups if g.name == group)
    return math.sqrt(c.gains[group][0] * g.kp_scale[0] / g.inertia[1]) / (2 * math.pi)


def _walking(task: WalkTask, c: Candidate) -> str:
    if c.failed:
        return f"breaks a constraint walking ({c.failed})"
    w = c.figures
    return (f"p95 speed error {w['p95_speed_error_pct']:.3g} % (slowest robot {w['p5_speed_ms']:.3g} m/s), "
            f"joints at {task.frequency:g} Hz: amplitude ratio {w['p5_amplitude_ratio']:.3g}, lag "
            f"{w['p95_lag_ms']:.3g} ms, p95 pitch {w['p95_pitch_rms_deg']:.3g}°")


def _standing(c: Candidate) -> str:
    if c.failed:
        return f"breaks a constraint under the push ({c.failed})"
    return f"p95 push dip {c.p95_dip_mm:.4g} mm"


def _lines(task: WalkTask, plan: Plan, pick: Candidate, cmp: Comparison, same: bool) -> list[str]:
    """The card's comparison: the two picks per group, each on both tasks,
    and why they differ."""
    stand, walking, standing = cmp.stand, cmp.stand_walking, cmp.walk_standing
    assert stand is not None and walking is not None and standing is not None
    gait = f"a {task.gait} at {task.frequency:g} Hz and {task.speed:g} m/s"
    out = ["against --task stand's pick (the same robots, trials and seed; ranked by its push dip):",
           "".join(f"{h:>12}" for h in ("group", "stand kp", "stand kd", "walk kp", "walk kd", "stand Hz",
                                        "walk Hz"))]
    for g in plan.groups:
        (sp, sd), (wp, wd) = stand.gains[g.name], pick.gains[g.name]
        vals = (g.name, f"{sp:.4g}", f"{sd:.4g}", f"{wp:.4g}", f"{wd:.4g}", f"{_hz(plan, stand, g.name):.3g}",
                f"{_hz(plan, pick, g.name):.3g}")
        out.append("".join(f"{v:>12}" for v in vals))
    out.append(f"  walking {gait}: stand's pick {_walking(task, walking)}; this pick {_walking(task, pick)}")
    out.append(f"  under the push: stand's pick {_standing(stand)}; this pick {_standing(standing)}")
    out.append("  why: " + _why(task, plan, pick, stand, walking, standing, same))
    return out


def _why(task: WalkTask, plan: Plan, pick: Candidate, stand: Candidate, walking: Candidate, standing: Candidate,
         same: bool) -> str:
    """Why the picks differ, from what was measured (no cause the numbers
    do not show)."""
    f = task.frequency
    slow = min(plan.groups, key=lambda g: _hz(plan, pick, g.name)).name
    hz = _hz(plan, pick, slow)
    if same:
        return (f"the same gains: the best walker the search found is the stand task's pick, the stiffest loop "
                f"the margins allow (its slowest group, {slow}, at {hz:.3g} Hz against the gait's {f:g} Hz); "
                "where the neighbours above would still win, more --polish may move it")
    moved = "; ".join(f"{g.name} kp ×{pick.gains[g.name][0] / stand.gains[g.name][0]:.2f}, kd "
                      f"×{pick.gains[g.name][1] / stand.gains[g.name][1]:.2f}"
                      for g in plan.groups if stand.gains[g.name] != pick.gains[g.name])
    out = [f"the walk ranks the speed the robots make at the gait, the stand the dip under one push ({moved})"]
    if walking.failed:
        out.append(f"the stand pick does not walk this gait on every robot ({walking.failed})")
    else:
        w, s = pick.figures, walking.figures
        out.append(f"walking, this pick is {w['p95_speed_error_pct']:.3g} % off the commanded speed, the stand "
                   f"pick {s['p95_speed_error_pct']:.3g} %")
        follows = w["p5_amplitude_ratio"] >= s["p5_amplitude_ratio"] and w["p95_lag_ms"] <= s["p95_lag_ms"]
        joints = (f"amplitude ratio {w['p5_amplitude_ratio']:.3g} against {s['p5_amplitude_ratio']:.3g}, lag "
                  f"{w['p95_lag_ms']:.3g} against {s['p95_lag_ms']:.3g} ms")
        if follows:
            out.append(f"its joints follow the {f:g} Hz targets better ({joints})")
        else:
            slip = (f"p95 slip {w['p95_slip_mm_s']:.3g} against {s['p95_slip_mm_s']:.3g} mm/s, pitch "
                    f"{w['p95_pitch_rms_deg']:.3g}° against {s['p95_pitch_rms_deg']:.3g}°")
            out.append(f"though its joints follow the {f:g} Hz targets no better ({joints}): the speed is made "
                       "where the feet meet the floor, and there "
                       + (f"its feet slip less ({slip})" if w["p95_slip_mm_s"] < s["p95_slip_mm_s"] else
                          f"the figures kept here do not tell them apart ({slip})"))
    out.append(f"the gait needs bandwidth: every group of this pick keeps its natural frequency sqrt(kp/J) at "
               f"{hz / f:.1f}× the gait's {f:g} Hz or more ({slow} {hz:.3g} Hz)"
               + ("" if hz >= 3 * f else ", under 3×: the joints lag a faster gait"))
    if standing.failed or not math.isfinite(standing.p95_dip_mm):
        out.append(f"this pick does not hold the stand task's push ({standing.failed or 'no dip measured'})")
    elif stand.p95_dip_mm <= standing.p95_dip_mm:
        out.append(f"the stand pick, stiffer where they differ, dips less under the push ({stand.p95_dip_mm:.4g} "
                   f"mm against {standing.p95_dip_mm:.4g})" if all(
                       stand.gains[g.name][0] >= pick.gains[g.name][0] for g in plan.groups) else
                   f"the stand pick dips less under the push ({stand.p95_dip_mm:.4g} mm against "
                   f"{standing.p95_dip_mm:.4g})")
    return "; ".join(out)


@dataclass
class WalkTask(Task):
    """`--task walk`: ranked by the p95 speed error of `pupper walk` at
    this gait on the drawn robots, every robot's roll and pitch RMS under
    `max_tilt` degrees."""

    name = "walk"
    about = "a gait"
    objective = "p95 speed error"
    column = "p95_speed_error_pct"
    unit = "%"
    #: the steady window is every whole gait cycle from 3.5 s on
    seconds = 8.0
    options = ("gait", "speed", "frequency", "max_tilt")

    #: `pupper walk`'s gait, commanded forward speed (m/s) and frequency (Hz)
    gait: str = "trot"
    speed: float = 0.25
    frequency: float = 2.0
    #: the most roll or pitch RMS a robot may keep while walking (degrees)
    max_tilt: float = 10.0

    @classmethod
    def of(cls, options: Mapping[str, Any]) -> WalkTask:
        t = cls(**options)
        if t.gait not in GAITS:
            raise RecommendError(f"unknown gait {t.gait!r}: use {', '.join(GAITS[:-1])} or {GAITS[-1]}")
        for flag, v, what in (("--frequency", t.frequency, "the gait's cycles per second, e.g. 2"),
                              ("--max-tilt", t.max_tilt, "degrees of roll or pitch RMS, e.g. 10")):
            if not (math.isfinite(v) and v > 0):
                raise RecommendError(f"{flag} {v} must be a number > 0: give {what}")
        if not (math.isfinite(t.speed) and t.speed != 0):
            raise RecommendError(f"--speed {t.speed} is no speed to walk at: the walk task ranks the speed error, "
                                 "give the commanded speed in m/s, e.g. 0.25")
        return cls(t.gait, float(t.speed), float(t.frequency), float(t.max_tilt))

    def run_options(self, plan: Plan) -> dict[str, Any]:
        """The walk every candidate runs on the robots: the sweep's firmware
        and draws, the gait instead of the push."""
        opts = {k: v for k, v in plan.sweep_options().items() if k != "push_force"}
        return {**opts, "gait": self.gait, "speed": self.speed, "frequency": self.frequency}

    def check_run(self, seconds: float, push_force: float | None) -> None:
        if push_force is not None:
            raise RecommendError("--push-force is the stand task's push; a walk has none: drop it, or use --task "
                                 "stand")

    def check(self, plan: Plan) -> None:
        check_walk(self, plan)

    def inputs(self) -> dict[str, Any]:
        return {"task": "walk", "gait": self.gait, "speed": self.speed, "frequency": self.frequency,
                "max_tilt_deg": self.max_tilt}

    def heading(self) -> str:
        return f" for a {self.gait} at {self.frequency:g} Hz and {self.speed:g} m/s"

    def constraints(self) -> str:
        return f"roll and pitch RMS under {self.max_tilt:g}°, "

    def simulate(self, plan: Plan, cands: Sequence[Candidate], robot_models: Sequence[str],
                 say: Callable[[str], None], own_gains: bool = False) -> None:
        simulate_walk(self, plan, cands, robot_models, say, own_gains)

    def row(self, c: Candidate) -> dict[str, Any]:
        return {k: c.figures.get(k, math.nan) for k in WALK_FIGURES}

    def card_line(self, plan: Plan, pick: Candidate, searched: Candidate | None) -> str:
        """The card's walking figures (where the stand task says its push dip)."""
        w = pick.figures
        also = (f" (on the exported MJCF, whose numbers MjSpec writes to six digits; {self.value(searched.score)} "
                "in the search)" if searched and self.value(searched.score) != self.value(pick.score) else "")
        return (f"p95 speed error {w['p95_speed_error_pct']:.4g} % of the {self.speed:g} m/s commanded (slowest "
                f"robot {w['p5_speed_ms']:.3g} m/s); p95 roll {w['p95_roll_rms_deg']:.3g}°, pitch "
                f"{w['p95_pitch_rms_deg']:.3g}° RMS; joints at {self.frequency:g} Hz: amplitude ratio "
                f"{w['p5_amplitude_ratio']:.3g}, lag {w['p95_lag_ms']:.3g} ms{also}")

    def card_columns(self, plan: Plan, pick: Candidate) -> dict[str, Any]:
        return {"task": "walk", "gait": self.gait, "frequency_hz": self.frequency, "speed_ms": self.speed,
                **pick.figures}

    def reproduce(self, plan: Plan, d: Path) -> str:
        """The walk that gives the card's figures again, to the digit."""
        if plan.fit_robots:
            return ""
        args = ["pupper", "walk", "--model", str(d / "recommended.xml"), "--mode", "torque", "--motor", plan.motor,
                "--seconds", f"{plan.seconds:g}", "--replicates", str(plan.robots), "--seed", str(plan.seed),
                "--common-draws", "--gait", self.gait, "--speed", f"{self.speed:g}", "--frequency",
                f"{self.frequency:g}"]
        for r in plan.spread:
            args += ["--randomize", r]
        return shlex.join(args)

    def after(self, rec: Any, models: Sequence[str], say: Callable[[str], None], wins: Mapping[str, Any]) -> None:
        """`--task stand`'s pick beside this one, each scored on both
        tasks; the card's push dip is this pick's under the stand's push."""
        cmp = compare(self, rec.plan, rec.pick, models, say, wins)
        rec.beside = cmp
        dip = cmp.walk_standing.p95_dip_mm if cmp.walk_standing else math.nan
        for c in rec.cards:
            c.p95_push_dip_mm = dip

    def lines(self, rec: Any) -> list[str]:
        return list(rec.beside.lines) if rec.beside else []

    def unanswered(self, rec: Any, models: Sequence[str], say: Callable[[str], None]) -> list[str]:
        """Where the robot's gains cannot walk this gait, the gait is what
        can still change (the chapter re-tunes gains for the gait
        frequency): the best available gains walk slower trots with lower
        and higher steps on the same robots, and the card says which gait
        they walk best."""
        if rec.nearest is None or not rec.nearest.robots:
            return []
        return gait_search(self, rec.plan, rec.nearest, models, say)

    def manifest(self, rec: Any) -> dict[str, Any]:
        cmp: Comparison | None = rec.beside
        if cmp is None:
            return {}
        stand, walking, standing = cmp.stand, cmp.stand_walking, cmp.walk_standing
        return {
            "compared": cmp.lines,
            "stand_pick": None if stand is None else {
                "gains": {g: {"kp": kp, "kd": kd} for g, (kp, kd) in stand.gains.items()},
                "p95_push_dip_mm": stand.p95_dip_mm,
                "walking": None if walking is None else {"failed": walking.failed, **walking.figures}},
            "pick_standing": None if standing is None else {"failed": standing.failed,
                                                            "p95_push_dip_mm": standing.p95_dip_mm}}
