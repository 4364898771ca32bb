"""A one-motor test stand as a robot's ROS 2 control loop would log it,
written as a plain MuJoCo loop (not pupper's code): a stand-in for a real
bench log, for docs/fit.md and the tests.

    python examples/stand_log.py stand.csv --kp 5 --kd 0.1 --seed 0
    python examples/stand_log.py stand.csv.gz --kp 5 --kd 0.1 --seed 0 --gzip

The "hardware" is the built-in robot hung in the air with heavier rotors,
more damping and friction than the nominal model; it steps at 0.5 ms
(finer than the model's 2 ms: continuous time, as far as the fit can
tell). One motor plays a stepped sine (1 to 20 Hz, 0.5 rad); the other
eleven hold 0 at the log's gains. Its servo is written out here, as a
real Pupper's behaves on a bench (issue 48's logs): the PD, at gains a
little off what the log says, acts on the command ``delay`` ago (outside
the loop); its torque, clamped to the torque limit, reaches the joint
through a first-order ``lag`` (a current loop's, inside the loop: the lag
that made pupper's fit stall its delay at 0 on the real logs); and it may read its
angle and velocity ``latency`` late (a feedback latency, inside the loop
too). The loop runs every 4 ms on time, but stamps each row with a clock
read late by up to 3.3 ms (the jitter of a ROS clock read in a callback),
from an arbitrary start, in its own column names:
``fr_knee_cmd,fr_knee_kp,fr_knee_kd,fr_knee_pos,fr_knee_vel,...,stamp``
(the command message's gains, and a column nobody maps). The command is
the sine at the stamp's time (what the loop believes); the angle carries
encoder noise and a 14-bit encoder's quantisation; the velocity is the
servo's estimate from the angles, ``VELOCITY_LAG`` behind the joint. With
``gzip`` (``--gzip``) the file is gzipped as the Pupper team's bench logs
are (``gzip -n -9``: no name, no time stamp)."""

from __future__ import annotations

import csv
import gzip as _gzip
import io
import math
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pupper_core as pc

SCENE = Path(pc.__file__).parent / "models" / "pupper_v3" / "scene.xml"
MOTOR = "leg_front_r_3"
#: the stand's truth, against the nominal armature 0.0016, damping 0.01, friction loss 0.01, no delay or lag
TRUTH = dict(armature=0.0016 * 1.5, damping=0.03, frictionloss=0.04, kp_scale=0.95, kd_scale=1.0, delay=0.020,
             lag=0.007, latency=0.0)
FREQS = (1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 14.0, 20.0)
AMPLITUDE = 0.5
#: the ROS export's column names for the motor, and the map that reads them
COLUMNS = (f"time=stamp,{MOTOR}.target=fr_knee_cmd,{MOTOR}.q=fr_knee_pos,{MOTOR}.qd=fr_knee_vel,"
           f"{MOTOR}.kp=fr_knee_kp,{MOTOR}.kd=fr_knee_kd")
HW_DT = 0.0005
#: the loop's period (s), and how late its clock may be read (its stamps' gaps: 4 ms give or take 1.9 ms RMS)
PERIOD, JITTER = 0.004, 0.0033
#: how far the servo's velocity estimate runs behind the joint's (s)
VELOCITY_LAG = 0.005
#: the motor's torque limit (the model's forcerange)
TORQUE_LIMIT = 3.0
#: the plain stand (stand_log's keywords): no torque lag, a 15 ms delay, rows at their stamps, a velocity on
#: time, 0.2 rad; a servo the default parameters can follow, for tests whose subject is not the servo's lag
PLAIN: dict = dict(truth={**TRUTH, "lag": 0.0, "delay": 0.015}, clock=False, velocity_lag=0.0, amplitude=0.2)


def segments(freqs: tuple[float, ...] = FREQS, hold: float = 0.3) -> list[tuple[float, float, float]]:
    """(start, end, frequency) of each step of the stepped sine: 3 cycles
    or 0.5 s, whichever is longer, after ``hold`` s at rest."""
    out, t = [], hold
    for f in freqs:
        d = max(3.0 / f, 0.5)
        out.append((t, t + d, f))
        t += d
    return out


def command(t: np.ndarray, amplitude: float = AMPLITUDE, freqs: tuple[float, ...] = FREQS) -> np.ndarray:
    out = np.zeros_like(t)
    for a, b, f in segments(freqs):
        on = (t >= a) & (t < b)
        out[on] = amplitude * np.sin(2 * np.pi * f * (t[on] - a))
    return out


