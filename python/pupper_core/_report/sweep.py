"""A sweep's and a hold's report: the pick, the map or bars of the ranking
metric, the base height after the landing, the table."""

from __future__ import annotations

import html

from pupper_core._report.page import (Page, best_cell, edge_of, metric_of, numbers, status_warnings, table, ties_with, z_figure,
                                      z_traces)
from pupper_core._report.svg import bars, heatmap, num

def sections(page: Page) -> list[str]:
    """A sweep or a hold: the pick, the figures that explain it, the table."""
    if not page.rows:
        return []
    status_warnings(page)
    d, header, rows = page.dir, page.header, page.rows
    best, rule = best_cell(d, page.kind)
    metric = metric_of(page.kind, header)
    ties: list[str] = []
    if best:
        row = next(r for r in rows if r.get("id") == best)
        page.answer.append(f'<p class="pick" data-id="{html.escape(best)}"><b>{html.escape(best)}</b>: '
                           f"{numbers(row, header)}</p>")
        edge = edge_of(page.manifest, rows, best)
        if edge:
            page.warnings.append(f"the picked cell {best} lies on the edge of the searched grid ({edge}): "
                                 "the best may lie beyond it; widen the grid there")
        ties = ties_with(rows, best, metric, page.kind) if metric else []
        if ties:
            by = "push_dip_mm" if page.kind == "sweep" else "the push dip"
            page.warnings.append(f"{len(ties)} other cell{'s' * (len(ties) > 1)} ({', '.join(ties[:6])}"
                                 f"{', …' if len(ties) > 6 else ''}) tie with the pick on {metric}: "
                                 f"{by} decided")
    none = ("no cell is eligible: each fell, diverged, saturated or lay past the stability bound, or the run "
            "is too short to measure (the warnings say which)")
    page.answer.append(f"<p class='note'>Rule: {html.escape(rule)}.</p>" if best else f"<p>{html.escape(none)}</p>")
    parts = ["<h2>Figures</h2>"]
    axes = [a.get("axis") for a in page.manifest.get("config", {}).get("grid", {}).get("axes", [])]
    if metric and len(axes) >= 2 and {"kp", "kd"} <= set(header):
        # with the pick tied on its metric, the map of what decided comes first
        shown = ([("push_dip_mm", "push_dip_mm, which decided among the tied cells")]
                 if ties and "push_dip_mm" in header else []) + [(metric, metric)]
        bodies = list(dict.fromkeys(r.get("variant", "") for r in rows))
        for body in bodies:
            sub = [r for r in rows if r.get("variant", "") == body]
            if body:
                parts.append(f"<h3>{html.escape(body)}</h3>")
            for m, title in shown:
                parts.append(heatmap(sub, "kp", "kd", m, best, title))
    elif metric:
        bi = next((i for i, r in enumerate(rows) if r.get("id") == best), None)
        parts.append(bars([r["id"] for r in rows], {metric: [num(r.get(metric)) for r in rows]},
                          f"{metric} per cell (orange: the pick)", bi))
    parts.append(z_figure(z_traces(d), rows, best))
    parts.append("<h2>Table (summary.csv; click a column to sort)</h2>" + table(header, rows, {best} if best else set()))
    return parts
