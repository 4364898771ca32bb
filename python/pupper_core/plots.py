"""Plots of sweep results (matplotlib, imported lazily).

Every function returns a ``matplotlib.figure.Figure`` built without pyplot
when it makes its own figure, so nothing accumulates in pyplot's registry
and a script needs no display; in a notebook, a returned figure shows once
when it is a cell's last expression (or via ``display(fig)``). Pass ``ax=`` to
draw into your own axes instead.

``table`` arguments are mappings column name -> sequence, with the columns of
``summary.csv`` (``read_run`` returns one; so does ``SweepResult.table``).
"""

from __future__ import annotations

import csv
import json
import math
import os
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator, Mapping, Sequence, Union

import numpy as np

from pupper_core._files import atomic_write

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from pupper_core._native import SweepResult

__all__ = ["base_z", "heatmap", "metric_vs_axis", "bars", "read_run", "write_run_plots",
           "grid_axes", "describe", "label_of", "read_replicates", "replicate_spread",
           "response_steps", "response_bode", "write_response_plots",
           "lab_heatmaps", "write_lab_plots", "write_hold_plots", "write_plots"]


def __dir__() -> list[str]:
    """The figures and readers, not numpy, os or sys."""
    return sorted(__all__)

Table = Mapping[str, Union[Sequence[Any], np.ndarray]]
Traces = Mapping[str, tuple[np.ndarray, np.ndarray]]
#: A table, or a result whose ``.table`` is one.
TableLike = Union[Table, "SweepResult"]

#: Columns of summary.csv that are text, not numbers.
TEXT_COLUMNS = ("id", "name", "status", "joint", "group", "status.haa", "status.hfe", "status.kfe", "status.other")
#: Axis columns holding names: plotted by their position in the grid.
NAMED_AXES = ("variant",)
#: The first metric column of summary.csv: the grid axes come before it.
FIRST_METRIC = "final_z"
#: Human labels with units.
LABELS: dict[str, str] = {
    "kp": "Kp (N·m/rad)",
    "kd": "Kd (N·m·s/rad)",
    "push_force": "push force, world z (N)",
    "max_torque": "torque limit (N·m)",
    "friction": "sliding friction μ",
    "timestep": "timestep (s)",
    "leg_scale": "leg length scale (×)",
    "torso_mass_scale": "torso mass scale (×)",
    "final_z": "final base height (m)",
    "last_1s_std_mm": "base-height std, last 1 s (mm)",
    "push_dip_mm": "push dip of base height (mm)",
    "settle_time_s": "settle time after push (s)",
    "max_tilt_deg": "max tilt (°)",
    "peak_torque": "peak joint torque (N·m)",
    "saturation_frac": "fraction of torque samples saturated",
    "tracking_rms": "joint tracking RMS error (rad)",
    "event_time": "fall / divergence time (s)",
    "sag_mm": "sag under the load (mm)",
    "compliance_mm_per_n": "sag per newton of load (mm/N)",
    "sway_mm": "sideways sway after the shove (mm)",
    "recovery_s": "recovery after the shove (s)",
    "copper_w": "copper loss (W)",
}
SHORT: dict[str, str] = {
    "kp": "Kp",
    "kd": "Kd",
    "push_force": "push",
    "max_torque": "τmax",
    "friction": "μ",
    "timestep": "dt",
    "leg_scale": "leg×",
    "torso_mass_scale": "torso×",
}
DPI = 120
_RC = {
    "font.size": 11,
    "axes.titlesize": 12,
    "axes.labelsize": 11,
    "xtick.labelsize": 10,
    "ytick.labelsize": 10,
    "legend.fontsize": 9,
    "figure.titlesize": 13,
    "axes.grid": False,
}
_BAD_GREY = "#c8c8c8"
_FELL = "#f6c9b8"


# ---------------------------------------------------------------------------
# helpers


def _ensure_backend() -> None:
    """Selects Agg when no backend was chosen and there is no display."""
    import matplotlib

    if os.environ.get("MPLBACKEND"):
        return
    chosen = getattr(matplotlib.rcParams, "_get_backend_or_none", lambda: "?")()
    headless = not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if chosen is None and headless and sys.platform.startswith("linux"):
        matplotlib.use("Agg")


@contextmanager
def _style() -> Iterator[None]:
    _ensure_backend()
    import matplotlib

    with matplotlib.rc_context(_RC):
        yield


def _new_figure(figsize: tuple[float, float]) -> "Figure":
    from matplotlib.figure import Figure

    _ipython_display()
    return Figure(figsize=figsize, dpi=DPI, layout="constrained")


_ipython_done = False


def _ipython_display() -> None:
    """In IPython/Jupyter, lets a returned Figure show as a PNG (once).

    Our figures are made without pyplot (so nothing piles up in its registry);
    IPython only knows how to show a Figure once matplotlib's inline support
    registered a formatter, so register one when none is there.
    """
    global _ipython_done
    if _ipython_done or "IPython" not in sys.modules:
        return
    _ipython_done = True
    try:
        from IPython import get_ipython
        from matplotlib.figure import Figure

        ip = get_ipython()
        if ip is None:
            return
        fmt = ip.display_formatter.formatters["image/png"]
        try:
            fmt.lookup_by_type(Figure)
            return  # inline backend (or the user) already handles figures
        except KeyError:
            pass

        def png(fig: "Figure") -> bytes:
            import io

            buf = io.BytesIO()
            fig.savefig(buf, format="png", dpi=fig.dpi)
            return buf.getvalue()

        fmt.for_type(Figure, png)
    except Exception:  # noqa: BLE001 - display is a nicety, never an error
        pass


def label_of(column: str) -> str:
    """Axis/colorbar label with units for a summary column (statistics over
    replicates, ``mean:M`` and ``p95:M``, say so)."""
    stat, sep, metric = column.partition(":")
    if sep and stat in ("mean", "p95"):
        word = "mean" if stat == "mean" else ("worst-side 95th percentile" if metric != "final_z" else "5th percentile")
        return f"{LABELS.get(metric, metric)}, {word} over replicates"
    if column == "failure_fraction":
        return "share of replicates that fell or diverged"
    return LABELS.get(column, column)


