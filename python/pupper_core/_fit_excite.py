"""`pupper excite` (``pupper_core._fit`` re-exports it): an excitation to
play on the robot hung in the air, per joint group a multisine or chirp
around the rest pose, inside the joint ranges and under velocity and torque
limits, with holds between, and the nominal model's response to it, in the
joint-log format."""

from __future__ import annotations

import math
import numbers
import os
import warnings as _warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core._fit_robot import Robot, load_robot, simulate, suspended_spec
from pupper_core._fit_terms import GROUPS, MAX_LOG_SECONDS, FitError
from pupper_core._joint_log import LogError, check_gains, write_log
from pupper_core._public import exported_from
from pupper_core._signals import _stop_on_signals


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


@exported_from("pupper_core._fit")
def excite(model: str | os.PathLike[str] = "pupper_v3", *, out: str | os.PathLike[str] | None = "excite.csv",
           kp: float | None = None, kd: float | None = None, seconds: float = 8.0, hold: float = 1.0,
           amplitude: float = 0.3, signal: str = "multisine", band: Sequence[float] | str = (0.3, 6.0),
           max_velocity: float = 8.0, seed: int = 0, force: bool = False,
           joints: str | Sequence[str] | None = None, rate: float | None = None) -> Path:
    """Writes an excitation to play on the robot and the nominal model's
    response to it, in the joint-log format; returns the file's path
    (``out``; None: excite.csv). Numbers may be Python's or NumPy's;
    ``band`` is (F0, F1) or "F0,F1" (Hz). ``joints``: the actuators (or
    joint groups haa, hfe, kfe) excited and logged, the others held at
    rest (a test stand); ``rate``: the log's sample rate (Hz), targets held
    between samples, fast enough for `fit` to read. Gains past the
    explicit PD's stability bound are said as a warning."""
    path, notes = _excite(model, out=out, kp=kp, kd=kd, seconds=seconds, hold=hold, amplitude=amplitude,
                          signal=signal, band=band, max_velocity=max_velocity, seed=seed, force=force,
                          joints=joints, rate=rate)
    for note in notes:
        _warnings.warn(note, stacklevel=2)
    return path


