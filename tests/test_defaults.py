"""The Python-run commands' defaults are one: what `pupper recommend|tune|
fit|excite --help` says a flag defaults to is what the Python function
that runs it takes when the keyword is left out (the CLI sends clap's
default, a notebook gets Python's: two that drift apart give the shell
and the notebook different answers).

A flag whose help names a value ([default: 30], [default: tpe]) must be
the same value in Python; a help that describes the default in words
("the model's own") stands for Python's None. The sweep's own flags, which
tune passes through to the core, are test_spec's.
"""

from __future__ import annotations

import inspect
import math
import re
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from conftest import clean_env

pc = pytest.importorskip("pupper_core")

#: Each Python-run command and the function that runs it.
COMMANDS: dict[str, Callable[..., Any]] = {
    "recommend": pc.recommend,
    "tune": pc.tune,
    "fit": pc.fit,
    "excite": pc.excite,
}
#: Flags whose help gives a word for what Python's None does (not a value
#: the CLI sends): why each is not a mismatch.
WORDS_FOR_NONE = {("excite", "joints"): "all: every actuator, as joints=None"}

_FLAG = re.compile(r"^\s+(?:-\w, )?--([a-z0-9-]+)")
_DEFAULT = re.compile(r"\[default: ([^\]]+)\]")


def help_defaults(text: str) -> dict[str, str]:
    """flag (as a keyword) -> its help's [default: ...] text."""
    out: dict[str, str] = {}
    flag = None
    for line in text.splitlines():
        m = _FLAG.match(line)
        if m:
            flag = m.group(1).replace("-", "_")
        d = _DEFAULT.search(line)
        if d and flag and flag not in out:
            out[flag] = d.group(1)
    return out


def _literal(text: str) -> Any:
    """The value a [default: ...] names, or None for a default in words."""
    parts = [p.strip() for p in text.split(",")]
    try:
        nums = [float(p) for p in parts]
    except ValueError:
        return text if re.fullmatch(r"[\w.\-]+", text) else None
    return nums[0] if len(nums) == 1 else tuple(nums)


def _same(python: Any, shown: Any) -> bool:
    if isinstance(shown, float):
        return isinstance(python, (int, float)) and not isinstance(python, bool) and math.isclose(python, shown)
    if isinstance(shown, tuple):
        return isinstance(python, (tuple, list)) and len(python) == len(shown) and all(
            _same(a, b) for a, b in zip(python, shown))
    return python == shown


def mismatches(command: str, help_text: str, sweep_flags: set[str]) -> list[str]:
    """Each flag whose help default is not the Python function's, in words."""
    params = inspect.signature(COMMANDS[command]).parameters
    bad = []
    for flag, text in help_defaults(help_text).items():
        p = params.get(flag)
        if p is None or (command, flag) in WORDS_FOR_NONE:
            continue
        if command == "tune" and flag in sweep_flags and p.default is None:
            continue  # the sweep's flag: None is the core's default (test_spec)
        shown = _literal(text)
        if shown is None:
            ok = p.default is None
        else:
            ok = _same(p.default, shown)
        if not ok:
            bad.append(f"{command} --{flag.replace('_', '-')}: --help says [default: {text}], "
                       f"python's {flag}={p.default!r}")
    return bad


def _help(pupper_bin: Path, *args: str) -> str:
    return subprocess.run([str(pupper_bin), *args, "--help"], capture_output=True, text=True, check=True,
                          env=clean_env(), timeout=60).stdout


@pytest.fixture(scope="module")
def sweep_flags(pupper_bin: Path) -> set[str]:
    return set(help_defaults(_help(pupper_bin, "sweep"))) | {
        m.group(1).replace("-", "_") for line in _help(pupper_bin, "sweep").splitlines() if (m := _FLAG.match(line))}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_help_and_python_default_alike(pupper_bin: Path, command: str, sweep_flags: set[str]) -> None:
    text = _help(pupper_bin, command)
    assert help_defaults(text), f"{command} --help shows no default at all: the parser is stale"
    assert mismatches(command, text, sweep_flags) == []


def test_a_staged_mismatch_is_named(pupper_bin: Path, sweep_flags: set[str]) -> None:
    text = _help(pupper_bin, "recommend")
    assert "[default: 30]" in text
    staged = text.replace("[default: 30]", "[default: 31]", 1)
    assert mismatches("recommend", staged, sweep_flags) == [
        "recommend --min-phase-margin: --help says [default: 31], python's min_phase_margin=30.0"]
    # a word where Python has a value is one too
    staged = _help(pupper_bin, "fit").replace("[default: 50]", "[default: the model's own]", 1)
    assert mismatches("fit", staged, sweep_flags) == [
        "fit --max-iters: --help says [default: the model's own], python's max_iters=50"]
