"""The experiment kinds' registry is the Rust core's `kinds!` row list
(`Experiment::KINDS`): every other registry, the files of each layer,
docs/architecture.md's table of them, and each kind's defaults in Python
and on the command line are checked against it (issue 60: each default
said once, a kind a module per layer)."""

from __future__ import annotations

import inspect
import subprocess
from pathlib import Path

import pytest

from conftest import REPO, clean_env
from test_defaults import _literal, _same, help_defaults

pc = pytest.importorskip("pupper_core")
from pupper_core import _native  # noqa: E402
from pupper_core._spec import KIND_DEFAULTS  # noqa: E402

#: Where each column of architecture.md's table lives.
ROOTS = {
    "request": "crates/pupper_core/src", "plan": "crates/pupper_core/src", "sim": "crates/pupper_core/src",
    "results": "crates/pupper_core/src", "cli": "crates/pupper_cli/src", "print": "crates/pupper_cli/src",
    "binding": "crates/pupper_py/src", "python": "python/pupper_core", "report": "python/pupper_core",
    "plots": "python/pupper_core",
}


def architecture_table() -> tuple[list[str], list[list[str]]]:
    """The header and rows of docs/architecture.md's table of kinds."""
    lines = (REPO / "docs" / "architecture.md").read_text().splitlines()
    start = next(i for i, x in enumerate(lines) if x.startswith("| kind |"))
    rows = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        rows.append([c.strip().strip("`") for c in line.strip("|").split("|")])
    return [c.strip() for c in lines[start].strip("|").split("|")], rows


def test_the_registry_names_the_kinds():
    assert _native.KINDS == ["response", "hold", "walk"]
    assert list(_native.kind_defaults()) == _native.KINDS == list(KIND_DEFAULTS)


@pytest.mark.parametrize("kind", _native.KINDS)
def test_every_layer_has_the_kind(kind):
    header, rows = architecture_table()
    assert [r[0] for r in rows] == _native.KINDS, "architecture.md's table lists other kinds than the registry"
    row = dict(zip(header, next(r for r in rows if r[0] == kind)))
    for column, root in ROOTS.items():
        path = REPO / root / row[column]
        assert path.is_file(), f"architecture.md: {kind}'s {column} is {row[column]}, which does not exist"
    # the layers' own registries know it
    from pupper_core._report import SECTIONS
    from pupper_core.plots import WRITERS

    assert kind in SECTIONS and kind in WRITERS
    assert callable(getattr(pc, kind)) and kind in pc.__all__
    assert (REPO / "docs" / f"{kind}.md").is_file() and (REPO / "tests" / f"test_{kind}.py").is_file()
    # the module file of each layer says the kind's name in its own `pupper KIND`
    assert f"pupper {kind}" in (REPO / ROOTS["cli"] / row["cli"]).read_text()


@pytest.mark.parametrize("kind", _native.KINDS)
def test_a_kinds_defaults_are_the_rust_cores_in_python_and_on_the_command_line(kind, pupper_bin: Path):
    own = KIND_DEFAULTS[kind]
    assert drift(kind, getattr(pc, kind)) == []
    # the native binding's signature, as help() shows it
    assert drift(kind, getattr(_native, kind)) == []
    # --help: a flag whose help names a value shows the same one
    text = subprocess.run([str(pupper_bin), kind, "--help"], capture_output=True, text=True, check=True,
                          env=clean_env(), timeout=60).stdout
    said = help_defaults(text)
    checked = 0
    for name, default in own.items():
        if name in said and default is not None and not isinstance(default, tuple):
            value = _literal(said[name])
            assert value is not None and _same(default, value), (kind, name, said[name], default)
            checked += 1
    assert checked >= 1, f"pupper {kind} --help shows none of its own defaults"


def drift(kind: str, fn: object) -> list[str]:
    """Each of the kind's own keywords whose default in ``fn``'s signature
    is not the Rust core's, in words."""
    params = inspect.signature(fn).parameters  # type: ignore[arg-type]
    return [f"{kind} {name}: {params[name].default!r} where the core says {default!r}"
            if name in params else f"{kind}: no keyword {name}"
            for name, default in KIND_DEFAULTS[kind].items()
            if name not in params or params[name].default != default]


def test_a_staged_drift_is_caught():
    """The comparison can fail: a default off by a step, and a keyword
    missing, are each named."""
    own = KIND_DEFAULTS["walk"]

    def moved(*, speed: float = own["speed"] + 0.05, **rest: object) -> None:
        return None

    found = drift("walk", moved)
    assert "walk: no keyword gait" in found
    assert f"walk speed: {own['speed'] + 0.05!r} where the core says {own['speed']!r}" in found