def _fmt(v: Any) -> str:
    """An axis value as a label: at most 3 significant digits (a log
    range's 22.8943 reads 22.9)."""
    if isinstance(v, str):
        return v
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    if math.isnan(f):
        return "—"
    return f"{f:.3g}"


#: Below this a *_mm metric is no difference at all (the ranking's tie, 1 µm).
MM_RESOLUTION = 0.001


def _cell_text(v: float, metric: str) -> str:
    """A heatmap cell's number, one format per metric: millimetres to the
    micrometre ("<0.001" below it: nanometres are no result), fractions in
    percent, others to 3 significant digits."""
    name = metric.split(":")[-1]
    if name.endswith("_mm"):
        if abs(v) < MM_RESOLUTION:
            return "<0.001"
        return f"{v:.3f}" if abs(v) < 10 else f"{v:.1f}"
    if name.endswith("_frac") or name == "failure_fraction":
        return f"{v * 100:.1f}%"
    return f"{v:.3g}"


def _as_table(table: TableLike) -> Table:
    """A column mapping from what the user has: a mapping, or a result
    (``SweepResult``, whose ``.table`` is one)."""
    if isinstance(table, Mapping):
        return table
    return table.table


def _col(table: Table, name: str) -> np.ndarray:
    if name not in table:
        raise KeyError(f"column '{name}' is not in the table (columns: {', '.join(table)})")
    return np.asarray(table[name])


def _num(table: Table, name: str) -> np.ndarray:
    a = _col(table, name)
    if a.dtype.kind in "fiub":
        return a.astype(float)
    out = np.full(a.shape, np.nan)
    for i, v in enumerate(a):
        try:
            out[i] = float(v) if v not in ("", None) else np.nan
        except (TypeError, ValueError):
            pass
    return out


def _nrows(table: Table) -> int:
    return len(next(iter(table.values()))) if table else 0


def _status(table: Table) -> np.ndarray:
    """Each row's status; a replicated cell counts as fallen when any of its
    replicates fell or diverged (it is never "best")."""
    if "status" in table:
        return np.asarray([str(s) for s in table["status"]], dtype=object)
    if "failure_fraction" in table:
        ff = np.asarray(table["failure_fraction"], dtype=float)
        return np.asarray(["ok" if f == 0 else "fell" for f in ff], dtype=object)
    return np.asarray(["ok"] * _nrows(table), dtype=object)


def _distinct(values: np.ndarray) -> list[Any]:
    """Distinct values in sorted order (numbers numerically, NaN dropped)."""
    if values.dtype.kind in "fiub":
        v = values[~np.isnan(values.astype(float))]
        return sorted(set(v.tolist()))
    return sorted(set(values.tolist()), key=str)


def _text(v: Any) -> str:
    """A table value as summary.csv writes it (NaN: empty)."""
    if isinstance(v, str):
        return v
    if isinstance(v, (bool, np.bool_)):
        return str(v)
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    return "" if math.isnan(f) else repr(f)


def _rule_best(table: Table, metric: str, minimize: bool, rows: np.ndarray) -> int | None:
    """The row (among ``rows``) that pupper's ranking rule picks, the one
    `--best-by` and the printed "steadiest" name: eligible cells only (they
    stood, under 5 % saturation), ties within 1 µm to the smaller dip. None
    when no row is eligible, or the table is not one pupper can rank."""
    from pupper_core import _native

    header = list(table)
    idx = [int(i) for i in np.flatnonzero(rows)]
    if not idx:
        return None
    cols = [np.asarray(table[h], dtype=object) for h in header]
    text = [[_text(c[i]) for c in cols] for i in idx]
    try:
        (pick,) = _native.best_rows(header, text, metric, minimize=minimize)
    except Exception:  # noqa: BLE001 (a table of other columns: no rule to apply)
        return None
    return None if pick is None else idx[pick]


def _rankable(table: Table, metric: str) -> bool:
    """Whether pupper's rule applies: a summary table with its status (or
    failure fraction) and the metric."""
    return metric in table and ("status" in table or "failure_fraction" in table)


def _best_index(values: np.ndarray, status: np.ndarray, minimize: bool) -> int | None:
    """Row of the best finite value among cells whose status is ok (else any)."""
    finite = np.isfinite(values)
    ok = finite & (status == "ok")
    pool = ok if ok.any() else finite
    if not pool.any():
        return None
    idx = np.flatnonzero(pool)
    sub = values[idx]
    return int(idx[np.argmin(sub) if minimize else np.argmax(sub)])


def _row_label(table: Table, i: int, axes: Sequence[str] | None = None, label: str = "name") -> str:
    name = str(table[label][i]) if label in table else ""
    if axes is None:
        axes = [a for a in SHORT if a in table]
    vals = ", ".join(f"{SHORT.get(a, a)} {_fmt(table[a][i])}" for a in axes)
    if name and vals:
        return f"{name} ({vals})"
    return name or vals or (str(table["id"][i]) if "id" in table else str(i))


def _key_line(best_word: str, status: np.ndarray, metric: str = "last_1s_std_mm") -> str:
    """'★ = lowest …' plus the colours used for fallen / diverged cells; the
    tie rule as the Rust core applies it to ``metric`` (0.001 mm on a
    millimetre column, exact equality on others)."""
    tie = "ties within 0.001 mm" if metric.split(":")[-1].endswith("_mm") else "equal values"
    parts = [f"★ = {best_word} among cells that stood below 5 % saturation ({tie}: the smaller dip)"
             if best_word == "lowest" else f"★ = {best_word} among cells that stood"]
    if (status == "fell").any():
        parts.append("pink = fell")
    if (status == "diverged").any():
        parts.append("grey = diverged")
    return " · ".join(parts)


def _wrap_parts(text: str, width_in: float, fontsize: float = 11.0) -> str:
    """Breaks a ' · '-separated line so it fits ``width_in`` inches."""
    limit = max(30, int(width_in * 72 / (0.55 * fontsize)))
    lines: list[str] = []
    cur = ""
    for part in text.split(" · "):
        cand = part if not cur else f"{cur} · {part}"
        if len(cand) > limit and cur:
            lines.append(cur)
            cur = part
        else:
            cur = cand
    if cur:
        lines.append(cur)
    # a part longer than the line breaks between words
    import textwrap

    return "\n".join(w for line in lines for w in (textwrap.wrap(line, limit) or [line]))


