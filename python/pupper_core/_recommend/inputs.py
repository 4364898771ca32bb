"""`pupper recommend`'s inputs checked before anything runs, into its
`Plan`: the model's joint groups and their own gains, the searched ranges,
the robots drawn from what the model does not know (or from a fit's
intervals), the firmware, the constraints."""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pupper_core._fit.terms import lag_matters
from pupper_core._recommend.fits import (FitRuns, actuators, fit_motor, fit_robots, fit_runs, kind, robot_loops,
                                         robot_of)
from pupper_core._recommend.plan import DEFAULT_MOTOR, DEFAULT_SPREAD, Group, Loop, Plan, RecommendError, Task
from pupper_core._recommend.robot_config import config_gains, current_gains, joint_order_of, read_robot_config
from pupper_core._recommend.stand import Stand
from pupper_core._recommend.walk import WalkTask

#: The registry: what the gains can be ranked for (`--task NAME`), each a
#: `plan.Task` in a module of its own.
TASKS: dict[str, type[Task]] = {
    "stand": Stand,
    "walk": WalkTask,
}


def task_of(name: str, options: Mapping[str, Any]) -> Task:
    """The task --task names, set by its keywords (None: not given); a
    keyword of another task's is refused, naming the task it sets."""
    if name not in TASKS:
        said = " or ".join(f"{n} ({t.about})" for n, t in TASKS.items())
        raise RecommendError(f"--task {name!r} is not a task: use {said}")
    given = {k: v for k, v in options.items() if v is not None}
    for k in given:
        if k not in TASKS[name].options:
            owner = next(n for n, t in TASKS.items() if k in t.options)
            raise RecommendError(f"--{k.replace('_', '-')} sets the {owner} the gains are ranked on: add --task "
                                 f"{owner}, or drop it")
    return TASKS[name].of(given)


def _positive(name: str, v: float, flag: str, *, zero: bool = False) -> float:
    ok = math.isfinite(v) and (v >= 0 if zero else v > 0)
    if not ok:
        raise RecommendError(f"{flag} {v} must be a number {'>= 0' if zero else '> 0'}: give {name}")
    return float(v)


def _relative(spread: Sequence[str], quantity: str) -> float:
    """P/100 of a `QUANTITY=±P%` spec in the spread (0 when absent)."""
    for s in spread:
        m = re.fullmatch(rf"{quantity}=(?:±|\+-)([0-9.]+)%", s.strip())
        if m:
            return float(m.group(1)) / 100
    return 0.0


def _numerics(model: str) -> dict[str, float]:
    """The model's `pupper:...` custom numerics, by name."""
    from pupper_core.render import _load_model

    m = _load_model(model)
    out: dict[str, float] = {}
    for i in range(m.nnumeric):
        name = m.numeric(i).name
        if name.startswith("pupper:") and m.numeric_size[i] >= 1:
            out[name] = float(m.numeric_data[m.numeric_adr[i]])
    return out


def _limit(actuator: Mapping[str, Any]) -> float:
    r = actuator["forcerange"] or actuator["ctrlrange"]
    return float(r[1]) if r else math.inf


def _gain_scale(actuator: Mapping[str, Any]) -> tuple[float, float]:
    """What the motor delivers of a commanded kp and kd (its `info`'s
    gain_scale, absent when both are 1)."""
    kp, kd = actuator.get("gain_scale") or (1.0, 1.0)
    return float(kp), float(kd)


def _model_loops(inf: Mapping[str, Any], rep: Mapping[str, Any], names: Sequence[str]) -> list[Loop]:
    """Each actuator's loop on the model as it is (``rep``: its `gains`
    report at the stand pose): its gain scales, reflected inertia, and on a
    calibrated model its damping, torque lag and feedback latency."""
    by_name = {str(j["actuator"]): j for j in rep["joints"]}
    out = []
    for a, name in zip(inf["actuators"], names):
        j = by_name[name]
        sp, sd = _gain_scale(a)
        damping = float((j.get("loop") or {}).get("damping", 0.0)) if rep.get("fitted") else 0.0
        out.append(Loop(sp, sd, float(j["inertia"]), damping, float(a.get("lag", 0.0)), float(a.get("latency", 0.0))))
    return out


