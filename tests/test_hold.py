"""`pupper hold` (and `pupper_core.hold`): the robot under a load ramped to
its own weight, then shoved sideways. Real MuJoCo on the built-in model and
on a copy that declares its motors' windings."""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import pupper_core as pc
import pytest

from conftest import read_csv

SCENE = Path(pc.__file__).parent / "models" / "pupper_v3" / "scene.xml"
GRID = ("-g", "kp=3,6,12", "-g", "kd=0.5")


def num(row: dict[str, str], col: str) -> float:
    return float(row[col]) if row[col] else math.nan


@pytest.fixture(scope="module")
def weight() -> float:
    m = mujoco.MjModel.from_xml_path(str(SCENE))
    return float(sum(m.body_mass) * abs(m.opt.gravity[2]))


def test_sag_follows_the_spring_and_the_stiffest_cell_is_picked(run, tmp_path, weight):
    p = run("hold", *GRID, "-o", tmp_path / "h", check=0)
    header, rows = read_csv(tmp_path / "h" / "summary.csv")
    for col in ("sag_mm", "compliance_mm_per_n", "sway_mm", "recovery_s",
                "torque_rms.haa", "torque_rms.hfe", "torque_rms.kfe"):
        assert col in header, col
    assert "copper_w" not in header  # the built-in model declares no windings
    sags = [num(r, "sag_mm") for r in rows]
    # a stiffer servo sags less: about as 1/kp (3 -> 12: a quarter, give or take)
    assert sags[0] > sags[1] > sags[2] > 0
    assert 2.5 < sags[0] / sags[2] < 6
    # compliance is the sag per newton of the model's own weight
    for r in rows:
        assert num(r, "sag_mm") / num(r, "compliance_mm_per_n") == pytest.approx(weight, rel=1e-9)
        assert r["status"] == "ok" and num(r, "sway_mm") > 0
    m = json.loads((tmp_path / "h" / "manifest.json").read_text())
    assert m["kind"] == "hold"
    assert m["config"]["schedule"]["push"]["force"] == pytest.approx([0, -0.25 * weight, 0])
    _, best = read_csv(tmp_path / "h" / "best.csv")
    assert best[0]["id"] == "kp12_kd0.5"
    assert "kp12_kd0.5" in p.stdout and "stiffest cell lies on the edge" in p.stdout
    page = (tmp_path / "h" / "report.html").read_text()
    assert "pupper hold" in page and "compliance_mm_per_n" in page and "kp12_kd0.5" in page
    # the page qualifies the pick as the CLI does: the stiffest kp searched
    assert "kp12_kd0.5 lies on the edge of the searched grid (kp 12, the largest)" in page


def test_twice_the_load_twice_the_sag_and_the_knees_carry_it(run, tmp_path):
    run("hold", *GRID, "-o", tmp_path / "one", check=0)
    run("hold", *GRID, "--load", "2", "-o", tmp_path / "two", check=0)
    _, one = read_csv(tmp_path / "one" / "summary.csv")
    _, two = read_csv(tmp_path / "two" / "summary.csv")
    for a, b in zip(one, two):
        # a linear spring: the same sag per newton
        assert num(b, "compliance_mm_per_n") == pytest.approx(num(a, "compliance_mm_per_n"), rel=0.15)
        # the knees hold the robot and the load: 2 weights, then 3
        assert num(b, "torque_rms.kfe") / num(a, "torque_rms.kfe") == pytest.approx(1.5, rel=0.1)


def test_copper_loss_from_the_declared_windings(run, tmp_path):
    kt, r = 0.2, 0.5
    spec = mujoco.MjSpec.from_file(str(SCENE))
    for a in spec.actuators:
        spec.add_numeric(name=f"pupper:kt:{a.name}", data=[kt])
        spec.add_numeric(name=f"pupper:resistance:{a.name}", data=[r])
    spec.meshdir = str(SCENE.parent)
    model = tmp_path / "wound.xml"
    model.write_text(spec.to_xml())
    run("hold", "--kp", "6", "--kd", "0.5", "--model", model, "-o", tmp_path / "h", check=0)
    header, rows = read_csv(tmp_path / "h" / "summary.csv")
    row = rows[0]
    # copper = R/kt^2 * sum over motors of mean tau^2 = R/kt^2 * sum over groups of n * rms^2
    assert all(a["winding"] == [kt, r] for a in pc.info(str(model))["actuators"])
    counts = {"haa": 4, "hfe": 4, "kfe": 4}  # Pupper's four legs
    want = r / kt**2 * sum(n * num(row, f"torque_rms.{g}") ** 2 for g, n in counts.items())
    assert num(row, "copper_w") == pytest.approx(want, rel=1e-9)
    # one constant without the other is refused, in one line
    spec = mujoco.MjSpec.from_file(str(SCENE))
    name = spec.actuators[0].name
    spec.add_numeric(name=f"pupper:kt:{name}", data=[kt])
    spec.meshdir = str(SCENE.parent)
    half = tmp_path / "half.xml"
    half.write_text(spec.to_xml())
    p = run("hold", "--kp", "6", "--model", half, "-o", tmp_path / "x", check=2)
    assert f"pupper:resistance:{name}" in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("args, words", [
    (("--shove-at", "2"), "leave 0.5 s of steady load"),
    (("--ramp", "-1"), "--ramp -1 must be"),
    (("--load", "50"), "at most 10"),
    (("--seconds", "3"), "--seconds 3 ends before"),
    (("-g", "push_force=1,2"), "drop the push_force grid axis"),
])
def test_bad_input_is_one_line_and_writes_nothing(run, tmp_path, args, words):
    p = run("hold", "--kp", "6", *args, "-o", tmp_path / "x", check=2)
    assert words in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert not (tmp_path / "x").exists()


def test_python_hold_matches_the_cli_byte_for_byte(run, tmp_path):
    run("hold", *GRID, "-j", "1", "-o", tmp_path / "cli", check=0)
    res = pc.hold({"kp": [3, 6, 12], "kd": [0.5]}, out=tmp_path / "py", progress=False, threads=3)
    assert (tmp_path / "py" / "summary.csv").read_bytes() == (tmp_path / "cli" / "summary.csv").read_bytes()
    assert res.best()["id"] == "kp12_kd0.5"
    assert res.best("sway_mm")["id"] in {"kp3_kd0.5", "kp6_kd0.5", "kp12_kd0.5"}
    with pytest.raises(pc.ConfigError, match="one robot per cell"):
        pc.hold({"kp": [6]}, progress=False, replicates=4)
    # a finished hold resumes to nothing left to do
    p = run("hold", "--resume", tmp_path / "cli", check=0)
    assert "nothing left to run" in p.stdout


def test_shards_merge_into_the_whole_run(run, tmp_path):
    """--shard I/N, a flag hold shares with sweep and response: each shard
    runs its part of the grid, and `pupper merge` puts the whole together."""
    run("hold", *GRID, "-q", "-o", tmp_path / "whole", check=0)
    for i in (1, 2):
        run("hold", *GRID, "--shard", f"{i}/2", "-q", "-o", tmp_path / f"s{i}", check=0)
    _, rows = read_csv(tmp_path / "s1" / "summary.csv")
    assert [r["id"] for r in rows] == ["kp3_kd0.5", "kp12_kd0.5"]
    assert json.loads((tmp_path / "s1" / "manifest.json").read_text())["shard"]["index"] == 1
    run("merge", tmp_path / "s1", tmp_path / "s2", "-o", tmp_path / "merged", check=0)
    assert (tmp_path / "merged" / "summary.csv").read_bytes() == (tmp_path / "whole" / "summary.csv").read_bytes()
