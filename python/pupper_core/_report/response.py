"""A response run's part of `report.html`: the cell that settles soonest on
each joint group, its step curve beside the grid's other cells (zoomed to
the first few settling times), rise time and overshoot per cell, the table."""

from __future__ import annotations

import html
import math

from pupper_core._report.page import Page, numbers, read_table, status_warnings, table
from pupper_core._report.svg import bars, lines, num
from pupper_core._spec import OVERSHOOT_NOISE_PCT
from pupper_core.plots.tables import response_pick

GROUPS = ("haa", "hfe", "kfe")
#: How many settling times of the slowest pick a step plot shows.
SETTLING_TIMES_SHOWN = 3.0


def _steps(page: Page, picks: dict[str, str]) -> list[str]:
    """Per joint group, each cell's angle change over the step, averaged over
    the group's joints and divided by the step: the group's pick bold, up to
    5 other cells thin; the x axis to a few settling times of the pick."""
    _, traces = read_table(page.dir / "response_traces.csv")
    if not traces:
        return ["<p class='note'>No step curves: response_traces.csv is written with --trace "
                "(or --plot).</p>"]
    resp = page.manifest.get("config", {}).get("response", {})
    amp = num(resp.get("signal", {}).get("amplitude"))
    if resp.get("signal", {}).get("kind") != "step" or not amp:
        return []
    from pupper_core.plots.response import step_curves

    ids = list(dict.fromkeys(r["id"] for r in traces))
    # the cells drawn, each group's pick and up to 5 others, run again at
    # the physics rate (response_traces.csv keeps every --trace-every-th step)
    drawn: dict[str, list[str]] = {}
    for g, pick in picks.items():
        others = [i for i in ids if i != pick]
        step = max(1, math.ceil(len(others) / 5))
        drawn[g] = [pick, *others[::step][:5]]
    curves = step_curves(page.dir, list(dict.fromkeys(c for cells in drawn.values() for c in cells)))
    out = []
    for g, pick in picks.items():
        row = next(r for r in page.rows if r["id"] == pick)
        settle = num(row.get(f"settling_time_s.{g}"))
        t_end = SETTLING_TIMES_SHOWN * settle if settle > 0 else math.inf
        series: dict[str, tuple[list[float], list[float]]] = {}
        for cell in drawn[g]:
            if (cell, g) not in curves:
                continue
            t, rel = curves[(cell, g)]
            keep = t <= t_end if (t <= t_end).any() else t == t
            series[cell] = (t[keep].tolist(), rel[keep].tolist())
        if pick in series:
            ts = series[pick][0]
            dt = ts[1] - ts[0] if len(ts) > 1 else math.nan
            zoom = f"{SETTLING_TIMES_SHOWN:g} settling times of the pick" if settle > 0 else "the run"
            out.append(lines(series, f"{g}: angle change / step (dashed: the target) over {zoom}, "
                             f"every physics step ({dt * 1e3:.3g} ms)", "time after the step (s)",
                             "angle change / step", pick=pick, guide=1.0, height=180))
    return out


def sections(page: Page) -> list[str]:
    """The picks per joint group, their step curves, the per-cell bars, the
    table."""
    if not page.rows:
        return []
    status_warnings(page)
    header, rows = page.header, page.rows
    groups = [g for g in GROUPS if f"settling_time_s.{g}" in header]
    picks: dict[str, str] = {}
    for g in groups:
        r = response_pick(header, rows, g)
        if r is None:
            page.answer.append(f'<p class="pick" data-group="{g}">{g}: no cell settled (status ok)</p>')
            continue
        picks[g] = r["id"]
        shown = numbers(r, header, lambda h: h.endswith(f".{g}") or h in ("kp", "kd"))
        page.answer.append(f'<p class="pick" data-group="{g}">{g}: <b>{html.escape(r["id"])}</b>: {shown}</p>')
    page.answer.append("<p class='note'>Rule: per joint group, the lowest settling_time_s among cells whose status "
                       "on that group is ok; the first in grid order on a tie.</p>")
    _, jrows = read_table(page.dir / "response.csv")
    bad = [r for r in jrows if num(r.get("stability_margin")) >= 1]
    if bad:
        page.warnings.append(f"{len(bad)} (cell, joint) pairs lie past the explicit PD's stability bound "
                             "(stability_margin >= 1): they may chatter at the torque limit")
    parts = ["<h2>Figures</h2>", *_steps(page, picks)]
    ids = [r["id"] for r in rows]
    for m in ("rise_time_s", "overshoot_pct"):
        cols = {g: f"{m}.{g}" for g in groups if f"{m}.{g}" in header}
        if not cols:
            continue
        # an overshoot below the simulation's resolution is drawn as none
        values = {g: [0.0 if m == "overshoot_pct" and abs(num(r[c])) < OVERSHOOT_NOISE_PCT else num(r[c])
                      for r in rows] for g, c in cols.items()}
        parts.append(bars(ids, values, f"{m} per cell, a bar per joint group"))
    parts.append("<h2>Table (summary.csv; click a column to sort)</h2>" + table(header, rows, set(picks.values())))
    return parts

