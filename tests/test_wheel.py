"""The wheel a user can `pip install`: built with `maturin build --release`,
installed into a new venv outside the checkout, it gives the `pupper` command
and `import pupper_core`, models, plots and rendering included, from any
working directory; its summaries equal the checkout build's byte for byte."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO, assert_drawn_as_traced, clean_env, read_csv

GRID = ["--grid", "kp=5,30", "--seconds", "2"]
#: Body variants and a sine force, traced every step: --render must draw exactly this.
VARIANTS = ["--grid", "leg_scale=1,1.5", "--sine", "2,1.2", "--seconds", "1", "--trace", "--trace-every", "1"]
#: What the wheel's venv must not see: anything pointing back at the checkout.
LEAKY = ("VIRTUAL_ENV", "PYTHONPATH", "PUPPER_PYTHON", "PUPPER_BIN", "PYO3_PYTHON")


def _run(cmd: list[str], cwd: Path, env: dict[str, str], timeout: float = 900) -> subprocess.CompletedProcess:
    p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert p.returncode == 0, (
        f"{' '.join(map(str, cmd))}: exit {p.returncode}\n"
        f"stdout:\n{p.stdout[-3000:]}\nstderr:\n{p.stderr[-3000:]}"
    )
    return p


def _base_python() -> str:
    """The interpreter the project venv was made from (a venv of a venv
    would still resolve to the checkout's .venv)."""
    cfg = (REPO / ".venv" / "pyvenv.cfg").read_text()
    for line in cfg.splitlines():
        key, _, value = line.partition("=")
        if key.strip() == "executable":
            return value.strip()
    return sys._base_executable  # type: ignore[attr-defined]


@pytest.fixture(scope="module")
def wheel_env(tmp_path_factory) -> tuple[Path, dict[str, str]]:
    """(venv, env): the built wheel installed with its plots extra, pinned by
    the project's lock file, in a venv that knows nothing of the checkout."""
    root = tmp_path_factory.mktemp("wheel")
    dist = root / "dist"
    build_env = clean_env(PYO3_PYTHON=str(REPO / ".venv" / "bin" / "python"))
    _run([str(REPO / ".venv" / "bin" / "maturin"), "build", "--release", "-q", "-o", str(dist)],
         cwd=REPO / "python", env=build_env)
    (wheel,) = dist.glob("pupper_core-*.whl")
    venv = root / "venv"
    _run([_base_python(), "-m", "venv", str(venv)], cwd=root, env=clean_env())
    _run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q",
          "-c", str(REPO / "python" / "requirements.lock"), f"{wheel}[plots]"],
         cwd=root, env=clean_env())
    env = {k: v for k, v in clean_env().items() if k not in LEAKY}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env.setdefault("MUJOCO_GL", "egl")
    return venv, env


def test_wheel_carries_models_and_stubs(wheel_env) -> None:
    venv, env = wheel_env
    code = (
        "import pathlib, pupper_core, pupper_core.render as r\n"
        "p = pathlib.Path(pupper_core.__file__).parent\n"
        "print(p)\n"
        "print(sorted(x.name for x in (p / 'models' / 'pupper_v3').iterdir()))\n"
        "print((p / '_native.pyi').is_file(), (p / 'py.typed').is_file())\n"
        "import mujoco, numpy as np\n"
        "a = mujoco.MjModel.from_xml_path(str(r.builtin_model_path('pupper_v3')))\n"
        "b = pupper_core._native.builtin_model('pupper_v3')\n"
        "print(all(np.array_equal(getattr(a, f), getattr(b, f)) for f in\n"
        "          ('body_mass', 'body_pos', 'geom_size', 'jnt_range', 'key_qpos', 'actuator_gainprm')))\n"
    )
    out = _run([str(venv / "bin" / "python"), "-c", code], cwd=venv, env=env).stdout.splitlines()
    assert Path(out[0]).is_relative_to(venv), f"pupper_core imported from {out[0]}, not the wheel's venv"
    assert not Path(out[0]).is_relative_to(REPO)
    assert out[1] == "['pupper_v3.xml', 'scene.xml']", out[1]
    assert out[2] == "True True"
    assert out[3] == "True", "the packaged model file differs from the one compiled in"


