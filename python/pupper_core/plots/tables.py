"""What the plots read (``pupper_core.plots`` draws it): a run directory's
summary.csv, manifest.json, traces.csv and replicates.csv, a table's
columns as numbers and statuses, its grid axes, the row pupper's ranking
rule picks, and one line saying what a run was."""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence, Union

import numpy as np

from pupper_core.plots.style import SHORT, _fmt
from pupper_core._types import exported_from

if TYPE_CHECKING:  # pragma: no cover
    from pupper_core._native import SweepResult

Table = Mapping[str, Union[Sequence[Any], np.ndarray]]
Traces = Mapping[str, tuple[np.ndarray, np.ndarray]]
#: A table, a result whose ``.table`` is one, or a run directory.
TableLike = Union[Table, "SweepResult", str, os.PathLike]
#: A run directory, or a result written to one (its ``.out``).
RunLike = Union[str, os.PathLike, "SweepResult"]

#: Columns of summary.csv that are text, not numbers.
TEXT_COLUMNS = ("id", "name", "status", "joint", "group", "status.haa", "status.hfe", "status.kfe", "status.other")
#: Axis columns holding names: plotted by their position in the grid.
NAMED_AXES = ("variant",)
#: The first metric column of summary.csv: the grid axes come before it.
FIRST_METRIC = "final_z"


def _as_table(table: TableLike) -> Table:
    """A column mapping from what the user has: a mapping, a result
    (``SweepResult``, whose ``.table`` is one) or a run directory."""
    if isinstance(table, Mapping):
        return table
    if isinstance(table, (str, os.PathLike)):
        return read_run(table)[0]
    return table.table


def run_dir_of(run: RunLike) -> Path:
    """The run directory of what the user has: its path, or a result
    written to one (``out=``)."""
    if isinstance(run, (str, os.PathLike)):
        return Path(run)
    out = getattr(run, "out", None)
    if out is None:
        raise ValueError("this result has no run directory (it ran with out=None): give out= to keep one, "
                         "or pass its table")
    return Path(out)


def _col(table: Table, name: str) -> np.ndarray:
    if name not in table:
        raise KeyError(f"column '{name}' is not in the table (columns: {', '.join(table)})")
    return np.asarray(table[name])


def _num(table: Table, name: str) -> np.ndarray:
    a = _col(table, name)
    if a.dtype.kind in "fiub":
        return a.astype(float)
    out = np.full(a.shape, np.nan)
    for i, v in enumerate(a):
        try:
            out[i] = float(v) if v not in ("", None) else np.nan
        except (TypeError, ValueError):
            pass
    return out


def _nrows(table: Table) -> int:
    return len(next(iter(table.values()))) if table else 0


def _status(table: Table) -> np.ndarray:
    """Each row's status; a replicated cell counts as fallen when any of its
    replicates fell or diverged (it is never "best")."""
    if "status" in table:
        return np.asarray([str(s) for s in table["status"]], dtype=object)
    if "failure_fraction" in table:
        ff = np.asarray(table["failure_fraction"], dtype=float)
        return np.asarray(["ok" if f == 0 else "fell" for f in ff], dtype=object)
    return np.asarray(["ok"] * _nrows(table), dtype=object)


def _distinct(values: np.ndarray) -> list[Any]:
    """Distinct values in sorted order (numbers numerically, NaN dropped)."""
    if values.dtype.kind in "fiub":
        v = values[~np.isnan(values.astype(float))]
        return sorted(set(v.tolist()))
    return sorted(set(values.tolist()), key=str)


def _text(v: Any) -> str:
    """A table value as summary.csv writes it (NaN: empty)."""
    if isinstance(v, str):
        return v
    if isinstance(v, (bool, np.bool_)):
        return str(v)
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    return "" if math.isnan(f) else repr(f)


def _rule_best(table: Table, metric: str, minimize: bool, rows: np.ndarray) -> int | None:
    """The row (among ``rows``) that pupper's ranking rule picks, the one
    `--best-by` and the printed "steadiest" name: eligible cells only (they
    stood, under 5 % saturation), ties within 1 µm to the smaller dip. None
    when no row is eligible, or the table is not one pupper can rank."""
    from pupper_core import _native

    header = list(table)
    idx = [int(i) for i in np.flatnonzero(rows)]
    if not idx:
        return None
    cols = [np.asarray(table[h], dtype=object) for h in header]
    text = [[_text(c[i]) for c in cols] for i in idx]
    try:
        (pick,) = _native.best_rows(header, text, metric, minimize=minimize)
    except Exception:  # noqa: BLE001 (a table of other columns: no rule to apply)
        return None
    return None if pick is None else idx[pick]


