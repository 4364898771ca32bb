"""Trust, round 3 (issue 36): no panic on a path that is not UTF-8, a
calibrated model's gain scales checked, grid validation in linear time, and
the Python API as documented. Each test here failed on the release before."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

pc = pytest.importorskip("pupper_core")
mujoco = pytest.importorskip("mujoco")

SCENE = Path(pc.__file__).parent / "models" / "pupper_v3" / "scene.xml"


def _no_panic(proc) -> None:
    assert proc.returncode != 101 and "panicked" not in proc.stderr, proc.stderr
    assert "internal error" not in proc.stderr, proc.stderr


def _odd(tmp_path: Path, name: bytes) -> str:
    """A path under tmp_path whose last part is not UTF-8, as argv holds it."""
    return os.fsdecode(os.fsencode(tmp_path) + b"/" + name)


def test_paths_that_are_not_utf8_reach_excite_and_tune_intact(run, tmp_path: Path) -> None:
    pytest.importorskip("optuna")
    log = _odd(tmp_path, b"ex\xff.csv")
    p = run("excite", "-o", log, "--seconds", "1", "--hold", "0.2")
    _no_panic(p)
    assert p.returncode == 0, p.stderr
    assert os.path.isfile(os.fsencode(log))
    pytest.importorskip("scipy")  # the fit extra
    fit = _odd(tmp_path, b"fit\xfd")
    # what it prints names the log by its bytes
    p = run("fit", log, "--params", "armature", "--max-iters", "2", "-o", fit, errors="replace")
    _no_panic(p)
    assert p.returncode == 0, p.stderr
    assert os.path.isfile(os.fsencode(fit) + b"/fit.csv") and os.path.isfile(os.fsencode(fit) + b"/report.html")
    out = _odd(tmp_path, b"tune\xfe")
    p = run("tune", "--space", "kp=5:50", "--trials", "2", "--batch", "2", "--seconds", "1", "--no-push",
            "-q", "-o", out)
    _no_panic(p)
    assert p.returncode == 0, p.stderr
    assert os.path.isfile(os.fsencode(out) + b"/trials.csv")
    # what it wrote is said by name (lossily shown), not as an error
    assert "wrote" in p.stderr and "trials.csv" in p.stderr


def _scaled(tmp_path: Path, numerics: dict[str, list[float]]) -> Path:
    spec = mujoco.MjSpec.from_file(str(SCENE))
    for name, data in numerics.items():
        spec.add_numeric(name=name, data=data)
    spec.meshdir = str(SCENE.parent)
    path = tmp_path / "calibrated.xml"
    path.write_text(spec.to_xml())
    return path


@pytest.mark.parametrize("numerics, said", [
    ({"pupper:kp_scale:leg_front_r_1": [-1.0]}, "must be a number in (0, 100]"),
    ({"pupper:kd_scale:leg_front_r_3": [-5.0]}, "must be a number in (0, 100]"),
    ({"pupper:kp_scale:leg_front_r_1": [0.0]}, "must be a number in (0, 100]"),
    ({"pupper:kd_scale:leg_back_l_2": [float("nan")]}, "must be a number in (0, 100]"),
    ({"pupper:kp_scale:elbow": [0.9]}, "names no actuator of the model"),
    ({"pupper:kp_scale:leg_front_r_1": [0.9, 1.1]}, "has 2 values"),
])
def test_a_calibrated_models_bad_gain_scale_is_refused(run, tmp_path: Path, numerics, said) -> None:
    model = _scaled(tmp_path, numerics)
    for args in (("sweep", "--seconds", "0.5", "-o", tmp_path / "run"), ("info",)):
        p = run(*args, "--model", model)
        _no_panic(p)
        assert p.returncode == 2, p.stderr
        errors = [ln for ln in p.stderr.splitlines() if ln.startswith("error:")]
        assert len(errors) == 1 and said in errors[0] and list(numerics)[0] in errors[0], p.stderr
    assert not (tmp_path / "run").exists()


def test_a_good_gain_scale_still_runs(run, tmp_path: Path) -> None:
    model = _scaled(tmp_path, {"pupper:kp_scale:leg_front_r_1": [0.9], "other:thing": [1.0, 2.0]})
    p = run("info", "--model", model, "--json", check=0)
    import json

    # a unit scale is not written (the manifests of uncalibrated models are unchanged)
    scales = {a["name"]: a.get("gain_scale", [1.0, 1.0]) for a in json.loads(p.stdout)["actuators"]}
    assert scales["leg_front_r_1"] == [0.9, 1.0] and scales["leg_front_r_2"] == [1.0, 1.0]


def test_a_huge_grid_is_refused_at_once(run, tmp_path: Path) -> None:
    # 20,001 values took 40 s to refuse (a quadratic duplicate check); a
    # range of 10^12 values allocated before the size check
    p = run("sweep", "--grid", "kp=0:20000:20001", "--max-cells", "10", "-o", tmp_path / "a", timeout=20)
    assert p.returncode == 2 and "over the limit of 10" in p.stderr, p.stderr
    p = run("sweep", "--grid", "kp=0:1:1000000000000", "-o", tmp_path / "b", timeout=20)
    assert p.returncode == 2 and "lower the count" in p.stderr, p.stderr
    with pytest.raises(pc.GridError, match="over the limit of 10"):
        pc.sweep({"kp": list(range(100000))}, max_cells=10, progress=False)


def test_gains_and_pose_are_in_python_as_documented() -> None:
    g = pc.gains(kp=120, kd=2)
    worst = max(j["stability_margin"] for j in g["joints"])
    assert worst > 1.0  # the knee past the bound, as `pupper gains` says
    assert all(j["kp"] == 120 and j["kd"] == 2 for j in g["joints"])
    b = pc.gains(bandwidth=8, damping=0.7)
    assert {j["group"] for j in b["joints"]} == {"haa", "hfe", "kfe"}
    with pytest.raises(pc.ConfigError, match="bandwidth=HZ"):
        pc.gains(kp=10)
    p = pc.pose()
    assert len(p["targets"]) == 12 and p["base_z"] > 0 and p["target_z"] == pytest.approx(-0.14)
    assert pc.pose(depth=0.12)["targets"] != p["targets"]


def test_tune_and_fit_errors_are_pupper_errors() -> None:
    for cls in (pc.TuneError, pc.FitError):
        assert issubclass(cls, pc.PupperError) and issubclass(cls, ValueError), cls.__mro__
        assert cls("x").kind == "config"
    assert {"TuneError", "FitError", "gains", "pose"} <= set(pc.__all__)


def test_python_options_take_numpy_numbers_and_refuse_what_they_cannot_mean(tmp_path: Path) -> None:
    np = pytest.importorskip("numpy")
    a = pc.sweep({"kp": [np.float32(10), np.int64(30)]}, kd=np.float32(0.5), seconds=np.float64(0.5),
                 progress=False)
    b = pc.sweep({"kp": [10, 30]}, kd=0.5, seconds=0.5, progress=False)
    assert a.rows == b.rows
    with pytest.raises(pc.ConfigError, match=r"threads=1099511627776 is more than 1024"):
        pc.sweep({"kp": [10]}, threads=2**40, seconds=0.5, progress=False)
    with pytest.raises(pc.GridError, match="non-numeric value True"):
        pc.sweep({"kp": [True, False]}, seconds=0.5, progress=False)
    with pytest.raises(pc.GridError, match="not a number"):
        pc.sweep([{"kp": True, "kd": 1}], seconds=0.5, progress=False)
    with pytest.raises(pc.ConfigError, match="is not a plain value"):
        pc.sweep({"kp": [10]}, seconds=0.5, keyframe=object(), progress=False)
    with pytest.raises(TypeError, match="not a dict"):
        pc.response({"kp": [5]}, joints={"kfe": 1}, seconds=0.5, progress=False)
    with pytest.raises(TypeError, match="not a dict"):
        pc.fit({"a.csv": 1})


def test_threads_past_the_limit_in_the_cli_is_one_line(run, tmp_path: Path) -> None:
    p = run("sweep", "-j", str(2**40), "--seconds", "0.5", "-o", tmp_path / "r")
    _no_panic(p)
    assert p.returncode == 2 and "more than 1024" in p.stderr, p.stderr
    assert not (tmp_path / "r").exists()


def test_huge_numbers_are_printed_in_exponent_form(run, tmp_path: Path) -> None:
    p = run("gains", "--kp", "1e300", "--kd", "1", check=0)
    import re

    assert re.search(r"\d{12}", p.stdout) is None and "1.00e300" in p.stdout, p.stdout
    p = run("sweep", "--grid", "kp=1e300", "--seconds", "0.2", "-q", "-o", tmp_path / "r", check=0)
    assert "worst: kp1e300 on" in p.stderr and "margin 5.51e296" in p.stderr, p.stderr
    assert (tmp_path / "r" / "summary.csv").read_text().splitlines()[1].startswith("0,kp1e300,,1e300,")


def test_a_full_stdout_does_not_suggest_a_resume(pupper_bin: Path, tmp_path: Path) -> None:
    import subprocess

    from conftest import clean_env

    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full here")
    with open("/dev/full", "w") as full:
        p = subprocess.run([str(pupper_bin), "info"], stdout=full, stderr=subprocess.PIPE, text=True,
                           env=clean_env(), cwd=tmp_path, timeout=120)
    assert p.returncode == 2 and "--resume" not in p.stderr and "send the output elsewhere" in p.stderr, p.stderr


def test_a_response_without_a_servo_spring_is_refused(run, tmp_path: Path) -> None:
    p = run("response", "--kp", "0", "--kd", "0", "--seconds", "1", "-o", tmp_path / "r")
    _no_panic(p)
    assert p.returncode == 2 and "kp 0" in p.stderr and "give kp > 0" in p.stderr, p.stderr
    assert not (tmp_path / "r").exists()
    p = run("response", "-g", "kp=0,5", "--seconds", "1", "-o", tmp_path / "g")
    assert p.returncode == 2 and "cell kp0 gives" in p.stderr, p.stderr


def test_a_model_without_a_floor_is_said(run, tmp_path: Path) -> None:
    bare = SCENE.parent / "pupper_v3.xml"  # the robot alone, no scene
    p = run("sweep", "--model", bare, "--seconds", "1", "-q", "-o", tmp_path / "r", check=0)
    assert "has no ground the feet can touch" in p.stderr, p.stderr
    p = run("sweep", "--seconds", "1", "-q", "-o", tmp_path / "s", check=0)
    assert "ground" not in p.stderr, p.stderr
    # hung in the air, a response needs no floor
    p = run("response", "--model", bare, "--seconds", "1", "--joints", "kfe", "-q", "-o", tmp_path / "t",
            check=0)
    assert "ground" not in p.stderr, p.stderr


def test_every_run_directory_names_its_kind(run, tmp_path: Path) -> None:
    import json

    run("sweep", "--seconds", "0.5", "-q", "-o", tmp_path / "s", check=0)
    run("response", "--seconds", "1", "--joints", "kfe", "-q", "-o", tmp_path / "r", check=0)
    run("lab", "--grid", "kp=30", "--grid", "kd=0.5", "--variants", "original", "--seconds", "1.5", "-q",
        "-o", tmp_path / "l", check=0)
    for d, kind in (("s", "sweep"), ("r", "response"), ("l", "lab")):
        manifest = json.loads((tmp_path / d / "manifest.json").read_text())
        assert manifest["kind"] == kind, (d, manifest.get("kind"))
        from pupper_core import _report

        assert _report.kind_of(manifest) == kind
    # a run read back knows how long it took (the manifest says)
    assert pc.load_run(tmp_path / "s").wall_seconds == json.loads(
        (tmp_path / "s" / "manifest.json").read_text())["wall_seconds"]