def _push_tuple(push: Any) -> tuple[float, float, float | None] | None:
    if push is None:
        return None
    if isinstance(push, Mapping):
        f = push.get("force")
        # the push's own direction: z for the chapter's, sideways for a hold's shove
        fz = max((float(v) for v in f), key=abs) if f is not None and len(f) > 2 else None
        return float(push["start"]), float(push["duration"]), fz
    seq = list(push)
    fz = None
    if len(seq) > 2:
        f = seq[2]
        fz = float(f) if np.ndim(f) == 0 else float(np.asarray(f, dtype=float)[-1])
    return float(seq[0]), float(seq[1]), fz


# ---------------------------------------------------------------------------
# plots


def base_z(
    traces: Traces,
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
    """
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
        if labels is None:
            names = {k: str(k) for k in ids}
        elif isinstance(labels, Mapping):
            names = {k: str(labels.get(k, k)) for k in ids}
        else:
            names = {k: str(lab) for k, lab in zip(ids, labels)}
        n = len(ids)
        import matplotlib

        if n > 20:
            cmap = matplotlib.colormaps["viridis"]
            colours = [cmap(i / max(1, n - 1)) for i in range(n)]
        elif n > 10:
            # twenty colours that can be told apart, not one ramp
            tab = matplotlib.colormaps["tab20"]
            colours = [tab(i) for i in range(n)]
        else:
            colours = [f"C{i}" for i in range(n)]
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
        if zax is not None and p is not None:
            lo_t, hi_t = p[0] - 0.5, p[0] + p[1] + 1.5
            zs = []
            for k in [k for k in ids if k not in chatter] or ids:
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
            ax.set_title("whole run", fontsize=11)
        # the whole run's range: the robots after landing, chattering ones aside
        steady = []
        top0 = -np.inf
        for k in [k for k in ids if k not in chatter] or ids:
            t, z = (np.asarray(v, float) for v in traces[k])
            w = (t >= landing) & np.isfinite(z)
            if w.any():
                steady.append(z[w] * 1000.0)
            if len(z) and np.isfinite(z[0]):
                top0 = max(top0, float(z[0]) * 1000.0)
        if steady:
            allz = np.concatenate(steady)
            lo, hi = float(allz.min()), float(allz.max())
            pad = 0.15 * (hi - lo) if hi > lo else 0.5
            ax.set_ylim(lo - pad, hi + pad)
            if top0 > hi + pad:
                ax.set_title(f"whole run (from {top0:.0f} mm at t = 0, off the top)", fontsize=11)
        if title is not None:
            (fig.suptitle if zax is not None else ax.set_title)(title)
        if n <= 24:
            ncol = 1 if n <= 8 else 2
            panels[-1].legend(loc="center left", bbox_to_anchor=(1.01, 0.5), ncol=ncol, frameon=False)
        return fig


def heatmap(
    table: TableLike,
    metric: str = "last_1s_std_mm",
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
    from matplotlib.colors import LogNorm, Normalize
    from matplotlib.patches import Rectangle

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

        # grids per panel
        grids = []
        for pv in panels:
            sel = np.ones(len(vals), bool) if bcol is None else (bcol == pv)
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
            grids.append((pv, grid, stat, seen))

        # the colour scale spans the cells that stayed up (a fallen robot lying
        # still has a tiny, misleading std); fallen cells get their own colour
        okv = [g[1][np.isfinite(g[1]) & (g[2] == "ok")] for g in grids]
        finite = np.concatenate(okv) if okv else np.array([])
        if finite.size == 0:
            finite = np.concatenate([g[1][np.isfinite(g[1])] for g in grids]) if grids else np.array([])
        if log is None:
            log = bool(finite.size and finite.min() > 0 and finite.max() / finite.min() > 100)
        if finite.size == 0:
            norm: Normalize = Normalize(0, 1)
        elif log:
            norm = LogNorm(max(finite.min(), 1e-12), max(finite.max(), finite.min() * 1.0001))
        else:
            lo, hi = float(finite.min()), float(finite.max())
            norm = Normalize(lo, hi if hi > lo else lo + 1e-9)
        import matplotlib

        cmap = matplotlib.colormaps["viridis_r" if minimize else "viridis"].with_extremes(bad=_BAD_GREY)

        npan = len(panels)
        cw = max(0.75, min(1.1, 9.0 / max(1, len(xv))))
        pw = cw * len(xv) + 1.2
        ph = 0.55 * len(yv) + 1.6
        if ax is None:
            ncols = min(npan, 3)
            nrows = math.ceil(npan / ncols)
            fig = _new_figure((pw * ncols + 1.4, ph * nrows + (0.5 if title else 0.2)))
            axs = list(np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False).ravel()))
            for extra in axs[npan:]:
                extra.set_visible(False)
            axs = axs[:npan]
        else:
            fig = ax.figure
            axs = [ax]
        best_marks: list[dict[str, Any]] = []
        im = None
        fs = 9 if len(xv) > 7 else 10
        for a, (pv, grid, stat, seen) in zip(axs, grids):
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
            for r in range(len(yv)):
                for c in range(len(xv)):
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
                        rgba = cmap(norm(v))
                        lum = 0.299 * rgba[0] + 0.587 * rgba[1] + 0.114 * rgba[2]
                        colour = "black" if lum > 0.55 else "white"
                        if stat[r, c] in ("saturated", "past_bound"):
                            # stood, but on its torque limits or past the
                            # integrator's stability bound: never ranked
                            a.add_patch(Rectangle((c - 0.5, r - 0.5), 1, 1, fill=False, hatch="///",
                                                  ec="#bbbbbb", lw=0, zorder=2, gid=str(stat[r, c])))
                            txt += "\nsaturated" if stat[r, c] == "saturated" else "\npast bound"
                    a.text(c, r, txt, ha="center", va="center", color=colour, fontsize=fs, zorder=3)
            # best cell
            sel_rows = np.ones(len(vals), bool) if bcol is None else (bcol == pv)
            v2 = np.where(sel_rows & (status != "diverged"), vals, np.nan)
            bi = None
            if mark_best:
                bi = _rule_best(table, metric, minimize, sel_rows)
                if bi is None and not _rankable(table, metric):
                    bi = _best_index(v2, status, minimize)
            if bi is not None:
                c, r = xv.index(xs_all[bi]), yv.index(ys_all[bi])
                a.add_patch(
                    Rectangle((c - 0.5, r - 0.5), 1, 1, fill=False, ec="red", lw=3, zorder=5, gid="best")
                )
                # inside the box, clear of its edge and of the number
                a.plot(c + 0.5 - 0.2, r + 0.5 - 0.24, marker="*", ms=11, color="red", mec="white",
                       mew=0.8, zorder=6, gid="best_star")
                best_marks.append({"panel": pv, x: xv[c], y: yv[r], metric: float(vals[bi])})
            if pv is not None:
                a.set_title(f"{by} = {_fmt(pv)}" if by in SHORT or by in LABELS else str(pv))
        if im is not None:
            cb = fig.colorbar(im, ax=axs, shrink=0.9 if len(yv) > 3 else 1.0)
            cb.set_label(label_of(metric))
        best_word = "lowest" if minimize else "highest"
        sub = _key_line(best_word, status, metric)
        head = title if title is not None else label_of(metric)
        if ax is None:
            fig.suptitle(f"{head}\n{_wrap_parts(sub, fig.get_figwidth(), 12)}", fontsize=12)
        else:
            ax.set_title(f"{head}\n{sub}", fontsize=11)
        fig.pupper_best = best_marks  # type: ignore[attr-defined]
        return fig


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
        ax.set_xlabel(label_of(axis))
        ax.set_ylabel(label_of(metric))
        ax.grid(True, alpha=0.3)
        if group is not None or fell_drawn:
            ax.legend(title=label_of(group) if group else None, frameon=False,
                      loc="center left", bbox_to_anchor=(1.01, 0.5))
        ax.set_title(title if title is not None else f"{label_of(metric)} vs {SHORT.get(axis, axis)}")
        return fig


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


# ---------------------------------------------------------------------------
# run directories


def read_run(run_dir: str | os.PathLike) -> tuple[dict[str, Any], dict[str, Any], dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Reads ``summary.csv``, ``manifest.json`` and (if present) ``traces.csv``.

    Returns ``(table, manifest, traces)``: numeric columns as float arrays
    (empty field = NaN; ``index`` int64, as in ``SweepResult.table``; a
    ``variant`` column as 0, 1, ... in order of appearance),
    ``id``/``name``/``status`` as lists of str; traces
    id -> (t, z) arrays in file order ({} when there is no traces.csv).
    """
    d = Path(run_dir)
    summary = d / "summary.csv"
    if not summary.exists():
        raise FileNotFoundError(f"{d} has no summary.csv: is it a pupper run directory?")
    with summary.open(newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None:
            raise ValueError(f"{summary} is empty")
        rows = [r for r in reader if r]
    table: dict[str, Any] = {}
    for j, name in enumerate(header):
        col = [r[j] if j < len(r) else "" for r in rows]
        if name in TEXT_COLUMNS:
            table[name] = col
        elif name == "index":  # as in SweepResult.table
            table[name] = np.array([int(v) for v in col], dtype=np.int64)
        elif name in NAMED_AXES:  # a body's name: its position in the grid's list
            names = list(dict.fromkeys(col))
            table[name] = np.array([float(names.index(v)) for v in col], dtype=float)
        else:
            table[name] = np.array([float(v) if v.strip() else np.nan for v in col], dtype=float)
    manifest: dict[str, Any] = {}
    mp = d / "manifest.json"
    if mp.exists():
        manifest = json.loads(mp.read_text())
    traces: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    tp = d / "traces.csv"
    if tp.exists():
        acc: dict[str, tuple[list[float], list[float]]] = {}
        with tp.open(newline="") as f:
            reader = csv.reader(f)
            head = next(reader, None) or []
            ci, ti, zi = (head.index(k) for k in ("id", "t", "z"))
            for r in reader:
                if not r:
                    continue
                ts, zs = acc.setdefault(r[ci], ([], []))
                ts.append(float(r[ti]) if r[ti] else np.nan)
                zs.append(float(r[zi]) if r[zi] else np.nan)
        traces = {k: (np.asarray(t, float), np.asarray(z, float)) for k, (t, z) in acc.items()}
    return table, manifest, traces


def grid_axes(table: TableLike) -> list[str]:
    """The grid-axis columns of a summary table (between ``name`` and the metrics)."""
    table = _as_table(table)
    cols = list(table)
    start = cols.index("name") + 1 if "name" in cols else 0
    out = []
    for c in cols[start:]:
        # a response run's figures per group (rise_time_s.hfe) end them too
        if c in (FIRST_METRIC, "replicates", "replicate", "joint", "status") or (
                "." in c and c.split(".", 1)[0] not in ("kp", "kd")):
            break
        out.append(c)
    return out


def describe(manifest: Mapping[str, Any], n_cells: int | None = None) -> str:
    """One line saying what a sweep was: mode, model, push, duration."""
    cfg = manifest.get("config", {}) or {}
    parts = []
    mode = cfg.get("mode")
    if mode:
        parts.append(f"{mode} mode")
    m = cfg.get("model") or {}
    if isinstance(m, Mapping):
        if "builtin" in m:
            parts.append(str(m["builtin"]))
        elif "path" in m:
            parts.append(Path(str(m["path"])).name)
    sched = cfg.get("schedule", {}) or {}
    p = _push_tuple(sched.get("push"))
    if sched and p is None:
        parts.append("no push")
    elif p is not None:
        f = (sched.get("push") or {}).get("force")
        ftxt = "[" + ", ".join(_fmt(v) for v in f) + "] N" if f is not None else ""
        parts.append(f"push {ftxt} at {p[0]:g} s for {p[1]:g} s")
    sine = sched.get("sine")
    if isinstance(sine, Mapping):
        parts.append(f"vertical sine {float(sine.get('amplitude', 0)):g} N at {float(sine.get('frequency', 0)):g} Hz")
    if sched.get("duration") is not None:
        parts.append(f"{float(sched['duration']):g} s simulated")
    defaults = cfg.get("defaults") or {}
    if defaults:
        # only what was set and not swept: no gain or torque limit means the
        # model's own, scales of 1 the model's body
        swept = {a.get("axis") for a in ((cfg.get("grid") or {}).get("axes") or []) if isinstance(a, Mapping)}
        shown = {k: v for k, v in defaults.items()
                 if v is not None and k not in swept
                 and not (k in ("leg_scale", "torso_mass_scale") and v == 1)}
        if shown:
            parts.append(", ".join(f"{SHORT.get(k, k)} {_fmt(v)}" for k, v in shown.items()))
    reps = cfg.get("replicates") or {}
    if reps:
        drawn = []
        for r in reps.get("randomize") or []:
            kind, v = next(iter(r["dist"].items()))
            text = {"relative": lambda x: f"±{x * 100:g}%", "normal": lambda x: f"N({x[0]:g},{x[1]:g})"}.get(
                kind, lambda x: f"{x[0]:g}:{x[1]:g}")(v)
            drawn.append(f"{r['quantity']} {text}")
        parts.append(f"{reps.get('count', 1)} replicates" + (f" ({', '.join(drawn)}; seed {reps.get('seed', 0)})"
                                                            if drawn else ""))
    if n_cells is not None:
        parts.append(f"{n_cells} cells")
    return " · ".join(parts)


def _save(fig: "Figure", path: Path) -> Path:
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=DPI))
    return path


