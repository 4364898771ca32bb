"""SIGINT and SIGTERM as Ctrl-C for Python work the CLI runs (a fit, an
excitation): the CLI's own handler only sets a flag its Rust loops read."""

from __future__ import annotations

import contextlib
import ctypes
import signal
import threading
from collections.abc import Iterator
from typing import Any


@contextlib.contextmanager
def _stop_on_signals(what: str, left: str = "nothing written") -> Iterator[None]:
    """SIGINT and SIGTERM stop ``what`` with KeyboardInterrupt, as Ctrl-C
    stops Python, and the handlers from before are put back after. (The CLI's
    own handler only sets a flag its Rust loops read, which a fit never
    does; off the main thread Python cannot take a signal, and this does
    nothing.)"""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(f"{what} stopped by {signal.Signals(signum).name}: {left}")

    saved = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        # the kernel's action too: a handler installed outside Python (the
        # CLI's) shows in Python as SIG_DFL or None, and only this puts it back
        raw = _raw_action(sig)
        saved.append((sig, signal.signal(sig, stop), raw))
    try:
        yield
    finally:
        for sig, previous, raw in reversed(saved):
            if callable(previous) or raw is None:
                signal.signal(sig, previous if previous is not None else signal.SIG_DFL)
            else:
                _libc().sigaction(int(sig), raw, None)


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
