"""The joint-log format: what a robot's servos did, one CSV per recording.

A log is plain CSV with a few ``# key: value`` lines above its header::

    # pupper joint log 1
    # mode: servo
    # base: suspended
    # kp: 5
    # kd: 0.1
    time,leg_front_r_1.target,leg_front_r_1.q,leg_front_r_1.qd,leg_front_r_1.tau,...
    0,0,0.0003,0,0.01,...

Units: ``time`` in s (strictly increasing, from any start, evenly spaced
or as recorded), ``.target`` (the commanded angle) and ``.q`` (the
measured angle) in rad, ``.qd`` in rad/s, ``.tau`` in N·m; a column map
(``# columns:`` or the caller's, ``pupper_core._log_columns``) reads the
robot's own column names and units instead. Each logged actuator needs
``.target`` and ``.q``; ``.qd`` and ``.tau`` are optional (most servos
report no torque). A log may cover any subset of the actuators (``held``:
the angles the others hold). ``kp``/``kd`` are the gains in use (N·m/rad,
N·m·s/rad): one number for every actuator, or one per logged actuator in
column order; the caller may give them for a log that does not say them.
``mode`` is who ran the PD (``servo``: the motor's firmware, ``torque``:
the host); ``base`` is ``suspended`` (the robot hung, its feet off the
ground) or ``standing``.
"""

from __future__ import annotations

import csv
import hashlib
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pupper_core._log_columns import ColumnMap, parse_map, resolve
from pupper_core._native import ConfigError

__all__ = ["JointLog", "LogError", "read_log", "write_log", "FIELDS", "KP_MAX", "KD_MAX"]

MAGIC = "# pupper joint log 1"
#: A column's suffix, what it holds, its unit.
FIELDS = {"target": ("commanded angle", "rad"), "q": ("measured angle", "rad"),
          "qd": ("measured velocity", "rad/s"), "tau": ("measured torque", "N·m"),
          "kp": ("the gain in use, constant", "N·m/rad"), "kd": ("the gain in use, constant", "N·m·s/rad")}
MODES = ("servo", "torque")
BASES = ("suspended", "standing")
#: The largest gains a log may say (N·m/rad, N·m·s/rad): past any servo. A
#: kp of 1e4 asks 10 N·m per mrad of error, three orders above Pupper's
#: 3 N·m limit at its usual kp 5; a larger number is in other units
#: (per degree, firmware counts) or a typo.
KP_MAX = 1e4
KD_MAX = 1e3
#: Header keys that say how the log was run: each may appear once.
SINGLE_KEYS = ("kp", "kd", "mode", "base", "columns", "held")


class LogError(ConfigError, ValueError):
    """A joint log that cannot be used: one line naming file, column and row."""

    kind = "config"


@dataclass
class JointLog:
    """One recording: ``target``, ``q`` (and ``qd``, ``tau`` where logged) are
    (samples, actuators) arrays in the order of ``actuators``."""

    path: Path
    times: np.ndarray
    actuators: list[str]
    target: np.ndarray
    q: np.ndarray
    qd: np.ndarray | None
    tau: np.ndarray | None
    kp: np.ndarray
    kd: np.ndarray
    mode: str = "servo"
    base: str = "suspended"
    sha256: str = ""
    #: the angle (rad) each actuator the log does not cover holds; "" for all of them
    held: dict[str, float] = field(default_factory=dict)
    #: the actuators the file covers, where ``actuators`` has been widened to a model's
    logged: list[str] = field(default_factory=list)

    @property
    def duration(self) -> float:
        return float(self.times[-1] - self.times[0])


def _gains(text: str, n: int, key: str, where: str) -> np.ndarray:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise LogError(f"{where}: '# {key}: {text}' is not a number or a comma-separated list: "
                       f"write e.g. '# {key}: 5'") from None
    if len(values) == 1:
        values = values * n
    if len(values) != n:
        raise LogError(f"{where}: '# {key}: {text}' must be one gain, or one per logged "
                       f"actuator ({n}) in column order")
    check_gains(values, key, where, f"'# {key}: {text}'")
    return np.asarray(values)