def _is_product(table: Table, varying: Sequence[str], manifest: Mapping[str, Any]) -> bool:
    grid = ((manifest.get("config") or {}).get("grid") or {}) if manifest else {}
    if grid.get("explicit"):
        return False
    n = _nrows(table)
    combos = {tuple(_num(table, a)[i] for a in varying) for i in range(n)}
    return len(combos) == n == math.prod(len(_distinct(_num(table, a))) for a in varying)


def write_plots(run_dir: str | os.PathLike) -> list[Path]:
    """Writes the plots of a run's kind (its manifest names it) into
    ``<run_dir>/plots/``; returns their paths. The registry of the kinds'
    plot writers."""
    manifest = json.loads((Path(run_dir) / "manifest.json").read_text())
    writers = {"lab": write_lab_plots, "response": write_response_plots, "hold": write_hold_plots}
    return writers.get(str(manifest.get("kind")), write_run_plots)(run_dir)


def write_hold_plots(run_dir: str | os.PathLike) -> list[Path]:
    """A hold's plots in ``<run_dir>/plots/``: ``base_z.png`` (the height
    sagging as the load ramps on, the shove shaded), and the sag per newton
    and the sway per cell (a heatmap for a Kp × Kd grid), as
    `write_run_plots` draws a sweep's."""
    return write_run_plots(run_dir, metrics=("compliance_mm_per_n", "sway_mm"), during="the hold")


