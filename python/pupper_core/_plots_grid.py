"""The figures of a grid (``pupper_core.plots`` re-exports them): the
base height against time, a heatmap over two axes, a metric against one
axis, and bars per cell."""

from __future__ import annotations

import math
import os
import re
from typing import TYPE_CHECKING, Any, Mapping, Sequence, cast

import numpy as np

from pupper_core._plots_style import (
    _BAD_GREY,
    _FELL,
    LABELS,
    SHORT,
    _cell_text,
    _fmt,
    _has_dip,
    _ink,
    _key_line,
    _new_figure,
    _style,
    _wrap_parts,
    label_of,
    plain_log_axis,
)
from pupper_core._plots_tables import (
    RunLike,
    TableLike,
    Traces,
    _as_table,
    _best_index,
    _col,
    _distinct,
    _num,
    _push_tuple,
    _rankable,
    _rule_best,
    _status,
    read_run,
)
from pupper_core._public import exported_from
from pupper_core._spec import DEFAULT_METRIC, OVERSHOOT_NOISE_PCT

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure


def _traces_of(run: "RunLike", push: Any, status: Mapping[str, str] | None) -> tuple[Traces, Any, Mapping[str, str]]:
    """A result's or a run directory's traces, push (unless given) and status."""
    if isinstance(run, (str, os.PathLike)):
        table, manifest, traces = read_run(run)
        config = manifest.get("config", {})
    else:
        table, traces, config = run.table, run.traces, run.config
    if push is None:
        push = config.get("schedule", {}).get("push")
    if status is None:
        status = {str(i): str(s) for i, s in zip(table["id"], table["status"])}
    return traces, push, status


@exported_from("pupper_core.plots")
def base_z(
    traces: "Traces | RunLike",
    push: Any = None,
    ax: "Axes | None" = None,
    labels: Mapping[str, str] | Sequence[str] | None = None,
    *,
    title: str | None = None,
    zoom: bool | None = None,
    status: Mapping[str, str] | None = None,
    landing: float = 1.0,
    ylabel: str = "base height z (mm)",
) -> "Figure":
    """Base height (mm) against time, one line per trace; the push window is shaded.

    ``traces``: id -> (t in s, z in m). ``push``: (start, duration[, force z]) or
    a manifest push dict or None. ``labels``: id -> label, or a list in trace order.
    With a push and no ``ax``, a second panel zooms on the push (0.5 s before
    to 1.5 s after, the window of push_dip_mm); ``zoom=False`` turns it off.
    ``status``: id -> status; saturated (chattering) cells are drawn thin and
    dashed and set no axis range. The whole-run panel's range is that of the
    robots after ``landing`` s, so a millimetre push dip is visible beside a
    drop of centimetres (the drop runs off the top, said in the panel title).
    ``traces`` may be a result or a run directory instead: its traces, its
    push and its cells' status.
    """
    if not isinstance(traces, Mapping):
        traces, push, status = _traces_of(traces, push, status)
    with _style():
        p = _push_tuple(push)
        zoom = (p is not None and ax is None) if zoom is None else (zoom and p is not None and ax is None)
        if ax is None:
            fig = _new_figure((12.5, 4.8) if zoom else (9.0, 4.8))
            if zoom:
                ax, zax = fig.subplots(1, 2, width_ratios=[1.5, 1.0])
            else:
                ax, zax = fig.add_subplot(), None
        else:
            fig, zax = ax.figure, None
        ids = list(traces)
        names = _trace_names(ids, labels)
        n = len(ids)
        colours = _trace_colours(n)
        chatter = {k for k in ids if status is not None and status.get(k) in ("saturated", "past_bound")}
        panels = [a for a in (ax, zax) if a is not None]
        for a in panels:
            for k, c in zip(ids, colours):
                t, z = traces[k]
                style = dict(lw=0.8, ls="--", alpha=0.6) if k in chatter else dict(lw=1.4)
                a.plot(np.asarray(t, float), np.asarray(z, float) * 1000.0, color=c,
                       label=names[k] if a is panels[-1] else None, **style)
            if p is not None:
                start, dur, fz = p
                what = f"push {fz:+g} N" if fz is not None else "push"
                a.axvspan(start, start + dur, color="tab:red", alpha=0.15, lw=0,
                          label=f"{what} ({dur:g} s)" if a is panels[-1] else None)
            a.set_xlabel("time (s)")
            a.grid(True, alpha=0.3)
        ax.set_ylabel(ylabel)
        # the robots' heights that set the ranges: chattering ones aside
        steady = [k for k in ids if k not in chatter] or ids
        if zax is not None and p is not None:
            _zoom_on_push(zax, traces, steady, p)
            ax.set_title("whole run", fontsize=11)
        _whole_run_range(ax, traces, steady, landing)
        if title is not None:
            (fig.suptitle if zax is not None else ax.set_title)(title)
        if n <= 24:
            ncol = 1 if n <= 8 else 2
            panels[-1].legend(loc="center left", bbox_to_anchor=(1.01, 0.5), ncol=ncol, frameon=False)
        return fig