def check_gains(values: Sequence[float], key: str, where: str, said: str) -> None:
    """Refuses gains no servo runs at: kp must be > 0 (a servo at kp 0 holds
    nothing, and a fit could not see its kp), kd >= 0, both finite and at
    most KP_MAX / KD_MAX."""
    top, unit = (KP_MAX, "N·m/rad") if key == "kp" else (KD_MAX, "N·m·s/rad")
    at = f"{where}: {said}" if said else where
    for v in values:
        if not math.isfinite(v):
            raise LogError(f"{at}: {v} is not a finite number: write the gains in use")
        if key == "kp" and v <= 0:
            raise LogError(f"{at}: kp must be > 0 ({v:g}): a servo at kp 0 does not hold its joint; "
                           "write the gains in use")
        if v < 0:
            raise LogError(f"{at}: {key} must be >= 0 ({v:g}): write the gains in use")
        if v > top:
            raise LogError(f"{at}: {key} {v:g} is past {top:g} {unit}, more than any servo delivers "
                           f"(a {key} of {top:g} asks {top / 1e3:g} N·m per mrad{'' if key == 'kp' else '/s'} "
                           f"of error): it is likely in other units (per degree, firmware counts); "
                           f"write {unit}")


def _meta(lines: list[str], name: str) -> tuple[dict[str, str], dict[str, int], int]:
    """The ``# key: value`` lines above the header, the line number of each
    key, and the header's index. A key that says how the log was run may not
    appear twice."""
    meta: dict[str, str] = {}
    seen: dict[str, int] = {}
    for i, line in enumerate(lines):
        if not line.startswith("#"):
            return meta, seen, i
        if ":" in line:
            k, v = line[1:].split(":", 1)
            key = k.strip().lower()
            if key in SINGLE_KEYS and key in seen:
                raise LogError(f"{name}, line {i + 1}: '# {key}:' appears twice (lines {seen[key]} "
                               f"and {i + 1}): keep the one in use")
            seen.setdefault(key, i + 1)
            meta[key] = v.strip()
    return meta, seen, len(lines)


def read_log(path: str | Path, ranges: Mapping[str, tuple[float, float] | None], *,
             columns: ColumnMap | None = None, defaults: Mapping[str, str | None] | None = None) -> JointLog:
    """Reads and checks one log against a model's actuators (``ranges``:
    each actuator's joint range, None where unlimited). ``columns``: a
    column map over the log's own (``# columns:``); ``defaults``: header
    keys (kp, kd, held) for a log that does not say them."""
    p = Path(path)
    name = str(p)
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise LogError(f"{name}: cannot read the log ({e.strerror}): check the path") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise LogError(f"{name} is not a CSV text file (it is binary): give a joint log "
                       "(see `pupper fit --help` for the format)") from None
    # a BOM (some editors and spreadsheets write one) is not part of the text
    text = text.removeprefix("\ufeff")
    lines = text.splitlines()
    meta, line_of, body_start = _meta(lines, name)
    cmap = (parse_map(meta["columns"], f"{name}, line {line_of['columns']}") if "columns" in meta
            else ColumnMap())
    cmap = cmap.merged(columns) if columns else cmap
    # blank lines at the end are an editor's, not missing samples
    while len(lines) > body_start and not lines[-1].strip():
        lines.pop()
    rows = list(csv.reader(lines[body_start:]))
    header = [h.strip() for h in rows[0]] if rows else []
    keys = resolve(header, cmap, set(ranges), name)
    if "time" not in keys:
        first = header[0][:30] if header else "nothing"
        raise LogError(f"{name} is not a pupper joint log: its header (line {body_start + 1}) starts with "
                       f"'{first}' and has no 'time' column: name the time column 'time', or map it "
                       "(--columns time=COLUMN; see `pupper fit --help` for the format)")
    columns_of = _columns(keys, ranges, name)
    data = _numbers(rows[1:], header, keys, body_start, name)
    for k, f in cmap.scale.items():
        if k in data:
            data[k] = data[k] * f
    where = {k: f"{name}, line {n}" for k, n in line_of.items()}
    acts = list(columns_of)
    for key in ("kp", "kd"):
        if key in columns_of[acts[0]]:
            meta[key], where[key] = _gain_columns(data, header, keys, acts, key, meta.get(key), name)
    for key, v in (defaults or {}).items():
        if key not in meta and v is not None:
            meta[key], where[key] = str(v), f"{name}: --{key}"
    for key in ("kp", "kd"):
        if key not in meta:
            raise LogError(f"{name}: no '# {key}:' line: the log must say the gains in use "
                           f"(write e.g. '# kp: 5' and '# kd: 0.1' above the header, or give --{key})")
    mode = meta.get("mode", "servo")
    base = meta.get("base", "suspended")
    if mode not in MODES:
        raise LogError(f"{name}: '# mode: {mode}' is not one of {', '.join(MODES)}")
    if base not in BASES:
        raise LogError(f"{name}: '# base: {base}' is not one of {', '.join(BASES)}")

    def take(fld: str) -> np.ndarray:
        return np.stack([data[f"{a}.{fld}"] for a in acts], axis=1)

    target, q = take("target"), take("q")
    _not_degrees(name, acts, ranges, target, q, cmap)
    return JointLog(
        path=p, times=data["time"], actuators=acts, target=target, q=q,
        qd=take("qd") if "qd" in columns_of[acts[0]] else None,
        tau=take("tau") if "tau" in columns_of[acts[0]] else None,
        kp=_gains(meta["kp"], len(acts), "kp", where["kp"]),
        kd=_gains(meta["kd"], len(acts), "kd", where["kd"]),
        mode=mode, base=base, sha256=hashlib.sha256(raw).hexdigest(),
        held=_held(meta["held"], ranges, acts, where["held"]) if "held" in meta else {})


