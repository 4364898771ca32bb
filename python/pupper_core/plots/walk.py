"""A walk's plots (``pupper_core.plots`` re-exports them): the speed
achieved against the speed commanded, and a sweep's standard figures of the
walk's own metrics (a heatmap for a Kp x Kd grid, the base height)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pupper_core.plots.grid import metric_vs_axis
from pupper_core.plots.run import write_run_plots
from pupper_core.plots.style import LABELS, _save, _say_setting
from pupper_core.plots.tables import RunLike, _distinct, _num, describe, grid_axes, read_run, run_dir_of
from pupper_core._types import exported_from

# the walk's axes and figures, labelled as every other plot labels its own
LABELS.update({
    "frequency": "gait frequency (Hz)",
    "speed": "commanded speed (m/s)",
    "duty": "duty factor",
    "step_height": "step height (m)",
    "speed_ms": "speed achieved (m/s)",
    "speed_error_pct": "speed error (% of commanded)",
    "pitch_rms_deg": "body pitch RMS (°)",
    "roll_rms_deg": "body roll RMS (°)",
})


@exported_from("pupper_core.plots")
def write_walk_plots(run_dir: RunLike) -> list[Path]:
    """A walk's plots in ``<run_dir>/plots/``: ``speed_vs_commanded.png``
    where the grid varies the speed (a line per setting of the other axes,
    the dashed diagonal perfect tracking), then `write_run_plots`' of
    speed_error_pct and pitch_rms_deg (with replicates their worst side and
    the share that fell), and the base height while walking."""
    d = run_dir_of(run_dir)
    table, manifest, _ = read_run(d)
    replicated = "failure_fraction" in table
    stat = "p95:" if replicated else ""
    written: list[Path] = []
    axes = grid_axes(table)
    if "speed" in axes and f"{stat}speed_ms" in table:
        others = [a for a in axes if a != "speed" and len(_distinct(_num(table, a))) > 1]
        group = others[0] if len(others) == 1 else None
        if len(others) <= 1:
            fig = metric_vs_axis(table, f"{stat}speed_ms", "speed", group, title="")
            ax = fig.axes[0]
            v = _num(table, "speed")
            lo, hi = float(np.nanmin(v)), float(np.nanmax(v))
            ax.plot([lo, hi], [lo, hi], ls="--", color="#555555", lw=1, label="commanded")
            ax.legend(frameon=False, loc="center left", bbox_to_anchor=(1.01, 0.5))
            fig.suptitle("Speed achieved against speed commanded", fontsize=12)
            _say_setting(fig, describe(manifest, len(v)))
            (d / "plots").mkdir(parents=True, exist_ok=True)
            written.append(_save(fig, d / "plots" / "speed_vs_commanded.png"))
    metrics = ("failure_fraction", "p95:speed_error_pct", "p95:pitch_rms_deg") if replicated else (
        "speed_error_pct", "pitch_rms_deg")
    return written + write_run_plots(d, metrics=metrics, during="the walk")
