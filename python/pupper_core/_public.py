"""Where a public function or error is used from: help(), repr and pickle
name the module a user imports it from (``pupper_core``,
``pupper_core.plots``, ...), not the private module that holds its code."""

from __future__ import annotations

from typing import Callable, TypeVar

_T = TypeVar("_T")


def exported_from(module: str) -> Callable[[_T], _T]:
    """Marks a function or an exception class as ``module``'s own (it must
    re-export it under the same name)."""

    def mark(obj: _T) -> _T:
        obj.__module__ = module
        return obj

    return mark