def _trace_names(ids: list[str], labels: Mapping[str, str] | Sequence[str] | None) -> dict[str, str]:
    """Each trace's legend label: its id, or ``labels`` by id or in order."""
    if labels is None:
        return {k: str(k) for k in ids}
    if isinstance(labels, Mapping):
        return {k: str(labels.get(k, k)) for k in ids}
    return {k: str(lab) for k, lab in zip(ids, labels)}


def _trace_colours(n: int) -> list[Any]:
    """Colours for ``n`` lines: matplotlib's cycle, twenty distinct ones, or a ramp."""
    import matplotlib

    if n > 20:
        cmap = matplotlib.colormaps["viridis"]
        return [cmap(i / max(1, n - 1)) for i in range(n)]
    if n > 10:
        # twenty colours that can be told apart, not one ramp
        tab = matplotlib.colormaps["tab20"]
        return [tab(i) for i in range(n)]
    return [f"C{i}" for i in range(n)]


def _zoom_on_push(zax: "Axes", traces: Traces, steady: list[str], push: tuple[float, float, float | None]) -> None:
    """The zoom panel's window (0.5 s before the push to 1.5 s after) and
    the range of the heights in it."""
    lo_t, hi_t = push[0] - 0.5, push[0] + push[1] + 1.5
    zs = []
    for k in steady:
        t, z = (np.asarray(v, float) for v in traces[k])
        w = (t >= lo_t) & (t <= hi_t) & np.isfinite(z)
        if w.any():
            zs.append(z[w] * 1000.0)
    zax.set_xlim(lo_t, hi_t)
    if zs:
        allz = np.concatenate(zs)
        lo, hi = float(allz.min()), float(allz.max())
        pad = max(0.08 * (hi - lo), 0.05)
        zax.set_ylim(lo - pad, hi + pad)
    zax.set_title("around the push", fontsize=11)


def _whole_run_range(ax: "Axes", traces: Traces, steady: list[str], landing: float) -> None:
    """The whole run's range: the robots after landing (a drop from higher
    runs off the top, said in the title)."""
    heights = []
    top0 = -np.inf
    for k in steady:
        t, z = (np.asarray(v, float) for v in traces[k])
        w = (t >= landing) & np.isfinite(z)
        if w.any():
            heights.append(z[w] * 1000.0)
        if len(z) and np.isfinite(z[0]):
            top0 = max(top0, float(z[0]) * 1000.0)
    if heights:
        allz = np.concatenate(heights)
        lo, hi = float(allz.min()), float(allz.max())
        pad = 0.15 * (hi - lo) if hi > lo else 0.5
        ax.set_ylim(lo - pad, hi + pad)
        if top0 > hi + pad:
            ax.set_title(f"whole run (from {top0:.0f} mm at t = 0, off the top)", fontsize=11)


