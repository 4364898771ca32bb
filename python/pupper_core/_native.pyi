"""Type stubs of the native module (Rust, pyo3). Use the wrappers in
`pupper_core` rather than these directly.

Sweep keywords are the fields of the Rust `SweepSpec`; their defaults live
there alone (`sweep_defaults()` returns them), so the stubs state types only."""

from collections.abc import Callable, Iterator, Mapping, Sequence
from os import PathLike
from pathlib import Path
import numpy as np
from numpy.typing import NDArray
from typing import TYPE_CHECKING, Any, Literal, overload

from typing_extensions import Unpack

if TYPE_CHECKING:
    import pandas  # type: ignore[import-untyped, import-not-found, unused-ignore]

from pupper_core._types import (
    JointInfo,
    ActuatorInfo,
    KeyframeInfo,
    SensorInfo,
    ModelInfo,
    StandReport,
    SimOptions,
    SweepOptions,
    RecordedSetup,
    Recording,
)

__version__: str
METRICS: list[str]
#: The named bodies (the lab's by default), in the Rust core's order.
VARIANTS: list[str]
#: The metric a standing run ranks by unless told.
DEFAULT_METRIC: str
#: The experiment kinds besides the stand, as the Rust core's registry names them.
KINDS: list[str]
#: Cells at the torque limit in this share of actuator-steps or more are never best.
MAX_SATURATION: float
#: Seconds after a push's end within which its dip (the lowest base height) is sought.
DIP_AFTER: float

ErrorCode = Literal[
    "grid", "config", "model", "model_not_found", "mujoco", "output", "run_not_found",
    "run_exists", "resume_mismatch", "run_busy", "not_found", "permission", "disk_full", "io",
    "interrupted", "display", "cluster", "internal",
]

class PupperError(Exception):
    """Base class of pupper's errors. The message is one line naming the
    problem and the fix; `kind` names the error for programs."""

    kind: ErrorCode
    """A stable name of the error, finer than the class (e.g. `run_exists`)."""

class GridError(PupperError):
    """A bad grid: unknown axis, bad values, too many cells."""

class ConfigError(PupperError):
    """A bad schedule, pose, gain or option."""

class ModelError(PupperError):
    """A model that is missing, unreadable, invalid or unsuitable."""

class MujocoError(PupperError):
    """The mujoco package is missing or the wrong version."""

class OutputError(PupperError):
    """A run directory that cannot be used: exists, differs, unreadable."""

class DisplayError(PupperError):
    """Rendering or a viewer is not possible here."""

class ClusterError(PupperError):
    """Ray is missing, the cluster cannot be reached, or a node cannot run pupper."""

class InternalError(PupperError):
    """A bug in pupper or MuJoCo."""

class ModelNotFoundError(ModelError, FileNotFoundError):
    """A model file that does not exist."""

class RunNotFoundError(OutputError, FileNotFoundError):
    """A run directory, or a file in it, that does not exist."""

class RunExistsError(OutputError, FileExistsError):
    """The run directory exists; pass force=True or resume=True."""

class OutputPermissionError(OutputError, PermissionError):
    """The run directory cannot be written or read."""

