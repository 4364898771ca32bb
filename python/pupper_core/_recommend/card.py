"""What `pupper recommend` shows and writes: a card per joint group (the
gains, their margins, the predicted step response, the push dip, the
torque headroom, why the neighbours lost), the candidates, the exports a
robot takes (a ROS 2 parameter file, the MJCF with the gains in its
actuators), the manifest and report.html."""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from pupper_core import _native
from pupper_core._rundir import atomic_write, atomic_write_text
from pupper_core._recommend import short
from pupper_core._recommend.fits import readings_line
from pupper_core._recommend.plan import Plan
from pupper_core._recommend.result import Card, Recommendation
from pupper_core._recommend.search import (Candidate, better, gains_key, gains_per_actuator, simulate, slowest_hz,
                                           tradeoffs, why_lost)


#: Seconds at the stand pose before the predicted step (the softest gains
#: take about a second to settle from where the robot starts).
STEP_HOLD = 2.0
#: A pick within this share of a range's log span from its end is said to
#: lie on the edge of the searched range.
EDGE = 0.05


def _step_response(plan: Plan, xml: Path) -> dict[str, dict[str, float]]:
    """Each group's step response at the recommended gains on the model's
    robot hung in the air (the calibrated one, with a fit), through the
    firmware (its command delay, and a calibrated model's lag and latency)."""
    import warnings

    from pupper_core._run import response

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # a long hold: the softest group's landing transient is over before its step
        res = response(model=str(xml), mode="torque", motor=plan.motor, hold=STEP_HOLD, seconds=STEP_HOLD + 2.5,
                       progress=False)
    return {g.name: {k: float(res.table[f"{k}.{g.name}"][0]) for k in ("rise_time_s", "overshoot_pct",
                                                                       "settling_time_s")}
            for g in plan.groups}


def _edges(plan: Plan, pick: Candidate) -> list[str]:
    """A pick on the edge of its searched range, said."""
    out = []
    for g in plan.groups:
        for axis, v, (lo, hi) in (("kp", pick.gains[g.name][0], g.kp_range), ("kd", pick.gains[g.name][1],
                                                                             g.kd_range)):
            span = math.log(hi / lo)
            if math.log(hi / v) < EDGE * span:
                out.append(f"{axis}.{g.name} {v:.4g} lies on the top edge of its searched range ({lo:.3g} to "
                           f"{hi:.3g}): a stiffer setting may hold too; raise --{axis}-max if the motors allow it")
            elif math.log(v / lo) < EDGE * span:
                out.append(f"{axis}.{g.name} {v:.4g} lies on the bottom edge of its searched range ({lo:.3g} to "
                           f"{hi:.3g}): nothing stiffer held every constraint")
    return out


#: A group whose worst-corner phase margin lies within this many degrees
#: of the limit (or gain margin within a fifth of a dB) is said to sit on it.
ON_MARGIN_DEG = 1.0


def _on_margin(plan: Plan, pick: Candidate) -> list[str]:
    """Groups as stiff as their loop margins allow, said: the margins hold
    for the latency assumed, and no more."""
    on = [g.name for g in plan.groups if pick.phase_deg[g.name] < plan.min_phase_margin + ON_MARGIN_DEG
          or pick.gain_db[g.name] < plan.min_gain_margin + ON_MARGIN_DEG / 5]
    if not on:
        return []
    return [f"{', '.join(on)} sit(s) on the margin limit (phase >= {plan.min_phase_margin:g}°, gain >= "
            f"{plan.min_gain_margin:g} dB at the spread's worst corner): they hold for the firmware and the "
            + (f"{plan.sensing_delay:g} s of sensing delay assumed" if plan.sensing_delay is not None
               else "latency the fit found") + ", no more; measure the robot's latency, or raise "
            "--min-phase-margin for room"]


#: Torque headroom (%) under which the card warns: the motors reach their
#: limit under the push on the worst-side robots.
LOW_HEADROOM_PCT = 1.0


