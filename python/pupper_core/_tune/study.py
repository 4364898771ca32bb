"""A tune's run directory (``pupper_core._tune`` runs the study): a fresh
start, a resume's checks, and the journal of finished
generations that a resume rebuilds study.db from."""

from __future__ import annotations

import json
import os
import signal
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pupper_core._rundir import LOCK, atomic_write_text, clear_run, is_ours_to_ignore
from pupper_core._tune.plan import INPUT_KEYS, STUDY, TuneError, _compared, _Plan
from pupper_core._tune.tables import _spent, _write, _write_manifest

#: Finished generations, a JSON line each, appended and fsynced once the
#: whole generation is told: what a resume rebuilds study.db from.
JOURNAL = "journal.jsonl"
#: What a fresh study writes (and --force removes) in its run directory.
STUDY_FILES = ("study.db", "study.db-journal", "study.db-wal", "study.db-shm", JOURNAL, "trials.csv", "best.json",
               "pareto.csv", "manifest.json")
#: Test hook (tests/test_tune_trust.py): ``SIG:POINT:G:K`` makes the process
#: send itself SIGKILL (SIG ``KILL``) or SIGSTOP (``STOP``) after the K-th
#: ask (POINT ``ask``) or tell (``tell``) of generation G, once G is
#: journaled (``journal:G:0``), after a fresh study's first manifest
#: (``start:0:0``), or after a resume's rebuild added its K-th trial
#: (``rebuild:0:K``).
TEST_SIGNAL = "PUPPER_TUNE_TEST_SIGNAL"


def _test_signal(point: str, generation: int, k: int) -> None:
    """The test hook (TEST_SIGNAL): a kill or a stop at a named moment."""
    sig, _, at = os.environ.get(TEST_SIGNAL, "").partition(":")
    if at and at == f"{point}:{generation}:{k}":
        os.kill(os.getpid(), getattr(signal, f"SIG{sig}"))


# -- the run directory: a fresh start, a resume ----------------------------


def _check_fresh(out_dir: Path, force: bool) -> None:
    if out_dir.exists() and not out_dir.is_dir():
        raise TuneError(f"output directory '{out_dir}' is a file: choose another -o")
    if out_dir.is_dir() and not force and not all(is_ours_to_ignore(p.name) for p in out_dir.iterdir()):
        raise TuneError(f"output directory '{out_dir}' already exists: choose another -o, "
                        "add --force to overwrite it, or --resume it")


def _manifest(out_dir: Path) -> dict[str, Any]:
    """A tune's manifest.json, or one line saying why there is none to resume."""
    path = out_dir / "manifest.json"
    if not path.is_file():
        raise TuneError(f"--resume {out_dir}: no tune there (no manifest.json); start it without --resume")
    from pupper_core import _native

    try:
        manifest = _native.read_manifest(os.fspath(out_dir))
    except (OSError, _native.PupperError):
        raise TuneError(f"cannot resume {out_dir}: its manifest.json is not valid JSON (damaged?): "
                        "start the study anew with --force, or use a new -o") from None
    if not isinstance(manifest, dict) or manifest.get("kind") != "tune":
        from pupper_core import _report

        what = _report.kind_of(manifest) if isinstance(manifest, dict) else "damaged"
        raise TuneError(f"cannot resume {out_dir}: it is a {what}'s run directory, not a tune's: "
                        "give --resume a tune's directory, or start the tune with a new -o")
    inputs = manifest.get("inputs")
    if not (isinstance(inputs, dict) and all(k in inputs for k in INPUT_KEYS)
            and isinstance(inputs["options"], dict) and isinstance(inputs["space"], list)):
        raise TuneError(f"cannot resume {out_dir}: its manifest.json has no tune's inputs (damaged?): "
                        "start the study anew with --force, or use a new -o")
    return manifest


def _check_resume(out_dir: Path, plan: _Plan) -> None:
    """The study in out_dir is a tune's, of these inputs (run-only options aside)."""
    old = _manifest(out_dir)
    was, now = _compared(old["inputs"]), _compared(json.loads(json.dumps(plan.inputs)))
    if was != now:
        diff = [k for k in sorted(set(was) | set(now)) if k != "options" and was.get(k) != now.get(k)]
        options = set(was["options"]) | set(now["options"])
        diff += [k for k in sorted(options) if was["options"].get(k) != now["options"].get(k)]
        raise TuneError(f"cannot resume {out_dir}: this command differs in {', '.join(diff)}; "
                        "rerun the original command with --resume, or use a new -o", kind="resume_mismatch")




