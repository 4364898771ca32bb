"""Type stubs of the native module (Rust, pyo3). Use the wrappers in
`pupper_core` rather than these directly."""

from collections.abc import Callable, Sequence

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

def info(model: str = "pupper_v3") -> str: ...
def stand(
    model: str = "pupper_v3",
    seconds: float = 10.0,
    kp: float = 5.0,
    kd: float = 0.1,
    keyframe: str = "home",
    pose: Sequence[float] | None = None,
    mode: str = "servo",
) -> str: ...
def sweep(
    axes: Sequence[tuple[str, Sequence[float]]] | None = None,
    specs: Sequence[str] | None = None,
    preset: str | None = None,
    model: str = "pupper_v3",
    mode: str = "servo",
    seconds: float = 10.0,
    kp: float = 5.0,
    kd: float = 0.1,
    max_torque: float = 3.0,
    push: bool = True,
    push_force: float = -25.0,
    push_at: float = 2.0,
    push_duration: float = 0.25,
    sine: tuple[float, float] | None = None,
    keyframe: str = "home",
    pose: Sequence[float] | None = None,
    trace_every: int = 0,
    threads: int = 0,
    chunk_cells: int = 256,
    max_cells: int = 100000,
    out: str | None = None,
    force: bool = False,
    resume: bool = False,
    progress: Callable[[int, int], object] | None = None,
) -> str: ...
def read_manifest(dir: str) -> str: ...
def parse_grid(specs: Sequence[str]) -> list[tuple[str, list[float]]]: ...
def builtin_xml(name: str) -> str: ...