def _headroom(plan: Plan, pick: Candidate) -> list[str]:
    lim = min(g.torque_limit for g in plan.groups)
    if not (math.isfinite(lim) and pick.p95_peak_torque >= lim * (1 - LOW_HEADROOM_PCT / 100)):
        return []
    return [f"the p95 peak torque {pick.p95_peak_torque:.3g} N·m reaches the {lim:.3g} N·m limit (0 % headroom): "
            "under the push the motors saturate on the worst-side robots, so a harder push or a heavier robot finds "
            "no torque left; lower --max-saturation, or check the motors' limit in the model"]


def _caps(plan: Plan) -> list[str]:
    """Searched ranges no motor cap bounded, said: a robot's firmware may
    refuse gains past what its own configuration allows."""
    if plan.caps:
        return []
    tops = ", ".join(f"{g.name} kp {g.kp_range[1]:.3g} kd {g.kd_range[1]:.3g}" for g in plan.groups)
    return [f"no motor caps given (--kp-max/--kd-max, or pupper:kp_max/kd_max numerics in the model): the search "
            f"reached {tops}, 20x and 50x the model's own gains; give the largest gains the robot's firmware and "
            "configuration accept"]


def card_of(plan: Plan, pick: Candidate, near: Sequence[tuple[str, Candidate]], d: Path,
            say: Callable[[str], None]) -> tuple[list[Card], list[str], list[str], Candidate]:
    """The cards, why each neighbour lost, the warnings that qualify the
    pick, and the pick as the card measured it."""
    d.mkdir(parents=True, exist_ok=True)
    xml = d / "recommended.xml"
    atomic_write_text(xml, mjcf(plan, pick))
    warnings = _edges(plan, pick) + _on_margin(plan, pick) + _caps(plan)
    reasons = [why_lost(plan, label, c, pick) for label, c in near]
    winners = [label for label, c in near if c.feasible and better(plan, c, pick)]
    if winners:
        warnings.append(f"the polish made its last move with {len(winners)} neighbour(s) that would still win "
                        f"({', '.join(winners)}): the pick may lie short of the best; raise --polish or --trials")
    if not plan.fit_robots:
        # the card's robots are the exported MJCF's: MjSpec writes numbers to
        # six digits, which moves a chaotic push dip in its fourth
        pick = _on_export(plan, pick, xml, say, warnings)
    step = _step_response(plan, xml)
    warnings += _headroom(plan, pick)
    cards = []
    # where some group's motors deliver other gains (a fit of some motors), every group says what it delivers
    scaled = any(g.scaled for g in plan.groups)
    for g in plan.groups:
        kp, kd = pick.gains[g.name]
        lim = g.torque_limit
        # the nominal motor: the middle of its scales (one value where the fit found one)
        mkp, mkd = (kp * math.sqrt(g.kp_scale[0] * g.kp_scale[1]), kd * math.sqrt(g.kd_scale[0] * g.kd_scale[1])
                    ) if scaled else (None, None)
        cards.append(Card(g.name, kp, kd, pick.phase_deg[g.name], pick.gain_db[g.name],
                          step[g.name]["rise_time_s"], step[g.name]["overshoot_pct"],
                          step[g.name]["settling_time_s"], pick.p95_dip_mm,
                          pick.p95_peak_torque, lim, 100 * (1 - pick.p95_peak_torque / lim), mkp, mkd))
    return cards, reasons, warnings, pick


def in_use(plan: Plan, models: Sequence[str], say: Callable[[str], None]) -> Candidate | None:
    """The gains the robot runs today (`Plan.current`), checked and run on
    the same robots as every candidate: what the card sets the pick beside."""
    from pupper_core._recommend.search import check_margins

    if not plan.current:
        return None
    c = Candidate(dict(plan.current), stage="current")
    check_margins(plan, c)
    # run even when its margins fail: the owner runs these today
    failed = c.failed
    c.failed = ""
    simulate(plan, [c], models, say)
    c.failed = failed or c.failed
    return c


def _on_export(plan: Plan, pick: Candidate, xml: Path, say: Callable[[str], None],
               warnings: list[str]) -> Candidate:
    """The pick run again on the exported MJCF at its own gains: what a
    sweep on that file reproduces to the digit."""
    again = Candidate(dict(pick.gains), dict(pick.phase_deg), dict(pick.gain_db), number=pick.number,
                      stage=pick.stage)
    simulate(plan, [again], [str(xml)], say, own_gains=True)
    if again.failed:
        warnings.append(f"on the exported MJCF the pick breaks a constraint ({again.failed}): the search's "
                        f"robots held it; treat it as on the edge")
        return pick
    return again