def write_run_plots(run_dir: str | os.PathLike, metrics: Sequence[str] | None = None,
                    during: str = "the sweep") -> list[Path]:
    """Writes the standard plots of a run into ``<run_dir>/plots/``; returns their paths.

    ``base_z.png`` when traces exist; for a Kp × Kd product grid
    ``heatmap_<metric>.png`` (a panel per value of a third axis), for one
    varying axis ``<metric>_vs_<axis>.png``, for two varying axes other than
    Kp × Kd ``<metric>_vs_<axis1>.png`` grouped by the other, else (presets,
    non-product grids) ``bars_<metric>.png``; metrics last_1s_std_mm and
    push_dip_mm. Files are written atomically.
    """
    d = Path(run_dir)
    table, manifest, traces = read_run(d)
    out = d / "plots"
    out.mkdir(parents=True, exist_ok=True)
    n = _nrows(table)
    what = describe(manifest, n)
    axes = grid_axes(table)
    varying = [a for a in axes if len(_distinct(_num(table, a))) > 1]
    written: list[Path] = []
    sched = ((manifest.get("config") or {}).get("schedule") or {}) if manifest else {}
    push = sched.get("push")

    def setting(fig: "Figure") -> None:
        # what was run, below the figure: the title says what is shown
        fig.supxlabel(_wrap_parts(what, fig.get_figwidth(), 8), fontsize=8, color="#555555")

    def finish(fig: "Figure", name: str, head: str) -> None:
        fig.suptitle(head, fontsize=12)
        setting(fig)
        written.append(_save(fig, out / name))

    if traces:
        labels = {}
        if "id" in table:
            for i, cid in enumerate(table["id"]):
                labels[cid] = _row_label(table, i, varying or axes)
                st = str(table["status"][i]) if "status" in table else "ok"
                if st != "ok":
                    labels[cid] += f" — {st}"
        status = ({str(c): str(s) for c, s in zip(table["id"], table["status"])}
                  if "id" in table and "status" in table else None)
        fig = base_z(traces, push=push, labels=labels, status=status,
                     landing=float(sched.get("landing", 1.0)))
        finish(fig, "base_z.png", f"Base height during {during}" + (
            "\nreplicate 0 of each cell (every replicate's metrics: spread_last_1s_std_mm.png)"
            if "failure_fraction" in table else ""))

    # a metric that is NaN in every cell (push_dip_mm without a push) has nothing to show
    replicated = "failure_fraction" in table
    candidates = (("failure_fraction", "p95:last_1s_std_mm", "p95:push_dip_mm") if replicated
                  else ("last_1s_std_mm", "push_dip_mm"))
    metrics = [
        m
        for m in (metrics or candidates)
        if m in table and np.isfinite(np.asarray(table[m], dtype=float)).any()
    ]
    if replicated:
        fig = replicate_spread(d, "last_1s_std_mm")
        if fig is not None:
            finish(fig, "spread_last_1s_std_mm.png", "Spread over replicates at the best cells")
    product = _is_product(table, varying, manifest) if varying else False
    for metric in metrics:
        if product and "kp" in varying and "kd" in varying:
            others = [a for a in varying if a not in ("kp", "kd")]
            t2: dict[str, Any] = dict(table)
            by = None
            if len(others) == 1:
                by = others[0]
            elif len(others) > 1:
                by = "_panel"
                t2[by] = [", ".join(f"{SHORT.get(a, a)} = {_fmt(table[a][i])}" for a in others) for i in range(n)]
            if metric == "failure_fraction":
                # the share itself: every cell coloured, none "best"
                t2.pop("failure_fraction", None)
                t2[metric] = table[metric]
                t2["status"] = ["ok"] * n
            fig = heatmap(t2, metric, "kp", "kd", by=by, mark_best=metric != "failure_fraction")
            key = _key_line("lowest", _status(t2), metric)
            if replicated:
                key = key.replace("pink = fell", "pink = some replicates fell or diverged")
            if metric == "failure_fraction":
                key = "0 = every replicate stayed up"
            fig.suptitle(f"{label_of(metric)}\n{_wrap_parts(key, fig.get_figwidth(), 12)}", fontsize=12)
            setting(fig)
            written.append(_save(fig, out / f"heatmap_{metric.replace(':', '_')}.png"))
        elif product and len(varying) in (1, 2):
            axis = varying[0]
            group = varying[1] if len(varying) == 2 else None
            if group is not None and axis not in ("kp", "kd") and group in ("kp", "kd"):
                axis, group = group, axis
            fig = metric_vs_axis(table, metric, axis, group, title="")
            finish(fig, f"{metric.replace(':', '_')}_vs_{axis}.png", f"{label_of(metric)} vs {label_of(axis)}")
        else:
            fig = bars(table, metric, title="")
            finish(fig, f"bars_{metric.replace(':', '_')}.png", label_of(metric) + "  (red outline = lowest)")
    return written


