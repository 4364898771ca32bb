"""A run directory as the Python-run kinds keep it: files written so that
a reader never sees half of one, lines on the standard streams that a full
disk cannot turn into a crash, the directory's lock (the one pupper's Rust
commands take), and SIGINT/SIGTERM turned into Ctrl-C while Python works."""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import stat
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Callable


def refuse_non_regular(path: Path) -> None:
    """Raises `OutputError` for a ``path`` that exists and is not a regular
    file (a FIFO, a device, a socket, a directory): renaming over it would
    replace the node itself, and such a node is no place for a table."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return
    if stat.S_ISREG(mode):
        return
    from pupper_core._native import OutputError

    kind = ("a directory" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode)
            else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "a socket" if stat.S_ISSOCK(mode)
            else "not a file")
    err = OutputError(f"'{path}' exists and is not a regular file ({kind}): pupper writes only regular files; "
                      "move it away or choose another path")
    err.kind = "output"
    raise err


def atomic_write(path: Path, write: Callable[[Path], None]) -> None:
    """``write(tmp)`` to a temporary name beside ``path``, then rename it over
    ``path``; the temporary file is removed on every error. A ``path`` that
    is not a regular file is refused (`refuse_non_regular`); an `OSError`
    (a full disk, a read-only folder) names ``path``, not the temporary."""
    from pupper_core import _native

    refuse_non_regular(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        write(tmp)
        # flushed and renamed by the Rust core, as a sweep's files are
        _native.publish(os.fspath(tmp), os.fspath(path))
    except OSError as e:
        if e.errno is None:
            raise
        raise type(e)(e.errno, e.strerror, os.fspath(path)) from None
    finally:
        with contextlib.suppress(OSError):
            if tmp.exists():
                tmp.unlink()


def atomic_write_text(path: Path, text: str) -> None:
    """``text`` as the whole of ``path`` (through `atomic_write`), its
    newlines as they are."""

    def write(tmp: Path) -> None:
        tmp.write_text(text, newline="")

    atomic_write(path, write)


def say(line: str) -> None:
    """``line`` on standard error. One the stream cannot take (a full disk,
    a closed stream) is dropped: there is nowhere left to say it, and the
    command's outcome is its exit status."""
    try:
        # what went to stdout before this line reaches it first, whatever
        # the buffering (a notebook, a pipe, PYTHONUNBUFFERED unset)
        sys.stdout.flush()
    except (OSError, ValueError):
        pass  # stdout's own failure: the next print or `printing` reports it
    try:
        print(line, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


@contextlib.contextmanager
def printing() -> Iterator[None]:
    """What is printed inside it reaches standard output, flushed at its
    end (the embedding binary exits without finalizing Python), or one
    `OutputError` says why it could not (a full disk); a closed pipe
    (``| head``) just ends the output, as the Rust commands do. Put only
    prints inside: any `OSError` there is standard output's."""
    from pupper_core._native import OutputError

    try:
        yield
        sys.stdout.flush()
    except BrokenPipeError:
        pass
    except OSError as e:
        fix = "free some space or send the output elsewhere" if e.errno == 28 else "send the output elsewhere"
        err = OutputError(f"cannot write to standard output: {e.strerror or e}; {fix}")
        err.kind = "disk_full" if e.errno == 28 else "io"
        raise err from None


def flush_stdout() -> None:
    """Standard output flushed, as `printing` does."""
    with printing():
        pass


# -- SIGINT and SIGTERM while Python works ----------------------------------


@contextlib.contextmanager
def stop_on_signals(what: str, left: str = "nothing written") -> Iterator[None]:
    """SIGINT and SIGTERM stop ``what`` with KeyboardInterrupt, as Ctrl-C
    stops Python, and the handlers from before are put back after. (The CLI's
    own handler only sets a flag its Rust loops read, which a fit never
    does; off the main thread Python cannot take a signal, and this does
    nothing.)"""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame: Any) -> None:
        said = f"{what} stopped by {signal.Signals(signum).name}: {left}"
        if _HOLD.depth:
            _HOLD.pending = _HOLD.pending or said
            return
        raise KeyboardInterrupt(said)

    saved = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        # the kernel's action too: a handler installed outside Python (the
        # CLI's) shows in Python as SIG_DFL or None, and only this puts it back
        raw = _raw_action(sig)
        saved.append((sig, signal.signal(sig, stop), raw))
    try:
        yield
    finally:
        _HOLD.pending = None  # a stop belongs to this command
        for sig, previous, raw in reversed(saved):
            if callable(previous) or raw is None:
                signal.signal(sig, previous if previous is not None else signal.SIG_DFL)
            else:
                _libc().sigaction(int(sig), raw, None)


