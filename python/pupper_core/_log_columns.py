"""A joint log's column map (``pupper_core._joint_log`` reads through it):
the robot's own column names and units for pupper's ``time`` and
``ACTUATOR.FIELD`` columns, so that a log written by the robot's control
loop (a ROS 2 bag exported to CSV, say) is read as it is.

A map is a list of ``KEY=COLUMN[:UNIT]`` entries, separated by commas or
new lines (``#`` starts a comment in a map file)::

    time=stamp, leg_front_r_3.target=fr_knee_cmd:deg, leg_front_r_3.q=fr_knee_pos:deg

KEY is ``time`` or ``ACTUATOR.FIELD`` (FIELD: target, q, qd, tau, and the
gains kp, kd where the loop logs them); UNIT is what the column is in,
when it is not pupper's own (s, rad, rad/s, N·m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

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


@dataclass
class ColumnMap:
    """KEY (``time`` or ``ACTUATOR.FIELD``) -> the log's column, and the
    factor from the column's unit to pupper's."""

    column: dict[str, str] = field(default_factory=dict)
    scale: dict[str, float] = field(default_factory=dict)
    unit: dict[str, str] = field(default_factory=dict)

    def __bool__(self) -> bool:
        return bool(self.column) or bool(self.unit)

    def merged(self, over: ColumnMap) -> ColumnMap:
        """This map with ``over``'s entries in place of its own."""
        return ColumnMap({**self.column, **over.column}, {**self.scale, **over.scale}, {**self.unit, **over.unit})


def field_of(key: str) -> str:
    return "time" if key == "time" else key.rpartition(".")[2]


def parse_map(text: str, where: str) -> ColumnMap:
    """A map's text (``where``: what to name in an error: the flag or the
    header line). A bad entry is a one-line error naming it."""
    from pupper_core._joint_log import LogError

    out = ColumnMap()
    entries = [e.strip() for line in text.splitlines() for e in line.split("#", 1)[0].split(",")]
    for entry in (e for e in entries if e):
        key, eq, rest = entry.partition("=")
        key, rest = key.strip(), rest.strip()
        if not eq or not key or not rest:
            raise LogError(f"{where}: '{entry}' is not KEY=COLUMN[:UNIT]: write e.g. "
                           "'time=stamp' or 'leg_front_r_3.q=fr_knee_pos:deg'")
        fld = field_of(key)
        if fld not in UNITS:
            raise LogError(f"{where}: '{key}' is not time or ACTUATOR.FIELD (fields: target, q, qd, tau, kp, kd): "
                           "write e.g. 'leg_front_r_3.q=fr_knee_pos'")
        column, colon, unit = rest.rpartition(":")
        if not colon:
            column, unit = rest, ""
        column, unit = column.strip(), unit.strip()
        if unit and unit not in UNITS[fld]:
            raise LogError(f"{where}: '{entry}': unit '{unit}' is not one of {', '.join(UNITS[fld])} "
                           f"for {fld}")
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
    from pupper_core._joint_log import LogError

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


def resolve(header: list[str], cmap: ColumnMap, actuators: set[str], name: str) -> list[str | None]:
    """Each of the log's columns as pupper's key (None: not read). Without
    a map every column must be pupper's own; with one, a column neither
    mapped nor named as pupper's is not read (a ROS export carries many)."""
    from pupper_core._joint_log import LogError

    keys: list[str | None] = []
    by_column = {c: k for k, c in cmap.column.items()}
    for k, c in cmap.column.items():
        if c not in header:
            shown = ", ".join(header[:8]) + (", ..." if len(header) > 8 else "")
            raise LogError(f"{name}: the column map's '{k}={c}' names no column of the log (its columns: "
                           f"{shown}): fix the map")
        act = k.rpartition(".")[0]
        if k != "time" and act not in actuators:
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
