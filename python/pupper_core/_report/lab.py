"""A lab's report: the steadiest gains of each body, each body's map and
base-height traces, the table."""

from __future__ import annotations

import html

from pupper_core._report.page import (RULES, Page, edge_of, metric_of, numbers, read_table, status_warnings, table,
                                      z_figure, z_traces)
from pupper_core._report.svg import heatmap
from pupper_core._spec import DEFAULT_METRIC

def sections(page: Page) -> list[str]:
    """A lab: the steadiest gains of each body (best.csv), each body's map
    and base-height traces, the table."""
    if not page.rows:
        return []
    status_warnings(page)
    _, picks = read_table(page.dir / "best.csv")
    by_body = {r.get("variant", ""): r for r in picks}
    series = z_traces(page.dir)
    parts = ["<h2>Figures</h2>"]
    metric = metric_of("lab", page.header) or DEFAULT_METRIC
    for body in dict.fromkeys(r.get("variant", "") for r in page.rows):
        sub = [r for r in page.rows if r.get("variant", "") == body]
        pick = by_body.get(body, {}).get("id") or None
        if pick:
            row = next(r for r in sub if r["id"] == pick)
            page.answer.append(f'<p class="pick" data-body="{html.escape(body)}"><b>{html.escape(body)}</b>: '
                               f"<b>{html.escape(pick)}</b>: {numbers(row, page.header, lambda h: h != 'variant')}"
                               "</p>")
            edge = edge_of(page.manifest, sub, pick, ("kp", "kd"))
            if edge:
                page.warnings.append(f"{body}'s pick {pick} lies on the edge of the searched grid ({edge}): "
                                     "the best may lie beyond it")
        else:
            page.answer.append(f'<p class="pick" data-body="{html.escape(body)}"><b>{html.escape(body)}</b>: '
                               "no cell is eligible (none stood inside the bound unsaturated)</p>")
        parts.append(f"<h3>{html.escape(body)}</h3>" + heatmap(sub, "kp", "kd", metric, pick)
                     + z_figure(series, sub, pick, f" ({body})"))
    page.answer.append(f"<p class='note'>Rule, per body: {html.escape(RULES['sweep'])}.</p>")
    starred = {r.get("id", "") for r in picks} - {""}
    parts.append("<h2>Table (summary.csv; click a column to sort)</h2>" + table(page.header, page.rows, starred))
    return parts