def _groups(model: str, inf: Mapping[str, Any], kp_max: float | None, kd_max: float | None, leg: float,
            fit: tuple[Sequence[Mapping[str, str]], Sequence[Sequence[float]]] | None
            ) -> tuple[list[str], list[Group], float, bool]:
    """The model's actuators (from its `info`), its joint groups with their
    searched ranges, its timestep, and whether motor caps bound every
    group's kp and kd. Each group's loops: its joints on the model, their
    link's part lightest and heaviest over the leg-mass spread; with a fit
    (its rows and the robots its logs allow), its joints on every drawn
    robot and on the fitted one."""
    from pupper_core._run import gains

    names = [str(a["name"]) for a in inf["actuators"]]
    own_kp = [float(a["gainprm"][0]) for a in inf["actuators"]]
    own_kd = [-float(a["biasprm"][2]) for a in inf["actuators"]]
    rep = gains(model, kp=max(own_kp[0], 1e-3), kd=max(own_kd[0], 0.0))
    numerics = _numerics(model)
    base = _model_loops(inf, rep, names)
    group_of = {names.index(str(j["actuator"])): str(j["group"]) for j in rep["joints"]}
    members: dict[str, list[int]] = {}
    for a in sorted(group_of):
        members.setdefault(group_of[a], []).append(a)
    if fit is not None:
        rows, drawn = fit
        armature = [float(j) for j in _armature(model, names)]
        robots = [base] + [robot_loops(base, armature, rows, x, names) for x in drawn]
        per: list[list[Loop]] = [[r[a] for r in robots] for a in range(len(names))]
    else:
        # the joints' least and most inertia over the leg-mass spread (the
        # armature scaled with the link: the conservative side)
        per = [[lp._replace(inertia=lp.inertia * (1 - leg)), lp._replace(inertia=lp.inertia * (1 + leg))]
               for lp in base]
    lo_i = {g: min(lp.inertia for a in m for lp in per[a]) for g, m in members.items()}
    hi_i = {g: max(lp.inertia for a in m for lp in per[a]) for g, m in members.items()}
    # joints alike but for round-off (a leg and its mirror) close one loop
    loops = {g: tuple(dict.fromkeys(Loop(*(float(f"{v:.9g}") for v in lp)) for a in m for lp in per[a]))
             for g, m in members.items()}
    # a position servo's own gains (kp, and kv as -biasprm[2]); a <motor>
    # has none (gain 1, no bias): its range comes from the caps alone
    servo = [float(a["gainprm"][0]) > 0 and float(a["biasprm"][1]) == -float(a["gainprm"][0])
             for a in inf["actuators"]]
    groups = []
    capped = True
    for name, acts in members.items():
        caps_p = [numerics[f"pupper:kp_max:{names[a]}"] for a in acts if f"pupper:kp_max:{names[a]}" in numerics]
        caps_d = [numerics[f"pupper:kd_max:{names[a]}"] for a in acts if f"pupper:kd_max:{names[a]}" in numerics]
        caps_p += [kp_max] if kp_max else []
        caps_d += [kd_max] if kd_max else []
        capped = capped and bool(caps_p) and bool(caps_d)
        if all(servo[a] for a in acts) and max(own_kd[a] for a in acts) > 0:
            kp0 = max(own_kp[a] for a in acts)
            kd0 = max(own_kd[a] for a in acts)
            hi_p, hi_d = min([kp0 * 20, *caps_p]), min([kd0 * 50, *caps_d])
            lo_p, lo_d = min(kp0 / 10, hi_p / 2), min(kd0 / 10, hi_d / 2)
        elif caps_p and caps_d:
            # the same spans as a servo's own gains give: 200x in kp, 500x in kd
            hi_p, hi_d = min(caps_p), min(caps_d)
            lo_p, lo_d = hi_p / 200, hi_d / 500
        else:
            kind = "motors" if not any(servo[a] for a in acts) else "servos without damping"
            raise RecommendError(f"the model's {name} actuators are {kind}, with no PD gains of their own to "
                                 "search around: give --kp-max and --kd-max, the largest gains the motors take "
                                 "(kp_max= and kd_max= in Python), or pupper:kp_max:ACT and pupper:kd_max:ACT "
                                 "numerics in the model")
        groups.append(Group(name, tuple(acts), (lo_p, hi_p), (lo_d, hi_d), (lo_i[name], hi_i[name]),
                            min(_limit(inf["actuators"][a]) for a in acts), loops[name]))
    return names, groups, float(rep["timestep"]), capped


