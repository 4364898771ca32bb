"""A robot that is not Pupper, as a user brings one (issue 40's own-robot
edges): errors in the CLI's words, `info` showing what a run uses, a start
from a pose that is not a stand said, and the default push scaled to the
robot's mass (Pupper's −25 N unchanged). Real MuJoCo on tests/models/:
crawler8 (8 kg, <motor> actuators clipped by their control range, no
keyframe) and trotter15 (15.2 kg, position servos, a home keyframe)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from conftest import assert_refused, read_csv

MODELS = Path(__file__).parent / "models"
CRAWLER = MODELS / "crawler8.xml"
TROTTER = MODELS / "trotter15.xml"
#: Pupper v3's mass as the default push's rule states it (kg).
PUPPER_KG = 3.17


def _push(run_dir: Path) -> list[float]:
    return json.loads((run_dir / "manifest.json").read_text())["config"]["schedule"]["push"]["force"]


def test_info_shows_a_motor_without_gains_and_the_limit_a_run_clips_at(run):
    out = run("info", "--model", CRAWLER, check=0).stdout
    rows = [ln for ln in out.splitlines() if "_motor " in ln]
    assert len(rows) == 12, out
    for row in rows:
        # kp and kd '-', the torque limit its control range, marked so
        assert row.split()[4:] == ["-", "-", "[-8,", "8]", "(ctrlrange)"], row
    assert "a motor, no servo gains of its own" in out and "--kp/--kd" in out
    assert "unlimited" not in out and "kp 1" not in out


def test_a_run_clips_a_motor_at_the_limit_info_shows(run, tmp_path):
    run("sweep", "--model", CRAWLER, "--mode", "torque", "--grid", "kp=40", "--kd", "0.5",
        "--seconds", "1", "--no-push", "-o", "run", "-q", check=0)
    m = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert m["torque_limits"] == [8.0] * 12, m["torque_limits"]


def test_the_cli_says_a_core_error_in_its_own_words_and_python_in_its(run, tmp_path):
    """tune's work is in Python; an error the Rust core raises inside it
    reaches the command line as the CLI says it (`--kp`), and the Python
    API as Python says it (`kp=`)."""
    pytest.importorskip("optuna")
    pc = pytest.importorskip("pupper_core")
    out = tmp_path / "study"
    p = run("tune", "--model", CRAWLER, "--space", "kp=5:50", "--trials", "2", "--batch", "2",
            "--seconds", "1", "-o", out)
    assert_refused(p, "no PD gains of its own", out)
    assert "give --kp and --kd" in p.stderr and "kp=" not in p.stderr, p.stderr
    with pytest.raises(pc.ConfigError, match="give kp= and kd=") as e:
        pc.tune(space=["kp=5:50"], trials=2, batch=2, seconds=1, model=str(CRAWLER), out=None)
    assert "--kp" not in str(e.value)
    # a number JSON cannot carry is refused, not dropped into the default
    p = run("tune", "--space", "kd=0.1:1", "--trials", "2", "--kp", "nan", "-o", out)
    assert_refused(p, "--kp NaN is not a finite number", out)
    p = run("tune", "--space", "kd=0.1:1", "--trials", "2", "--push-force", "inf", "-o", out)
    assert_refused(p, "--push-force inf is not a finite number", out)


def test_a_start_without_keyframe_is_said_where_it_applies(run, tmp_path):
    words = "has no keyframe: starting from its default pose (qpos0)"
    p = run("sweep", "--model", CRAWLER, "--grid", "kp=30", "--kd", "0.5", "--seconds", "2",
            "--no-push", "-o", "sweep", "-q", check=0)
    notes = [ln for ln in p.stderr.splitlines() if words in ln]
    assert len(notes) == 1 and notes[0].startswith("note:") and "not a stand pose" in notes[0], p.stderr
    m = json.loads((tmp_path / "sweep" / "manifest.json").read_text())
    assert len(m["start_notes"]) == 1 and words in m["start_notes"][0]
    assert words in (tmp_path / "sweep" / "report.html").read_text()
    p = run("hold", "--model", CRAWLER, "--grid", "kp=30", "--kd", "0.5", "-o", "hold", "-q", check=0)
    assert sum(words in ln for ln in p.stderr.splitlines()) == 1, p.stderr
    assert words in (tmp_path / "hold" / "report.html").read_text()
    # a model with its home keyframe, and response (a searched stand pose): unsaid
    p = run("sweep", "--model", TROTTER, "--grid", "kp=50", "--seconds", "2", "--no-push",
            "-o", "trotter", "-q", check=0)
    assert "keyframe" not in p.stderr, p.stderr
    assert "start_notes" not in json.loads((tmp_path / "trotter" / "manifest.json").read_text())
    p = run("response", "--model", CRAWLER, "--grid", "kp=10", "--kd", "0.5", "--seconds", "1",
            "--joints", "kfe", "-o", "response", "-q", check=0)
    assert "keyframe" not in p.stderr, p.stderr


def test_the_default_push_scales_with_the_robots_mass(run, tmp_path):
    # Pupper: the chapter's -25 N, as every earlier run had it, and no note
    p = run("sweep", "--grid", "kp=5", "--seconds", "2", "-o", "pupper", "-q", check=0)
    assert _push(tmp_path / "pupper") == [0.0, 0.0, -25.0]
    assert "the push is" not in p.stderr
    for model, kg in ((CRAWLER, 8.0), (TROTTER, 15.2)):
        info = json.loads(run("info", "--model", model, "--json", check=0).stdout)
        assert abs(info["total_mass"] - kg) < 1e-9
        want = round(-25 * info["total_mass"] / PUPPER_KG, 1)
        out = f"run_{model.stem}"
        p = run("sweep", "--model", model, "--grid", "kp=30", "--kd", "0.5", "--seconds", "2",
                "-o", out, "-q", check=0)
        assert _push(tmp_path / out) == [0.0, 0.0, want], want
        said = [ln for ln in p.stderr.splitlines() if "the push is" in ln]
        assert len(said) == 1 and f"{want} N" in said[0] and "3.17 kg" in said[0], p.stderr
        assert "--push-force" in said[0]
    assert _push(tmp_path / "run_trotter15")[2] == -119.9
    # the same newtons per kilogram
    assert math.isclose(-119.9 / 15.2, -25 / PUPPER_KG, rel_tol=1e-3)
    # a given force is used as given, also -25 N on another robot
    p = run("sweep", "--model", TROTTER, "--grid", "kp=50", "--seconds", "2", "--push-force", "-25",
            "-o", "given", "-q", check=0)
    assert _push(tmp_path / "given") == [0.0, 0.0, -25.0] and "the push is" not in p.stderr
    # a push_force axis is the cells' own
    run("sweep", "--model", TROTTER, "--grid", "push_force=-10,-20", "--seconds", "2",
        "-o", "axis", "-q", check=0)
    _, rows = read_csv(tmp_path / "axis" / "summary.csv")
    assert [r["push_force"] for r in rows] == ["-10", "-20"]
    # said in --help
    help_text = " ".join(run("sweep", "--help", check=0).stdout.split())
    assert "-25 N x mass / 3.17 kg" in help_text, help_text


def test_python_takes_the_same_rule(tmp_path):
    pc = pytest.importorskip("pupper_core")
    pc.sweep({"kp": [30]}, kd=0.5, model=str(CRAWLER), seconds=2, progress=False, out=tmp_path / "a")
    assert _push(tmp_path / "a") == [0.0, 0.0, -63.1]
    pc.sweep({"kp": [30]}, kd=0.5, model=str(CRAWLER), seconds=2, push_force=-25, progress=False,
             out=tmp_path / "b")
    assert _push(tmp_path / "b") == [0.0, 0.0, -25.0]
    pc.sweep({"kp": [5]}, seconds=2, progress=False, out=tmp_path / "c")
    assert _push(tmp_path / "c") == [0.0, 0.0, -25.0]


def test_recommend_searches_motors_below_the_caps_it_is_given(run, tmp_path):
    """A motor has no gains of its own to search around: recommend asks for
    the caps, and takes them (it asked for them before and refused them)."""
    pytest.importorskip("optuna")
    out = tmp_path / "rec"
    p = run("recommend", "--model", CRAWLER, "--trials", "2", "-o", out)
    assert_refused(p, "are motors, with no PD gains of their own", out)
    assert "--kp-max and --kd-max" in p.stderr
    p = run("recommend", "--model", CRAWLER, "--kp-max", "60", "--kd-max", "2", "--trials", "2",
            "--robots", "2", "-o", out, timeout=600, check=0)
    _, rows = read_csv(out / "trials.csv")
    assert rows
    for r in rows:
        for g in ("haa", "hfe", "kfe"):
            assert 0 < float(r[f"kp.{g}"]) <= 60 and 0 < float(r[f"kd.{g}"]) <= 2, r
