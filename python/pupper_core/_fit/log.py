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
or as recorded, without holes), ``.target`` (the commanded angle) and
``.q`` (the measured angle) in rad, ``.qd`` in rad/s, ``.tau`` in N·m; a
column map (``# columns:`` or the caller's, ``pupper_core._fit.columns``)
reads the robot's own column names and units instead, and a Pupper v3's
real2sim bench log is read with a built-in one. Each logged actuator needs
``.target`` and ``.q``; ``.qd`` and ``.tau`` are optional (most servos
report no torque). A log may cover any subset of the actuators (``held``:
the angles the others hold). ``kp``/``kd`` are the gains in use (N·m/rad,
N·m·s/rad): one number for every actuator, or one per logged actuator in
column order; the caller may give them for a log that does not say them.
``mode`` is who ran the PD (``servo``: the motor's firmware, ``torque``:
the host); ``base`` is ``suspended`` (the robot hung, its feet off the
ground) or ``standing``.

A log is read as it streams (through its compression), row by row: one
past the rows or the seconds a fit takes is refused at the row that
passes them, before the rest is read.
"""

from __future__ import annotations

import bz2
import contextlib
import csv
import gzip
import hashlib
import itertools
import lzma
import math
import zlib
from array import array
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from time import monotonic
from typing import IO, Protocol, cast

import numpy as np

from pupper_core._fit.columns import (FIELDS, ColumnMap, LogError, blank_row, builtin_map, builtin_note,
                                      logged_columns, not_degrees, parse_map, plausible, resolve, same_motor,
                                      with_motor)
from pupper_core._fit.specs import (KD_MAX, KP_MAX, check_gains, finite, gain_columns, gains, held_angles, settle,
                                    sources)
from pupper_core._fit.terms import MAX_LOG_SECONDS
from pupper_core._rundir import say

__all__ = ["JointLog", "LogError", "read_log", "write_log", "check_gains", "FIELDS", "KP_MAX", "KD_MAX"]

MAGIC = "# pupper joint log 1"
MODES = ("servo", "torque")
BASES = ("suspended", "standing")
#: Header keys that say how the log was run: each may appear once.
SINGLE_KEYS = ("kp", "kd", "mode", "base", "columns", "held")
#: The most rows a log may have: 600 s at 1.7 kHz. Past it the fit's
#: Jacobians (a row per sample, a column per parameter) outgrow a
#: machine's memory; reading it alone took 13-30 s and 1.3 GB (issue 61).
MAX_ROWS = 1_000_000
#: A time step this many times the log's median spacing, and at least
#: GAP_SECONDS, is a hole in the recording (a logger that stopped), not
#: jitter: a real Pupper's loop logs 4 ms +- 1.9 ms, at most 10 ms apart.
GAP_PERIODS = 20.0
GAP_SECONDS = 0.1
#: A read still going after this long (s) says so, once, on stderr.
SLOW_READ_S = 2.0


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


def _meta(lines: Iterator[str], name: str) -> tuple[dict[str, str], dict[str, int], int, str | None]:
    """The ``# key: value`` lines above the header, the line number of each
    key, the header's index and the header line (None: there is none). A
    key that says how the log was run may not appear twice."""
    meta: dict[str, str] = {}
    seen: dict[str, int] = {}
    count = 0
    for i, line in enumerate(lines):
        if not line.startswith("#"):
            return meta, seen, i, line
        count = i + 1
        if ":" in line:
            k, v = line[1:].split(":", 1)
            key = k.strip().lower()
            if key in SINGLE_KEYS and key in seen:
                raise LogError(f"{name}, line {i + 1}: '# {key}:' appears twice (lines {seen[key]} "
                               f"and {i + 1}): keep the one in use")
            seen.setdefault(key, i + 1)
            meta[key] = v.strip()
    return meta, seen, count, None


class _Stream(Protocol):
    def read(self, n: int = ..., /) -> bytes: ...
    def peek(self, n: int, /) -> bytes: ...
    def close(self) -> None: ...


#: Compressions a log is read through, told by their magic bytes (whatever
#: the file's suffix): the name said, and the reader.
COMPRESSED: dict[bytes, tuple[str, Callable[[_Stream], _Stream]]] = {
    b"\x1f\x8b": ("gzip", lambda f: gzip.GzipFile(fileobj=cast(IO[bytes], f), mode="rb")),
    b"BZh": ("bzip2", lambda f: bz2.BZ2File(cast(IO[bytes], f))),
    b"\xfd7zXZ\x00": ("xz", lambda f: lzma.LZMAFile(cast(IO[bytes], f))),
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
#: What is read of a log at a time (bytes), and how much of its start tells text from binary.
CHUNK = 2**20
HEAD = 65536


#: What reading a damaged compressed stream raises.
BROKEN = (OSError, EOFError, zlib.error, lzma.LZMAError)


def _broken(e: BaseException, name: str, layers: list[str]) -> LogError:
    """A log whose bytes cannot be read (``layers``: the compressions
    read through), in one line."""
    if not layers:
        return LogError(f"{name}: cannot read the log ({getattr(e, 'strerror', None) or e}): check the path")
    return LogError(f"{name} is {layers[-1]}-compressed but does not decompress ({e}): the file is truncated "
                    "or damaged; copy it from the robot again")


def _read(stream: _Stream, n: int, name: str, layers: list[str]) -> bytes:
    """Up to ``n`` bytes of the (decompressed) log."""
    try:
        return stream.read(n)
    except BROKEN as e:
        raise _broken(e, name, layers) from None


def _open(p: Path, name: str, stack: contextlib.ExitStack) -> tuple[_Stream, list[str]]:
    """The log's bytes as a stream, through any compression its magic bytes
    say (layers of it), and the compressions passed."""
    try:
        stream: _Stream = stack.enter_context(p.open("rb"))
    except OSError as e:
        raise LogError(f"{name}: cannot read the log ({e.strerror}): check the path") from None
    layers: list[str] = []
    while True:
        try:
            start = stream.peek(8)[:8]
        except BROKEN as e:
            raise _broken(e, name, layers) from None
        kind = next((v for k, v in COMPRESSED.items() if start.startswith(k)), None)
        if kind is None:
            return stream, layers
        what, opener = kind
        if len(layers) == MAX_LAYERS:
            raise LogError(f"{name} is compressed more than {MAX_LAYERS} times over ({', '.join(layers)}, "
                           f"{what}): decompress it and give the CSV")
        stream = opener(stream)
        stack.callback(stream.close)
        layers.append(what)


def _chunks(p: Path, name: str) -> Iterator[tuple[bytes, list[str]]]:
    """The log's decompressed bytes, a chunk at a time (with the
    compressions passed); refused past MAX_TEXT_BYTES (a bomb)."""
    with contextlib.ExitStack() as stack:
        stream, layers = _open(p, name, stack)
        total = 0
        while chunk := _read(stream, CHUNK, name, layers):
            total += len(chunk)
            if layers and total > MAX_TEXT_BYTES:
                raise LogError(f"{name} is {layers[-1]}-compressed and decompresses past "
                               f"{MAX_TEXT_BYTES // 2**30} GiB: no joint log is that long; split the recording")
            yield chunk, layers
        yield b"", layers


def _binary(head: bytes) -> bool:
    control = sum(1 for b in head if b < 32 and b not in b"\t\n\r\f")
    return b"\x00" in head or control > len(head) // 100


def _text_lines(p: Path, name: str) -> Iterator[str]:
    """A log's lines as text, as they are read: decompressed where its
    magic bytes say so, decoded as UTF-8 (a BOM dropped), UTF-16 with its
    BOM (a spreadsheet's "Unicode text"), else a line at a time as Latin-1
    where the bytes are text (a header written by an older tool); refused,
    saying what it is, where the bytes are no text."""
    chunks = _chunks(p, name)
    first, layers = next(chunks)
    inner = f" (decompressed: {', '.join(layers)})" if layers else ""
    while not first.strip():
        more = next(chunks, (b"", layers))[0]
        if not more:
            what = ("is empty (0 bytes)" if not first and not layers else f"decompresses to nothing{inner}"
                    if layers else "holds only blank lines")
            raise LogError(f"{name} {what}: give a joint log, a header and a row per sample "
                           "(see `pupper fit --help` for the format)")
        first += more
    kind = next((v for k, v in NOT_CSV.items() if first.startswith(k)), None)
    if kind is not None:
        raise LogError(f"{name} is not a CSV text file{inner}: it is {kind}")
    rest: Iterable[bytes] = (c for c, _ in chunks)
    if first.startswith((b"\xff\xfe", b"\xfe\xff")):
        data = first + b"".join(rest)
        try:
            yield from data.decode("utf-16").splitlines()
            return
        except UnicodeDecodeError:
            first, rest = data, ()
    head = first[:HEAD]
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as e:
        cut = e.reason == "unexpected end of data" and len(head) == HEAD
        if not cut and _binary(head):
            # no text from its start: said before any line is read as one
            raise LogError(f"{name} is not a CSV text file{inner} (it is binary: byte {head[e.start]:#04x} at "
                           f"offset {e.start} is no text): give a joint log (see `pupper fit --help` for the "
                           "format)") from None
    yield from _decoded(itertools.chain([first], rest), head, name, inner)


def _decoded(chunks: Iterable[bytes], head: bytes, name: str, inner: str) -> Iterator[str]:
    """The lines of ``chunks`` (split as str.splitlines splits them: CRLF
    is one line end), each decoded as UTF-8, else (where the start is
    text) as Latin-1: every byte is a Latin-1 character."""
    offset, rest = 0, b""

    def text(raw: bytes) -> list[str]:
        try:
            out = raw.decode("utf-8")
        except UnicodeDecodeError as e:
            if _binary(head):
                raise LogError(f"{name} is not a CSV text file{inner} (it is binary: byte {raw[e.start]:#04x} at "
                               f"offset {offset + e.start} is no text): give a joint log (see `pupper fit --help` "
                               "for the format)") from None
            out = raw.decode("latin-1")
        # a BOM (some editors and spreadsheets write one) is not part of the text
        return (out.removeprefix("\ufeff") if offset == 0 else out).splitlines() or [""]

    for chunk in chunks:
        lines = (rest + chunk).split(b"\n")
        rest = lines.pop()
        for raw in lines:
            yield from text(raw)
            offset += len(raw) + 1
    if rest:
        yield from text(rest)


def _content_digest(times: np.ndarray, actuators: Sequence[str], arrays: Sequence[np.ndarray | None]) -> str:
    """The hash of a log's samples as read (every number, in pupper's units
    and the model's names): what makes two files one recording."""
    h = hashlib.sha256()
    h.update("\0".join(actuators).encode())
    for a in (times, *arrays):
        h.update(b"-" if a is None else np.ascontiguousarray(a, dtype="<f8").tobytes())
    return h.hexdigest()


def _sha256(p: Path) -> str:
    h = hashlib.sha256()
    with p.open("rb") as f:
        while chunk := f.read(CHUNK):
            h.update(chunk)
    return h.hexdigest()


#: The kinds of note said so far (once a process each, as Python's warnings are: a fit of many logs in one
#: format says it once).
_SAID: set[str] = set()


def _note_once(kind: str, note: str) -> None:
    if kind not in _SAID:
        _SAID.add(kind)
        say(f"note: {note}")


def read_log(path: str | Path, ranges: Mapping[str, tuple[float, float] | None], *,
             columns: ColumnMap | None = None, defaults: Mapping[str, str | None] | None = None,
             stated: Mapping[str, Sequence[tuple[str, str]]] | None = None, advice: str = "") -> JointLog:
    """Reads and checks one log against a model's actuators (``ranges``:
    each actuator's joint range, None where unlimited, in the model's
    order: a motor column's index counts in it). ``columns``: a column map
    over the log's own (``# columns:``); ``stated``: header keys (kp, kd,
    held) the caller states for this log, each as (value, where it was
    said); ``defaults``: values given as ``--KEY``. Every source of a key,
    the log's own line or columns included, must agree; ``advice`` ends
    the refusal of a log whose gains nobody states. A log may be plain or
    compressed (gzip, bzip2, xz: told by its bytes, not its suffix)."""
    p = Path(path)
    name = str(p)
    lines = _text_lines(p, name)
    meta, line_of, body_start, head = _meta(lines, name)
    cmap = (parse_map(meta["columns"], f"{name}, line {line_of['columns']}") if "columns" in meta
            else ColumnMap())
    cmap = cmap.merged(columns) if columns else cmap
    header = [h.strip() for h in next(csv.reader([head]), [])] if head is not None else []
    acts = list(ranges)
    if not cmap and (built := builtin_map(header)) is not None:
        cmap = built
        _note_once("pupper_v3", builtin_note(p.name))
    keys = resolve(header, cmap, acts, name)
    if "time" not in keys:
        first = header[0][:30] if header else "nothing"
        raise LogError(f"{name} is not a pupper joint log: its header (line {body_start + 1}) starts with "
                       f"'{first}' and has no 'time' column: name the time column 'time', or map it "
                       "(--columns time=COLUMN; see `pupper fit --help` for the format)")
    rows, cmap, keys, motor = with_motor(csv.reader(lines), header, cmap, keys, acts, body_start, name)
    columns_of = logged_columns(keys, ranges, name)
    data = _numbers(rows, header, keys, body_start, name, cmap.scale.get("time", 1.0), motor, acts)
    for k, f in cmap.scale.items():
        if k in data:
            data[k] = data[k] * f
    return _log(p, meta, line_of, cmap, data, header, keys, columns_of, ranges, sources(stated, defaults), advice,
                body_start)


def _log(p: Path, meta: dict[str, str], line_of: dict[str, int], cmap: ColumnMap, data: dict[str, np.ndarray],
         header: list[str], keys: list[str | None], columns_of: dict[str, dict[str, int]],
         ranges: Mapping[str, tuple[float, float] | None], given_by: Mapping[str, Sequence[tuple[str, str]]],
         advice: str, body_start: int) -> JointLog:
    """The log from its samples (in pupper's units) and header lines: its
    gains settled with every other source of them, its angles checked."""
    name = str(p)
    where = {k: f"{name}, line {n}" for k, n in line_of.items()}
    # how each key was said, for the messages: a header line by default
    said = {k: f"'# {k}: {meta[k]}'" for k in line_of if k in meta}
    acts = list(columns_of)
    for key in ("kp", "kd"):
        if key in columns_of[acts[0]]:
            meta[key], where[key] = gain_columns(data, header, keys, acts, key, meta.get(key), name)
            where[key], said[key] = name, f"the {key} columns ({meta[key]})"
    settle(meta, where, said, given_by, name, acts, ranges, advice)
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

    not_degrees(name, acts, ranges, target, q, cmap, line_of_row)
    plausible(name, acts, {"qd": qd, "tau": tau}, cmap, line_of_row)
    return JointLog(
        path=p, times=data["time"], actuators=acts, target=target, q=q, qd=qd, tau=tau,
        kp=gains(meta["kp"], len(acts), "kp", where["kp"], said.get("kp", "")),
        kd=gains(meta["kd"], len(acts), "kd", where["kd"], said.get("kd", "")),
        mode=mode, base=base, sha256=_sha256(p),
        held=held_angles(meta["held"], ranges, acts, where["held"] if "held" in line_of
                         else f"{name}: {said['held']}") if "held" in meta else {},
        digest=_content_digest(data["time"], acts, (target, q, qd, tau)))


def _cells(row: list[str], used: list[int], header: list[str], name: str, line_no: int) -> None:
    """Refuses the row's first cell that is no finite number (the row's
    sum was none: a cell is, or the sum overflowed)."""
    for j in used:
        cell = row[j]
        finite(cell, lambda inf: f"{name}, column '{header[j]}', row {line_no}: " + (
            f"{cell} is not a finite number: drop or fill the sample" if inf
            else f"'{cell}' is not a number: fix or drop the row"))


def _numbers(rows: Iterator[list[str]], header: list[str], keys: list[str | None], body_start: int, name: str,
             time_scale: float, motor: tuple[int, str, str] | None, acts: list[str]) -> dict[str, np.ndarray]:
    """The samples of the columns read (by pupper's name), every one a
    finite number, as they stream: refused at the row past MAX_ROWS or
    past MAX_LOG_SECONDS after the first; times strictly increasing, with
    no hole. A long read says so once."""
    used = [j for j, k in enumerate(keys) if k is not None]
    ti = used.index(keys.index("time"))
    col_t = header[used[ti]]
    values: array[float] = array("d")
    started, said = monotonic(), False
    blank: tuple[int, int] | None = None
    n, t0 = 0, 0.0
    for r, row in enumerate(rows):
        line_no = body_start + 2 + r
        if blank_row(row):
            # a blank line at the end is an editor's; one before a row is a missing sample
            blank = blank or (line_no, len(row))
            continue
        if blank is not None or len(row) != len(header):
            at, width = blank or (line_no, len(row))
            raise LogError(f"{name}, row {at}: {width} fields, the header has {len(header)}: fix or drop the row")
        try:
            cells = [float(row[j]) for j in used]
        except ValueError:
            cells = []
        if not cells or not math.isfinite(sum(cells)):
            _cells(row, used, header, name, line_no)
        if motor is not None and row[motor[0]] != motor[1]:
            same_motor(row[motor[0]], motor, acts, f"{name}, column '{header[motor[0]]}', row {line_no}")
        t = cells[ti] * time_scale
        if n == 0:
            t0 = t
        elif t - t0 > MAX_LOG_SECONDS:
            raise _too_long(name, col_t, line_no, t - t0, n)
        if n == MAX_ROWS:
            raise LogError(f"{name}, row {line_no}: more than {MAX_ROWS:,} rows, past what fit takes (its "
                           "Jacobians would outgrow the memory): split the log, or keep every k-th row (a servo's "
                           "motion needs 250 to 1000 rows a second)")
        values.extend(cells)
        n += 1
        if not said and n % 65536 == 0 and monotonic() - started > SLOW_READ_S:
            say(f"note: reading {name}: {n:,} rows in {monotonic() - started:.0f} s so far (fit takes at most "
                f"{MAX_ROWS:,} rows and {MAX_LOG_SECONDS:g} s)")
            said = True
    if n < 2:
        raise LogError(f"{name}: {n} samples: a log needs many (e.g. 10 s at 500 Hz)")
    data = np.frombuffer(values, dtype=float).reshape(n, len(used))
    out = {str(keys[j]): data[:, c] for c, j in enumerate(used)}
    _times(out["time"], time_scale, name, col_t, body_start)
    return out


def _too_long(name: str, col: str, line_no: int, span: float, n: int) -> LogError:
    spacing = span / n
    # samples a second or more apart, which in ms would be a servo's rate
    ms = (f" (its samples are {spacing:g} apart: the time column looks like milliseconds; divide it by 1000, or "
          "map it time=COLUMN:ms)") if 1e-4 <= spacing / 1000 <= 0.1 and spacing >= 0.5 else ""
    return LogError(f"{name}, column '{col}', row {line_no}: the log runs past the {MAX_LOG_SECONDS:g} s fit takes "
                    f"({span:.6g} s after its first row){ms}: times are in s; split a longer recording")


def _times(t: np.ndarray, scale: float, name: str, col: str, body_start: int) -> None:
    """Times increase strictly (as written: the error shows the column's
    own numbers), and hold no hole: a step of GAP_PERIODS median spacings
    and GAP_SECONDS or more is a recording that stopped and went on."""
    steps = np.diff(t)
    if (bad := np.flatnonzero(steps <= 0)).size:
        r = int(bad[0]) + 1
        word = "repeats" if steps[r - 1] == 0 else "goes back"
        raise LogError(f"{name}, column '{col}', row {body_start + 2 + r}: time {word} "
                       f"({float(t[r])!r} after {float(t[r - 1])!r}): times must increase strictly")
    seconds = steps * scale
    median = float(np.median(seconds))
    if (bad := np.flatnonzero(seconds > max(GAP_PERIODS * median, GAP_SECONDS))).size:
        r = int(bad[0]) + 1
        gap = float(seconds[r - 1])
        raise LogError(f"{name}, column '{col}', row {body_start + 2 + r}: the time jumps by {gap:.4g} s "
                       f"({float(t[r - 1])!r} to {float(t[r])!r}), {gap / median:.0f} times the log's median "
                       f"spacing ({median * 1e3:.3g} ms): a hole in the recording, which the replay would fill by "
                       f"holding a target; split the log at row {body_start + 2 + r} and give both parts")


def _number(v: float) -> str:
    return repr(float(v))


def write_log(path: str | Path, times: np.ndarray, actuators: Sequence[str], *,
              target: np.ndarray, q: np.ndarray, qd: np.ndarray | None = None,
              tau: np.ndarray | None = None, kp: Sequence[float] | np.ndarray, kd: Sequence[float] | np.ndarray,
              mode: str = "servo", base: str = "suspended", note: str = "") -> None:
    """Writes a log in the format above (every digit of each float)."""
    from pupper_core._rundir import atomic_write

    fields = [("target", target), ("q", q)] + [(f, a) for f, a in (("qd", qd), ("tau", tau))
                                               if a is not None]

    def gains_text(v: Sequence[float] | np.ndarray) -> str:
        values = [float(x) for x in v]
        return _number(values[0]) if len(set(values)) == 1 else ",".join(map(_number, values))

    def write(tmp: Path) -> None:
        with tmp.open("w", newline="") as f:
            f.write(f"{MAGIC}\n")
            if note:
                f.write(f"# note: {note}\n")
            f.write(f"# mode: {mode}\n# base: {base}\n# kp: {gains_text(kp)}\n# kd: {gains_text(kd)}\n")
            f.write("# units: time s; target, q rad; qd rad/s; tau N·m\n")
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["time"] + [f"{a}.{fld}" for a in actuators for fld, _ in fields])
            for i, t in enumerate(times):
                w.writerow([_number(t)] + [_number(arr[i, k]) for k in range(len(actuators))
                                           for _, arr in fields])

    atomic_write(Path(path), write)
