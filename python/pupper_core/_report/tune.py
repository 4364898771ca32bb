"""A tune's report: the best trial (or Pareto front), the best objective
against cell-steps spent, the trials."""

from __future__ import annotations

import json
import math
from typing import Any

from pupper_core._report.page import Page, read_table, table
from pupper_core._report.svg import lines, num

def sections(page: Page) -> list[str]:
    """A tune: the best trial, the best objective against cell-steps, the trials."""
    parts: list[str] = []
    th, trials = read_table(page.dir / "trials.csv")
    bj = page.dir / "best.json"
    if bj.is_file():
        bh, brows = best_trials(json.loads(bj.read_text()))
        said = "Best trial" if len(brows) == 1 else f"Best trials (the Pareto front, {len(brows)})"
        page.answer.append(f"<h3>{said} (best.json)</h3>" + (table(bh, brows, set()) if brows else
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
        parts.append("<h2>Trials (trials.csv)</h2>" + table(th, trials, set()))
    return parts

def best_trials(best: Any) -> tuple[list[str], list[dict[str, str]]]:
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