def _gain_columns(data: dict[str, np.ndarray], header: list[str], keys: list[str | None], acts: list[str],
                  key: str, said: str | None, name: str) -> tuple[str, str]:
    """Gains logged as columns (a command message's per-motor kp, kd): each
    constant through the log, and the same as a header line that says them."""
    values = []
    for a in acts:
        col = data[f"{a}.{key}"]
        if (bad := np.flatnonzero(col != col[0])).size:
            own = header[keys.index(f"{a}.{key}")]
            raise LogError(f"{name}, column '{own}': {key} changes during the log ({col[0]:g} to "
                           f"{col[bad[0]]:g}): fit replays one gain per log; split the log where it changes")
        values.append(float(col[0]))
    text = ",".join(repr(v) for v in values)
    if said is not None:
        try:
            same = [float(v) for v in said.split(",")]
        except ValueError:
            same = []
        if not (same == values or (len(same) == 1 and set(values) == set(same))):
            raise LogError(f"{name}: the {key} columns ({text}) and '# {key}: {said}' disagree: keep one")
    return text, f"{name}, the {key} columns"


def _held(text: str, ranges: Mapping[str, tuple[float, float] | None], logged: list[str],
          where: str) -> dict[str, float]:
    """``held``: one angle (rad) for every actuator the log does not cover,
    or ACTUATOR=RAD,... (the others at the model's rest pose)."""
    out: dict[str, float] = {}
    for item in (x.strip() for x in text.split(",") if x.strip()):
        act, eq, v = item.rpartition("=")
        act = act.strip() if eq else ""
        value = _finite(v, lambda inf: f"{where}: held '{item}' is not a finite angle: give the angle in rad"
                        if inf else f"{where}: held '{item}' is not RAD or ACTUATOR=RAD: write e.g. "
                        "'held: 0' or 'held: leg_front_r_1=0,leg_front_r_2=0.5'")
        if act and act not in ranges:
            raise LogError(f"{where}: held '{item}' names no actuator of the model: use the model's "
                           "actuator names")
        if act in logged:
            raise LogError(f"{where}: held '{item}': {act} is in the log, which says what it did: "
                           "drop it from held")
        out[act] = value
    if "" in out and len(out) > 1:
        raise LogError(f"{where}: held '{text}' mixes one angle for all with per-actuator ones: give one form")
    return out


def _columns(keys: list[str | None], ranges: Mapping[str, tuple[float, float] | None],
             name: str) -> dict[str, dict[str, int]]:
    """Each logged actuator's columns by field, checked (``keys``: each of
    the log's columns as pupper's name, None where not read)."""
    columns: dict[str, dict[str, int]] = {}
    for j, h in enumerate(keys):
        if h is None or h == "time":
            if h == "time" and keys.index("time") != j:
                raise LogError(f"{name}: column 'time' appears twice: keep one")
            continue
        act, dot, fld = h.rpartition(".")
        if not dot or fld not in FIELDS:
            raise LogError(f"{name}: column '{h}' is not ACTUATOR.FIELD (fields: "
                           f"{', '.join(FIELDS)}): rename it, or map the log's columns (--columns)")
        if act not in ranges:
            known = ", ".join(list(ranges)[:6])
            raise LogError(f"{name}: column '{h}' names no actuator of the model ('{act}'; "
                           f"its actuators: {known}, ...): use the model's actuator names")
        if fld in columns.setdefault(act, {}):
            raise LogError(f"{name}: column '{h}' appears twice: keep one")
        columns[act][fld] = j
    if not columns:
        raise LogError(f"{name}: no actuator columns beside 'time': add ACTUATOR.target and ACTUATOR.q, "
                       "or map the log's own (--columns)")
    for act, cols in columns.items():
        for need in ("target", "q"):
            if need not in cols:
                raise LogError(f"{name}: column '{act}.{need}' is missing (each logged actuator "
                               "needs .target and .q): add or map it")
    for fld in ("qd", "tau", "kp", "kd"):
        have = [a for a, c in columns.items() if fld in c]
        if have and len(have) != len(columns):
            miss = next(a for a in columns if fld not in columns[a])
            raise LogError(f"{name}: column '{miss}.{fld}' is missing while other actuators "
                           f"log .{fld}: log it for every actuator or for none")
    return columns


