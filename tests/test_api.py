"""The notebook API, `import pupper_core`: the same numbers as the CLI."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import REFERENCE_XML, as_float, read_csv

pc = pytest.importorskip("pupper_core")

GRID = {"kp": [5, 30], "kd": [0.1]}
CLI_GRID = ["--grid", "kp=5,30", "--grid", "kd=0.1"]
SECONDS = 3


@pytest.fixture(scope="module")
def result():
    return pc.sweep(GRID, seconds=SECONDS, progress=False)


def test_info_counts():
    info = pc.info()
    assert (info["nq"], info["nv"], info["nu"], info["nbody"]) == (19, 18, 12, 14)
    fixed = pc.info("pupper_v3_fixed")
    assert (fixed["nq"], fixed["nv"], fixed["nu"], fixed["nbody"]) == (12, 12, 12, 14)


def test_info_of_an_mjcf_path():
    if not REFERENCE_XML.is_file():
        pytest.skip(f"reference description not present at {REFERENCE_XML}")
    for model in (REFERENCE_XML, str(REFERENCE_XML)):
        info = pc.info(model)
        assert (info["nq"], info["nv"], info["nu"], info["nbody"]) == (19, 18, 12, 14)


def test_stand_final_z():
    rep = pc.stand()
    assert abs(rep["final_z"] - 0.120) <= 0.0005, rep
    assert rep["status"] == "ok"


def test_stand_same_as_cli(run):
    import json

    cli = json.loads(run("stand", "--json", "--seconds", "2", "--kp", "30", check=0).stdout)
    api = pc.stand(seconds=2, kp=30)
    for k in ("final_z", "last_1s_std_mm", "max_tilt_deg"):
        assert api[k] == cli[k], k


def test_sweep_from_dict_and_best(result):
    assert len(result) == 2
    assert result.ids == ["kp5_kd0.1", "kp30_kd0.1"]
    assert result.axes == ["kp", "kd"]
    assert result.complete is True and result.out is None
    np.testing.assert_array_equal(result["kp"], [5.0, 30.0])
    assert result["kp"].dtype == np.float64 and result["index"].dtype == np.int64
    assert result["status"] == ["ok", "ok"]
    best = result.best("last_1s_std_mm")
    assert isinstance(best, dict)
    assert best["id"] == "kp30_kd0.1"
    assert best["last_1s_std_mm"] == min(result["last_1s_std_mm"])
    worst = result.best("last_1s_std_mm", minimize=False)
    assert worst["id"] == "kp5_kd0.1"
    with pytest.raises(pc.ConfigError):
        result.best("nope")
    with pytest.raises(KeyError):
        result["nope"]


def test_numbers_equal_the_cli_summary(result, run, tmp_path):
    run("sweep", *CLI_GRID, "--seconds", SECONDS, "-o", tmp_path / "cli", "-q", check=0)
    header, rows = read_csv(tmp_path / "cli" / "summary.csv")
    assert header == result.header
    assert len(rows) == len(result)
    for i, row in enumerate(rows):
        for col in header:
            got = result[col][i]
            if col in ("id", "name", "status"):
                assert got == row[col], (col, got, row[col])
            else:
                want = as_float(row[col])
                assert (math.isnan(want) and math.isnan(got)) or float(got) == want, (
                    col, i, got, want)


def test_cli_strings_equal_dict(result):
    res = pc.sweep(["kp=5,30", "kd=0.1"], seconds=SECONDS, progress=False)
    assert res.header == result.header
    assert res.rows == result.rows


def test_single_string_grid():
    res = pc.sweep("kp=5,30", seconds=1, progress=False)
    assert res.ids == ["kp5", "kp30"]


def test_to_pandas(result):
    pytest.importorskip("pandas")
    df = result.to_pandas()
    assert list(df.columns) == result.header
    for col in ("id", "kp", "kd", "final_z", "last_1s_std_mm", "push_dip_mm", "status"):
        assert col in df.columns
    assert len(df) == 2
    assert df["final_z"].tolist() == list(result["final_z"])


def test_out_writes_the_same_bytes_as_cli(run, tmp_path):
    res = pc.sweep(GRID, seconds=SECONDS, progress=False, out=tmp_path / "api")
    assert res.out == tmp_path / "api"
    run("sweep", *CLI_GRID, "--seconds", SECONDS, "-o", tmp_path / "cli", "-q", check=0)
    assert (tmp_path / "api" / "summary.csv").read_bytes() == \
        (tmp_path / "cli" / "summary.csv").read_bytes()
    assert (tmp_path / "api" / "manifest.json").is_file()


def test_out_exists_is_output_error(tmp_path):
    (tmp_path / "api").mkdir()
    with pytest.raises(pc.OutputError, match="already exists"):
        pc.sweep(GRID, seconds=1, progress=False, out=tmp_path / "api")


def test_load_run_round_trips(tmp_path):
    res = pc.sweep(GRID, seconds=SECONDS, progress=False, out=tmp_path / "r", trace=True)
    back = pc.load_run(tmp_path / "r")
    assert back.header == res.header
    assert back.rows == res.rows
    assert back.complete is True
    assert back.out == tmp_path / "r"
    assert back.config["schedule"]["duration"] == SECONDS
    assert back.best("last_1s_std_mm")["id"] == res.best("last_1s_std_mm")["id"]
    for col in res.header:
        a, b = res[col], back[col]
        if isinstance(a, list):
            assert a == b
        else:
            np.testing.assert_array_equal(a, b)
    assert sorted(back.traces) == sorted(res.traces)
    for cid, (t, z) in res.traces.items():
        np.testing.assert_array_equal(back.traces[cid][0], t)
        np.testing.assert_array_equal(back.traces[cid][1], z)


@pytest.mark.parametrize("seconds,every", [(1.0, 10), (1.001, 7)])
def test_trace_lengths(seconds, every):
    res = pc.sweep({"kp": [5, 30]}, seconds=seconds, trace=True, trace_every=every,
                   progress=False)
    dt = 0.002
    # the loop runs while the accumulated time is < seconds
    steps, t = 0, 0.0
    while t < seconds:
        t += dt
        steps += 1
    assert sorted(res.traces) == sorted(res.ids)
    for cid, (t, z) in res.traces.items():
        assert len(t) == len(z) == math.ceil(steps / every), (cid, len(t), steps)
        assert t[0] == pytest.approx(dt)
        assert np.all(np.diff(t) > 0)
        assert np.all((z > 0.05) & (z < 0.3))


def test_no_trace_by_default(result):
    assert result.traces == {}


def test_progress_callable():
    calls: list[tuple[int, int]] = []
    pc.sweep({"kp": [5, 30]}, seconds=1, progress=lambda done, total: calls.append((done, total)))
    assert calls, "the progress callable was never called"
    totals = {t for _, t in calls}
    assert len(totals) == 1
    (total,) = totals
    assert total == 2 * 500
    dones = [d for d, _ in calls]
    assert dones == sorted(dones)
    assert dones[-1] == total


def test_best_by_groups_follows_the_rule_and_the_cli(run, tmp_path):
    """best(by=...) against the rule computed here by hand, and the CLI's
    --best-by lines and best.csv against best(by=...)."""
    import csv

    grid = ["kp=2,30,120", "kd=0.05,2"]
    run("sweep", *sum((["--grid", g] for g in grid), []), "--seconds", "2", "--mode", "torque",
        "--best-by", "kd", "-o", tmp_path / "run", "-q", check=0)
    res = pc.load_run(tmp_path / "run")
    groups = res.best("last_1s_std_mm", by=["kd"])
    assert [g["kd"] for g in groups] == [0.05, 2.0]
    for g in groups:
        rows = [i for i in range(len(res)) if res["kd"][i] == g["kd"]]
        eligible = [i for i in rows if res["status"][i] == "ok" and np.isfinite(res["last_1s_std_mm"][i])
                    and res["saturation_frac"][i] < 0.05]
        assert (g["cells"], g["eligible"]) == (len(rows), len(eligible))
        want = min(eligible, key=lambda i: (res["last_1s_std_mm"][i], i)) if eligible else None
        assert g["id"] == (res["id"][want] if want is not None else None)
    with open(tmp_path / "run" / "best.csv", newline="") as f:
        written = list(csv.DictReader(f))
    assert [r["id"] or None for r in written] == [g["id"] for g in groups]
    assert res.best("last_1s_std_mm")["id"] == min(
        (g for g in groups if g["id"]), key=lambda g: g["last_1s_std_mm"])["id"]
    with pytest.raises(pc.ConfigError, match="cannot group by 'leg_scale'"):
        res.best(by=["leg_scale"])


def test_a_result_behaves_like_a_table_in_a_notebook(tmp_path):
    """`in`, iteration, HTML, plots on the result itself, a clean dir(),
    signatures that show real defaults, Python's words in messages."""
    import inspect
    import subprocess
    import sys
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = pc.sweep({"kp": [10, 30], "kd": [0.5, 1]}, seconds=2.5, progress=False)
    assert any("seconds=2.5" in str(w.message) for w in caught), [str(w.message) for w in caught]
    assert not any("--seconds" in str(w.message) for w in caught)
    assert "kp" in res and "nope" not in res
    rows = list(res)
    assert [r["id"] for r in rows] == res.ids and rows[0]["kp"] == 10.0
    html = res._repr_html_()
    assert html.startswith("<table") and html.count("<tr") == 1 + len(res)
    assert "<th>name</th>" not in html  # empty in a sweep without a preset
    assert not repr(res).splitlines()[1].split()[0] == "name"
    from pupper_core import plots

    fig = plots.heatmap(res, "final_z", x="kp", y="kd")
    assert fig.axes and fig.pupper_best
    for module in (pc, plots):
        assert not {"os", "sys", "np", "typing", "inspect"} & set(dir(module)), dir(module)
    sig = inspect.signature(pc.sweep)
    assert sig.parameters["randomize"].default == ()
    assert inspect.signature(pc.SweepResult.best).parameters["max_saturation"].default == 0.05
    lab = inspect.signature(pc._native.lab).parameters
    assert lab["seconds"].default == 6.0 and lab["max_saturation"].default == 0.05
    # no progress bar in a script whose stderr is a pipe, for a short sweep
    p = subprocess.run([sys.executable, "-c", "import pupper_core as pc; pc.sweep({'kp': [5]}, seconds=0.1)"],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and "pupper sweep" not in p.stderr and "it/s" not in p.stderr, p.stderr


def test_a_result_pickles(tmp_path):
    """A result crosses to worker processes and into files: table, traces,
    replicates, inputs and where it was written all come back."""
    import pickle

    res = pc.sweep({"kp": [10, 30]}, seconds=2.5, replicates=2, randomize=["torso_mass=±10%"],
                   trace=True, out=tmp_path / "run", progress=False)
    back = pickle.loads(pickle.dumps(res))
    assert back.header == res.header and back.rows == res.rows
    assert back.config == res.config and back.out == res.out and back.complete == res.complete
    assert back.replicates is not None and back.replicates.rows == res.replicates.rows
    assert set(back.traces) == set(res.traces)
    for cid, (t, z) in res.traces.items():
        assert list(back.traces[cid][0]) == list(t) and list(back.traces[cid][1]) == list(z)
    assert back.best("p95:last_1s_std_mm")["id"] == res.best("p95:last_1s_std_mm")["id"]
