"""`pupper fit` and `pupper excite`: the model calibrated to a robot's joint
logs with MuJoCo's system-identification toolbox (`mujoco.sysid`).

`excite` writes a trajectory to play on the hardware (per joint group a
multisine or chirp around the rest pose, inside the joint ranges and under
velocity and torque limits, with holds between) and the nominal model's
response to it, in the joint-log format (`pupper_core._joint_log`).

`fit` replays each log's targets, at the log's gains, through the robot
hung in the air (the free joint removed, contacts off), and fits joint
armature, damping and friction loss, the servo's kp and kd scales and its
command delay to the logged angles (and torques, where logged) by
`mujoco.sysid`'s bounded Levenberg–Marquardt, every rollout of a Jacobian
in one batch on all cores. Intervals are sysid's Gauss–Newton 95 % ones,
their residual noise floored at NOISE_FLOOR (noise-free logs). What cannot
be trusted is said as a warning: a parameter on a bound, an interval that
is infinite or below 0, confounded parameters, a log made worse, a joint
that never moves (left out); a fit that ends worse than the nominal values
restarts from them, and keeps them if it cannot do better.

Outputs (a run directory): ``fit.csv``, ``calibrated.xml`` (the model with
the fitted values, written through `MjSpec`; every command loads it with
``--model``), ``residuals.csv``, ``manifest.json``, ``warnings.csv`` (when
there are warnings) and, with ``plot``, ``plots/fit_<log>.png`` (measured
against simulated angle per joint, before and after).
"""

from __future__ import annotations

import contextlib
import csv
import ctypes
import hashlib
import io
import json
import math
import os
import shutil
import signal
import sys
import threading
import time
import warnings as _warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core._joint_log import JointLog, LogError, check_gains, read_log, write_log
from pupper_core._native import ConfigError

__all__ = ["fit", "excite", "FitResult", "FitError", "PARAMS"]

#: Each fittable quantity: unit, lower bound, upper bound (None: from the nominal).
PARAMS: dict[str, tuple[str, float, float]] = {
    "armature": ("kg·m²", 0.0, 0.05),
    "damping": ("N·m·s/rad", 0.0, 1.0),
    "frictionloss": ("N·m", 0.0, 1.0),
    "kp_scale": ("", 0.2, 5.0),
    "kd_scale": ("", 0.2, 5.0),
    "delay": ("s", 0.0, 0.05),
}
DEFAULT_PARAMS = ("armature", "damping", "frictionloss", "kp_scale", "kd_scale", "delay")
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
RUN_FILES = ("fit.csv", "residuals.csv", "calibrated.xml", "manifest.json", "warnings.csv", "report.html")


class FitError(ConfigError, ValueError):
    """Bad input to `fit` or `excite`: one line naming the problem and the fix."""

    kind = "config"


def _sysid() -> Any:
    sysid: Any
    try:
        import scipy  # noqa: F401  (sysid's own imports hide a missing one)
        from mujoco import sysid
    except ImportError:
        sysid = None
    if sysid is None or not hasattr(sysid, "optimize"):
        raise FitError("pupper fit needs mujoco.sysid's dependencies: install the extra with "
                       "`make setup PUPPER_EXTRAS=fit` (or pip install 'pupper_core[fit]')")
    import logging

    logging.getLogger("absl").setLevel(logging.ERROR)
    return sysid


# ---------------------------------------------------------------- the robot


#: The built-in models: their file, and whether the base is welded.
BUILTINS = {"pupper_v3": ("pupper_v3/scene.xml", False), "pupper_v3_fixed": ("pupper_v3/pupper_v3.xml", True)}


def _model_file(model: str | os.PathLike[str]) -> tuple[Path, bool]:
    """A model's file, and whether its base is welded to the world (the
    built-in pupper_v3_fixed: the robot file, free joint removed)."""
    p = Path(model)
    if p.is_file():
        return p.resolve(), False
    if str(model) in BUILTINS:
        rel, fixed = BUILTINS[str(model)]
        return Path(__file__).parent / "models" / rel, fixed
    raise FitError(f"model '{model}' is neither an MJCF file nor a built-in model "
                   f"({', '.join(BUILTINS)}): give --model PATH or pupper_v3")


@dataclass
class Robot:
    """What the fit needs of a model: its actuators, their joints, groups,
    ranges, torque limits and nominal joint parameters."""

    file: Path
    actuators: list[str]
    joints: list[str]
    groups: list[str]
    ranges: dict[str, tuple[float, float] | None]
    limits: np.ndarray
    own_kp: np.ndarray
    own_kd: np.ndarray
    armature: np.ndarray
    damping: np.ndarray
    frictionloss: np.ndarray
    rest: np.ndarray
    timestep: float
    #: each joint's inertia at rest (kg·m², armature included)
    inertia: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: the base welded to the world (pupper_v3_fixed): calibrated.xml keeps it so
    fixed_base: bool = False

    def natural_hz(self, kp: np.ndarray) -> np.ndarray:
        """Each joint's natural frequency (Hz) at stiffness ``kp``."""
        return np.asarray(np.sqrt(np.asarray(kp) / self.inertia) / (2 * math.pi))

    def members(self, per: str) -> list[tuple[str, list[int]]]:
        """The parameter sets: (suffix, actuator indices)."""
        if per == "all":
            return [("", list(range(len(self.actuators))))]
        if per == "joint":
            return [(f".{a}", [i]) for i, a in enumerate(self.actuators)]
        out = [(f".{g}", [i for i, x in enumerate(self.groups) if x == g]) for g in GROUPS]
        return [(s, m) for s, m in out if m]


def load_robot(model: str | os.PathLike[str]) -> Robot:
    import mujoco

    import pupper_core as pc

    path, fixed = _model_file(model)
    try:
        m = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as e:
        raise FitError(f"model '{path}' does not compile ({str(e).splitlines()[0]}): fix the MJCF") from None
    info = pc.info(str(path))
    group_of: dict[int, str] = {}
    for leg in info["legs"]:
        for k, leg_joint in enumerate(leg["joints"]):
            group_of[leg_joint] = GROUPS[min(k, 2)]
    acts, joints, groups, ranges, limits = [], [], [], {}, []
    own_kp, own_kd, arm, damp, fric, rest = [], [], [], [], [], []
    key: int | None = next((k for k in range(m.nkey)
                            if mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_KEY, k) == "home"), None)
    for a, ai in enumerate(info["actuators"]):
        j = ai["joint"]
        if j is None:
            raise FitError(f"actuator '{ai['name']}' drives no joint: fit needs joint actuators")
        jid = int(m.actuator_trnid[a, 0])
        acts.append(ai["name"])
        joints.append(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, jid))
        groups.append(group_of.get(j, "joint"))
        lim = m.jnt_range[jid] if m.jnt_limited[jid] else None
        ranges[ai["name"]] = (float(lim[0]), float(lim[1])) if lim is not None else None
        fr = ai["forcerange"]
        limits.append(max(abs(fr[0]), abs(fr[1])) if fr else math.inf)
        g, b = ai["gainprm"], ai["biasprm"]
        own_kp.append(g[0] if b[1] == -g[0] else math.nan)
        own_kd.append(-b[2] if b[1] == -g[0] else math.nan)
        dof = int(m.jnt_dofadr[jid])
        arm.append(float(m.dof_armature[dof]))
        damp.append(float(m.dof_damping[dof]))
        fric.append(float(m.dof_frictionloss[dof]))
        q = float(m.key_ctrl[key, a]) if key is not None and m.nu else float(m.qpos0[m.jnt_qposadr[jid]])
        if lim is not None:
            q = min(max(q, lim[0] + 0.1), lim[1] - 0.1)
        rest.append(q)
    return Robot(path, acts, joints, groups, ranges, np.array(limits), np.array(own_kp),
                 np.array(own_kd), np.array(arm), np.array(damp), np.array(fric), np.array(rest),
                 float(m.opt.timestep), _inertia(m, joints, rest), fixed)


