"""`pupper response`: how each joint follows its target."""

from __future__ import annotations

import os
from typing import Any, Callable, Mapping, Sequence

from pupper_core import _native
from pupper_core._native import SweepResult
from pupper_core._types import exported_from
from pupper_core._spec import DEFAULTS, KIND_DEFAULTS, parse_sine, sweep_options
from pupper_core._run.progress import progress_printer
from pupper_core._run.runs import with_report


#: This kind's own keywords' defaults (the Rust core's)
OWN = KIND_DEFAULTS["response"]


@exported_from("pupper_core")
def response(
    grid: Mapping[str, Sequence[float] | float | str] | Sequence[str] | str | None = None,
    *,
    signal: str = OWN["signal"],
    amplitude: float = OWN["amplitude"],
    frequency: float | None = OWN["frequency"],
    chirp: Sequence[float] | str | None = OWN["chirp"],
    hold: float = OWN["hold"],
    joints: Sequence[str] | str = OWN["joints"],
    standing: bool = OWN["standing"],
    out: str | os.PathLike[str] | None = None,
    progress: bool | Callable[[int, int], None] = True,
    **options: Any,
) -> SweepResult:
    """How each joint follows its target, as `pupper response` runs it: every
    joint excited alone (its target steps by ``amplitude`` rad, or follows a
    sine of ``frequency`` Hz, or a logarithmic ``chirp`` F0,F1 Hz, after
    ``hold`` s at the stand pose) while the others hold, on the robot hung
    in the air (``standing=True``: on the floor), for every cell of
    ``grid`` in one batch.

    The result's table is summary.csv (each joint group's figures per
    cell); ``res.tables["response"]`` has a row per cell and joint (rise
    and settling time, overshoot, steady-state error; gain, phase,
    bandwidth), ``res.tables["bode"]`` the frequency response of a sine or
    chirp. ``joints``: groups (haa, hfe, kfe) or actuator names. Other
    keywords are `sweep`'s (model, mode, kp, kd, seconds (default 3),
    pose, replicates, threads, ...); see `pupper response --help` for the
    definitions.
    """
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise TypeError(f"response() got unexpected keyword argument(s) {', '.join(unknown)}: "
                        "see help(pupper_core.response)")
    callback = progress_printer("pupper response") if progress is True else (progress or None)
    if isinstance(chirp, str):
        chirp = parse_sine(chirp)
    if isinstance(joints, str):
        joints = [j for j in joints.split(",") if j]
    elif isinstance(joints, Mapping):
        # iterating a dict gives its keys: a typo would pass as a joint list
        raise TypeError(f"joints must be a joint group or actuator name, or a list of them, not a dict "
                        f"({joints!r}): e.g. joints=['kfe'] or joints='haa,hfe'")
    return with_report(_native.response(grid, out=out, progress=callback, signal=signal, amplitude=amplitude,
                            frequency=frequency, chirp=None if chirp is None else list(chirp),
                            hold=hold, joints=list(joints), standing=standing, **sweep_options(options)))
