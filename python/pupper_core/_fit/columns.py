"""A joint log's column map (``pupper_core._fit.log`` reads through it):
the robot's own column names and units for pupper's ``time`` and
``ACTUATOR.FIELD`` columns, so that a log written by the robot's control
loop (a ROS 2 bag exported to CSV, say) is read as it is.

A map is a list of ``KEY=COLUMN[:UNIT]`` entries, separated by commas or
new lines (``#`` starts a comment in a map file)::

    time=stamp, leg_front_r_3.target=fr_knee_cmd:deg, leg_front_r_3.q=fr_knee_pos:deg

KEY is ``time`` or ``ACTUATOR.FIELD`` (FIELD: target, q, qd, tau, and the
gains kp, kd where the loop logs them); or ``motor``, the column that says
which motor a log is of (the model's actuator index or name, one per
log), with FIELD alone for that motor's columns, so that one map reads
the logs of every motor::

    time=time_since_fade_in (s), motor=motor_idx, target=command (rad), q=motor_position (rad)

UNIT is what the column is in, when it is not pupper's own (s, rad,
rad/s, N·m); where the map gives none, a unit in the column's own name
(``command (rad)``, ``stamp (ms)``) is read. A Pupper v3's real2sim
bench log (``PUPPER_V3``) is read with its built-in map where no map is
given.

Also here, what the columns a log is read through must be: each logged
actuator's (``logged_columns``), the motor a motor column names
(``with_motor``), and angles, velocities and torques no servo gives
(``not_degrees``, ``plausible``).
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pupper_core._native import ConfigError

class LogError(ConfigError, ValueError):
    """A joint log that cannot be used: one line naming file, column and row."""

    kind = "config"


#: The units each field may be declared in, and the factor to pupper's own.
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "ns": 1e-9},
    "target": {"rad": 1.0, "deg": math.pi / 180},
    "q": {"rad": 1.0, "deg": math.pi / 180},
    "qd": {"rad/s": 1.0, "deg/s": math.pi / 180},
    "tau": {"N·m": 1.0, "Nm": 1.0, "N.m": 1.0, "N*m": 1.0},
    "kp": {"N·m/rad": 1.0, "Nm/rad": 1.0},
    "kd": {"N·m·s/rad": 1.0, "Nms/rad": 1.0},
}
#: A column's suffix, what it holds, its unit.
FIELDS = {"target": ("commanded angle", "rad"), "q": ("measured angle", "rad"),
          "qd": ("measured velocity", "rad/s"), "tau": ("measured torque", "N·m"),
          "kp": ("the gain in use, constant", "N·m/rad"), "kd": ("the gain in use, constant", "N·m·s/rad")}
#: A unit in a column's own name: its last parenthesised words (``motor_velocity (rad/s)``).
NAMED_UNIT = re.compile(r"\(\s*([^()]+?)\s*\)\s*$")
#: The key of the column that names a log's motor (``motor=COLUMN``).
MOTOR = "motor"
#: A Pupper v3's real2sim bench log, as its ROS 2 loop writes it (one motor per
#: file, the motor's index in ``motor_idx``): read with this map where none is given.
PUPPER_V3 = {"time": "time_since_fade_in (s)", MOTOR: "motor_idx", "target": "command (rad)",
             "q": "motor_position (rad)", "qd": "motor_velocity (rad/s)"}
#: The columns that tell a log is in that format.
PUPPER_V3_HAS = ("motor_idx", "command (rad)", "motor_position (rad)")


@dataclass
class ColumnMap:
    """KEY (``time``, ``ACTUATOR.FIELD``, ``motor`` or a FIELD of the
    motor's) -> the log's column, and the factor from the column's unit to
    pupper's."""

    column: dict[str, str] = field(default_factory=dict)
    scale: dict[str, float] = field(default_factory=dict)
    unit: dict[str, str] = field(default_factory=dict)

    def __bool__(self) -> bool:
        return bool(self.column) or bool(self.unit)

    def merged(self, over: ColumnMap) -> ColumnMap:
        """This map with ``over``'s entries in place of its own."""
        return ColumnMap({**self.column, **over.column}, {**self.scale, **over.scale}, {**self.unit, **over.unit})

    def bare(self) -> list[str]:
        """The keys that are a FIELD alone: the motor column's actuator's."""
        return [k for k in self.column if k in UNITS and k != "time"]

    def for_motor(self, actuator: str, where: str) -> ColumnMap:
        """The map with each bare FIELD as ``actuator``'s (the motor column's)."""
        out = ColumnMap(dict(self.column), dict(self.scale), dict(self.unit))
        for k in self.bare():
            key = f"{actuator}.{k}"
            if key in out.column:
                raise LogError(f"{where}: the column map maps '{key}' twice (as {k}= of the motor, {actuator}, and "
                               f"as {key}=): keep one")
            out.column[key] = out.column.pop(k)
            if k in out.unit:
                out.scale[key], out.unit[key] = out.scale.pop(k), out.unit.pop(k)
        return out


def field_of(key: str) -> str:
    return "time" if key == "time" else key.rpartition(".")[2]


def unit_in_name(column: str) -> str:
    """The unit a column's name says in parentheses (``command (rad)``),
    if it is one of any field's units; "" where it says none."""
    m = NAMED_UNIT.search(column)
    unit = m.group(1) if m else ""
    return unit if any(unit in units for units in UNITS.values()) else ""


def _unit(key: str, column: str, unit: str, entry: str, where: str) -> str:
    """The entry's unit: the map's own, else its column's name's; one that
    is no unit of the field, or a name's that disagrees with the map's, is
    refused."""
    fld = field_of(key)
    if unit and unit not in UNITS[fld]:
        raise LogError(f"{where}: '{entry}': unit '{unit}' is not one of {', '.join(UNITS[fld])} for {fld}")
    named = unit_in_name(column)
    if named and named not in UNITS[fld]:
        raise LogError(f"{where}: '{entry}': the column's name says it is in {named}, no unit of {fld} "
                       f"({', '.join(UNITS[fld])}): map the {fld} column, or rename this one")
    if unit and named and UNITS[fld][unit] != UNITS[fld][named]:
        raise LogError(f"{where}: '{entry}': the map says {unit}, the column's name says {named}: drop the "
                       "map's unit (the name's is read) or fix the one that is wrong")
    return unit or named


def parse_map(text: str, where: str) -> ColumnMap:
    """A map's text (``where``: what to name in an error: the flag or the
    header line). A bad entry is a one-line error naming it."""
    out = ColumnMap()
    entries = [e.strip() for line in text.splitlines() for e in line.split("#", 1)[0].split(",")]
    for entry in (e for e in entries if e):
        key, eq, rest = entry.partition("=")
        key, rest = key.strip(), rest.strip()
        if not eq or not key or not rest:
            raise LogError(f"{where}: '{entry}' is not KEY=COLUMN[:UNIT]: write e.g. "
                           "'time=stamp' or 'leg_front_r_3.q=fr_knee_pos:deg'")
        fld = field_of(key)
        if fld not in UNITS and key != MOTOR:
            raise LogError(f"{where}: '{key}' is not time or ACTUATOR.FIELD (fields: target, q, qd, tau, kp, kd), "
                           "nor motor or a FIELD of the motor column's: write e.g. 'leg_front_r_3.q=fr_knee_pos'")
        column, colon, unit = rest.rpartition(":")
        if not colon:
            column, unit = rest, ""
        column, unit = column.strip(), unit.strip()
        if key == MOTOR and unit:
            raise LogError(f"{where}: '{entry}': the motor column has no unit: write motor={column}")
        unit = _unit(key, column, unit, entry, where) if key != MOTOR else ""
        if key in out.column:
            raise LogError(f"{where}: '{key}' is mapped twice: keep one")
        out.column[key] = column or key
        if unit:
            out.scale[key] = UNITS[fld][unit]
            out.unit[key] = unit
    return out


def read_map(value: str, base: Path | None = None, flag: str = "--columns") -> ColumnMap:
    """``--columns``' value (or a log's own ``columns=``: ``flag`` names
    it): a map, or the path of a file holding one (relative to ``base``
    where given: a list of logs' folder)."""
    p = Path(value)
    if base is not None and not p.is_absolute():
        p = base / p
    if "=" not in value and value.strip():
        try:
            text = p.read_text()
        except (OSError, UnicodeDecodeError) as e:
            why = getattr(e, "strerror", None) or "not a text file"
            raise LogError(f"{flag} {value}: neither a map (KEY=COLUMN[:UNIT],...) nor a readable "
                           f"map file ({why}): give e.g. {flag} time=stamp,leg_front_r_3.q=fr_knee_pos") from None
        return parse_map(text, f"{flag} {value}")
    return parse_map(value, flag)


def builtin_map(header: list[str]) -> ColumnMap | None:
    """The built-in map of a header in a known robot's format (a Pupper v3's
    real2sim log: ``PUPPER_V3``), or None."""
    if not all(c in header for c in PUPPER_V3_HAS):
        return None
    return parse_map(",".join(f"{k}={c}" for k, c in PUPPER_V3.items() if k != "qd" or c in header),
                     "the built-in Pupper v3 map")


def builtin_note(name: str) -> str:
    """What a log read with the built-in map is said to be (a note line,
    ``name``: the first such log's)."""
    said = ", ".join(f"{k}={c}" for k, c in PUPPER_V3.items())
    return (f"{name} (and any log like it) has no column map and a Pupper v3 real2sim log's header: read with the "
            f"built-in map {said} (the motor: the model's actuator at that index); --columns reads it otherwise")


def motor_of(cell: str, actuators: Sequence[str], where: str) -> str:
    """The actuator a motor column's cell names: the model's actuator at
    that index (0 first), or of that name."""
    text = cell.strip()
    if text in actuators:
        return text
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    n = len(actuators)
    if not (math.isfinite(v) and v == int(v) and v >= 0):
        raise LogError(f"{where}: '{text}' is neither an actuator's index (0 to {n - 1}) nor its name "
                       f"({actuators[0]}, ...): the motor column says which of the model's actuators the log is of")
    if v >= n:
        raise LogError(f"{where}: motor {int(v)} is past the model's {n} actuators (0 to {n - 1}: {actuators[0]} "
                       f"to {actuators[-1]}): fit with the model the log was taken on (--model), or map the log's "
                       "columns to an actuator (--columns ACTUATOR.target=COLUMN,...)")
    return actuators[int(v)]


def resolve(header: list[str], cmap: ColumnMap, actuators: Sequence[str], name: str) -> list[str | None]:
    """Each of the log's columns as pupper's key (None: not read; ``motor``
    and a bare FIELD as themselves, for the motor column to name).
    Without a map every column must be pupper's own; with one, a column
    neither mapped nor named as pupper's is not read (a ROS export carries
    many)."""
    keys: list[str | None] = []
    by_column = {c: k for k, c in cmap.column.items()}
    for k, c in cmap.column.items():
        if c not in header:
            shown = ", ".join(header[:8]) + (", ..." if len(header) > 8 else "")
            raise LogError(f"{name}: the column map's '{k}={c}' names no column of the log (its columns: "
                           f"{shown}): fix the map")
        act = k.rpartition(".")[0]
        if k in cmap.bare() and MOTOR not in cmap.column:
            raise LogError(f"{name}: the column map's '{k}={c}' names no actuator: write ACTUATOR.{k}={c}, or "
                           "map the column that names the log's motor (motor=COLUMN)")
        if k not in ("time", MOTOR) and k not in cmap.bare() and act not in actuators:
            known = ", ".join(sorted(actuators)[:6])
            raise LogError(f"{name}: the column map's '{k}' names no actuator of the model ('{act}'; its "
                           f"actuators: {known}, ...): use the model's actuator names")
    for h in header:
        if h in by_column:
            keys.append(by_column[h])
        elif h in cmap.column:
            # pupper's own name, mapped to another column
            keys.append(None)
        elif not cmap.column:
            keys.append(h)
        else:
            act, dot, fld = h.rpartition(".")
            own = h == "time" or (dot and act in actuators and fld in UNITS)
            keys.append(h if own else None)
    return keys


def not_degrees(name: str, acts: list[str], ranges: Mapping[str, tuple[float, float] | None],
                target: np.ndarray, q: np.ndarray, cmap: ColumnMap, line_of_row: Callable[[int], int]) -> None:
    """Angles past a joint's range: a sample past it in degrees too is no
    angle (a glitch, or another unit), said with its row; a column past it
    in rad only looks like degrees."""
    for fld, values in (("target", target), ("q", q)):
        for k, a in enumerate(acts):
            top = float(np.max(np.abs(values[:, k])))
            rng = ranges[a]
            reach = max(abs(rng[0]), abs(rng[1])) if rng else math.pi
            bound = max(2 * reach, 2 * math.pi)
            if top > bound and top > 6.3:
                key = f"{a}.{fld}"
                col = cmap.column.get(key, key)
                r = int(np.argmax(np.abs(values[:, k])))
                if top > math.degrees(bound):
                    raise LogError(f"{name}, column '{col}', row {line_of_row(r)}: {values[r, k]:.4g} is no angle "
                                   f"of this joint, in rad or in degrees (its range reaches {reach:.3g} rad): a "
                                   "glitch or another unit (encoder counts?); fix or drop the row, or convert the "
                                   "column to rad")
                raise LogError(f"{name}, column '{col}': values up to {top:.4g} are past "
                               f"the joint's range ({reach:.3g} rad): they look like degrees; the "
                               "log's angles are in rad: multiply by pi/180, or declare the unit in the "
                               f"column map (--columns {key}={col}:deg)")


#: Past these no servo's velocity (rad/s: 10^4 is 95,000 rpm) or torque (N·m) is.
PLAUSIBLE = {"qd": (1e4, "rad/s"), "tau": (1e4, "N·m")}


def plausible(name: str, acts: list[str], columns: Mapping[str, np.ndarray | None], cmap: ColumnMap,
              line_of_row: Callable[[int], int]) -> None:
    """A velocity or torque sample no servo gives (a glitch, 1e300) is
    refused with its row: a fit would chase it."""
    for fld, values in columns.items():
        if values is None:
            continue
        top, unit = PLAUSIBLE[fld]
        bad = np.argwhere(np.abs(values) > top)
        if bad.size:
            r, k = (int(x) for x in bad[0])
            key = f"{acts[k]}.{fld}"
            col = cmap.column.get(key, key)
            raise LogError(f"{name}, column '{col}', row {line_of_row(r)}: {values[r, k]:.4g} {unit} is past "
                           f"what any servo gives ({top:g} {unit}): a glitch or another unit; fix or drop the row")


# -- the columns read, and the motor a motor column names ---------------------------------------------


def blank_row(row: list[str]) -> bool:
    """A row of a blank line (an editor's at the end; a missing sample before a row)."""
    return not row or (len(row) == 1 and not row[0].strip())


def with_motor(rows: Iterator[list[str]], header: list[str], cmap: ColumnMap, keys: list[str | None],
               acts: list[str], body_start: int,
               name: str) -> tuple[Iterator[list[str]], ColumnMap, list[str | None], tuple[int, str, str] | None]:
    """Where the map names the log's motor column (``motor=COLUMN``): its
    first row's actuator, whose columns the bare FIELD keys are; the rows
    (the first put back), the map and keys for that actuator, and (the
    motor column, its first cell, its actuator) for every row to agree."""
    if MOTOR not in cmap.column:
        return rows, cmap, keys, None
    seen: list[list[str]] = []
    for row in rows:
        seen.append(row)
        if not blank_row(row):
            break
    rows = itertools.chain(seen, rows)
    mj = keys.index(MOTOR)
    if not seen or blank_row(seen[-1]):
        raise LogError(f"{name}: 0 samples: a log needs many (e.g. 10 s at 500 Hz)")
    first, line_no = seen[-1], body_start + 1 + len(seen)
    if len(first) != len(header):
        raise LogError(f"{name}, row {line_no}: {len(first)} fields, the header has {len(header)}: fix or drop "
                       "the row")
    act = motor_of(first[mj], acts, f"{name}, column '{header[mj]}', row {line_no}")
    cmap = cmap.for_motor(act, name)
    keys = resolve(header, cmap, acts, name)
    keys[mj] = None
    return rows, cmap, keys, (mj, first[mj], act)


def logged_columns(keys: list[str | None], ranges: Mapping[str, tuple[float, float] | None],
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


def same_motor(cell: str, motor: tuple[int, str, str], acts: list[str], where: str) -> None:
    """A row's motor cell names the log's motor (its first row's)."""
    act = motor_of(cell, acts, where)
    if act != motor[2]:
        raise LogError(f"{where}: the motor changes ({motor[1].strip()}, {motor[2]}, to {cell.strip()}, {act}): "
                       "fit reads one motor per log; split the log where it changes")
