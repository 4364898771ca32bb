"""The sweep spec's keywords on the Python side: their defaults (held by the
Rust core), the signature help() shows for a wrapper taking ``**options``,
and a call's keywords turned into the plain values the core takes."""

from __future__ import annotations

import functools
import inspect
import os
from typing import Any, Callable, Literal, Mapping, TypeVar, cast

from pupper_core import _native
from pupper_core._native import ConfigError

#: Metric columns of summary.csv, in order (defined once, in the Rust core).
METRICS: tuple[str, ...] = tuple(_native.METRICS)

#: The metric a standing run ranks by unless told, and its replicated form
#: (the Rust core's).
DEFAULT_METRIC: str = _native.DEFAULT_METRIC
ROBUST_METRIC: str = f"p95:{DEFAULT_METRIC}"

#: Below this an overshoot (%) is the integrator's rounding, not a robot's:
#: tables and figures show it as 0 (summary.csv keeps every digit; the
#: CLI's table says the same, print/response.rs).
OVERSHOOT_NOISE_PCT: float = 1e-6

#: Defaults of every sweep keyword, as the Rust core's SweepSpec holds them
#: (the CLI's --help shows the same ones; tests/test_spec.py checks).
DEFAULTS: dict[str, Any] = _native.sweep_defaults()

#: Each experiment kind's own keywords and their defaults, by its key in
#: the Rust core's registry (the structs the CLI's flags default to):
#: what `pupper_core.response`, `hold` and `walk` take when a keyword is
#: left out. A list reads as a tuple (a default shared between calls).
KIND_DEFAULTS: dict[str, dict[str, Any]] = {
    kind: {name: tuple(v) if isinstance(v, list) else v for name, v in own.items()}
    for kind, own in _native.kind_defaults().items()
}

Mode = Literal["servo", "torque"]
Variant = Literal["original", "long-leg", "heavy"]


_F = TypeVar("_F", bound=Callable[..., Any])


def with_spec_signature(options: type, *, after: str) -> Callable[[_F], _F]:
    """Gives a wrapper taking `**options` the full signature notebooks and
    help() show: each keyword of the TypedDict `options` (names and types
    written once, in _types.py) with its default from the Rust spec
    (DEFAULTS), placed after the parameter `after`."""

    def wrap(fn: _F) -> _F:
        sig = inspect.signature(fn)
        head = [p for p in sig.parameters.values() if p.kind is not p.VAR_KEYWORD]
        at = [p.name for p in head].index(after) + 1
        spec = [
            inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY,
                              # a list default would read as a shared mutable one
                              default=tuple(DEFAULTS[name]) if isinstance(DEFAULTS[name], list) else DEFAULTS[name],
                              annotation=getattr(kind, "__forward_arg__", kind))
            for name, kind in options.__annotations__.items()
            if name not in sig.parameters
        ]
        fn.__signature__ = sig.replace(parameters=head[:at] + spec + head[at:])  # type: ignore[attr-defined]
        known = set(options.__annotations__) | set(sig.parameters)

        @functools.wraps(fn)
        def checked(*args: Any, **kwargs: Any) -> Any:
            unknown = sorted(set(kwargs) - known)
            if unknown:
                raise TypeError(
                    f"{fn.__name__}() got an unexpected keyword argument {unknown[0]!r}; "
                    f"it takes {', '.join(p for p in fn.__signature__.parameters)}"  # type: ignore[attr-defined]
                )
            return fn(*args, **kwargs)

        # the wrapper keeps the function's declared types for type checkers
        return cast(_F, checked)

    return wrap


def sweep_options(arguments: Mapping[str, Any]) -> dict[str, Any]:
    """The spec's keyword arguments among a call's `locals()`, as plain
    values: paths as text, sequences as lists of floats."""
    out: dict[str, Any] = {}
    for name, value in arguments.items():
        if name not in DEFAULTS or name == "out":
            continue
        if name == "model":
            value = os.fspath(value)
        elif name == "sine" and isinstance(value, str):
            value = parse_sine(value)
        elif name in ("pose", "sine") and value is not None and not isinstance(value, str):
            value = [float(x) for x in value]
        out[name] = value
    return out


def parse_sine(text: str) -> list[float]:
    """`"2,1.2"`, as the CLI's --sine takes it: amplitude (N), frequency (Hz)."""
    try:
        return [float(x) for x in text.split(",")]
    except ValueError:
        raise ConfigError(f"sine={text!r} is not 'AMPLITUDE,FREQUENCY': give two numbers, "
                          "e.g. sine='2,1.2' or sine=(2, 1.2)") from None

#: The frequencies (Hz) at which a response's phase is reported.
PHASE_AT = (2.0, 5.0, 10.0)
