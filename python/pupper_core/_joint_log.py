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

import bz2
import csv
import gzip
import hashlib
import io
import lzma
import math
import zlib
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
    #: the samples read (time, actuators, angles, velocities, torques), hashed: the same
    #: recording in other bytes (compressed, a BOM, CRLF, other columns) has the same digest
    digest: str = ""

    @property
    def duration(self) -> float:
        return float(self.times[-1] - self.times[0])


def _gains(text: str, n: int, key: str, where: str, said: str = "") -> np.ndarray:
    """A gain as said (``said``: how, a header line by default): one value,
    or one per logged actuator."""
    said = said or f"'# {key}: {text}'"
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise LogError(f"{where}: {said} is not a number or a comma-separated list: "
                       f"write e.g. {key} 5") from None
    if len(values) == 1:
        values = values * n
    if len(values) != n:
        raise LogError(f"{where}: {said} must be one gain, or one per logged "
                       f"actuator ({n}) in column order")
    check_gains(values, key, where, said)
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


#: Compressions a log is read through, told by their magic bytes (whatever
#: the file's suffix): the name said, and the reader.
COMPRESSED: dict[bytes, tuple[str, Callable[[io.BytesIO], io.BufferedIOBase]]] = {
    b"\x1f\x8b": ("gzip", lambda f: gzip.GzipFile(fileobj=f)),
    b"BZh": ("bzip2", lambda f: bz2.BZ2File(f)),
    b"\xfd7zXZ\x00": ("xz", lambda f: lzma.LZMAFile(f)),
}
#: Files that are no CSV, told by their magic bytes: what each is, and what to do.
NOT_CSV = {
    b"\x28\xb5\x2f\xfd": "zstd-compressed, which fit does not read: decompress it (zstd -d) or recompress it "
                         "with gzip",
    b"\x04\x22\x4d\x18": "lz4-compressed, which fit does not read: decompress it (lz4 -d) or recompress it "
                         "with gzip",
    b"PK\x03\x04": "a zip archive (or a spreadsheet: .xlsx, .ods): unzip it, or export the sheet as CSV",
    b"SQLite format 3\x00": "an SQLite database (a ROS 2 bag's .db3?): export the joint topics to CSV",
    b"\x89MCAP": "an MCAP file (a ROS 2 bag): export the joint topics to CSV",
    b"PAR1": "a Parquet file: export it as CSV",
    b"\x93NUMPY": "a NumPy array (.npy): write it as CSV",
    b"\x89HDF\r\n\x1a\n": "an HDF5 file: export the joint data as CSV",
}
#: The most text a compressed log may decompress to: a 600 s log at 1 kHz
#: of 12 joints' four columns is about 600 MB; past this it is a bomb or
#: no log.
MAX_TEXT_BYTES = 2**30
#: Compression inside compression (a .csv.gz gzipped again) is unpacked this deep.
MAX_LAYERS = 3


def _decompressed(raw: bytes, name: str) -> tuple[bytes, list[str]]:
    """The bytes of a log, through any compression its magic bytes say
    (layers of it), and the compressions passed."""
    layers: list[str] = []
    data = raw
    while (kind := next((v for k, v in COMPRESSED.items() if data.startswith(k)), None)) is not None:
        what, opener = kind
        if len(layers) == MAX_LAYERS:
            raise LogError(f"{name} is compressed more than {MAX_LAYERS} times over ({', '.join(layers)}, "
                           f"{what}): decompress it and give the CSV")
        try:
            with opener(io.BytesIO(data)) as f:
                data = f.read(MAX_TEXT_BYTES + 1)
        except (OSError, EOFError, zlib.error, lzma.LZMAError) as e:
            raise LogError(f"{name} is {what}-compressed but does not decompress ({e}): the file is truncated "
                           "or damaged; copy it from the robot again") from None
        if len(data) > MAX_TEXT_BYTES:
            raise LogError(f"{name} is {what}-compressed and decompresses past {MAX_TEXT_BYTES // 2**30} GiB: "
                           "no joint log is that long; split the recording")
        layers.append(what)
    return data, layers


