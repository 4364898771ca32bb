"""Benchmark (issue 60): a fit through the servo firmware against the same
fit through MuJoCo's own servo, in one run, and a default fit of a leg's
bench logs.

Run from the repository root, after `make setup PUPPER_EXTRAS=fit`:

    .venv/bin/python benches/bench_fit_firmware.py            # both parts
    .venv/bin/python benches/bench_fit_firmware.py --quick    # the ratio only

1. The ratio: two one-motor 20 s logs at 250 Hz (the real hip's, at kp 5
   and 7.5, from ../shared/real_logs; else the stand-in's of
   examples/stand_log.py at the same gains) fitted with the parameters a
   servo can carry (armature, damping, friction loss, the gain scales, the
   command delay, the torque limit: MuJoCo's servo, mujoco.rollout), then
   the same plus the torque lag (the firmware: the Rust core's, between the
   steps of a MuJoCo batch). Target: the firmware fit costs at most 1.5x
   the servo fit.
2. A leg's default fit: six one-motor 20 s logs at 250 Hz, three motors at
   kp 5 with kd 0.25 and 0.5, in the real logs' own format (the stand-in
   writes them: it holds a real motor's torque lag, delay and friction).
   Target: under 60 s wall on 2 cores.

Each fit says how many rollouts of a log it ran and what one replay of
every log costs, so the floor (rollouts x one replay / logs) is visible
beside the wall time.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import pupper_core as pc

REPO = Path(__file__).resolve().parent.parent
REAL = REPO.parent / "shared" / "real_logs"
sys.path.insert(0, str(REPO / "examples"))

SERVO = "armature,damping,frictionloss,kp_scale,kd_scale,delay,torque_limit"


def hip_logs(d: Path) -> list[Path]:
    """The real hip's logs at kp 5 and 7.5 (motor 3), else the stand-in's."""
    real = [REAL / f"freq_sweep_motor_3_min_1Hz_max_20Hz_amp_0.5rad_kp_{kp}_kd_0.25.csv.gz" for kp in ("5", "7.5")]
    if all(p.is_file() for p in real):
        return real
    return [stand(d, 3, kp, 0.25, seed) for seed, kp in enumerate((5.0, 7.5))]


def stand(d: Path, motor: int, kp: float, kd: float, seed: int) -> Path:
    """A stand-in's log of one motor in the real logs' format."""
    from stand_log import TRUTH, stand_log

    out = d / f"freq_sweep_motor_{motor}_min_1Hz_max_20Hz_amp_0.5rad_kp_{kp:g}_kd_{kd:g}.csv.gz"
    name = pc.info()["actuators"][motor]["name"]
    return stand_log(out, kp=kp, kd=kd, seed=seed, truth=TRUTH, gzip=True, motor_name=name, real2sim=True)


def timed(logs: list[Path], params: str | None) -> tuple[float, pc.FitResult]:
    kw = {} if params is None else {"params": params}
    t = time.perf_counter()
    r = pc.fit(logs, gains_from_name="kp_{kp}_kd_{kd}", progress=False, **kw)
    return time.perf_counter() - t, r


def said(label: str, wall: float, r: pc.FitResult, logs: int) -> str:
    floor = r.rollouts * r.replay_seconds / logs
    return (f"{label}: {wall:.1f} s wall; {r.rollouts} rollouts of a log, one replay of the {logs} logs "
            f"{r.replay_seconds:.3f} s: the rollouts alone {floor:.1f} s")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="the servo-against-firmware ratio only")
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        logs = hip_logs(d)
        print(f"logs: {', '.join(x.name for x in logs)}")
        ts, rs = timed(logs, SERVO)
        print(said("servo fit (MuJoCo's servo)", ts, rs, len(logs)))
        tf, rf = timed(logs, SERVO + ",lag")
        print(said("firmware fit (the same + lag)", tf, rf, len(logs)))
        print(f"firmware / servo: {tf / ts:.2f}x (target: at most 1.5x)")
        if a.quick:
            return
        leg = [stand(d, motor, 5.0, kd, 10 * motor + i) for motor in (0, 1, 2) for i, kd in enumerate((0.25, 0.5))]
        t, r = timed(leg, None)
        print(said("a leg's default fit, six logs", t, r, len(leg)))
        print(f"  target: under 60 s wall on 2 cores: {'met' if t < 60 else 'MISSED'}")


if __name__ == "__main__":
    main()