def _numbers(rows: list[list[str]], header: list[str], keys: list[str | None], body_start: int,
             name: str) -> dict[str, np.ndarray]:
    """The samples of the columns read (by pupper's name), every one a
    finite number, times strictly increasing."""
    used = [j for j, k in enumerate(keys) if k is not None]
    data = np.empty((len(rows), len(used)))
    for r, row in enumerate(rows):
        line_no = body_start + 2 + r
        if len(row) != len(header):
            raise LogError(f"{name}, row {line_no}: {len(row)} fields, the header has "
                           f"{len(header)}: fix or drop the row")
        for c, j in enumerate(used):
            cell = row[j]
            data[r, c] = _finite(cell, lambda inf: f"{name}, column '{header[j]}', row {line_no}: " + (
                f"{cell} is not a finite number: drop or fill the sample" if inf else f"'{cell}' is not a number"))
    if len(data) < 2:
        raise LogError(f"{name}: {len(data)} samples: a log needs many (e.g. 10 s at 500 Hz)")
    out = {str(keys[j]): data[:, c] for c, j in enumerate(used)}
    t = out["time"]
    steps = np.diff(t)
    if (bad := np.flatnonzero(steps <= 0)).size:
        r = int(bad[0]) + 1
        word = "repeats" if steps[r - 1] == 0 else "goes back"
        raise LogError(f"{name}, column '{header[keys.index('time')]}', row {body_start + 2 + r}: time {word} "
                       f"({float(t[r])!r} after {float(t[r - 1])!r}): times must increase strictly")
    return out


def _finite(text: str, says: Callable[[bool], str]) -> float:
    """``text`` as a finite number, else a LogError: ``says(True)`` where it
    is a number but not finite, ``says(False)`` where it is none."""
    try:
        v = float(text)
    except ValueError:
        raise LogError(says(False)) from None
    if not math.isfinite(v):
        raise LogError(says(True))
    return v


def _not_degrees(name: str, acts: list[str], ranges: Mapping[str, tuple[float, float] | None],
                 target: np.ndarray, q: np.ndarray, cmap: ColumnMap) -> None:
    for fld, values in (("target", target), ("q", q)):
        for k, a in enumerate(acts):
            top = float(np.max(np.abs(values[:, k])))
            rng = ranges[a]
            reach = max(abs(rng[0]), abs(rng[1])) if rng else math.pi
            if top > max(2 * reach, 2 * math.pi) and top > 6.3:
                key = f"{a}.{fld}"
                col = cmap.column.get(key, key)
                raise LogError(f"{name}, column '{col}': values up to {top:.4g} are past "
                               f"the joint's range ({reach:.3g} rad): they look like degrees; the "
                               "log's angles are in rad: multiply by pi/180, or declare the unit in the "
                               f"column map (--columns {key}={col}:deg)")


def _number(v: float) -> str:
    return repr(float(v))


def write_log(path: str | Path, times: np.ndarray, actuators: Sequence[str], *,
              target: np.ndarray, q: np.ndarray, qd: np.ndarray | None = None,
              tau: np.ndarray | None = None, kp: Sequence[float] | np.ndarray, kd: Sequence[float] | np.ndarray,
              mode: str = "servo", base: str = "suspended", note: str = "") -> None:
    """Writes a log in the format above (every digit of each float)."""
    from pupper_core._files import atomic_write

    fields = [("target", target), ("q", q)] + [(f, a) for f, a in (("qd", qd), ("tau", tau))
                                               if a is not None]

    def gains(v: Sequence[float] | np.ndarray) -> str:
        values = [float(x) for x in v]
        return _number(values[0]) if len(set(values)) == 1 else ",".join(map(_number, values))

    def write(tmp: Path) -> None:
        with tmp.open("w", newline="") as f:
            f.write(f"{MAGIC}\n")
            if note:
                f.write(f"# note: {note}\n")
            f.write(f"# mode: {mode}\n# base: {base}\n# kp: {gains(kp)}\n# kd: {gains(kd)}\n")
            f.write("# units: time s; target, q rad; qd rad/s; tau N·m\n")
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["time"] + [f"{a}.{fld}" for a in actuators for fld, _ in fields])
            for i, t in enumerate(times):
                w.writerow([_number(t)] + [_number(arr[i, k]) for k in range(len(actuators))
                                           for _, arr in fields])

    atomic_write(Path(path), write)
