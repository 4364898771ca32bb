"""Writing files so that a reader never sees half of one."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable


def atomic_write(path: Path, write: Callable[[Path], None]) -> None:
    """``write(tmp)`` to a temporary name beside ``path``, then rename it over
    ``path``; the temporary file is removed on every error."""
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def atomic_write_text(path: Path, text: str) -> None:
    """``text`` as the whole of ``path`` (through `atomic_write`), its
    newlines as they are."""

    def write(tmp: Path) -> None:
        tmp.write_text(text, newline="")

    atomic_write(path, write)