def _log_text(raw: bytes, name: str) -> str:
    """A log's text: decompressed where its magic bytes say so, decoded as
    UTF-8 (a BOM dropped), UTF-16 with its BOM (a spreadsheet's "Unicode
    text"), else as Latin-1 where the bytes are text (a header written by
    an older tool); refused, saying what it is, where the bytes are no text."""
    data, layers = _decompressed(raw, name)
    inner = f" (decompressed: {', '.join(layers)})" if layers else ""
    if not data.strip():
        what = ("is empty (0 bytes)" if not raw else f"decompresses to nothing{inner}" if layers
                else "holds only blank lines")
        raise LogError(f"{name} {what}: give a joint log, a header and a row per sample "
                       "(see `pupper fit --help` for the format)")
    kind = next((v for k, v in NOT_CSV.items() if data.startswith(k)), None)
    if kind is not None:
        raise LogError(f"{name} is not a CSV text file{inner}: it is {kind}")
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            return data.decode("utf-16")
        except UnicodeDecodeError:
            pass
    try:
        # a BOM (some editors and spreadsheets write one) is not part of the text
        return data.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError as e:
        at = e.start
    head = data[:65536]
    control = sum(1 for b in head if b < 32 and b not in b"\t\n\r\f")
    if b"\x00" in head or control > len(head) // 100:
        raise LogError(f"{name} is not a CSV text file{inner} (it is binary: byte {data[at]:#04x} at offset {at} "
                       "is no text): give a joint log (see `pupper fit --help` for the format)")
    # every byte is a Latin-1 character: a header in an older encoding reads as written
    return data.decode("latin-1")


def _content_digest(times: np.ndarray, actuators: Sequence[str], arrays: Sequence[np.ndarray | None]) -> str:
    """The hash of a log's samples as read (every number, in pupper's units
    and the model's names): what makes two files one recording."""
    h = hashlib.sha256()
    h.update("\0".join(actuators).encode())
    for a in (times, *arrays):
        h.update(b"-" if a is None else np.ascontiguousarray(a, dtype="<f8").tobytes())
    return h.hexdigest()