class SweepResult:
    """Per-cell metrics of a sweep: the rows of its summary.csv, as numpy
    columns (float64, NaN where the file is empty; `index` int64; `id`,
    `name`, `status` lists of str)."""

    traces: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]]
    """Cell id -> (t, z) arrays, when traces were kept."""
    out: Path | None
    """The run directory, or None when nothing was written."""
    complete: bool
    """False when the sweep was interrupted before every cell ran."""
    wall_seconds: float
    """Seconds the sweep took (for a run read back from disk, as its manifest says)."""
    config: dict[str, Any]
    """The inputs that decide the numbers, as stored in manifest.json."""
    cell_steps: list[int | None]
    """Cell-steps each row's cell took (fewer for a robot stopped by
    stop_fallen). A row resumed from disk has None; a run read back
    (load_run) has what its manifest knows: the schedule's steps at the
    cell's timestep times its simulations, None for a cell that diverged,
    a replicate that failed, a fall under stop_fallen, or a manifest that
    did not record the model's timestep."""
    tables: dict[str, SweepResult]
    """Every table beside summary.csv by name: "replicates"; a response
    run's "response" (a row per cell and joint) and "bode"."""
    replicates: SweepResult | None
    """replicates.csv (a row per cell and replicate: drawn values, metrics);
    None without replicates."""
    @property
    def table(self) -> dict[str, NDArray[Any] | list[str]]:
        """Every column by name."""
    @property
    def header(self) -> list[str]:
        """summary.csv's columns, in order."""
    @property
    def rows(self) -> list[list[str]]:
        """summary.csv's rows as text, in cell order."""
    @property
    def axes(self) -> list[str]:
        """The grid's axis columns, in grid order."""
    @property
    def ids(self) -> list[str]:
        """Cell ids, in cell order."""
    def __len__(self) -> int: ...
    def __getitem__(self, column: str) -> NDArray[Any] | list[str]:
        """A column; KeyError names the columns there are."""
    def row(self, i: int) -> dict[str, Any]:
        """Row `i` as a dict: index an int, text as str, numbers as float."""
    @overload
    def best(self, metric: str | None = None, *, by: None = None, minimize: bool = True,
             max_saturation: float = ...) -> dict[str, Any]: ...
    @overload
    def best(self, metric: str | None = None, *, by: Sequence[str], minimize: bool = True,
             max_saturation: float = ...) -> list[dict[str, Any]]:
        """The best cell, by pupper's rule: among cells whose status is ok,
        whose metric is a number and whose saturation_frac is under
        `max_saturation`, the lowest metric (highest with `minimize=False`).
        Ties: on a millimetre metric (`*_mm`) cells within 0.001 mm of the
        best are tied, on others only equal values; the smallest push dip
        among the tied wins, then the first in grid order. A cell past the
        stability bound (status past_bound) is never eligible. `metric` is
        any numeric column the table carries (a response's
        "settling_time_s.kfe" is judged by that group's status). With `by`,
        the best of each group of those axes' values (with `cells` and
        `eligible` counts). metric defaults to the kind's own:
        "last_1s_std_mm" (a hold: "compliance_mm_per_n"), or for a
        replicated sweep "p95:last_1s_std_mm" (statistics are "mean:M" and
        "p95:M"; eligible: no replicate fell or diverged,
        p95:saturation_frac under the bound)."""
    def __contains__(self, column: str) -> bool:
        """Whether the table has that column."""
    def __iter__(self) -> Iterator[dict[str, Any]]:
        """Each row as a dict of typed values (as `row(i)`)."""
    def _repr_html_(self) -> str:
        """The table as HTML, for notebooks."""
    def to_pandas(self) -> "pandas.DataFrame":
        """The table as a pandas DataFrame (pandas must be installed)."""

def info(model: str = ..., variant: str = ...) -> ModelInfo:
    """What `pupper info --json` prints, as a dict."""

def sweep_defaults() -> dict[str, Any]:
    """The default of every sweep keyword, from the Rust SweepSpec."""

def kind_defaults() -> dict[str, dict[str, Any]]:
    """Each experiment kind's own keywords and defaults, by its key in KINDS."""

def stand(**options: Unpack[SimOptions]) -> StandReport:
    """What `pupper stand --json` prints, as a dict."""

def stance(**options: Unpack[SimOptions]) -> float:
    """The stance height (m) a run of these options starts from: the base
    height with the lowest foot on the floor in the start pose."""

def pose(model: str = ..., variant: str = ..., depth: float | None = ...) -> dict[str, Any]:
    """What `pupper pose --json` prints, as a dict."""

def loop_margins(inertia: float, kp: float, kd: float, *, motor: str | None = ...,
                 sensing_delay: float | None = ..., timestep: float, damping: float = ...,
                 lag: float = ..., latency: float = ..., fitted: bool = ...) -> tuple[float, float]: ...
def fit_run(dir: str | PathLike[str]) -> str:
    """The calibrated model of a `pupper fit` run, the run checked against its manifest first."""
def loop_response(inertia: float, kp: float, kd: float, hz: Sequence[float], *, motor: str | None = ...,
                  sensing_delay: float | None = ..., timestep: float, damping: float = ..., lag: float = ...,
                  latency: float = ..., command_delay: float = ..., fitted: bool = ...) -> list[tuple[float, float]]:
    """The closed loop of `loop_margins`' joint from its target: (gain dB, phase deg) per frequency."""
def gains(model: str = ..., *, kp: float | None = ..., kd: float | None = ..., bandwidth: float | None = ...,
          damping: float = ..., pose: list[float] | None = ..., integrator: str | None = ...,
          motor: str | None = ..., sensing_delay: float | None = ...) -> dict[str, Any]:
    """What `pupper gains --json` prints, as a dict."""

def sweep(
    grid: Mapping[str, Sequence[float] | float | str] | Sequence[str] | Sequence[Mapping[str, float | str]] | str | None = ...,
    *,
    preset: str | None = ...,
    out: str | PathLike[str] | None = ...,
    progress: Callable[[int, int], object] | None = ...,
    **options: Unpack[SweepOptions],
) -> SweepResult:
    """Runs a sweep; its table as a `SweepResult`."""

def check_axes(names: Sequence[str]) -> None:
    """Raises GridError for a name that is not a grid axis."""

