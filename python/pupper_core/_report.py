"""`report.html`: one self-contained page per run directory, readable in any
browser with no network (no script, font or picture from elsewhere). Plots
are inline SVG drawn here from the files beside it, so the page weighs a
few tens of kB and needs no charting library; the only script is a few
lines that sort the table by a clicked column.

Built from what the run directory holds (manifest.json, summary.csv and the
experiment kind's own tables), never by stepping physics.
"""

from __future__ import annotations

import csv
import html
import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Callable, NamedTuple

from pupper_core._report_svg import bars, fmt, heatmap, lines, num, rounded, scatter
from pupper_core._spec import DEFAULT_METRIC, ROBUST_METRIC

__all__ = ["report"]

STATUS_COLOUR = {"ok": "#d8f0d8", "saturated": "#fff0c0", "past_bound": "#ffd8a8", "fell": "#f8d0d0",
                 "diverged": "#e0c8f0", "pruned": "#e8e8e8"}
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
#answer { background: #f6f9ff; border: 1px solid #c8d4e8; padding: 4px 14px 10px; }
#answer .pick { font-size: 1.05em; }
body { font-family: system-ui, sans-serif; margin: 1.5em; color: #222; max-width: 1200px; }
h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; font-size: 0.85em; }
td, th { border: 1px solid #ccc; padding: 2px 6px; text-align: right; }
th { background: #eee; cursor: pointer; } td.text, th.text { text-align: left; }
td.text { max-width: 24em; overflow-wrap: break-word; }
td.worse { background: #fde4e0; }
th.group { text-align: center; cursor: default; }
.scroll { overflow-x: auto; max-width: 100%; margin: 4px 0; }
svg, img { max-width: 100%; height: auto; }
.best { font-weight: bold; outline: 2px solid #333; }
.warn { background: #fff4d0; border-left: 4px solid #e0a000; padding: 4px 8px; margin: 4px 0; }
.verdict { font-size: 1.05em; padding: 6px 10px; margin: 6px 0; border-left: 4px solid; }
.verdict.good { background: #e6f4e6; border-color: #3a9a3a; }
.verdict.bad { background: #fde4e0; border-color: #c0392b; }
.verdict.unjudged { background: #fff4d0; border-color: #e0a000; }
.note { color: #555; font-size: 0.9em; }
dl { display: grid; grid-template-columns: max-content auto; gap: 2px 12px; font-size: 0.9em; }
dt { font-weight: bold; } dd { margin: 0; overflow-wrap: anywhere; }
pre { overflow-x: auto; }
svg text { font-family: system-ui, sans-serif; }
"""


def _read(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    if not path.is_file():
        return [], []
    # a log's name that is not UTF-8 stands in a fit's tables as its bytes
    with path.open(newline="", errors="surrogateescape") as f:
        r = csv.DictReader(f)
        return list(r.fieldnames or []), list(r)


def _breakable(name: str) -> str:
    """A name that may wrap after its underscores, dots and dashes (a
    table of long names narrows to the page instead of running off it)."""
    return "".join(html.escape(c) + ("<wbr>" if c in "_.-/" else "") for c in name)


def _table(header: list[str], rows: list[dict[str, str]], picks: str | set[str] | None, key: str = "id",
           shown: Callable[[str, dict[str, str]], str] | None = None) -> str:
    """A sortable table; the rows of ``picks`` (one key, a set, or None; by
    ``key``) in bold; ``shown(column, row)``, where given, the HTML of a
    text cell. In a box of its own that scrolls sideways where the page is
    too narrow for it: no column is ever cut off."""
    picks = {picks} if isinstance(picks, str) else picks or set()
    out = ['<div class="scroll"><table class="sortable"><thead><tr>']
    for h in header:
        out.append(f'<th class="{"text" if h in ("id", "name", "status", "parameter", "actuators") else ""}">'
                   f'{_breakable(h)}</th>')
    out.append("</tr></thead><tbody>")
    for r in rows:
        cls = ' class="best"' if r.get(key) in picks else ""
        out.append(f"<tr{cls}>")
        for h in header:
            v = r.get(h, "")
            if h == "status" or h.startswith("status."):
                out.append(f'<td class="text" style="background:{STATUS_COLOUR.get(v, "#fff")}">{html.escape(v)}</td>')
            elif h in ("id", "name", "parameter", "actuators", "unit", "log", "actuator"):
                out.append(f'<td class="text">{shown(h, r) if shown else _breakable(v)}</td>')
            else:
                # every digit in the title, four significant ones shown
                out.append(f'<td title="{html.escape(v)}">{fmt(v, h)}</td>')
        out.append("</tr>")
    out.append("</tbody></table></div>")
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
            force = ", ".join(f"{f:.4g}" for f in p.get("force", []))
            items.append(("push", f"[{force}] N at {p.get('start')} s for {p.get('duration')} s"))
        if sch.get("sine"):
            items.append(("sine force", json.dumps(sch["sine"])))
        if cfg.get("replicates"):
            items.append(("replicates", json.dumps(cfg["replicates"])))
        if cfg.get("motor"):
            items.append(("motor", json.dumps(cfg["motor"])))
        if cfg.get("response"):
            # the joints' inertias are the core's working, not an input
            items.append(("excitation", json.dumps({k: v for k, v in cfg["response"].items()
                                                    if k in ("signal", "hold", "select", "standing")})))
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
            v = manifest[k]
            items.append((k.replace("_", " "), f"{v:.3g}" if isinstance(v, float) else str(v)))
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
    return str(b["id"]), RULES["hold" if kind == "hold" else "sweep"]


RULES = {
    "hold": ("the lowest compliance_mm_per_n (sag per newton of load) among cells that stood inside the "
             "stability bound (status ok or saturated, saturation_frac under 5 %); equal values go to the "
             "smaller push dip, then grid order"),
    "sweep": ("the lowest last_1s_std_mm (with replicates: p95 over them) among cells that stood inside the "
              "stability bound (status ok or saturated, saturation_frac under 5 %); cells within 0.001 mm are "
              "tied and the smaller push dip decides, then grid order"),
}


def _edge(manifest: dict[str, Any], rows: list[dict[str, str]], best: str,
          axes: Sequence[str] | None = None) -> str:
    """The numeric axes on whose largest or smallest value the picked cell
    lies, in a product grid (named cells one by one are no range), as the
    CLI's line says them; "" when none."""
    if axes is None:
        axes = [str(a.get("axis")) for a in manifest.get("config", {}).get("grid", {}).get("axes", [])]
    values = {a: sorted({num(r.get(a)) for r in rows}) for a in axes}
    if not axes or math.prod(len(v) for v in values.values()) != len(rows):
        return ""
    row = next(r for r in rows if r.get("id") == best)
    said = []
    for a in axes:
        v, vs = num(row.get(a)), values[a]
        if len(vs) < 2 or any(math.isnan(x) for x in vs):
            continue
        if v == vs[-1]:
            said.append(f"{a} {row[a]}, the largest")
        elif v == vs[0]:
            said.append(f"{a} {row[a]}, the smallest")
    return "; ".join(said)


def _numbers(row: dict[str, str], header: Sequence[str], keep: Callable[[str], bool] = lambda h: True) -> str:
    """A row's values, each rounded with every digit in its tooltip."""
    return ", ".join(f"{html.escape(h)} {rounded(row[h], h)}" for h in header
                     if h not in ("index", "name", "id") and row.get(h, "") != "" and keep(h))


def _metric(kind: str, header: list[str]) -> str | None:
    if kind == "hold":
        return "compliance_mm_per_n"
    return DEFAULT_METRIC if DEFAULT_METRIC in header else ROBUST_METRIC if ROBUST_METRIC in header else None


def _ties(rows: list[dict[str, str]], best: str, metric: str, kind: str) -> list[str]:
    """The other eligible cells the ranking metric cannot tell from the
    pick (within 0.001 mm for a sweep's steadiness; equal for a hold)."""
    row = next(r for r in rows if r.get("id") == best)
    v, tol = num(row.get(metric)), (0.0 if kind == "hold" else 1e-3)
    return [r["id"] for r in rows if r.get("id") != best and r.get("status") in ("ok", "saturated")
            and not num(r.get("saturation_frac")) >= 0.05 and abs(num(r.get(metric)) - v) <= tol]


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


class Page(NamedTuple):
    """What a kind's sections are drawn from: the run directory, its
    manifest and kind, summary.csv, the page's warnings (a section adds its
    own) and its answer (the pick, its numbers and the rule that chose it,
    which the page opens with)."""

    dir: Path
    manifest: dict[str, Any]
    kind: str
    header: list[str]
    rows: list[dict[str, str]]
    warnings: list[str]
    answer: list[str]


Sections = Callable[[Page], list[str]]


def _status_warnings(page: Page) -> None:
    counts: dict[str, int] = {}
    for r in page.rows:
        counts[r.get("status", "")] = counts.get(r.get("status", ""), 0) + 1
    why = {"saturated": " (at the torque limit in 5 % or more of actuator-steps)",
           "past_bound": (" the stability bound of the PD as the integrator computes it: their numbers "
                          "describe the integrator, not a robot, so they are never ranked (a smaller "
                          "timestep or --integrator implicitfast simulates such gains)")}
    for s in ("fell", "diverged", "saturated", "past_bound"):
        if counts.get(s):
            said = "lie past" if s == "past_bound" else s
            page.warnings.append(f"{counts[s]} of {len(page.rows)} cells {said}" + why.get(s, ""))
    m = page.manifest
    # a model without a home keyframe: where its cells started
    page.warnings.extend(m.get("start_notes", []))
    if not m.get("complete", True):
        page.warnings.append(f"the run is incomplete ({m.get('cells_done')} of {m.get('cells_total')} "
                             "cells): finish it with --resume")


def _z_traces(d: Path) -> dict[str, tuple[list[float], list[float]]]:
    """Base height per cell after the landing (the drop would set the scale)."""
    _, trows = _read(d / "traces.csv")
    series: dict[str, tuple[list[float], list[float]]] = {}
    for r in trows:
        t = num(r.get("t"))
        if t >= 1.0 and "z" in r:
            xs, ys = series.setdefault(r.get("id", ""), ([], []))
            xs.append(t)
            ys.append(num(r.get("z")))
    return series


def _z_figure(series: dict[str, tuple[list[float], list[float]]], rows: list[dict[str, str]],
              pick: str | None, what: str = "") -> str:
    """The pick's base height (bold, black) beside up to 11 other cells that
    stood inside the bound."""
    ids = {r["id"] for r in rows}
    stood = [r["id"] for r in rows if r.get("status") == "ok" and r["id"] != pick and r["id"] in series]
    keep = ([pick] if pick in series else []) + stood[:11]
    if not keep:
        return ""
    n = sum(1 for i in series if i in ids)
    title = (f"base height after the landing{what}: the pick (black) and {len(keep) - (pick in series)} "
             f"of {n - (pick in series)} other cells, those that stood inside the bound")
    return lines({k: series[k] for k in keep}, title, "time (s)", "base z (m)", pick=pick)


def _grid_sections(page: Page) -> list[str]:
    """A run of the sweep runner (sweep, lab, response, hold): the pick (one
    per body for a lab, per joint group for a response), the figures that
    explain it, the table."""
    if not page.rows:
        return []
    _status_warnings(page)
    if page.kind == "response":
        from pupper_core._report_response import response_sections

        return response_sections(page)
    if page.kind == "lab":
        return _lab_sections(page)
    d, header, rows = page.dir, page.header, page.rows
    best, rule = _best(d, page.kind)
    metric = _metric(page.kind, header)
    ties: list[str] = []
    if best:
        row = next(r for r in rows if r.get("id") == best)
        page.answer.append(f'<p class="pick" data-id="{html.escape(best)}"><b>{html.escape(best)}</b>: '
                           f"{_numbers(row, header)}</p>")
        edge = _edge(page.manifest, rows, best)
        if edge:
            page.warnings.append(f"the picked cell {best} lies on the edge of the searched grid ({edge}): "
                                 "the best may lie beyond it; widen the grid there")
        ties = _ties(rows, best, metric, page.kind) if metric else []
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
    parts.append(_z_figure(_z_traces(d), rows, best))
    parts.append("<h2>Table (summary.csv; click a column to sort)</h2>" + _table(header, rows, {best} if best else set()))
    return parts


def _lab_sections(page: Page) -> list[str]:
    """A lab: the steadiest gains of each body (best.csv), each body's map
    and base-height traces, the table."""
    _, picks = _read(page.dir / "best.csv")
    by_body = {r.get("variant", ""): r for r in picks}
    series = _z_traces(page.dir)
    parts = ["<h2>Figures</h2>"]
    metric = _metric("lab", page.header) or DEFAULT_METRIC
    for body in dict.fromkeys(r.get("variant", "") for r in page.rows):
        sub = [r for r in page.rows if r.get("variant", "") == body]
        pick = by_body.get(body, {}).get("id") or None
        if pick:
            row = next(r for r in sub if r["id"] == pick)
            page.answer.append(f'<p class="pick" data-body="{html.escape(body)}"><b>{html.escape(body)}</b>: '
                               f"<b>{html.escape(pick)}</b>: {_numbers(row, page.header, lambda h: h != 'variant')}"
                               "</p>")
            edge = _edge(page.manifest, sub, pick, ("kp", "kd"))
            if edge:
                page.warnings.append(f"{body}'s pick {pick} lies on the edge of the searched grid ({edge}): "
                                     "the best may lie beyond it")
        else:
            page.answer.append(f'<p class="pick" data-body="{html.escape(body)}"><b>{html.escape(body)}</b>: '
                               "no cell is eligible (none stood inside the bound unsaturated)</p>")
        parts.append(f"<h3>{html.escape(body)}</h3>" + heatmap(sub, "kp", "kd", metric, pick)
                     + _z_figure(series, sub, pick, f" ({body})"))
    page.answer.append(f"<p class='note'>Rule, per body: {html.escape(RULES['sweep'])}.</p>")
    starred = {r.get("id", "") for r in picks} - {""}
    parts.append("<h2>Table (summary.csv; click a column to sort)</h2>" + _table(page.header, page.rows, starred))
    return parts


def _tune_sections(page: Page) -> list[str]:
    """A tune: the best trial, the best objective against cell-steps, the trials."""
    parts: list[str] = []
    th, trials = _read(page.dir / "trials.csv")
    bj = page.dir / "best.json"
    if bj.is_file():
        bh, brows = _best_trials(json.loads(bj.read_text()))
        said = "Best trial" if len(brows) == 1 else f"Best trials (the Pareto front, {len(brows)})"
        page.answer.append(f"<h3>{said} (best.json)</h3>" + (_table(bh, brows, set()) if brows else
                                                              "<p>No trial is eligible.</p>"))
        page.answer.append("<p class='note'>Rule: the lowest objective (several: the Pareto front) among the "
                           "trials; one whose robot fell, diverged, saturated or lay past the stability bound "
                           "was told a penalty and is never a best.</p>")
    objs = [o for o in page.manifest.get("inputs", {}).get("objectives", []) if o in th]
    if trials and objs and "cell_steps" in th:
        spent, best_so_far, acc, cur = [], [], 0.0, math.inf
        for r in trials:
            acc += num(r["cell_steps"])
            v = num(r[objs[0]])
            # a trial that fell, diverged, saturated or lay past the bound was told a penalty: never a best
            if not math.isnan(v) and r.get("status", "ok") == "ok":
                cur = min(cur, v)
            spent.append(acc)
            best_so_far.append(cur if math.isfinite(cur) else math.nan)
        parts.append("<h2>Figures</h2>" + lines({"best so far": (spent, best_so_far)},
                                                "best objective against cell-steps spent", "cell-steps", objs[0],
                                                pick="best so far"))
    if trials:
        parts.append("<h2>Trials (trials.csv)</h2>" + _table(th, trials, set()))
    return parts


def _best_trials(best: Any) -> tuple[list[str], list[dict[str, str]]]:
    """best.json's trials (one, or a Pareto front) as table rows: the
    parameters, each objective's value by its name, the status."""
    trials = best if isinstance(best, list) else [best]
    header: list[str] = []
    rows: list[dict[str, str]] = []
    for t in trials:
        if not isinstance(t, dict):
            continue
        row = {"trial": str(t.get("trial", t.get("number", ""))), "generation": str(t.get("generation", "")),
               "slot": str(t.get("slot", ""))}
        row.update({str(k): repr(v) for k, v in (t.get("params") or {}).items()})
        row.update({str(k): repr(v) for k, v in zip(t.get("objectives") or [], t.get("values") or [])})
        row["status"] = str(t.get("status", ""))
        header += [k for k in row if k not in header and row[k] != ""]
        rows.append(row)
    return header, rows


def _fit_sections(page: Page) -> list[str]:
    """A fit: its verdict on the logs it did not see, then the rest
    (``pupper_core._report_fit``)."""
    from pupper_core._report_fit import fit_sections

    return fit_sections(page)


def _recommend_sections(page: Page) -> list[str]:
    """A recommendation: the answer (a card per group, the rule, the
    warnings), the margins it keeps, why the neighbours lost, the sweep
    that reproduces it, then every candidate."""
    d, manifest = page.dir, page.manifest
    parts: list[str] = []
    ch, cards = _read(d / "recommend.csv")
    inp = manifest.get("inputs", {})
    rule = (f"the lowest p95 push dip over {inp.get('robots')} drawn robots among gains that hold on every one: "
            f"none fell, saturation under {100 * float(inp.get('max_saturation', 0.05)):g} % of steps, "
            + (f"none ends more than {100 * float(inp['max_sag']):g} % below its "
               f"{1000 * float(inp['stance_m']):.1f} mm stance height, "
               if inp.get("max_sag") is not None and math.isfinite(float(inp.get("stance_m") or "nan")) else "")
            + "phase "
            f"margin >= {inp.get('min_phase_margin_deg')}° and gain margin >= {inp.get('min_gain_margin_db')} dB "
            f"for the loop the firmware ({inp.get('motor')}) closes with {inp.get('sensing_delay')} s of sensing "
            "delay; push dips within 2 % tie, won by the faster slowest group")
    if cards:
        dip = num(cards[0].get("p95_push_dip_mm", "nan"))
        page.answer.append(f"<p class='pick'>Put these gains on the robot: every constraint held on each drawn "
                           f"robot, p95 push dip {dip:.4g} mm over them.</p><p>Rule: {html.escape(rule)}.</p>"
                           + _table(ch, cards, None, key="group") + _commanded(cards)
                           + _in_use(manifest.get("current"), dip))
        parts.append("<h2>Figures</h2>" + bars([c["group"] for c in cards],
                                               {"phase margin": [num(c["phase_margin_deg"]) for c in cards]},
                                               "phase margin at the spread's worst corner (deg)", unit="°"))
    else:
        page.answer.append(f"<p class='pick'>No gains held every constraint.</p><p>Rule: {html.escape(rule)}.</p>")
    fh, front = _read(d / "tradeoffs.csv")
    th, trials = _read(d / "trials.csv")
    parts.append(_tradeoff_figure(inp, trials, front, manifest.get("pick") or {}))
    if len(front) > 1:
        parts.append("<h2>Trade-off set (tradeoffs.csv)</h2><p>The candidates that held every constraint and "
                     "that no other beats at once on push dip (lower), the slowest group's natural frequency "
                     "(faster tracking) and the lowest robot's stand height (higher): where the rule's pick "
                     "gives one up for another.</p>" + _table(fh, front, None, key="trial"))
    if manifest.get("neighbours"):
        parts.append("<h2>Why the neighbours lost</h2><ul>"
                     + "".join(f"<li>{html.escape(n)}</li>" for n in manifest["neighbours"]) + "</ul>")
    if manifest.get("reproduce"):
        parts.append("<h2>Reproduce the push dip</h2><pre>" + html.escape(manifest["reproduce"]) + "</pre>")
    page.warnings.extend(manifest.get("warnings", []))
    if trials:
        parts.append("<h2>Candidates (trials.csv)</h2>" + _table(th, trials, None, key="trial"))
    return parts


def _commanded(cards: list[dict[str, str]]) -> str:
    """What the card's gains are: to command; and, on a calibrated model,
    what the motors deliver of them (the margins are of those)."""
    line = "kp, kd: the gains to command (recommended.yaml's kps, kds)"
    if cards and cards[0].get("motor_kp"):
        line += ("; motor kp, motor kd: what the motors deliver of them by the model's fitted gain scales; the "
                 "margins are of the delivered gains")
    return f"<p>{html.escape(line)}.</p>"


def _in_use(current: dict[str, Any] | None, dip: float) -> str:
    """The gains the robot runs today, on the same robots, beside the pick."""
    if not current:
        return ""
    gains = ", ".join(f"{g} kp {v['kp']:.4g} kd {v['kd']:.4g}" for g, v in current["gains"].items())
    ran = (f"{current['fell']} robot(s) fell" if current.get("fell") else
           f"p95 push dip {num(str(current.get('p95_push_dip_mm'))):.4g} mm (the pick's {dip:.4g} mm)")
    held = "holds every constraint" if not current.get("failed") else f"breaks one: {current['failed']}"
    return f"<p>In use today ({html.escape(gains)}): {html.escape(ran)}; {html.escape(held)}.</p>"


def _tradeoff_figure(inputs: dict[str, Any], trials: list[dict[str, str]], front: list[dict[str, str]],
                     picked: dict[str, dict[str, float]]) -> str:
    """Every candidate that held, by its slowest group's natural frequency
    and its p95 push dip: the trade-off set filled, the pick starred."""
    inertia = {g: float(v[1]) for g, v in inputs.get("inertia", {}).items()}
    if not inertia:
        return ""

    def hz(r: dict[str, str]) -> float:
        return min(math.sqrt(num(r[f"kp.{g}"]) / J) for g, J in inertia.items()) / (2 * math.pi)

    pts = {f"trial {r['trial']}": (hz(r), num(r["p95_push_dip_mm"])) for r in trials if r.get("status") == "ok"}
    # the pick: the first candidate with its gains (the polish may ask one twice)
    pick = next((f"trial {r['trial']}" for r in trials if r.get("status") == "ok" and picked
                 and all(num(r[f"{k}.{g}"]) == v[k] for g, v in picked.items() for k in ("kp", "kd"))), None)
    return scatter(pts, "candidates that held every constraint: the trade-off set filled, the pick ★",
                   "slowest group's natural frequency sqrt(kp/J) (Hz): faster tracking →",
                   "p95 push dip (mm)", [f"trial {r['trial']}" for r in front], pick)


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
    answer: list[str] = []
    header, rows = _read(d / "summary.csv")
    parts = SECTIONS[kind](Page(d, manifest, kind, header, rows, warnings, answer))
    files = sorted(p.relative_to(d).as_posix() for p in d.rglob("*")
                   if p.is_file() and not p.name.startswith(".") and p.name != "report.html")
    links = "".join(f'<li><a href="{html.escape(f)}">{html.escape(f)}</a></li>' for f in files)
    warn_html = "".join(f'<div class="warn">{html.escape(w)}</div>' for w in warnings) or "<p>None.</p>"
    # the page opens with the run's answer and the warnings that qualify it
    top = (f'<section id="answer"><h2>Answer</h2>{"".join(answer)}<h3>Warnings</h3>{warn_html}</section>'
           if answer else f"<h2>Warnings</h2>{warn_html}")
    page = (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            f"<title>pupper {kind}: {html.escape(d.name)}</title><style>{STYLE}</style></head><body>"
            f"<h1>pupper {kind}: {html.escape(d.name)}</h1>{top}"
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
