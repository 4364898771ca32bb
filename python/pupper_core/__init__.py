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
# functions in _api, the spec's keywords in _spec, the native module's types
# and errors in _native, the typed dicts in _types).
from typing import Any

from pupper_core import _native
from pupper_core._api import (
    excite,
    fit,
    gains,
    hold,
    info,
    lab,
    load_run,
    merge,
    pose,
    recommend,
    report,
    response,
    stand,
    sweep,
    tune,
)
from pupper_core._api import lazy_attribute as _lazy_attribute
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


def __getattr__(name: str) -> Any:
    # the search's and the fit's errors, plots and render: imported when used
    return _lazy_attribute(name)
