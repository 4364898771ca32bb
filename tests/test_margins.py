"""`pupper gains --motor ... --sensing-delay ...`: the phase and gain margin
of each joint's loop as the firmware closes it, re-checked here from the
reported inertia with the closed form of a PD on a delayed double
integrator; latency in the feedback path costs margin, a command delay
does not."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest


def gains(run, *args: str) -> dict:
    return json.loads(run("gains", "--json", *args, check=0).stdout)


def closed_form(inertia: float, kp: float, kd: float, latency: float) -> float:
    """Phase margin (deg) of (kp + kd s) e^{-s latency} / (J s^2)."""
    w = np.logspace(-1, 6, 200001)
    mag = np.sqrt(kp**2 + (kd * w) ** 2) / (inertia * w**2)
    k = int(np.argmax(mag <= 1.0))
    lo, hi = w[k - 1], w[k]
    for _ in range(80):  # bisection on |L| = 1
        mid = math.sqrt(lo * hi)
        if math.hypot(kp, kd * mid) / (inertia * mid**2) > 1.0:
            lo = mid
        else:
            hi = mid
    wc = math.sqrt(lo * hi)
    return math.degrees(math.atan2(kd * wc, kp) - wc * latency)


def test_margins_match_the_closed_form_and_the_issue_figures(run):
    r = gains(run, "--kp", "10", "--kd", "1", "--motor", "rate=500", "--sensing-delay", "0.001")
    assert r["feedback"]["latency"] == pytest.approx(0.002)  # 1 ms + half of 2 ms
    for j in r["joints"]:
        want = closed_form(j["inertia"], 10, 1, 0.002)
        assert j["phase_margin_deg"] == pytest.approx(want, abs=1e-4), j["actuator"]
    knee = next(g for g in r["groups"] if g["group"] == "kfe")
    assert 24 < knee["phase_margin_deg"] < 29 and knee["gain_margin_db"] > 0
    stiff = gains(run, "--kp", "120", "--kd", "2", "--motor", "rate=500", "--sensing-delay", "0.001")
    assert next(g for g in stiff["groups"] if g["group"] == "kfe")["phase_margin_deg"] < -30


def test_feedback_latency_costs_margin_a_command_delay_does_not(run):
    base = ["--kp", "10", "--kd", "0.5", "--sensing-delay", "0.001"]
    pm = lambda motor: [j["phase_margin_deg"] for j in gains(run, *base, "--motor", motor)["joints"]]  # noqa: E731
    fast, slow = pm("rate=1000"), pm("rate=250")
    assert all(s < f for s, f in zip(slow, fast))
    assert all(f < a for f, a in zip(pm("rate=1000,filter=100"), fast))
    assert all(c < a for c, a in zip(pm("rate=1000,counts=16384"), fast))
    assert pm("rate=1000,delay=0.01") == fast  # a command delay stays out of the loop
    # without a firmware the report is as before: no margins
    plain = gains(run, "--kp", "10", "--kd", "0.5")
    assert "feedback" not in plain and "phase_margin_deg" not in plain["joints"][0]


HINGE = Path(__file__).parent / "models" / "hinge1.xml"


@pytest.mark.parametrize("motor", ["lag=0.01", "filter=200,lag=0.004,counts=16384"])
def test_the_calibrated_loop_is_the_simulated_joint(run, tmp_path, motor):
    """One loop, two views (issue 59): on one hinge of known inertia, the
    closed loop a calibrated servo's margins close (`loop_response(...,
    fitted=True)`: the sampled loop, its PD every physics step) is the
    simulated sine response through the same firmware in torque mode."""
    from pupper_core._native import loop_response

    hz = [1.0, 4.0, 10.0, 20.0]
    lin = loop_response(0.01, 2.0, 0.2, hz, motor=motor, timestep=0.0005, fitted=True)
    for f, (g_lin, p_lin) in zip(hz, lin):
        out = tmp_path / f"r{f:g}"
        run("response", "--model", HINGE, "--mode", "torque", "--motor", motor, "--kp", "2", "--kd", "0.2",
            "--signal", "sine", "--frequency", f, "--amplitude", "0.2", "--seconds", max(8.0, 0.5 + 24 / f),
            "--pose", "0", "-o", out, "-q", check=0)
        with open(out / "bode.csv", newline="") as fh:
            row = next(csv.DictReader(fh))
        g_sim, p_sim = float(row["gain_db"]), float(row["phase_deg"])
        d_phase = (p_sim - p_lin + 180) % 360 - 180
        # the sine is fitted from its start: what is left of the start-up transient is all that differs
        assert abs(g_sim - g_lin) < 0.1 and abs(d_phase) < 1.0, (f, g_sim, g_lin, p_sim, p_lin)


def test_a_negative_sensing_delay_is_one_line(run):
    p = run("gains", "--kp", "10", "--kd", "1", "--sensing-delay", "-1", check=2)
    assert "--sensing-delay -1" in p.stderr and len(p.stderr.strip().splitlines()) == 1


def test_python_gives_the_same_margins(run):
    import pupper_core as pc

    cli = gains(run, "--kp", "10", "--kd", "1", "--motor", "rate=500", "--sensing-delay", "0.001")
    py = pc.gains(kp=10, kd=1, motor="rate=500", sensing_delay=0.001)
    assert [j["phase_margin_deg"] for j in py["joints"]] == [j["phase_margin_deg"] for j in cli["joints"]]