def mjcf(plan: Plan, pick: Candidate) -> str:
    """The model with the recommended gains in its actuators (a PD servo:
    gain kp, bias -kp·q - kd·q̇), written through MjSpec."""
    import mujoco

    spec = mujoco.MjSpec.from_file(plan.model) if Path(plan.model).is_file() else None
    if spec is None:
        from pupper_core.render import builtin_model_path

        path = builtin_model_path(plan.model)
        if path is None:
            return ""
        spec = mujoco.MjSpec.from_file(str(path))
        base = path.parent
    else:
        base = Path(plan.model).parent
    # assets stay where the original's are
    spec.meshdir = str((base / spec.meshdir).resolve()) if spec.meshdir else str(base.resolve())
    spec.texturedir = str((base / spec.texturedir).resolve()) if spec.texturedir else str(base.resolve())
    limits = _torque_limits(spec)
    for name, (kp, kd) in zip(plan.actuators, gains_per_actuator(plan, pick.gains)):
        act = spec.actuator(name)
        if name in limits:
            # a torque motor becomes a PD servo: its control is now the target
            # angle, and its torque limit (the control range) the force range
            act.forcerange = limits[name]
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        act.gainprm[0] = kp
        act.biasprm[0], act.biasprm[1], act.biasprm[2] = 0.0, -kp, -kd
    spec.modelname = f"{spec.modelname}_recommended" if spec.modelname else "recommended"
    return str(spec.to_xml())


def _torque_limits(spec: Any) -> dict[str, list[float]]:
    """The torque motors (no bias: the control is the torque) whose limit is
    their control range alone, by name: the force range (gain x control
    range) the exported PD servo must keep, or plain MuJoCo would apply any
    torque and clamp the target angle instead."""
    import mujoco

    m = spec.compile()
    out = {}
    for a in range(m.nu):
        if (m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE and not m.actuator_forcelimited[a]
                and m.actuator_ctrllimited[a]):
            lo, hi = sorted(float(m.actuator_gainprm[a, 0] * c) for c in m.actuator_ctrlrange[a])
            out[m.actuator(a).name] = [lo, hi]
    return out