def response(
    grid: Any = ...,
    *,
    out: str | PathLike[str] | None = ...,
    progress: Callable[[int, int], None] | None = ...,
    signal: str = ...,
    amplitude: float = ...,
    frequency: float | None = ...,
    chirp: Sequence[float] | None = ...,
    hold: float = ...,
    joints: Sequence[str] = ...,
    standing: bool = ...,
    **options: Any,
) -> SweepResult: ...

def hold(
    grid: Any = ...,
    *,
    out: str | PathLike[str] | None = ...,
    progress: Callable[[int, int], None] | None = ...,
    load: float = ...,
    ramp: float = ...,
    shove: float = ...,
    shove_at: float | None = ...,
    shove_duration: float = ...,
    **options: Any,
) -> SweepResult: ...

def walk(
    grid: Any = ...,
    *,
    out: str | PathLike[str] | None = ...,
    progress: Callable[[int, int], None] | None = ...,
    gait: str = ...,
    frequency: float = ...,
    speed: float = ...,
    sideways: float = ...,
    yaw_rate: float = ...,
    duty: float | None = ...,
    step_height: float | None = ...,
    height: float | None = ...,
    **options: Any,
) -> SweepResult: ...

def lab(
    variants: Sequence[str] | None = ...,
    grid: Sequence[str] | None = ...,
    *,
    seconds: float = ...,
    sine: Sequence[float] = ...,
    model: str = ...,
    out: str | PathLike[str] | None = ...,
    force: bool = ...,
    resume: bool = ...,
    threads: int = ...,
    max_saturation: float = ...,
    rank: str | None = ...,
    replicates: int = ...,
    seed: int = ...,
    randomize: Sequence[str] = ...,
    common_draws: bool = ...,
    backend: Literal["cpu", "warp"] = ...,
    device: str | None = ...,
    ray: str | None = ...,
    depth: float | None = ...,
    motor: str | None = ...,
    progress: Callable[[int, int], object] | None = ...,
) -> SweepResult:
    """The chapter's lab; best.csv in `out`. Plots and rendering are the wrapper's."""

def best_rows(header: Sequence[str], rows: Sequence[Sequence[str]], metric: str, *,
              by: Sequence[str] = ..., minimize: bool = ..., max_saturation: float = ...) -> list[int | None]:
    """pupper's ranking rule on a table of text rows: the best row of each group."""

def _result_from_state(state: dict[str, Any]) -> SweepResult:
    """A result rebuilt from its pickled state."""

def _shutdown() -> None:
    """At interpreter exit: stops running sweeps and waits for them (atexit)."""

def _run_task(job: bytes, task: bytes, threads: int) -> bytes:
    """A Ray task's cells run on this node (see `pupper_core._ray`)."""

def merge(dirs: Sequence[str | PathLike[str]], out: str | PathLike[str], *, force: bool = ...) -> SweepResult:
    """Shards of one sweep (each run with shard="I/N") put together into `out`."""

def load_run(run_dir: str) -> SweepResult:
    """A run directory read back, its rows checked against its manifest."""

def read_manifest(dir: str) -> dict[str, Any]:
    """The manifest of a run directory of any kind, as a dict (the one
    reader): RunNotFoundError without one, OutputError for one that is not
    a JSON object."""

class RunLock:
    """A held run-directory lock (`lock_run`)."""

    def release(self) -> None:
        """Lets the lock go; the lock file stays, naming nobody."""

def lock_run(dir: str) -> RunLock:
    """Takes `dir`'s lock, the one every pupper command takes: PupperError
    of kind run_busy while another pupper writes there; OSError if it
    cannot be written."""

def publish(tmp: str, path: str) -> None:
    """The finished temporary file `tmp` flushed and renamed into place as
    `path`; OSError naming `path` if that fails."""

def write_manifest(dir: str, kind: str, body: dict[str, Any]) -> None:
    """`dir/manifest.json`: the stamp every manifest starts with (kind,
    pupper_version, mujoco_version, python), then `body`'s fields."""

def clear_run(dir: str) -> None:
    """Every file an older run of any kind left in `dir` removed (--force)."""

def check_kind(dir: str, kind: str) -> None:
    """Refuses to resume `dir` as a `kind` run when another kind's run is there."""

def builtin_model(name: str) -> Any:
    """A built-in model compiled as the CLI compiles it (a `mujoco.MjModel`)."""

def cli_main(argv: Sequence[str]) -> int:
    """The `pupper` command inside this interpreter; returns the exit status."""

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

def step_traces(run_dir: str | PathLike[str], cells: Sequence[int]) -> list[dict[str, Any]]:
    """A response run's excited joints at every physics step, its cells run
    again as the manifest says: a dict per (cell, joint) of replicate 0 with
    `index`, `id`, `joint`, `t` and `angle` (arrays)."""
