"""Type stubs of the native module (Rust, pyo3). Use the wrappers in
`pupper_core` rather than these directly.

Sweep keywords are the fields of the Rust `SweepSpec`; their defaults live
there alone (`sweep_defaults()` returns them), so the stubs state types only."""

from collections.abc import Callable, Mapping, Sequence
from os import PathLike
import numpy as np
from numpy.typing import NDArray
from typing import Any, Literal, TypedDict, Unpack

__version__: str
METRICS: list[str]

class PupperError(Exception): ...
class GridError(PupperError): ...
class ConfigError(PupperError): ...
class ModelError(PupperError): ...
class MujocoError(PupperError): ...
class OutputError(PupperError): ...
class DisplayError(PupperError): ...
class InternalError(PupperError): ...

def info(model: str = ...) -> str:
    """Model info as JSON (what `pupper info --json` prints)."""

def sweep_defaults() -> dict[str, Any]:
    """The default of every sweep keyword, from the Rust SweepSpec."""

class SimOptions(TypedDict, total=False):
    """Keywords of every simulating call (`stand`, `sweep`)."""

    model: str
    mode: Literal["servo", "torque"]
    seconds: float
    kp: float
    kd: float
    max_torque: float
    keyframe: str
    pose: Sequence[float] | None

class SweepOptions(SimOptions, total=False):
    """The other keywords of `sweep`."""

    push: bool
    push_force: float
    push_at: float
    push_duration: float
    sine: Sequence[float] | None
    trace: bool
    trace_every: int
    threads: int
    chunk_cells: int
    max_cells: int
    force: bool
    resume: bool

def stand(**options: Unpack[SimOptions]) -> str:
    """Stand report as JSON (what `pupper stand --json` prints)."""

def sweep(
    grid: Mapping[str, Sequence[float] | float | str] | Sequence[str] | str | None = ...,
    *,
    preset: str | None = ...,
    out: str | PathLike[str] | None = ...,
    progress: Callable[[int, int], object] | None = ...,
    **options: Unpack[SweepOptions],
) -> str:
    """Runs a sweep; the summary table (and traces) as JSON."""

def read_manifest(dir: str) -> str:
    """The manifest of a run directory, as JSON."""

def builtin_xml(name: str) -> str:
    """The MJCF text of a built-in model."""

def cli_main(argv: Sequence[str]) -> int:
    """The `pupper` command inside this interpreter; returns the exit status."""

class RecordedSetup(TypedDict):
    """A recorded cell's physical setting, as the runner resolved it."""

    kp: float
    kd: float
    max_torque: float
    push_force: list[float]
    """World-frame push force (N) while the push acts."""
    friction: float | None
    timestep: float | None
    leg_scale: float
    torso_mass_scale: float

class Recording(TypedDict):
    """One cell simulated by the sweep's runner, with its states at `fps`."""

    index: int
    id: str
    name: str
    values: dict[str, float]
    """The cell's grid values by axis name."""
    setup: RecordedSetup
    status: Literal["ok", "fell", "diverged"]
    event_time: float
    model: Any
    """The compiled `mujoco.MjModel` the cell ran on (its body variant)."""
    fps: float
    times: NDArray[np.float64]
    """Time of each frame (s); frame 0 is the initial state."""
    qpos: NDArray[np.float64]
    """(frames, nq) joint positions."""
    pushing: NDArray[np.bool_]
    """Whether the push acted on the step that led to each frame."""

def record(
    grid: Mapping[str, Sequence[float] | float | str] | Sequence[str] | str | None = ...,
    *,
    preset: str | None = ...,
    fps: float = ...,
    **options: Unpack[SweepOptions],
) -> list[Recording]:
    """Simulates every cell (nothing written), recording qpos at `fps`."""

def record_run(run_dir: str, cells: Sequence[int], fps: float = ...) -> list[Recording]:
    """`record` for cells of a run directory, by their `index` column."""
