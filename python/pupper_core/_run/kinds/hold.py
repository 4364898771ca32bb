"""`pupper hold`: sag under a load, sway after a shove."""

from __future__ import annotations

import os
from typing import Any, Callable, Mapping, Sequence

from pupper_core import _native
from pupper_core._native import SweepResult
from pupper_core._types import exported_from
from pupper_core._spec import DEFAULTS, KIND_DEFAULTS, sweep_options
from pupper_core._run.progress import progress_printer
from pupper_core._run.runs import with_report


#: This kind's own keywords' defaults (the Rust core's)
OWN = KIND_DEFAULTS["hold"]


@exported_from("pupper_core")
def hold(
    grid: Mapping[str, Sequence[float] | float | str] | Sequence[str] | str | None = None,
    *,
    load: float = OWN["load"],
    ramp: float = OWN["ramp"],
    shove: float = OWN["shove"],
    shove_at: float | None = OWN["shove_at"],
    shove_duration: float = OWN["shove_duration"],
    out: str | os.PathLike[str] | None = None,
    progress: bool | Callable[[int, int], None] = True,
    **options: Any,
) -> SweepResult:
    """How firmly each cell of ``grid`` holds the robot up, as `pupper hold`
    runs it: the robot lands (1 s), a vertical load on its base ramps to
    ``load`` times its own weight (total mass times gravity, from the model)
    over ``ramp`` s and is held; 0.5 s after it is full (or at ``shove_at``)
    a sideways shove of ``shove`` times the weight acts for
    ``shove_duration`` s.

    The table (summary.csv) has the sweep's metrics per cell and the
    hold's: ``sag_mm`` (unloaded minus loaded base height, each the mean
    over 0.5 s), ``compliance_mm_per_n`` (sag per newton; lower is
    stiffer), ``sway_mm`` and ``recovery_s`` (the shove's sideways
    excursion, and the time until the base stays within 5 % of it of where
    it rests), ``torque_rms.GROUP`` (what each joint group spends holding
    the load) and, when the model declares each motor's ``pupper:kt:NAME``
    and ``pupper:resistance:NAME``, ``copper_w``. ``res.best()`` is the
    stiffest cell that stood. Other keywords are `sweep`'s (model, mode,
    kp, kd, seconds (default 7), pose, threads, motor, ...); see `pupper
    hold --help`.
    """
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise TypeError(f"hold() got unexpected keyword argument(s) {', '.join(unknown)}: "
                        "see help(pupper_core.hold)")
    callback = progress_printer("pupper hold") if progress is True else (progress or None)
    return with_report(_native.hold(grid, out=out, progress=callback, load=load, ramp=ramp, shove=shove,
                                     shove_at=shove_at, shove_duration=shove_duration, **sweep_options(options)))
