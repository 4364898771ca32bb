"""`pupper lab`: the chapter's lab, every body from its own stand pose."""

from __future__ import annotations

import os
from typing import Any, Callable, Mapping, Sequence

from pupper_core import _native
from pupper_core._native import SweepResult
from pupper_core._types import exported_from
from pupper_core._spec import Variant, parse_sine
from pupper_core._run.progress import progress_printer
from pupper_core._run.runs import with_report


@exported_from("pupper_core")
def lab(
    variants: Variant | Sequence[Variant] | None = None,
    grid: Mapping[str, Any] | Sequence[str] | str | None = None,
    *,
    out: str | os.PathLike[str] | None = None,
    render: bool = False,
    progress: bool | Callable[[int, int], None] = True,
    **options: Any,
) -> SweepResult:
    """The chapter's lab, as `pupper lab` runs it: every body (default
    original, long-leg, heavy) from a stand pose searched on its own body,
    Kp 10,30,60,120 x Kd 0.5,1,2,5 (or `grid`, CLI strings) in torque mode
    under a 2 N, 1.2 Hz vertical sine force, 6 s, no push, in one batch.

    `res.best(by=["variant"])` gives each body's steadiest gains (by
    last_1s_std_mm, or p95:last_1s_std_mm over replicates). With `out`, the run directory also gets best.csv, the lab's
    figures and (where OpenGL works) the bodies drawn at their best gains;
    `render=True` adds the GIF. Other keywords: seconds, sine, model,
    force, resume, threads, max_saturation, rank, backend, device, ray, motor
    (the servo firmware of the lab's torque-mode PD, as `sweep`'s), depth
    (the feet's depth below the hips in m; default the chapter's 0.14 m scaled
    to the model's legs), and the
    population (replicates, seed, randomize) as `sweep` takes them (defaults as
    `pupper lab --help`).
    """
    callback = progress_printer("pupper lab") if progress is True else (progress or None)
    if isinstance(options.get("sine"), str):
        options["sine"] = parse_sine(options["sine"])
    res = _native.lab(_names(variants), _grid_specs(grid), out=out, progress=callback, **options)
    if res.out is not None:
        from pupper_core.plots.lab import write_lab_plots
        from pupper_core.render import RenderUnavailable, write_lab_effects

        write_lab_plots(res.out)
        try:
            write_lab_effects(res.out, gif=render)
        except RenderUnavailable:
            if render:
                raise
    return with_report(res)


def _names(variants: str | Sequence[str] | None) -> list[str] | None:
    """Body names: one name or several (a string is one name, never its letters)."""
    if variants is None:
        return None
    return [variants] if isinstance(variants, str) else [str(v) for v in variants]


def _grid_specs(grid: Any) -> list[str] | None:
    """The lab's grid as CLI strings, from what `sweep` takes: a dict of
    axis -> values (numbers or text), `AXIS=VALUES` strings, or one."""
    if grid is None:
        return None
    if isinstance(grid, str):
        return [grid]
    if isinstance(grid, Mapping):
        def one(v: Any) -> str:
            if isinstance(v, str) or (isinstance(v, int) and not isinstance(v, bool)):
                return str(v)
            return repr(float(v))  # numpy scalars too: the shortest exact text

        def text(values: Any) -> str:
            if isinstance(values, (str, int, float)):
                return one(values)
            return ",".join(one(v) for v in values)

        return [f"{axis}={text(values)}" for axis, values in grid.items()]
    return [str(g) for g in grid]
