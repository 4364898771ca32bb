"""`pupper sweep`: a grid of settings as one batched simulation."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Callable, Mapping, Sequence

if TYPE_CHECKING:
    from typing_extensions import Unpack

from pupper_core import _native
from pupper_core._native import SweepResult
from pupper_core._types import exported_from
from pupper_core._spec import sweep_options, with_spec_signature
from pupper_core._types import SweepOptions
from pupper_core._run.progress import progress_printer
from pupper_core._run.runs import with_report


@exported_from("pupper_core")
@with_spec_signature(SweepOptions, after="preset")
def sweep(
    grid: Mapping[str, Sequence[float] | float | str] | Sequence[str] | Sequence[Mapping[str, float | str]]
    | str | None = None,
    *,
    preset: str | None = None,
    out: str | os.PathLike[str] | None = None,
    progress: bool | Callable[[int, int], None] = True,
    **options: Unpack[SweepOptions],
) -> SweepResult:
    """Run a grid of settings as one batched MuJoCo simulation.

    grid: {"kp": [10, 30], "kd": 1} (a value may also be text parsed as the
    CLI parses it: "10,30" or "1:120:16:log"), or the CLI's strings
    ["kp=10,30", "kd=1"] (or one such string), or cells one by one
    [{"kp": 10, "kd": 1}, {"kp": 30, "kd": 0.5, "name": "b"}] (not a product). preset: "chapter-4.6" or
    "lab-grid" (the lab's Kp x Kd grid only) instead of a grid. Every other keyword is the CLI flag of the same
    name, with the same default and checks (`pupper sweep --help`).
    out: also write the run directory (summary.csv, manifest.json, traces.csv)
    as `pupper sweep --out` does; resume=True continues an interrupted one.
    progress: True shows a tqdm bar when tqdm is installed; or a callable
    (done_steps, total_steps). Ctrl-C stops within a second, keeps what is
    finished, and raises KeyboardInterrupt.
    """
    callback = progress_printer("pupper sweep") if progress is True else (progress or None)
    return with_report(_native.sweep(grid, preset=preset, out=out, progress=callback, **sweep_options(options)))
