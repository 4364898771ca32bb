"""`pupper tune`: Optuna's ask/tell over pupper's runner, a generation per
batch. Samplers find a known optimum; the study is the same at any thread
count and across a kill and resume; bad input is one line."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import assert_refused, clean_env, read_csv, wait_rows

pc = pytest.importorskip("pupper_core")
pytest.importorskip("optuna")

from pupper_core import _tune as T  # noqa: E402

#: A cheap question with a known answer: the stiffer the servos, the smaller
#: the joints' tracking error, so the optimum is kp's upper bound.
CHEAP = dict(seconds=1.5, push=False, kd=0.3)


@pytest.mark.parametrize("sampler", ["tpe", "cmaes", "random"])
def test_each_sampler_finds_a_known_optimum(sampler):
    res = T.tune(["kp=2:60:log"], objective="tracking_rms", trials=24, batch=8, sampler=sampler,
                 seed=1, progress=False, **CHEAP)
    best = res.best[0]["params"]["kp"]
    # the top fifth of the log range
    assert best > 60 * (2 / 60) ** 0.2, (sampler, best)
    # a trial that fell stopped early: never more than the full schedule
    assert len(res.trials) == 24 and 0 < res.cell_steps <= 24 * 750
    if sampler == "tpe":
        df = res.to_pandas()  # a row per trial, the columns of trials.csv
        assert len(df) == 24 and list(df.columns) == list(res.trials[0])
        assert df["tracking_rms"].min() == min(t["tracking_rms"] for t in res.trials)


def test_gp_without_torch_says_so_in_one_line():
    try:
        import torch  # noqa: F401
        pytest.skip("torch is installed here")
    except ImportError:
        pass
    with pytest.raises(T.TuneError, match="needs torch"):
        T.tune(["kp=2:60:log"], trials=2, batch=2, sampler="gp", progress=False, **CHEAP)


def _args(out: Path) -> list[str]:
    return ["tune", "--space", "kp=2:60:log", "--space", "kd=0.05:2:log", "--objective", "tracking_rms",
            "--trials", "24", "--batch", "4", "--seconds", "1.5", "--no-push", "-q", "-o", str(out)]


def test_the_study_is_the_same_at_any_thread_count(run, tmp_path):
    run(*_args(tmp_path / "a"), "-j", "1", check=0)
    run(*_args(tmp_path / "b"), "-j", "2", check=0)
    a, b = ((tmp_path / d / "trials.csv").read_bytes() for d in ("a", "b"))
    assert a == b
    _, rows = read_csv(tmp_path / "a" / "trials.csv")
    assert len(rows) == 24 and [r["generation"] for r in rows[:5]] == ["0", "0", "0", "0", "1"]
    best = json.loads((tmp_path / "a" / "best.json").read_text())[0]
    assert float(best["values"][0]) == min(float(r["tracking_rms"]) for r in rows)
    manifest = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert manifest["complete"] and manifest["cell_steps"] <= 24 * 750 and manifest["trials"] == 24
    assert manifest["cell_steps"] == sum(int(r["cell_steps"]) for r in rows)


def test_the_schedule_flags_of_sweep_reach_the_trials(run, tmp_path):
    """--push-at, --push-force, --sine and --chunk-cells as sweep takes them:
    the trial's cell is the sweep of the same flags, to the digit; a resume
    may change the threads or the chunk size (they never change numbers)."""
    flags = ["--seconds", "2", "--push-at", "0.2", "--push-force", "-15", "--sine", "1,2"]
    run("tune", "--space", "kp=5:50:log", "--kd", "0.5", "--objective", "push_dip_mm", "--trials", "2",
        "--batch", "2", *flags, "--chunk-cells", "1", "-q", "-o", tmp_path / "t", check=0)
    _, rows = read_csv(tmp_path / "t" / "trials.csv")
    kp = rows[0]["kp"]
    run("sweep", "--grid", f"kp={kp}", "--kd", "0.5", *flags, "--stop-fallen", "-q", "-o", tmp_path / "s", check=0)
    _, cell = read_csv(tmp_path / "s" / "summary.csv")
    assert float(rows[0]["push_dip_mm"]) == float(cell[0]["push_dip_mm"])
    p = run("tune", "--resume", tmp_path / "t", "--trials", "4", "-j", "1", "-q", check=0)
    assert "4 trials" in p.stdout, p.stdout + p.stderr
    # what decides numbers may not change: the refusal names it
    p = run("tune", "--space", "kp=5:50:log", "--kd", "0.7", "--objective", "push_dip_mm", "--trials", "4",
            "--batch", "2", *flags, "-q", "--resume", tmp_path / "t", check=2)
    assert "differs in kd;" in p.stderr and p.stderr.count("\n") == 1, p.stderr


def test_a_kill_and_resume_neither_repeat_nor_lose_a_trial(pupper_bin, run, tmp_path):
    run(*_args(tmp_path / "whole"), check=0)
    cut = tmp_path / "cut"
    proc = subprocess.Popen([str(pupper_bin), *_args(cut)], env=clean_env(), cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    trials = cut / "trials.csv"
    wait_rows(trials, proc, 8)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    kept = len(trials.read_text().splitlines()) - 1
    assert 0 < kept < 24, kept
    p = run("tune", "--resume", cut, "-q", check=0)
    assert "24 trials" in p.stdout
    assert trials.read_bytes() == (tmp_path / "whole" / "trials.csv").read_bytes()


def test_several_objectives_give_a_pareto_front(tmp_path):
    res = T.tune(["kp=2:60:log", "kd=0.05:2:log"], objective="tracking_rms,peak_torque", trials=16, batch=8,
                 seed=3, progress=False, out=tmp_path / "p", **CHEAP)
    _, front = read_csv(tmp_path / "p" / "pareto.csv")
    assert front and len(front) == len(res.best)
    pts = [(float(r["tracking_rms"]), float(r["peak_torque"])) for r in front]
    # no point of the front is dominated by another trial
    for a in pts:
        assert not any(b[0] <= a[0] and b[1] <= a[1] and b != a for b in
                       [(t["tracking_rms"], t["peak_torque"]) for t in res.trials])


BAD = [
    (["--space", "kp=50:5"], "LOW < HIGH"),
    (["--space", "kp=0:50:log"], "LOW > 0"),
    (["--space", "kq=1:5", "--trials", "4"], "unknown grid axis 'kq'"),
    (["--space", "kp=1:5", "--budget", "100"], "below one generation"),
    (["--space", "kp=1:5"], "give --trials N or --budget"),
    (["--space", "kp=1:5", "--trials", "4", "--objective", "nope"], "is not a metric"),
]


@pytest.mark.parametrize("args,words", BAD, ids=[w for _, w in BAD])
def test_bad_input_is_one_line_exit_2_and_nothing_written(run, tmp_path, args, words):
    out = tmp_path / "never"
    p = run("tune", *args, "-o", out)
    assert_refused(p, words, out)


def test_without_the_extra_one_line_names_it(tmp_path):
    code = ("import sys; sys.modules['optuna'] = None\n"
            "from pupper_core import _tune as tune\n"
            "try:\n    tune.tune(['kp=1:5'], trials=1)\n"
            "except tune.TuneError as e:\n    print(e)\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.stdout.strip() == ("pupper tune needs Optuna: install the extra with `make setup PUPPER_EXTRAS=tune` "
                                "(or pip install 'pupper_core[tune]')"), p.stdout + p.stderr


@pytest.mark.parametrize("where,after", [("ask", 6), ("tell", 6), ("ask", 1)])
def test_a_stop_mid_ask_or_mid_tell_resumes_to_the_same_study(tmp_path, monkeypatch, where, after):
    """The moments a kill can fall between: while a generation is being
    asked (some trials running), and while it is being told (some told)."""
    import optuna

    args = dict(objective="tracking_rms", trials=16, batch=4, seed=5, progress=False, **CHEAP)
    T.tune(["kp=2:60:log", "kd=0.05:2:log"], out=tmp_path / "whole", **args)
    real = getattr(optuna.study.Study, where)
    calls = {"n": 0}

    def dying(self, *a, **kw):
        calls["n"] += 1
        if calls["n"] > after:
            raise KeyboardInterrupt("killed")
        return real(self, *a, **kw)

    monkeypatch.setattr(optuna.study.Study, where, dying)
    with pytest.raises(KeyboardInterrupt):
        T.tune(["kp=2:60:log", "kd=0.05:2:log"], out=tmp_path / "cut", **args)
    monkeypatch.setattr(optuna.study.Study, where, real)
    T.tune(["kp=2:60:log", "kd=0.05:2:log"], out=tmp_path / "cut", resume=True, **args)
    assert (tmp_path / "cut" / "trials.csv").read_bytes() == (tmp_path / "whole" / "trials.csv").read_bytes()


def test_early_stop_spends_less_and_changes_no_standing_cell(run, tmp_path):
    """`sweep --stop-fallen`: a robot that falls (below the fall line or
    past the fall tilt at some moment) stops stepping: fewer cell-steps,
    status fell; every other row is byte-identical. (A slow collapse is
    judged on the last second, at the end, so it runs to the end.)"""
    grid = {"kp": [1, 5, 30], "kd": [0.05, 0.5]}
    push = dict(push_force=-300, seconds=4, progress=False)
    full = pc.sweep(grid, **push)
    cut = pc.sweep(grid, stop_fallen=True, **push)
    stopped = [i for i, n in enumerate(cut.cell_steps) if n < full.cell_steps[i]]
    assert stopped, list(zip(full["status"], full["event_time"]))
    assert sum(cut.cell_steps) < sum(full.cell_steps)
    for i in range(len(full)):
        assert cut["status"][i] == full["status"][i]
        if i in stopped:
            assert cut["status"][i] == "fell" and cut.cell_steps[i] <= full["event_time"][i] / 0.002 + 251
        else:
            assert cut.rows[i] == full.rows[i]
    # the CLI's flag is the same switch
    args = ["sweep", "--grid", "kp=1,5,30", "--grid", "kd=0.05,0.5", "--push-force", "-300", "--seconds", "4",
            "-q", "--stop-fallen"]
    run(*args, "-o", tmp_path / "cli", check=0)
    _, rows = read_csv(tmp_path / "cli" / "summary.csv")
    assert [list(r.values()) for r in rows] == cut.rows


def test_the_plots_show_the_search(run, tmp_path):
    run(*_args(tmp_path / "p"), "--plot", check=0)
    names = sorted(p.name for p in (tmp_path / "p" / "plots").iterdir())
    assert names == ["tune_progress.png", "tune_trials.png"]
    progress = T.progress_figure(tmp_path / "p").axes[0]
    best = [line for line in progress.lines if line.get_label() == "best so far"][0]
    ys = best.get_ydata()
    assert all(b <= a for a, b in zip(ys, ys[1:]))  # never worse as the search goes on
    _, rows = read_csv(tmp_path / "p" / "trials.csv")
    assert ys[-1] == pytest.approx(min(float(r["tracking_rms"]) for r in rows))


def test_lab_tune_answers_the_labs_question_per_body(run, tmp_path):
    d = tmp_path / "lab"
    p = run("lab", "--tune", "--variants", "original,heavy", "--trials", "8", "--batch", "8", "--seconds", "3",
            "-o", d, "-q", check=0)
    assert [line.split()[0] for line in p.stdout.splitlines()] == ["original", "heavy"]
    _, best = read_csv(d / "best.csv")
    assert [r["variant"] for r in best] == ["original", "heavy"]
    for r in best:
        manifest = json.loads((d / r["variant"] / "manifest.json").read_text())
        assert manifest["inputs"]["options"]["variant"] == r["variant"]
        assert manifest["inputs"]["options"]["mode"] == "torque"
        _, trials = read_csv(d / r["variant"] / "trials.csv")
        ok = [float(t["last_1s_std_mm"]) for t in trials if t["status"] == "ok"]
        assert float(r["last_1s_std_mm"]) == min(ok)


HALVING = dict(objective="tracking_rms", trials=16, batch=8, seed=2, progress=False, replicates=4,
               randomize=["motor_gain=±10%"], aggregate="p95", **CHEAP)


def test_halving_spends_less_and_prunes_the_rest(tmp_path):
    """Successive halving over replicates (eta 4): each generation runs all
    8 trials on 1 robot and the best 2 on all 4; the others are pruned."""
    full = T.tune(["kp=2:60:log"], **HALVING)
    half = T.tune(["kp=2:60:log"], halving=4, out=tmp_path / "h", **HALVING)
    assert half.cell_steps < full.cell_steps
    _, rows = read_csv(tmp_path / "h" / "trials.csv")
    assert len(rows) == 16
    for g in ("0", "1"):
        gen = [r for r in rows if r["generation"] == g]
        assert sorted(r["rung"] for r in gen) == ["0"] * 6 + ["1"] * 2
        assert all(r["status"] == "pruned" and int(r["cell_steps"]) == 750 for r in gen if r["rung"] == "0")
        # a promoted trial ran its first robot again with the rest
        assert all(int(r["cell_steps"]) == 750 + 4 * 750 for r in gen if r["rung"] == "1")
    best = json.loads((tmp_path / "h" / "best.json").read_text())[0]
    kept = {(r["generation"], r["slot"]) for r in rows if r["rung"] == "1"}
    assert (str(best["generation"]), str(best["slot"])) in kept


def test_halving_resumes_to_the_same_study(tmp_path, monkeypatch):
    import optuna

    T.tune(["kp=2:60:log"], halving=4, out=tmp_path / "whole", **HALVING)
    real = optuna.study.Study.tell
    calls = {"n": 0}

    def dying(self, *a, **kw):
        calls["n"] += 1
        if calls["n"] > 11:  # in the second generation's tells
            raise KeyboardInterrupt("killed")
        return real(self, *a, **kw)

    monkeypatch.setattr(optuna.study.Study, "tell", dying)
    with pytest.raises(KeyboardInterrupt):
        T.tune(["kp=2:60:log"], halving=4, out=tmp_path / "cut", **HALVING)
    monkeypatch.setattr(optuna.study.Study, "tell", real)
    T.tune(["kp=2:60:log"], halving=4, out=tmp_path / "cut", resume=True, **HALVING)
    assert (tmp_path / "cut" / "trials.csv").read_bytes() == (tmp_path / "whole" / "trials.csv").read_bytes()


def test_the_plots_put_a_grid_behind_the_search(run, tmp_path):
    run("sweep", "--grid", "kp=2:60:4:log", "--grid", "kd=0.05:2:4:log", "--seconds", "1.5", "--no-push",
        "-o", tmp_path / "grid", "-q", check=0)
    run(*_args(tmp_path / "s"), "--plot", "--compare", tmp_path / "grid", check=0)
    fig = T.progress_figure(tmp_path / "s", tmp_path / "grid")
    labels = [line.get_label() for line in fig.axes[0].lines]
    assert "grid's best so far (16 cells)" in labels
    trials = T.trials_figure(tmp_path / "s", tmp_path / "grid")
    mesh = [c for c in trials.axes[0].collections if c.__class__.__name__ == "QuadMesh"]
    assert len(mesh) == 1 and mesh[0].get_array().size == 16


def test_a_best_on_the_edge_of_the_space_is_said():
    kp, kd = T.parse_space(["kp=5:120:log", "kd=0.1:2"])
    # 5 % of the log span from the top: 120 * (5/120)**0.05 = 102.4
    assert kp.edge(110.0) == "the largest" and kp.edge(100.0) is None
    assert kp.edge(5.5) == "the smallest" and kd.edge(0.19) == "the smallest" and kd.edge(0.3) is None
    line = T.edge_line([kp, kd], {"kp": 110.0, "kd": 1.0})
    assert line is not None and "kp 110, the largest of kp=5:120:log" in line and "kd" not in line
    assert T.edge_line([kp, kd], {"kp": 50.0, "kd": 1.0}) is None


def test_the_cli_says_when_its_best_is_on_the_edge(tmp_path, pupper_bin):
    """Stiffer tracks better: the search's best drifts to the top of kp; the
    line appears exactly when the best trial (trials.csv) lies within 5 %."""
    out = tmp_path / "t"
    args = [str(pupper_bin), "tune", "--space", "kp=2:60:log", "--objective", "tracking_rms",
            "--trials", "16", "--batch", "8", "--seconds", "1.5", "--no-push", "--kd", "0.3", "-q", "-o", str(out)]
    p = subprocess.run(args, capture_output=True, text=True, env=clean_env(), timeout=300)
    assert p.returncode == 0, p.stderr
    best = json.loads((out / "best.json").read_text())
    kp = best["params"]["kp"] if "params" in best else best[0]["params"]["kp"]
    on_edge = kp >= 60 * (2 / 60) ** 0.05
    assert ("lies on the edge of the searched range" in p.stdout) == on_edge, (kp, p.stdout)
