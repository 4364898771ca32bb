"""report.html's sections of a walk (`pupper walk`): the gains that walk
best for each gait setting (best.csv, the Rust core's rule), the speed
achieved against the speed commanded, the ranking metric over the gains,
the base height while walking, the table."""

from __future__ import annotations

import html
import math
from typing import Any

from pupper_core._report.page import Page, TaskWords, edge_of, numbers, read_table, status_warnings, table, z_figure, z_traces
from pupper_core._report.svg import bars, heatmap, lines, num, rounded

#: The gait axes a grid may vary (the Rust core's axes the walk kind owns, axis.rs).
GAIT_AXES = ("frequency", "speed", "duty", "step_height")

#: A pick this far off the commanded velocity (% of it) does not walk the
#: gait: the page says so rather than call it the best walker.
NOT_WALKING = 50.0

#: The figures the answer quotes for a pick, in this order.
QUOTED = ("speed_ms", "speed_error_pct", "drift_ms", "roll_rms_deg", "pitch_rms_deg", "slip_mm_s",
          "amplitude_ratio", "lag_ms", "torque_rms", "cost_of_transport")


def _commanded(page: Page, row: dict[str, str]) -> float:
    """The forward speed a cell was commanded: its speed axis, else the walk's."""
    if row.get("speed", "") != "":
        return num(row["speed"])
    return float(page.manifest.get("config", {}).get("walk", {}).get("speed", math.nan))


def _stat(header: list[str], name: str) -> str:
    """A figure's column: as named, or with replicates its worst side."""
    return name if name in header else f"p95:{name}"


def sections(page: Page) -> list[str]:
    """A walk: per gait setting the pick and its numbers, the speed figure,
    the metric over the gains, the base height, the table."""
    if not page.rows:
        return []
    status_warnings(page)
    d, header, rows = page.dir, page.header, page.rows
    bhead, picks = read_table(d / "best.csv")
    axes = [str(a.get("axis")) for a in page.manifest.get("config", {}).get("grid", {}).get("axes", [])]
    gait = [a for a in axes if a in GAIT_AXES]
    gains = [a for a in axes if a not in GAIT_AXES]
    by = [h for h in bhead[: bhead.index("cells")]] if "cells" in bhead else []
    metric = _stat(header, "speed_error_pct")
    picked: set[str] = set()
    for p in picks:
        key = ", ".join(f"{k} {p[k]}" for k in by)
        where = f" at {html.escape(key)}" if key else ""
        pid = p.get("id", "")
        if not pid:
            page.answer.append(f"<p class='pick'>No gains walk{where}: every cell fell, diverged or saturated.</p>")
            continue
        picked.add(pid)
        row = next(r for r in rows if r.get("id") == pid)
        asked = _commanded(page, row)
        speed = rounded(row.get(_stat(header, "speed_ms"), ""), "speed_ms")
        quoted = [q for q in (_stat(header, q) for q in QUOTED) if q in header]
        error = num(row.get(metric))
        walks = not error >= NOT_WALKING
        verb = "walks best" if walks else "comes closest but does not walk the gait"
        page.answer.append(
            f'<p class="pick" data-id="{html.escape(pid)}"><b>{html.escape(pid)}</b> {verb}{where}: '
            f"{speed} m/s of the {asked:g} m/s commanded; "
            f"{numbers(row, header, lambda h: h in quoted)}</p>")
        if not walks:
            page.warnings.append(f"no cell{where} walks within {NOT_WALKING:g} % of the commanded velocity (the "
                                 f"closest, {pid}, is {error:.0f} % off): these gains carry the robot but do not "
                                 "walk this gait; try stiffer gains, another frequency or step height")
        same = [r for r in rows if all(r.get(k) == p.get(k) for k in by)]
        edge = edge_of(page.manifest, same, pid, gains) if gains else ""
        if edge:
            page.warnings.append(f"the pick {pid}{where} lies on the edge of the searched gains ({edge}): "
                                 "better gains may lie beyond it; widen the grid there")
    rule = ("the lowest speed_error_pct (the achieved velocity's distance from the commanded one, % of the "
            "commanded speed; with replicates p95 over them) among cells that stayed up (status ok, "
            "saturation_frac under 5 %)" + (f", for each setting of {', '.join(by)}" if by else "")
            + "; equal values go to the first in grid order")
    page.answer.append(f"<p class='note'>Rule: {html.escape(rule)}.</p>" if picked else
                       "<p>No cell is eligible: each fell, diverged, saturated or lay past the stability bound, "
                       "or the run is too short to measure (the warnings say which).</p>")
    back = [r["id"] for r in rows if num(r.get(_stat(header, "speed_ms"))) < 0 < _commanded(page, r)]
    if back:
        page.warnings.append(f"{len(back)} cell{'s' * (len(back) > 1)} walked backwards when commanded forwards "
                             f"({', '.join(back[:6])}{', …' if len(back) > 6 else ''})")
    parts = ["<h2>Figures</h2>", _speed_figure(page, gait, gains, picked)]
    if {"kp", "kd"} <= set(gains) and metric in header:
        keys = list(dict.fromkeys(tuple(r.get(a, "") for a in gait) for r in rows))
        for k in keys:
            sub = [r for r in rows if tuple(r.get(a, "") for a in gait) == k]
            pick = next((r["id"] for r in sub if r["id"] in picked), None)
            label = ", ".join(f"{a} {v}" for a, v in zip(gait, k))
            parts.append(heatmap(sub, "kp", "kd", metric, pick, f"{metric}{' at ' + label if label else ''}"))
    elif metric in header:
        bi = next((i for i, r in enumerate(rows) if r["id"] in picked), None)
        parts.append(bars([r["id"] for r in rows], {metric: [num(r.get(metric)) for r in rows]},
                          f"{metric} per cell (orange: a pick)", bi))
    parts.append(z_figure(z_traces(d), rows, next(iter(sorted(picked)), None), " while walking"))
    parts.append("<h2>Table (summary.csv; click a column to sort)</h2>" + table(header, rows, picked))
    return parts


