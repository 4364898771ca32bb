"""The `pupper` CLI end to end: info, stand, doctor, sweep (preset, grid, trace)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

from conftest import REFERENCE_XML, read_csv

COUNTS = {
    "pupper_v3": {"nq": 19, "nv": 18, "nu": 12, "nbody": 14},
    "pupper_v3_fixed": {"nq": 12, "nv": 12, "nu": 12, "nbody": 14},
}

# The chapter's §4.6 table (README of the reference): final z to 3 decimals,
# last-1s std (mm) to 2, push dip (mm) to 2.
CHAPTER = {
    "soft": (1, 0.05, "0.085", "0.01", "12.97"),
    "default": (5, 0.1, "0.120", "0.00", "6.79"),
    "stiff": (30, 0.1, "0.126", "0.00", "1.97"),
    "underD": (5, 0, "0.120", "0.00", "9.75"),
}

LAB_GRID = ["--grid", "kp=10,30,60,120", "--grid", "kd=0.5,1,2,5"]


def need_reference() -> Path:
    if not REFERENCE_XML.is_file():
        pytest.skip(f"reference description not present at {REFERENCE_XML}")
    return REFERENCE_XML


# ----------------------------------------------------------------------- info


@pytest.mark.parametrize("model", sorted(COUNTS))
def test_info_text_counts(run, model):
    p = run("info", "--model", model, check=0)
    c = COUNTS[model]
    assert re.search(
        rf"nq {c['nq']}\s+nv {c['nv']}\s+nu {c['nu']}\s+nbody {c['nbody']}\b", p.stdout
    ), p.stdout
    assert model in p.stdout


@pytest.mark.parametrize("model", sorted(COUNTS))
def test_info_json_counts(run, model):
    p = run("info", "--model", model, "--json", check=0)
    info = json.loads(p.stdout)
    for k, v in COUNTS[model].items():
        assert info[k] == v, (k, info[k])
    assert info["name"] == model
    assert len(info["actuators"]) == 12
    assert re.fullmatch(r"[0-9a-f]{64}", info["sha256"])
    assert [k["name"] for k in info["keyframes"]] == ["home"]


def test_info_on_reference_description(run):
    ref = need_reference()
    p = run("info", "--model", ref, "--json")
    assert p.returncode == 0, p.stderr
    info = json.loads(p.stdout)
    assert (info["nq"], info["nv"], info["nu"], info["nbody"]) == (19, 18, 12, 14)


# ---------------------------------------------------------------------- stand


def test_stand_json_final_z(run):
    p = run("stand", "--json", check=0)
    rep = json.loads(p.stdout)
    assert rep["status"] == "ok"
    assert abs(rep["final_z"] - 0.120) <= 0.0005, rep
    assert rep["kp"] == 5 and rep["kd"] == 0.1 and rep["seconds"] == 10


def test_stand_text(run):
    p = run("stand", "--seconds", "2", check=0)
    m = re.search(r"final z\s+([0-9.]+) m", p.stdout)
    assert m, p.stdout
    assert abs(float(m.group(1)) - 0.120) < 0.001, p.stdout
    assert re.search(r"status\s+ok", p.stdout), p.stdout


def test_stand_reference_description_equals_ours(run):
    ref = need_reference()
    ours = json.loads(run("stand", "--json", "--kp", "5", "--kd", "0.1", check=0).stdout)
    p = run("stand", "--json", "--model", ref, "--kp", "5", "--kd", "0.1")
    assert p.returncode == 0, p.stderr
    theirs = json.loads(p.stdout)
    assert abs(theirs["final_z"] - ours["final_z"]) < 1e-4, (theirs, ours)


# --------------------------------------------------------------------- doctor


def test_doctor(run):
    p = run("doctor", check=0)
    venv_python = Path(__file__).resolve().parents[1] / ".venv" / "bin" / "python"
    assert str(venv_python) in p.stdout, p.stdout
    assert re.search(r"mujoco\s+4\.0", p.stdout), p.stdout


def test_doctor_json(run):
    d = json.loads(run("doctor", "--json", check=0).stdout)
    assert d["mujoco"].startswith("4.0")
    assert d["problem"] is None
    assert d["executable"].endswith(".venv/bin/python")


# ---------------------------------------------------------------------- sweep


def test_chapter_preset_matches_reference_table(run, tmp_path):
    out = tmp_path / "ch"
    p = run("sweep", "--preset", "chapter-4.6", "-o", out, "--json", check=0)
    doc = json.loads(p.stdout)
    cells = {c["name"]: c for c in doc["cells"]}
    assert set(cells) == set(CHAPTER)
    _, rows = read_csv(out / "summary.csv")
    csv_rows = {r["name"]: r for r in rows}
    assert [r["name"] for r in rows] == ["soft", "default", "stiff", "underD"]
    for name, (kp, kd, z, std, dip) in CHAPTER.items():
        for src in (cells[name], {k: float(v) for k, v in csv_rows[name].items()
                                  if k in ("kp", "kd", "final_z", "last_1s_std_mm", "push_dip_mm")}):
            assert src["kp"] == kp and src["kd"] == kd, (name, src)
            assert f"{src['final_z']:.3f}" == z, (name, src["final_z"])
            assert f"{src['last_1s_std_mm']:.2f}" == std, (name, src["last_1s_std_mm"])
            assert f"{src['push_dip_mm']:.2f}" == dip, (name, src["push_dip_mm"])
        assert cells[name]["status"] == "ok"


def test_chapter_preset_text_table(run, tmp_path):
    p = run("sweep", "--preset", "chapter-4.6", "--seconds", "3", "-o", tmp_path / "t", check=0)
    for name in CHAPTER:
        assert re.search(rf"^{name}\s", p.stdout, re.M), p.stdout
    assert (tmp_path / "t" / "summary.csv").is_file()


def test_sweep_json_types(run, tmp_path):
    p = run("sweep", "--grid", "kp=5,30", "--seconds", "3", "--json", "-o", tmp_path / "j", check=0)
    doc = json.loads(p.stdout)
    assert doc["complete"] is True
    cells = doc["cells"]
    assert [c["id"] for c in cells] == ["kp5", "kp30"]
    for i, c in enumerate(cells):
        # an index is an integer, as in summary.csv
        assert c["index"] == i and isinstance(c["index"], int), c["index"]
        assert isinstance(c["status"], str) and isinstance(c["final_z"], float)
        assert c["event_time"] is None  # NaN / empty is null, not NaN (invalid JSON)


def test_lab_grid_run_directory(run, tmp_path):
    # from a cwd unrelated to the checkout, with a relative --out
    cwd = tmp_path / "elsewhere" / "deep"
    cwd.mkdir(parents=True)
    run("sweep", *LAB_GRID, "--mode", "torque", "--seconds", "3", "-o", "lab", "-q",
        cwd=cwd, check=0)
    out = cwd / "lab"
    header, rows = read_csv(out / "summary.csv")
    assert len(rows) == 16
    assert header[:5] == ["index", "id", "name", "kp", "kd"]
    assert [(float(r["kp"]), float(r["kd"])) for r in rows] == [
        (kp, kd) for kp in (10, 30, 60, 120) for kd in (0.5, 1, 2, 5)
    ]
    # every cell stands; Kd 5 chatters at the torque limit
    # Kd 2 and 5 lie past the explicit PD's bound at the 2 ms step on every body
    assert all(r["status"] == ("past_bound" if r["kd"] in ("2", "5") else "ok") for r in rows), rows
    assert all(math.isfinite(float(r["final_z"])) for r in rows)
    m = json.loads((out / "manifest.json").read_text())
    assert m["complete"] is True
    assert m["cells_total"] == m["cells_done"] == 16
    assert m["config"]["mode"] == "torque"
    assert m["config"]["schedule"]["duration"] == 3
    assert re.fullmatch(r"[0-9a-f]{64}", m["model"]["sha256"])
    info = json.loads(run("info", "--json", check=0).stdout)
    assert m["model"]["sha256"] == info["sha256"]
    assert m["mujoco_version"].startswith("4.0")
    assert m["pupper_version"]
    version = run("--version", check=0).stdout
    assert m["pupper_version"] in version
    assert not (tmp_path / "runs").exists()


def test_default_run_directory_lands_in_cwd(run, tmp_path):
    run("sweep", "--grid", "kp=5", "--seconds", "1", "-q", check=0)
    runs = list((tmp_path / "runs").iterdir())
    assert len(runs) == 1
    assert (runs[0] / "summary.csv").is_file() and (runs[0] / "manifest.json").is_file()


def test_trace_writes_traces_csv(run, tmp_path):
    out = tmp_path / "tr"
    run("sweep", "--grid", "kp=5,30", "--seconds", "1", "--trace", "--trace-every", "10",
        "-o", out, "-q", check=0)
    header, rows = read_csv(out / "traces.csv")
    assert header == ["id", "t", "z"]
    ids = [r["id"] for r in rows]
    assert sorted(set(ids)) == ["kp30", "kp5"]
    # 1 s at 2 ms = 500 steps, every 10th kept
    assert ids.count("kp5") == ids.count("kp30") == 50
    z = [float(r["z"]) for r in rows]
    assert all(0.05 < v < 0.3 for v in z)


def test_no_trace_no_traces_csv(run, tmp_path):
    run("sweep", "--grid", "kp=5", "--seconds", "1", "-o", tmp_path / "nt", "-q", check=0)
    assert not (tmp_path / "nt" / "traces.csv").exists()


# ----------------------------------------------------------------------- help

HELP_FLAGS = {
    "info": ["--model", "--json"],
    "stand": ["--model", "--seconds", "--kp", "--kd", "--mode", "--keyframe", "--pose", "--json"],
    "sweep": [
        "--grid", "--preset", "--model", "--mode", "--seconds", "--kp", "--kd", "--max-torque",
        "--push-force", "--push-at", "--push-duration", "--no-push", "--sine", "--keyframe",
        "--pose", "--out", "--force", "--resume", "--trace", "--trace-every", "--threads",
        "--chunk-cells", "--max-cells", "--plot", "--json", "--quiet",
    ],
    "doctor": ["--json"],
    "render": ["--model", "--mode", "--seconds", "--kp", "--kd", "--pose", "--out", "--width", "--height"],
}
HELP_FLAGS["sweep"].append("--render")


def _documented(help_text: str, flag: str) -> bool:
    """`flag` opens an option line of --help (not as part of a longer flag:
    `--mode` is not `--model`) and the option has a description."""
    pattern = rf"^\s+(?:-\w, )?{re.escape(flag)}(?![\w-])[^\n]*\n?(?P<desc>.*)$"
    for m in re.finditer(pattern, help_text, re.M):
        line = m.group(0)
        rest = line.split(flag, 1)[1]
        if re.search(r"\S\s{2,}\S", rest) or re.search(r"\w", m.group("desc") or ""):
            return True
    return False


@pytest.mark.parametrize("sub", sorted(HELP_FLAGS))
def test_help_mentions_flags(run, sub):
    p = run(sub, "--help", check=0)
    for flag in HELP_FLAGS[sub]:
        assert _documented(p.stdout, flag), f"`pupper {sub} --help` does not document {flag}"


def test_help_check_can_fail():
    text = "Options:\n      --model <MODEL>  Which model\n      --json\n"
    assert _documented(text, "--model")
    assert not _documented(text, "--mode")  # only a prefix of --model
    assert not _documented(text, "--threads")


def test_top_level_help_lists_commands(run):
    p = run("--help", check=0)
    for sub in ("info", "stand", "sweep", "doctor"):
        assert re.search(rf"^\s+{sub}\s", p.stdout, re.M), sub
    assert "Exit status" in p.stdout


def test_info_shows_what_a_run_uses_of_a_motor(run, tmp_path):
    """A `<motor>` has no servo gains of its own and its limit is its control
    range: `info` says so instead of printing kp 1, kd -0, unlimited."""
    src = (Path(__file__).parent / "models" / "trotter15.xml").read_text()
    motor = src.replace('<position kp="50" kv="0.5" forcerange="-24 24"/>',
                        '<motor ctrlrange="-24 24" ctrllimited="true"/>').replace("<position name=", "<motor name=")
    assert motor != src
    (tmp_path / "motor.xml").write_text(motor)
    out = run("info", "--model", tmp_path / "motor.xml", check=0).stdout
    row = next(line for line in out.splitlines() if "fl_knee_motor" in line)
    assert row.split()[4:] == ["-", "-", "[-24,", "24]", "(ctrlrange)"], row
    assert "a motor, no servo gains of its own" in out
    # the run asks for the gains info says it lacks
    p = run("sweep", "--model", tmp_path / "motor.xml", "--seconds", "1", "-o", tmp_path / "r", check=2)
    assert "give --kp and --kd" in p.stderr