class _Hold:
    """How deep in `held_signals` the main thread is, and the stop that
    waits for its end (signal handlers run on the main thread only)."""

    depth = 0
    pending: str | None = None


_HOLD = _Hold()


@contextlib.contextmanager
def held_signals() -> Iterator[None]:
    """A `stop_on_signals` stop that arrives inside waits for the block's
    end: for a storage's queries, which a KeyboardInterrupt in the middle
    leaves half-closed, SQLAlchemy then logging a traceback of it to stderr.
    `signals_through` opens it again around the long, safe-to-stop work."""
    _HOLD.depth += 1
    try:
        yield
    except BaseException:
        _HOLD.depth -= 1
        if _HOLD.depth == 0:
            _HOLD.pending = None  # the block ends anyway: no stop left for a later one
        raise
    _HOLD.depth -= 1
    _raise_pending()


@contextlib.contextmanager
def signals_through() -> Iterator[None]:
    """Inside a `held_signals` block, a stretch a stop may cut (a batch of
    simulations): a stop that waited is raised on entry."""
    depth, _HOLD.depth = _HOLD.depth, 0
    try:
        _raise_pending()
        yield
    finally:
        _HOLD.depth = depth


def _raise_pending() -> None:
    if _HOLD.depth == 0 and _HOLD.pending is not None:
        said, _HOLD.pending = _HOLD.pending, None
        raise KeyboardInterrupt(said)


def _libc() -> Any:
    return ctypes.CDLL(None, use_errno=True)


def _raw_action(sig: int) -> Any:
    """The current sigaction of ``sig`` as bytes (a buffer larger than any
    platform's struct), or None where there is no libc to ask."""
    try:
        buf = ctypes.create_string_buffer(1024)
        return buf if _libc().sigaction(int(sig), None, buf) == 0 else None
    except (OSError, AttributeError):
        return None


# -- the run directory's lock ------------------------------------------------

#: The run directory's lock file, the one pupper's Rust commands take (an
#: flock: the OS drops it when its holder dies, kill -9 included).
LOCK = ".pupper.lock"


def is_ours_to_ignore(name: str) -> bool:
    """The lock, and the temporary files a killed writer left: not a study."""
    # atomic_write's temporary files are `.NAME.tmpPID`
    return name == LOCK or name.startswith(".") and ".tmp" in name


@contextlib.contextmanager
def locked(out_dir: Path, error: Callable[[str], Exception]) -> Iterator[None]:
    """The run directory's lock for the study's whole life: the Rust core's
    lock on .pupper.lock, the one every pupper command takes, so a second
    tune or a sweep there is refused; the OS drops it when this process dies, kill
    -9 included, so a resume after a kill finds it free. At the end the
    file names nobody, as a sweep leaves it. A directory that cannot be
    written (read-only, a full disk) is `error`, one line."""
    from pupper_core import _native

    def unwritable(e: OSError) -> Exception:
        return error(f"cannot write the run directory '{out_dir}' ({e.strerror or e}): "
                     + ("free some space, or choose another -o" if e.errno == 28 else "choose another -o"))

    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        # the Rust core's lock, the one its sweeps take (it also clears a
        # killed writer's temporary files)
        held = _native.lock_run(os.fspath(out_dir))
    except OSError as e:
        raise unwritable(e) from None
    except _native.PupperError as e:
        if getattr(e, "kind", None) != "run_busy":
            raise
        busy = error(str(e))
        busy.kind = "run_busy"  # type: ignore[attr-defined]  # (the CLI's exit code for a busy run)
        raise busy from None
    try:
        yield
    finally:
        held.release()


def clear_run(out_dir: Path) -> None:
    """Every file an older run of any kind left in ``out_dir`` removed
    (``--force``), and its ``plots/`` and ``robots/`` once empty, so that
    nothing of it outlives the new run: the one rule every kind follows
    (the list is Rust's, ``pupper_core::results::clear``). A user's own
    files stay; a FIFO or a device where a run file would be is
    `OutputError`, with nothing removed."""
    from pupper_core import _native

    _native.clear_run(os.fspath(out_dir))


def check_kind(out_dir: Path, kind: str) -> None:
    """Refuses to resume ``out_dir`` as a ``kind`` run when another kind's
    run is there: a `PupperError` (kind ``resume_mismatch``), one line
    naming both kinds."""
    from pupper_core import _native

    _native.check_kind(os.fspath(out_dir), kind)


def sayer(progress: bool | Callable[[str], None]) -> Callable[[str], None]:
    """Where a kind's progress lines go: a callable of the caller's, stderr
    (True), or nowhere."""
    if callable(progress):
        return progress
    if progress:
        return say
    return lambda line: None
