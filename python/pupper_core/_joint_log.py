"""The joint-log format: what a robot's servos did, one CSV per recording.

A log is plain CSV with a few ``# key: value`` lines above its header::

    # pupper joint log 1
    # mode: servo
    # base: suspended
    # kp: 5
    # kd: 0.1
    time,leg_front_r_1.target,leg_front_r_1.q,leg_front_r_1.qd,leg_front_r_1.tau,...
    0,0,0.0003,0,0.01,...

Units: ``time`` in s (strictly increasing), ``.target`` (the commanded
angle) and ``.q`` (the measured angle) in rad, ``.qd`` in rad/s, ``.tau`` in
N·m. Each logged actuator needs ``.target`` and ``.q``; ``.qd`` and ``.tau``
are optional (most servos report no torque). ``kp``/``kd`` are the gains in
use (N·m/rad, N·m·s/rad): one number for every actuator, or one per logged
actuator in column order. ``mode`` is who ran the PD (``servo``: the motor's
firmware, ``torque``: the host); ``base`` is ``suspended`` (the robot hung,
its feet off the ground) or ``standing``.
"""

from __future__ import annotations

import csv
import hashlib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["JointLog", "LogError", "read_log", "write_log", "FIELDS"]

MAGIC = "# pupper joint log 1"
#: A column's suffix, what it holds, its unit.
FIELDS = {"target": ("commanded angle", "rad"), "q": ("measured angle", "rad"),
          "qd": ("measured velocity", "rad/s"), "tau": ("measured torque", "N·m")}
MODES = ("servo", "torque")
BASES = ("suspended", "standing")


class LogError(ValueError):
    """A joint log that cannot be used: one line naming file, column and row."""


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
    if len(values) != n or not all(math.isfinite(v) and v >= 0 for v in values):
        raise LogError(f"{where}: '# {key}: {text}' must be one gain >= 0, or one per logged "
                       f"actuator ({n}) in column order")
    return np.asarray(values)


