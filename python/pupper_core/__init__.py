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

import json
import math
import os
import sys
from pathlib import Path
from typing import Any, Callable, Literal, Mapping, Sequence

import numpy as np

from pupper_core import _native
from pupper_core._native import (
    ConfigError,
    DisplayError,
    GridError,
    InternalError,
    ModelError,
    MujocoError,
    OutputError,
    PupperError,
)

__version__: str = _native.__version__

__all__ = [
    "ConfigError",
    "DisplayError",
    "GridError",
    "InternalError",
    "ModelError",
    "MujocoError",
    "OutputError",
    "PupperError",
    "SweepResult",
    "info",
    "load_run",
    "stand",
    "sweep",
    "METRICS",
]

#: Metric columns of summary.csv, in order (defined once, in the Rust core).
METRICS: tuple[str, ...] = tuple(_native.METRICS)
_TEXT_COLUMNS = ("id", "name", "status")


def info(model: str | Path = "pupper_v3") -> dict[str, Any]:
    """Sizes, mass, joints, actuators (ctrl order), keyframes and sensors of a model."""
    return json.loads(_native.info(str(model)))


#: Defaults of every sweep keyword, as the Rust core's SweepSpec holds them
#: (the CLI's --help shows the same ones; tests/test_spec.py checks).
_D: dict[str, Any] = _native.sweep_defaults()

Mode = Literal["servo", "torque"]


def stand(
    model: str | os.PathLike[str] = _D["model"],
    *,
    seconds: float = _D["seconds"],
    kp: float = _D["kp"],
    kd: float = _D["kd"],
    max_torque: float = _D["max_torque"],
    keyframe: str = _D["keyframe"],
    pose: Sequence[float] | None = _D["pose"],
    mode: Mode = _D["mode"],
) -> dict[str, Any]:
    """Reset to a keyframe (or pose), stand with no push; final z, last-second std, tilt."""
    return json.loads(_native.stand(**_options(locals())))


def _options(arguments: Mapping[str, Any]) -> dict[str, Any]:
    """The spec's keyword arguments among a call's `locals()`, as plain
    values: paths as text, sequences as lists of floats."""
    out: dict[str, Any] = {}
    for name, value in arguments.items():
        if name not in _D or name == "out":
            continue
        if name == "model":
            value = os.fspath(value)
        elif name in ("pose", "sine") and value is not None:
            value = [float(x) for x in value]
        out[name] = value
    return out


class SweepResult:
    """Per-cell metrics of a sweep: the rows of its summary.csv.

    `table` maps each column to a numpy array (text columns to lists);
    `res["kp"]` is a column; `traces` maps a cell id to its (t, z) arrays.
    """

    def __init__(self, payload: Mapping[str, Any]) -> None:
        self.header: list[str] = list(payload["header"])
        self.rows: list[list[str]] = [list(r) for r in payload["rows"]]
        out = payload.get("out")
        self.out: Path | None = Path(out) if out else None
        self.complete: bool = bool(payload.get("complete", True))
        self.config: dict[str, Any] = dict(payload.get("config") or {})
        self.wall_seconds: float = float(payload.get("wall_seconds", math.nan))
        self.table: dict[str, Any] = {}
        for i, name in enumerate(self.header):
            values = [r[i] for r in self.rows]
            if name in _TEXT_COLUMNS:
                self.table[name] = values
            elif name == "index":
                self.table[name] = np.array([int(v) for v in values], dtype=np.int64)
            else:
                self.table[name] = np.array(
                    [float(v) if v != "" else math.nan for v in values], dtype=np.float64
                )
        self.traces: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for cell_id, samples in payload.get("traces") or []:
            arr = np.asarray(samples, dtype=np.float64).reshape(-1, 2)
            self.traces[cell_id] = (arr[:, 0], arr[:, 1])

    @property
    def axes(self) -> list[str]:
        """The grid's axis columns, in grid order."""
        return self.header[3 : self.header.index("final_z")]

    @property
    def ids(self) -> list[str]:
        return list(self.table["id"])

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, column: str) -> Any:
        try:
            return self.table[column]
        except KeyError:
            raise KeyError(f"no column {column!r}; columns are {', '.join(self.header)}") from None

    def row(self, i: int) -> dict[str, Any]:
        """Row i as a dict, numbers as floats."""
        out: dict[str, Any] = {}
        for name in self.header:
            v = self.table[name][i]
            out[name] = v.item() if isinstance(v, np.generic) else v
        return out

    def best(self, metric: str = "last_1s_std_mm", *, minimize: bool = True) -> dict[str, Any]:
        """The healthy (status ok) cell with the lowest (or highest) metric."""
        if metric not in self.table or metric in _TEXT_COLUMNS:
            raise ConfigError(
                f"unknown metric {metric!r}: use one of "
                + ", ".join(m for m in METRICS if m not in _TEXT_COLUMNS)
            )
        values = np.asarray(self.table[metric], dtype=np.float64)
        ok = np.array([s == "ok" for s in self.table["status"]]) & np.isfinite(values)
        if not ok.any():
            raise ConfigError(f"no healthy cell has a finite {metric}")
        candidates = np.where(ok, values, np.inf if minimize else -np.inf)
        i = int(np.argmin(candidates) if minimize else np.argmax(candidates))
        return self.row(i)

    def to_pandas(self) -> Any:
        """The table as a pandas DataFrame (pandas must be installed)."""
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("to_pandas() needs pandas: pip install pandas") from e
        return pd.DataFrame({name: self.table[name] for name in self.header})

    def __repr__(self) -> str:
        cols = [c for c in ("name", *self.axes, "final_z", "last_1s_std_mm", "push_dip_mm", "status")
                if c in self.table]
        lines = ["  ".join(f"{c:>14}" for c in cols)]
        for i in range(len(self)):
            cells = []
            for c in cols:
                v = self.table[c][i]
                cells.append(f"{v:>14.4g}" if isinstance(v, (float, np.floating)) else f"{v!s:>14}")
            lines.append("  ".join(cells))
        where = f", written to {self.out}" if self.out else ""
        return f"SweepResult({len(self)} cells{where})\n" + "\n".join(lines)