def _armature(model: str, names: Sequence[str]) -> list[float]:
    """Each actuator's joint armature in the model (kg·m²)."""
    from pupper_core.render import _load_model

    m = _load_model(model)
    return [float(m.dof_armature[m.jnt_dofadr[m.actuator_trnid[m.actuator(n).id, 0]]]) for n in names]


def _motor(motor: str | None, command_delay: float) -> str:
    """The firmware spec with the command delay in it."""
    spec = DEFAULT_MOTOR if motor is None else motor
    if command_delay > 0:
        if re.search(r"(^|,)\s*delay\s*=", spec):
            raise RecommendError("--command-delay and --motor delay= both set the command delay: keep one")
        spec = f"{spec},delay={command_delay:g}" if spec else f"delay={command_delay:g}"
    return spec


#: The feedback latency assumed where neither --sensing-delay nor a calibrated model says one (s).
SENSING_DELAY = 0.002


def _values(rows: Sequence[Mapping[str, str]], k: str) -> list[tuple[float, float, float]]:
    """The fit's rows of kind ``k``: (fitted, low95, high95)."""
    return [(float(r["fitted"]), *_interval(r)) for r in rows if kind(r) == k]


def _timing_words(rows: Sequence[Mapping[str, str]], sensing: float | None, motor: str | None,
                  timestep: float) -> str:
    """The card's line on the loop's timing with a fit: the torque lag, the
    feedback latency and the command delay it runs, each the fit's (every
    robot its own, drawn with the rest) or the one a flag gave instead."""
    def said(vals: list[tuple[float, float, float]], unit: float = 1e3) -> str:
        return ", ".join(f"{v * unit:.3g} ms [{a * unit:.3g}, {b * unit:.3g}]" for v, a, b in vals)

    lags = [v for v in _values(rows, "lag") if lag_matters(v[0], timestep)]
    if motor is not None and re.search(r"(^|,)\s*lag\s*=", motor):
        lag = "torque lag given by --motor" + (f" (the fit measured {said(lags)})" if lags else "")
    else:
        lag = f"torque lag the fit's, each robot its own (fit.csv: lag {said(lags)})" if lags else "no torque lag"
    lat = _values(rows, "latency")
    unplaced = any(not all(math.isfinite(float(r[k] or "nan")) for k in ("low95", "high95"))
                   for r in rows if kind(r) == "latency")
    if sensing is not None:
        latency = f"feedback latency {sensing:g} s, given by --sensing-delay" + (
            f" (the fit measured {said(lat)})" if lat else "")
    elif lat and not unplaced:
        latency = f"feedback latency the fit's, each robot its own (fit.csv: latency {said(lat)})"
    else:
        latency = "no feedback latency (" + ("the fit could not place it: its logs are at one kp" if unplaced
                                             else "the fit did not fit one: --params ...,latency") + ")"
    delays = [v for v in _values(rows, "delay") if v[2] > 1e-9]
    command = (f"command delay the fit's, each robot its own (fit.csv: delay {said(delays)})" if delays
               else "no command delay (the fit found none)")
    return f"the loop the fit found: {lag}; {latency}; {command}"


def _interval(r: Mapping[str, str], floor: float = 0.0) -> tuple[float, float]:
    """A fit.csv row's 95 % interval, inside the parameter's physical bound
    (the fitted value alone where the interval is not meaningful)."""
    try:
        a, b, v = float(r["low95"] or "nan"), float(r["high95"] or "nan"), float(r["fitted"])
    except (KeyError, ValueError):
        raise RecommendError(f"fit.csv row {dict(r)} is not a fit's: give a `pupper fit` run directory") from None
    if not (math.isfinite(a) and math.isfinite(b)):
        return v, v
    return max(a, floor), max(b, floor)


