"""A recommendation's report: the card per group, the rule, the gains in
use beside it, the margins, the trade-off set, why the neighbours lost,
the sweep that reproduces it, every candidate."""

from __future__ import annotations

import html
import math
from typing import Any

from pupper_core._report import walk
from pupper_core._report.page import Page, TaskWords, read_table, table
from pupper_core._report.svg import bars, num, scatter

#: The stand task's words (`recommend --task stand`, the default).
STAND = TaskWords("p95_push_dip_mm", "p95 push dip", "mm", lambda inputs, rule: rule,
                  lambda inputs, cards: f"p95 push dip {num(cards[0].get('p95_push_dip_mm', 'nan')):.4g} mm over them",
                  lambda manifest: "", "the push dip")
#: The registry: each task's words, by the name the manifest's inputs give
#: it (a task of its own writes `task`; the stand's runs write none).
TASKS: dict[str, TaskWords] = {
    "stand": STAND,
    "walk": walk.RECOMMEND,
}

def sections(page: Page) -> list[str]:
    """A recommendation: the answer (a card per group, the rule, the
    warnings), the margins it keeps, why the neighbours lost, the sweep
    that reproduces it, then every candidate."""
    d, manifest = page.dir, page.manifest
    parts: list[str] = []
    ch, cards = read_table(d / "recommend.csv")
    inp = manifest.get("inputs", {})
    rule = (f"the lowest p95 push dip over {inp.get('robots')} drawn robots among gains that hold on every one: "
            f"none fell, saturation under {100 * float(inp.get('max_saturation', 0.05)):g} % of steps, "
            + (f"none ends more than {100 * float(inp['max_sag']):g} % below its "
               f"{1000 * float(inp['stance_m']):.1f} mm stance height, "
               if inp.get("max_sag") is not None and math.isfinite(float(inp.get("stance_m") or "nan")) else "")
            + "phase "
            f"margin >= {inp.get('min_phase_margin_deg')}° and gain margin >= {inp.get('min_gain_margin_db')} dB "
            f"for the loop the firmware ({inp.get('motor') or 'ideal'}) closes with "
            + (f"{inp.get('sensing_delay')} s of sensing delay" if inp.get("sensing_delay") is not None
               else "the model's own feedback latency (a fit's: each robot its own)")
            + "; push dips within 2 % tie, won by the faster slowest group")
    task = TASKS[str(inp.get("task", "stand"))]
    rule = task.rule(inp, rule)
    if cards:
        page.answer.append(f"<p class='pick'>Put these gains on the robot: every constraint held on each drawn "
                           f"robot, {task.quoted(inp, cards)}.</p><p>Rule: {html.escape(rule)}.</p>"
                           + table(ch, cards, None, key="group") + commanded(cards)
                           + in_use(manifest.get("current"), num(cards[0].get(task.column, "nan")), task)
                           + task.shown(manifest))
        parts.append("<h2>Figures</h2>" + bars([c["group"] for c in cards],
                                               {"phase margin": [num(c["phase_margin_deg"]) for c in cards]},
                                               "phase margin at the spread's worst corner (deg)", unit="°"))
    else:
        near = manifest.get("nearest") or {}
        best = ("" if not near else "<p>Best available (not an answer): " + html.escape(", ".join(
            f"{g} kp {v['kp']:.4g} kd {v['kd']:.4g}" for g, v in near.get("gains", {}).items())) + "; "
            + html.escape(str(near.get("short", ""))) + ".</p>")
        page.answer.append(f"<p class='pick'>No gains held every constraint: none to put on the robot.</p>{best}"
                           f"<p>Rule: {html.escape(rule)}.</p>"
                           + in_use(manifest.get("current"), math.nan, task))
    fh, front = read_table(d / "tradeoffs.csv")
    th, trials = read_table(d / "trials.csv")
    parts.append(tradeoff_figure(inp, trials, front, manifest.get("pick") or {}, task))
    if len(front) > 1:
        parts.append("<h2>Trade-off set (tradeoffs.csv)</h2><p>The candidates that held every constraint and "
                     f"that no other beats at once on {task.measure} (lower), the slowest group's natural frequency "
                     "(faster tracking) and the lowest robot's stand height (higher): where the rule's pick "
                     "gives one up for another.</p>" + table(fh, front, None, key="trial"))
    if manifest.get("neighbours"):
        parts.append("<h2>Why the neighbours lost</h2><ul>"
                     + "".join(f"<li>{html.escape(n)}</li>" for n in manifest["neighbours"]) + "</ul>")
    if manifest.get("reproduce"):
        parts.append(f"<h2>Reproduce {task.reproduces}</h2><pre>" + html.escape(manifest["reproduce"]) + "</pre>")
    page.warnings.extend(manifest.get("warnings", []))
    if trials:
        parts.append("<h2>Candidates (trials.csv)</h2>" + table(th, trials, None, key="trial"))
    return parts

def commanded(cards: list[dict[str, str]]) -> str:
    """What the card's gains are: to command; and, on a calibrated model,
    what the motors deliver of them (the margins are of those)."""
    line = "kp, kd: the gains to command (recommended.yaml's kps, kds)"
    if cards and cards[0].get("motor_kp"):
        line += ("; motor kp, motor kd: what the motors deliver of them by the model's fitted gain scales; the "
                 "margins are of the delivered gains")
    return f"<p>{html.escape(line)}.</p>"

def in_use(current: dict[str, Any] | None, picked: float, task: TaskWords) -> str:
    """The gains the robot runs today, on the same robots, beside the pick
    (whose score is `picked`)."""
    if not current:
        return ""
    gains = ", ".join(f"{g} kp {v['kp']:.4g} kd {v['kd']:.4g}" for g, v in current["gains"].items())
    ran = (f"{current['fell']} robot(s) fell" if current.get("fell") else
           f"{task.objective} {num(str(current.get(task.column))):.4g} {task.unit}"
           + (f" (the pick's {picked:.4g} {task.unit})" if math.isfinite(picked) else ""))
    held = "holds every constraint" if not current.get("failed") else f"breaks one: {current['failed']}"
    return f"<p>In use today ({html.escape(gains)}): {html.escape(ran)}; {html.escape(held)}.</p>"

def tradeoff_figure(inputs: dict[str, Any], trials: list[dict[str, str]], front: list[dict[str, str]],
                    picked: dict[str, dict[str, float]], task: TaskWords = STAND) -> str:
    """Every candidate that held, by its slowest group's natural frequency
    and its score (the stand task's p95 push dip): the trade-off set
    filled, the pick starred."""
    inertia = {g: float(v[1]) for g, v in inputs.get("inertia", {}).items()}
    if not inertia:
        return ""

    def hz(r: dict[str, str]) -> float:
        return min(math.sqrt(num(r[f"kp.{g}"]) / J) for g, J in inertia.items()) / (2 * math.pi)

    pts = {f"trial {r['trial']}": (hz(r), num(r[task.column])) for r in trials if r.get("status") == "ok"}
    # the pick: the first candidate with its gains (the polish may ask one twice)
    pick = next((f"trial {r['trial']}" for r in trials if r.get("status") == "ok" and picked
                 and all(num(r[f"{k}.{g}"]) == v[k] for g, v in picked.items() for k in ("kp", "kd"))), None)
    return scatter(pts, "candidates that held every constraint: the trade-off set filled, the pick ★",
                   "slowest group's natural frequency sqrt(kp/J) (Hz): faster tracking →",
                   f"{task.objective} ({task.unit})", [f"trial {r['trial']}" for r in front], pick)