@exported_from("pupper_core.plots")
def heatmap(
    table: TableLike,
    metric: str = DEFAULT_METRIC,
    x: str = "kp",
    y: str = "kd",
    by: str | None = None,
    ax: "Axes | None" = None,
    minimize: bool = True,
    *,
    title: str | None = None,
    log: bool | None = None,
    mark_best: bool = True,
) -> "Figure":
    """Heatmap of ``metric`` over ``x`` × ``y``, one panel per value of ``by``.

    Values are annotated; the best cell (min if ``minimize``, among cells whose
    status is ok when any is) is boxed with a star; NaN and diverged cells are
    grey. ``log=None`` picks a log colour scale for positive data spanning
    more than 100×. The figure's ``pupper_best`` attribute lists the marked
    cells as dicts ``{"panel", x, y, metric}``.
    """
    table = _as_table(table)
    with _style():
        vals = _num(table, metric)
        xs_all = _num(table, x)
        ys_all = _num(table, y)
        status = _status(table)
        xv = _distinct(xs_all)
        yv = _distinct(ys_all)
        if by is not None:
            bcol = _col(table, by)
            panels: list[Any] = _distinct(bcol if bcol.dtype.kind not in "fiub" else bcol.astype(float))
        else:
            bcol = None
            panels = [None]
        if ax is not None and len(panels) > 1:
            raise ValueError("heatmap: ax= draws one panel; drop ax or by")
        # each panel's rows, and its grid of values, statuses and cells seen
        rows = [np.ones(len(vals), bool) if bcol is None else (bcol == pv) for pv in panels]
        grids = [_panel_grid(sel, vals, status, (x, xs_all, xv), (y, ys_all, yv)) for sel in rows]
        if metric.split(":")[-1].startswith("overshoot_pct"):
            # an overshoot below the simulation's resolution is drawn as none
            grids = [(np.where(np.abs(g) < OVERSHOOT_NOISE_PCT, 0.0, g), s, n) for g, s, n in grids]
        norm = _colour_scale(grids, log)
        import matplotlib

        cmap = matplotlib.colormaps["viridis_r" if minimize else "viridis"].with_extremes(bad=_BAD_GREY)

        npan = len(panels)
        fig, axs = _heatmap_axes(ax, npan, len(xv), len(yv), title)
        best_marks: list[dict[str, Any]] = []
        im = None
        fs = 9 if len(xv) > 7 else 10
        for a, pv, sel, (grid, stat, seen) in zip(axs, panels, rows, grids):
            shown = np.where(stat == "fell", np.nan, grid) if (stat == "ok").any() else grid
            im = a.imshow(np.ma.masked_invalid(shown), cmap=cmap, norm=norm, origin="lower", aspect="auto")
            a.set_xticks(range(len(xv)), [_fmt(v) for v in xv])
            a.set_yticks(range(len(yv)), [_fmt(v) for v in yv])
            a.set_xlabel(label_of(x))
            if a is axs[0] or (ax is None and axs.index(a) % min(npan, 3) == 0):
                a.set_ylabel(label_of(y))
            a.set_xticks(np.arange(-0.5, len(xv)), minor=True)
            a.set_yticks(np.arange(-0.5, len(yv)), minor=True)
            a.grid(which="minor", color="white", lw=1.5)
            a.tick_params(which="minor", length=0)
            _annotate_cells(a, (grid, stat, seen), shown, cmap, norm, metric, fs)
            bi = _best_row(table, metric, minimize, sel, vals, status) if mark_best else None
            if bi is not None:
                c, r = xv.index(xs_all[bi]), yv.index(ys_all[bi])
                _box_best(a, c, r)
                best_marks.append({"panel": pv, x: xv[c], y: yv[r], metric: float(vals[bi])})
            if pv is not None:
                a.set_title(f"{by} = {_fmt(pv)}" if by in SHORT or by in LABELS else str(pv))
        if im is not None:
            cb = fig.colorbar(im, ax=axs, shrink=0.9 if len(yv) > 3 else 1.0)
            from matplotlib.colors import LogNorm

            if isinstance(norm, LogNorm):
                plain_log_axis(cb.long_axis)
            # wrapped to the bar's height (about half the figure's; 10 pt
            # glyphs about 6 pt wide); a label longer than two such lines (a
            # statistic over replicates) would stick out past the bar into
            # the title: the bar says the statistic and unit, the title the rest
            import textwrap

            label = textwrap.wrap(label_of(metric), max(14, int(fig.get_figheight() * 0.45 * 72 / 6)),
                                  break_long_words=False)
            cb.set_label("\n".join(label) if len(label) <= 2 else _bar_label(metric))
        best_word = "lowest" if minimize else "highest"
        sub = _key_line(best_word, status, metric, _has_dip(table, metric))
        head = title if title is not None else label_of(metric)
        if ax is None:
            # both wrapped to the figure, a little inside it (wide glyphs)
            width = 0.9 * fig.get_figwidth()
            heading = f"{_wrap_parts(head, width, 12)}\n{_wrap_parts(sub, width, 12)}"
            _room_for_title(fig, heading)
            fig.suptitle(heading, fontsize=12)
        else:
            ax.set_title(f"{head}\n{sub}", fontsize=11)
        fig.pupper_best = best_marks  # type: ignore[attr-defined]
        return fig