GROUP_TITLES = {"haa": "hip abduction (haa)", "hfe": "hip pitch (hfe)", "kfe": "knee (kfe)"}


def _read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def response_steps(run_dir: str | os.PathLike, cells: Sequence[str] | None = None) -> "Figure | None":
    """Step responses of a response run, a panel per joint group: each
    chosen cell's angle change over the step, averaged over the group's
    joints and divided by the step, against time after the step; the target
    (1) dashed and the 2 % settling band shaded. Needs response_traces.csv
    (`--trace` or `--plot`). ``cells``: cell ids (default: up to 6 spread
    over the grid)."""
    d = Path(run_dir)
    if not (d / "response_traces.csv").exists():
        return None
    traces = _read_csv(d / "response_traces.csv")
    joints = _read_csv(d / "response.csv")
    group_of = {r["joint"]: r["group"] for r in joints}
    ids = list(dict.fromkeys(r["id"] for r in traces))
    if cells is None:
        step = max(1, math.ceil(len(ids) / 6))
        cells = ids[::step][:6]
    manifest = json.loads((d / "manifest.json").read_text())
    amp = float(manifest["config"]["response"]["signal"]["amplitude"])
    groups = [g for g in ("haa", "hfe", "kfe") if g in group_of.values()] + sorted(
        {g for g in group_of.values() if g not in ("haa", "hfe", "kfe")})
    # (cell, group) -> joint -> (t, angle)
    curves: dict[tuple[str, str], dict[str, list[tuple[float, float]]]] = {}
    for r in traces:
        if r["id"] in cells:
            curves.setdefault((r["id"], group_of[r["joint"]]), {}).setdefault(r["joint"], []).append(
                (float(r["t"]), float(r["angle"])))
    with _style():
        fig = _new_figure((4.2 * len(groups) + 1.5, 4.2))
        axes = np.atleast_1d(fig.subplots(1, len(groups), sharey=True))
        colours = [f"C{i}" for i in range(len(cells))]
        for ax, g in zip(axes, groups):
            tmax = 0.0
            for c, colour in zip(cells, colours):
                per_joint = curves.get((c, g), {})
                if not per_joint:
                    continue
                n = min(len(v) for v in per_joint.values())
                t = np.array([p[0] for p in next(iter(per_joint.values()))[:n]])
                rel = np.mean([[(p[1] - v[0][1]) / amp for p in v[:n]] for v in per_joint.values()], axis=0)
                ax.plot(t, rel, color=colour, lw=1.4, label=c)
                tmax = max(tmax, float(t[-1]))
            ax.axhline(1.0, color="black", ls="--", lw=1, label="target")
            ax.axhspan(0.98, 1.02, color="tab:green", alpha=0.15, lw=0, label="±2 % band")
            ax.set_title(GROUP_TITLES.get(g, g), fontsize=11)
            ax.set_xlabel("time after the step (s)")
            ax.set_xlim(0, tmax if tmax > 0 else None)
            ax.grid(True, alpha=0.3)
        axes[0].set_ylabel("angle change / step size")
        axes[-1].legend(loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False, fontsize=9)
        fig.pupper_cells = list(cells)
        return fig


def response_bode(run_dir: str | os.PathLike, cells: Sequence[str] | None = None) -> "Figure | None":
    """Bode plot of a sine or chirp response run: gain (dB) and phase (deg)
    against frequency, a column per joint group (the mean over the group's
    joints), a line per chosen cell (default: up to 6 spread over the
    grid); the −3 dB line dotted."""
    d = Path(run_dir)
    if not (d / "bode.csv").exists():
        return None
    rows = [r for r in _read_csv(d / "bode.csv") if r["replicate"] == "0"]
    group_of = {r["joint"]: r["group"] for r in _read_csv(d / "response.csv")}
    ids = list(dict.fromkeys(r["id"] for r in rows))
    if cells is None:
        step = max(1, math.ceil(len(ids) / 6))
        cells = ids[::step][:6]
    groups = [g for g in ("haa", "hfe", "kfe") if g in group_of.values()] + sorted(
        {g for g in group_of.values() if g not in ("haa", "hfe", "kfe")})
    with _style():
        fig = _new_figure((4.2 * len(groups) + 1.5, 6.0))
        axes = np.array(fig.subplots(2, len(groups), sharex=True, squeeze=False))
        for k, g in enumerate(groups):
            for i, c in enumerate(cells):
                pts: dict[float, list[tuple[float, float]]] = {}
                for r in rows:
                    if r["id"] == c and group_of[r["joint"]] == g and r["gain_db"]:
                        pts.setdefault(float(r["hz"]), []).append((float(r["gain_db"]), float(r["phase_deg"])))
                if not pts:
                    continue
                hz = np.array(sorted(pts))
                gain = np.array([np.mean([p[0] for p in pts[f]]) for f in hz])
                phase = np.array([np.mean([p[1] for p in pts[f]]) for f in hz])
                style = dict(color=f"C{i}", lw=1.4, marker="o" if len(hz) == 1 else None)
                axes[0, k].plot(hz, gain, label=c, **style)
                axes[1, k].plot(hz, phase, **style)
            axes[0, k].axhline(-3, color="grey", ls=":", lw=1)
            axes[0, k].set_title(GROUP_TITLES.get(g, g), fontsize=11)
            axes[1, k].set_xlabel("frequency (Hz)")
            for a in axes[:, k]:
                a.set_xscale("log")
                a.grid(True, which="both", alpha=0.3)
        axes[0, 0].set_ylabel("gain (dB)")
        axes[1, 0].set_ylabel("phase (deg)")
        axes[0, -1].legend(loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False, fontsize=9)
        return fig


