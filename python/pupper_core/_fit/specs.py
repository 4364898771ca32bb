"""How logs are named to `pupper fit` (and `pupper_core.fit`), each with
what it was run at, so that logs as they come off a robot need no editing:

- a path (plain, or gzip-, bzip2- or xz-compressed: ``pupper_core._fit.log``
  tells by the bytes);
- ``LOG::kp=5,kd=0.25``: a log with options of its own, ``kp`` and ``kd``
  (the gains it ran at: one value, or one per logged actuator), ``held``
  (what the joints it does not cover held) and ``columns`` (its column
  map, or a map file), in place of ``--held``/``--columns`` for it;
- ``@FILE``: a list of such logs, one per line (``#`` starts a comment
  line; a relative path, the log's or its map file's, is read from the
  list's folder);
- the gains a file's name states, read by a pattern with ``{kp}`` and
  ``{kd}`` (``--gains-from-name 'kp_{kp}_kd_{kd}'`` reads 5 and 0.25 from
  ``..._kp_5_kd_0.25.csv.gz``).

Every source of a log's gains (its header line or columns, ``LOG::``, its
name, ``--kp``) must agree, or the log is refused (``settle``, as
``pupper_core._fit.log`` reads it); gains no servo runs at are refused
(``check_gains``)."""

from __future__ import annotations

import math
import numbers
import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pupper_core._fit.columns import LogError

__all__ = ["LogSpec", "log_specs", "name_pattern", "gains_in_name", "option_text", "path_list", "OPTIONS",
           "KP_MAX", "KD_MAX", "gains", "check_gains", "settle", "sources", "gain_columns", "held_angles", "finite"]

#: The options a log may carry (``LOG::KEY=VALUE,...``).
OPTIONS = ("kp", "kd", "held", "columns")
SEP = "::"
#: A number in a file name: 0.25, 5, 2.5e-1, and 0p25 (a name that avoids a second dot).
NUMBER = r"[-+]?\d+(?:[.p]\d+)?(?:[eE][-+]?\d+)?"
#: Where an option starts: after a comma or '::', a known key and '='.
_SPLIT = re.compile(r"(?:,|::)(?=\s*(?:" + "|".join(OPTIONS) + r")\s*=)")


@dataclass(frozen=True)
class LogSpec:
    """One log as named: its path, its own options (text, as the command
    line gives them), and how it was named (for messages)."""

    path: Path
    options: dict[str, str] = field(default_factory=dict)
    #: the log as the user named it (the path as given)
    given: str = ""
    #: the folder a relative map file is read from (a list file's); None: the working directory
    base: Path | None = None


def option_text(key: str, value: Any, where: str) -> str | None:
    """A log option's value (kp, kd, held, columns) as the command line
    writes it: a number (Python's or NumPy's), one per joint (a list or an
    array), a string, a path, or for held a mapping ACTUATOR -> RAD."""
    if value is None:
        return None
    if isinstance(value, (str, os.PathLike)):
        text = os.fspath(value)
        return text if isinstance(text, str) else os.fsdecode(text)
    if key == "held" and isinstance(value, Mapping):
        return ",".join(f"{a}={_number(v, key, where)!r}" for a, v in value.items())
    if key in ("kp", "kd", "held") and _is_number(value):
        return repr(_number(value, key, where))
    if key in ("kp", "kd") and hasattr(value, "__iter__"):
        values = list(value)
        if values and all(_is_number(v) for v in values):
            return ",".join(repr(_number(v, key, where)) for v in values)
    kinds = {"kp": "a number or one per logged joint (a list)", "kd": "a number or one per logged joint (a list)",
             "held": "an angle in rad, or a mapping ACTUATOR -> rad", "columns": "a map or a map file's path"}
    raise LogError(f"{where + ': ' if where else ''}{key}={value!r} is not {kinds[key]}: give e.g. "
                   + {"kp": "kp=5", "kd": "kd=0.1", "held": "held=0", "columns": "columns='time=stamp,...'"}[key])


def _is_number(v: Any) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def _number(v: Any, key: str, where: str) -> float:
    at = f"{where}: " if where else ""
    if not _is_number(v):
        raise LogError(f"{at}{key} {v!r} is not a number: give e.g. {key}=5")
    x = float(v)
    if not math.isfinite(x):
        raise LogError(f"{at}{key} {x} is not a finite number: give the value in use")
    return x


def path_list(value: Any, flag: str) -> list[Any]:
    """``logs`` or ``validate`` as a list: one path (a string names one
    log, never its characters), a list of them, or a mapping LOG -> its
    options."""
    if value is None:
        return []
    if isinstance(value, (str, bytes, os.PathLike)):
        return [value]
    if isinstance(value, Mapping):
        # each log with its own options: {"run.csv.gz": {"kp": 5, "kd": 0.25}}
        for log, own in value.items():
            if not isinstance(own, Mapping):
                raise TypeError(f"logs as a dict maps each log to its options ({{'kp': 5, 'kd': 0.25}}): "
                                f"{log!r}'s {own!r} is not a dict")
        return list(value.items())
    if isinstance(value, Sequence) or hasattr(value, "__iter__"):
        return list(value)
    raise LogError(f"{flag}={value!r} is not a log's path or a list of them: give e.g. {flag}=['run1.csv']")


