"""The model's facts, without a run: its sizes and legs (info), its stand,
the gains its joints take, a stand pose."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any, Sequence, cast

if TYPE_CHECKING:
    from typing_extensions import Unpack

from pupper_core import _native
from pupper_core._types import exported_from
from pupper_core._spec import DEFAULTS, Variant, sweep_options, with_spec_signature
from pupper_core._types import ModelInfo, SimOptions, StandReport


@exported_from("pupper_core")
def info(model: str | os.PathLike[str] = "pupper_v3", variant: Variant = "original") -> ModelInfo:
    """Sizes, mass, joints, actuators (ctrl order), keyframes, sensors and
    legs (hip, knee, foot, measured on the compiled body) of a model, or of
    one of its named variants ("long-leg", "heavy")."""
    return _native.info(os.fspath(model), variant)


@exported_from("pupper_core")
@with_spec_signature(SimOptions, after="model")
def stand(model: str | os.PathLike[str] = DEFAULTS["model"], **options: Unpack[SimOptions]) -> StandReport:
    """Reset to a keyframe (or pose), stand with no push; final z, last-second std, tilt.

    Keywords are those of `pupper stand` (`--help` there), same defaults."""
    return _native.stand(**sweep_options({**options, "model": model}))


@exported_from("pupper_core")
def gains(model: str | os.PathLike[str] = "pupper_v3", *, kp: float | None = None, kd: float | None = None,
          bandwidth: float | None = None, damping: float = 0.7,
          pose: Sequence[float] | None = None, integrator: str | None = None,
          motor: str | None = None, sensing_delay: float | None = None) -> dict[str, Any]:
    """Servo gains for a ``bandwidth`` (Hz) and ``damping`` ratio per joint,
    or the natural frequency, damping ratio and stability margin of given
    ``kp`` and ``kd``, from each joint's inertia at ``pose`` (default: the
    stand pose), as `pupper gains --json` prints them. A stability margin
    of 1 or more is past the bound of the PD at the model's timestep as
    ``integrator`` (default: the model's own) takes its damping: the joint
    chatters or diverges there.

    With ``motor`` (a firmware spec as `--motor` takes it, e.g.
    ``"rate=500,filter=100"``) or ``sensing_delay`` (s), each joint and
    group also gets ``phase_margin_deg`` and ``gain_margin_db``: the
    margins of the loop that firmware closes (see `pupper gains --help`);
    below 0 degrees the real joint is unstable."""
    return cast("dict[str, Any]", _native.gains(os.fspath(model), kp=kp, kd=kd, bandwidth=bandwidth,
                                                 damping=damping,
                                                 pose=None if pose is None else [float(q) for q in pose],
                                                 integrator=integrator, motor=motor,
                                                 sensing_delay=sensing_delay))


@exported_from("pupper_core")
def pose(model: str | os.PathLike[str] = "pupper_v3", variant: Variant = "original",
         depth: float | None = None) -> dict[str, Any]:
    """The stand pose of a body, as `pupper pose --json` prints it: each
    leg's joint angles that put its foot ``depth`` m below the hip (default:
    the chapter's 0.14 m scaled to the model's legs)."""
    return cast("dict[str, Any]", _native.pose(os.fspath(model), variant, depth))