def test_wheel_cli_and_module_equal_the_checkout_build(wheel_env, run, tmp_path) -> None:
    venv, env = wheel_env
    work = tmp_path / "elsewhere"
    work.mkdir()
    info = json.loads(_run(["pupper", "info", "--json"], cwd=work, env=env).stdout)
    assert (info["nq"], info["nv"], info["nu"], info["nbody"]) == (19, 18, 12, 14)
    doctor = _run(["pupper", "doctor"], cwd=work, env=env).stdout
    assert str(venv) in doctor, doctor

    _run(["pupper", "sweep", *GRID, "--plot", "-o", "wheel", "-q"], cwd=work, env=env)
    _run(["pupper", "sweep", *VARIANTS, "--render", "-o", "wheel-variants", "-q"], cwd=work, env=env)
    _run([str(venv / "bin" / "python"), "-c",
          "import pupper_core as pc\n"
          "pc.sweep({'kp': [5, 30]}, seconds=2, out='module', trace=True, progress=False)\n"
          "pc.plots.write_run_plots('module')\n"
          "pc.sweep({'leg_scale': [1, 1.5]}, sine=(2, 1.2), seconds=1, trace=True, trace_every=1,\n"
          "         out='module-variants', progress=False)\n"
          "pc.render.write_run_effects('module-variants')\n"],
         cwd=work, env=env)
    run("sweep", *GRID, "-o", tmp_path / "checkout", "-q", check=0)

    want = (tmp_path / "checkout" / "summary.csv").read_bytes()
    header, rows = read_csv(tmp_path / "checkout" / "summary.csv")
    assert len(rows) == 2 and all(r["status"] == "ok" for r in rows)
    assert (work / "wheel" / "summary.csv").read_bytes() == want
    assert (work / "module" / "summary.csv").read_bytes() == want
    for run_dir in ("wheel", "module"):
        plots = sorted(p.name for p in (work / run_dir / "plots").iterdir())
        assert any(n.endswith(".png") and n.startswith("base_z") for n in plots), plots
    for run_dir in ("wheel-variants", "module-variants"):
        plots = sorted(p.name for p in (work / run_dir / "plots").iterdir())
        assert "gain_sweep_effects.gif" in plots and "gain_sweep_effects.png" in plots, plots
        assert_drawn_as_traced(work / run_dir)


def _pyenv_python(minor: str) -> str | None:
    """An interpreter of that minor version: on PATH, or one of pyenv's."""
    import glob
    import shutil

    root = os.environ.get("PYENV_ROOT", os.path.expanduser("~/.pyenv"))
    hits = sorted(glob.glob(os.path.join(root, "versions", f"{minor}.*", "bin", f"python{minor}")))
    if hits:
        return hits[-1]
    found = shutil.which(f"python{minor}")
    # a pyenv shim answers only for the version pyenv has selected
    return found if found and "/shims/" not in found else None


@pytest.mark.parametrize("minor", ["3.12", "3.13"])
def test_the_one_wheel_installs_into_other_pythons(wheel_env, tmp_path, minor) -> None:
    """The stable-ABI wheel built for the checkout's 3.11 installs into a
    fresh venv of another CPython and runs there: import, a 2-cell sweep, the
    pupper command; the public API shows no module it imported for itself."""
    venv, _ = wheel_env
    (wheel,) = (venv.parent / "dist").glob("pupper_core-*.whl")
    assert "-cp311-abi3-" in wheel.name, wheel.name
    py = _pyenv_python(minor)
    if py is None:
        pytest.skip(f"no Python {minor} on this machine (pyenv install {minor})")
    other = tmp_path / f"venv{minor}"
    _run([py, "-m", "venv", str(other)], cwd=tmp_path, env=clean_env())
    _run([str(other / "bin" / "python"), "-m", "pip", "install", "-q", "--disable-pip-version-check",
          str(wheel)], cwd=tmp_path, env=clean_env())
    env = {k: v for k, v in clean_env().items() if k not in LEAKY}
    env["PATH"] = f"{other / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    out = _run([str(other / "bin" / "python"), "-c",
                "import sys, pupper_core as pc\n"
                "print(sys.version_info[:2])\n"
                "r = pc.sweep({'kp': [5, 30]}, seconds=1, push=False, progress=False)\n"
                "print(len(r.rows), sorted(set(r['status'])))\n"
                "print(sorted(n for n in dir(pc) if n in ('os', 'sys', 'typing', 'functools', 'inspect')))\n"],
               cwd=tmp_path, env=env).stdout.splitlines()
    assert out[0] == str(tuple(int(x) for x in minor.split("."))), out
    assert out[1] == "2 ['ok']", out
    assert out[2] == "[]", out
    _run(["pupper", "sweep", "-g", "kp=5,30", "--seconds", "1", "--no-push", "-q", "-o", "cli"],
         cwd=tmp_path, env=env)
    _, rows = read_csv(tmp_path / "cli" / "summary.csv")
    assert len(rows) == 2