def _rankable(table: Table, metric: str) -> bool:
    """Whether pupper's rule applies: a summary table with its status (or
    failure fraction) and the metric."""
    return metric in table and ("status" in table or "failure_fraction" in table)


def _best_index(values: np.ndarray, status: np.ndarray, minimize: bool) -> int | None:
    """Row of the best finite value among cells whose status is ok (else any)."""
    finite = np.isfinite(values)
    ok = finite & (status == "ok")
    pool = ok if ok.any() else finite
    if not pool.any():
        return None
    idx = np.flatnonzero(pool)
    sub = values[idx]
    return int(idx[np.argmin(sub) if minimize else np.argmax(sub)])


def _row_label(table: Table, i: int, axes: Sequence[str] | None = None, label: str = "name") -> str:
    name = str(table[label][i]) if label in table else ""
    if axes is None:
        axes = [a for a in SHORT if a in table]
    vals = ", ".join(f"{SHORT.get(a, a)} {_fmt(table[a][i])}" for a in axes)
    if name and vals:
        return f"{name} ({vals})"
    return name or vals or (str(table["id"][i]) if "id" in table else str(i))


def _push_tuple(push: Any) -> tuple[float, float, float | None] | None:
    if push is None:
        return None
    if isinstance(push, Mapping):
        f = push.get("force")
        # the push's own direction: z for the chapter's, sideways for a hold's shove
        fz = max((float(v) for v in f), key=abs) if f is not None and len(f) > 2 else None
        return float(push["start"]), float(push["duration"]), fz
    seq = list(push)
    fz = None
    if len(seq) > 2:
        f = seq[2]
        fz = float(f) if np.ndim(f) == 0 else float(np.asarray(f, dtype=float)[-1])
    return float(seq[0]), float(seq[1]), fz