def log_specs(items: Sequence[Any], flag: str) -> list[LogSpec]:
    """The logs named (``flag``: what to name in a message, LOG or
    --validate): paths, ``LOG::OPTIONS``, ``@FILE`` lists, and from Python
    (path, {option: value}) pairs."""
    out: list[LogSpec] = []
    for item in items:
        if isinstance(item, tuple) and len(item) == 2 and isinstance(item[1], Mapping):
            out.append(_from_mapping(item[0], item[1], flag))
            continue
        if isinstance(item, bytes):
            item = os.fsdecode(item)
        if not isinstance(item, (str, os.PathLike)):
            raise LogError(f"{flag} {item!r} is not a log's path: give the path of a joint log")
        text = os.fspath(item)
        if text.startswith("@") and not Path(text).is_file():
            out += _list_file(Path(text[1:]), flag)
        else:
            out.append(parse_spec(text, flag, None))
    return out


def _from_mapping(path: Any, options: Mapping[str, Any], flag: str) -> LogSpec:
    given = os.fspath(path)
    unknown = [k for k in options if k not in OPTIONS]
    if unknown:
        raise LogError(f"{flag} {given}: option '{unknown[0]}' is none of {', '.join(OPTIONS)}: give e.g. "
                       "{'kp': 5, 'kd': 0.25}")
    texts = {k: option_text(k, v, f"{flag} {given}") for k, v in options.items()}
    return LogSpec(Path(given), {k: v for k, v in texts.items() if v is not None}, given)


def parse_spec(text: str, flag: str, base: Path | None) -> LogSpec:
    """``LOG`` or ``LOG::KEY=VALUE,...`` (``base``: the folder relative
    paths are read from; None: the working directory). A file whose own
    name holds '::' is taken as a path."""
    if SEP not in text or Path(text).exists() or (base is not None and (base / text).exists()):
        return LogSpec(_under(base, text), {}, text, base)
    path, _, rest = text.partition(SEP)
    if not path.strip():
        raise LogError(f"{flag} '{text}' names no log before '::': write LOG::kp=5,kd=0.25")
    options: dict[str, str] = {}
    for item in _SPLIT.split(rest):
        key, eq, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or key not in OPTIONS:
            raise LogError(f"{flag} '{text}': '{item}' is not one of the log's options {', '.join(OPTIONS)} "
                           "as KEY=VALUE: write e.g. LOG::kp=5,kd=0.25")
        if not value:
            raise LogError(f"{flag} '{text}': {key}= has no value: write e.g. {key}=" + ("0" if key == "held" else
                                                                                     "time=stamp" if key == "columns"
                                                                                     else "5"))
        if key in options:
            raise LogError(f"{flag} '{text}': {key} is given twice: keep one")
        options[key] = value
    return LogSpec(_under(base, path), options, path, base)


def _under(base: Path | None, path: str) -> Path:
    p = Path(path)
    return p if base is None or p.is_absolute() else base / p


def _list_file(path: Path, flag: str) -> list[LogSpec]:
    """A list of logs, one ``LOG[::OPTIONS]`` per line."""
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise LogError(f"{flag} @{path}: cannot read the list of logs ({e.strerror}): check the path") from None
    try:
        text = raw.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError:
        raise LogError(f"{flag} @{path}: is not a text file: a list of logs is one LOG[::kp=K,kd=D] per "
                       "line") from None
    out = []
    for n, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("@"):
            raise LogError(f"@{path}, line {n}: '{line}' names another list: name the logs themselves")
        out.append(parse_spec(line, f"@{path}, line {n}:", path.parent))
    if not out:
        raise LogError(f"{flag} @{path} names no log: write one LOG[::kp=K,kd=D] per line")
    return out


def name_pattern(pattern: str) -> re.Pattern[str]:
    """``--gains-from-name``'s pattern as a regular expression: ``{kp}``
    and ``{kd}`` stand for numbers, the rest is matched as written,
    anywhere in a file's name."""
    parts = re.split(r"(\{[^{}]*\})", pattern)
    holes = [p for p in parts if p.startswith("{") and p.endswith("}")]
    bad = [h for h in holes if h not in ("{kp}", "{kd}")]
    if bad:
        raise LogError(f"--gains-from-name '{pattern}': {bad[0]} is neither {{kp}} nor {{kd}}: write e.g. "
                       "'kp_{kp}_kd_{kd}'")
    if not holes:
        raise LogError(f"--gains-from-name '{pattern}' has neither {{kp}} nor {{kd}}: write where the name holds "
                       "them, e.g. 'kp_{kp}_kd_{kd}'")
    if len(set(holes)) != len(holes):
        raise LogError(f"--gains-from-name '{pattern}' names {holes[0]} twice: keep one")
    return re.compile("".join(f"(?P<{p[1:-1]}>{NUMBER})" if p in holes else re.escape(p) for p in parts))


