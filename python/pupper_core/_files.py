"""Writing files so that a reader never sees half of one, and lines on the
standard streams that a full disk cannot turn into a crash."""

from __future__ import annotations

import contextlib
import os
import stat
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Callable


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
    refuse_non_regular(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        write(tmp)
        os.replace(tmp, path)
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
