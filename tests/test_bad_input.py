"""Bad input: exit status 2, exactly one `error: ...` line that names the
problem (and the fix), no traceback or panic, and nothing left on disk.

The same mistakes through the Python API raise the matching PupperError
subclass with the same message.
"""

from __future__ import annotations

import os
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from conftest import REPO

GARBAGE_MJCF = "<mujoco><worldbody><body>"
# A free base, a floor, a keyframe named home, but no actuators.
NO_ACTUATOR_MJCF = """<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="base_link" pos="0 0 0.3">
      <freejoint name="root"/>
      <geom type="box" size="0.1 0.05 0.03" mass="1"/>
    </body>
  </worldbody>
  <keyframe><key name="home" qpos="0 0 0.3 1 0 0 0"/></keyframe>
</mujoco>
"""

FORBIDDEN = ("Traceback", "panicked", "incompatible function arguments", "RUST_BACKTRACE")


@dataclass
class Case:
    id: str
    args: list[str]
    phrases: list[str]
    # add `-o <tmp>/out` (sweep) and check it is not created
    out: bool = True
    setup: str | None = None
    env: dict = field(default_factory=dict)


CASES = [
    Case("unknown-axis", ["sweep", "--grid", "kq=1"],
         ["unknown grid axis 'kq'", "did you mean 'kp'"]),
    Case("empty-value", ["sweep", "--grid", "kp="], ["grid axis 'kp' has no values"]),
    Case("empty-list-item", ["sweep", "--grid", "kp=1,,2"], ["grid axis 'kp' has an empty value"]),
    Case("non-numeric", ["sweep", "--grid", "kp=abc"], ["non-numeric value 'abc'"]),
    Case("nan", ["sweep", "--grid", "kp=nan"], ["non-finite value 'nan'", "finite numbers"]),
    Case("inf", ["sweep", "--grid", "kp=inf"], ["non-finite value 'inf'", "finite numbers"]),
    Case("range-count-0", ["sweep", "--grid", "kp=1:2:0"], ["count 0", "at least 1"]),
    Case("log-range-through-zero", ["sweep", "--grid", "kp=0:10:3:log"],
         ["log range", "both ends must be > 0"]),
    Case("no-equals", ["sweep", "--grid", "kp"], ["has no '='", "AXIS=VALUES"]),
    Case("negative-gain", ["sweep", "--grid", "kp=-1"], ["'kp' has value -1", "gains must be >= 0"]),
    Case("negative-kp-flag", ["stand", "--kp=-1"], ["--kp -1", ">= 0"], out=False),
    Case("negative-max-torque", ["sweep", "--max-torque", "-1"],
         ["max torque -1 is not positive", "--max-torque"]),
    Case("negative-max-torque-eq", ["sweep", "--max-torque=-1"],
         ["max torque -1 is not positive", "--max-torque"]),
    Case("duplicate-axis", ["sweep", "--grid", "kp=1", "--grid", "kp=2"],
         ["'kp' is given twice", "merge"]),
    Case("over-max-cells",
         ["sweep", "--grid", "kp=1:2:100", "--grid", "kd=1:2:100", "--max-cells", "1000"],
         ["10000 cells", "1000", "--max-cells"]),
    Case("missing-model", ["sweep", "--model", "{tmp}/nope.xml"], ["does not exist", "check the path"]),
    Case("missing-model-bare-name", ["stand", "--model", "pupper_v4"],
         ["does not exist", "not a built-in model"], out=False),
    Case("unreadable-model", ["sweep", "--model", "{tmp}/unreadable.xml"],
         ["cannot be read", "permissions"], setup="unreadable"),
    Case("invalid-mjcf", ["sweep", "--model", "{tmp}/garbage.xml"],
         ["is not valid MJCF", "parse error"], setup="garbage"),
    Case("invalid-mjcf-info", ["info", "--model", "{tmp}/garbage.xml"],
         ["is not valid MJCF", "parse error"], setup="garbage", out=False),
    Case("fixed-base-sweep", ["sweep", "--model", "pupper_v3_fixed"],
         ["no free-joint base", "freejoint"]),
    Case("fixed-base-stand", ["stand", "--model", "pupper_v3_fixed"],
         ["no free-joint base", "freejoint"], out=False),
    Case("no-actuators", ["sweep", "--model", "{tmp}/noact.xml"], ["has no actuators"],
         setup="noact"),
    Case("out-exists", ["sweep", "--seconds", "1"], ["already exists", "--force", "--resume"],
         setup="out-exists"),
    Case("unknown-preset", ["sweep", "--preset", "nope"], ["unknown preset 'nope'", "chapter-4.6"]),
    Case("old-lab-preset", ["sweep", "--preset", "lab"], ["now 'lab-grid'", "pupper lab"]),
    Case("lab-random-push", ["lab", "--replicates", "2", "--randomize", "push_at=1:2"], ["this run has none", "pupper sweep"]),
    Case("bad-pose-length", ["sweep", "--pose", "1,2,3"],
         ["pose has 3 angles", "12 actuated joints"]),
    Case("bad-pose-length-stand", ["stand", "--pose", "0.1,0.2"],
         ["pose has 2 angles", "12 actuated joints"], out=False),
    Case("unknown-keyframe", ["sweep", "--keyframe", "nope"], ["no keyframe 'nope'", "home"]),
    Case("unknown-keyframe-stand", ["stand", "--keyframe", "nope"], ["no keyframe 'nope'", "home"],
         out=False),
    Case("bad-sine", ["sweep", "--sine", "1"], ["--sine '1'", "AMPLITUDE,FREQUENCY", "2,1.2"]),
    Case("bad-sine-text", ["sweep", "--sine", "a,b"], ["--sine 'a,b'", "AMPLITUDE,FREQUENCY"]),
    Case("best-by-unknown-axis", ["sweep", "--grid", "kp=5", "--best-by", "leg_scale"],
         ["cannot group by 'leg_scale'", "use one of kp"]),
    Case("best-metric-unknown", ["sweep", "--grid", "kp=5", "--best-by", "kp", "--best-metric", "speed"],
         ["unknown metric 'speed'"]),
    Case("negative-seconds", ["sweep", "--seconds", "-1"],
         ["duration -1 s is not positive", "--seconds"]),
    Case("negative-seconds-eq", ["sweep", "--seconds=-1"],
         ["duration -1 s is not positive", "--seconds"]),
    Case("zero-seconds-stand", ["stand", "--seconds", "0"],
         ["duration 0 s is not positive", "--seconds"], out=False),
    Case("mujoco-missing", ["sweep", "--seconds", "1"],
         ["cannot import the Python package 'mujoco'", "pip install", "pupper doctor"],
         setup="bare-venv"),
    Case("mujoco-missing-stand", ["stand"],
         ["cannot import the Python package 'mujoco'", "pip install"], setup="bare-venv", out=False),
]


