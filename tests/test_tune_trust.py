"""`pupper tune`, trust (issue 36): a kill -9 at any moment and a resume
give the uninterrupted study byte for byte (TPE, CMA-ES and halving); a
second pupper on a running study's directory is refused and the running
study goes on untouched; bad input is one line, exit 2, before anything is
written; a study with nothing to rank says so instead of naming a penalty
as its best."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest

from conftest import assert_refused, clean_env

pc = pytest.importorskip("pupper_core")
pytest.importorskip("optuna")

from pupper_core import _tune as T  # noqa: E402

#: Cheap studies (1.5 s cells, no push): each kind of sampler state that a
#: resume must rebuild — TPE's history, CMA-ES's optimizer (kept in the
#: trials' system attributes), halving's rungs and pruned trials.
STUDIES = {
    "tpe": ["--space", "kp=2:60:log", "--space", "kd=0.05:2:log", "--objective", "tracking_rms",
            "--trials", "16", "--batch", "4", "--seconds", "1.5", "--no-push", "-q"],
    "cmaes": ["--space", "kp=2:60:log", "--space", "kd=0.05:2:log", "--objective", "tracking_rms",
              "--sampler", "cmaes", "--trials", "16", "--batch", "4", "--seconds", "1.5", "--no-push", "-q"],
    "halving": ["--space", "kp=2:60:log", "--kd", "0.3", "--objective", "tracking_rms", "--trials", "16",
                "--batch", "8", "--seed", "2", "--replicates", "4", "--randomize", "motor_gain=±10%",
                "--aggregate", "p95", "--halving", "4", "--seconds", "1.5", "--no-push", "-q"],
}
RESULTS = ("trials.csv", "best.json")


def _pupper(pupper_bin: Path, *args: object, env: dict[str, str] | None = None,
            cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(pupper_bin), *map(str, args)], env=clean_env(**(env or {})), cwd=cwd,
                          capture_output=True, text=True, timeout=240)


@pytest.fixture(scope="module")
def whole(pupper_bin: Path, tmp_path_factory: pytest.TempPathFactory):
    """The uninterrupted run of each study, made once."""
    made: dict[str, Path] = {}

    def get(name: str) -> Path:
        if name not in made:
            d = tmp_path_factory.mktemp("whole") / name
            p = _pupper(pupper_bin, "tune", *STUDIES[name], "-o", d)
            assert p.returncode == 0, p.stderr
            made[name] = d
        return made[name]

    return get


def _same_results(got: Path, want: Path) -> None:
    for n in RESULTS:
        assert (got / n).read_bytes() == (want / n).read_bytes(), f"{n} differs from the uninterrupted run's"


# A kill at a named moment: the test hook PUPPER_TUNE_TEST_SIGNAL=KILL:POINT:G:K
# makes the process SIGKILL itself there. ask:G:K after the K-th ask of
# generation G (asked, none told); tell:G:K after its K-th tell (the
# generation half told: the case that repeated trials before); tell:G:<all>
# told but not journaled; journal:G:0 journaled but trials.csv not rewritten;
# start:0:0 a fresh study's manifest written, nothing else yet.
KILLS = [
    ("tpe", "start:0:0"),
    ("tpe", "ask:1:2"),
    ("tpe", "tell:2:1"),
    ("tpe", "tell:2:3"),
    ("tpe", "tell:1:4"),
    ("tpe", "journal:2:0"),
    ("tpe", "tell:0:2"),
    ("cmaes", "tell:2:2"),
    ("cmaes", "tell:3:3"),
    ("cmaes", "journal:1:0"),
    ("halving", "tell:1:3"),
    ("halving", "tell:0:8"),
]


@pytest.mark.parametrize("study,moment", KILLS, ids=[f"{s}-{m}" for s, m in KILLS])
def test_a_kill_at_a_named_moment_resumes_to_the_uninterrupted_study(pupper_bin, whole, tmp_path, study, moment):
    cut = tmp_path / "cut"
    p = _pupper(pupper_bin, "tune", *STUDIES[study], "-o", cut, env={"PUPPER_TUNE_TEST_SIGNAL": f"KILL:{moment}"})
    assert p.returncode == -signal.SIGKILL, (p.returncode, p.stderr)
    p = _pupper(pupper_bin, "tune", "--resume", cut, "-q")
    assert p.returncode == 0, p.stderr
    assert "16 trials" in p.stdout, p.stdout
    _same_results(cut, whole(study))


@pytest.mark.parametrize("sig", ["INT", "TERM"])
def test_a_stop_in_the_middle_of_a_generations_bookkeeping_waits_for_its_end(pupper_bin, whole, tmp_path, sig):
    """SIGINT or SIGTERM while a generation is being told (the study's
    SQLite queries, where a KeyboardInterrupt left SQLAlchemy printing a
    traceback) stops the tune at the next batch instead: that generation
    is told and journaled whole, stderr is the one line, and the resume
    gives the uninterrupted study."""
    cut = tmp_path / "cut"
    p = _pupper(pupper_bin, "tune", *STUDIES["tpe"], "-o", cut, env={"PUPPER_TUNE_TEST_SIGNAL": f"{sig}:tell:1:2"})
    assert p.returncode == 130, (p.returncode, p.stderr)
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and f"tune stopped by SIG{sig}" in lines[0] and "--resume" in lines[0], p.stderr
    journal = [json.loads(ln) for ln in (cut / "journal.jsonl").read_text().splitlines()]
    assert [g["generation"] for g in journal] == [0, 1]
    assert [len(g["trials"]) for g in journal] == [4, 4]
    p = _pupper(pupper_bin, "tune", "--resume", cut, "-q")
    assert p.returncode == 0, p.stderr
    _same_results(cut, whole("tpe"))


def test_a_kill_during_the_rebuild_of_a_resume_is_harmless(pupper_bin, whole, tmp_path):
    """A resume rebuilds study.db from the journal into a temporary file:
    killed half way through, the next resume starts it again."""
    cut = tmp_path / "cut"
    p = _pupper(pupper_bin, "tune", *STUDIES["tpe"], "-o", cut, env={"PUPPER_TUNE_TEST_SIGNAL": "KILL:tell:2:2"})
    assert p.returncode == -signal.SIGKILL, p.stderr
    p = _pupper(pupper_bin, "tune", "--resume", cut, "-q", env={"PUPPER_TUNE_TEST_SIGNAL": "KILL:rebuild:0:5"})
    assert p.returncode == -signal.SIGKILL, p.stderr
    p = _pupper(pupper_bin, "tune", "--resume", cut, "-q")
    assert p.returncode == 0, p.stderr
    _same_results(cut, whole("tpe"))
    assert not [f.name for f in cut.iterdir() if f.name.endswith(".tmp")]


def test_kills_at_several_wall_clock_moments_resume_to_the_uninterrupted_study(pupper_bin, whole, tmp_path):
    """Whatever the moment of a kill -9 (starting up, asking, running,
    telling, writing), the resumed study is the uninterrupted one; a kill
    before the study was set up leaves nothing to resume, and the same
    command starts it again."""
    want = whole("tpe")
    t0 = time.monotonic()
    _pupper(pupper_bin, "tune", *STUDIES["tpe"], "-o", tmp_path / "timing")
    span = time.monotonic() - t0
    for k, f in enumerate((0.25, 0.5, 0.75, 0.95)):
        cut = tmp_path / f"cut{k}"
        proc = subprocess.Popen([str(pupper_bin), "tune", *STUDIES["tpe"], "-o", str(cut)], env=clean_env(),
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(f * span)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
        if (cut / "manifest.json").exists():
            p = _pupper(pupper_bin, "tune", "--resume", cut, "-q")
        else:
            p = _pupper(pupper_bin, "tune", *STUDIES["tpe"], "-o", cut)
        assert p.returncode == 0, (f, p.stderr)
        _same_results(cut, want)


def test_a_garbage_study_db_beside_its_journal_is_rebuilt(pupper_bin, whole, tmp_path):
    cut = tmp_path / "cut"
    p = _pupper(pupper_bin, "tune", *STUDIES["tpe"], "-o", cut, env={"PUPPER_TUNE_TEST_SIGNAL": "KILL:tell:2:1"})
    assert p.returncode == -signal.SIGKILL
    (cut / "study.db").write_bytes(b"this is not a database" * 100)
    p = _pupper(pupper_bin, "tune", "--resume", cut, "-q")
    assert p.returncode == 0, p.stderr
    _same_results(cut, whole("tpe"))


def test_a_study_without_a_journal_resumes_from_its_study_db(pupper_bin, whole, tmp_path):
    """A run directory of an earlier pupper has no journal: its study.db's
    fully told generations are taken, a half told one is run again."""
    cut = tmp_path / "cut"
    p = _pupper(pupper_bin, "tune", *STUDIES["tpe"], "-o", cut, env={"PUPPER_TUNE_TEST_SIGNAL": "KILL:tell:2:2"})
    assert p.returncode == -signal.SIGKILL
    (cut / "journal.jsonl").unlink()
    p = _pupper(pupper_bin, "tune", "--resume", cut, "-q")
    assert p.returncode == 0, p.stderr
    _same_results(cut, whole("tpe"))


def _snapshot(d: Path) -> dict[str, bytes]:
    return {f.name: f.read_bytes() for f in sorted(d.iterdir()) if f.is_file() and f.name != ".pupper.lock"}


def _wait_stopped(pid: int, timeout: float = 120) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        if state == "T":
            return
        time.sleep(0.05)
    raise AssertionError("the tune never reached its stop")


def test_a_second_pupper_on_a_running_study_is_refused_and_it_goes_on(pupper_bin, whole, tmp_path):
    """The running tune is held (SIGSTOP by the test hook) between two tells
    of a generation: a resume of its directory, the same command with
    --force and a sweep into it are each refused in one line; continued,
    the tune finishes as the uninterrupted one."""
    d = tmp_path / "busy"
    proc = subprocess.Popen([str(pupper_bin), "tune", *STUDIES["tpe"], "-o", str(d)],
                            env=clean_env(PUPPER_TUNE_TEST_SIGNAL="STOP:tell:1:2"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_stopped(proc.pid)
        before = _snapshot(d)
        for args in (["tune", "--resume", d, "-q"], ["tune", *STUDIES["tpe"], "-o", d, "--force"],
                     ["sweep", "--grid", "kp=10", "--seconds", "0.5", "-q", "-o", d, "--force"]):
            p = _pupper(pupper_bin, *args)
            assert p.returncode == 2, (args, p.stderr)
            assert p.stderr.count("\n") == 1 and "is being written by another pupper" in p.stderr, p.stderr
            if args[0] == "tune":
                assert f"pid {proc.pid}" in p.stderr, p.stderr
        assert _snapshot(d) == before
    finally:
        proc.send_signal(signal.SIGCONT)
    out, err = proc.communicate(timeout=240)
    assert proc.returncode == 0, err
    _same_results(d, whole("tpe"))


BAD = [
    (["--space", "kp=-5:5"], "gains must be >= 0"),
    (["--space", "timestep=0.1:0.5"], "timestep must be in [1e-6, 0.05] s"),
    (["--space", "kp=|"], "an empty choice"),
    (["--space", "variant=original|nope"], "unknown body 'nope'"),
    (["--space", "variant=0:2:int"], "the variant axis takes names"),
    (["--space", "kp=soft|stiff"], "kp takes numbers"),
    (["--space", "kp=5|5"], "the value 5 twice"),
    (["--space", "kp=1.5:5:int"], "whole numbers"),
    (["--space", "kp.hfee=5:50"], "did you mean 'kp.hfe'"),
    (["--space", "kp=5:50", "--objective="], "--objective is empty"),
    (["--space", "kp=5:50", "--objective", "tracking_rms,tracking_rms"], "tracking_rms twice"),
    (["--space", "kp=5:50", "--halving", "1"], "an eta of 2 or more"),
]


@pytest.mark.parametrize("args,words", BAD, ids=[w for _, w in BAD])
def test_bad_input_is_refused_before_anything_is_written(run, tmp_path, args, words):
    out = tmp_path / "never"
    p = run("tune", *args, "--trials", "2", "--batch", "2", "--seconds", "1.5", "-o", out)
    assert_refused(p, words, out)


def test_what_only_the_model_refuses_leaves_no_directory_either(run, tmp_path):
    """A pose of the wrong length is refused by the runner at the first
    generation, once the model is loaded: the study it began is removed."""
    out = tmp_path / "never"
    p = run("tune", "--space", "kp=5:50", "--pose", "0,0", "--trials", "2", "--batch", "2", "--seconds", "1.5",
            "-o", out)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "the pose has 2 angles" in p.stderr, p.stderr
    assert not out.exists()


def test_gp_without_torch_is_refused_before_the_directory_is_made(run, tmp_path):
    try:
        import torch  # noqa: F401
        pytest.skip("torch is installed here")
    except ImportError:
        pass
    out = tmp_path / "never"
    p = run("tune", "--space", "kp=5:50", "--sampler", "gp", "--trials", "2", "-o", out)
    assert p.returncode == 2 and "needs torch" in p.stderr and p.stderr.count("\n") == 1, p.stderr
    assert not out.exists()


def test_axis_names_are_case_blind_as_in_sweep(run, tmp_path):
    """`--grid KP.HFE=...` is sweep's kp.hfe; so is tune's `--space`: the
    same study, under the axis's own name."""
    args = ["--kd", "0.5", "--trials", "2", "--batch", "2", "--seconds", "1.5", "--no-push", "-q"]
    run("tune", "--space", "kp.hfe=5:50:log", *args, "-o", tmp_path / "lower", check=0)
    run("tune", "--space", "KP.HFE=5:50:log", *args, "-o", tmp_path / "upper", check=0)
    _same_results(tmp_path / "upper", tmp_path / "lower")
    assert (tmp_path / "upper" / "trials.csv").read_text().startswith("trial,generation,slot,kp.hfe,")


