"""The kit every kind's report sections are drawn with: the page's style and
script, the run's tables read from its files, a sortable table, the
page a kind draws on (`Page`), and the picks and rules the core's ranking
makes, read through the native module (never by stepping physics)."""

from __future__ import annotations

import html
import json
import math
from collections.abc import Collection, Sequence
from pathlib import Path
from typing import Any, Callable, NamedTuple

from pupper_core._report.svg import fmt, lines, num, rounded
from pupper_core.plots.tables import read_table
from pupper_core._spec import DEFAULT_METRIC, ROBUST_METRIC

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


def breakable(name: str) -> str:
    """A name that may wrap after its underscores, dots and dashes (a
    table of long names narrows to the page instead of running off it)."""
    return "".join(html.escape(c) + ("<wbr>" if c in "_.-/" else "") for c in name)

def table(header: list[str], rows: list[dict[str, str]], picks: str | set[str] | None, key: str = "id",
           shown: Callable[[str, dict[str, str]], str] | None = None) -> str:
    """A sortable table; the rows of ``picks`` (one key, a set, or None; by
    ``key``) in bold; ``shown(column, row)``, where given, the HTML of a
    text cell. In a box of its own that scrolls sideways where the page is
    too narrow for it: no column is ever cut off."""
    picks = {picks} if isinstance(picks, str) else picks or set()
    out = ['<div class="scroll"><table class="sortable"><thead><tr>']
    for h in header:
        out.append(f'<th class="{"text" if h in ("id", "name", "status", "parameter", "actuators") else ""}">'
                   f'{breakable(h)}</th>')
    out.append("</tr></thead><tbody>")
    for r in rows:
        cls = ' class="best"' if r.get(key) in picks else ""
        out.append(f"<tr{cls}>")
        for h in header:
            v = r.get(h, "")
            if h == "status" or h.startswith("status."):
                out.append(f'<td class="text" style="background:{STATUS_COLOUR.get(v, "#fff")}">{html.escape(v)}</td>')
            elif h in ("id", "name", "parameter", "actuators", "unit", "log", "actuator"):
                out.append(f'<td class="text">{shown(h, r) if shown else breakable(v)}</td>')
            else:
                # every digit in the title, four significant ones shown
                out.append(f'<td title="{html.escape(v)}">{fmt(v, h)}</td>')
        out.append("</tr>")
    out.append("</tbody></table></div>")
    return "".join(out)

def kind_of(manifest: dict[str, Any], kinds: Collection[str]) -> str:
    """The run's kind: the manifest's, where it is one of `kinds` (the
    report's registry), else what an older manifest's inputs say."""
    kind = manifest.get("kind")
    if kind in kinds:
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

def inputs_html(manifest: dict[str, Any], kind: str) -> str:
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
    if "versions" in manifest:  # a fit from before the stamp
        items.append(("versions", json.dumps(manifest["versions"])))
    return "<dl>" + "".join(f"<dt>{html.escape(k)}</dt><dd>{html.escape(v)}</dd>" for k, v in items) + "</dl>"

def best_cell(run_dir: Path, kind: str = "sweep") -> tuple[str | None, str]:
    """The cell pupper's rule picks (by the kind's own metric), and the rule
    in words."""
    try:
        from pupper_core import _native

        res = _native.load_run(str(run_dir))
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

def edge_of(manifest: dict[str, Any], rows: list[dict[str, str]], best: str,
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

def numbers(row: dict[str, str], header: Sequence[str], keep: Callable[[str], bool] = lambda h: True) -> str:
    """A row's values, each rounded with every digit in its tooltip."""
    return ", ".join(f"{html.escape(h)} {rounded(row[h], h)}" for h in header
                     if h not in ("index", "name", "id") and row.get(h, "") != "" and keep(h))

def metric_of(kind: str, header: list[str]) -> str | None:
    if kind == "hold":
        return "compliance_mm_per_n"
    return DEFAULT_METRIC if DEFAULT_METRIC in header else ROBUST_METRIC if ROBUST_METRIC in header else None

def ties_with(rows: list[dict[str, str]], best: str, metric: str, kind: str) -> list[str]:
    """The other eligible cells the ranking metric cannot tell from the
    pick (within 0.001 mm for a sweep's steadiness; equal for a hold)."""
    row = next(r for r in rows if r.get("id") == best)
    v, tol = num(row.get(metric)), (0.0 if kind == "hold" else 1e-3)
    return [r["id"] for r in rows if r.get("id") != best and r.get("status") in ("ok", "saturated")
            and not num(r.get("saturation_frac")) >= 0.05 and abs(num(r.get(metric)) - v) <= tol]


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

class TaskWords(NamedTuple):
    """What a recommendation's page says of its task (`recommend --task`):
    the measure the rule ranks, as trials.csv names it, in words and its
    unit; the rule in words from the manifest's inputs (given the stand
    task's, whose constraints every task keeps); what the answer quotes of
    the cards; what else the answer shows of the manifest; what its
    reproduce command gives again."""

    column: str
    objective: str
    unit: str
    rule: Callable[[dict[str, Any], str], str]
    quoted: Callable[[dict[str, Any], list[dict[str, str]]], str]
    shown: Callable[[dict[str, Any]], str]
    reproduces: str

    @property
    def measure(self) -> str:
        """What is measured, without its statistic: "push dip"."""
        return self.objective.removeprefix("p95 ")

def status_warnings(page: Page) -> None:
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

def z_traces(d: Path) -> dict[str, tuple[list[float], list[float]]]:
    """Base height per cell after the landing (the drop would set the scale)."""
    _, trows = read_table(d / "traces.csv")
    series: dict[str, tuple[list[float], list[float]]] = {}
    for r in trows:
        t = num(r.get("t"))
        if t >= 1.0 and "z" in r:
            xs, ys = series.setdefault(r.get("id", ""), ([], []))
            xs.append(t)
            ys.append(num(r.get("z")))
    return series

def z_figure(series: dict[str, tuple[list[float], list[float]]], rows: list[dict[str, str]],
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