def _inertia(m: Any, joints: list[str], rest: list[float]) -> np.ndarray:
    """Each joint's own inertia at the rest pose: its diagonal of the mass
    matrix (the same whether the base is free or welded)."""
    import mujoco

    d = mujoco.MjData(m)
    ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in joints]
    for jid, q in zip(ids, rest):
        d.qpos[m.jnt_qposadr[jid]] = q
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    return np.array([max(float(full[m.jnt_dofadr[j], m.jnt_dofadr[j]]), 1e-12) for j in ids])


def _history_samples(robot: Robot) -> int:
    return int(math.ceil(PARAMS["delay"][2] / robot.timestep)) + 3


def suspended_spec(robot: Robot, kp: np.ndarray, kd: np.ndarray) -> Any:
    """The robot hung in the air at the given gains, sensing each actuated
    joint's angle, velocity and actuator force (sensors in that order)."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(robot.file))
    for j in list(spec.joints):
        if j.type == mujoco.mjtJoint.mjJNT_FREE:
            spec.delete(j)
    for k in list(spec.keys):
        spec.delete(k)
    for s in list(spec.sensors):
        spec.delete(s)
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    n = _history_samples(robot)
    for i, name in enumerate(robot.actuators):
        act = spec.actuator(name)
        act.gainprm[0] = kp[i]
        act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        act.biasprm[0] = 0.0
        act.biasprm[1] = -kp[i]
        act.biasprm[2] = -kd[i]
        act.nsample = n
        act.interp = 1
    for kind, obj in ((mujoco.mjtSensor.mjSENS_JOINTPOS, "joint"), (mujoco.mjtSensor.mjSENS_JOINTVEL, "joint"),
                      (mujoco.mjtSensor.mjSENS_ACTUATORFRC, "actuator")):
        for i, name in enumerate(robot.actuators):
            target = robot.joints[i] if obj == "joint" else name
            spec.add_sensor(name=f"pupper_{kind.name}_{name}", type=kind,
                            objtype=mujoco.mjtObj.mjOBJ_JOINT if obj == "joint" else mujoco.mjtObj.mjOBJ_ACTUATOR,
                            objname=target)
    return spec


def initial_state(model: Any, robot: Robot, q0: np.ndarray, qd0: np.ndarray, target0: np.ndarray) -> np.ndarray:
    """The full physics state at a log's start: its angles and velocities,
    and a command history that has held the first target."""
    import mujoco

    d = mujoco.MjData(model)
    for i, j in enumerate(robot.joints):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)
        d.qpos[model.jnt_qposadr[jid]] = q0[i]
        d.qvel[model.jnt_dofadr[jid]] = qd0[i]
    d.ctrl[:] = target0
    for a in range(model.nu):
        n = int(model.actuator_history[a, 0])
        if n:
            mujoco.mj_initCtrlHistory(model, d, a, None, np.full((n, 1), float(target0[a])))
    state = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, d, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return state


def simulate(spec: Any, robot: Robot, times: np.ndarray, targets: np.ndarray,
             q0: np.ndarray | None = None, settle: float = 1.0) -> np.ndarray:
    """Angles, velocities and torques (samples, 3 nu) of the targets played
    through `spec`, after ``settle`` seconds held at the first target
    (started there, or at ``q0``)."""
    import mujoco
    from mujoco import rollout

    m = spec.compile()
    dt = float(np.median(np.diff(times)))
    if abs(dt - m.opt.timestep) > 1e-9:
        m.opt.timestep = dt
    x0 = initial_state(m, robot, targets[0] if q0 is None else q0, np.zeros(m.nu), targets[0])
    if settle > 0:
        # the robot has rested at the first target before the log starts
        hold = np.tile(targets[0], (round(settle / dt), 1))
        state, _ = rollout.rollout(m, mujoco.MjData(m), x0, hold)
        x0 = np.asarray(state[0, -1])
    _, sens = rollout.rollout(m, mujoco.MjData(m), x0, targets)
    return np.asarray(sens[0])


# ------------------------------------------------------------------- excite


def _multisine(t: np.ndarray, band: tuple[float, float], count: int, rng: np.random.Generator) -> np.ndarray:
    f = np.geomspace(band[0], band[1], count)
    # Schroeder-like phases keep the crest factor low; a random offset per joint
    k = np.arange(1, count + 1)
    phase = -np.pi * k * (k - 1) / count + rng.uniform(0, 2 * np.pi)
    s = np.sin(2 * np.pi * f[:, None] * t[None, :] + phase[:, None]).sum(0)
    return np.asarray(s / np.max(np.abs(s)))


def _chirp(t: np.ndarray, band: tuple[float, float]) -> np.ndarray:
    f0, f1 = band
    span = t[-1] if t[-1] > 0 else 1.0
    r = (f1 / f0) ** (1 / span)
    return np.asarray(np.sin(2 * np.pi * f0 * (r ** t - 1) / math.log(r)))


# ------------------------------------------------------------------ signals


@contextlib.contextmanager
def _stop_on_signals(what: str) -> Iterator[None]:
    """SIGINT and SIGTERM stop ``what`` with KeyboardInterrupt, as Ctrl-C
    stops Python, and the handlers from before are put back after. (The CLI's
    own handler only sets a flag its Rust loops read, which a fit never
    does; off the main thread Python cannot take a signal, and this does
    nothing.)"""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(f"{what} stopped by {signal.Signals(signum).name}: nothing written")

    saved = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        # the kernel's action too: a handler installed outside Python (the
        # CLI's) shows in Python as SIG_DFL or None, and only this puts it back
        raw = _raw_action(sig)
        saved.append((sig, signal.signal(sig, stop), raw))
    try:
        yield
    finally:
        for sig, previous, raw in reversed(saved):
            if callable(previous) or raw is None:
                signal.signal(sig, previous if previous is not None else signal.SIG_DFL)
            else:
                _libc().sigaction(int(sig), raw, None)


def _libc() -> Any:
    return ctypes.CDLL(None, use_errno=True)


def _raw_action(sig: int) -> Any:
    """The current sigaction of ``sig`` as bytes (a buffer larger than any
    platform's struct), or None where there is no libc to ask."""
    try:
        buf = ctypes.create_string_buffer(1024)
        return buf if _libc().sigaction(int(sig), None, buf) == 0 else None
    except (OSError, AttributeError):
        return None


# ------------------------------------------------------------------- excite


def excite(model: str | os.PathLike[str] = "pupper_v3", *, out: str | os.PathLike[str] = "excite.csv",
           kp: float | None = None, kd: float | None = None, seconds: float = 8.0, hold: float = 1.0,
           amplitude: float = 0.3, signal: str = "multisine", band: Sequence[float] = (0.3, 6.0),
           max_velocity: float = 8.0, seed: int = 0, force: bool = False) -> Path:
    """Writes an excitation to play on the robot and the nominal model's
    response to it, in the joint-log format; returns the file's path. Gains
    past the explicit PD's stability bound are said as a warning."""
    path, notes = _excite(model, out=out, kp=kp, kd=kd, seconds=seconds, hold=hold, amplitude=amplitude,
                          signal=signal, band=band, max_velocity=max_velocity, seed=seed, force=force)
    for note in notes:
        _warnings.warn(note, stacklevel=2)
    return path


def _excite(model: str | os.PathLike[str], *, out: str | os.PathLike[str], kp: float | None, kd: float | None,
            seconds: float, hold: float, amplitude: float, signal: str, band: Sequence[float],
            max_velocity: float, seed: int, force: bool) -> tuple[Path, list[str]]:
    """`excite`, and its notes."""
    robot = load_robot(model)
    out = _excite_out(out, force)
    lo, hi = _excite_options(robot, signal, band, seconds, hold, amplitude, max_velocity)
    gains_kp, gains_kd = _excite_gains(robot, kp, kd)
    notes = _stability_notes(robot, gains_kp, gains_kd)
    with _stop_on_signals("excite"):
        times, targets = _excite_targets(robot, gains_kp, signal, (lo, hi), seconds, hold, amplitude,
                                         max_velocity, seed)
        spec = suspended_spec(robot, gains_kp, gains_kd)
        sens = simulate(spec, robot, times, targets)
        if not np.all(np.isfinite(sens)):
            raise FitError(f"the model diverges at kp {gains_kp.max():g}, kd {gains_kd.max():g}: its response "
                           "is not finite; lower the gains (pupper gains --kp KP --kd KD shows the bound)")
        nu = len(robot.actuators)
        write_log(out, times, robot.actuators, target=targets, q=sens[:, :nu], qd=sens[:, nu:2 * nu],
                  tau=sens[:, 2 * nu:], kp=gains_kp, kd=gains_kd,
                  note=f"pupper excite {signal} {lo:g}-{hi:g} Hz; q, qd, tau: the nominal model's response")
    return out, notes


def _excite_out(out: str | os.PathLike[str], force: bool) -> Path:
    path = Path(out)
    if path.is_dir():
        raise FitError(f"--out {path} is a directory: give a file path (e.g. {path / 'excite.csv'})")
    if path.exists() and not force:
        raise FitError(f"{path} exists: give another --out, or --force to overwrite it")
    parent = path.parent
    if not parent.is_dir():
        raise FitError(f"--out {path}: its directory {parent} does not exist: create it "
                       f"(mkdir -p {parent}) or give another --out")
    return path


def _number(name: str, v: Any) -> float:
    """A flag's number; the CLI passes NaN and infinity as null."""
    if v is None or not isinstance(v, (int, float)) or not math.isfinite(v):
        # the CLI passes NaN and infinity alike, as null
        raise FitError(f"--{name} {'(nan or inf)' if v is None else v} is not a finite number: give e.g. "
                       f"--{name} {dict(seconds=8, hold=1, amplitude=0.3, band='0.3,6').get(name, 8)}")
    return float(v)


def _excite_options(robot: Robot, signal: str, band: Sequence[float], seconds: float, hold: float,
                    amplitude: float, max_velocity: float) -> tuple[float, float]:
    """Checks excite's options; returns the band."""
    if signal not in ("multisine", "chirp"):
        raise FitError(f"--signal {signal} is unknown: use multisine or chirp")
    lo, hi = (_number("band", b) for b in band)
    if not (0 < lo < hi < 0.5 / robot.timestep / 4):
        raise FitError(f"--band {lo:g},{hi:g} Hz is not 0 < F0 < F1 below a quarter of the "
                       f"Nyquist rate ({0.125 / robot.timestep:g} Hz): give e.g. 0.3,6")
    for name, v in (("seconds", seconds), ("amplitude", amplitude), ("max-velocity", max_velocity)):
        if not _number(name, v) > 0:
            raise FitError(f"--{name} {v} must be > 0")
    if not _number("hold", hold) >= 0:
        raise FitError(f"--hold {hold} must be >= 0")
    groups = len([g for g in GROUPS if g in robot.groups] or ["joint"])
    total = hold + groups * (seconds + hold)
    if total > MAX_LOG_SECONDS:
        most = max((MAX_LOG_SECONDS - hold) / groups - hold, 0.0)
        raise FitError(f"--seconds {seconds:g} --hold {hold:g} make a {total:.4g} s log ({groups} joint "
                       f"groups), past the {MAX_LOG_SECONDS:g} s fit takes: give --seconds of at most "
                       f"{math.floor(most * 10) / 10:g} (8 is the default)")
    return lo, hi


def _excite_gains(robot: Robot, kp: float | None, kd: float | None) -> tuple[np.ndarray, np.ndarray]:
    """The gains to excite at: --kp/--kd, else the model's own."""
    n = len(robot.actuators)
    for key, v in (("kp", kp), ("kd", kd)):
        if v is not None:
            try:
                check_gains([float(v)], key, f"--{key} {v:g}", "")
            except LogError as e:
                raise FitError(str(e)) from None
    gains_kp = np.full(n, float(kp)) if kp is not None else robot.own_kp
    gains_kd = np.full(n, float(kd)) if kd is not None else robot.own_kd
    if np.isnan(gains_kp).any() or np.isnan(gains_kd).any() or (gains_kp <= 0).any() or (gains_kd < 0).any():
        raise FitError("the model's actuators have no PD gains of their own: give --kp and --kd")
    return gains_kp, gains_kd


def _stability_notes(robot: Robot, kp: np.ndarray, kd: np.ndarray) -> list[str]:
    """A note when the gains lie past the stability bound of an explicitly
    integrated PD at the timestep (pupper gains' margin, 1 or more)."""
    from pupper_core import _native

    g = _native.gains(str(robot.file), kp=float(kp.max()), kd=float(kd.max()), bandwidth=None,
                      damping=0.7, pose=None)
    worst = max(g.get("joints", []), key=lambda j: float(j.get("stability_margin", 0.0)), default=None)
    if worst is None or not float(worst["stability_margin"]) >= 1:
        return []
    return [f"kp {kp.max():g}, kd {kd.max():g} lie past the stability bound of an explicitly integrated PD "
            f"at the timestep (worst: {worst['actuator']}, margin {float(worst['stability_margin']):.3g}): "
            "the nominal response in the log may chatter at the torque limit or diverge; "
            f"`pupper gains --kp {kp.max():g} --kd {kd.max():g}` shows the bound per joint"]


def _excite_targets(robot: Robot, gains_kp: np.ndarray, signal: str, band: tuple[float, float], seconds: float,
                    hold: float, amplitude: float, max_velocity: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The excitation's times and targets: per joint group a multisine or
    chirp inside the ranges and the speed and torque limits, with holds."""
    dt = robot.timestep
    rng = np.random.default_rng(seed)
    groups = [g for g in GROUPS if g in robot.groups] or ["joint"]
    n_seg = int(round(seconds / dt))
    n_hold = int(round(hold / dt))
    total = n_hold + len(groups) * (n_seg + n_hold)
    times = np.arange(total + 1) * dt
    targets = np.tile(robot.rest, (total + 1, 1))
    ts = np.arange(n_seg) * dt
    taper = np.minimum(1.0, np.minimum(ts, ts[-1] - ts) / 0.5) if n_seg > 1 else np.ones(1)
    taper = 0.5 - 0.5 * np.cos(np.pi * taper)
    for gi, g in enumerate(groups):
        start = n_hold + gi * (n_seg + n_hold)
        for a in (i for i, x in enumerate(robot.groups) if x == g or g == "joint"):
            s = (_multisine(ts, band, 8, rng) if signal == "multisine" else _chirp(ts, band)) * taper
            speed = np.max(np.abs(np.diff(s))) / dt
            amp = min(amplitude, max_velocity / max(speed, 1e-9))
            rng_a = robot.ranges[robot.actuators[a]]
            if rng_a is not None:
                amp = min(amp, robot.rest[a] - rng_a[0] - 0.05, rng_a[1] - robot.rest[a] - 0.05)
            if gains_kp[a] > 0 and math.isfinite(robot.limits[a]):
                # the PD's stiffness alone may ask 80 % of the motor's torque
                amp = min(amp, 0.8 * robot.limits[a] / gains_kp[a])
            targets[start:start + n_seg, a] = robot.rest[a] + max(amp, 0.0) * s
    return times, targets


# ---------------------------------------------------------------------- fit


@dataclass
class FitResult:
    """What `fit` found: ``table`` is fit.csv's rows; ``rms_before`` and
    ``rms_after`` the RMS angle error (rad) of each log, per actuator."""

    table: list[dict[str, Any]]
    rms_before: dict[str, list[float]]
    rms_after: dict[str, list[float]]
    out: Path | None
    seconds: float
    warnings: list[str] = field(default_factory=list)
    #: the actuators fitted (a joint that never moves is left out)
    actuators: list[str] = field(default_factory=list)
    #: the intervals assume NOISE_FLOOR: the residual was below it (noise-free logs)
    floored: bool = False

    def value(self, name: str) -> float:
        return next(float(r["fitted"]) for r in self.table if r["parameter"] == name)

    def interval(self, name: str) -> tuple[float, float]:
        r = next(r for r in self.table if r["parameter"] == name)
        return float(r["low95"]), float(r["high95"])


def _parse_params(params: str | Sequence[str]) -> list[str]:
    names = [p.strip() for p in (params.split(",") if isinstance(params, str) else params) if p.strip()]
    if not names:
        raise FitError("--params is empty: name some of " + ", ".join(PARAMS))
    for n in names:
        if n not in PARAMS:
            raise FitError(f"--params names '{n}', which fit does not know: use any of {', '.join(PARAMS)}")
    if len(set(names)) != len(names):
        raise FitError("--params names a parameter twice: keep one")
    return names


def fit(logs: Sequence[str | os.PathLike[str]], *, model: str | os.PathLike[str] = "pupper_v3",
        params: str | Sequence[str] = DEFAULT_PARAMS, per: str = "all", out: str | os.PathLike[str] | None = None,
        force: bool = False, max_iters: int = 50, plot: bool = False, progress: bool = True) -> FitResult:
    """Fits ``params`` (per ``all`` actuators, joint ``group`` or ``joint``)
    to the joint ``logs`` and, with ``out``, writes the run directory.
    SIGINT and SIGTERM stop it (KeyboardInterrupt) with nothing written."""
    names = _parse_params(params)
    if per not in PER:
        raise FitError(f"--per {per} is unknown: use all, group or joint")
    if not logs:
        raise FitError("no log given: pupper fit LOG.csv [LOG.csv ...] (pupper excite writes one)")
    if max_iters < 1:
        raise FitError("--max-iters must be >= 1")
    out_dir = Path(out) if out is not None else None
    if out_dir is not None and out_dir.exists() and not out_dir.is_dir():
        raise FitError(f"--out {out_dir} is a file: give a directory for the run (e.g. runs/fit)")
    if out_dir is not None and out_dir.exists() and any(out_dir.iterdir()) and not force:
        raise FitError(f"{out_dir} exists and is not empty: give another --out, or --force")
    with _stop_on_signals("fit"):
        robot = load_robot(model)
        read = _read_logs(logs, robot)
        _check_memory(read, robot, len(names) * len(robot.members(per)))
        sysid = _sysid()
        started = time.perf_counter()
        # sysid's linear algebra on a degenerate problem divides by zero: the
        # outcome is checked and said below, numpy's warnings would only leak
        with np.errstate(all="ignore"):
            pb = _problem(sysid, robot, read, names, per)
            sol = _solve(sysid, pb, max_iters)
        result = _result(pb, sol, out_dir, time.perf_counter() - started)
        if out_dir is not None:
            _write_run(out_dir, result, pb, sol, model, names, per, force, plot)
    return result


def _read_logs(paths: Sequence[str | os.PathLike[str]], robot: Robot) -> list[JointLog]:
    """Reads and checks every log, and refuses the same log given twice."""
    read: list[JointLog] = []
    for p in paths:
        try:
            lg = read_log(Path(p), robot.ranges)
        except LogError as e:
            raise FitError(str(e)) from None
        _check_log(lg, robot)
        twin = next((x for x in read if x.sha256 == lg.sha256), None)
        if twin is not None:
            # a copy adds no information, yet would narrow every interval
            raise FitError(f"{lg.path} has the same content as {twin.path} (sha256 {lg.sha256[:12]}): "
                           "give each log once")
        read.append(lg)
    return read


def _check_log(lg: JointLog, robot: Robot) -> None:
    missing = [a for a in robot.actuators if a not in lg.actuators]
    if missing:
        raise FitError(f"{lg.path}: column '{missing[0]}.target' is missing: a log must cover "
                       f"every actuator of the model ({len(robot.actuators)})")
    if lg.base != "suspended":
        raise FitError(f"{lg.path}: '# base: {lg.base}': fit replays logs of the robot hung in "
                       "the air (base: suspended); standing logs are not supported yet")
    if lg.duration <= PARAMS["delay"][2] * 4:
        raise FitError(f"{lg.path}: the log spans {lg.duration:g} s, too short for the delay "
                       f"range (0 to {PARAMS['delay'][2]:g} s): log at least a few seconds")
    dts = np.diff(lg.times)
    if np.max(np.abs(dts - dts.mean())) > 1e-6 * max(dts.mean(), 1e-9) + 1e-9:
        raise FitError(f"{lg.path}: samples are not evenly spaced in time: resample the log "
                       "to a fixed rate")
    spacing = float(dts.mean())
    # samples a second or more apart, which in ms would be a servo's rate
    ms = (f" (its samples are {spacing:g} apart: the time column looks like milliseconds; divide it "
          "by 1000)") if 1e-4 <= spacing / 1000 <= 0.1 and spacing >= 0.5 else ""
    if lg.duration > MAX_LOG_SECONDS:
        raise FitError(f"{lg.path}: the log spans {lg.duration:.4g} s, past the {MAX_LOG_SECONDS:g} s "
                       f"fit takes{ms}: times are in s; split a longer recording")
    order = _order(lg, robot)
    hz = robot.natural_hz(lg.kp[order])
    k = int(np.argmax(hz))
    if 1 / spacing < 2 * hz[k]:
        # the samples cannot show a motion faster than half their rate
        raise FitError(f"{lg.path}: sampled at {1 / spacing:.3g} Hz, too slow for the joints' dynamics{ms}: "
                       f"at the log's kp {lg.kp[order][k]:g} {robot.actuators[k]} swings at {hz[k]:.3g} Hz, "
                       f"past half the sample rate; log at {10 * hz[k]:.0f} Hz or more")


def _memory_limit() -> float:
    """The bytes a fit may allocate: a fraction of the machine's memory."""
    try:
        total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        total = 16 * 2**30
    return MEMORY_FRACTION * float(total)


def _check_memory(read: list[JointLog], robot: Robot, n_params: int) -> None:
    """Refuses a fit whose rollouts would not fit in memory, before any is
    allocated: every Jacobian rolls each log out once per parameter and once
    more, keeping the full state and the sensors of every physics step, and
    sysid copies them (MEMORY_COPIES)."""
    import mujoco

    m = suspended_spec(robot, read[0].kp, read[0].kd).compile()
    per_step = 8 * (mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS) + m.nsensordata)
    steps = sum(lg.duration / min(robot.timestep, float(np.mean(np.diff(lg.times)))) + 1 for lg in read)
    need = per_step * steps * (n_params + 1) * MEMORY_COPIES
    limit = _memory_limit()
    if need > limit:
        raise FitError(f"the fit would allocate about {_size(need)} ({len(read)} log(s), {steps:,.0f} physics "
                       f"steps, {n_params + 1} rollouts of each per Jacobian), past {_size(limit)} "
                       f"({MEMORY_FRACTION:.0%} of this machine's memory): fit fewer or shorter logs at once, "
                       "or fewer parameters (--params, --per all)")


def _size(n: float) -> str:
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 else f"{n / 2**20:.0f} MiB"


@dataclass
class _Problem:
    """A fit set up: the logs as sysid sequences, what is fitted, the
    parameters at their nominal values and what was left out (said)."""

    robot: Robot
    logs: list[JointLog]
    sequences: list[Any]
    pdict: Any
    labels: list[tuple[str, str, list[int], float]]
    x_nominal: np.ndarray
    #: the enabled sensors, as indices into (angles, velocities, torques) x actuators
    sensors: list[int]
    gains: dict[int, tuple[np.ndarray, np.ndarray]]
    warnings: list[str] = field(default_factory=list)

    @property
    def kept(self) -> list[int]:
        """The actuators whose angle is fitted."""
        nu = len(self.robot.actuators)
        return [s for s in self.sensors if s < nu]


def _problem(sysid: Any, robot: Robot, read: list[JointLog], names: list[str], per: str) -> _Problem:
    nu = len(robot.actuators)
    has_tau = all(lg.tau is not None for lg in read)
    has_qd = all(lg.qd is not None for lg in read)
    sensors, warnings = _enabled_sensors(robot, read, has_qd, has_tau)
    # one spec per gain setting: its actuators run at the logged gains
    specs: dict[tuple[bytes, bytes], Any] = {}
    gains: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    sequences = []
    for li, lg in enumerate(read):
        order = _order(lg, robot)
        kp, kd = lg.kp[order], lg.kd[order]
        key = (kp.tobytes(), kd.tobytes())
        if key not in specs:
            spec = suspended_spec(robot, kp, kd)
            specs[key] = spec
            gains[id(spec)] = (kp, kd)
        spec = specs[key]
        # the model steps at its own timestep; sysid resamples the logged
        # targets to it and the predictions to the log's times
        m = spec.compile()
        t = lg.times - lg.times[0]
        target = lg.target[:, order]
        q = lg.q[:, order]
        cols = [q, lg.qd[:, order] if lg.qd is not None and has_qd else np.zeros_like(q),
                lg.tau[:, order] if lg.tau is not None and has_tau else np.zeros_like(q)]
        y = np.hstack(cols)
        # the start: where the robot rests when the log begins on a hold
        # (the mean of its first samples, less noise than one)
        held = int(np.argmax(np.any(target != target[0], axis=1))) or len(target)
        n0 = max(1, min(held, round(0.01 / float(np.mean(np.diff(t))))))
        q0 = q[:n0].mean(axis=0) if held >= n0 and not has_qd else q[0]
        qd0 = cols[1][0] if has_qd else np.zeros(nu)
        x0 = initial_state(m, robot, q0, qd0, target[0])
        control = sysid.TimeSeries.from_control_names(*_held(t, target, m.opt.timestep), m)
        measured = sysid.TimeSeries.from_names(t, y, m)
        sequences.append(sysid.ModelSequences(f"log{li}", spec, lg.path.stem, x0, control, measured))
    kept = {s for s in sensors if s < nu}
    pdict, labels, x_nominal = _parameters(sysid, robot, names, per, gains, kept, warnings)
    return _Problem(robot, read, sequences, pdict, labels, x_nominal, sensors, gains, warnings)


def _order(lg: JointLog, robot: Robot) -> list[int]:
    """A log's columns in the model's actuator order."""
    return [lg.actuators.index(a) for a in robot.actuators]


def _enabled_sensors(robot: Robot, read: list[JointLog], has_qd: bool,
                     has_tau: bool) -> tuple[list[int], list[str]]:
    """The signals the fit compares: a joint whose angle never moves shows
    nothing (and sysid, which divides each signal by its size, would divide
    by zero), so it is left out, as is a velocity or torque column that is
    all zero; each is said. Refuses a fit with nothing left."""
    nu = len(robot.actuators)
    warnings: list[str] = []
    still: dict[int, JointLog] = {}
    for lg in read:
        for k, c in enumerate(_order(lg, robot)):
            if k not in still and float(np.ptp(lg.q[:, c])) <= STILL_RAD:
                still[k] = lg
    for k, lg in sorted(still.items()):
        warnings.append(f"{robot.actuators[k]} never moves in {lg.path.name} (its angle stays at "
                        f"{lg.q[0, _order(lg, robot)[k]]:.6g} rad): left out of the fit")
    if len(still) == nu:
        raise FitError(f"no joint moves in {', '.join(sorted({lg.path.name for lg in still.values()}))} "
                       "(every angle column is constant): nothing to fit; log a run where the joints "
                       "move (pupper excite writes its targets)")
    sensors = [k for k in range(nu) if k not in still]
    for block, fld, on in ((1, "qd", has_qd), (2, "tau", has_tau)):
        for k in (k for k in range(nu) if on and k not in still):
            zero = next((lg for lg in read if not np.any(getattr(lg, fld)[:, _order(lg, robot)[k]])), None)
            if zero is not None:
                warnings.append(f"{zero.path.name}: column '{robot.actuators[k]}.{fld}' is all zero: left "
                                "out of the fit (drop the column if the servo does not report it)")
            else:
                sensors.append(block * nu + k)
    return sensors, warnings


def _parameters(sysid: Any, robot: Robot, names: list[str], per: str, gains: dict[int, tuple[np.ndarray, np.ndarray]],
                kept: set[int], warnings: list[str]) -> tuple[Any, list[tuple[str, str, list[int], float]], np.ndarray]:
    """The parameters at their nominal values (the vector returned, before
    sysid moves those on a bound inside for its start)."""
    pdict = sysid.ParameterDict()
    nominal = {"armature": robot.armature, "damping": robot.damping, "frictionloss": robot.frictionloss}
    labels: list[tuple[str, str, list[int], float]] = []
    for kind in names:
        for suffix, members in robot.members(per):
            if not kept.intersection(members):
                warnings.append(f"{kind + suffix} is not fitted: none of its joints moves")
                continue
            if kind in nominal:
                values = nominal[kind][members]
                nom = float(values[0]) if np.all(values == values[0]) else float(np.mean(values))
            else:
                nom = 1.0 if "scale" in kind else 0.0
            _, lo, hi = PARAMS[kind]
            modifier = _modifier(kind, members, robot, gains)
            pdict.add(sysid.Parameter(kind + suffix, nom, lo, max(hi, 4 * nom), modifier=modifier))
            labels.append((kind + suffix, kind, members, nom))
    x_nominal = pdict.as_vector().copy()
    pdict.move_off_bounds()
    return pdict, labels, x_nominal


@dataclass
class _Solution:
    """Where the fit ended: the values, the interval half-widths (NaN where
    not meaningful), the correlations, the RMS angle errors."""

    x: np.ndarray
    half: np.ndarray
    corr: np.ndarray | None
    residual_fn: Any
    params: Any
    before: list[list[float]]
    after: list[list[float]]
    floored: bool
    warnings: list[str]


def _solve(sysid: Any, pb: _Problem, max_iters: int) -> _Solution:
    nu = len(pb.robot.actuators)
    enabled = [(s.name, sysid.SignalType.MjSensor) for s in pb.sequences[0].spec.sensors
               if [x.name for x in pb.sequences[0].spec.sensors].index(s.name) in pb.sensors]
    residual_fn = _residual_fn(sysid, pb.sequences, enabled, None)
    _check_finite(residual_fn, pb)
    before = _rms(residual_fn, pb.pdict, pb.x_nominal, pb.sensors, nu)
    sink = io.StringIO()
    opt, res = _optimize(sysid, pb.pdict, residual_fn, max_iters, sink)
    weights = None
    if any(s >= nu for s in pb.sensors):
        # whiten: each kind of signal by its own noise, so the pooled
        # variance of the intervals means something
        weights = _whitening(residual_fn, opt, nu, pb.sensors)
        residual_fn = _residual_fn(sysid, pb.sequences, enabled, weights)
        opt, res = _optimize(sysid, opt, residual_fn, max_iters, sink)
    warnings: list[str] = []
    opt, res = _no_worse_than_nominal(sysid, pb, residual_fn, opt, res, max_iters, sink, warnings)
    x = opt.as_vector()
    half, corr, floored = _intervals(sysid, pb, residual_fn, opt, res, weights)
    after = before if res is None else _rms(residual_fn, opt, x, pb.sensors, nu)
    return _Solution(x, half, corr, residual_fn, opt, before, after, floored, warnings)


def _optimize(sysid: Any, start: Any, residual_fn: Any, max_iters: int, sink: io.StringIO) -> tuple[Any, Any]:
    try:
        opt, res = sysid.optimize(start, residual_fn, optimizer="mujoco", verbose=False,
                                  max_iters=max_iters, x_scale="jac", output=sink)
        return opt, res
    except np.linalg.LinAlgError as e:
        raise FitError(f"the fit's linear algebra failed ({e}): the logs do not determine the parameters; "
                       "fit fewer (--params) or give logs where every joint moves") from None


def _check_finite(residual_fn: Any, pb: _Problem) -> None:
    """Refuses logs the nominal model cannot replay (it diverges)."""
    p = pb.pdict.copy()
    p.update_from_vector(pb.x_nominal)
    r, _, _ = residual_fn(pb.x_nominal, p)
    for lg, ri in zip(pb.logs, r):
        if not np.all(np.isfinite(ri)):
            raise FitError(f"{lg.path}: the model's replay of it is not finite at the nominal values (it "
                           f"diverges at the log's gains, kp up to {lg.kp.max():g}, kd up to {lg.kd.max():g}): "
                           "check the gains in its header")


def _cost(residual_fn: Any, params: Any, x: np.ndarray) -> float:
    p = params.copy()
    p.update_from_vector(x)
    r, _, _ = residual_fn(x, p)
    return float(sum(np.sum(np.square(ri)) for ri in r))


def _no_worse_than_nominal(sysid: Any, pb: _Problem, residual_fn: Any, opt: Any, res: Any, max_iters: int,
                           sink: io.StringIO, warnings: list[str]) -> tuple[Any, Any]:
    """A fit that ends worse than the nominal values (it started from them
    with those on a bound moved inside, and can stall in a flat valley or a
    step, like the delay's below one timestep) is restarted from them
    exactly; if it still ends worse, the nominal values are kept (``res``
    None: no interval means anything there)."""
    nominal = _cost(residual_fn, pb.pdict, pb.x_nominal)
    ended = _cost(residual_fn, opt, opt.as_vector())
    if ended <= nominal:
        return opt, res
    start = pb.pdict.copy()
    start.update_from_vector(pb.x_nominal)
    opt2, res2 = _optimize(sysid, start, residual_fn, max_iters, sink)
    again = _cost(residual_fn, opt2, opt2.as_vector())
    if again <= nominal:
        warnings.append(f"the fit ended worse than the nominal values (cost {ended:.4g} against {nominal:.4g}): "
                        "restarted from them")
        return opt2, res2
    warnings.append(f"the fit ended worse than the nominal values (cost {ended:.4g}, restarted from them "
                    f"{again:.4g}, against {nominal:.4g}): the nominal values are kept and no interval is "
                    "meaningful; check the logs (an angle offset, the gains in the header, a joint's columns "
                    "under another's name)")
    return start, None


def _intervals(sysid: Any, pb: _Problem, residual_fn: Any, opt: Any, res: Any,
               weights: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None, bool]:
    """sysid's Gauss-Newton 95 % half-widths (infinite where the logs do not
    determine a parameter), the correlations, and whether the residual noise
    behind them was floored at NOISE_FLOOR."""
    n = len(pb.labels)
    if res is None:
        return np.full(n, math.nan), None, False
    r_star, _, _ = residual_fn(opt.as_vector(), opt.copy())
    r_iv, floored = _interval_residuals(r_star, _predictions(residual_fn, opt, opt.as_vector()), weights,
                                        pb.sensors, len(pb.robot.actuators))
    try:
        cov, half = sysid.calculate_intervals(r_iv, res.jac, alpha=0.05)
    except (np.linalg.LinAlgError, ValueError):
        return np.full(n, math.inf), None, floored
    half = np.where(np.isnan(half), math.inf, half)
    sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    corr = cov / np.outer(sd, sd)
    return half, (corr if np.all(np.isfinite(corr)) else None), floored


def _interval_residuals(r_star: list[np.ndarray], preds: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
                        weights: np.ndarray | None, sensors: list[int], nu: int) -> tuple[list[np.ndarray], bool]:
    """The residual the intervals' pooled variance is taken from: sysid's
    own, unless a kind of signal's RMS error lies below its NOISE_FLOOR (a
    noise-free log), where that kind counts at the floor instead."""
    low = set()
    for block in range(3):
        cols = [p for p, s in enumerate(sensors) if s // nu == block]
        if cols:
            err = np.concatenate([(me[:, cols] - pr[:, cols]).ravel() for _, me, pr in preds])
            if math.sqrt(float(np.mean(err ** 2))) < NOISE_FLOOR[block]:
                low.add(block)
    if not low:
        return r_star, False
    # sysid divides each signal by its norm / sqrt(2) and multiplies by its weight
    total = 0.0
    for _, me, pr in preds:
        for p, s in enumerate(sensors):
            scale = (1.0 if weights is None else float(weights[p])) * math.sqrt(2) / float(np.linalg.norm(me[:, p]))
            e2 = len(me) * NOISE_FLOOR[s // nu] ** 2 if s // nu in low else float(np.sum((me[:, p] - pr[:, p]) ** 2))
            total += scale ** 2 * e2
    size = sum(int(np.size(r)) for r in r_star)
    return [np.full(size, math.sqrt(total / size))], True


def _judge(pb: _Problem, sol: _Solution) -> list[str]:
    """What the user must know of each parameter: on a bound, undetermined,
    an interval past a physical bound (every parameter is >= 0), a delay
    under one timestep, confounded pairs; and logs the fit made worse."""
    out: list[str] = []
    lo_b, hi_b = pb.pdict.get_bounds()
    for i, (name, kind, _, _) in enumerate(pb.labels):
        x, h, unit = float(sol.x[i]), float(sol.half[i]), PARAMS[kind][0]
        u = f" {unit}" if unit else ""
        span = float(hi_b[i] - lo_b[i])
        bound = next(((side, b) for side, b in (("lower", float(lo_b[i])), ("upper", float(hi_b[i])))
                      if abs(x - b) <= 1e-6 * span), None)
        if bound is not None:
            # a Gauss-Newton interval assumes a minimum inside the bounds
            out.append(f"{name} ends on its {bound[0]} bound ({bound[1]:g}{u}): its interval is not meaningful; "
                       "the logs ask for a value the fit does not allow, or show none")
        if kind == "delay" and 0 < x < pb.robot.timestep * (1 - 1e-9):
            out.append(f"{name} ends at {x:.3g} s, under one timestep ({pb.robot.timestep:g} s): MuJoCo applies "
                       "any delay up to a timestep as a whole step, so the logs cannot place it there; read it "
                       f"as 0 or {pb.robot.timestep:g} s")
        if math.isinf(h):
            out.append(f"{name}: the logs do not determine it (its 95 % interval is infinite): leave it out "
                       "of --params, or give logs that excite it")
        elif bound is None and math.isfinite(h) and x - h < 0:
            out.append(f"{name}'s 95 % interval [{x - h:.4g}, {x + h:.4g}]{u} reaches below 0, which it cannot "
                       "be: the logs show it poorly or it is near 0; read its upper end as a bound")
    out += _confounded(pb, sol)
    for lg, rms0, rms1 in zip(pb.logs, sol.before, sol.after):
        # by more than 1 % and a micro-radian: not round-off
        if np.mean(rms1) > 1.01 * np.mean(rms0) + 1e-6:
            out.append(f"{lg.path.name}: the RMS angle error rose ({np.mean(rms0) * 1e3:.3f} -> "
                       f"{np.mean(rms1) * 1e3:.3f} mrad): the fitted model explains it worse than the nominal one; "
                       "check the log (an angle offset, the gains in its header)")
    return out


def _confounded(pb: _Problem, sol: _Solution) -> list[str]:
    out: list[str] = []
    if sol.corr is None:
        return out
    for i, (a_name, a_kind, a_mem, _) in enumerate(pb.labels):
        for j, (b_name, b_kind, b_mem, _) in enumerate(pb.labels):
            c = float(sol.corr[i, j])
            if i >= j or abs(c) <= 0.95:
                continue
            if a_mem == b_mem and {a_kind, b_kind} == {"damping", "kd_scale"}:
                out.append(f"{a_name} and {b_name} are confounded (correlation {c:+.2f}): the logs "
                           "show only their sum; add a log at another kd (pupper excite --kd) or a torque column")
            elif abs(c) > CONFOUNDED:
                out.append(f"{a_name} and {b_name} are confounded (correlation {c:+.3f}): the logs cannot tell "
                           "them apart; leave one out of --params, or add logs that separate them")
    return out


def _result(pb: _Problem, sol: _Solution, out_dir: Path | None, seconds: float) -> FitResult:
    table = []
    for i, (name, kind, members, nom) in enumerate(pb.labels):
        x, h = float(sol.x[i]), float(sol.half[i])
        table.append({"parameter": name, "kind": kind,
                      "actuators": " ".join(pb.robot.actuators[k] for k in members),
                      "nominal": nom, "fitted": x, "low95": x - h, "high95": x + h, "unit": PARAMS[kind][0]})
    kept = pb.kept
    return FitResult(table, {lg.path.name: v for lg, v in zip(pb.logs, sol.before)},
                     {lg.path.name: v for lg, v in zip(pb.logs, sol.after)}, out_dir, seconds,
                     pb.warnings + sol.warnings + _judge(pb, sol), [pb.robot.actuators[k] for k in kept],
                     floored=sol.floored)


def _held(t: np.ndarray, target: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Targets logged slower than the physics, as a servo holds them: each
    one until the next (sysid would interpolate between them)."""
    period = float(np.mean(np.diff(t)))
    if period <= dt * (1 + 1e-9):
        return t, target
    tc = np.arange(0.0, t[-1] + dt / 2, dt)
    idx = np.searchsorted(t, tc + 1e-9 * dt, side="right") - 1
    return tc, target[np.clip(idx, 0, len(t) - 1)]


def _modifier(kind: str, members: list[int], robot: Robot, gains: dict[int, tuple[np.ndarray, np.ndarray]]) -> Any:
    def apply(spec: Any, p: Any) -> None:
        v = float(p.value[0])
        for i in members:
            if kind in ("armature", "damping", "frictionloss"):
                j = spec.joint(robot.joints[i])
                if kind == "damping":
                    j.damping[0] = v
                else:
                    setattr(j, kind, v)
            elif kind == "delay":
                spec.actuator(robot.actuators[i]).delay = v
            else:
                kp, kd = gains[id(spec)]
                act = spec.actuator(robot.actuators[i])
                if kind == "kp_scale":
                    act.gainprm[0] = kp[i] * v
                    act.biasprm[1] = -kp[i] * v
                else:
                    act.biasprm[2] = -kd[i] * v
    return apply


def _residual_fn(sysid: Any, sequences: list[Any], enabled: list[Any], weights: np.ndarray | None) -> Any:
    def rollout(**kw: Any) -> Any:
        # mujoco.rollout's sensordata row k is the state before step k (time
        # k dt); sysid labels it one step later: put it back
        trajs = sysid.sysid_rollout(kw["models"], kw["datas"], kw["control_signal"], kw["initial_states"],
                                    kw["rollout_signal_mapping"], kw["rollout_state_mapping"], kw["ctrl_mapping"])
        dt = kw["models"][0].opt.timestep
        return [tr.replace(sensordata=sysid.TimeSeries(tr.sensordata.times - dt, tr.sensordata.data,
                                                       tr.sensordata.signal_mapping)) for tr in trajs]

    return sysid.build_residual_fn(models_sequences=sequences, custom_rollout=rollout,
                                   enabled_observations=enabled, sensor_weights=weights)


def _predictions(residual_fn: Any, params: Any, x: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(times, measured, predicted) of every log at parameters ``x``."""
    p = params.copy()
    p.update_from_vector(x)
    _, preds, meas = residual_fn(x, p, return_pred_all=True)
    out = []
    for pr, me in zip(preds, meas):
        pt, mt = pr[0], me[0]
        pred = np.stack([np.interp(mt.times, pt.times, pt.data[:, k]) for k in range(mt.data.shape[1])], axis=1)
        out.append((mt.times, mt.data, pred))
    return out


def _rms(residual_fn: Any, params: Any, x: np.ndarray, sensors: list[int], nu: int) -> list[list[float]]:
    """Each log's RMS angle error per fitted actuator (the predictions'
    columns are the enabled sensors, angles first)."""
    cols = [p for p, s in enumerate(sensors) if s < nu]
    return [[float(v) for v in np.sqrt(np.mean((me[:, cols] - pr[:, cols]) ** 2, axis=0))]
            for _, me, pr in _predictions(residual_fn, params, x)]


def _whitening(residual_fn: Any, opt: Any, nu: int, sensors: list[int]) -> np.ndarray:
    """Weights that make each kind of signal (angle, velocity, torque)
    count by its own noise, estimated from the fit's residual."""
    preds = _predictions(residual_fn, opt, opt.as_vector())
    # by position among the enabled sensors (a dict would be read by the
    # model's sensor index)
    weights = np.ones(len(sensors))
    for block in range(3):
        # the predictions' columns are the enabled sensors, in order
        cols = [p for p, s in enumerate(sensors) if s // nu == block]
        if not cols:
            continue
        err = np.concatenate([(me[:, cols] - pr[:, cols]).ravel() for _, me, pr in preds])
        sigma = max(float(np.std(err)), 1e-12)
        for p in cols:
            # sysid divides each column by its norm / sqrt(2): undo that, divide by sigma
            norm = np.linalg.norm(np.concatenate([me[:, p] for _, me, _ in preds])) / np.sqrt(2)
            weights[p] = float(norm / sigma) if norm > 0 else 1.0
    return weights


def _write_run(out: Path, res: FitResult, pb: _Problem, sol: _Solution, model: Any, names: list[str], per: str,
               force: bool, plot: bool) -> None:
    """The run directory, written beside it first and moved in at the end:
    a run stopped or failing while it writes leaves the directory as it was
    (a --force run's earlier files too), or none if it made it."""
    made = not out.exists()
    stage = out.parent / f".{out.name}.partial{os.getpid()}"
    try:
        shutil.rmtree(stage, ignore_errors=True)
        stage.mkdir(parents=True)
        _write(stage, res, pb, sol.x, model, names, per)
        if plot:
            _plot(stage, pb, sol)
        out.mkdir(parents=True, exist_ok=True)
        for f in sorted(stage.rglob("*")):
            if f.is_file():
                dest = out / f.relative_to(stage)
                dest.parent.mkdir(parents=True, exist_ok=True)
                os.replace(f, dest)
        from pupper_core import _report

        _report.report(out)
    except BaseException as e:
        if made:
            shutil.rmtree(out, ignore_errors=True)
        if isinstance(e, OSError):
            raise FitError(f"cannot write the run directory {out} ({e.strerror or e}): check the path, its "
                           "permissions and the free space") from None
        raise
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _write(out: Path, res: FitResult, pb: _Problem, x: np.ndarray, model: Any, names: list[str], per: str) -> None:
    import mujoco

    from pupper_core._files import atomic_write

    robot, logs = pb.robot, pb.logs

    def table(tmp: Path) -> None:
        with tmp.open("w", newline="", errors="surrogateescape") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["parameter", "actuators", "nominal", "fitted", "low95", "high95", "unit"])
            for r in res.table:
                w.writerow([r["parameter"], r["actuators"], repr(r["nominal"]), repr(r["fitted"]),
                            repr(r["low95"]), repr(r["high95"]), r["unit"]])

    atomic_write(out / "fit.csv", table)

    def residuals(tmp: Path) -> None:
        with tmp.open("w", newline="", errors="surrogateescape") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["log", "actuator", "rms_before_rad", "rms_after_rad"])
            for lg in logs:
                for k, a in enumerate(res.actuators):
                    w.writerow([lg.path.name, a, repr(res.rms_before[lg.path.name][k]),
                                repr(res.rms_after[lg.path.name][k])])

    atomic_write(out / "residuals.csv", residuals)
    _write_warnings(out, res)
    xml = _calibrated_xml(robot, pb.labels, x)
    atomic_write(out / "calibrated.xml", lambda tmp: _write_text(tmp, xml))
    manifest = {
        "kind": "fit",
        "command": "fit",
        "inputs": {"model": str(model), "logs": [{"path": str(lg.path), "sha256": lg.sha256} for lg in logs],
                   "params": names, "per": per},
        "fit": {r["parameter"]: {"nominal": r["nominal"], "fitted": r["fitted"], "low95": r["low95"],
                                 "high95": r["high95"], "unit": r["unit"]} for r in res.table},
        "rms_before_rad": res.rms_before, "rms_after_rad": res.rms_after,
        "warnings": res.warnings, "seconds": res.seconds,
        "intervals": {"noise_floor": dict(zip(("angle_rad", "velocity_rad_s", "torque_nm"), NOISE_FLOOR)),
                      "floored": res.floored},
        "versions": {"mujoco": mujoco.__version__, "pupper": _version()},
    }
    atomic_write(out / "manifest.json", lambda tmp: _write_text(tmp, json.dumps(manifest, indent=2) + "\n"))


def _write_text(path: Path, text: str) -> None:
    # a log's name that is not UTF-8 keeps its bytes
    path.write_text(text, errors="surrogateescape")


def _write_warnings(out: Path, res: FitResult) -> None:
    """warnings.csv: one row per warning (the parameter it is about, if
    one), only when there are any (a stale one from --force goes)."""
    from pupper_core._files import atomic_write

    path = out / "warnings.csv"
    if not res.warnings:
        path.unlink(missing_ok=True)
        return
    names = sorted((r["parameter"] for r in res.table), key=len, reverse=True)

    def write(tmp: Path) -> None:
        with tmp.open("w", newline="", errors="surrogateescape") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["parameter", "warning"])
            for text in res.warnings:
                w.writerow([next((n for n in names if text.startswith(n)), ""), text])

    atomic_write(path, write)


def _calibrated_xml(robot: Robot, labels: list[tuple[str, str, list[int], float]], x: np.ndarray) -> str:
    """The whole robot with the fitted values, written through MjSpec."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(robot.file))
    # assets stay where the original's are
    base = robot.file.parent
    spec.meshdir = str((base / spec.meshdir).resolve()) if spec.meshdir else str(base)
    spec.texturedir = str((base / spec.texturedir).resolve()) if spec.texturedir else str(base)
    if robot.fixed_base:
        # the model fitted had its base welded: so has its calibration
        for j in [j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_FREE]:
            spec.delete(j)
        for k in list(spec.keys):
            spec.delete(k)
    scales: dict[tuple[str, int], float] = {}
    n = _history_samples(robot)
    for (name, kind, members, _), v in zip(labels, x):
        for i in members:
            if kind in ("armature", "frictionloss"):
                setattr(spec.joint(robot.joints[i]), kind, float(v))
            elif kind == "damping":
                spec.joint(robot.joints[i]).damping[0] = float(v)
            elif kind == "delay":
                act = spec.actuator(robot.actuators[i])
                act.delay = float(v)
                act.nsample = n
                act.interp = 1
            else:
                scales[(kind, i)] = float(v)
    for (kind, i), v in sorted(scales.items()):
        spec.add_numeric(name=SCALE_NUMERIC.format(kind=kind, actuator=robot.actuators[i]), data=[v])
    spec.modelname = f"{spec.modelname}_calibrated" if spec.modelname else "calibrated"
    return str(spec.to_xml())


def _version() -> str:
    from pupper_core import __version__

    return str(__version__)


def _plot(out: Path, pb: _Problem, sol: _Solution) -> list[Path]:
    """Per log, measured against simulated angle of each fitted joint, at
    the nominal and the fitted values."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pupper_core._files import atomic_write

    kept = pb.kept
    nu = len(kept)
    first = _predictions(sol.residual_fn, pb.pdict, pb.x_nominal)
    last = _predictions(sol.residual_fn, sol.params, sol.x)
    (out / "plots").mkdir(exist_ok=True)
    wrote = []
    for lg, (t, me, p0), (_, _, p1) in zip(pb.logs, first, last):
        cols = 4 if nu >= 4 else nu
        rows = math.ceil(nu / cols)
        fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 2.4 * rows), sharex=True, squeeze=False)
        for k in range(nu):
            # the predictions' first columns are the fitted joints' angles
            ax = axes[k // cols][k % cols]
            ax.plot(t, me[:, k], color="black", lw=1.0, label="measured")
            ax.plot(t, p0[:, k], color="tab:gray", lw=0.8, ls="--", label="nominal model")
            ax.plot(t, p1[:, k], color="tab:orange", lw=0.8, label="fitted model")
            r0 = np.sqrt(np.mean((me[:, k] - p0[:, k]) ** 2)) * 1e3
            r1 = np.sqrt(np.mean((me[:, k] - p1[:, k]) ** 2)) * 1e3
            ax.set_title(f"{pb.robot.actuators[kept[k]]}: RMS {r0:.2f} → {r1:.2f} mrad", fontsize=8)
            ax.tick_params(labelsize=7)
        axes[0][0].legend(fontsize=7, loc="upper right")
        for ax in axes[-1]:
            ax.set_xlabel("time (s)", fontsize=8)
        for row in axes:
            row[0].set_ylabel("angle (rad)", fontsize=8)
        fig.suptitle(f"{lg.path.name}: measured against simulated joint angle, before and after the fit", fontsize=10)
        fig.tight_layout()
        path = out / "plots" / f"fit_{lg.path.stem}.png"
        atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=90))
        plt.close(fig)
        wrote.append(path)
    return wrote


