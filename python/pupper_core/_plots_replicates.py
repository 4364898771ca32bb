"""The spread over replicates (``pupper_core.plots`` re-exports it): every
replicate of the best cells, coloured by the drawn quantity that best
orders the metric."""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np

from pupper_core._plots_style import _new_figure, _style, label_of, plain_log_axis
from pupper_core._plots_tables import FIRST_METRIC, RunLike, read_replicates, run_dir_of
from pupper_core._public import exported_from
from pupper_core._spec import DEFAULT_METRIC

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure



def _splitting_quantity(reps: Mapping[str, Any], metric: str, rows: Sequence[int]) -> str | None:
    """The drawn quantity that best orders ``metric`` over these replicate
    rows (largest absolute rank correlation): what the dots are coloured by."""
    names = list(reps)
    if "replicate" not in names or FIRST_METRIC not in names:
        return None
    # replicates.csv: ..., replicate, <the drawn quantities>, final_z, ...
    drawn = names[names.index("replicate") + 1:names.index(FIRST_METRIC)]
    y = np.asarray(reps[metric], dtype=float)[list(rows)]
    ok = np.isfinite(y)
    best: tuple[float, str] | None = None
    for name in drawn:
        x = np.asarray(reps[name], dtype=float)[list(rows)]
        w = ok & np.isfinite(x)
        if w.sum() < 3 or np.ptp(x[w]) == 0:
            continue
        rx, ry = np.argsort(np.argsort(x[w])), np.argsort(np.argsort(y[w]))
        c = abs(float(np.corrcoef(rx, ry)[0, 1])) if np.ptp(ry) > 0 else 0.0
        if best is None or c > best[0]:
            best = (c, name)
    return best[1] if best else None


def _best_cells(rows: list[dict[str, str]], key: str, cells: int) -> tuple[list[str], set[str]]:
    """The ``cells`` best rows by ``key`` (a p95 column), those where no
    replicate failed first, with the row pupper's rule picks among them
    (in the last place if it was not); and that pick."""

    def rank(r: dict[str, str]) -> tuple[int, float]:
        v = float(r[key]) if r.get(key) else math.inf
        return (0 if r["failure_fraction"] == "0" else 1, v)

    chosen = [r["id"] for r in sorted(rows, key=rank)[:cells]]
    picked: set[str] = set()
    if rows and key in rows[0]:
        from pupper_core import _native

        header = list(rows[0])
        (pick,) = _native.best_rows(header, [[r[h] for h in header] for r in rows], key)
        if pick is not None:
            picked = {rows[pick]["id"]}
            if rows[pick]["id"] not in chosen:
                chosen[-1] = rows[pick]["id"]
    return chosen, picked


@exported_from("pupper_core.plots")
def replicate_spread(run_dir: RunLike, metric: str = DEFAULT_METRIC,
                     cells: int = 6, by: str | None = None) -> "Figure | None":
    """The spread of ``metric`` over every replicate at the best cells: a
    box (quartiles) with each replicate that stayed up as a dot, coloured by
    the drawn quantity that best orders the metric (a colour bar names it),
    each replicate that fell or diverged as a red cross above the others,
    the mean (diamond) and the worst-side 95th percentile (bar) that
    summary.csv reports. Cells are the ``cells`` best by ``p95:<metric>``
    among those where no replicate failed (then the rest), always with the
    cell pupper's rule picks (starred); or with ``by`` the best of each
    group as best.csv has them. None when the run has no replicates."""
    d = run_dir_of(run_dir)
    if not (d / "replicates.csv").exists():
        return None
    reps = read_replicates(d)
    with open(d / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    key = f"p95:{metric}"
    if by is not None and (d / "best.csv").exists():
        with open(d / "best.csv", newline="") as f:
            chosen = [r["id"] for r in csv.DictReader(f) if r["id"]]
        picked = set(chosen)
    else:
        chosen, picked = _best_cells(rows, key, cells)
    if not chosen:
        return None
    by_id = {r["id"]: r for r in rows}
    members = {cid: [i for i, x in enumerate(reps["id"]) if x == cid] for cid in chosen}
    shown = [i for cid in chosen for i in members[cid]]
    colour_by = _splitting_quantity(reps, metric, shown)
    with _style():
        fig = _new_figure((max(5.5, 1.25 * len(chosen) + 3.0), 4.6))
        ax = fig.subplots()
        values = np.asarray(reps[metric], dtype=float)
        up = [[i for i in members[cid] if reps["status"][i] == "ok"] for cid in chosen]
        data = [values[sel] for sel in up]
        ax.boxplot([x[np.isfinite(x)] for x in data], positions=range(len(data)), widths=0.5,
                   showfliers=False, medianprops={"color": "#4e79a7"})
        jitter = np.random.default_rng(0)
        finite = np.concatenate([x[np.isfinite(x)] for x in data]) if data else np.array([])
        top = float(finite.max()) if finite.size else 1.0
        log = bool(finite.size) and bool(np.all(finite > 0))
        cross_y = top * (1.6 if log else 1.0) + (0 if log else 0.1 * (top - float(finite.min(initial=0))) + 1e-9)
        scatter = None
        if colour_by is not None:
            q = np.asarray(reps[colour_by], dtype=float)
            lo, hi = float(np.nanmin(q[shown])), float(np.nanmax(q[shown]))
        labels = []
        any_cross = False
        for i, cid in enumerate(chosen):
            x = i + jitter.uniform(-0.15, 0.15, len(up[i]))
            if colour_by is not None:
                scatter = ax.scatter(x, data[i], c=q[up[i]], cmap="viridis", vmin=lo, vmax=hi, s=14,
                                     alpha=0.85, zorder=3)
            else:
                ax.plot(x, data[i], "o", ms=3, alpha=0.6, color="#59a14f")
            down = [j for j in members[cid] if reps["status"][j] != "ok"]
            if down:
                any_cross = True
                ax.plot(i + jitter.uniform(-0.15, 0.15, len(down)), [cross_y] * len(down), "x",
                        color="red", ms=7, mew=2, zorder=4,
                        label="a replicate that fell or diverged" if not any(
                            lbl.get_label().startswith("a replicate") for lbl in ax.lines) else None)
            r = by_id[cid]
            if r.get(f"mean:{metric}"):
                ax.plot([i], [float(r[f"mean:{metric}"])], "D", color="black", ms=6,
                        label="mean of those up" if i == 0 else None)
            if r.get(key):
                ax.plot([i - 0.3, i + 0.3], [float(r[key])] * 2, color="red", lw=2,
                        label="worst-side 95th percentile" if i == 0 else None)
            n_down, n = len(down), len(members[cid])
            name = r.get("variant") or ""
            labels.append(("★ " if cid in picked else "") + (f"{name}\n" if name else "") + cid
                          + (f"\n{n_down}/{n} fell" if n_down else ""))
        ax.set_xticks(range(len(chosen)), labels, fontsize=9)
        ax.set_ylabel(label_of(metric))
        if log:
            ax.set_yscale("log")
            plain_log_axis(ax.yaxis)
        if scatter is not None and colour_by is not None:
            bar = fig.colorbar(scatter, ax=ax, pad=0.02)
            bar.set_label(f"drawn {colour_by}", fontsize=9)
        ax.legend(loc="best", fontsize=8)
        if picked:
            ax.set_xlabel("★ = the cell pupper's rule picks", fontsize=9)
        return fig