def write_response_plots(run_dir: str | os.PathLike) -> list[Path]:
    """`pupper response --plot`: into ``<run_dir>/plots/``,
    ``response_steps.png`` (step responses per joint group), ``bode.png``
    (sine, chirp) and, for a Kp x Kd product grid, ``response_<figure>.png``
    heatmaps (rise time, overshoot, settling time; a panel per group)."""
    d = Path(run_dir)
    out = d / "plots"
    out.mkdir(parents=True, exist_ok=True)
    table, manifest, _ = read_run(d)
    what = describe(manifest, _nrows(table))
    written: list[Path] = []

    def finish(fig: "Figure", name: str, head: str) -> None:
        fig.suptitle(head, fontsize=12)
        fig.supxlabel(_wrap_parts(what, fig.get_figwidth(), 8), fontsize=8, color="#555555")
        written.append(_save(fig, out / name))

    fig = response_steps(d)
    if fig is not None:
        finish(fig, "response_steps.png", "Step response per joint group (mean over the group's joints)")
    fig = response_bode(d)
    if fig is not None:
        finish(fig, "bode.png", "Frequency response per joint group (mean over the group's joints)")
    axes = grid_axes(table)
    varying = [a for a in axes if len(_distinct(_num(table, a))) > 1]
    if {"kp", "kd"} <= set(varying) and _is_product(table, varying, manifest) and len(varying) == 2:
        n = _nrows(table)
        groups = [c.split(".", 1)[1] for c in table if c.startswith("rise_time_s.")]
        for metric, label in (("rise_time_s", "rise time (s)"), ("overshoot_pct", "overshoot (%)"),
                              ("settling_time_s", "settling time (s)")):
            if not groups:
                break
            stacked: dict[str, Any] = {"kp": [], "kd": [], "status": [], metric: [], "_panel": []}
            for g in groups:
                stacked["kp"] += list(_num(table, "kp"))
                stacked["kd"] += list(_num(table, "kd"))
                # the group's own status: another group's chatter is not this one's
                stacked["status"] += [str(v) for v in _col(table, f"status.{g}")]
                stacked[metric] += list(_num(table, f"{metric}.{g}"))
                stacked["_panel"] += [GROUP_TITLES.get(g, g)] * n
            # a linear scale: a numerically zero overshoot (1e-9 %) is no
            # decade of its own
            # no star: the lowest of these is no verdict on the gains
            fig = heatmap(stacked, metric, "kp", "kd", by="_panel", mark_best=False,
                          log=False if metric == "overshoot_pct" else None)
            finish(fig, f"response_{metric}.png", f"{label} per joint group")
    return written


def read_replicates(run_dir: str | os.PathLike) -> dict[str, Any]:
    """``replicates.csv`` as columns (numbers as float arrays, ``id``,
    ``name``, ``status`` and a ``variant`` axis as lists of str)."""
    path = Path(run_dir) / "replicates.csv"
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return {}
    out: dict[str, Any] = {}
    for name in rows[0]:
        col = [r[name] for r in rows]
        if name in TEXT_COLUMNS or name in NAMED_AXES:
            out[name] = col
        else:
            out[name] = np.array([float(v) if v.strip() else np.nan for v in col], dtype=float)
    return out


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