def read_log(path: str | Path, ranges: Mapping[str, tuple[float, float] | None], *,
             columns: ColumnMap | None = None, defaults: Mapping[str, str | None] | None = None,
             stated: Mapping[str, Sequence[tuple[str, str]]] | None = None, advice: str = "") -> JointLog:
    """Reads and checks one log against a model's actuators (``ranges``:
    each actuator's joint range, None where unlimited). ``columns``: a
    column map over the log's own (``# columns:``); ``stated``: header
    keys (kp, kd, held) the caller states for this log, each as (value,
    where it was said); ``defaults``: values given as ``--KEY``. Every
    source of a key, the log's own line or columns included, must agree;
    ``advice`` ends the refusal of a log whose gains nobody states. A log
    may be plain or compressed (gzip, bzip2, xz: told by its bytes, not
    its suffix)."""
    p = Path(path)
    name = str(p)
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise LogError(f"{name}: cannot read the log ({e.strerror}): check the path") from None
    text = _log_text(raw, name)
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
    # how each key was said, for the messages: a header line by default
    said = {k: f"'# {k}: {meta[k]}'" for k in line_of if k in meta}
    acts = list(columns_of)
    for key in ("kp", "kd"):
        if key in columns_of[acts[0]]:
            meta[key], where[key] = _gain_columns(data, header, keys, acts, key, meta.get(key), name)
            where[key], said[key] = name, f"the {key} columns ({meta[key]})"
    sources = {k: list(v) for k, v in (stated or {}).items()}
    for key, v in (defaults or {}).items():
        if v is not None:
            sources.setdefault(key, []).append((str(v), f"--{key} {v}"))
    for key, given in sources.items():
        if given and key not in meta:
            (meta[key], said[key]), where[key] = given[0], name
            given = given[1:]
        for v, w in given:
            _agree(key, (meta[key], where[key], said[key]), (v, w), len(acts), ranges, acts)
    for key in ("kp", "kd"):
        if key not in meta:
            raise LogError(f"{name}: no '# {key}:' line and no {key} given for it: " + (
                advice or f"write e.g. '# kp: 5' and '# kd: 0.1' above the header, or give --{key}"))
    mode = meta.get("mode", "servo")
    base = meta.get("base", "suspended")
    if mode not in MODES:
        raise LogError(f"{name}: '# mode: {mode}' is not one of {', '.join(MODES)}")
    if base not in BASES:
        raise LogError(f"{name}: '# base: {base}' is not one of {', '.join(BASES)}")

    def take(fld: str) -> np.ndarray:
        return np.stack([data[f"{a}.{fld}"] for a in acts], axis=1)

    target, q = take("target"), take("q")
    qd = take("qd") if "qd" in columns_of[acts[0]] else None
    tau = take("tau") if "tau" in columns_of[acts[0]] else None

    def line_of_row(r: int) -> int:
        return body_start + 2 + r

    _not_degrees(name, acts, ranges, target, q, cmap, line_of_row)
    _plausible(name, acts, {"qd": qd, "tau": tau}, cmap, line_of_row)
    return JointLog(
        path=p, times=data["time"], actuators=acts, target=target, q=q, qd=qd, tau=tau,
        kp=_gains(meta["kp"], len(acts), "kp", where["kp"], said.get("kp", "")),
        kd=_gains(meta["kd"], len(acts), "kd", where["kd"], said.get("kd", "")),
        mode=mode, base=base, sha256=hashlib.sha256(raw).hexdigest(),
        held=_held(meta["held"], ranges, acts, where["held"] if "held" in line_of else f"{name}: {said['held']}")
        if "held" in meta else {},
        digest=_content_digest(data["time"], acts, (target, q, qd, tau)))


def _agree(key: str, have: tuple[str, str, str], other: tuple[str, str], n: int,
           ranges: Mapping[str, tuple[float, float] | None], acts: list[str]) -> None:
    """Two sources of one header key (the log's own line or columns, a
    flag, the file's name) must say the same (``have``: the value, where
    and how it was said; ``other``: the value and how): a disagreement is
    refused, never settled silently (issue 49, item 10)."""
    (value, where, said), (value2, said2) = have, other
    name = where.split(", line ")[0]
    if key == "held":
        same = _held(value, ranges, acts, f"{where}: {said}") == _held(value2, ranges, acts, f"{name}: {said2}")
    else:
        a = _gains(value, n, key, where, said)
        b = _gains(value2, n, key, name, said2)
        same = bool(np.allclose(a, b, rtol=1e-9, atol=0.0))
    if not same:
        raise LogError(f"{where}: {said} and {said2} disagree: say the {key} it ran at once (drop one, or fix "
                       "the other)")


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
    for act, value in out.items():
        # a held angle past the joint's range is a typo or another unit, and the replay could not hold it
        for a in [act] if act else [a for a in ranges if a not in logged]:
            rng = ranges[a]
            if rng is not None and not rng[0] <= value <= rng[1]:
                raise LogError(f"{where}: the held angle {value:g} rad is outside {a}'s range [{rng[0]:.3g}, {rng[1]:.3g}] "
                               "rad: give the angle the joint held, in rad, inside its range")
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
                f"{cell} is not a finite number: drop or fill the sample" if inf
                else f"'{cell}' is not a number: fix or drop the row"))
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


def _plausible(name: str, acts: list[str], columns: Mapping[str, np.ndarray | None], cmap: ColumnMap,
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
