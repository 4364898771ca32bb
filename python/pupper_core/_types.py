"""The shapes of what pupper_core returns and takes, as TypedDicts (the
native module's stubs import them from here, so each is written once), and
where a public function or error is used from."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Callable, Literal, TypedDict, TypeVar

if TYPE_CHECKING:
    from typing_extensions import NotRequired
    import numpy as np
    from numpy.typing import NDArray


class JointInfo(TypedDict):
    name: str
    kind: Literal["free", "ball", "slide", "hinge"]
    qpos_adr: int
    dof_adr: int
    range: list[float] | None
    """[low, high] (rad or m) when the joint is limited."""
    body: int
    """Index into `bodies` of the body the joint moves."""


class ActuatorInfo(TypedDict):
    name: str
    joint: int | None
    """Index into `joints` of the joint it drives."""
    gainprm: list[float]
    biasprm: list[float]
    forcerange: list[float] | None


class KeyframeInfo(TypedDict):
    name: str
    qpos: list[float]
    ctrl: list[float]


class SensorInfo(TypedDict):
    name: str
    kind: str
    dim: int


class ModelInfo(TypedDict):
    """What `pupper info --json` prints."""

    name: str
    source: str
    sha256: str
    """SHA-256 of the model's XML text."""
    nq: int
    nv: int
    nu: int
    nbody: int
    timestep: float
    total_mass: float
    """kg."""
    bodies: list[str]
    joints: list[JointInfo]
    actuators: list[ActuatorInfo]
    """In ctrl order."""
    keyframes: list[KeyframeInfo]
    sensors: list[SensorInfo]
    qpos0: list[float]
    legs: list[LegInfo]


class StandReport(TypedDict):
    """What `pupper stand --json` prints."""

    model: str
    mode: Literal["servo", "torque"]
    kp: float
    kd: float
    """The gains the cell ran at (the first actuator's when they differ)."""
    gains_from: Literal["given", "model"]
    gains: str
    seconds: float
    final_z: float
    """Base height at the end (m)."""
    last_1s_std_mm: float
    max_tilt_deg: float
    status: Literal["ok", "saturated", "past_bound", "fell", "diverged"]
    notes: NotRequired[list[str]]
    """What you should know, e.g. that the start fell back to the default pose."""


class LegInfo(TypedDict):
    """One leg at the default pose, world frame (m)."""

    name: str
    joints: list[int]
    """Indices into `joints`: abduction, hip flexion, knee."""
    hip: list[float]
    knee: list[float]
    foot: list[float]
    hip_axis: list[float]
    knee_axis: list[float]
    hip_to_foot: float
    foot_radius: float
    abduction: list[float]
    abduction_axis: list[float]


class SimOptions(TypedDict, total=False):
    """Keywords of every simulating call (`stand`, `sweep`)."""

    model: str
    variant: Literal["original", "long-leg", "heavy"]
    mode: Literal["servo", "torque"]
    seconds: float
    kp: float | None
    """Kp of every actuator; None: each actuator's own, from the model."""
    kd: float | None
    max_torque: float | None
    keyframe: str
    pose: Sequence[float] | Literal["auto"] | None
    """Start and target joint angles (rad, actuator order), or "auto": a stand
    pose searched on each cell's own body."""
    depth: float | None
    """With pose="auto": the feet's depth below the hips (m); None: the
    chapter's 0.14 m scaled to the model's legs."""
    motor: str | None
    """Torque mode's servo firmware and motor, as `--motor` takes it:
    "rate=1000,filter=100,counts=16384,delay=0.004,noload=30,lag=0.007" (any
    subset; lag: the torque's first-order lag behind the PD, s);
    None: the ideal motor (the PD every physics step on the exact state)."""
    integrator: Literal["euler", "implicitfast", "implicit", "rk4"] | None
    """MuJoCo's integrator for every cell; None: the model's own. Cells past
    the stability bound of the PD as it integrates are marked past_bound."""


class RecordedSetup(TypedDict):
    """A recorded cell's physical setting, as the runner resolved it."""

    kp: list[float]
    """Each actuator's Kp, in ctrl order."""
    kd: list[float]
    max_torque: float | None
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
    values: dict[str, float | str]
    """The cell's grid values by axis name."""
    setup: RecordedSetup
    status: Literal["ok", "saturated", "past_bound", "fell", "diverged"]
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


class SweepOptions(SimOptions, total=False):
    """The other keywords of `sweep`."""

    push: bool
    push_force: float | None
    """The push along world z (N); None or absent: the chapter's −25 N
    scaled to the model's mass (−25 N × mass / 3.17 kg, to 0.1 N: −25 N on
    Pupper); the manifest records the force used."""
    push_at: float
    push_duration: float
    sine: Sequence[float] | None
    trace: bool
    trace_every: int
    stop_fallen: bool
    """Stop stepping a robot once it has fallen or diverged; its row keeps
    its status and the metrics up to the stop (`pupper sweep --stop-fallen`)."""
    replicates: int
    """Runs of every cell, each on a robot drawn by `randomize`."""
    seed: int
    """Seed of the draws (each a function of seed, cell id, replicate, quantity)."""
    randomize: Sequence[str]
    """`QUANTITY=DISTRIBUTION` specs as `pupper sweep --randomize` takes them:
    "torso_mass=±10%", "friction=0.5:1.2", "q_noise=N(0,0.002)", "delay=0:3"."""
    common_draws: bool
    """Every cell's replicate r is the same drawn robot (common random
    numbers), so cells differ only by their settings."""
    backend: Literal["cpu", "warp"]
    """What steps the physics: "cpu" (MuJoCo, float64) or "warp" (MuJoCo
    Warp, float32; needs `pip install 'pupper_core[gpu]'`)."""
    device: str | None
    """The Warp device of backend="warp": "cuda:0" (default) or "cpu"."""
    shard: str | None
    """Run only shard "I/N" of the grid's cells (1-based, interleaved); put
    the shards together with `merge`."""
    ray: str | None
    """Run the cells as tasks on a Ray cluster: "auto" (RAY_ADDRESS),
    "ray://HOST:PORT" or "HOST:PORT"; needs `pip install 'pupper_core[ray]'`.
    Same table as a local run; `threads` is then the CPUs per task."""
    threads: int
    chunk_cells: int | None
    """Most cells per batch; None: 256 on the cpu backend, as many as the
    device holds on warp."""
    max_cells: int
    force: bool
    resume: bool


_T = TypeVar("_T")


def exported_from(module: str) -> Callable[[_T], _T]:
    """Marks a function or an exception class as ``module``'s own (it must
    re-export it under the same name): help(), repr and pickle name the
    module a user imports it from (``pupper_core``, ``pupper_core.plots``,
    ...), not the private module that holds its code."""

    def mark(obj: _T) -> _T:
        obj.__module__ = module
        return obj

    return mark