def _progress_printer() -> Callable[[int, int], None] | None:
    """A progress callback: tqdm in notebooks/terminals if installed, else none."""
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    bar = None

    def update(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, unit="step", unit_scale=True, desc="pupper sweep")
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return update


def sweep(
    grid: Mapping[str, Sequence[float] | float | str] | Sequence[str] | str | None = None,
    *,
    preset: str | None = None,
    model: str | os.PathLike[str] = _D["model"],
    mode: Mode = _D["mode"],
    seconds: float = _D["seconds"],
    kp: float = _D["kp"],
    kd: float = _D["kd"],
    max_torque: float = _D["max_torque"],
    push: bool = _D["push"],
    push_force: float = _D["push_force"],
    push_at: float = _D["push_at"],
    push_duration: float = _D["push_duration"],
    sine: tuple[float, float] | None = _D["sine"],
    keyframe: str = _D["keyframe"],
    pose: Sequence[float] | None = _D["pose"],
    trace: bool = _D["trace"],
    trace_every: int = _D["trace_every"],
    threads: int = _D["threads"],
    chunk_cells: int = _D["chunk_cells"],
    max_cells: int = _D["max_cells"],
    out: str | os.PathLike[str] | None = _D["out"],
    force: bool = _D["force"],
    resume: bool = _D["resume"],
    progress: bool | Callable[[int, int], None] = True,
) -> SweepResult:
    """Run a grid of settings as one batched MuJoCo simulation.

    grid: {"kp": [10, 30], "kd": 1} (a value may also be text parsed as the
    CLI parses it: "10,30" or "1:120:16:log"), or the CLI's strings
    ["kp=10,30", "kd=1"] (or one such string). preset: "chapter-4.6" or
    "lab" instead of a grid. Every other keyword is the CLI flag of the same
    name, with the same default and checks (`pupper sweep --help`).
    out: also write the run directory (summary.csv, manifest.json, traces.csv)
    as `pupper sweep --out` does; resume=True continues an interrupted one.
    progress: True shows a tqdm bar when tqdm is installed; or a callable
    (done_steps, total_steps). Ctrl-C stops within a second, keeps what is
    finished, and raises KeyboardInterrupt.
    """
    options = _options(locals())
    callback = _progress_printer() if progress is True else (progress or None)
    payload = _native.sweep(grid, preset=preset, out=out, progress=callback, **options)
    return SweepResult(json.loads(payload))


def load_run(run_dir: str | Path) -> SweepResult:
    """A SweepResult from a run directory written by `pupper sweep` or sweep(out=...)."""
    import csv

    run = Path(run_dir)
    with open(run / "summary.csv", newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        rows = list(reader)
    traces: dict[str, list[list[float]]] = {}
    if (run / "traces.csv").exists():
        with open(run / "traces.csv", newline="") as f:
            reader = csv.reader(f)
            next(reader)
            for cell_id, t, z in reader:
                traces.setdefault(cell_id, []).append([float(t), float(z)])
    manifest = json.loads(_native.read_manifest(str(run)))
    return SweepResult(
        {
            "header": header,
            "rows": rows,
            "traces": list(traces.items()),
            "out": str(run),
            "complete": manifest.get("complete", False),
            "config": manifest.get("config"),
        }
    )


def __getattr__(name: str) -> Any:
    # plots and render import matplotlib / a GL context: only when used
    if name in ("plots", "render"):
        import importlib

        module = importlib.import_module(f"pupper_core.{name}")
        setattr(sys.modules[__name__], name, module)
        return module
    raise AttributeError(f"module 'pupper_core' has no attribute {name!r}")