@exported_from("pupper_core.plots")
def read_run(run_dir: str | os.PathLike) -> tuple[dict[str, Any], dict[str, Any], dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Reads ``summary.csv``, ``manifest.json`` and (if present) ``traces.csv``.

    Returns ``(table, manifest, traces)``: numeric columns as float arrays
    (empty field = NaN; ``index`` int64, as in ``SweepResult.table``; a
    ``variant`` column as 0, 1, ... in order of appearance),
    ``id``/``name``/``status`` as lists of str; traces
    id -> (t, z) arrays in file order ({} when there is no traces.csv).
    """
    d = Path(run_dir)
    summary = d / "summary.csv"
    if not summary.exists():
        raise FileNotFoundError(f"{d} has no summary.csv: is it a pupper run directory?")
    with summary.open(newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None:
            raise ValueError(f"{summary} is empty")
        rows = [r for r in reader if r]
    table: dict[str, Any] = {}
    for j, name in enumerate(header):
        col = [r[j] if j < len(r) else "" for r in rows]
        if name in TEXT_COLUMNS:
            table[name] = col
        elif name == "index":  # as in SweepResult.table
            table[name] = np.array([int(v) for v in col], dtype=np.int64)
        elif name in NAMED_AXES:  # a body's name: its position in the grid's list
            names = list(dict.fromkeys(col))
            table[name] = np.array([float(names.index(v)) for v in col], dtype=float)
        else:
            table[name] = np.array([float(v) if v.strip() else np.nan for v in col], dtype=float)
    manifest: dict[str, Any] = {}
    if (d / "manifest.json").exists():
        from pupper_core import _native

        manifest = _native.read_manifest(os.fspath(d))
    traces: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    tp = d / "traces.csv"
    if tp.exists():
        acc: dict[str, tuple[list[float], list[float]]] = {}
        with tp.open(newline="") as f:
            reader = csv.reader(f)
            head = next(reader, None) or []
            ci, ti, zi = (head.index(k) for k in ("id", "t", "z"))
            for r in reader:
                if not r:
                    continue
                ts, zs = acc.setdefault(r[ci], ([], []))
                ts.append(float(r[ti]) if r[ti] else np.nan)
                zs.append(float(r[zi]) if r[zi] else np.nan)
        traces = {k: (np.asarray(t, float), np.asarray(z, float)) for k, (t, z) in acc.items()}
    return table, manifest, traces


@exported_from("pupper_core.plots")
def grid_axes(table: TableLike) -> list[str]:
    """The grid-axis columns of a summary table (between ``name`` and the metrics)."""
    table = _as_table(table)
    cols = list(table)
    start = cols.index("name") + 1 if "name" in cols else 0
    out = []
    for c in cols[start:]:
        # a response run's figures per group (rise_time_s.hfe) end them too
        if c in (FIRST_METRIC, "replicates", "replicate", "joint", "status") or (
                "." in c and c.split(".", 1)[0] not in ("kp", "kd")):
            break
        out.append(c)
    return out


@exported_from("pupper_core.plots")
def describe(manifest: Mapping[str, Any], n_cells: int | None = None) -> str:
    """One line saying what a sweep was: mode, model, push, duration."""
    cfg = manifest.get("config", {}) or {}
    parts = []
    mode = cfg.get("mode")
    if mode:
        parts.append(f"{mode} mode")
    m = cfg.get("model") or {}
    if isinstance(m, Mapping):
        if "builtin" in m:
            parts.append(str(m["builtin"]))
        elif "path" in m:
            parts.append(Path(str(m["path"])).name)
    sched = cfg.get("schedule", {}) or {}
    p = _push_tuple(sched.get("push"))
    if sched and p is None:
        parts.append("no push")
    elif p is not None:
        f = (sched.get("push") or {}).get("force")
        ftxt = "[" + ", ".join(_fmt(v) for v in f) + "] N" if f is not None else ""
        parts.append(f"push {ftxt} at {p[0]:g} s for {p[1]:g} s")
    sine = sched.get("sine")
    if isinstance(sine, Mapping):
        parts.append(f"vertical sine {float(sine.get('amplitude', 0)):g} N at {float(sine.get('frequency', 0)):g} Hz")
    if sched.get("duration") is not None:
        parts.append(f"{float(sched['duration']):g} s simulated")
    defaults = cfg.get("defaults") or {}
    if defaults:
        # only what was set and not swept: no gain or torque limit means the
        # model's own, scales of 1 the model's body
        swept = {a.get("axis") for a in ((cfg.get("grid") or {}).get("axes") or []) if isinstance(a, Mapping)}
        shown = {k: v for k, v in defaults.items()
                 if v is not None and k not in swept
                 and not (k in ("leg_scale", "torso_mass_scale") and v == 1)}
        if shown:
            parts.append(", ".join(f"{SHORT.get(k, k)} {_fmt(v)}" for k, v in shown.items()))
    reps = cfg.get("replicates") or {}
    if reps:
        drawn = []
        for r in reps.get("randomize") or []:
            kind, v = next(iter(r["dist"].items()))
            text = {"relative": lambda x: f"±{x * 100:g}%", "normal": lambda x: f"N({x[0]:g},{x[1]:g})"}.get(
                kind, lambda x: f"{x[0]:g}:{x[1]:g}")(v)
            drawn.append(f"{r['quantity']} {text}")
        parts.append(f"{reps.get('count', 1)} replicates" + (f" ({', '.join(drawn)}; seed {reps.get('seed', 0)})"
                                                            if drawn else ""))
    if n_cells is not None:
        parts.append(f"{n_cells} cells")
    return " · ".join(parts)


def _is_product(table: Table, varying: Sequence[str], manifest: Mapping[str, Any]) -> bool:
    grid = ((manifest.get("config") or {}).get("grid") or {}) if manifest else {}
    if grid.get("explicit"):
        return False
    n = _nrows(table)
    combos = {tuple(_num(table, a)[i] for a in varying) for i in range(n)}
    return len(combos) == n == math.prod(len(_distinct(_num(table, a))) for a in varying)


def _read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


@exported_from("pupper_core.plots")
def read_replicates(run_dir: str | os.PathLike) -> dict[str, Any]:
    """``replicates.csv`` as columns (numbers as float arrays, ``id``,
    ``name``, ``status`` and a ``variant`` axis as lists of str)."""
    path = Path(run_dir) / "replicates.csv"
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return {}
    out: dict[str, Any] = {}
    for name in rows[0]:
        col = [r[name] for r in rows]
        if name in TEXT_COLUMNS or name in NAMED_AXES:
            out[name] = col
        else:
            out[name] = np.array([float(v) if v.strip() else np.nan for v in col], dtype=float)
    return out


def read_table(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    if not path.is_file():
        return [], []
    # a log's name that is not UTF-8 stands in a fit's tables as its bytes
    with path.open(newline="", errors="surrogateescape") as f:
        r = csv.DictReader(f)
        return list(r.fieldnames or []), list(r)


def response_pick(header: list[str], rows: list[dict[str, str]], group: str) -> dict[str, str] | None:
    """The response cell that settles soonest on a joint group: pupper's
    ranking rule (the Rust core's `best`) on settling_time_s.GROUP, judged
    by that group's status; the first in grid order on a tie."""
    from pupper_core import _native

    col = f"settling_time_s.{group}"
    if col not in header:
        return None
    (i,) = _native.best_rows(header, [[r.get(h, "") for h in header] for r in rows], col)
    return None if i is None else rows[i]
