"""An answer on the real robot (issue 59): real Pupper v3 bench logs of
one leg's three motors (``../shared/real_logs``, gzipped as the robot
wrote them, read with no map), one `pupper fit` of all of them, and what
the tools then say of the gains the robot ran on the bench.

- The loop the margins close is the one the fit found: its torque lag,
  latency and damping, nothing stacked on top; every gain the logs were
  recorded at comes out stable (`gains --from-fit`).
- One loop, two views: the closed loop the margins' model predicts
  (`loop_response`) is the simulated sine response of the calibrated
  model through the same firmware (`response --mode torque`), within 1 dB
  and 5° from 1 to 20 Hz, at the gains in use and at recommend's pick.
- The robots recommend stands its candidates on are ones the logs allow.
- `recommend --from-fit` with the robot's caps names gains.

Skipped where the real logs are absent; none is copied into the project."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pupper_core as pc
import pytest

from conftest import REPO, read_csv

pytest.importorskip("scipy", reason="the fit extra (make test installs it)")
pytest.importorskip("optuna", reason="the tune extra (make test installs it)")

REAL = REPO.parent / "shared" / "real_logs"
pytestmark = pytest.mark.skipif(not REAL.is_dir(), reason="no real logs here (../shared/real_logs)")

#: The logged leg's actuators (the logs' motor_idx 3, 4, 5) and each one's sine amplitude (rad).
LOGGED = {"leg_front_l_1": 0.3, "leg_front_l_2": 0.15, "leg_front_l_3": 0.3}
HZ = [1.0, 2.0, 5.0, 10.0, 15.0, 20.0]


@pytest.fixture(scope="module")
def fitted(tmp_path_factory, run) -> Path:
    """One default fit of every real log, as the robot wrote them."""
    d = tmp_path_factory.mktemp("real_answer")
    logs = sorted(REAL.glob("*.csv.gz"))
    run("fit", *logs, "--gains-from-name", "kp_{kp}_kd_{kd}", "-o", d / "fit", cwd=d, check=0)
    return d / "fit"


@pytest.fixture(scope="module")
def run(pupper_bin):
    """The module's own runner (the conftest one is per test)."""
    import subprocess

    from conftest import TIMEOUT_S, clean_env

    def _run(*args, cwd: Path, check: int | None = None):
        p = subprocess.run([str(pupper_bin), *map(str, args)], cwd=str(cwd), env=clean_env(), capture_output=True,
                           text=True, timeout=TIMEOUT_S)
        assert check is None or p.returncode == check, f"exit {p.returncode}\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}"
        return p

    return _run


def logged_gains() -> set[tuple[float, float]]:
    """The (kp, kd) the real logs were recorded at, from their names."""
    import re

    out = set()
    for p in REAL.glob("*.csv.gz"):
        m = re.search(r"kp_([0-9.]+)_kd_([0-9.]+)\.csv", p.name)
        assert m, p.name
        out.add((float(m.group(1)), float(m.group(2))))
    return out


def test_every_gain_the_logs_were_recorded_at_comes_out_stable(fitted, run):
    """`gains --from-fit`: the loop the fit found, per joint, stable at
    every gain the bench ran (positive phase and gain margin on every
    joint), with the fitted lag in it."""
    for kp, kd in sorted(logged_gains()):
        p = run("gains", "--from-fit", fitted, "--kp", kp, "--kd", kd, "--json", cwd=fitted.parent, check=0)
        r = json.loads(p.stdout)
        assert r["fitted"] is True
        for j in r["joints"]:
            assert j["phase_margin_deg"] > 0 and j["gain_margin_db"] > 0, (kp, kd, j)
            assert j["loop"]["torque_lag"] > 0.001, j  # the fit's lag is in the loop
    # what the tools used to stack on top (2 ms of sensing, a 500 Hz firmware) is not added by default
    plain = json.loads(run("gains", "--from-fit", fitted, "--kp", 5, "--kd", 0.25, "--json",
                           cwd=fitted.parent, check=0).stdout)
    stacked = json.loads(run("gains", "--from-fit", fitted, "--kp", 5, "--kd", 0.25, "--json", "--sensing-delay",
                             0.002, cwd=fitted.parent, check=0).stdout)
    worst = lambda r: min(j["phase_margin_deg"] for j in r["joints"])  # noqa: E731
    assert worst(stacked) < worst(plain) - 5