def _spread(spread: Sequence[str] | None, fitted: bool) -> list[str]:
    """What differs between robots besides the fit: the given spread or
    the default; with a fit, without what each drawn robot carries of its
    own (its motor's gains and command delay)."""
    base = list(DEFAULT_SPREAD if spread is None else spread)
    if fitted:
        base = [s for s in base if not s.strip().startswith(("motor_gain=", "motor_delay="))]
    return base


def plan(model: str | os.PathLike[str], *, robots: int, trials: int, batch: int, seed: int, seconds: float | None,
         push_force: float | None, motor: str | None, sensing_delay: float | None, command_delay: float,
         spread: Sequence[str] | None, from_fit: FitRuns, min_phase_margin: float,
         min_gain_margin: float, max_saturation: float, kp_max: float | None, kd_max: float | None,
         joint_order: Sequence[str] | str | None, controller: str, polish: int, max_sag: float,
         current: Sequence[float] | str | None, robot_config: str | os.PathLike[str] | None, task: str,
         gait: str | None, speed: float | None, frequency: float | None, max_tilt: float | None) -> Plan:
    """Every input checked, the model read; one line per mistake. (No
    defaults here: `pupper_core.recommend` declares them, once.)"""
    _check_types(dict(locals()))
    if isinstance(spread, str):
        spread = [spread]  # one spec (a spec may hold a comma: N(0,0.001))
    ranked = task_of(task, {"gait": gait, "speed": speed, "frequency": frequency, "max_tilt": max_tilt})
    seconds = ranked.seconds if seconds is None else seconds
    _check_numbers(robots=robots, trials=trials, batch=batch, polish=polish, seconds=seconds,
                   sensing_delay=sensing_delay, command_delay=command_delay, min_phase_margin=min_phase_margin,
                   min_gain_margin=min_gain_margin, max_sag=max_sag, max_saturation=max_saturation, kp_max=kp_max,
                   kd_max=kd_max, task=ranked, push_force=push_force)
    runs = fit_runs(from_fit)
    fit_dir = runs[0] if len(runs) == 1 else None
    rows, merged_xml, fitted = robot_of(runs)
    model = os.fspath(fitted or model)
    base = _spread(spread, bool(rows))
    g, leg = _relative(base, "motor_gain"), _relative(base, "leg_mass")
    drawn, worst = fit_robots(runs, rows) if rows else ([], math.nan)
    from pupper_core._run import info

    inf = info(model)
    _standing_robot(model, inf)
    names, groups, dt, capped = _groups(model, inf, kp_max, kd_max, leg, (rows, drawn) if rows else None)
    calibrated = any(a.get("lag") or a.get("latency") for a in inf["actuators"])
    if rows or calibrated:
        # the loop the fit found: its firmware, each robot's own lag and latency (the model's), no default latency
        motor_spec = _motor(fit_motor(runs) if motor is None and rows else motor if motor is not None else "",
                            command_delay)
        latency_from = _timing_words(rows, sensing_delay, motor, dt) if rows else ""
    else:
        motor_spec = _motor(motor, command_delay)
        sensing_delay, latency_from = (SENSING_DELAY if sensing_delay is None else sensing_delay), ""
    _servo_delay(motor_spec)
    from pupper_core._native import loop_margins, stance

    loop_margins(1.0, 1.0, 0.1, motor=motor_spec, sensing_delay=sensing_delay, timestep=dt)  # checks the spec
    steps = math.ceil((sensing_delay or 0.0) / dt - 1e-9)
    if any(s.strip().startswith("delay=") for s in base):
        raise RecommendError("the sensing latency is --sensing-delay (drawn 0 to it in whole steps): "
                             "drop delay= from --spread")
    drawn_spread = base + ([f"delay=0:{steps}"] if steps else [])
    kp_factors, kd_factors = (1 - g, 1 + g), (1 - g, 1 + g)
    if rows and robots % len(drawn):
        raise RecommendError(f"--robots {robots}: with --from-fit the robots stand on the {len(drawn)} the fit drew "
                             f"(its robots.csv) with an equal share each: give a multiple of {len(drawn)}")
    config = None if robot_config is None else read_robot_config(Path(robot_config), controller, names)
    if config is not None and joint_order is None:
        joint_order = config[0]
    order = joint_order_of(joint_order, names)
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_/]*", controller):
        raise RecommendError(f"--controller '{controller}' is not a ROS 2 node name: letters, digits, _ and /")
    if config is not None and current is None:
        now, now_from = config_gains(config, names, groups, Path(robot_config or ""))
    else:
        now, now_from = current_gains(current, inf, groups)
    p = Plan(model=model, actuators=names, groups=groups, timestep=dt, motor=motor_spec,
                sensing_delay=sensing_delay, command_delay=command_delay, spread=drawn_spread, kp_factors=kp_factors,
                kd_factors=kd_factors, robots=robots, trials=trials, batch=batch, seed=seed, seconds=seconds,
                push_force=push_force, min_phase_margin=min_phase_margin, min_gain_margin=min_gain_margin,
                max_saturation=max_saturation, joint_order=order, controller=controller, polish=polish,
                max_sag=max_sag, stance=stance(model=model), from_fit=fit_dir, fit_rows=rows,
                fit_runs=runs if merged_xml else [], merged_xml=merged_xml,
                fit_robots=drawn, fit_robots_worst=worst, current=now, current_from=now_from,
                caps=capped, latency_from=latency_from, task=ranked)
    ranked.check(p)
    return p


