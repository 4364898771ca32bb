"""A study's figures (``pupper_core._tune`` re-exports them): the best
objective against the cell-steps spent, and the trials over the searched
plane, each beside a grid of the same question if given."""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Any

from pupper_core.plots.style import _new_figure, _save, _style, label_of, plain_log_axis
from pupper_core._tune.plan import PENALTY, TuneError, parse_space


def _study_table(out: Path) -> tuple[dict[str, Any], list[dict[str, str]]]:
    from pupper_core import _native

    manifest = _native.read_manifest(os.fspath(out))
    with (out / "trials.csv").open(newline="") as f:
        return manifest["inputs"], list(csv.DictReader(f))


def _grid_table(grid: str | os.PathLike[str], objective: str, maximize: bool) -> tuple[list[dict[str, str]], Any]:
    """A grid run's rows and their objective, ineligible cells (not ok)
    as NaN: what a search is compared with."""
    import numpy as np

    with (Path(grid) / "summary.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows or objective not in rows[0]:
        raise TuneError(f"--compare {grid}: its summary.csv has no column {objective}: give a sweep of the same question")
    v = np.array([float(r[objective]) if r[objective] and r.get("status", "ok") == "ok" else np.nan for r in rows])
    return rows, v


def progress_figure(out: str | os.PathLike[str], grid: str | os.PathLike[str] | None = None) -> Any:
    """The best objective so far against the cell-steps spent, each trial a
    dot (those told the penalty — fallen, chattering — as red crosses at
    the top); with ``grid`` (a sweep's
    run directory of the same question) the grid's own best-so-far curve,
    its cells taken in grid order. A matplotlib Figure."""
    import numpy as np


    inputs, rows = _study_table(Path(out))
    objective, maximize = inputs["objectives"][0], bool(inputs["maximize"])
    values = np.array([float(r[objective]) for r in rows])
    bad = values <= -PENALTY if maximize else values >= PENALTY
    spent = np.cumsum([int(r["cell_steps"]) for r in rows])
    good = np.where(bad, np.nan, values)
    worst = -np.inf if maximize else np.inf
    best = (np.fmax if maximize else np.fmin).accumulate(np.where(np.isnan(good), worst, good))
    with _style():
        fig = _new_figure((7.5, 4.4))
        ax = fig.subplots()
        ax.plot(spent[~bad], values[~bad], "o", ms=4, alpha=0.5, color="#4e79a7", label="a trial")
        if bad.any():
            top = float(np.nanmax(good)) if np.isfinite(good).any() else 1.0
            ax.plot(spent[bad], np.full(int(bad.sum()), top), "x", color="red", ms=6, label="fell, chattered or no value")
        ax.step(spent, best, where="post", color="black", lw=1.6, label="best so far")
        if grid is not None:
            grows, gv = _grid_table(grid, objective, maximize)
            from pupper_core import _native

            per = _native.read_manifest(os.fspath(grid))["config"]["schedule"]["duration"]
            steps = round(float(per) / 0.002)
            gbest = (np.fmax if maximize else np.fmin).accumulate(np.where(np.isnan(gv), worst, gv))
            ax.step(steps * np.arange(1, len(gv) + 1), gbest, where="post", color="tab:orange", lw=1.4,
                    label=f"grid's best so far ({len(gv)} cells)")
            ax.set_xscale("log")
            plain_log_axis(ax.xaxis)
        if np.all(values[~bad] > 0):
            ax.set_yscale("log")
            plain_log_axis(ax.yaxis)
        ax.set_xlabel("cell-steps spent")
        ax.set_ylabel(label_of(objective))
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=9)
        fig.suptitle(f"{inputs['sampler']} search, batch {inputs['batch']}: {len(rows)} trials", fontsize=12)
        return fig


def trials_figure(out: str | os.PathLike[str], grid: str | os.PathLike[str] | None = None) -> Any:
    """The trials over the two searched axes, coloured by the objective, the
    best starred; with ``grid`` (a sweep over the same two axes) over that
    grid's heatmap. None unless exactly two numeric axes were searched."""
    import numpy as np


    inputs, rows = _study_table(Path(out))
    dims = parse_space(inputs["space"])
    if len(dims) != 2 or any(d.choices for d in dims):
        return None
    objective, maximize = inputs["objectives"][0], bool(inputs["maximize"])
    values = np.array([float(r[objective]) for r in rows])
    bad = values <= -PENALTY if maximize else values >= PENALTY
    x, y = dims
    xs = np.array([float(r[x.axis]) for r in rows])
    ys = np.array([float(r[y.axis]) for r in rows])
    with _style():
        fig = _new_figure((6.5, 5.0))
        ax = fig.subplots()
        from matplotlib.colors import LogNorm, Normalize

        shown = values[~bad]
        # no trial ranked: the crosses alone, on a unit colour scale
        lo, hi = (float(np.min(shown)), float(np.max(shown))) if shown.size else (1.0, 2.0)
        if grid is not None:
            grows, gv = _grid_table(grid, objective, maximize)
            gx = sorted({float(r[x.axis]) for r in grows})
            gy = sorted({float(r[y.axis]) for r in grows})
            z = np.full((len(gy), len(gx)), np.nan)
            for r, v in zip(grows, gv):
                z[gy.index(float(r[y.axis])), gx.index(float(r[x.axis]))] = v
            lo, hi = min(lo, float(np.nanmin(gv))), max(hi, float(np.nanmax(gv)))
        norm = LogNorm(lo, hi) if lo > 0 else Normalize(lo, hi)
        cmap = "viridis" if maximize else "viridis_r"
        if grid is not None:
            ax.pcolormesh(gx, gy, z, cmap=cmap, norm=norm, shading="nearest", alpha=0.55)
        sc = ax.scatter(xs[~bad], ys[~bad], c=shown, cmap=cmap, norm=norm, s=28, edgecolors="white",
                        linewidths=0.5)
        if bad.any():
            ax.plot(xs[bad], ys[bad], "x", color="red", ms=6, label="fell, chattered or no value")
        if shown.size:
            good = np.where(bad, np.nan, values)
            k = int(np.nanargmax(good) if maximize else np.nanargmin(good))
            ax.plot([xs[k]], [ys[k]], "*", color="black", ms=16, mfc="none", mew=1.5, label="best")
        for axis, dim, scale in ((ax.xaxis, x, ax.set_xscale), (ax.yaxis, y, ax.set_yscale)):
            scale("log" if dim.log else "linear")
            if dim.log:
                plain_log_axis(axis)
        ax.set_xlabel(label_of(x.axis))
        ax.set_ylabel(label_of(y.axis))
        bar = fig.colorbar(sc, ax=ax)
        bar.set_label(label_of(objective))
        if isinstance(norm, LogNorm):
            plain_log_axis(bar.long_axis)
        ax.legend(loc="best", fontsize=9)
        fig.suptitle("The trials over the searched plane", fontsize=12)
        return fig


def write_plots(out: str | os.PathLike[str], grid: str | os.PathLike[str] | None = None) -> list[Path]:
    """A study's figures into ``<out>/plots/``: ``tune_progress.png`` and,
    for two searched axes, ``tune_trials.png``; with ``grid`` (a sweep of
    the same question) beside that grid's curve and over its heatmap."""

    d = Path(out)
    (d / "plots").mkdir(exist_ok=True)
    written = [_save(progress_figure(d, grid), d / "plots" / "tune_progress.png")]
    fig = trials_figure(d, grid)
    if fig is not None:
        written.append(_save(fig, d / "plots" / "tune_trials.png"))
    return written