def replicate_spread(run_dir: str | os.PathLike, metric: str = "last_1s_std_mm",
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
    d = Path(run_dir)
    if not (d / "replicates.csv").exists():
        return None
    reps = read_replicates(d)
    with open(d / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    key = f"p95:{metric}"
    picked: set[str] = set()
    if by is not None and (d / "best.csv").exists():
        with open(d / "best.csv", newline="") as f:
            chosen = [r["id"] for r in csv.DictReader(f) if r["id"]]
        picked = set(chosen)
    else:
        def rank(r: dict[str, str]) -> tuple[int, float]:
            v = float(r[key]) if r.get(key) else math.inf
            return (0 if r["failure_fraction"] == "0" else 1, v)

        chosen = [r["id"] for r in sorted(rows, key=rank)[:cells]]
        if rows and key in rows[0]:
            from pupper_core import _native

            header = list(rows[0])
            (pick,) = _native.best_rows(header, [[r[h] for h in header] for r in rows], key)
            if pick is not None:
                picked = {rows[pick]["id"]}
                if rows[pick]["id"] not in chosen:
                    chosen[-1] = rows[pick]["id"]
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
        if scatter is not None and colour_by is not None:
            bar = fig.colorbar(scatter, ax=ax, pad=0.02)
            bar.set_label(f"drawn {colour_by}", fontsize=9)
        ax.legend(loc="best", fontsize=8)
        if picked:
            ax.set_xlabel("★ = the cell pupper's rule picks", fontsize=9)
        return fig


def lab_heatmaps(
    bodies: Sequence[str],
    kp: Sequence[float],
    kd: Sequence[float],
    values: Mapping[str, np.ndarray],
    best: Mapping[str, tuple[float, float] | None],
    metric: str = "last_1s_std_mm",
    status: Mapping[str, np.ndarray] | None = None,
) -> "Figure":
    """One Kp × Kd heatmap per body on one shared (log) colour scale, the
    body's best cell starred, as the sweep's heatmaps: yellow is steadier,
    numbers in the cells. ``values[body]`` is a (len(kd), len(kp)) array,
    NaN where the cell fell, diverged or saturated; ``status[body]`` (the
    same shape, text) names why a cell is blank. A best cell on the grid's
    edge gets a hint to widen the grid that way."""
    from matplotlib.colors import LogNorm

    with _style():
        fig = _new_figure((4.2 * len(bodies) + 1.2, 4.2))
        axes = fig.subplots(1, len(bodies), squeeze=False)[0]
        finite = np.concatenate([v[np.isfinite(v) & (v > 0)] for v in values.values()] or [np.array([1.0])])
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (1e-3, 1.0)
        norm = LogNorm(vmin=lo, vmax=max(hi, lo * 1.0001))
        image = None
        import matplotlib

        cmap = matplotlib.colormaps["viridis_r"].with_extremes(bad=_BAD_GREY)
        edges: list[str] = []
        for ax, body in zip(axes, bodies):
            v = np.ma.masked_invalid(values[body])
            image = ax.imshow(v, origin="lower", cmap=cmap, norm=norm, aspect="auto")
            ax.set_xticks(range(len(kp)), [_fmt(x) for x in kp])
            ax.set_yticks(range(len(kd)), [_fmt(x) for x in kd])
            ax.set_xlabel("Kp (N·m/rad)")
            ax.set_title(body)
            st = status.get(body) if status is not None else None
            for r in range(len(kd)):
                for c in range(len(kp)):
                    x = values[body][r, c]
                    if np.isfinite(x):
                        rgba = cmap(norm(x))
                        lum = 0.299 * rgba[0] + 0.587 * rgba[1] + 0.114 * rgba[2]
                        txt, colour = _cell_text(float(x), metric), "black" if lum > 0.55 else "white"
                    else:
                        why = str(st[r, c]) if st is not None else ""
                        txt, colour = (why if why and why != "ok" else "n/a"), "#444444"
                    ax.text(c, r, txt, ha="center", va="center", color=colour, fontsize=8, zorder=3)
            b = best.get(body)
            if b is not None:
                c, r = list(kp).index(b[0]), list(kd).index(b[1])
                ax.plot([c + 0.28], [r + 0.25], marker="*", color="red", markersize=12,
                        markeredgecolor="white", zorder=6, gid="best_star")
                side = [w for w, on in (("Kp up", c == len(kp) - 1 and len(kp) > 1),
                                        ("Kp down", c == 0 and len(kp) > 1),
                                        ("Kd up", r == len(kd) - 1 and len(kd) > 1),
                                        ("Kd down", r == 0 and len(kd) > 1)) if on]
                if side:
                    edges.append(f"{body}: {', '.join(side)}")
        axes[0].set_ylabel("Kd (N·m·s/rad)")
        if image is not None:
            fig.colorbar(image, ax=list(axes), label=f"{LABELS.get(metric, metric)} (log)")
        if edges:
            fig.supxlabel("★ on the grid's edge, the steadiest gains may lie beyond it: widen the grid ("
                          + "; ".join(edges) + ")", fontsize=9, color="#9a6700")
        fig.pupper_edges = edges  # type: ignore[attr-defined]
        return fig


def write_lab_plots(run_dir: str | os.PathLike) -> list[Path]:
    """`pupper lab`'s figures in ``<run_dir>/plots/``: ``lab_heatmaps.png``
    (Kp × Kd per body, shared colour scale, best starred; blank where a
    cell fell or diverged) and ``lab_best_base_z.png`` (each body's
    base height at its best gains). Reads summary.csv, best.csv, traces.csv."""
    d = Path(run_dir)
    with open(d / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    with open(d / "best.csv", newline="") as f:
        best_rows = list(csv.DictReader(f))
    table, manifest, traces = read_run(d)
    replicated = bool(rows) and "failure_fraction" in rows[0]
    metric = "p95:last_1s_std_mm" if replicated else "last_1s_std_mm"
    bodies = list(dict.fromkeys(r["variant"] for r in rows))
    kp = sorted({float(r["kp"]) for r in rows})
    kd = sorted({float(r["kd"]) for r in rows})
    values: dict[str, np.ndarray] = {b: np.full((len(kd), len(kp)), np.nan) for b in bodies}
    status: dict[str, np.ndarray] = {b: np.full((len(kd), len(kp)), "", dtype=object) for b in bodies}
    for r in rows:
        up = r["failure_fraction"] == "0" if replicated else r["status"] == "ok"
        at = (kd.index(float(r["kd"])), kp.index(float(r["kp"])))
        status[r["variant"]][at] = ("fell" if not up else "ok") if replicated else r["status"]
        if up and r[metric]:
            values[r["variant"]][at] = float(r[metric])
    best: dict[str, tuple[float, float] | None] = {}
    for b in best_rows:
        best[b["variant"]] = (float(b["kp"]), float(b["kd"])) if b["id"] else None
    out = d / "plots"
    out.mkdir(parents=True, exist_ok=True)
    written = []
    fig = lab_heatmaps(bodies, kp, kd, values, best, metric="last_1s_std_mm", status=status)
    head = ("Worst-side 95th percentile over replicates of the last-second base-z std per body"
            if replicated else "Last-second base-z std per body")
    fig.suptitle(f"{head}\n{describe(manifest, len(rows))}", fontsize=11)
    written.append(_save(fig, out / "lab_heatmaps.png"))
    if replicated:
        shares = {**table, "status": ["ok"] * len(rows)}
        fig = heatmap(shares, "failure_fraction", "kp", "kd", by="variant", mark_best=False)
        for a, body in zip(fig.axes, bodies):
            a.set_title(body)
        written.append(_save(fig, out / "lab_failure_fraction.png"))
        fig = replicate_spread(d, "last_1s_std_mm", by="variant")
        if fig is not None:
            fig.suptitle("Each body's best gains: spread over replicates", fontsize=11)
            written.append(_save(fig, out / "lab_spread_last_1s_std_mm.png"))
    chosen = {b["id"]: f"{b['variant']}: Kp {float(b['kp']):g}, Kd {float(b['kd']):g}" for b in best_rows if b["id"]}
    picked = {cid: traces[cid] for cid in chosen if cid in traces}
    if picked:
        # each body about its own mean: the bodies stand 160 and 230 mm
        # tall, and their response to the sine is a twentieth of a millimetre
        landing = float(((manifest.get("config") or {}).get("schedule") or {}).get("landing", 1.0))
        for cid, (t, z) in list(picked.items()):
            t, z = np.asarray(t, float), np.asarray(z, float)
            mean = float(np.mean(z[t >= landing])) if (t >= landing).any() else float(np.mean(z))
            picked[cid] = (t, z - mean)
            chosen[cid] += f" (stands at {mean * 1000:.1f} mm)"
        fig = base_z(picked, push=None, labels=chosen, landing=landing,
                     title="Each body at its best gains: base height about its own mean",
                     ylabel="base z − its mean after landing (mm)")
        written.append(_save(fig, out / "lab_best_base_z.png"))
    return written
