"""Shared fixtures for the pupper CLI and Python-API tests.

The tests run the real `pupper` binary (and real MuJoCo) on the real models.
The binary is taken from $PUPPER_BIN, else target/release/pupper of this
checkout; `make test` builds it first.
"""

from __future__ import annotations

import csv
import io
import os
import subprocess
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
DEFAULT_BIN = REPO / "target" / "release" / "pupper"
#: The upstream Pupper v3 description (not part of the project; optional).
REFERENCE_XML = (
    REPO.parent / "shared" / "reference" / "pupper_v3_description" / "mujoco_xml"
    / "pupper_v3_complete.xml"
)
#: Environment variables that would tell the binary which Python to use: the
#: binary must find the project's venv by itself.
SCRUBBED_ENV = ("VIRTUAL_ENV", "PYTHONHOME", "PUPPER_PYTHON")
# a bound on hangs, not a speed check: under `make test` two tests share the
# 2 cores of CI, and a fit through the firmware took 240 s with other work
# on the machine
TIMEOUT_S = 480


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Under pytest-xdist (`make test` runs `-n 2 --dist loadgroup`), the
    tests that share a module- or session-scoped fixture of their own
    module (a sweep, a fit, a wheel, a Ray cluster) run on one worker, so
    that fixture runs once rather than once per worker (two workers
    building one wheel race in target/maturin); every other test goes to
    whichever worker is free. First among the hooks: xdist's own reads the
    groups from the marks (registered after this file, it runs before it
    otherwise, and saw none)."""
    for item in items:
        module = getattr(item, "module", None)
        info = getattr(item, "_fixtureinfo", None)
        if module is None or info is None:
            continue
        shared = any(d.scope != "function" and getattr(d.func, "__module__", None) == module.__name__
                     for defs in info.name2fixturedefs.values() for d in defs)
        if shared:
            item.add_marker(pytest.mark.xdist_group(module.__name__))


def clean_env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in SCRUBBED_ENV}
    env.update(extra)
    return env


@pytest.fixture(scope="session")
def pupper_bin() -> Path:
    path = Path(os.environ.get("PUPPER_BIN", str(DEFAULT_BIN)))
    if not (path.is_file() and os.access(path, os.X_OK)):
        pytest.fail(
            f"the pupper binary {path} is missing or not executable: run make test "
            "(or build it with cargo build --release, or set PUPPER_BIN)",
            pytrace=False,
        )
    return path


@pytest.fixture
def run(pupper_bin: Path, tmp_path: Path):
    """run(*args, cwd=tmp_path, env=None, timeout=..., check=None) -> CompletedProcess.

    Runs the binary with a clean environment (no VIRTUAL_ENV, PYTHONHOME,
    PUPPER_PYTHON), in tmp_path by default so a default runs/ lands there.
    `env` adds variables; `check=N` asserts the exit status is N.
    """

    def _run(*args, cwd: Path | None = None, env: dict | None = None,
             timeout: float = TIMEOUT_S, check: int | None = None, **kw):
        proc = subprocess.run(
            [str(pupper_bin), *map(str, args)],
            cwd=str(cwd or tmp_path),
            env=clean_env(**(env or {})),
            capture_output=True,
            text=True,
            timeout=timeout,
            **kw,
        )
        if check is not None:
            assert proc.returncode == check, (
                f"pupper {' '.join(map(str, args))}: exit {proc.returncode}, expected {check}\n"
                f"stdout:\n{proc.stdout[-3000:]}\nstderr:\n{proc.stderr[-3000:]}"
            )
        return proc

    return _run


def assert_refused(p: subprocess.CompletedProcess[str], words: str, out: Path) -> None:
    """A refused command line: exit 2, one line on stderr that says
    ``words``, and nothing written at ``out``."""
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], p.stderr
    assert not out.exists()


def wait_rows(path: Path, proc: subprocess.Popen, at_least: int, timeout: float = 120) -> int:
    """Waits until the table at `path` (summary.csv, trials.csv) holds
    `at_least` whole rows while `proc` runs; returns how many it holds."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, "the run ended before it could be stopped mid-way"
        if path.exists():
            rows = path.read_text().count("\n") - 1
            if rows >= at_least:
                return rows
        time.sleep(0.05)
    raise AssertionError(f"{path} never reached {at_least} rows")


def hidden(tmp_path: Path, *modules: str) -> dict[str, str]:
    """Environment in which importing `modules` fails (a sitecustomize puts
    None in sys.modules for them): a machine without an optional package."""
    d = tmp_path / "hide"
    d.mkdir(exist_ok=True)
    lines = "".join(f"sys.modules[{m!r}] = None\n" for m in modules)
    (d / "sitecustomize.py").write_text("import sys\n" + lines)
    return {"PYTHONPATH": str(d)}