# ------------------------------------------------------------------- helpers


@pytest.fixture(scope="session")
def bare_python(tmp_path_factory) -> Path:
    """A venv of the same base interpreter as .venv, without mujoco."""
    cfg = (REPO / ".venv" / "pyvenv.cfg").read_text()
    home = next(line.split("=", 1)[1].strip() for line in cfg.splitlines()
                if line.split("=", 1)[0].strip() == "home")
    base = Path(home) / "python3"
    d = tmp_path_factory.mktemp("bare") / "venv"
    subprocess.run([str(base), "-m", "venv", "--without-pip", str(d)], check=True, timeout=120)
    py = d / "bin" / "python"
    probe = subprocess.run([str(py), "-c", "import mujoco"], capture_output=True)
    assert probe.returncode != 0, "the bare venv can import mujoco"
    return py


def prepare(case: Case, tmp: Path, request) -> tuple[list[str], dict]:
    env = dict(case.env)
    if case.setup == "garbage":
        (tmp / "garbage.xml").write_text(GARBAGE_MJCF)
    elif case.setup == "noact":
        (tmp / "noact.xml").write_text(NO_ACTUATOR_MJCF)
    elif case.setup == "unreadable":
        f = tmp / "unreadable.xml"
        f.write_text(GARBAGE_MJCF)
        f.chmod(0)
        try:
            with open(f, "rb"):
                readable = True
        except PermissionError:
            readable = False
        if readable:
            pytest.skip("running as root (or with CAP_DAC_OVERRIDE): chmod 000 does not stop reads")
    elif case.setup == "out-exists":
        (tmp / "out").mkdir()
        (tmp / "out" / "mine.txt").write_text("user data")
    elif case.setup == "bare-venv":
        env["PUPPER_PYTHON"] = str(request.getfixturevalue("bare_python"))
    args = [a.replace("{tmp}", str(tmp)) for a in case.args]
    if case.out:
        args += ["-o", str(tmp / "out")]
    return args, env


def snapshot(d: Path) -> dict[str, bytes]:
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


