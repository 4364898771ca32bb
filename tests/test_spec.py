"""One sweep specification: every parameter's default is written once, in the
Rust core's SweepSpec, and `pupper sweep --help`, the Python signature and
the native stub all agree with it."""

from __future__ import annotations

import ast
import inspect
import re
from pathlib import Path

import pytest

pc = pytest.importorskip("pupper_core")

STUB = Path(pc.__file__).parent / "_native.pyi"
#: Spec fields that are CLI switches or arguments without a default value.
NO_CLI_DEFAULT = {"out", "force", "resume", "trace", "stop_fallen", "common_draws", "sine", "pose", "max_torque",
                  "randomize",  # repeatable: none unless given
                  "device", "chunk_cells",  # None: the backend's own (help says which)
                  "shard",  # none: the whole grid
                  "ray",  # none: run here
                  "kp", "kd",  # none: each actuator's own (help says so)
                  "depth",  # none: scaled to the model's legs (help says so)
                  "motor",  # none: the ideal motor (help says so)
                  "integrator",  # none: the model's own (help says so)
                  "push_force"}  # none: -25 N scaled to the model's mass (help says so)
#: Spec fields whose flag has another name on the command line.
CLI_FLAG = {"push": "--no-push"}


def defaults() -> dict:
    return pc._native.sweep_defaults()


def test_python_signatures_take_the_spec_defaults():
    # a list default shows as a tuple: help() must not suggest a shared list
    shown = {k: tuple(v) if isinstance(v, list) else v for k, v in defaults().items()}
    sweep = inspect.signature(pc.sweep).parameters
    assert set(shown) <= set(sweep), set(shown) - set(sweep)
    for name, value in shown.items():
        assert sweep[name].default == value, (name, sweep[name].default, value)
    for name, p in inspect.signature(pc.stand).parameters.items():
        assert p.default == shown[name], (name, p.default, shown[name])


def _typed_dict_fields(tree: ast.Module, name: str) -> dict[str, str]:
    cls = next(c for c in tree.body if isinstance(c, ast.ClassDef) and c.name == name)
    return {
        f.target.id: ast.unparse(f.annotation)
        for f in cls.body
        if isinstance(f, ast.AnnAssign) and isinstance(f.target, ast.Name)
    }


def test_stub_lists_every_keyword_without_restating_defaults():
    tree = ast.parse(STUB.read_text())
    types = ast.parse((STUB.parent / "_types.py").read_text())
    sim = _typed_dict_fields(types, "SimOptions")
    sweep = {**sim, **_typed_dict_fields(types, "SweepOptions")}
    # `out` is a named keyword of its own (str or PathLike, checked apart)
    assert set(sweep) | {"out"} == set(defaults()), set(sweep) ^ set(defaults())
    assert set(sim) == set(inspect.signature(pc.stand).parameters)
    assert "Literal" in sim["mode"]
    fns = {f.name: f for f in tree.body if isinstance(f, ast.FunctionDef)}
    for fn, options in (("stand", "SimOptions"), ("sweep", "SweepOptions")):
        kwarg = fns[fn].args.kwarg
        assert kwarg is not None and ast.unparse(kwarg.annotation) == f"Unpack[{options}]"


def test_cli_help_shows_the_spec_defaults(run):
    text = run("sweep", "--help", check=0).stdout
    flat = re.sub(r"\s+", " ", text)
    for name, value in defaults().items():
        flag = CLI_FLAG.get(name, "--" + name.replace("_", "-"))
        assert re.search(rf"(^|\s){re.escape(flag)}\b", text, re.M), f"--help lacks {flag}"
        if name in NO_CLI_DEFAULT or name in CLI_FLAG:
            continue
        m = re.search(rf"{re.escape(flag)} <[^>]+>.*?\[default: ([^\]]+)\]", flat)
        assert m, f"--help shows no default for {flag}"
        # "10; response: 3": the sweep's default comes first
        shown = m.group(1).split(";")[0]
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            assert float(shown) == value, (flag, shown, value)
        else:
            assert shown == str(value), (flag, shown, value)


def test_stand_and_sweep_share_the_spec_checks(run):
    with pytest.raises(pc.ConfigError) as a:
        pc.stand(kp=-1)
    with pytest.raises(pc.ConfigError) as b:
        pc.sweep(kp=-1, progress=False)
    p = run("stand", "--kp=-1")
    # the same check, said in each one's words
    assert str(a.value) == str(b.value) == "kp=-1 is negative or not finite: gains must be >= 0"
    assert p.stderr.strip() == "error: --kp -1 is negative or not finite: gains must be >= 0"


def test_python_grid_text_is_parsed_like_the_cli():
    res = pc.sweep({"kp": "10"}, seconds=0.2, push=False, progress=False)
    assert list(res["kp"]) == [10.0]
    res = pc.sweep({"kp": "10,30", "kd": 1}, seconds=0.2, push=False, progress=False)
    assert res.ids == ["kp10_kd1", "kp30_kd1"]
    with pytest.raises(pc.GridError, match="non-numeric value 'ten'"):
        pc.sweep({"kp": "ten"}, progress=False)


@pytest.mark.parametrize("bad", [123, b"runs/x", 1.5])
def test_out_must_be_a_path(bad, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(TypeError, match="out must be a str or os.PathLike"):
        pc.sweep(out=bad, progress=False)
    assert list(tmp_path.iterdir()) == []


def test_out_empty_and_resume_without_out_are_refused(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(pc.OutputError, match="empty path"):
        pc.sweep(out="", progress=False)
    with pytest.raises(pc.OutputError, match="resume needs the run directory"):
        pc.sweep(resume=True, progress=False)
    with pytest.raises(pc.ConfigError, match="trace_every="):
        pc.sweep(trace=True, trace_every=0, progress=False)
    assert list(tmp_path.iterdir()) == []