def _excite(model: str | os.PathLike[str], *, out: str | os.PathLike[str] | None, kp: float | None, kd: float | None,
            seconds: float, hold: float, amplitude: float, signal: str, band: Sequence[float] | str,
            max_velocity: float, seed: int, force: bool, joints: str | Sequence[str] | None = None,
            rate: float | None = None) -> tuple[Path, list[str]]:
    """`excite`, and its notes. Every option is checked before any work."""
    seed = _seed(seed)
    robot = load_robot(model)
    out = _excite_out(out, force)
    chosen = _excite_joints(robot, joints)
    lo, hi = _excite_options(robot, signal, band, seconds, hold, amplitude, max_velocity,
                             {robot.groups[k] for k in chosen})
    stride = _excite_stride(robot, rate)
    gains_kp, gains_kd = _excite_gains(robot, kp, kd)
    _excite_rate_fits(robot, stride, gains_kp, chosen, hi)
    notes = _stability_notes(robot, gains_kp, gains_kd)
    with _stop_on_signals("excite"):
        times, targets = _excite_targets(robot, gains_kp, signal, (lo, hi), seconds, hold, amplitude,
                                         max_velocity, seed, chosen)
        # a slower log's targets: each held until the next sample, as the servo holds it
        targets = targets[(np.arange(len(targets)) // stride) * stride]
        spec = suspended_spec(robot, gains_kp, gains_kd)
        sens = simulate(spec, robot, times, targets)
        if not np.all(np.isfinite(sens)):
            raise FitError(f"the model diverges at kp {gains_kp.max():g}, kd {gains_kd.max():g}: its response "
                           "is not finite; lower the gains (pupper gains --kp KP --kd KD shows the bound)")
        nu, rows = len(robot.actuators), slice(None, None, stride)
        block = [sens[rows, b * nu:(b + 1) * nu][:, chosen] for b in range(3)]
        # torque sampled slower than the physics would land on the held targets' switches: left out
        write_log(out, times[rows], [robot.actuators[k] for k in chosen], target=targets[rows][:, chosen],
                  q=block[0], qd=block[1], tau=block[2] if stride == 1 else None, kp=gains_kp[chosen],
                  kd=gains_kd[chosen],
                  note=f"pupper excite {signal} {lo:g}-{hi:g} Hz; q, qd{', tau' if stride == 1 else ''}: "
                       "the nominal model's response")
    return out, notes


def _seed(seed: Any) -> int:
    """The multisine's seed: a whole number >= 0 (NumPy's too), as the CLI's --seed."""
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or not 0 <= int(seed) < 2**64:
        raise FitError(f"--seed {seed!r} is not a whole number from 0 to 2^64-1: give e.g. --seed 0")
    return int(seed)


def _excite_out(out: str | os.PathLike[str] | None, force: bool) -> Path:
    if out is None:
        out = "excite.csv"
    if not isinstance(out, (str, os.PathLike)):
        raise FitError(f"--out {out!r} is not a path: give the file to write, e.g. excite.csv")
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


def _excite_joints(robot: Robot, joints: str | Sequence[str] | None) -> list[int]:
    """The actuators excited and logged (names or joint groups): all by default."""
    if joints is None:
        return list(range(len(robot.actuators)))
    names = [j.strip() for j in (joints.split(",") if isinstance(joints, str) else joints) if j.strip()]
    chosen: set[int] = set()
    for n in names:
        hit = [k for k, (a, g) in enumerate(zip(robot.actuators, robot.groups)) if n in (a, g)]
        if not hit:
            raise FitError(f"--joints names '{n}', neither an actuator of the model ({robot.actuators[0]}, "
                           f"{robot.actuators[1]}, ...) nor a joint group (haa, hfe, kfe): give e.g. "
                           f"--joints {robot.actuators[min(2, len(robot.actuators) - 1)]}")
        chosen.update(hit)
    if not chosen:
        raise FitError("--joints is empty: name actuators or joint groups (haa, hfe, kfe)")
    return sorted(chosen)


def _excite_stride(robot: Robot, rate: float | None) -> int:
    """Physics steps per logged sample at ``rate`` Hz: a whole number."""
    if rate is None:
        return 1
    top = 1 / robot.timestep
    r = _number("rate", rate)
    stride = round(top / r) if r > 0 else 0
    if stride < 1 or abs(stride * r - top) > 1e-6 * top:
        ok = ", ".join(f"{top / k:g}" for k in (1, 2, 4, 5) if top / k == int(top / k))
        raise FitError(f"--rate {r:g} Hz is not the physics rate ({top:g} Hz) divided by a whole number: "
                       f"give e.g. {ok}")
    return stride


def _excite_rate_fits(robot: Robot, stride: int, kp: np.ndarray, chosen: list[int], hi: float) -> None:
    """Refuses a log rate fit could not read, before any work: fit refuses a
    log sampled below twice the fastest joint's natural frequency at its
    gains (it cannot show that motion), and below twice the band's top the
    excitation itself aliases."""
    if stride == 1:
        return
    top = 1 / robot.timestep
    rate = top / stride
    hz = robot.natural_hz(kp)[chosen]
    k = int(np.argmax(hz))
    swing = float(hz[k])
    if rate >= 2 * max(swing, hi):
        return
    if swing >= hi:
        why = (f"at kp {kp[chosen[k]]:g} {robot.actuators[chosen[k]]} swings at {swing:.3g} Hz, and fit refuses a "
               f"log sampled below twice that ({2 * swing:.3g} Hz)")
    else:
        why = f"the --band reaches {hi:g} Hz, which a log below twice that ({2 * hi:g} Hz) cannot carry"
    want = max(10 * swing, 2 * hi)
    # the slowest rate that divides the physics rate into whole Hz at or above the one advised
    ok = next((top / n for n in range(max(1, int(top // want)), 0, -1) if (top / n).is_integer()), top)
    raise FitError(f"--rate {rate:g} Hz is too slow for fit: {why}; give --rate {ok:g} or more")


def _number(name: str, v: Any) -> float:
    """A flag's number (Python's or NumPy's); the CLI passes NaN and infinity as null."""
    if v is None or isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(float(v)):
        # the CLI passes NaN and infinity alike, as null
        raise FitError(f"--{name} {'(nan or inf)' if v is None else v} is not a finite number: give e.g. "
                       f"--{name} {dict(seconds=8, hold=1, amplitude=0.3, band='0.3,6').get(name, 8)}")
    return float(v)


def _excite_options(robot: Robot, signal: str, band: Sequence[float] | str, seconds: float, hold: float,
                    amplitude: float, max_velocity: float, excited: set[str]) -> tuple[float, float]:
    """Checks excite's options; returns the band."""
    if signal not in ("multisine", "chirp"):
        raise FitError(f"--signal {signal} is unknown: use multisine or chirp")
    lo, hi = _band(band)
    if not (0 < lo < hi < 0.5 / robot.timestep / 4):
        raise FitError(f"--band {lo:g},{hi:g} Hz is not 0 < F0 < F1 below a quarter of the "
                       f"Nyquist rate ({0.125 / robot.timestep:g} Hz): give e.g. 0.3,6")
    for name, v in (("seconds", seconds), ("amplitude", amplitude), ("max-velocity", max_velocity)):
        if not _number(name, v) > 0:
            raise FitError(f"--{name} {v} must be > 0")
    if not _number("hold", hold) >= 0:
        raise FitError(f"--hold {hold} must be >= 0")
    groups = len([g for g in GROUPS if g in excited] or ["joint"])
    total = hold + groups * (seconds + hold)
    if total > MAX_LOG_SECONDS:
        most = max((MAX_LOG_SECONDS - hold) / groups - hold, 0.0)
        raise FitError(f"--seconds {seconds:g} --hold {hold:g} make a {total:.4g} s log ({groups} joint "
                       f"groups), past the {MAX_LOG_SECONDS:g} s fit takes: give --seconds of at most "
                       f"{math.floor(most * 10) / 10:g} (8 is the default)")
    return lo, hi


def _band(band: Any) -> tuple[float, float]:
    """--band: (F0, F1), or the CLI's text "F0,F1"."""
    parts = band.split(",") if isinstance(band, str) else band
    try:
        values = [float(p) if isinstance(p, str) else _number("band", p) for p in parts]
    except (TypeError, ValueError, FitError):
        values = []
    if len(values) != 2 or not all(math.isfinite(v) for v in values):
        raise FitError(f"--band {band!r} is not two numbers F0,F1 (Hz): give e.g. --band 0.3,6")
    return values[0], values[1]


def _excite_gains(robot: Robot, kp: float | None, kd: float | None) -> tuple[np.ndarray, np.ndarray]:
    """The gains to excite at: --kp/--kd, else the model's own."""
    n = len(robot.actuators)
    for key, v in (("kp", kp), ("kd", kd)):
        if v is not None:
            if isinstance(v, bool) or not isinstance(v, numbers.Real):
                raise FitError(f"--{key} {v!r} is not a number: excite runs every actuator at one {key}; "
                               f"give e.g. --{key} 5")
            try:
                check_gains([float(v)], key, f"--{key} {float(v):g}", "")
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

    # at the stand pose, where the model has legs to pose; else (a bench of
    # one joint) at the rest pose the excitation starts from
    legged = any(leg >= 0 for leg in robot.legs)
    g = _native.gains(str(robot.file), kp=float(kp.max()), kd=float(kd.max()), bandwidth=None,
                      damping=0.7, pose=None if legged else [float(q) for q in robot.rest])
    worst = max(g.get("joints", []), key=lambda j: float(j.get("stability_margin", 0.0)), default=None)
    if worst is None or not float(worst["stability_margin"]) >= 1:
        return []
    return [f"kp {kp.max():g}, kd {kd.max():g} lie past the stability bound of an explicitly integrated PD "
            f"at the timestep (worst: {worst['actuator']}, margin {float(worst['stability_margin']):.3g}): "
            "the nominal response in the log may chatter at the torque limit or diverge; "
            f"`pupper gains --kp {kp.max():g} --kd {kd.max():g}` shows the bound per joint"]


def _excite_targets(robot: Robot, gains_kp: np.ndarray, signal: str, band: tuple[float, float], seconds: float,
                    hold: float, amplitude: float, max_velocity: float, seed: int,
                    chosen: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """The excitation's times and targets: per joint group (of the chosen
    actuators) a multisine or chirp inside the ranges and the speed and
    torque limits, with holds."""
    dt = robot.timestep
    rng = np.random.default_rng(seed)
    groups = [g for g in GROUPS if any(robot.groups[k] == g for k in chosen)] or ["joint"]
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
        for a in (i for i, x in enumerate(robot.groups) if (x == g or g == "joint") and i in chosen):
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