def _simulated(fitted: Path, run, actuator: str, kp: float, kd: float, amp: float, d: Path) -> list[tuple[float, float]]:
    """The calibrated model's sine response of one joint at each of HZ,
    through its fitted firmware (torque mode): (gain dB, phase deg)."""
    out = []
    for hz in HZ:
        o = d / f"{actuator}_{kp:g}_{kd:g}_{hz:g}"
        seconds = max(3.0, 0.5 + 4.0 / hz)
        run("response", "--model", fitted / "calibrated.xml", "--mode", "torque", "--kp", kp, "--kd", kd,
            "--signal", "sine", "--frequency", hz, "--amplitude", amp, "--joints", actuator, "--seconds", seconds,
            "-o", o, "-q", cwd=d, check=0)
        _, rows = read_csv(o / "bode.csv")
        (row,) = [r for r in rows if r["joint"] == actuator]
        out.append((float(row["gain_db"]), float(row["phase_deg"])))
    return out


def _linearised(fitted: Path, actuator: str, kp: float, kd: float) -> list[tuple[float, float]]:
    """The closed loop of the margins' model of the same joint (its loop
    as `gains` reads it from the calibrated model), target delayed by the
    fitted command delay."""
    from pupper_core._native import loop_response

    model = str(fitted / "calibrated.xml")
    g = pc.gains(model, kp=kp, kd=kd)
    (j,) = [j for j in g["joints"] if j["actuator"] == actuator]
    (a,) = [a for a in pc.info(model)["actuators"] if a["name"] == actuator]
    dkp, dkd = j.get("delivered", [kp, kd])
    return loop_response(j["inertia"], dkp, dkd, HZ, timestep=g["timestep"], damping=j["loop"]["damping"],
                         lag=a.get("lag", 0.0), latency=a.get("latency", 0.0), command_delay=a.get("delay", 0.0),
                         fitted=True)


def _agree(sim: list[tuple[float, float]], lin: list[tuple[float, float]], what: str) -> None:
    for hz, (gs, ps), (gl, pl) in zip(HZ, sim, lin):
        dphase = (ps - pl + 180.0) % 360.0 - 180.0
        assert abs(gs - gl) <= 1.0 and abs(dphase) <= 5.0, (
            f"{what} at {hz:g} Hz: simulated {gs:.2f} dB {ps:.1f}°, linearised {gl:.2f} dB {pl:.1f}°")


@pytest.mark.parametrize("actuator", sorted(LOGGED))
def test_the_margins_loop_is_the_simulated_one_at_the_gains_in_use(fitted, run, actuator, tmp_path):
    """At the gains the robot walks on (kp 5, kd 0.25), each logged joint's
    linearised closed loop is its simulated sine response."""
    _agree(_simulated(fitted, run, actuator, 5.0, 0.25, LOGGED[actuator], tmp_path),
           _linearised(fitted, actuator, 5.0, 0.25), f"{actuator} at kp 5 kd 0.25")


def test_the_robots_the_logs_allow_follow_them(fitted):
    """Drawn from the fit's joint distribution and kept near its logs:
    every robot's RMS error within the stated ratio of the fit's."""
    m = json.loads((fitted / "manifest.json").read_text())["robots"]
    assert m["count"] == 8 and len(m["rms_rad"]) == 8
    assert m["worst_over_fitted"] <= m["ratio"] * 1.05, m
    with open(fitted / "robots.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 8
    # they differ from each other (a spread, not the fit eight times)
    assert len({r["kp_scale"] for r in rows}) == 8


def test_recommend_names_gains_on_the_real_fit_and_they_agree_with_the_simulation(fitted, run, tmp_path):
    """`recommend --from-fit` with the robot's caps and the gains it runs
    today names gains (a quick search: the defaults are benchmarked), the
    gains in use beside them; the pick's loop is its simulated one too."""
    out = tmp_path / "rec"
    p = run("recommend", "--from-fit", fitted, "--kp-max", 10, "--kd-max", 1, "--current", "5,0.25", "--robots", 8,
            "--trials", 8, "--batch", 8, "--polish", 1, "-q", "-o", out, cwd=tmp_path, check=0)
    assert p.stdout.startswith("recommended gains"), p.stdout
    assert "in use (--current: kp 5 kd 0.25 on every group)" in p.stdout
    assert "the loop the fit found" in p.stdout and "nominal robot" not in p.stdout
    _, cards = read_csv(out / "recommend.csv")
    for c in cards:
        assert 0 < float(c["kp"]) <= 10 and 0 <= float(c["kd"]) <= 1, c
        assert float(c["phase_margin_deg"]) >= 30, c
    kfe = next(c for c in cards if c["group"] == "kfe")
    kp, kd = float(kfe["kp"]), float(kfe["kd"])
    actuator = "leg_front_l_3"
    _agree(_simulated(fitted, run, actuator, kp, kd, LOGGED[actuator], tmp_path),
           _linearised(fitted, actuator, kp, kd), f"{actuator} at the pick kp {kp:g} kd {kd:g}")
    assert math.isfinite(float(kfe["gain_margin_db"]))
