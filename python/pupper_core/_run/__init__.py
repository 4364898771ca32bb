"""The runs of the Rust core, below the package's facade
(``pupper_core/__init__.py`` re-exports them): a module per kind of run
in ``kinds/`` (sweep, response, hold, walk, lab), the model's facts without
a run (``model``: info, stand, gains, pose) and what every run directory
has (``runs``: its report, merge, load_run). A new kind is its own module
in ``kinds/`` and one line below."""

from __future__ import annotations

import atexit
import sys
import threading

from pupper_core import _native
from pupper_core._run.kinds.hold import hold
from pupper_core._run.kinds.lab import lab
from pupper_core._run.kinds.response import response
from pupper_core._run.kinds.sweep import sweep
from pupper_core._run.kinds.walk import walk
from pupper_core._run.model import gains, info, pose, stand
from pupper_core._run.runs import load_run, merge, report

__all__ = ["gains", "hold", "info", "lab", "load_run", "merge", "pose", "report", "response", "stand", "sweep",
           "walk"]

# A sweep still running in a thread when the interpreter exits stops at
# its next check (finished cells kept) before Python tears threads down.
atexit.register(_native._shutdown)


def _stop_after_ctrl_c() -> None:
    """Python waits for non-daemon threads before exiting: when the main
    thread ended on Ctrl-C, their sweeps stop too instead of running on."""
    if isinstance(getattr(sys, "last_value", None), KeyboardInterrupt):
        _native._shutdown()


if hasattr(threading, "_register_atexit"):  # CPython >= 3.9: before the joins
    threading._register_atexit(_stop_after_ctrl_c)