# --------------------------------------------------------------------- tests


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input(case: Case, run, tmp_path, request):
    args, env = prepare(case, tmp_path, request)
    before = snapshot(tmp_path / "out") if (tmp_path / "out").is_dir() else None
    p = run(*args, env=env, timeout=120)
    out = p.stdout + p.stderr
    assert p.returncode == 2, f"exit {p.returncode}, expected 2\nstderr: {p.stderr}"
    for bad in FORBIDDEN:
        assert bad not in out, f"{bad!r} in output:\n{out}"
    lines = p.stderr.splitlines()
    assert len(lines) == 1, f"stderr should be one line, got {len(lines)}:\n{p.stderr}"
    line = lines[0]
    assert line.startswith("error: "), line
    for phrase in case.phrases:
        assert phrase in line, f"{phrase!r} not in {line!r}"
    assert p.stdout == "", p.stdout
    if before is None:
        assert not (tmp_path / "out").exists(), (
            f"output directory left behind: {sorted(snapshot(tmp_path / 'out'))}"
        )
    else:
        assert snapshot(tmp_path / "out") == before, "pupper touched the existing --out directory"
    assert not (tmp_path / "runs").exists(), "a default runs/ directory was left behind"


def test_bad_input_without_out_leaves_no_runs_dir(run, tmp_path):
    """The default run directory (runs/<time>-...) is not created for bad input either."""
    for args in (["--pose", "1,2,3"], ["--keyframe", "nope"], ["--grid", "kq=1"],
                 ["--model", "pupper_v3_fixed"]):
        p = run("sweep", *args)
        assert p.returncode == 2, p.stderr
        assert not (tmp_path / "runs").exists(), (args, list((tmp_path / "runs").rglob("*")))


# ------------------------------------------------------------- Python API


def test_api_unknown_axis_is_grid_error_with_cli_message(run, tmp_path):
    import pupper_core as pc

    with pytest.raises(pc.GridError) as ei:
        pc.sweep({"kq": [1]}, progress=False)
    p = run("sweep", "--grid", "kq=1", "-o", tmp_path / "out")
    assert p.returncode == 2
    assert p.stderr.strip() == "error: " + str(ei.value)
    assert "did you mean 'kp'" in str(ei.value)


def test_api_cli_strings_give_the_same_error():
    import pupper_core as pc

    with pytest.raises(pc.GridError) as a:
        pc.sweep(["kq=1"], progress=False)
    with pytest.raises(pc.GridError) as b:
        pc.sweep({"kq": [1]}, progress=False)
    assert str(a.value) == str(b.value)


def test_api_negative_gain_is_grid_error(tmp_path):
    import pupper_core as pc

    with pytest.raises(pc.GridError, match="gains must be >= 0"):
        pc.sweep({"kp": [-1]}, progress=False, out=tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_api_non_numeric_dict_value_is_grid_error():
    import pupper_core as pc

    with pytest.raises(pc.GridError, match="non-numeric"):
        pc.sweep({"kp": ["abc"]}, progress=False)


def test_api_fixed_model_stand_is_model_error():
    import pupper_core as pc

    with pytest.raises(pc.ModelError, match="no free-joint base"):
        pc.stand(model="pupper_v3_fixed")


def test_api_errors_have_a_kind_and_the_os_error_users_catch(tmp_path):
    import pupper_core as pc

    (tmp_path / "taken").mkdir()
    with pytest.raises(FileExistsError) as e:
        pc.sweep({"kp": [5]}, seconds=0.1, progress=False, out=tmp_path / "taken")
    assert isinstance(e.value, pc.OutputError) and e.value.kind == "run_exists"
    with pytest.raises(FileNotFoundError) as e:
        pc.info(tmp_path / "nope.xml")
    assert isinstance(e.value, pc.ModelError) and e.value.kind == "model_not_found"
    with pytest.raises(FileNotFoundError) as e:
        pc.load_run(tmp_path / "nowhere")
    assert isinstance(e.value, pc.OutputError) and e.value.kind == "run_not_found"
    with pytest.raises(pc.GridError) as e:
        pc.sweep({"kq": [1]}, progress=False)
    assert e.value.kind == "grid" and not isinstance(e.value, OSError)
    pc.sweep({"kp": [5]}, seconds=0.1, progress=False, out=tmp_path / "run")
    with pytest.raises(pc.OutputError) as e:
        pc.sweep({"kp": [6]}, seconds=0.1, progress=False, out=tmp_path / "run", resume=True)
    assert e.value.kind == "resume_mismatch"


def test_wrong_mujoco_version_is_one_clear_line(pupper_bin: Path, tmp_path: Path) -> None:
    """A mujoco 3.x earlier on the path is refused with the fix, exit 2."""
    fake = tmp_path / "site" / "mujoco"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("__version__ = '3.1.6'\n")
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONHOME", "PUPPER_PYTHON")}
    env["PYTHONPATH"] = str(tmp_path / "site")
    r = subprocess.run(
        [str(pupper_bin), "sweep", "--seconds", "1", "-o", str(tmp_path / "out")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60,
    )
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert "needs mujoco 4.x" in lines[0] and "3.1.6" in lines[0] and "make setup" in lines[0]
    assert not (tmp_path / "out").exists()
