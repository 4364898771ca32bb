"""`report.html`: one self-contained page per run directory, readable in any
browser with no network (no script, font or picture from elsewhere). Plots
are inline SVG drawn here from the files beside it, so the page weighs a
few tens of kB and needs no charting library; the only script is a few
lines that sort the table by a clicked column.

Built from what the run directory holds (manifest.json, summary.csv and the
experiment kind's own tables), never by stepping physics.
"""

from __future__ import annotations
from pupper_core._spec import DEFAULT_METRIC, ROBUST_METRIC

import base64
import csv
import html
import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Callable, NamedTuple

__all__ = ["report"]

STATUS_COLOUR = {"ok": "#d8f0d8", "saturated": "#fff0c0", "past_bound": "#ffd8a8", "fell": "#f8d0d0",
                 "diverged": "#e0c8f0", "pruned": "#e8e8e8"}
#: The steadiest-first colour ramp of the heatmaps (viridis, reversed: yellow is best).
RAMP = ["#fde725", "#b5de2b", "#6ece58", "#35b779", "#1f9e89", "#26828e", "#31688e", "#3e4989",
        "#482878", "#440154"]

SCRIPT = """
document.querySelectorAll('table.sortable').forEach(function (t) {
  t.querySelectorAll('th').forEach(function (th, i) {
    th.addEventListener('click', function () {
      var body = t.tBodies[0], rows = Array.from(body.rows);
      var up = th.dataset.dir !== 'up'; th.dataset.dir = up ? 'up' : 'down';
      rows.sort(function (a, b) {
        var x = a.cells[i].textContent, y = b.cells[i].textContent;
        var nx = parseFloat(x), ny = parseFloat(y);
        var c = (isNaN(nx) || isNaN(ny)) ? x.localeCompare(y) : nx - ny;
        return up ? c : -c;
      });
      rows.forEach(function (r) { body.appendChild(r); });
    });
  });
});
"""

STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em; color: #222; max-width: 1200px; }
h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; font-size: 0.85em; }
td, th { border: 1px solid #ccc; padding: 2px 6px; text-align: right; }
th { background: #eee; cursor: pointer; } td.text, th.text { text-align: left; }
.best { font-weight: bold; outline: 2px solid #333; }
.warn { background: #fff4d0; border-left: 4px solid #e0a000; padding: 4px 8px; margin: 4px 0; }
.note { color: #555; font-size: 0.9em; }
dl { display: grid; grid-template-columns: max-content auto; gap: 2px 12px; font-size: 0.9em; }
dt { font-weight: bold; } dd { margin: 0; }
svg text { font-family: system-ui, sans-serif; }
"""


def _read(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    if not path.is_file():
        return [], []
    # a log's name that is not UTF-8 stands in a fit's tables as its bytes
    with path.open(newline="", errors="surrogateescape") as f:
        r = csv.DictReader(f)
        return list(r.fieldnames or []), list(r)


def _num(v: Any) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def _fmt(v: str) -> str:
    x = _num(v)
    if math.isnan(x) or v.strip() == "":
        return html.escape(v)
    return f"{x:.4g}"


def _colour(x: float, lo: float, hi: float, log: bool) -> str:
    if math.isnan(x):
        return "#ffffff"
    if log and lo > 0:
        x, lo, hi = math.log10(max(x, lo)), math.log10(lo), math.log10(hi)
    f = 0.0 if hi <= lo else min(max((x - lo) / (hi - lo), 0.0), 1.0)
    return RAMP[min(int(f * len(RAMP)), len(RAMP) - 1)]


def _heatmap(rows: list[dict[str, str]], xa: str, ya: str, metric: str, best: str | None) -> str:
    xs = sorted({_num(r[xa]) for r in rows})
    ys = sorted({_num(r[ya]) for r in rows})
    cells = {(_num(r[xa]), _num(r[ya])): r for r in rows}
    # the ramp spans the cells whose numbers describe a robot: a cell past
    # the stability bound is drawn grey, never as a colour to pick
    vals = [_num(r.get(metric)) for r in rows if r.get("status") in ("ok", "saturated")]
    vals = [v for v in vals if not math.isnan(v)]
    lo, hi = (min(vals), max(vals)) if vals else (0.0, 1.0)
    w, h, left, top = 64, 34, 70, 30
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{max(left + w * len(xs) + 20, 760)}" '
           f'height="{top + h * len(ys) + 50}" role="img" aria-label="{html.escape(metric)} heatmap">']
    for j, y in enumerate(reversed(ys)):
        out.append(f'<text x="{left - 6}" y="{top + j * h + h / 2 + 4}" text-anchor="end" font-size="11">'
                   f'{y:g}</text>')
        for i, x in enumerate(xs):
            r = cells.get((x, y))
            v = _num(r.get(metric)) if r else math.nan
            past = r is not None and r.get("status") == "past_bound"
            stood = r is not None and r.get("status") in ("ok", "saturated")
            fill = (_colour(v, lo, hi, lo > 0 and hi / max(lo, 1e-300) > 20) if stood
                    else "#d0d0d0" if past else "#f0c0c0")
            px, py = left + i * w, top + j * h
            mark = ' stroke="#000" stroke-width="3"' if r and best and r.get("id") == best else ' stroke="#fff"'
            label = (f"{v:.3g}" if stood and not math.isnan(v) else "past bound" if past
                     else (r.get("status", "") if r else ""))
            shown = f"{label} ({v:.3g}: the integrator's number)" if past and not math.isnan(v) else label
            out.append(f'<rect x="{px}" y="{py}" width="{w}" height="{h}" fill="{fill}"{mark}>'
                       f'<title>{html.escape(xa)} {x:g}, {html.escape(ya)} {y:g}: {html.escape(shown)}</title></rect>')
            out.append(f'<text x="{px + w / 2}" y="{py + h / 2 + 4}" text-anchor="middle" font-size="10">'
                       f'{html.escape(label)}{" ★" if r and best and r.get("id") == best else ""}</text>')
    for i, x in enumerate(xs):
        out.append(f'<text x="{left + i * w + w / 2}" y="{top + h * len(ys) + 16}" text-anchor="middle" '
                   f'font-size="11">{x:g}</text>')
    out.append(f'<text x="{left + w * len(xs) / 2}" y="{top + h * len(ys) + 36}" text-anchor="middle" '
               f'font-size="12">{html.escape(xa)}</text>')
    out.append(f'<text x="12" y="{top + h * len(ys) / 2}" font-size="12" transform="rotate(-90 12 '
               f'{top + h * len(ys) / 2})" text-anchor="middle">{html.escape(ya)}</text>')
    out.append(f'<text x="{left}" y="18" font-size="12">{html.escape(metric)} (yellow is lower; red: fell or '
               'diverged; grey: past the stability bound; ★ the pick)</text></svg>')
    return "".join(out)


def _bars(labels: Sequence[str], values: Sequence[float], title: str, best: int | None = None) -> str:
    finite = [v for v in values if not math.isnan(v)]
    top = max(finite) if finite else 1.0
    top = top if top > 0 else 1.0
    bh, left, width = 16, 170, 420
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{left + width + 90}" height="{30 + bh * len(labels)}" '
           f'role="img" aria-label="{html.escape(title)}"><text x="4" y="14" font-size="12">{html.escape(title)}</text>']
    for i, (lab, v) in enumerate(zip(labels, values)):
        y = 22 + i * bh
        wv = 0 if math.isnan(v) else width * max(v, 0) / top
        fill = "#f0a030" if i == best else "#3e7cb1"
        out.append(f'<text x="{left - 4}" y="{y + 11}" text-anchor="end" font-size="10">{html.escape(lab)}</text>'
                   f'<rect x="{left}" y="{y + 2}" width="{wv:.1f}" height="{bh - 4}" fill="{fill}"/>'
                   f'<text x="{left + wv + 4:.1f}" y="{y + 11}" font-size="10">'
                   f'{"–" if math.isnan(v) else f"{v:.4g}"}</text>')
    out.append("</svg>")
    return "".join(out)


def _lines(series: dict[str, tuple[list[float], list[float]]], title: str, xlabel: str, ylabel: str) -> str:
    pts = [(x, y) for xs, ys in series.values() for x, y in zip(xs, ys) if not math.isnan(y)]
    if not pts:
        return ""
    x0, x1 = min(p[0] for p in pts), max(p[0] for p in pts)
    y0, y1 = min(p[1] for p in pts), max(p[1] for p in pts)
    if x1 == x0:
        x1 = x0 + 1
    if y1 == y0:
        y1 = y0 + 1e-9
    W, H, L, T = 640, 260, 70, 24
    palette = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
               "#bcbd22", "#17becf"]
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W + L + 170}" height="{H + T + 44}" role="img" '
           f'aria-label="{html.escape(title)}"><text x="{L}" y="16" font-size="12">{html.escape(title)}</text>',
           f'<rect x="{L}" y="{T}" width="{W}" height="{H}" fill="none" stroke="#999"/>']
    for k, (name, (xs, ys)) in enumerate(series.items()):
        c = palette[k % len(palette)]
        path = " ".join(f"{L + W * (x - x0) / (x1 - x0):.1f},{T + H - H * (y - y0) / (y1 - y0):.1f}"
                        for x, y in zip(xs, ys) if not math.isnan(y))
        out.append(f'<polyline points="{path}" fill="none" stroke="{c}" stroke-width="1.2"/>')
        if k < 12:
            out.append(f'<text x="{L + W + 8}" y="{T + 12 + 13 * k}" font-size="10" fill="{c}">{html.escape(name)}</text>')
    for f in (0.0, 0.5, 1.0):
        out.append(f'<text x="{L - 4}" y="{T + H - H * f + 4}" text-anchor="end" font-size="10">'
                   f'{y0 + f * (y1 - y0):.4g}</text>'
                   f'<text x="{L + W * f}" y="{T + H + 14}" text-anchor="middle" font-size="10">{x0 + f * (x1 - x0):.4g}</text>')
    out.append(f'<text x="{L + W / 2}" y="{T + H + 32}" text-anchor="middle" font-size="11">{html.escape(xlabel)}</text>'
               f'<text x="14" y="{T + H / 2}" font-size="11" transform="rotate(-90 14 {T + H / 2})" '
               f'text-anchor="middle">{html.escape(ylabel)}</text></svg>')
    return "".join(out)


def _table(header: list[str], rows: list[dict[str, str]], best: str | None, key: str = "id") -> str:
    out = ['<table class="sortable"><thead><tr>']
    for h in header:
        out.append(f'<th class="{"text" if h in ("id", "name", "status", "parameter", "actuators") else ""}">'
                   f'{html.escape(h)}</th>')
    out.append("</tr></thead><tbody>")
    for r in rows:
        cls = ' class="best"' if best and r.get(key) == best else ""
        out.append(f"<tr{cls}>")
        for h in header:
            v = r.get(h, "")
            if h == "status" or h.startswith("status."):
                out.append(f'<td class="text" style="background:{STATUS_COLOUR.get(v, "#fff")}">{html.escape(v)}</td>')
            elif h in ("id", "name", "parameter", "actuators", "unit", "log", "actuator"):
                out.append(f'<td class="text">{html.escape(v)}</td>')
            else:
                # every digit in the title, four significant ones shown
                out.append(f'<td title="{html.escape(v)}">{_fmt(v)}</td>')
        out.append("</tr>")
    out.append("</tbody></table>")
    return "".join(out)


#: The kinds a manifest names (sweep, lab and response by the Rust core;
#: tune and fit by their Python drivers).
KINDS = ("sweep", "lab", "response", "hold", "tune", "fit", "recommend")


def _kind(manifest: dict[str, Any]) -> str:
    kind = manifest.get("kind")
    if kind in KINDS:
        return str(kind)
    # a manifest written before runs named their kind
    if manifest.get("command") == "fit":
        return "fit"
    if "space" in manifest.get("inputs", {}) or manifest.get("kind") == "tune":
        return "tune"
    cfg = manifest.get("config", {})
    if cfg.get("response"):
        return "response"
    cmd = manifest.get("command")
    if isinstance(cmd, list) and len(cmd) > 1 and cmd[1] == "lab":
        return "lab"
    return "sweep"


def _inputs(manifest: dict[str, Any], kind: str) -> str:
    items: list[tuple[str, str]] = []
    cmd = manifest.get("command")
    if isinstance(cmd, list) and cmd:
        # the program by its name (where it was installed says nothing of the run)
        items.append(("command", " ".join([Path(str(cmd[0])).name, *map(str, cmd[1:])])))
    cfg = manifest.get("config")
    if cfg:
        model = manifest.get("model", {})
        items.append(("model", f"{model.get('name', cfg.get('model'))} (sha256 {str(model.get('sha256', ''))[:12]})"))
        items.append(("mode", str(cfg.get("mode"))))
        for a in cfg.get("grid", {}).get("axes", []):
            items.append((f"axis {a.get('axis')}", ", ".join(f"{v:g}" if isinstance(v, (int, float)) else str(v)
                                                             for v in a.get("values", []))))
        sch = cfg.get("schedule", {})
        items.append(("seconds", str(sch.get("duration"))))
        if sch.get("push"):
            p = sch["push"]
            items.append(("push", f"{p.get('force')} N at {p.get('start')} s for {p.get('duration')} s"))
        if sch.get("sine"):
            items.append(("sine force", json.dumps(sch["sine"])))
        if cfg.get("replicates"):
            items.append(("replicates", json.dumps(cfg["replicates"])))
        if cfg.get("motor"):
            items.append(("motor", json.dumps(cfg["motor"])))
        if cfg.get("response"):
            items.append(("excitation", json.dumps(cfg["response"])))
    if kind == "tune":
        for k, v in manifest.get("inputs", {}).items():
            if k != "options":
                items.append((k, json.dumps(v)))
    if kind == "fit":
        inp = manifest.get("inputs", {})
        items.append(("model", str(inp.get("model"))))
        for lg in inp.get("logs", []):
            items.append(("log", f"{lg['path']} (sha256 {lg['sha256'][:12]})"))
        items.append(("parameters", ", ".join(inp.get("params", [])) + f" per {inp.get('per')}"))
    for k in ("pupper_version", "mujoco_version", "wall_seconds", "cells_done", "cells_total", "complete"):
        if k in manifest:
            items.append((k.replace("_", " "), str(manifest[k])))
    if "versions" in manifest:
        items.append(("versions", json.dumps(manifest["versions"])))
    return "<dl>" + "".join(f"<dt>{html.escape(k)}</dt><dd>{html.escape(v)}</dd>" for k, v in items) + "</dl>"


def _best(run_dir: Path, kind: str = "sweep") -> tuple[str | None, str]:
    """The cell pupper's rule picks (by the kind's own metric), and the rule
    in words."""
    try:
        from pupper_core._api import load_run

        res = load_run(run_dir)
        b = res.best()
    except Exception:  # a run with nothing ranked (or not a sweep)
        return None, ""
    if not b:
        return None, "no cell is eligible (none stood, or the run is too short to measure)"
    if kind == "hold":
        rule = ("the lowest compliance_mm_per_n (sag per newton of load) among cells that stood inside the "
                "stability bound (status ok or saturated, saturation_frac under 5 %); equal values go to the "
                "smaller push dip, then grid order")
    else:
        rule = ("the lowest last_1s_std_mm (with replicates: p95 over them) among cells that stood inside the "
                "stability bound (status ok or saturated, saturation_frac under 5 %); cells within 0.001 mm are "
                "tied and the smaller push dip decides, then grid order")
    return str(b["id"]), rule


def _edge(manifest: dict[str, Any], rows: list[dict[str, str]], best: str) -> str:
    """The numeric axes on whose largest or smallest value the picked cell
    lies, in a product grid (named cells one by one are no range), as the
    CLI's line says them; "" when none."""
    axes = [str(a.get("axis")) for a in manifest.get("config", {}).get("grid", {}).get("axes", [])]
    values = {a: sorted({_num(r.get(a)) for r in rows}) for a in axes}
    if not axes or math.prod(len(v) for v in values.values()) != len(rows):
        return ""
    row = next(r for r in rows if r.get("id") == best)
    said = []
    for a in axes:
        v, vs = _num(row.get(a)), values[a]
        if len(vs) < 2 or any(math.isnan(x) for x in vs):
            continue
        if v == vs[-1]:
            said.append(f"{a} {row[a]}, the largest")
        elif v == vs[0]:
            said.append(f"{a} {row[a]}, the smallest")
    return "; ".join(said)


def response_pick(header: list[str], rows: list[dict[str, str]], group: str) -> dict[str, str] | None:
    """The response cell that settles soonest on a joint group: pupper's
    ranking rule (the Rust core's `best`) on settling_time_s.GROUP, judged
    by that group's status; the first in grid order on a tie."""
    from pupper_core import _native

    col = f"settling_time_s.{group}"
    if col not in header:
        return None
    (i,) = _native.best_rows(header, [[r.get(h, "") for h in header] for r in rows], col)
    return None if i is None else rows[i]


def _response_best(header: list[str], rows: list[dict[str, str]]) -> str:
    out = []
    for g in ("haa", "hfe", "kfe"):
        if f"settling_time_s.{g}" not in header:
            continue
        r = response_pick(header, rows, g)
        if r is None:
            out.append(f"<p>{g}: no cell settled (status ok)</p>")
            continue
        shown = ", ".join(f"{h} {r[h]}" for h in header
                          if (h.endswith(f".{g}") or h in ("kp", "kd")) and r.get(h, "") != "")
        out.append(f'<p class="pick" data-group="{g}">{g}: <b>{html.escape(r["id"])}</b>: {html.escape(shown)}</p>')
    out.append("<p class='note'>Rule: per joint group, the lowest settling_time_s among cells whose status on "
               "that group is ok; the first in grid order on a tie.</p>")
    return "".join(out)


class Page(NamedTuple):
    """What a kind's sections are drawn from: the run directory, its
    manifest and kind, summary.csv, and the page's warnings (a section adds
    its own)."""

    dir: Path
    manifest: dict[str, Any]
    kind: str
    header: list[str]
    rows: list[dict[str, str]]
    warnings: list[str]


Sections = Callable[[Page], list[str]]


def _grid_sections(page: Page) -> list[str]:
    """A run of the sweep runner (sweep, lab, response, hold): the pick, the
    plots of its kind, the table."""
    d, manifest, kind, header, rows, warnings = page
    parts: list[str] = []
    best, rule = _best(d, kind) if kind in ("sweep", "lab", "hold") and rows else (None, "")
    if kind == "response" and rows:
        parts.append("<h2>Best cells</h2>" + _response_best(header, rows))
    if not rows:
        return parts
    counts: dict[str, int] = {}
    for r in rows:
        counts[r.get("status", "")] = counts.get(r.get("status", ""), 0) + 1
    why = {"saturated": " (at the torque limit in 5 % or more of actuator-steps)",
           "past_bound": (" the stability bound of the PD as the integrator computes it: their numbers "
                          "describe the integrator, not a robot, so they are never ranked (a smaller "
                          "timestep or --integrator implicitfast simulates such gains)")}
    for s in ("fell", "diverged", "saturated", "past_bound"):
        if counts.get(s):
            said = "lie past" if s == "past_bound" else s
            warnings.append(f"{counts[s]} of {len(rows)} cells {said}" + why.get(s, ""))
    if not manifest.get("complete", True):
        warnings.append(f"the run is incomplete ({manifest.get('cells_done')} of {manifest.get('cells_total')} "
                        "cells): finish it with --resume")
    if best and kind in ("sweep", "hold"):
        edge = _edge(manifest, rows, best)
        if edge:
            warnings.append(f"the picked cell {best} lies on the edge of the searched grid ({edge}): "
                            "the best may lie beyond it; widen the grid there")
    if best:
        row = next(r for r in rows if r.get("id") == best)
        # rounded to what a reader uses; every digit in the tooltip
        shown = ", ".join(f'{html.escape(h)} <span title="{html.escape(row[h])}">{_fmt(row[h])}</span>'
                          for h in header if h not in ("index", "name") and row.get(h, "") != "")
        parts.append(f"<h2>Best cell</h2><p><b>{html.escape(best)}</b>: {shown}</p>"
                     f"<p class='note'>Rule: {html.escape(rule)}.</p>")
    elif rule:
        parts.append(f"<h2>Best cell</h2><p>{html.escape(rule)}</p>")
    axes = [a.get("axis") for a in manifest.get("config", {}).get("grid", {}).get("axes", [])]
    metric = "compliance_mm_per_n" if kind == "hold" else (
        DEFAULT_METRIC if DEFAULT_METRIC in header else (
            ROBUST_METRIC if ROBUST_METRIC in header else None))
    parts.append("<h2>Plots</h2>")
    if kind == "response":
        for m in ("rise_time_s", "overshoot_pct"):
            for g in ("haa", "hfe", "kfe"):
                col = f"{m}.{g}"
                if col in header:
                    parts.append(_bars([r["id"] for r in rows], [_num(r[col]) for r in rows], f"{col} per cell"))
        _, jrows = _read(d / "response.csv")
        bad = [r for r in jrows if _num(r.get("stability_margin")) >= 1]
        if bad:
            warnings.append(f"{len(bad)} (cell, joint) pairs lie past the explicit PD's stability bound "
                            "(stability_margin >= 1): they may chatter at the torque limit")
    elif metric and len(axes) >= 2 and {"kp", "kd"} <= set(header):
        # one Kp x Kd map per body (the lab's, or a variant axis)
        _, picks = _read(d / "best.csv")
        starred = {r.get("id") for r in picks} | {best}
        bodies = sorted({r.get("variant", "") for r in rows}, key=[r.get("variant", "") for r in rows].index)
        for body in bodies:
            sub = [r for r in rows if r.get("variant", "") == body]
            pick = next((r["id"] for r in sub if r.get("id") in starred), None)
            if body:
                parts.append(f"<h3>{html.escape(body)}</h3>")
            parts.append(_heatmap(sub, "kp", "kd", metric, pick))
    elif metric:
        bi = next((i for i, r in enumerate(rows) if r.get("id") == best), None)
        parts.append(_bars([r["id"] for r in rows], [_num(r.get(metric)) for r in rows],
                           f"{metric} per cell (orange: the pick)", bi))
    _, trows = _read(d / "traces.csv")
    if trows and "z" in trows[0]:
        series: dict[str, tuple[list[float], list[float]]] = {}
        for r in trows:
            t = _num(r.get("t"))
            if t < 1.0:  # the drop and landing would set the scale
                continue
            xs, ys = series.setdefault(r.get("id", r.get("cell", "")), ([], []))
            xs.append(t)
            ys.append(_num(r.get("z")))
        keep = dict(list(series.items())[:12])
        more = f" (the first 12 of {len(series)} cells)" if len(series) > 12 else ""
        parts.append(_lines(keep, f"base height after the landing (traces.csv){more}", "time (s)",
                            "base z (m)"))
    parts.append("<h2>Table (summary.csv; click a column to sort)</h2>" + _table(header, rows, best))
    return parts


def _tune_sections(page: Page) -> list[str]:
    """A tune: the best objective against cell-steps, the best trial, the trials."""
    parts: list[str] = []
    th, trials = _read(page.dir / "trials.csv")
    objs = [o for o in page.manifest.get("inputs", {}).get("objectives", []) if o in th]
    if trials and objs and "cell_steps" in th:
        spent, best_so_far, acc, cur = [], [], 0.0, math.inf
        for r in trials:
            acc += _num(r["cell_steps"])
            v = _num(r[objs[0]])
            if not math.isnan(v) and r.get("status", "ok") not in ("fell", "diverged", "pruned"):
                cur = min(cur, v)
            spent.append(acc)
            best_so_far.append(cur if math.isfinite(cur) else math.nan)
        parts.append("<h2>Plots</h2>" + _lines({"best so far": (spent, best_so_far)},
                                               "best objective against cell-steps spent", "cell-steps", objs[0]))
    bj = page.dir / "best.json"
    if bj.is_file():
        parts.append("<h2>Best trial</h2><pre>" + html.escape(bj.read_text()) + "</pre>")
    if trials:
        parts.append("<h2>Trials (trials.csv)</h2>" + _table(th, trials, None))
    return parts


def _fit_sections(page: Page) -> list[str]:
    """A fit: the fitted parameters, the error before and after, its warnings."""
    parts: list[str] = []
    fh, frows = _read(page.dir / "fit.csv")
    parts.append("<h2>Fitted parameters (fit.csv)</h2>" + _table(fh, frows, None, key="parameter"))
    rh, rrows = _read(page.dir / "residuals.csv")
    if rrows:
        labels = [f"{r['log']} {r['actuator']}" for r in rrows]
        parts.append("<h2>Plots</h2>"
                     + _bars(labels, [_num(r["rms_before_rad"]) * 1e3 for r in rrows], "RMS angle error before (mrad)")
                     + _bars(labels, [_num(r["rms_after_rad"]) * 1e3 for r in rrows], "RMS angle error after (mrad)"))
    parts += _validation_sections(page.dir)
    page.warnings.extend(page.manifest.get("warnings", []))
    return parts


def _recommend_sections(page: Page) -> list[str]:
    """A recommendation: the answer first (a card per group), the rule and
    why the neighbours lost, the exports, then every candidate."""
    d, manifest, warnings = page.dir, page.manifest, page.warnings
    parts: list[str] = []
    ch, cards = _read(d / "recommend.csv")
    inp = manifest.get("inputs", {})
    rule = (f"the lowest p95 push dip over {inp.get('robots')} drawn robots among gains that hold on every one: "
            f"none fell, saturation under {100 * float(inp.get('max_saturation', 0.05)):g} % of steps, phase "
            f"margin >= {inp.get('min_phase_margin_deg')}° and gain margin >= {inp.get('min_gain_margin_db')} dB "
            f"for the loop the firmware ({inp.get('motor')}) closes with {inp.get('sensing_delay')} s of sensing "
            "delay; push dips within 2 % tie, won by the faster slowest group")
    if cards:
        dip = _num(cards[0].get("p95_push_dip_mm", "nan"))
        parts.append(f"<h2>The answer</h2><p>Put these gains on the robot (p95 push dip {dip:.3g} mm). "
                     f"Rule: {html.escape(rule)}.</p>" + _table(ch, cards, None, key="group"))
        parts.append(_bars([c["group"] for c in cards], [_num(c["phase_margin_deg"]) for c in cards],
                           "phase margin at the worst corner (deg)"))
    else:
        parts.append(f"<h2>The answer</h2><p>No gains held every constraint. Rule: {html.escape(rule)}.</p>")
    if manifest.get("neighbours"):
        parts.append("<h2>Why the neighbours lost</h2><ul>"
                     + "".join(f"<li>{html.escape(n)}</li>" for n in manifest["neighbours"]) + "</ul>")
    if manifest.get("reproduce"):
        parts.append("<h2>Reproduce the push dip</h2><pre>" + html.escape(manifest["reproduce"]) + "</pre>")
    warnings.extend(manifest.get("warnings", []))
    th, trials = _read(d / "trials.csv")
    if trials:
        parts.append("<h2>Candidates (trials.csv)</h2>" + _table(th, trials, None, key="trial"))
    return parts


def _validation_sections(d: Path) -> list[str]:
    """A fit's validation (fit --validate): its table, the RMS angle error
    of both models, and each log's Bode plot and residual (the PNG, inline)."""
    vh, vrows = _read(d / "validation.csv")
    if not vrows:
        return []
    labels = [f"{r['log']} {r['actuator']}" for r in vrows]
    parts = ["<h2>Validation on logs not fitted (validation.csv)</h2>" + _table(vh, vrows, None, key="log"),
             _bars(labels, [_num(r["rms_nominal_rad"]) * 1e3 for r in vrows], "RMS angle error, nominal model (mrad)")
             + _bars(labels, [_num(r["rms_calibrated_rad"]) * 1e3 for r in vrows],
                     "RMS angle error, calibrated model (mrad)")]
    for png in sorted((d / "plots").glob("validate_*.png")):
        data = base64.b64encode(png.read_bytes()).decode("ascii")
        parts.append(f'<figure><img alt="{html.escape(png.name)}: Bode plot and residual" '
                     f'src="data:image/png;base64,{data}"><figcaption>{html.escape(png.name)}</figcaption></figure>')
    return parts


#: The registry: each kind's sections of the page, between its warnings and
#: its inputs.
SECTIONS: dict[str, Sections] = {
    "sweep": _grid_sections,
    "lab": _grid_sections,
    "response": _grid_sections,
    "hold": _grid_sections,
    "tune": _tune_sections,
    "fit": _fit_sections,
    "recommend": _recommend_sections,
}


def report(run_dir: str | os.PathLike[str]) -> Path:
    """Writes ``run_dir/report.html`` from the files in it; returns its path."""
    from pupper_core._files import atomic_write

    d = Path(run_dir)
    mpath = d / "manifest.json"
    if not mpath.is_file():
        from pupper_core._native import OutputError

        raise OutputError(f"{d} holds no pupper run (no manifest.json): give a run directory")
    manifest = json.loads(mpath.read_text())
    kind = _kind(manifest)
    warnings: list[str] = []
    header, rows = _read(d / "summary.csv")
    parts = SECTIONS[kind](Page(d, manifest, kind, header, rows, warnings))
    files = sorted(p.relative_to(d).as_posix() for p in d.rglob("*")
                   if p.is_file() and not p.name.startswith(".") and p.name != "report.html")
    links = "".join(f'<li><a href="{html.escape(f)}">{html.escape(f)}</a></li>' for f in files)
    warn_html = "".join(f'<div class="warn">{html.escape(w)}</div>' for w in warnings) or "<p>None.</p>"
    page = (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            f"<title>pupper {kind}: {html.escape(d.name)}</title><style>{STYLE}</style></head><body>"
            f"<h1>pupper {kind}: {html.escape(d.name)}</h1>"
            f"<h2>Warnings</h2>{warn_html}"
            + "".join(parts)
            + f"<h2>Inputs (manifest.json)</h2>{_inputs(manifest, kind)}"
            f"<h2>Files</h2><ul>{links}</ul>"
            f"<script>{SCRIPT}</script></body></html>\n")
    out = d / "report.html"
    # a name that is not UTF-8 shows as U+FFFD in the page
    atomic_write(out, lambda tmp: tmp.write_bytes(page.encode("utf-8", "replace")))
    return out


def _cli_hex(run_dir: str) -> list[str]:
    """The CLI's call: the directory's path as the hex of its bytes (the CLI
    says the page's path itself)."""
    report(os.fsdecode(bytes.fromhex(run_dir)))
    return []