def gains_in_name(rx: re.Pattern[str], pattern: str, name: str) -> dict[str, str]:
    """The gains ``name`` states by the pattern (none where it does not
    match); a name the pattern reads two ways is refused."""
    found = {tuple(sorted(m.groupdict().items())) for m in rx.finditer(name)}
    if len(found) > 1:
        raise LogError(f"{name}: --gains-from-name '{pattern}' matches its name more than once, with other "
                       "numbers: write more of the name around the gains")
    if not found:
        return {}
    return {k: v.replace("p", ".") for k, v in next(iter(found))}


# -- what each source says of a log's gains and held angles, and that they agree ----------------------

#: The largest gains a log may say (N·m/rad, N·m·s/rad): past any servo. A
#: kp of 1e4 asks 10 N·m per mrad of error, three orders above Pupper's
#: 3 N·m limit at its usual kp 5; a larger number is in other units
#: (per degree, firmware counts) or a typo.
KP_MAX = 1e4
KD_MAX = 1e3


def gains(text: str, n: int, key: str, where: str, said: str = "") -> np.ndarray:
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


def sources(stated: Mapping[str, Sequence[tuple[str, str]]] | None,
            defaults: Mapping[str, str | None] | None) -> dict[str, list[tuple[str, str]]]:
    """Each header key's values said outside the log: the caller's, then --KEY's."""
    out = {k: list(v) for k, v in (stated or {}).items()}
    for key, v in (defaults or {}).items():
        if v is not None:
            out.setdefault(key, []).append((str(v), f"--{key} {v}"))
    return out


def settle(meta: dict[str, str], where: dict[str, str], said: dict[str, str],
           given_by: Mapping[str, Sequence[tuple[str, str]]], name: str, acts: list[str],
           ranges: Mapping[str, tuple[float, float] | None], advice: str) -> None:
    """Every source of a key agrees with the log's own (which it fills in
    where the log says nothing); gains nobody states are refused."""
    for key, given in given_by.items():
        if given and key not in meta:
            (meta[key], said[key]), where[key] = given[0], name
            given = given[1:]
        for v, w in given:
            _agree(key, (meta[key], where[key], said[key]), (v, w), len(acts), ranges, acts)
    for key in ("kp", "kd"):
        if key not in meta:
            raise LogError(f"{name}: no '# {key}:' line and no {key} given for it: " + (
                advice or f"write e.g. '# kp: 5' and '# kd: 0.1' above the header, or give --{key}"))


def _agree(key: str, have: tuple[str, str, str], other: tuple[str, str], n: int,
           ranges: Mapping[str, tuple[float, float] | None], acts: list[str]) -> None:
    """Two sources of one header key (the log's own line or columns, a
    flag, the file's name) must say the same (``have``: the value, where
    and how it was said; ``other``: the value and how): a disagreement is
    refused, never settled silently (issue 49, item 10)."""
    (value, where, said), (value2, said2) = have, other
    name = where.split(", line ")[0]
    if key == "held":
        same = (held_angles(value, ranges, acts, f"{where}: {said}")
                == held_angles(value2, ranges, acts, f"{name}: {said2}"))
    else:
        a = gains(value, n, key, where, said)
        b = gains(value2, n, key, name, said2)
        same = bool(np.allclose(a, b, rtol=1e-9, atol=0.0))
    if not same:
        raise LogError(f"{where}: {said} and {said2} disagree: say the {key} it ran at once (drop one, or fix "
                       "the other)")


def gain_columns(data: dict[str, np.ndarray], header: list[str], keys: list[str | None], acts: list[str],
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


def held_angles(text: str, ranges: Mapping[str, tuple[float, float] | None], logged: list[str],
                where: str) -> dict[str, float]:
    """``held``: one angle (rad) for every actuator the log does not cover,
    or ACTUATOR=RAD,... (the others at the model's rest pose)."""
    out: dict[str, float] = {}
    for item in (x.strip() for x in text.split(",") if x.strip()):
        act, eq, v = item.rpartition("=")
        act = act.strip() if eq else ""
        value = finite(v, lambda inf: f"{where}: held '{item}' is not a finite angle: give the angle in rad"
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


def finite(text: str, says: Callable[[bool], str]) -> float:
    """``text`` as a finite number, else a LogError: ``says(True)`` where it
    is a number but not finite, ``says(False)`` where it is none."""
    try:
        v = float(text)
    except ValueError:
        raise LogError(says(False)) from None
    if not math.isfinite(v):
        raise LogError(says(True))
    return v
