"""A one-motor test stand as a robot's ROS 2 control loop would log it,
written as a plain MuJoCo loop (not pupper's code): a stand-in for a real
bench log, for docs/fit.md and the tests.

    python examples/stand_log.py stand.csv --kp 5 --kd 0.1 --seed 0
    python examples/stand_log.py stand.csv.gz --kp 5 --kd 0.1 --seed 0 --gzip

The "hardware" is the built-in robot hung in the air with heavier rotors,
more damping and friction than the nominal model, its gains a little off
what the log says and a command delay; it steps at 0.5 ms (finer than the
model's 2 ms: continuous time, as far as the fit can tell). One motor
plays a stepped sine (1 to 20 Hz); the other eleven hold 0 at the log's
gains. The loop writes a row per cycle at about 250 Hz, its time stamps
jittered by up to 2 ms around 4 ms and starting at an arbitrary time, in
its own column names: ``fr_knee_cmd,fr_knee_kp,fr_knee_kd,fr_knee_pos,
fr_knee_vel,...,stamp`` (the command message's gains, and a column nobody
maps), the angle with encoder noise and a 14-bit
encoder's quantisation. With ``gzip`` (``--gzip``) the file is gzipped as
the Pupper team's bench logs are (``gzip -n -9``: no name, no time stamp)."""

from __future__ import annotations

import csv
import gzip as _gzip
import io
import math
from pathlib import Path

import mujoco
import numpy as np
import pupper_core as pc

SCENE = Path(pc.__file__).parent / "models" / "pupper_v3" / "scene.xml"
MOTOR = "leg_front_r_3"
#: the stand's truth, against the nominal armature 0.0016, damping 0.01, friction loss 0.01
TRUTH = dict(armature=0.0016 * 1.5, damping=0.03, frictionloss=0.04, kp_scale=0.95, kd_scale=1.0, delay=0.015)
FREQS = (1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 14.0, 20.0)
#: the ROS export's column names for the motor, and the map that reads them
COLUMNS = (f"time=stamp,{MOTOR}.target=fr_knee_cmd,{MOTOR}.q=fr_knee_pos,{MOTOR}.qd=fr_knee_vel,"
           f"{MOTOR}.kp=fr_knee_kp,{MOTOR}.kd=fr_knee_kd")
HW_DT = 0.0005


def segments(freqs: tuple[float, ...] = FREQS, hold: float = 0.3) -> list[tuple[float, float, float]]:
    """(start, end, frequency) of each step of the stepped sine: 3 cycles
    or 0.5 s, whichever is longer, after ``hold`` s at rest."""
    out, t = [], hold
    for f in freqs:
        d = max(3.0 / f, 0.5)
        out.append((t, t + d, f))
        t += d
    return out


def command(t: np.ndarray, amplitude: float = 0.2) -> np.ndarray:
    out = np.zeros_like(t)
    for a, b, f in segments():
        on = (t >= a) & (t < b)
        out[on] = amplitude * np.sin(2 * np.pi * f * (t[on] - a))
    return out


def hardware(kp: float, kd: float, truth: dict[str, float]) -> mujoco.MjModel:
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
    return spec.compile()


def stamps(seconds: float, seed: int, start: float) -> np.ndarray:
    """A control loop's time stamps: 4 ms apart, give or take up to 2 ms."""
    rng = np.random.default_rng(seed)
    gaps = 0.004 + rng.uniform(-0.0019, 0.0019, int(seconds / 0.004) + 1)
    return start + np.concatenate([[0.0], np.cumsum(gaps)])


def stand_log(path: Path, *, kp: float, kd: float, seed: int, truth: dict[str, float] = TRUTH, start: float = 1732600000.25,
              noise: float = 1e-3, held_columns: bool = False, gzip: bool = False) -> Path:
    """Plays the stepped sine on the stand and writes the loop's log (no
    header lines: the gains are the command line's to give); ``gzip``:
    compressed as the bench's tool does (``gzip -n -9``)."""
    m = hardware(kp, kd, truth)
    d = mujoco.MjData(m)
    motor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, MOTOR)
    qadr = m.jnt_qposadr[m.actuator_trnid[motor, 0]]
    vadr = m.jnt_dofadr[m.actuator_trnid[motor, 0]]
    seconds = segments()[-1][1] + 0.3
    ts = stamps(seconds, seed, start)
    rel = ts - ts[0]
    cmd = command(rel)
    rng = np.random.default_rng(seed + 100)
    q, qd = np.empty(len(ts)), np.empty(len(ts))
    # the command in force at each instant: the last one sent at least `delay` ago
    for i, t in enumerate(rel):
        while d.time < t - 1e-12:
            sent = np.searchsorted(rel, d.time - truth["delay"] + 1e-12, side="right") - 1
            d.ctrl[motor] = cmd[sent] if sent >= 0 else 0.0
            mujoco.mj_step(m, d)
        q[i], qd[i] = d.qpos[qadr], d.qvel[vadr]
    step = 2 * math.pi / 2**14
    q = np.round((q + noise * rng.standard_normal(len(q))) / step) * step
    qd = qd + 0.05 * rng.standard_normal(len(qd))
    with io.StringIO(newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        extra = ["fr_hip_cmd", "fr_hip_pos", "fr_hip_vel"] if held_columns else []
        w.writerow(["fr_knee_cmd", "fr_knee_kp", "fr_knee_kd", "fr_knee_pos", "fr_knee_vel", "fr_knee_effort",
                    *extra, "stamp"])
        for i in range(len(ts)):
            row = [repr(float(cmd[i])), repr(kp), repr(kd), repr(float(q[i])), repr(float(qd[i])), "nan"]
            row += ["0.0", "0.0", "0.0"] if held_columns else []
            w.writerow(row + [f"{ts[i]:.6f}"])
        data = f.getvalue().encode()
    if gzip:
        packed = bytearray(_gzip.compress(data, compresslevel=9, mtime=0))
        # the OS byte gzip writes on Linux (Python's module writes 255, "unknown")
        packed[9] = 3
        data = bytes(packed)
    path.write_bytes(data)
    return path


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