def _check_numbers(*, robots: int, trials: int, batch: int, polish: int, seconds: float,
                   sensing_delay: float | None,
                   command_delay: float, min_phase_margin: float, min_gain_margin: float, max_sag: float,
                   max_saturation: float, kp_max: float | None, kd_max: float | None, task: Task,
                   push_force: float | None) -> None:
    """Each number in its range, or one line naming the flag and a value
    (the run's length and push as the task needs them)."""
    if robots < 1 or trials < 1 or batch < 1:
        raise RecommendError(f"robots {robots}, trials {trials}, batch {batch}: each must be a whole number >= 1")
    if polish < 0:
        raise RecommendError(f"--polish {polish} must be a whole number >= 0 (0: the search's pick, unmoved)")
    _positive("the simulated seconds per robot, e.g. 4", seconds, "--seconds")
    task.check_run(seconds, push_force)
    if sensing_delay is not None:
        _positive("seconds of feedback latency, e.g. 0.002", sensing_delay, "--sensing-delay", zero=True)
    _positive("seconds of command delay, e.g. 0.01", command_delay, "--command-delay", zero=True)
    _positive("degrees, e.g. 30", min_phase_margin, "--min-phase-margin", zero=True)
    if min_phase_margin >= 180:
        raise RecommendError(f"--min-phase-margin {min_phase_margin:g} must be below 180: a loop's phase margin is "
                             "under 180 degrees (a PD's under 90), so no gains could keep it; give e.g. 30")
    _positive("decibels, e.g. 6", min_gain_margin, "--min-gain-margin", zero=True)
    if not (0 < max_sag < 1):
        raise RecommendError(f"--max-sag {max_sag} must lie in (0, 1): a share of the stance height, e.g. 0.1")
    if not (0 < max_saturation <= 1):
        raise RecommendError(f"--max-saturation {max_saturation} must lie in (0, 1]: a fraction of steps, e.g. 0.05")
    for v, flag in ((kp_max, "--kp-max"), (kd_max, "--kd-max")):
        if v is not None:
            _positive("the motors' largest gain", v, flag)


#: The longest command delay (s) the card's predicted step response can
#: show: it is measured over the 2.5 s after its step (card), and
#: a delayed step needs room to rise and settle there.
MAX_COMMAND_DELAY = 1.0


