"""A sweep's standard figures in its run directory (``pupper_core.plots``
re-exports them), and a hold's, which are a sweep's of its own metrics."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np

from pupper_core._plots_grid import _room_for_title, bars, base_z, heatmap, metric_vs_axis
from pupper_core._plots_replicates import replicate_spread
from pupper_core._plots_style import SHORT, _fmt, _has_dip, _key_line, _save, _say_setting, _wrap_parts, label_of
from pupper_core._plots_tables import (
    RunLike,
    Traces,
    _distinct,
    _is_product,
    _nrows,
    _num,
    _row_label,
    _status,
    describe,
    grid_axes,
    read_run,
    run_dir_of,
)
from pupper_core._public import exported_from
from pupper_core._spec import DEFAULT_METRIC, ROBUST_METRIC

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure



@exported_from("pupper_core.plots")
def write_hold_plots(run_dir: RunLike) -> list[Path]:
    """A hold's plots in ``<run_dir>/plots/``: ``base_z.png`` (the height
    sagging as the load ramps on, the shove shaded), and the sag per newton
    and the sway per cell (a heatmap for a Kp × Kd grid), as
    `write_run_plots` draws a sweep's."""
    return write_run_plots(run_dir, metrics=("compliance_mm_per_n", "sway_mm"), during="the hold")


@exported_from("pupper_core.plots")
def write_run_plots(run_dir: RunLike, metrics: Sequence[str] | None = None,
                    during: str = "the sweep") -> list[Path]:
    """Writes the standard plots of a run into ``<run_dir>/plots/``; returns their paths.

    ``base_z.png`` when traces exist; for a Kp × Kd product grid
    ``heatmap_<metric>.png`` (a panel per value of a third axis), for one
    varying axis ``<metric>_vs_<axis>.png``, for two varying axes other than
    Kp × Kd ``<metric>_vs_<axis1>.png`` grouped by the other, else (presets,
    non-product grids) ``bars_<metric>.png``; metrics last_1s_std_mm and
    push_dip_mm. Files are written atomically.
    """
    d = run_dir_of(run_dir)
    table, manifest, traces = read_run(d)
    out = d / "plots"
    out.mkdir(parents=True, exist_ok=True)
    what = describe(manifest, _nrows(table))
    axes = grid_axes(table)
    varying = [a for a in axes if len(_distinct(_num(table, a))) > 1]
    written: list[Path] = []
    sched = ((manifest.get("config") or {}).get("schedule") or {}) if manifest else {}

    def finish(fig: "Figure", name: str, head: str) -> None:
        fig.suptitle(head, fontsize=12)
        _say_setting(fig, what)
        written.append(_save(fig, out / name))

    if traces:
        fig = _run_base_z(table, traces, sched, varying or axes)
        finish(fig, "base_z.png", f"Base height during {during}" + (
            "\nreplicate 0 of each cell (every replicate's metrics: spread_last_1s_std_mm.png)"
            if "failure_fraction" in table else ""))

    # a metric that is NaN in every cell (push_dip_mm without a push) has nothing to show
    replicated = "failure_fraction" in table
    candidates = (("failure_fraction", ROBUST_METRIC, "p95:push_dip_mm") if replicated
                  else (DEFAULT_METRIC, "push_dip_mm"))
    metrics = [
        m
        for m in (metrics or candidates)
        if m in table and np.isfinite(np.asarray(table[m], dtype=float)).any()
    ]
    if replicated:
        fig = replicate_spread(d, DEFAULT_METRIC)
        if fig is not None:
            finish(fig, "spread_last_1s_std_mm.png", "Spread over replicates at the best cells")
    product = _is_product(table, varying, manifest) if varying else False
    for metric in metrics:
        if product and "kp" in varying and "kd" in varying:
            fig = _run_heatmap(table, metric, varying, replicated)
            _say_setting(fig, what)
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


def _run_base_z(table: Mapping[str, Any], traces: Traces, sched: Mapping[str, Any], axes: list[str]) -> "Figure":
    """Every cell's base height, labelled by its values on ``axes`` and
    its status where that is not ok, the push shaded."""
    labels = {}
    if "id" in table:
        for i, cid in enumerate(table["id"]):
            labels[cid] = _row_label(table, i, axes)
            st = str(table["status"][i]) if "status" in table else "ok"
            if st != "ok":
                labels[cid] += f" — {st}"
    status = ({str(c): str(s) for c, s in zip(table["id"], table["status"])}
              if "id" in table and "status" in table else None)
    return base_z(traces, push=sched.get("push"), labels=labels, status=status,
                  landing=float(sched.get("landing", 1.0)))


def _run_heatmap(table: Mapping[str, Any], metric: str, varying: list[str], replicated: bool) -> "Figure":
    """``metric`` over Kp x Kd, a panel per value of the other varying axes
    (together); the share of failed replicates is coloured in every cell
    and names no best."""
    n = _nrows(table)
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
    key = _key_line("lowest", _status(t2), metric, _has_dip(table, metric))
    if replicated:
        key = key.replace("pink = fell", "pink = some replicates fell or diverged")
    if metric == "failure_fraction":
        key = "0 = every replicate stayed up"
    # both lines wrapped to the figure, a little inside it (wide glyphs): a
    # statistic over replicates names itself at length
    width = 0.9 * fig.get_figwidth()
    heading = f"{_wrap_parts(label_of(metric), width, 12)}\n{_wrap_parts(key, width, 12)}"
    _room_for_title(fig, heading)
    fig.suptitle(heading, fontsize=12)
    return fig
