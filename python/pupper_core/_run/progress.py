"""A run's progress bar: tqdm where it is installed and shown."""

from __future__ import annotations

import sys
from typing import Callable


def progress_printer() -> Callable[[int, int], None] | None:
    """A progress callback: tqdm in notebooks/terminals if installed, else none."""
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    bar = None

    def update(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            # tqdm's habit: nothing for a run shorter than a second, and
            # nothing in a script whose stderr is not a terminal (a log)
            shown = sys.stderr.isatty() or "ipykernel" in sys.modules
            bar = tqdm(total=total, unit="step", unit_scale=True, desc="pupper sweep",
                       delay=1.0, disable=not shown)
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return update