def _comment(text: str) -> str:
    """`text` safe on one comment line: a character YAML reads as a line
    break (a newline in a path), or any other unprintable one, escaped."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text)


def ros2_yaml(plan: Plan, pick: Candidate) -> str:
    """A ROS 2 parameter file: the controller's joint_names, kps and kds in
    --joint-order."""
    import yaml  # type: ignore[import-untyped]  # (PyYAML, with Optuna)

    per = dict(zip(plan.actuators, gains_per_actuator(plan, pick.gains)))
    doc = {plan.controller: {"ros__parameters": {
        "joint_names": list(plan.joint_order),
        "kps": [per[n][0] for n in plan.joint_order],
        "kds": [per[n][1] for n in plan.joint_order],
    }}}
    head = ("# " + _comment(f"pupper recommend: {plan.model}, {plan.robots} drawn robots, firmware "
                            f"{plan.motor or 'ideal'}, {plan.latency_words()}")
            + f"\n# kps, kds: the gains to command{_delivered_note(plan)}\n")
    return head + str(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=100))


def _delivered_note(plan: Plan) -> str:
    """What the motors deliver of the commanded gains, where the model's
    gain scales say they differ."""
    scaled = [g for g in plan.groups if g.scaled]
    if not scaled:
        return ""

    def span(lo: float, hi: float) -> str:
        return f"{lo:.3g}x" if f"{lo:.3g}" == f"{hi:.3g}" else f"{lo:.3g}-{hi:.3g}x"

    return ("; the motors deliver " + ", ".join(f"{g.name} {span(*g.kp_scale)} the kp and {span(*g.kd_scale)} "
                                                 "the kd" for g in scaled) + " (the model's fitted gain scales)")


def _write_rows(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    def write(tmp: Path) -> None:
        with open(tmp, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
            w.writeheader()
            w.writerows(rows)

    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, write)


def write_trials(d: Path, plan: Plan, cands: Sequence[Candidate]) -> None:
    rows = [c.row(plan.groups, plan.task) for c in cands]
    if rows:
        _write_rows(d / "trials.csv", rows)


def tradeoff_rows(plan: Plan, cands: Sequence[Candidate], pick: Candidate | None) -> list[dict[str, Any]]:
    """The trade-off set as tradeoffs.csv holds it: each candidate's gains,
    push dip, slowest group's natural frequency, lowest stand height, and
    whether it is the pick."""
    rows = []
    for c in tradeoffs(plan, cands):
        r = c.row(plan.groups, plan.task)
        rows.append({"trial": r["trial"], **{k: v for k, v in r.items() if k.startswith(("kp.", "kd."))},
                     plan.task.column: c.score, "slowest_hz": slowest_hz(plan, c), "min_height_m": c.min_height_m,
                     "p95_peak_torque": c.p95_peak_torque,
                     "pick": pick is not None and gains_key(c.gains) == gains_key(pick.gains)})
    return rows


def write_outputs(rec: Recommendation, d: Path, keep: bool, wall: float) -> tuple[str, str]:
    """recommend.csv, the exports, the manifest and report.html (with
    `keep`); the YAML and MJCF texts."""
    plan, pick = rec.plan, rec.pick
    yaml_text = ros2_yaml(plan, pick) if pick else ""
    xml_text = (d / "recommended.xml").read_text() if pick and (d / "recommended.xml").exists() else ""
    if not keep:
        return yaml_text, xml_text
    front = tradeoff_rows(plan, rec.candidates, rec.searched)
    if front:
        _write_rows(d / "tradeoffs.csv", front)
    # a run over an older one (--force) leaves none of its answer behind
    stale = (["tradeoffs.csv"] if not front else []) + ([] if pick else ["recommend.csv", "recommended.yaml",
                                                                         "recommended.xml"])
    for name in stale:
        (d / name).unlink(missing_ok=True)
    if pick:
        atomic_write_text(d / "recommended.yaml", yaml_text)

        # a task's own columns beside each group's card
        rows = [asdict(c) | plan.task.card_columns(plan, pick) for c in rec.cards]
        # the motors' delivered gains only where the model scales them
        names = [k for k in rows[0] if any(r[k] is not None for r in rows)]

        def cards(tmp: Path) -> None:
            with open(tmp, "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=names, lineterminator="\n", extrasaction="ignore")
                w.writeheader()
                w.writerows(rows)

        atomic_write(d / "recommend.csv", cards)
    _native.write_manifest(os.fspath(d), "recommend", _manifest(rec, wall))
    from pupper_core import _report

    _report.report(d)
    return yaml_text, xml_text


def _manifest(rec: Recommendation, wall: float) -> dict[str, Any]:
    pick, task = rec.pick, rec.plan.task
    return {
        "inputs": rec.plan.inputs(),
        "pick": None if pick is None else {g: {"kp": kp, "kd": kd} for g, (kp, kd) in pick.gains.items()},
        task.column: None if pick is None else pick.score,
        "neighbours": rec.neighbours,
        "warnings": rec.warnings,
        "reproduce": task.reproduce(rec.plan, rec.out) if pick and rec.out else "",
        "current": None if rec.current is None else {
            "gains": {g: {"kp": kp, "kd": kd} for g, (kp, kd) in rec.current.gains.items()},
            task.column: rec.current.score, "fell": rec.current.fell, "failed": rec.current.failed,
            "p95_peak_torque": rec.current.p95_peak_torque, "phase_margin_deg": rec.current.phase_deg,
            "gain_margin_db": rec.current.gain_db},
        **task.manifest(rec),
        "nearest": None if rec.nearest is None else {
            "gains": {g: {"kp": kp, "kd": kd} for g, (kp, kd) in rec.nearest.gains.items()},
            "how": rec.nearest.stage, "short": short.shortfall(rec.plan, rec.nearest),
            "phase_margin_deg": rec.nearest.phase_deg, "gain_margin_db": rec.nearest.gain_db,
            "lines": rec.short_lines},
        "candidates": len(rec.candidates),
        "cell_steps": sum(c.cell_steps for c in rec.candidates),
        "complete": True,
        "wall_seconds": round(wall, 3),
    }


def constraints_line(plan: Plan) -> str:
    sag = (f"none ends more than {100 * plan.max_sag:g} % below its {1000 * plan.stance:.1f} mm stance height, "
           if math.isfinite(plan.stance) else "")
    return (f"none fell, saturation under {100 * plan.max_saturation:g} % of steps, {sag}{plan.task.constraints()}"
            f"phase margin >= "
            f"{plan.min_phase_margin:g}°, gain margin >= {plan.min_gain_margin:g} dB (firmware {plan.motor or 'ideal'}, "
            f"{plan.latency_words()})")


def print_card(rec: Recommendation) -> None:
    plan, pick = rec.plan, rec.pick
    # gains asked again in the polish reuse their robots' results: not run twice
    ran = [c for c in rec.candidates if c.cell_steps]
    steps = sum(c.cell_steps for c in rec.candidates)
    if pick is None:
        print(_no_pick(rec, len(ran)))
        if rec.nearest is not None:
            print(short.line(plan, rec.nearest))
        for line in rec.short_lines:
            print(line)
        if rec.current is not None:
            print(in_use_line(plan, rec.current))
        if plan.latency_from:
            print(plan.latency_from)
        other = readings_line(plan, rec.nearest.gains if rec.nearest else None,
                              rec.current.gains if rec.current else None, "the best available")
        if other:
            print(other)
        return
    print(f"recommended gains{plan.task.heading()}, holding on each of {plan.robots} drawn robots: "
          f"{constraints_line(plan)}")
    scaled = any(c.motor_kp is not None for c in rec.cards)
    head = ("group", "kp", "kd", *(("motor kp", "motor kd") if scaled else ()), "phase °", "gain dB", "rise s",
            "overshoot %", "settle s")
    print("".join(f"{h:>12}" for h in head))
    for c in rec.cards:
        motor = (f"{c.motor_kp:.4g}", f"{c.motor_kd:.4g}") if c.motor_kp is not None and c.motor_kd is not None else ()
        vals = (c.group, f"{c.kp:.4g}", f"{c.kd:.4g}", *motor, f"{c.phase_margin_deg:.1f}",
                f"{c.gain_margin_db:.1f}", f"{c.rise_time_s:.3g}", f"{c.overshoot_pct:.3g}", f"{c.settling_time_s:.3g}")
        print("".join(f"{v:>12}" for v in vals))
    print(f"kp, kd: the gains to command (recommended.yaml's kps, kds){_delivered_note(plan)}"
          + ("; the margins are of the delivered gains (motor kp, motor kd)" if scaled else ""))
    if plan.fit_runs:
        print(fits_line(plan))
    if plan.latency_from:
        print(plan.latency_from)
    other = readings_line(plan, pick.gains, rec.current.gains if rec.current else None)
    if other:
        print(other)
    c0 = rec.cards[0]
    print(f"{plan.task.card_line(plan, pick, rec.searched)}; peak torque p95 {pick.p95_peak_torque:.3g} N·m of "
          f"{min(c.torque_limit for c in rec.cards):.3g} ({c0.torque_headroom_pct:.0f} % headroom); "
          f"step response: {'the calibrated' if plan.calibrated else 'the nominal'} robot hung in the air")
    if rec.current is not None:
        print(in_use_line(plan, rec.current))
    if rec.neighbours:
        print("why the neighbours lost:")
        for r in rec.neighbours:
            print(f"  {r}")
    for w in rec.warnings:
        print(f"warning: {w}")
    front = tradeoffs(plan, rec.candidates)
    if len(front) > 1:
        print(f"trade-off set: {len(front)} candidates that no other beats at once on {plan.task.measure}, "
              "tracking speed and stand height (tradeoffs.csv)")
    for line in plan.task.lines(rec):
        print(line)
    polished = sum(1 for c in ran if c.stage == "polish")
    print(f"{len(ran)} candidates on the robots ({len(rec.candidates)} asked, {polished} of them neighbours "
          f"in the polish), {steps} cell-steps")


def fits_line(plan: Plan) -> str:
    """Where a model merged from several fit runs came from."""
    return (f"robot: the fit runs {', '.join(str(d) for d in plan.fit_runs)} merged into one model ({plan.model}): "
            "each actuator's calibrated parameters from the run that fitted it")


def in_use_line(plan: Plan, c: Candidate) -> str:
    """The gains the robot runs today, on the same robots, in a line."""
    gains = sorted(set(c.gains.values()))
    which = (f"kp {gains[0][0]:.4g} kd {gains[0][1]:.4g} on every group" if len(gains) == 1 else
             ", ".join(f"{g} kp {kp:.4g} kd {kd:.4g}" for g, (kp, kd) in c.gains.items()))
    worst = min(plan.groups, key=lambda g: c.phase_deg[g.name])
    loop = (f"worst loop {worst.name} phase {c.phase_deg[worst.name]:.1f}°, gain "
            f"{min(c.gain_db.values()):.1f} dB")
    lim = min(g.torque_limit for g in plan.groups)
    if c.fell:
        ran = f"{c.fell} of {c.robots} robots fell, diverged or lay past the stability bound"
    else:
        head = f" ({100 * (1 - c.p95_peak_torque / lim):.0f} % headroom)" if math.isfinite(lim) else ""
        ran = f"{plan.task.says(c.score)}, peak torque p95 {c.p95_peak_torque:.3g} N·m{head}"
    held = "holds every constraint" if not c.failed else f"breaks one: {c.failed}"
    return f"in use ({plan.current_from}: {which}): {ran}; {loop}; {held}"


def _no_pick(rec: Recommendation, ran: int) -> str:
    """Why no candidate held, with what to try."""
    plan = rec.plan
    head = f"no gains held every constraint on all {plan.robots} robots ({constraints_line(plan)})"
    if not rec.candidates:
        # the margin map found no gains at all: nothing was asked or run
        where = "; ".join(f"{g.name} (kp {g.kp_range[0]:.3g} to {g.kp_range[1]:.3g}, kd {g.kd_range[0]:.3g} to "
                          f"{g.kd_range[1]:.3g})" for g in plan.groups if g.name in rec.no_window)
        return (f"{head}: no gains keep the loop margins, so no candidate was asked: they hold nowhere in the "
                f"searched range of {where or 'the groups'}. Try a lower --min-phase-margin or --min-gain-margin, "
                "less sensing delay, a faster firmware (--motor rate=), or a wider range (--kp-max, --kd-max)")
    said = (f"{head}: {len(rec.candidates)} candidates asked, {ran} ran on the robots; most common reason "
            f"{_commonest(rec.candidates)}.")
    tried = [c for c in rec.candidates if c.robots]
    if tried and all(c.fell == c.robots for c in tried):
        top = max(g.kp_range[1] for g in plan.groups)
        return (f"{said} Every robot fell with every candidate: gains up to kp {top:.3g} may be too soft to hold the "
                "robot up; raise --kp-max if the motors allow it, or check that the robot stands "
                f"(pupper stand --model {plan.model})")
    return (f"{said} Try a faster firmware (--motor rate=), less sensing delay, a lower --min-phase-margin, or "
            "(for a robot that sags) a larger --max-sag")


def _commonest(cands: Sequence[Candidate]) -> str:
    """The reason most candidates failed on, as one of them says it (its
    numbers are that candidate's), and how many share it."""
    import re
    from collections import Counter

    # the reason without its numbers: "kfe phase margin N° < N°"
    failed = [c for c in cands if c.failed]
    kinds = Counter(re.sub(r"\d+(\.\d+)?", "N", c.failed) for c in failed)
    if not kinds:
        return "(none said)"
    kind, n = kinds.most_common(1)[0]
    first = next(c.failed for c in failed if re.sub(r"\d+(\.\d+)?", "N", c.failed) == kind)
    return f"({n} of {len(failed)} candidates, e.g. trial {next(c.number for c in failed if c.failed == first)}): {first}"