#: A heatmap panel: its values, statuses and which cells a row fills, each (len(y values), len(x values)).
_Grid = tuple[np.ndarray, np.ndarray, np.ndarray]


def _panel_grid(sel: np.ndarray, vals: np.ndarray, status: np.ndarray, xs: tuple[str, np.ndarray, list[Any]],
                ys: tuple[str, np.ndarray, list[Any]]) -> _Grid:
    """The rows ``sel`` on the grid of x and y values (each axis: its
    name, every row's value, the distinct values); a diverged cell has no
    value. Refuses two rows on one cell."""
    (x, xs_all, xv), (y, ys_all, yv) = xs, ys
    grid = np.full((len(yv), len(xv)), np.nan)
    stat = np.full((len(yv), len(xv)), "", dtype=object)
    seen = np.zeros((len(yv), len(xv)), bool)
    for i in np.flatnonzero(sel):
        if not (np.isfinite(xs_all[i]) and np.isfinite(ys_all[i])):
            continue
        c, r = xv.index(xs_all[i]), yv.index(ys_all[i])
        if seen[r, c]:
            raise ValueError(
                f"heatmap: several rows share {x}={_fmt(xs_all[i])}, {y}={_fmt(ys_all[i])}; "
                "pass by=<the other axis> or filter the table"
            )
        seen[r, c] = True
        grid[r, c] = vals[i] if status[i] != "diverged" else np.nan
        stat[r, c] = status[i]
    return grid, stat, seen


def _colour_scale(grids: Sequence[_Grid], log: bool | None) -> "Normalize":
    """One colour scale for every panel, spanning the cells that stayed up
    (a fallen robot lying still has a tiny, misleading std; fallen cells get
    their own colour); ``log=None``: log for positive values over 100x."""
    from matplotlib.colors import LogNorm, Normalize

    okv = [g[0][np.isfinite(g[0]) & (g[1] == "ok")] for g in grids]
    finite = np.concatenate(okv) if okv else np.array([])
    if finite.size == 0:
        finite = np.concatenate([g[0][np.isfinite(g[0])] for g in grids]) if grids else np.array([])
    if log is None:
        log = bool(finite.size and finite.min() > 0 and finite.max() / finite.min() > 100)
    if finite.size == 0:
        return Normalize(0, 1)
    if log:
        return LogNorm(max(finite.min(), 1e-12), max(finite.max(), finite.min() * 1.0001))
    lo, hi = float(finite.min()), float(finite.max())
    return Normalize(lo, hi if hi > lo else lo + 1e-9)


def _bar_label(metric: str) -> str:
    """A colour bar's short label: the statistic and the unit (the
    figure's title names the metric whole)."""
    stat, sep, name = metric.partition(":")
    unit = re.search(r"\(([^)]*)\)", LABELS.get(name if sep else metric, ""))
    word = {"p95": "worst-side p95", "mean": "mean"}.get(stat, "") if sep else ""
    return " ".join(w for w in (word, f"({unit.group(1)})" if unit else "") if w) or metric


def _room_for_title(fig: "Figure", title: str) -> None:
    """A figure sized for a two-line title made taller by each line more
    (12 pt, 1.2 lines apart): the panels keep their height."""
    fig.set_figheight(fig.get_figheight() + max(0, title.count("\n") - 1) * 12 * 1.2 / 72)


def _heatmap_axes(ax: "Axes | None", npan: int, nx: int, ny: int, title: str | None) -> tuple["Figure", list[Any]]:
    """The figure and a panel's axes each (at most three a row, sized to
    the cells), or the one ``ax`` given."""
    if ax is not None:
        # (a SubFigure too: with ax given, heatmap uses only what both have)
        return cast("Figure", ax.figure), [ax]
    cw = max(0.75, min(1.1, 9.0 / max(1, nx)))
    pw = cw * nx + 1.2
    ph = 0.55 * ny + 1.6
    ncols = min(npan, 3)
    nrows = math.ceil(npan / ncols)
    fig = _new_figure((pw * ncols + 1.4, ph * nrows + (0.5 if title else 0.2)))
    axs = list(np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False).ravel()))
    for extra in axs[npan:]:
        extra.set_visible(False)
    return fig, axs[:npan]