def _check_types(kw: Mapping[str, Any]) -> None:
    """The keywords' types, as Python gives them (the CLI's are right by
    construction): one line naming the keyword, before any work."""
    import numbers

    def bad(name: str, what: str) -> RecommendError:
        return RecommendError(f"recommend({name}={kw[name]!r}): give {what}")

    for n in ("robots", "trials", "batch", "polish", "seed"):
        v = kw[n]
        if isinstance(v, bool) or not isinstance(v, numbers.Integral):
            raise bad(n, "a whole number")
    if not 0 <= kw["seed"] < 2**64:
        raise bad("seed", "a whole number from 0 to 2**64 - 1")
    for n in ("seconds", "sensing_delay", "command_delay", "min_phase_margin", "min_gain_margin", "max_saturation",
              "max_sag", "push_force", "kp_max", "kd_max", "speed", "frequency", "max_tilt"):
        v = kw[n]
        if v is None and n in ("seconds", "push_force", "kp_max", "kd_max", "sensing_delay", "speed", "frequency",
                               "max_tilt"):
            continue
        if isinstance(v, bool) or not isinstance(v, numbers.Real):
            raise bad(n, "a number")
    if kw["push_force"] is not None and not math.isfinite(kw["push_force"]):
        raise bad("push_force", "a finite number of newtons")
    for n in ("motor", "controller", "task", "gait"):
        if not (isinstance(kw[n], str) or (n in ("motor", "gait") and kw[n] is None)):
            raise bad(n, "a string")
    if not isinstance(kw["model"], (str, os.PathLike)):
        raise bad("model", "a path")
    f = kw["from_fit"]
    if not (f is None or isinstance(f, (str, os.PathLike))
            or (isinstance(f, Sequence) and f and all(isinstance(x, (str, os.PathLike)) for x in f))):
        raise bad("from_fit", "a path, or a list of paths")
    for n in ("spread", "joint_order"):
        v = kw[n]
        if v is None or isinstance(v, str):
            continue
        if not isinstance(v, Sequence) or not all(isinstance(x, str) for x in v):
            raise bad(n, "a string or a list of strings")


def _servo_delay(spec: str) -> None:
    """A command delay (--command-delay, or delay= in --motor) the card's
    step response can show."""
    m = re.search(r"(?:^|,)\s*delay\s*=\s*([^,\s]+)", spec)
    try:
        delay = float(m.group(1)) if m else 0.0
    except ValueError:
        return  # the spec's own check says it
    if delay > MAX_COMMAND_DELAY:
        raise RecommendError(f"a command delay of {delay:g} s is longer than the {MAX_COMMAND_DELAY:g} s the card's "
                             "step response (2.5 s after its step) can show: give the firmware's delay in seconds, "
                             "e.g. --command-delay 0.01")


def _standing_robot(model: str, inf: Mapping[str, Any]) -> None:
    """A robot recommend can judge: legs it stands on, ground under them,
    and a torque limit on every motor (saturation and headroom are judged
    against it)."""
    if not inf.get("legs"):
        raise RecommendError(f"model '{model}' has no legs pupper can pose (a chain of abduction, hip and knee "
                             "hinges under the base ending in a colliding foot): recommend tunes the gains of a "
                             "robot standing on its legs; give a legged model")
    # (a welded base has no ground to stand on and is refused by the runs themselves)
    floating = any(j.get("kind") == "free" for j in inf["joints"])
    if floating and inf.get("ground", True) is False:
        raise RecommendError(f"model '{model}' has no ground the feet can touch (no geom fixed in the world that "
                             "collides with them): every robot would fall at once; add a floor, e.g. "
                             "<geom type=\"plane\" size=\"0 0 0.05\"/> in the worldbody, or include the model in a "
                             "scene that has one")
    free = [str(a["name"]) for a in inf["actuators"] if not math.isfinite(_limit(a))]
    if free:
        shown = ", ".join(free[:3]) + (f" and {len(free) - 3} more" if len(free) > 3 else "")
        raise RecommendError(f"the model's actuators {shown} have no force or control range: recommend holds every "
                             "robot to its motors' torque limit (saturation, headroom); give each actuator its "
                             "limit in the model, e.g. forcerange=\"-3 3\" (N·m)")
