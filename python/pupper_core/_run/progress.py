"""A run's progress: tqdm's bar where it is installed and shown; off a
terminal (a script under nohup, CI, a pipe) a plain line on stderr now and
then, as build tools print, so a long run says that it runs and when it
should end."""

from __future__ import annotations

import sys
import time
from typing import Callable

#: Off a terminal: the first line after this many seconds (a shorter run
#: prints nothing more than it did), then one every EVERY_S.
FIRST_S = 10.0
EVERY_S = 30.0


def clock(s: float) -> str:
    """``s`` seconds as 42 s, 3m05s or 1h02m."""
    n = max(0, round(s))
    return f"{n} s" if n < 60 else f"{n // 60}m{n % 60:02d}s" if n < 3600 else f"{n // 3600}h{n // 60 % 60:02d}m"


def line_printer(what: str, unit: str = "step") -> Callable[[int, int], None]:
    """A progress callback writing a plain line to stderr after FIRST_S
    seconds and every EVERY_S after: what runs, how far, about how long."""
    from pupper_core._rundir import say

    started = time.monotonic()
    due = [FIRST_S]

    def update(done: int, total: int) -> None:
        spent = time.monotonic() - started
        if spent < due[0] or total <= 0 or done >= total:
            return
        share = done / total
        left = f"about {clock(spent * (1 - share) / share)} left" if share > 0 else "no estimate yet"
        first = due[0] == FIRST_S
        size = f" of {total} {unit}s" if first else ""
        say(f"progress: {what}{size} {100 * share:.0f} % done in {clock(spent)}, {left}"
            + (f"; a line every {EVERY_S:.0f} s" if first else ""))
        due[0] = spent + EVERY_S

    return update


def in_notebook() -> bool:
    """Whether this process is a Jupyter kernel running a notebook (where a
    bar draws), not merely one that has imported ipykernel on the way."""
    ipython = sys.modules.get("IPython")
    shell = ipython.get_ipython() if ipython is not None and hasattr(ipython, "get_ipython") else None
    return getattr(shell, "kernel", None) is not None


def progress_printer(what: str = "pupper sweep") -> Callable[[int, int], None] | None:
    """A progress callback: tqdm in notebooks/terminals if installed; off a
    terminal, plain lines (`line_printer`); else none."""
    shown = sys.stderr.isatty() or in_notebook()
    if not shown:
        return line_printer(what)
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    bar = None

    def update(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            # tqdm's habit: nothing for a run shorter than a second
            bar = tqdm(total=total, unit="step", unit_scale=True, desc=what, delay=1.0)
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return update