def read_log(path: str | Path, ranges: Mapping[str, tuple[float, float] | None]) -> JointLog:
    """Reads and checks one log against a model's actuators (``ranges``:
    each actuator's joint range, None where unlimited)."""
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
    meta: dict[str, str] = {}
    lines = text.splitlines()
    body_start = 0
    for i, line in enumerate(lines):
        if not line.startswith("#"):
            body_start = i
            break
        if ":" in line:
            k, v = line[1:].split(":", 1)
            meta[k.strip().lower()] = v.strip()
    else:
        body_start = len(lines)
    rows = list(csv.reader(lines[body_start:]))
    if not rows or not rows[0] or rows[0][0].strip() != "time":
        first = rows[0][0][:30] if rows and rows[0] else "nothing"
        raise LogError(f"{name} is not a pupper joint log: its header (line {body_start + 1}) "
                       f"starts with '{first}', not 'time' (see `pupper fit --help` for the format)")
    header = [h.strip() for h in rows[0]]
    columns: dict[str, dict[str, int]] = {}
    for j, h in enumerate(header[1:], start=1):
        act, dot, field = h.rpartition(".")
        if not dot or field not in FIELDS:
            raise LogError(f"{name}: column '{h}' is not ACTUATOR.FIELD (fields: "
                           f"{', '.join(FIELDS)}): rename it")
        if act not in ranges:
            known = ", ".join(list(ranges)[:6])
            raise LogError(f"{name}: column '{h}' names no actuator of the model ('{act}'; "
                           f"its actuators: {known}, ...): use the model's actuator names")
        if field in columns.setdefault(act, {}):
            raise LogError(f"{name}: column '{h}' appears twice: keep one")
        columns[act][field] = j
    if not columns:
        raise LogError(f"{name}: no actuator columns after 'time': add ACTUATOR.target and ACTUATOR.q")
    for act, cols in columns.items():
        for need in ("target", "q"):
            if need not in cols:
                raise LogError(f"{name}: column '{act}.{need}' is missing (each logged actuator "
                               "needs .target and .q): add it")
    for field in ("qd", "tau"):
        have = [a for a, c in columns.items() if field in c]
        if have and len(have) != len(columns):
            miss = next(a for a in columns if field not in columns[a])
            raise LogError(f"{name}: column '{miss}.{field}' is missing while other actuators "
                           f"log .{field}: log it for every actuator or for none")
    data = np.empty((len(rows) - 1, len(header)))
    for r, row in enumerate(rows[1:]):
        line_no = body_start + 2 + r
        if len(row) != len(header):
            raise LogError(f"{name}, row {line_no}: {len(row)} fields, the header has "
                           f"{len(header)}: fix or drop the row")
        for j, cell in enumerate(row):
            try:
                v = float(cell)
            except ValueError:
                raise LogError(f"{name}, column '{header[j]}', row {line_no}: '{cell}' is not a "
                               "number") from None
            if not math.isfinite(v):
                raise LogError(f"{name}, column '{header[j]}', row {line_no}: {cell} is not a "
                               "finite number: drop or fill the sample")
            data[r, j] = v
    if len(data) < 2:
        raise LogError(f"{name}: {len(data)} samples: a log needs many (e.g. 10 s at 500 Hz)")
    t = data[:, 0]
    steps = np.diff(t)
    if (bad := np.flatnonzero(steps <= 0)).size:
        r = int(bad[0]) + 1
        word = "repeats" if steps[r - 1] == 0 else "goes back"
        raise LogError(f"{name}, column 'time', row {body_start + 2 + r}: time {word} "
                       f"({t[r]:g} after {t[r - 1]:g}): times must increase strictly")
    where = f"{name}"
    for key in ("kp", "kd"):
        if key not in meta:
            raise LogError(f"{where}: no '# {key}:' line: the log must say the gains in use "
                           "(write e.g. '# kp: 5' and '# kd: 0.1' above the header)")
    acts = list(columns)
    mode = meta.get("mode", "servo")
    base = meta.get("base", "suspended")
    if mode not in MODES:
        raise LogError(f"{where}: '# mode: {mode}' is not one of {', '.join(MODES)}")
    if base not in BASES:
        raise LogError(f"{where}: '# base: {base}' is not one of {', '.join(BASES)}")

    def take(field: str) -> np.ndarray:
        return data[:, [columns[a][field] for a in acts]]

    target, q = take("target"), take("q")
    for field, values in (("target", target), ("q", q)):
        for k, a in enumerate(acts):
            top = float(np.max(np.abs(values[:, k])))
            rng = ranges[a]
            reach = max(abs(rng[0]), abs(rng[1])) if rng else math.pi
            if top > max(2 * reach, 2 * math.pi) and top > 6.3:
                raise LogError(f"{name}, column '{a}.{field}': values up to {top:.4g} are past "
                               f"the joint's range ({reach:.3g} rad): they look like degrees; the "
                               "log's angles are in rad (multiply by pi/180)")
    return JointLog(
        path=p, times=t, actuators=acts, target=target, q=q,
        qd=take("qd") if "qd" in columns[acts[0]] else None,
        tau=take("tau") if "tau" in columns[acts[0]] else None,
        kp=_gains(meta["kp"], len(acts), "kp", where),
        kd=_gains(meta["kd"], len(acts), "kd", where),
        mode=mode, base=base, sha256=hashlib.sha256(raw).hexdigest())


def _number(v: float) -> str:
    return repr(float(v))


def write_log(path: str | Path, times: np.ndarray, actuators: Sequence[str], *,
              target: np.ndarray, q: np.ndarray, qd: np.ndarray | None = None,
              tau: np.ndarray | None = None, kp: Sequence[float], kd: Sequence[float],
              mode: str = "servo", base: str = "suspended", note: str = "") -> None:
    """Writes a log in the format above (every digit of each float)."""
    from pupper_core._files import atomic_write

    fields = [("target", target), ("q", q)] + [(f, a) for f, a in (("qd", qd), ("tau", tau))
                                               if a is not None]

    def gains(v: Sequence[float]) -> str:
        v = [float(x) for x in v]
        return _number(v[0]) if len(set(v)) == 1 else ",".join(map(_number, v))

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