def _discard(out_dir: Path, made: bool) -> None:
    """A fresh study's files, and its directory if this tune made it."""
    for name in (*STUDY_FILES, "report.html"):
        (out_dir / name).unlink(missing_ok=True)
    if made:
        (out_dir / LOCK).unlink(missing_ok=True)
        try:
            out_dir.rmdir()
        except OSError:
            pass  # something else was put there meanwhile: it stays


def _started(optuna: Any, out_dir: Path, plan: _Plan, force: bool) -> Any:
    if force:
        # every file of the older run, whatever kind wrote it
        clear_run(out_dir)
    # the manifest first: a kill before it leaves no file but the lock, and
    # the same command starts again; a kill at any later moment leaves a
    # study to resume (without a journal yet, from no generation)
    _write_manifest(out_dir, plan, 0, 0, complete=False)
    _test_signal("start", 0, 0)
    (out_dir / JOURNAL).write_bytes(b"")
    _write(out_dir, plan, None, 0, complete=False)
    storage = optuna.storages.RDBStorage(f"sqlite:///{(out_dir / 'study.db').resolve()}")
    return optuna.create_study(study_name=STUDY, storage=storage, directions=plan.directions, load_if_exists=True)


def _resumed(optuna: Any, out_dir: Path, plan: _Plan) -> Any:
    """The study as its journal left it: study.db rebuilt from the
    generations told whole; a generation a kill cut (half asked, half
    told) runs again, its sampler seeing what it saw the first time."""
    records = _read_journal(out_dir)
    if records is None:
        # an earlier pupper's run directory: the journal from its study.db
        records = _records_from_study(optuna, out_dir)
    _rebuild(optuna, out_dir, plan, records)
    # the journal without a torn last line, or made from study.db (a kill
    # before this leaves the old one, from which the next resume rebuilds)
    text = "".join(_journal_line(r) for r in records)
    if not (out_dir / JOURNAL).is_file() or (out_dir / JOURNAL).read_bytes() != text.encode():
        atomic_write_text(out_dir / JOURNAL, text)
    storage = optuna.storages.RDBStorage(f"sqlite:///{(out_dir / 'study.db').resolve()}")
    study = optuna.load_study(study_name=STUDY, storage=storage)
    _write(out_dir, plan, study, _spent(study), complete=False)
    return study


# -- the journal: finished generations, what a resume rebuilds ---------------


def _trial_record(t: Any) -> dict[str, Any]:
    """A finished trial as the storage holds it: the samplers' own system
    attributes too (CMA-ES keeps its optimizer there)."""
    return {"number": t.number, "state": t.state.name, "params": t.params, "values": t.values,
            "intermediate_values": {str(k): v for k, v in t.intermediate_values.items()},
            "user_attrs": t.user_attrs, "system_attrs": t.system_attrs}


def _journal_line(record: Mapping[str, Any]) -> str:
    return json.dumps(record, separators=(",", ":")) + "\n"


