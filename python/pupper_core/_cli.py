"""The wheel's ``pupper`` command: the Rust CLI, run inside this interpreter.

The ``pupper`` binary built from a checkout embeds CPython; this entry point
runs the same Rust code (``pupper_core._native.cli_main``) in the Python that
``pip`` installed ``pupper_core`` into, so one install gives both the command
and ``import pupper_core``.
"""

from __future__ import annotations

import sys


def main() -> None:
    from pupper_core import _native

    sys.exit(_native.cli_main(sys.argv))


if __name__ == "__main__":
    main()
