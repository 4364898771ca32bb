"""The stubs say what the package does: mypy (pinned in
python/requirements-dev.lock, installed by `make test`) checks a
notebook-style script against them, strictly, and the script runs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO, clean_env

TOUR = REPO / "examples" / "typed_tour.py"


def _mypy(*paths: Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    pytest.importorskip("mypy", reason="make test installs mypy (python/requirements-dev.lock)")
    return subprocess.run(
        [sys.executable, "-m", "mypy", "--strict", "--no-incremental", "--cache-dir", str(cwd / ".mypy"),
         *map(str, paths)],
        capture_output=True, text=True, cwd=cwd, timeout=300, env=clean_env(),
    )


def test_the_typed_tour_checks_and_runs(tmp_path: Path) -> None:
    p = _mypy(TOUR, REPO / "python" / "pupper_core" / "_native.pyi", cwd=tmp_path)
    assert p.returncode == 0, p.stdout + p.stderr
    run = subprocess.run([sys.executable, str(TOUR)], capture_output=True, text=True, cwd=tmp_path,
                         timeout=300, env=clean_env())
    assert run.returncode == 0 and "stood at" in run.stdout, run.stdout + run.stderr


def test_a_wrong_type_is_caught(tmp_path: Path) -> None:
    """The check can fail: the sweep keeps its types through its wrapper."""
    bad = tmp_path / "bad.py"
    bad.write_text(
        "import pupper_core as pc\n"
        "res = pc.sweep({'kp': [10]}, progress=False)\n"
        "header: int = res.header\n"
        "z: str = pc.stand()['final_z']\n"
    )
    p = _mypy(bad, cwd=tmp_path)
    assert p.returncode == 1, p.stdout + p.stderr
    assert "bad.py:3" in p.stdout and "bad.py:4" in p.stdout, p.stdout
