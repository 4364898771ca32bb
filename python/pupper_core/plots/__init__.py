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

# The figures and readers are written by concern in this package's modules
# (a grid's figures in grid, a run's in run, a response's in response,
# replicates' in replicates, the lab's in lab, a fit's in fit; their look in
# style, their reading in tables): this module re-exports them and keeps the
# registry of each run kind's plot writer.

import os
from pathlib import Path
from typing import Callable

from pupper_core.plots.grid import bars, base_z, heatmap, metric_vs_axis
from pupper_core.plots.lab import lab_heatmaps, write_lab_plots
from pupper_core.plots.replicates import replicate_spread
from pupper_core.plots.response import GROUP_TITLES as GROUP_TITLES
from pupper_core.plots.response import response_bode, response_steps, write_response_plots
from pupper_core.plots.run import write_hold_plots, write_run_plots
from pupper_core.plots.style import DPI as DPI
from pupper_core.plots.style import LABELS as LABELS
from pupper_core.plots.style import MM_RESOLUTION as MM_RESOLUTION
from pupper_core.plots.style import SHORT as SHORT
from pupper_core.plots.style import label_of
from pupper_core.plots.tables import FIRST_METRIC as FIRST_METRIC
from pupper_core.plots.tables import NAMED_AXES as NAMED_AXES
from pupper_core.plots.tables import TEXT_COLUMNS as TEXT_COLUMNS
from pupper_core.plots.tables import Table as Table
from pupper_core.plots.tables import TableLike as TableLike
from pupper_core.plots.tables import Traces as Traces
from pupper_core.plots.tables import describe, grid_axes, read_replicates, read_run
from pupper_core.plots.walk import write_walk_plots

__all__ = ["base_z", "heatmap", "metric_vs_axis", "bars", "read_run", "write_run_plots",
           "grid_axes", "describe", "label_of", "read_replicates", "replicate_spread",
           "response_steps", "response_bode", "write_response_plots",
           "lab_heatmaps", "write_lab_plots", "write_hold_plots", "write_walk_plots", "write_plots"]


def __dir__() -> list[str]:
    """The figures and readers, not numpy, os or sys."""
    return sorted(__all__)


#: The registry of the kinds' plot writers (a sweep's, and any kind not
#: here, the run plots).
WRITERS: dict[str, Callable[[str | os.PathLike], list[Path]]] = {
    "lab": write_lab_plots, "response": write_response_plots, "hold": write_hold_plots, "walk": write_walk_plots}


def write_plots(run_dir: str | os.PathLike) -> list[Path]:
    """Writes the plots of a run's kind (its manifest names it) into
    ``<run_dir>/plots/``; returns their paths."""
    from pupper_core import _native

    manifest = _native.read_manifest(os.fspath(run_dir))
    return WRITERS.get(str(manifest.get("kind")), write_run_plots)(run_dir)
