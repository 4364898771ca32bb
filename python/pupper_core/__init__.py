"""Physics experiments on the Pupper v3 quadruped in MuJoCo.

    import pupper_core as pc
    pc.info("pupper_v3")["nq"]                       # 19
    res = pc.sweep({"kp": [10, 30, 60, 120], "kd": [0.5, 1, 2, 5]})
    res.best("last_1s_std_mm")                       # the steadiest cell
    res.to_pandas()                                  # with pandas installed

The numbers come from the same Rust functions as the `pupper` CLI, so the
same inputs give the same summary.csv.
"""

from __future__ import annotations

# The facade: what a user imports, re-exported from where it is written (the
# Rust core's runs in _run, the spec's keywords in _spec, the native module's
# types and errors in _native, the typed dicts in _types); the kinds driven
# in Python (tune, recommend, excite, fit), their errors, plots and render
# are imported when first used (they import numpy, Optuna, matplotlib).
from typing import TYPE_CHECKING, Any

from pupper_core import _native
from pupper_core._run import gains, hold, info, lab, load_run, merge, pose, report, response, stand, sweep, walk
from pupper_core._native import (
    ClusterError,
    ConfigError,
    DisplayError,
    GridError,
    InternalError,
    ModelError,
    ModelNotFoundError,
    MujocoError,
    OutputError,
    OutputPermissionError,
    PupperError,
    RunExistsError,
    RunNotFoundError,
    SweepResult,
)
from pupper_core._spec import METRICS
from pupper_core._spec import Mode as Mode
from pupper_core._spec import Variant as Variant
from pupper_core._types import ModelInfo, Recording, StandReport
from pupper_core._types import SimOptions as SimOptions
from pupper_core._types import SweepOptions as SweepOptions

__version__: str = _native.__version__

__all__ = [
    "ClusterError",
    "ConfigError",
    "DisplayError",
    "GridError",
    "InternalError",
    "ModelError",
    "ModelInfo",
    "ModelNotFoundError",
    "MujocoError",
    "OutputError",
    "OutputPermissionError",
    "PupperError",
    "RunExistsError",
    "TuneError",
    "FitError",
    "RecommendError",
    "RunNotFoundError",
    "Recording",
    "StandReport",
    "SweepResult",
    "info",
    "gains",
    "pose",
    "lab",
    "response",
    "hold",
    "walk",
    "tune",
    "recommend",
    "excite",
    "fit",
    "load_run",
    "merge",
    "report",
    "stand",
    "sweep",
    "METRICS",
]


def __dir__() -> list[str]:
    """The public API (and the lazily imported `plots` and `render`), not
    the modules this file imports for itself."""
    return sorted([*__all__, "plots", "render", "__version__"])


#: What the package imports when first used: name -> (module, attribute).
_LAZY = {
    "tune": ("pupper_core._tune", "tune"),
    "TuneError": ("pupper_core._tune", "TuneError"),
    "recommend": ("pupper_core._recommend", "recommend"),
    "RecommendError": ("pupper_core._recommend", "RecommendError"),
    "excite": ("pupper_core._fit", "excite"),
    "fit": ("pupper_core._fit", "fit"),
    "FitError": ("pupper_core._fit", "FitError"),
    # plots and render import matplotlib / a GL context
    "plots": ("pupper_core.plots", ""),
    "render": ("pupper_core.render", ""),
}

if TYPE_CHECKING:
    from pupper_core import plots, render
    from pupper_core._fit import FitError, excite, fit
    from pupper_core._recommend import RecommendError, recommend
    from pupper_core._tune import TuneError, tune


def __getattr__(name: str) -> Any:
    """The kinds driven in Python, their errors, plots and render: imported
    when first used, bound on the package so this runs once per name."""
    import importlib

    if name not in _LAZY:
        raise AttributeError(f"module 'pupper_core' has no attribute {name!r}")
    module, attribute = _LAZY[name]
    value = importlib.import_module(module)
    value = getattr(value, attribute) if attribute else value
    globals()[name] = value
    return value
