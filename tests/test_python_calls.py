"""The Rust→Python boundary, checked from the Python side: every entry of
the table in crates/pupper_mujoco/src/bridge/calls.rs (the only way the
CLI calls a function of our package by name) names a function that exists
and takes what the entry says it is given. The Rust side checks the other
half: every call goes through an entry and matches it."""

from __future__ import annotations

import importlib
import inspect
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

TABLE = Path(__file__).resolve().parent.parent / "crates" / "pupper_mujoco" / "src" / "bridge" / "calls.rs"

ENTRY = re.compile(
    r'pub const (?P<const>\w+): PyCall =\s*(?P<open>PyCall \{\s*open: true,\s*\.\.)?call\(\s*'
    r'"(?P<module>[\w.]+)",\s*"(?P<function>\w+)",\s*&\[(?P<pos>[^\]]*)\],\s*&\[(?P<kw>[^\]]*)\],?\s*\)',
    re.S,
)


@dataclass
class Entry:
    const: str
    module: str
    function: str
    positional: list[str]
    keywords: list[str]
    open: bool


def names(text: str) -> list[str]:
    return re.findall(r'"(\w+)"', text)


def entries(text: str) -> list[Entry]:
    return [Entry(m["const"], m["module"], m["function"], names(m["pos"]), names(m["kw"]), bool(m["open"]))
            for m in ENTRY.finditer(text)]


def problems(e: Entry, fn: object) -> list[str]:
    """What a call made as the entry says would get wrong."""
    sig = inspect.signature(fn)  # type: ignore[arg-type]
    params = list(sig.parameters.values())
    positional = [p.name for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    out = []
    if positional[:len(e.positional)] != e.positional:
        out.append(f"takes {positional} positionally, the table gives {e.positional}")
    takes = {p.name for p in params}
    var_kw = any(p.kind is p.VAR_KEYWORD for p in params)
    for k in e.keywords:
        if k not in takes and not var_kw:
            out.append(f"has no parameter {k}")
    if e.open and not var_kw:
        out.append("takes no other keywords (no **options), but the table says open")
    given = set(e.positional) | set(e.keywords)
    for p in params:
        required = p.default is p.empty and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
        if required and p.name not in given:
            out.append(f"needs {p.name}, which no call gives")
    return out


def test_every_entry_is_a_function_that_takes_what_it_is_given():
    found = entries(TABLE.read_text())
    # the table's own count: every entry of ALL was read here
    count = int(re.search(r"pub const ALL: \[PyCall; (\d+)\]", TABLE.read_text())[1])
    assert len(found) == count, [e.const for e in found]
    bad = {}
    for e in found:
        fn = getattr(importlib.import_module(e.module), e.function, None)
        if fn is None:
            bad[e.const] = [f"{e.module} has no {e.function}"]
        elif p := problems(e, fn):
            bad[e.const] = p
    assert not bad, bad


def test_the_check_can_fail():
    def write(run_dir: str, *, gif: bool = False) -> None: ...

    ok = Entry("X", "m", "write", ["run_dir"], ["gif"], False)
    assert problems(ok, write) == []
    assert problems(Entry("X", "m", "write", ["path"], [], False), write)
    assert problems(Entry("X", "m", "write", ["run_dir"], ["fps"], False), write)
    assert problems(Entry("X", "m", "write", ["run_dir"], [], True), write)
    assert problems(Entry("X", "m", "write", [], [], False), write)  # run_dir never given


@pytest.mark.parametrize("text, want", [
    ('pub const A: PyCall = call("pupper_core.x", "f", &["a"], &[]);', [("pupper_core.x", "f", ["a"], [], False)]),
    ('pub const B: PyCall = PyCall {\n    open: true,\n    ..call(\n        "m", "g",\n        &["p"],\n        &["w", "h"],\n    )\n};',
     [("m", "g", ["p"], ["w", "h"], True)]),
])
def test_the_table_is_read_as_written(text, want):
    assert [(e.module, e.function, e.positional, e.keywords, e.open) for e in entries(text)] == want