def same_files(got: Path, want: Path, names=("summary.csv",)) -> None:
    """The files `names` of two run directories are equal byte for byte."""
    for n in names:
        a, b = (got / n).read_bytes(), (want / n).read_bytes()
        assert a == b, f"{got / n} differs from {want / n} ({len(a)} vs {len(b)} bytes)"


#: What every run's manifest starts with, whichever side wrote it.
STAMP = ("kind", "pupper_version", "mujoco_version", "python")


def stamp_of(run_dir: Path, kind: str) -> dict[str, str]:
    """The stamp heading ``run_dir``'s manifest, checked to be ``kind``'s
    and this package's and MuJoCo's versions."""
    import json

    import mujoco
    import pupper_core

    manifest = json.loads((run_dir / "manifest.json").read_text())
    head = dict(list(manifest.items())[: len(STAMP)])
    assert tuple(head) == STAMP, list(manifest)[:6]
    assert head["kind"] == kind and head["pupper_version"] == pupper_core.__version__, head
    assert head["mujoco_version"] == mujoco.__version__ and Path(head["python"]).name.startswith("python"), head
    return head


def read_csv(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    """summary.csv's header and rows (dicts of strings), checking every row is complete."""
    text = Path(path).read_text()
    assert text.endswith("\n"), f"{path} does not end with a newline (truncated line?)"
    reader = csv.reader(io.StringIO(text))
    header = next(reader)
    rows = []
    for line in reader:
        assert len(line) == len(header), f"{path}: row {line} has {len(line)} fields, header {len(header)}"
        rows.append(dict(zip(header, line)))
    return header, rows


def as_float(s: str) -> float:
    return float(s) if s != "" else float("nan")


def chapter_metrics(ts, zs, timestep: float, push_at: float = 2.0, push_for: float = 0.25) -> dict:
    """The chapter's numbers from a hand-written loop's post-step (t, base z)
    samples: final z, last-second std (mm), and the push dip (mm: mean z over
    the 0.5 s before the push minus the lowest z until 1.5 s after it)."""
    import numpy as np

    t, z = np.asarray(ts), np.asarray(zs)
    n = round(1.0 / timestep)
    pre = z[(t >= push_at - 0.5) & (t < push_at)].mean()
    low = z[(t >= push_at) & (t < push_at + push_for + 1.5)].min()
    return {
        "final_z": z[-1],
        "last_1s_std_mm": z[-n:].std() * 1000.0,
        "push_dip_mm": max(pre - low, 0.0) * 1000.0,
        "samples": len(z),
    }


def assert_drawn_as_traced(run_dir: Path) -> None:
    """Every frame that --render drew shows the base where traces.csv (written
    by the sweep itself, one sample per step) has it, at that time, exactly."""
    import csv

    with open(run_dir / "traces.csv", newline="") as f:
        traced = {(r["id"], float(r["t"])): float(r["z"]) for r in csv.DictReader(f)}
    with open(run_dir / "plots" / "gain_sweep_effects.csv", newline="") as f:
        drawn = list(csv.DictReader(f))
    ids = {r["id"] for r in drawn}
    assert ids == {k[0] for k in traced}, (ids, {k[0] for k in traced})
    checked = 0
    for r in drawn:
        t = float(r["time"])
        if t == 0.0:
            continue  # the initial state precedes the first trace sample
        assert (r["id"], t) in traced, f"frame at t={t} of {r['id']} has no trace sample"
        assert float(r["base_z"]) == traced[(r["id"], t)], r
        checked += 1
    assert checked >= len(ids) * 10, checked


def write_hardware_log(out: Path, t, names: list[str], targets, q, kp: float, kd: float, *, tau=None,
                       rng=None) -> Path:
    """A stand-in hardware's log in pupper's format (the tests' own writer,
    not pupper's): the targets and angles, and the torque with 0.01 N·m of
    noise from ``rng`` where given."""
    import csv

    with out.open("w", newline="") as f:
        f.write(f"# pupper joint log 1\n# mode: servo\n# base: suspended\n# kp: {kp}\n# kd: {kd}\n")
        w = csv.writer(f, lineterminator="\n")
        fields = ["target", "q"] + (["tau"] if tau is not None else [])
        w.writerow(["time"] + [f"{a}.{x}" for a in names for x in fields])
        for k in range(len(t)):
            row = [repr(float(t[k]))]
            for i in range(len(names)):
                row += [repr(float(targets[k, i])), repr(float(q[k, i]))]
                if tau is not None:
                    row.append(repr(float(tau[k, i] + 0.01 * rng.standard_normal())))
            w.writerow(row)
    return out