def _annotate_cells(a: "Axes", panel: _Grid, shown: np.ndarray, cmap: Any, norm: "Normalize", metric: str,
                    fs: int) -> None:
    """Each filled cell's number (black or white on its colour), or what
    it is instead: diverged, no value, fell (pink), or hatched when it stood
    but saturated or lay past the stability bound."""
    from matplotlib.patches import Rectangle

    grid, stat, seen = panel
    for r in range(grid.shape[0]):
        for c in range(grid.shape[1]):
            if not seen[r, c]:
                continue
            v = grid[r, c]
            if stat[r, c] == "diverged":
                txt, colour = "diverged", "#444444"
            elif not np.isfinite(v):
                txt, colour = "n/a", "#444444"
            elif not np.isfinite(shown[r, c]):  # fell
                a.add_patch(Rectangle((c - 0.5, r - 0.5), 1, 1, color=_FELL, lw=0, zorder=1))
                txt, colour = f"fell\n{_cell_text(v, metric)}", "#7a2a12"
            else:
                txt = _cell_text(v, metric)
                colour = _ink(cmap(norm(v)))
                if stat[r, c] in ("saturated", "past_bound"):
                    # stood, but on its torque limits or past the
                    # integrator's stability bound: never ranked
                    a.add_patch(Rectangle((c - 0.5, r - 0.5), 1, 1, fill=False, hatch="///",
                                          ec="#bbbbbb", lw=0, zorder=2, gid=str(stat[r, c])))
                    txt += "\nsaturated" if stat[r, c] == "saturated" else "\npast bound"
            a.text(c, r, txt, ha="center", va="center", color=colour, fontsize=fs, zorder=3)


def _best_row(table: Mapping[str, Any], metric: str, minimize: bool, sel: np.ndarray, vals: np.ndarray,
              status: np.ndarray) -> int | None:
    """The row to star among ``sel``: pupper's ranking rule's pick, or for a
    table the rule cannot rank, the best value among cells that did not
    diverge."""
    bi = _rule_best(table, metric, minimize, sel)
    if bi is None and not _rankable(table, metric):
        bi = _best_index(np.where(sel & (status != "diverged"), vals, np.nan), status, minimize)
    return bi


def _box_best(a: "Axes", c: int, r: int) -> None:
    """The best cell boxed in red, a star inside it clear of its edge and of the number."""
    from matplotlib.patches import Rectangle

    a.add_patch(
        Rectangle((c - 0.5, r - 0.5), 1, 1, fill=False, ec="red", lw=3, zorder=5, gid="best")
    )
    a.plot(c + 0.5 - 0.2, r + 0.5 - 0.24, marker="*", ms=11, color="red", mec="white",
           mew=0.8, zorder=6, gid="best_star")


@exported_from("pupper_core.plots")
def metric_vs_axis(
    table: TableLike,
    metric: str,
    axis: str,
    group: str | None = None,
    *,
    ax: "Axes | None" = None,
    title: str | None = None,
) -> "Figure":
    """``metric`` against one grid axis, one line per value of ``group``.

    Cells that fell are drawn with a red ×; diverged / NaN cells are left out.
    """
    table = _as_table(table)
    with _style():
        xs = _num(table, axis)
        vs = _num(table, metric)
        status = _status(table)
        fig = _new_figure((7.5, 4.6)) if ax is None else ax.figure
        ax = fig.add_subplot() if ax is None else ax
        if group is not None:
            gcol = _col(table, group)
            groups: list[Any] = _distinct(gcol.astype(float) if gcol.dtype.kind in "fiub" else gcol)
        else:
            gcol = None
            groups = [None]
        fell_all: list[int] = []
        for gi, gv in enumerate(groups):
            sel = np.ones(len(xs), bool) if gcol is None else (gcol == gv)
            sel &= np.isfinite(xs)
            order = np.flatnonzero(sel)[np.argsort(xs[sel], kind="stable")]
            shown = order[(status[order] != "diverged") & np.isfinite(vs[order])]
            up = shown[status[shown] != "fell"]
            lab = None if gv is None else f"{SHORT.get(group or '', group)} = {_fmt(gv)}"
            colour = f"C{gi % 10}"
            ax.plot(xs[up], vs[up], marker="o", ms=5, lw=1.6, color=colour, label=lab)
            fell = shown[status[shown] == "fell"]
            if fell.size:
                ax.plot(xs[fell], vs[fell], ls="none", marker="o", ms=5, color=colour, alpha=0.5)
                fell_all.extend(fell.tolist())
        fell_drawn = bool(fell_all)
        if fell_drawn:
            ax.plot(xs[fell_all], vs[fell_all], ls="none", marker="x", ms=10, mew=2, color="red",
                    label="fell (not joined)", zorder=5)
        pos = xs[np.isfinite(xs)]
        if pos.size and pos.min() > 0 and pos.max() / pos.min() > 30:
            ax.set_xscale("log")
            plain_log_axis(ax.xaxis)
        ax.set_xlabel(label_of(axis))
        ax.set_ylabel(label_of(metric))
        ax.grid(True, alpha=0.3)
        if group is not None or fell_drawn:
            ax.legend(title=label_of(group) if group else None, frameon=False,
                      loc="center left", bbox_to_anchor=(1.01, 0.5))
        ax.set_title(title if title is not None else f"{label_of(metric)} vs {SHORT.get(axis, axis)}")
        return fig