def hardware(kp: float, kd: float, truth: dict[str, float], motor_name: str = MOTOR) -> mujoco.MjModel:
    """The stand: every motor a servo at the log's gains (times the truth's
    scales), the logged one (``motor_name``) a plain torque motor its loop drives."""
    spec = mujoco.MjSpec.from_file(str(SCENE))
    for j in [j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_FREE]:
        spec.delete(j)
    for k in list(spec.keys):
        spec.delete(k)
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    spec.option.timestep = HW_DT
    for j in spec.joints:
        j.armature, j.frictionloss = truth["armature"], truth["frictionloss"]
        j.damping[0] = truth["damping"]
    for a in spec.actuators:
        g, d = kp * truth["kp_scale"], kd * truth["kd_scale"]
        a.gainprm[0], a.biasprm[1], a.biasprm[2] = g, -g, -d
    motor = spec.actuator(motor_name)
    motor.biastype = mujoco.mjtBias.mjBIAS_NONE
    motor.gainprm[0] = 1.0
    motor.biasprm[:] = 0.0
    motor.forcerange[0], motor.forcerange[1] = -TORQUE_LIMIT, TORQUE_LIMIT
    return spec.compile()


def stamps(seconds: float, seed: int, start: float, clock: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """When each row happens, and the time stamp it carries: with ``clock``
    every PERIOD on time, stamped up to JITTER late (a ROS clock read in a
    callback); else at the stamps themselves, PERIOD give or take JITTER / 2."""
    rng = np.random.default_rng(seed)
    n = int(seconds / PERIOD) + 1
    if clock:
        true = np.arange(n + 1) * PERIOD
        return true, start + true + rng.uniform(0.0, JITTER, n + 1)
    gaps = PERIOD + rng.uniform(-JITTER / 2, JITTER / 2, n)
    rel = np.concatenate([[0.0], np.cumsum(gaps)])
    return rel, start + rel


def stand_log(path: Path, *, kp: float, kd: float, seed: int, truth: dict[str, float] = TRUTH,
              start: float = 1732600000.25, noise: float = 1e-3, held_columns: bool = False,
              clock: bool = True, velocity_lag: float = VELOCITY_LAG, amplitude: float = AMPLITUDE,
              gzip: bool = False, freqs: tuple[float, ...] = FREQS, motor_name: str = MOTOR,
              prefix: str = "fr_knee", real2sim: bool = False) -> Path:
    """Plays the stepped sine on the stand and writes the loop's log (no
    header lines: the gains are the command line's to give). ``truth``:
    the stand's values (TRUTH's keys; ``lag`` and ``latency`` default 0);
    ``clock``: rows on time, stamps late (else each row at its stamp);
    ``amplitude``: the sine's (rad); ``gzip``: compressed as the bench's tool does (``gzip -n -9``);
    ``freqs``: the stepped sine's frequencies (Hz; fewer make a shorter log);
    ``motor_name``: the motor on the stand, its columns named ``prefix``_cmd, ``prefix``_pos, ....;
    ``real2sim``: in the Pupper team's real2sim format instead (``REAL2SIM``: the motor by its index, the
    columns' units in their names, the time since the sine faded in)."""
    truth = {"lag": 0.0, "latency": 0.0, **truth}
    m = hardware(kp, kd, truth, motor_name)
    d = mujoco.MjData(m)
    motor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, motor_name)
    qadr = m.jnt_qposadr[m.actuator_trnid[motor, 0]]
    vadr = m.jnt_dofadr[m.actuator_trnid[motor, 0]]
    seconds = segments(freqs)[-1][1] + 0.3
    when, ts = stamps(seconds, seed, start, clock)
    # the loop computes its command from the time it reads
    cmd = command(ts - ts[0], amplitude, freqs)
    rng = np.random.default_rng(seed + 100)
    q, qd = np.empty(len(ts)), np.empty(len(ts))
    g, dg = kp * truth["kp_scale"], kd * truth["kd_scale"]
    follow = -math.expm1(-HW_DT / truth["lag"]) if truth["lag"] > 0 else 1.0
    keep = int(math.ceil(max(truth["latency"], velocity_lag) / HW_DT)) + 2
    past: list[tuple[float, float, float]] = []
    torque = 0.0
    for i, t in enumerate(when):
        while d.time < t - 1e-12:
            past = (past + [(d.time, float(d.qpos[qadr]), float(d.qvel[vadr]))])[-keep:]
            # the command in force: the last one sent at least `delay` ago
            sent = np.searchsorted(when, d.time - truth["delay"] + 1e-12, side="right") - 1
            target = cmd[sent] if sent >= 0 else 0.0
            seen = _ago(past, truth["latency"])
            # the firmware clamps the torque it asks for; the current loop follows it
            pd = min(max(g * (target - seen[0]) - dg * seen[1], -TORQUE_LIMIT), TORQUE_LIMIT)
            torque += follow * (pd - torque)
            d.ctrl[motor] = torque
            mujoco.mj_step(m, d)
        q[i] = d.qpos[qadr]
        qd[i] = _ago(past + [(d.time, float(d.qpos[qadr]), float(d.qvel[vadr]))], velocity_lag)[1]
    step = 2 * math.pi / 2**14
    q = np.round((q + noise * rng.standard_normal(len(q))) / step) * step
    qd = qd + 0.05 * rng.standard_normal(len(qd))
    with io.StringIO(newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        if real2sim:
            _real2sim(w, ts - ts[0], cmd, q, qd, motor, amplitude, freqs)
            return _written(path, f.getvalue().encode(), gzip)
        extra = ["fr_hip_cmd", "fr_hip_pos", "fr_hip_vel"] if held_columns else []
        w.writerow([f"{prefix}_{c}" for c in ("cmd", "kp", "kd", "pos", "vel", "effort")] + [*extra, "stamp"])
        for i in range(len(ts)):
            row = [repr(float(cmd[i])), repr(kp), repr(kd), repr(float(q[i])), repr(float(qd[i])), "nan"]
            row += ["0.0", "0.0", "0.0"] if held_columns else []
            w.writerow(row + [f"{ts[i]:.6f}"])
        data = f.getvalue().encode()
    return _written(path, data, gzip)


#: The Pupper v3 real2sim logger's header (ros2_ws/src/real2sim_controller): the motor by its index in the
#: robot's joint order, each column's unit in its name.
REAL2SIM = ("time_since_fade_in (s)", "phase_", "amp (rad)", "freq (Hz)", "motor_idx", "policy_output",
            "command (rad)", "motor_position (rad)", "motor_velocity (rad/s)")


def _real2sim(w: Any, t: np.ndarray, cmd: np.ndarray, q: np.ndarray, qd: np.ndarray, motor: int,
              amplitude: float, freqs: tuple[float, ...]) -> None:
    """The rows as the real2sim logger writes them: the sine's phase,
    amplitude and frequency beside the command it sent."""
    w.writerow(REAL2SIM)
    seg = segments(freqs)
    for i in range(len(t)):
        a, f = next(((a, f) for a, b, f in seg if a <= t[i] < b), (0.0, 0.0))
        phase = 2 * math.pi * f * (t[i] - a) if f else 0.0
        w.writerow([f"{t[i]:.6g}", f"{phase:.6g}", f"{amplitude:g}", f"{f:g}", motor, repr(float(cmd[i])),
                    repr(float(cmd[i])), repr(float(q[i])), repr(float(qd[i]))])


def _written(path: Path, data: bytes, gzip: bool) -> Path:
    if gzip:
        packed = bytearray(_gzip.compress(data, compresslevel=9, mtime=0))
        # the OS byte gzip writes on Linux (Python's module writes 255, "unknown")
        packed[9] = 3
        data = bytes(packed)
    path.write_bytes(data)
    return path


def _ago(past: list[tuple[float, float, float]], lag: float) -> tuple[float, float]:
    """The angle and velocity ``lag`` before the last sample, linearly
    between samples (the first one before the start)."""
    t = past[-1][0] - lag
    if lag <= 0 or t <= past[0][0]:
        k = -1 if lag <= 0 else 0
        return past[k][1], past[k][2]
    for (t0, q0, v0), (t1, q1, v1) in zip(past[:-1], past[1:]):
        if t0 <= t <= t1:
            w = (t - t0) / (t1 - t0) if t1 > t0 else 0.0
            return q0 + w * (q1 - q0), v0 + w * (v1 - v0)
    return past[-1][1], past[-1][2]


def main() -> None:
    import argparse

    p = argparse.ArgumentParser(description="Write a staged one-motor test-stand log, as a ROS 2 loop logs it.")
    p.add_argument("out", type=Path)
    p.add_argument("--kp", type=float, default=5.0)
    p.add_argument("--kd", type=float, default=0.1)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--gzip", action="store_true", help="gzip the log, as the bench's tool does")
    a = p.parse_args()
    print(f"wrote {stand_log(a.out, kp=a.kp, kd=a.kd, seed=a.seed, gzip=a.gzip)}")


if __name__ == "__main__":
    main()
