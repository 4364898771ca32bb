"""What `pupper fit`'s words mean (``pupper_core._fit`` runs the fit): the
fittable parameters with their units and bounds, the limits a log and a
fit keep to, the files a fit writes, and the error bad input gets."""

from __future__ import annotations

from pupper_core._native import ConfigError
from pupper_core._types import exported_from

#: Each fittable quantity: unit, lower bound, upper bound (None: from the nominal).
PARAMS: dict[str, tuple[str, float, float]] = {
    "armature": ("kg·m²", 0.0, 0.05),
    "damping": ("N·m·s/rad", 0.0, 1.0),
    "frictionloss": ("N·m", 0.0, 1.0),
    "kp_scale": ("", 0.2, 5.0),
    "kd_scale": ("", 0.2, 5.0),
    "delay": ("s", 0.0, 0.05),
    "lag": ("s", 0.0, 0.05),
    "latency": ("s", 0.0, 0.05),
    # the motor's torque limit (the actuator's force range, symmetric)
    "torque_limit": ("N·m", 0.1, 20.0),
}
#: The parameters of the servo firmware's loop: a fit that names one replays through the firmware
#: (``--motor``, ideal where not given): the torque's lag behind the PD, and how old the PD's readings are.
FIRMWARE_ONLY = ("lag", "latency")


def lag_matters(lag: float, timestep: float) -> bool:
    """Whether a fitted torque lag is one a simulation should run: at
    least half a physics step. Under it each step's torque is nearly the
    PD's (a noise-free stand with no lag fits 0.1 ms on a 2 ms step)."""
    return lag >= 0.5 * timestep
#: What `fit` fits unless told: the joint's armature, damping and friction, what the servo delivers of its
#: gains, its command delay, its torque's first-order lag and its torque limit. The lag and the limit are
#: the servo's as a real Pupper v3 motor shows them (issue 48: fitted at kp 5, predicting kp 7.5 of the
#: hip and the abduction motor, RMS x0.07 and x0.09 of the nominal model's, phase at 10 Hz within 1 deg;
#: without them x0.18 and x0.12, the abduction motor's phase 6.3 deg off; with the lag alone the hip's
#: 5.1 deg off, its model clamping at the nominal 3 N·m a torque its kp 5 log shows it deliver).
DEFAULT_PARAMS = ("armature", "damping", "frictionloss", "kp_scale", "kd_scale", "delay", "lag", "torque_limit")
#: The defaults before the servo's lag and limit (a fit through MuJoCo's own servo, without the firmware).
SERVO_FREE_PARAMS = ("armature", "damping", "frictionloss", "kp_scale", "kd_scale", "delay")
GROUPS = ("haa", "hfe", "kfe")
PER = ("all", "group", "joint")
#: The custom numeric a calibrated model keeps a gain scale in, per actuator.
SCALE_NUMERIC = "pupper:{kind}:{actuator}"
#: The longest log (s) fit takes and excite writes: an excitation is seconds
#: to a minute; a longer time axis is in other units (ms) or several runs.
MAX_LOG_SECONDS = 600.0
#: The least residual noise the intervals assume, per kind of signal (angle
#: rad, velocity rad/s, torque N·m): finer than any servo reports (a 16-bit
#: encoder alone quantises to 2.8e-5 rad RMS), so a real log is never
#: floored, while a noise-free (simulated) log gets the intervals a
#: near-perfect sensor would, not the simulator's round-off.
NOISE_FLOOR = (1e-5, 1e-3, 1e-4)
#: An angle column that changes by no more than this (rad) never moves.
STILL_RAD = 1e-9
#: A correlation past which two parameters are said to be confounded
#: (damping and kd scale, which angles alone show only as a sum: 0.95).
CONFOUNDED = 0.99
#: A fit may allocate at most this fraction of the machine's memory.
MEMORY_FRACTION = 0.5
#: A fit's peak memory over its rollouts' state and sensors (measured 1.0 to
#: 2.5 times: sysid copies them as it resamples).
MEMORY_COPIES = 2.5
#: The files a fit writes in its run directory (and removes if it stops).
RUN_FILES = ("fit.csv", "residuals.csv", "calibrated.xml", "manifest.json", "warnings.csv", "report.html",
             "validation.csv", "validation_bode.csv", "robots.csv")



@exported_from("pupper_core._fit")
class FitError(ConfigError, ValueError):
    """Bad input to `fit` or `excite`: one line naming the problem and the fix."""

    kind = "config"