# ---------------------------------------------------------------------- CLI


def _cli_fit(args_json: str) -> list[str]:
    a = json.loads(args_json)
    res = fit(a.pop("logs"), **a)
    width = max(len(r["parameter"]) for r in res.table)
    print(f"{'parameter':<{width}}  {'nominal':>10}  {'fitted':>10}  {'95 % interval':>25}  unit")
    for r in res.table:
        interval = (f"[{r['low95']:>10.4g}, {r['high95']:>10.4g}]" if not math.isnan(r["low95"])
                    else f"{'(not meaningful)':>25}")
        print(f"{r['parameter']:<{width}}  {r['nominal']:>10.4g}  {r['fitted']:>10.4g}  {interval}  {r['unit']}")
    for name in res.rms_before:
        b, f = np.mean(res.rms_before[name]) * 1e3, np.mean(res.rms_after[name]) * 1e3
        print(f"{name}: RMS angle error {b:.3f} -> {f:.3f} mrad (mean over {len(res.actuators)} joints)")
    for w in res.warnings:
        print(f"warning: {w}", file=sys.stderr)
    print(f"fitted in {res.seconds:.1f} s")
    sys.stdout.flush()
    if res.out is None:
        return []
    wrote = [str(res.out / n) for n in ("fit.csv", "residuals.csv", "calibrated.xml")]
    if res.warnings:
        wrote.append(str(res.out / "warnings.csv"))
    if (res.out / "plots").is_dir():
        wrote += [str(p) for p in sorted((res.out / "plots").glob("fit_*.png"))]
    return wrote + [str(res.out / "report.html")]


def _cli_excite(args_json: str) -> list[str]:
    a = json.loads(args_json)
    path, notes = _excite(a.pop("model", "pupper_v3"), **a)
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    sys.stdout.flush()
    return [str(path)]


def _hash(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()