def _tune_dir(run, d: Path) -> None:
    run("tune", "--space", "kp=5:50:log", "--kd", "0.5", "--trials", "2", "--batch", "2", "--seconds", "1.5",
        "--no-push", "-q", "-o", d, check=0)


@pytest.mark.parametrize("what", ["sweep", "fit", "garbage manifest", "garbage study.db", "damaged journal"])
def test_a_resume_of_what_is_not_a_sound_tune_is_one_line(run, tmp_path, what):
    d = tmp_path / "d"
    words = {"sweep": "is a sweep's run directory, not a tune's", "fit": "is a fit's run directory, not a tune's",
             "garbage manifest": "manifest.json is not valid JSON", "garbage study.db": "study.db cannot be read",
             "damaged journal": "journal.jsonl line 1 is damaged"}[what]
    if what == "sweep":
        run("sweep", "--grid", "kp=10", "--seconds", "0.5", "-q", "-o", d, check=0)
    else:
        _tune_dir(run, d)
    if what == "fit":
        (d / "manifest.json").write_text(json.dumps({"command": "fit", "inputs": {"model": "pupper_v3"}}))
    elif what == "garbage manifest":
        (d / "manifest.json").write_text('{"kind": "tune", "inp')
    elif what == "garbage study.db":
        # a run directory of an earlier pupper (no journal) whose study.db is damaged
        (d / "journal.jsonl").unlink()
        (d / "study.db").write_bytes(b"not a database" * 100)
    elif what == "damaged journal":
        lines = (d / "journal.jsonl").read_text().splitlines(keepends=True)
        (d / "journal.jsonl").write_text("{garbage\n" + "".join(lines))
    before = _snapshot(d)
    p = run("tune", "--resume", d, "-q")
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], p.stderr
    assert _snapshot(d) == before


