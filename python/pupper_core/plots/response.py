"""The figures of a response run (``pupper_core.plots`` re-exports them):
step responses and Bode plots per joint group, and the heatmaps of rise
time, overshoot and settling time over a Kp x Kd grid."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from pupper_core.plots.grid import heatmap
from pupper_core.plots.style import _new_figure, _save, _say_setting, _style, plain_log_axis
from pupper_core.plots.tables import (
    _col,
    _distinct,
    _is_product,
    _nrows,
    _num,
    _read_csv,
    describe,
    grid_axes,
    read_run,
    run_dir_of,
    RunLike,
)
from pupper_core._types import exported_from

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

GROUP_TITLES = {"haa": "hip abduction (haa)", "hfe": "hip pitch (hfe)", "kfe": "knee (kfe)"}


#: How many settling times of a group's pick a step panel shows.
SETTLING_TIMES_SHOWN = 3.0


def _step_picks(d: Path) -> dict[str, str]:
    """Each joint group's pick: the cell that settles soonest (report.html's rule)."""
    from pupper_core.plots.tables import read_table, response_pick

    header, rows = read_table(d / "summary.csv")
    picks = {}
    for g in ("haa", "hfe", "kfe"):
        r = response_pick(header, rows, g)
        if r is not None:
            picks[g] = r["id"]
    return picks


def _settling(d: Path, cell: str, group: str) -> float:
    row = next((r for r in _read_csv(d / "summary.csv") if r["id"] == cell), {})
    try:
        return float(row.get(f"settling_time_s.{group}", "nan") or "nan")
    except ValueError:
        return math.nan


def step_curves(d: Path, cells: Sequence[str]) -> dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]:
    """Each (cell, joint group)'s angle change over the step, averaged over
    the group's joints and divided by the step, at the physics rate: the
    cells (by id) run again as the manifest says, their every step kept
    (response_traces.csv keeps every ``--trace-every``-th: 20 ms against
    rise times of 10 ms). Time is from the step."""
    from pupper_core import _native

    index = {r["id"]: int(r["index"]) for r in _read_csv(d / "summary.csv")}
    group_of = {r["joint"]: r["group"] for r in _read_csv(d / "response.csv")}
    manifest = _native.read_manifest(str(d))
    amp = float(manifest["config"]["response"]["signal"]["amplitude"])
    wanted = [index[c] for c in cells if c in index]
    per: dict[tuple[str, str], list[tuple[np.ndarray, np.ndarray]]] = {}
    for tr in _native.step_traces(str(d), wanted) if wanted else []:
        g = group_of.get(tr["joint"])
        if g is not None:
            per.setdefault((tr["id"], g), []).append((np.asarray(tr["t"]), np.asarray(tr["angle"])))
    out = {}
    for key, joints in per.items():
        n = min(len(t) for t, _ in joints)
        t = joints[0][0][:n]
        out[key] = (t, np.mean([(a[:n] - a[0]) / amp for _, a in joints], axis=0))
    return out


@exported_from("pupper_core.plots")
def response_steps(run: RunLike, cells: Sequence[str] | None = None) -> "Figure | None":
    """Step responses of a response run (its directory, or its result), a
    panel per joint group: each chosen cell's angle change over the step,
    averaged over the group's joints and divided by the step, against time
    after the step; the group's pick (the cell that settles soonest) bold,
    always drawn; the target (1) dashed and the 2 % settling
    band shaded; the time axis zoomed to three settling times of the pick.
    The curves are at the physics rate: the drawn cells run again (a few
    cells, quick), every step kept. Needs response_traces.csv (`--trace`
    or `--plot`: the run was asked for traces). ``cells``: cell ids
    (default: the picks, then others spread over the grid, 6 in all)."""
    d = run_dir_of(run)
    if not (d / "response_traces.csv").exists():
        return None
    traces = _read_csv(d / "response_traces.csv")
    joints = _read_csv(d / "response.csv")
    group_of = {r["joint"]: r["group"] for r in joints}
    ids = list(dict.fromkeys(r["id"] for r in traces))
    picks = _step_picks(d)
    if cells is None:
        chosen = list(dict.fromkeys(i for i in picks.values() if i in ids))
        rest = [i for i in ids if i not in chosen]
        step = max(1, math.ceil(len(rest) / max(1, 6 - len(chosen))))
        cells = chosen + rest[::step][: max(0, 6 - len(chosen))]
    groups = [g for g in ("haa", "hfe", "kfe") if g in group_of.values()] + sorted(
        {g for g in group_of.values() if g not in ("haa", "hfe", "kfe")})
    # (cell, group) -> (t, angle change / step), every physics step
    curves = step_curves(d, list(cells))
    sample = math.nan
    with _style():
        fig = _new_figure((4.2 * len(groups) + 1.5, 4.2))
        axes = np.atleast_1d(fig.subplots(1, len(groups), sharey=True))
        colours = [f"C{i}" for i in range(len(cells))]
        for ax, g in zip(axes, groups):
            tmax = 0.0
            for c, colour in zip(cells, colours):
                if (c, g) not in curves:
                    continue
                t, rel = curves[(c, g)]
                if len(t) > 1:
                    sample = float(t[1] - t[0])
                picked = picks.get(g) == c
                # the pick in its own colour (the legend's), bold
                ax.plot(t, rel, color=colour, lw=3.2 if picked else 1.1, label=c, zorder=3 if picked else 2)
                tmax = max(tmax, float(t[-1]))
            ax.axhline(1.0, color="black", ls="--", lw=1, label="target")
            ax.axhspan(0.98, 1.02, color="tab:green", alpha=0.15, lw=0, label="±2 % band")
            settle = _settling(d, picks[g], g) if g in picks else math.nan
            zoom = SETTLING_TIMES_SHOWN * settle if settle > 0 else tmax
            ax.set_title(GROUP_TITLES.get(g, g), fontsize=11)
            if g in picks:
                ax.text(0.97, 0.04, f"bold: {picks[g]}, settles soonest", transform=ax.transAxes, ha="right",
                        va="bottom", fontsize=9)
            ax.set_xlabel("time after the step (s)")
            ax.set_xlim(0, min(zoom, tmax) if tmax > 0 else None)
            ax.grid(True, alpha=0.3)
        axes[0].set_ylabel("angle change / step size")
        axes[-1].legend(loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False, fontsize=9)
        fig.pupper_cells = list(cells)
        # the traces' sample spacing (s): the physics step
        fig.pupper_sample_dt = sample
        fig.pupper_picks = dict(picks)
        return fig


@exported_from("pupper_core.plots")
def response_bode(run: RunLike, cells: Sequence[str] | None = None) -> "Figure | None":
    """Bode plot of a sine or chirp response run: gain (dB) and phase (deg)
    against frequency, a column per joint group (the mean over the group's
    joints), a line per chosen cell (default: up to 6 spread over the
    grid); the −3 dB line dotted. ``run``: the run directory, or its result."""
    d = run_dir_of(run)
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
                plain_log_axis(a.xaxis)
                a.grid(True, which="both", alpha=0.3)
        axes[0, 0].set_ylabel("gain (dB)")
        axes[1, 0].set_ylabel("phase (deg)")
        axes[0, -1].legend(loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False, fontsize=9)
        return fig


@exported_from("pupper_core.plots")
def write_response_plots(run_dir: RunLike) -> list[Path]:
    """`pupper response --plot`: into ``<run_dir>/plots/``,
    ``response_steps.png`` (step responses per joint group), ``bode.png``
    (sine, chirp) and, for a Kp x Kd product grid, ``response_<figure>.png``
    heatmaps (rise time, overshoot, settling time; a panel per group).
    ``run_dir``: the run directory, or its result."""
    d = run_dir_of(run_dir)
    out = d / "plots"
    out.mkdir(parents=True, exist_ok=True)
    table, manifest, _ = read_run(d)
    what = describe(manifest, _nrows(table))
    written: list[Path] = []

    def finish(fig: "Figure", name: str, head: str) -> None:
        fig.suptitle(head, fontsize=12)
        _say_setting(fig, what)
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
