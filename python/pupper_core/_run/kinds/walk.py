"""`pupper walk`: the robot walks a gait at a commanded velocity."""

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
OWN = KIND_DEFAULTS["walk"]


@exported_from("pupper_core")
def walk(
    grid: Mapping[str, Sequence[float] | float | str] | Sequence[str] | str | None = None,
    *,
    gait: str = OWN["gait"],
    frequency: float = OWN["frequency"],
    speed: float = OWN["speed"],
    sideways: float = OWN["sideways"],
    yaw_rate: float = OWN["yaw_rate"],
    duty: float | None = OWN["duty"],
    step_height: float | None = OWN["step_height"],
    height: float | None = OWN["height"],
    out: str | os.PathLike[str] | None = None,
    progress: bool | Callable[[int, int], None] = True,
    **options: Any,
) -> SweepResult:
    """How well each cell of ``grid`` walks, as `pupper walk` runs it: the
    robot lands (1 s), moves its feet to the gait's stance (0.5 s), then
    walks ``gait`` (trot, walk, pace or bound) at ``frequency`` Hz, its
    commanded velocity (``speed`` forward and ``sideways`` in m/s,
    ``yaw_rate`` in rad/s) ramped up over 1 s, open loop: the feet placed
    by the gait (``duty``: the share of a cycle each foot is down, default
    0.6, 0.75 for walk; ``step_height`` in m, default 6 cm on Pupper's legs
    scaled to the model's), the joint targets from each leg's inverse
    kinematics on the model's own legs, at ``height`` m (default: the start
    pose's). The grid may vary the gains and the gait (frequency, speed,
    duty, step_height).

    The table (summary.csv) has the sweep's metrics per cell and the
    walk's over the steady window (the whole gait cycles from 3.5 s on):
    ``speed_ms``, ``speed_error_pct``, ``drift_ms``, ``yaw_drift_deg_s``,
    ``roll_rms_deg``, ``pitch_rms_deg``, ``height_std_mm``, ``slip_mm_s``,
    ``amplitude_ratio`` and ``lag_ms`` (the joints at the gait frequency),
    ``torque_rms``, ``power_w`` and ``cost_of_transport``; see
    docs/walk.md. ``res.best()`` is the cell that walks closest to the
    commanded velocity among those that stayed up. Other keywords are
    `sweep`'s (model, mode, kp, kd, seconds (default 8), pose, replicates,
    randomize, threads, motor, ...); see `pupper walk --help`.
    """
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise TypeError(f"walk() got unexpected keyword argument(s) {', '.join(unknown)}: "
                        "see help(pupper_core.walk)")
    callback = progress_printer("pupper walk") if progress is True else (progress or None)
    return with_report(_native.walk(grid, out=out, progress=callback, gait=gait, frequency=frequency,
                                     speed=speed, sideways=sideways, yaw_rate=yaw_rate, duty=duty,
                                     step_height=step_height, height=height, **sweep_options(options)))