def _speed_figure(page: Page, gait: list[str], gains: list[str], picked: set[str]) -> str:
    """Speed achieved against commanded: a line per gain setting over a
    speed axis (the dashed level: none), else a bar per cell beside the
    commanded speed."""
    header, rows = page.header, page.rows
    col = _stat(header, "speed_ms")
    if "speed" in gait:
        series: dict[str, tuple[list[float], list[float]]] = {}
        for r in rows:
            name = " ".join(f"{a}{r[a]}" for a in gains + [g for g in gait if g != "speed"]) or "achieved"
            xs, ys = series.setdefault(name, ([], []))
            xs.append(num(r["speed"]))
            ys.append(num(r.get(col)))
        lo = min(num(r["speed"]) for r in rows)
        hi = max(num(r["speed"]) for r in rows)
        series["commanded"] = ([lo, hi], [lo, hi])
        return lines(series, f"{col} (m/s) against the speed commanded; the line 'commanded' is perfect tracking",
                     "commanded speed (m/s)", "achieved (m/s)", pick="commanded")
    bi = next((i for i, r in enumerate(rows) if r["id"] in picked), None)
    return bars([r["id"] for r in rows], {col: [num(r.get(col)) for r in rows],
                                           "commanded": [_commanded(page, r) for r in rows]},
                f"speed achieved ({col}) beside the speed commanded, m/s (orange: a pick)", bi, " m/s")


def recommend_walk_rule(inp: dict[str, Any], stand_rule: str) -> str:
    """`recommend --task walk`'s rule, in words: the stand rule's
    constraints, ranked by the walk's speed error instead of the push dip."""
    head, _, rest = stand_rule.partition(" among gains that hold on every one: ")
    constraints = rest.rsplit("; push dips within", 1)[0]
    return (f"the lowest p95 speed error of a {inp.get('gait')} at {inp.get('frequency')} Hz and {inp.get('speed')} "
            f"m/s over {inp.get('robots')} drawn robots among gains that hold on every one while walking: "
            f"{constraints}, roll and pitch RMS under {inp.get('max_tilt_deg')}°; speed errors within 2 % tie, won by "
            "the faster slowest group")


def _recommend_quoted(inp: dict[str, Any], cards: list[dict[str, str]]) -> str:
    """What the answer quotes of `recommend --task walk`'s card."""
    return (f"p95 speed error {num(cards[0].get('p95_speed_error_pct', 'nan')):.4g} % over them at a "
            f"{inp.get('gait')} of {inp.get('frequency')} Hz and {inp.get('speed')} m/s")


def _recommend_shown(manifest: dict[str, Any]) -> str:
    """The pick beside `--task stand`'s, as the card printed it."""
    lines = manifest.get("compared")
    return "<pre>" + html.escape("\n".join(lines)) + "</pre>" if lines else ""


#: `recommend --task walk`'s words (the recommend page's registry holds them).
RECOMMEND = TaskWords("p95_speed_error_pct", "p95 speed error", "%", recommend_walk_rule, _recommend_quoted,
                      _recommend_shown, "the walk")
