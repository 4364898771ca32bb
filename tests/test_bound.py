"""No pick the simulation cannot vouch for (issue 39): a cell whose gains lie
past the stability bound of the PD as the integrator computes it is marked
past_bound and never ranked, in sweep, lab, tune and response; the margins
are re-checked here from the model's own linearisation (`pupper gains`);
--integrator implicitfast runs such gains honestly in servo mode."""

from __future__ import annotations

from pathlib import Path

import pytest

from conftest import read_csv

pc = pytest.importorskip("pupper_core")


def _rows(res) -> list[dict]:
    return [res.row(i) for i in range(len(res))]


def _past(kp: float, kd: float, model: str = "pupper_v3") -> bool:
    """Past the explicit PD's bound on some joint, by `pupper gains`."""
    return max(j["stability_margin"] for j in pc.gains(model, kp=kp, kd=kd)["joints"]) >= 1.0


def test_cells_past_the_bound_are_marked_and_never_picked(run, tmp_path: Path) -> None:
    p = run("sweep", "--grid", "kp=10,60,120", "--grid", "kd=0.5,1,2,5", "--seconds", "4", "-o",
            tmp_path / "s", check=0)
    _, rows = read_csv(tmp_path / "s" / "summary.csv")
    for r in rows:
        past = _past(float(r["kp"]), float(r["kd"]))
        assert (r["status"] == "past_bound") == (past and r["status"] not in ("fell", "diverged")), r
    assert any(r["status"] == "past_bound" for r in rows)
    # the pick is a cell the simulation vouches for, and the output says why
    # the stiff corner was passed over
    best = pc.load_run(tmp_path / "s").best()
    assert best is not None and not _past(float(best["kp"]), float(best["kd"])), best
    assert f"steadiest: {best['id']}," in p.stdout
    assert "marked past_bound and never ranked" in p.stderr and "--integrator implicitfast" in p.stderr
    assert "cell(s) past_bound" in p.stdout
    assert "lies on the edge of the searched range (kp 120, the largest)" in p.stdout


def test_implicit_damping_runs_stiff_damped_gains_as_a_finer_step_does(tmp_path: Path) -> None:
    grid = {"kp": [30, 120], "kd": [2, 5]}
    euler = pc.sweep(grid, seconds=4, progress=False)
    assert {r["status"] for r in _rows(euler)} == {"past_bound"}
    fast = pc.sweep(grid, seconds=4, integrator="implicitfast", progress=False)
    fine = pc.sweep({**grid, "timestep": [0.0002]}, seconds=4, progress=False)
    for f, g in zip(_rows(fast), _rows(fine)):
        # no chatter: off the torque limit, and ranked
        assert f["status"] == "ok" and f["saturation_frac"] < 0.005, f
        # Euler at a tenth of the step agrees to a tenth of a millimetre of
        # push dip and a millimetre of height (stated in docs/sweep.md)
        assert abs(f["push_dip_mm"] - g["push_dip_mm"]) < 0.1, (f, g)
        assert abs(f["final_z"] - g["final_z"]) < 1e-3, (f, g)
    assert fast.best() is not None
    # the manifest keeps the integrator
    out = tmp_path / "r"
    pc.sweep({"kp": [30]}, seconds=1, integrator="implicitfast", out=out, progress=False)
    import json

    assert json.loads((out / "manifest.json").read_text())["config"]["integrator"] == "implicitfast"
    assert pc.load_run(out).row(0)["status"] == "ok"


def test_a_bad_integrator_is_one_line(run, tmp_path: Path) -> None:
    p = run("sweep", "--integrator", "leapfrog", "-o", tmp_path / "x")
    assert p.returncode == 2 and "--integrator leapfrog is unknown" in p.stderr, p.stderr
    assert not (tmp_path / "x").exists()


def test_a_response_marks_the_joints_past_the_bound(tmp_path: Path) -> None:
    res = pc.response({"kp": [5], "kd": [0.1, 2]}, seconds=1, joints="kfe", progress=False)
    joints = _rows(res.tables["response"])
    for r in joints:
        assert (r["status"] == "past_bound") == (float(r["stability_margin"]) >= 1.0), r
    assert {r["status"] for r in joints if float(r["kd"]) == 2} == {"past_bound"}
    # with the servo's damping integrated implicitly, the same joints are
    # inside the bound, and response.csv's margin is that integrator's
    fast = pc.response({"kp": [5], "kd": [2]}, seconds=1, joints="kfe", integrator="implicitfast",
                       progress=False)
    by_joint = {j["actuator"]: j for j in pc.gains(kp=5, kd=2, integrator="implicitfast")["joints"]}
    for r in _rows(fast.tables["response"]):
        assert r["status"] == "ok", r
        assert float(r["stability_margin"]) == pytest.approx(by_joint[r["joint"]]["stability_margin"],
                                                             rel=1e-6), r


def test_the_lab_and_tune_never_pick_past_the_bound(tmp_path: Path) -> None:
    lab = pc.lab(seconds=3, progress=False)
    picks = [r for r in lab.best(by=["variant"]) if r is not None]
    assert picks, "the lab picked nothing"
    # each body is checked on its own inertias (long legs weigh more on
    # their joints): the original's against `pupper gains` on the model
    # (torque mode: the Rust PD is explicit), every pick inside its bound
    for r in picks:
        assert r["status"] == "ok", r
        if r["variant"] == "original":
            assert not _past(float(r["kp"]), float(r["kd"])), r
    pytest.importorskip("optuna")
    t = pc.tune(["kp=5:120:log", "kd=0.05:2:log"], trials=16, batch=8, seconds=3, progress=False)
    best = t.best[0]["params"]
    assert not _past(best["kp"], best["kd"]), best
    # a trial past the bound is told the penalty, never its value
    for row in t.trials:
        if _past(row["kp"], row["kd"]):
            assert row["status"] == "past_bound" and row[t.objectives[0]] >= 1e6, row


def test_gains_states_the_bound_of_the_integrator_asked_for(run) -> None:
    explicit = pc.gains(kp=120, kd=2)
    implicit = pc.gains(kp=120, kd=2, integrator="implicitfast")
    assert "implicit_damping" not in explicit and implicit["implicit_damping"] is True
    for e, i in zip(explicit["joints"], implicit["joints"]):
        h, inertia = 0.002, e["inertia"]
        a, b = h * h * 120 / inertia, h * 2 / inertia
        assert i["stability_margin"] == pytest.approx(a / (4 + 2 * b), rel=1e-12)
        assert e["stability_margin"] == pytest.approx(max((a + 2 * b) / 4, b / 2), rel=1e-12)
    assert max(j["stability_margin"] for j in implicit["joints"]) < 1 <= max(
        j["stability_margin"] for j in explicit["joints"])
    p = run("gains", "--kp", "120", "--kd", "2", "--integrator", "implicitfast", check=0)
    assert "damping integrated implicitly" in p.stdout and "PAST" not in p.stdout
    p = run("gains", "--kp", "120", "--kd", "2", "--integrator", "nope")
    assert p.returncode == 2 and "--integrator nope is unknown" in p.stderr