def _append_journal(out_dir: Path, study: Any, generation: int) -> None:
    """Generation `generation`, told whole, as one line, fsynced: a kill
    before its last byte leaves a torn line, which a resume drops."""
    trials = sorted((t for t in study.get_trials(deepcopy=False) if t.user_attrs.get("generation") == generation),
                    key=lambda t: t.number)
    data = _journal_line({"generation": generation, "trials": [_trial_record(t) for t in trials]}).encode()
    fd = os.open(out_dir / JOURNAL, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        while data:
            data = data[os.write(fd, data):]
        os.fsync(fd)
    finally:
        os.close(fd)


def _read_journal(out_dir: Path) -> list[dict[str, Any]] | None:
    """The journal's generations (None without a journal). A last line
    without its newline is one a kill tore: dropped."""
    try:
        lines = (out_dir / JOURNAL).read_bytes().split(b"\n")
    except FileNotFoundError:
        return None
    records = []
    for k, line in enumerate(lines[:-1]):
        try:
            record = json.loads(line)
            sound = (isinstance(record, dict) and record.get("generation") == k
                     and isinstance(record.get("trials"), list))
        except ValueError:
            sound = False
        if not sound:
            raise TuneError(f"cannot resume {out_dir}: its {JOURNAL} line {k + 1} is damaged: "
                            "start the study anew with --force, or use a new -o")
        records.append(record)
    return records


def _records_from_study(optuna: Any, out_dir: Path) -> list[dict[str, Any]]:
    """The generations of an earlier pupper's study.db told whole (every
    trial complete or pruned), from the first: a half told one and those
    after it run again."""
    path = out_dir / "study.db"
    if not path.is_file():
        return []
    from sqlalchemy.exc import SQLAlchemyError

    try:
        storage = optuna.storages.RDBStorage(f"sqlite:///{path.resolve()}")
        try:
            trials = optuna.load_study(study_name=STUDY, storage=storage).get_trials(deepcopy=False)
        finally:
            storage.engine.dispose()
    except (SQLAlchemyError, KeyError, RuntimeError, ValueError) as e:
        raise TuneError(f"cannot resume {out_dir}: its study.db cannot be read ({type(e).__name__}) and there "
                        f"is no {JOURNAL} to rebuild it from: start the study anew with --force, or use a new -o"
                        ) from None
    by_generation: dict[Any, list[Any]] = {}
    for t in trials:
        by_generation.setdefault(t.user_attrs.get("generation"), []).append(t)
    told = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)
    records: list[dict[str, Any]] = []
    while len(records) in by_generation and all(t.state in told for t in by_generation[len(records)]):
        g = len(records)
        records.append({"generation": g, "trials": [_trial_record(t) for t in
                                                    sorted(by_generation[g], key=lambda t: t.number)]})
    return records


def _rebuild(optuna: Any, out_dir: Path, plan: _Plan, records: Sequence[Mapping[str, Any]]) -> None:
    """study.db anew from the journal's generations, each trial added as it
    was told (its number, parameters, values, attributes, the samplers' own
    ones): the study the next generation's sampler sees is the
    uninterrupted one's. Built in a temporary file moved into place at the
    end: a kill during it leaves the journal, and the next resume starts
    again."""
    dists = {d.axis: d.distribution(optuna) for d in plan.dims}
    states = optuna.trial.TrialState
    fd, tmp = tempfile.mkstemp(dir=out_dir, prefix=".study.db.", suffix=".tmp")
    os.close(fd)

    def unsynced() -> Any:
        # no fsync per added trial (a file replaced whole at the end, fsynced
        # once): a resume of a long study takes a moment, not a minute
        import sqlite3

        con = sqlite3.connect(tmp, check_same_thread=False)
        con.execute("PRAGMA synchronous=OFF")
        return con

    storage = optuna.storages.RDBStorage(f"sqlite:///{Path(tmp).resolve()}", engine_kwargs={"creator": unsynced})
    try:
        study = optuna.create_study(study_name=STUDY, storage=storage, directions=plan.directions)
        n = 0
        for g, record in enumerate(records):
            try:
                if not all(t["state"] in ("COMPLETE", "PRUNED") for t in record["trials"]):
                    raise ValueError("a journal holds finished trials only")
                frozen = [optuna.trial.create_trial(
                    state=states[t["state"]], params=t["params"], distributions=dists, values=t["values"],
                    user_attrs=t["user_attrs"], system_attrs=t["system_attrs"],
                    intermediate_values={int(k): v for k, v in t["intermediate_values"].items()})
                    for t in record["trials"]]
            except (KeyError, TypeError, ValueError, AttributeError):
                raise TuneError(f"cannot resume {out_dir}: its {JOURNAL} line {g + 1} is damaged (or its space "
                                "differs): start the study anew with --force, or use a new -o") from None
            for t in frozen:
                study.add_trial(t)
                n += 1
                _test_signal("rebuild", 0, n)
    except BaseException:
        storage.engine.dispose()
        os.unlink(tmp)
        raise
    storage.engine.dispose()
    with open(tmp, "rb") as f:
        os.fsync(f.fileno())
    # SQLite's rollback journal of the old study.db would be played into the new one
    for side in ("study.db-journal", "study.db-wal", "study.db-shm"):
        (out_dir / side).unlink(missing_ok=True)
    os.replace(tmp, out_dir / "study.db")