def test_a_torn_last_journal_line_is_ignored(run, tmp_path):
    """A kill while a generation's line was being appended leaves a part of
    it: that generation is run again."""
    d = tmp_path / "d"
    _tune_dir(run, d)
    want = (d / "trials.csv").read_bytes()
    journal = d / "journal.jsonl"
    text = journal.read_text()
    journal.write_text(text[: len(text) // 2])  # the last (only) line, torn
    p = run("tune", "--resume", d, "-q", check=0)
    assert "2 trials" in p.stdout
    assert (d / "trials.csv").read_bytes() == want
    assert journal.read_text() == text


def test_a_study_with_nothing_to_rank_says_so(run, tmp_path):
    """At 1.5 s there is no last-second-after-the-push to measure: every
    trial is told the penalty, and none of them is a best."""
    d = tmp_path / "d"
    p = run("tune", "--space", "kp=5:50", "--space", "kd=0.1:1", "--seconds", "1.5", "--trials", "4", "--batch", "4",
            "-q", "-o", d, "--plot", check=0)
    assert "best (" not in p.stdout and "->" not in p.stdout, p.stdout
    assert "no trial could be ranked: 4 no value (last_1s_std_mm empty)" in p.stdout, p.stdout
    assert json.loads((d / "best.json").read_text()) == []
    # the plots draw the crosses alone
    assert sorted(p.name for p in (d / "plots").iterdir()) == ["tune_progress.png", "tune_trials.png"]


def test_tune_error_is_a_pupper_config_error():
    assert issubclass(T.TuneError, pc.ConfigError) and issubclass(T.TuneError, ValueError)
    with pytest.raises(pc.PupperError) as e:
        T.tune(["kp=-5:5"], trials=2, progress=False)
    assert e.value.kind == "config" and "gains must be >= 0" in str(e.value)


def test_a_tune_holds_its_directory_against_a_python_caller_too(tmp_path):
    """The lock is the run directory's (.pupper.lock, flock): a holder in this
    process is refused a second study in the same directory."""
    import fcntl

    d = tmp_path / "d"
    d.mkdir()
    with open(d / ".pupper.lock", "a+") as f:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(T.TuneError, match="is being written by another pupper") as e:
            T.tune(["kp=5:50"], trials=2, batch=2, seconds=1.5, push=False, progress=False, out=d)
        assert e.value.kind == "run_busy"
    assert sorted(p.name for p in d.iterdir()) == [".pupper.lock"]


def test_a_held_stop_waits_for_the_holds_end_and_dies_with_its_command():
    """`held_signals` (a tune's storage queries): a SIGTERM inside it is
    raised at its end, not in the middle; one that arrives in a block that
    fails anyway is not raised later, in the next command's."""
    import os
    import threading

    from pupper_core import _rundir as R

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signals reach the main thread only")
    reached = False
    with pytest.raises(KeyboardInterrupt, match="x stopped by SIGTERM"):
        with R.stop_on_signals("x"), R.held_signals():
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)  # the handler has run by now: held
            reached = True
    assert reached
    with R.stop_on_signals("y"):
        with pytest.raises(ValueError), R.held_signals():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
            raise ValueError
        try:
            with R.held_signals(), R.signals_through():
                pass
        except KeyboardInterrupt as e:  # (not pytest's own Ctrl-C)
            pytest.fail(f"a stop from a failed block was raised in the next one: {e}")