@exported_from("pupper_core.plots")
def bars(
    table: TableLike,
    metric: str,
    label: str = "name",
    *,
    ax: "Axes | None" = None,
    minimize: bool = True,
    title: str | None = None,
) -> "Figure":
    """Bar chart of ``metric`` per cell (e.g. named presets), values annotated.

    Bars of cells that fell are orange, diverged / NaN cells are marked; the
    best ok cell (min if ``minimize``) is outlined in red.
    """
    table = _as_table(table)
    with _style():
        vs = _num(table, metric)
        status = _status(table)
        n = len(vs)
        axes_cols = [a for a in SHORT if a in table and len(_distinct(_num(table, a))) > 1]
        names = []
        for i in range(n):
            nm = str(table[label][i]) if label in table else ""
            params = ", ".join(f"{SHORT[a]} {_fmt(table[a][i])}" for a in axes_cols)
            if not nm:
                nm = params or (str(table["id"][i]) if "id" in table else str(i))
            elif params:
                nm = f"{nm}\n{params}"
            names.append(nm)
        fig = _new_figure((max(5.0, 1.1 * n + 2.0), 4.8)) if ax is None else ax.figure
        ax = fig.add_subplot() if ax is None else ax
        heights = np.where(np.isfinite(vs) & (status != "diverged"), vs, 0.0)
        colours = ["#f28e2b" if s == "fell" else ("#bbbbbb" if s == "diverged" else "#4e79a7") for s in status]
        rects = ax.bar(range(n), heights, color=colours, edgecolor="none")
        best = _best_index(np.where(status != "diverged", vs, np.nan), status, minimize)
        top = np.nanmax(np.abs(heights)) if n and np.isfinite(heights).any() else 1.0
        for i, rect in enumerate(rects):
            if status[i] == "diverged":
                txt = "diverged"
            elif not np.isfinite(vs[i]):
                txt = "n/a"
            else:
                txt = f"{vs[i]:.3g}" + (" (fell)" if status[i] == "fell" else "")
            ax.annotate(txt, (rect.get_x() + rect.get_width() / 2, heights[i]), xytext=(0, 3),
                        textcoords="offset points", ha="center", va="bottom", fontsize=9)
            if best is not None and i == best:
                rect.set_edgecolor("red")
                rect.set_linewidth(2.5)
                rect.set_gid("best")
        ax.set_ylim(0, top * 1.18 if top > 0 else 1.0)
        ax.set_xticks(range(n), names, fontsize=9 if n > 6 else 10)
        if n > 8:
            for tl in ax.get_xticklabels():
                tl.set_rotation(45)
                tl.set_ha("right")
        ax.set_ylabel(label_of(metric))
        ax.grid(True, axis="y", alpha=0.3)
        best_word = "lowest" if minimize else "highest"
        ax.set_title(title if title is not None else f"{label_of(metric)}\n(red outline = {best_word})")
        fig.pupper_best = (  # type: ignore[attr-defined]
            [] if best is None else [{"row": best, "label": names[best].split("\n")[0], metric: float(vs[best])}]
        )
        return fig
