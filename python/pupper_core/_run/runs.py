"""What every run directory has: report.html written when a run ends; runs
merged; a run read back."""

from __future__ import annotations

import os
from typing import Sequence

from pupper_core import _native
from pupper_core._native import SweepResult
from pupper_core._types import exported_from


def with_report(res: SweepResult) -> SweepResult:
    """Writes report.html into a finished run's directory."""
    if res.out is not None and res.complete:
        from pupper_core import _report

        _report.report(res.out)
    return res


@exported_from("pupper_core")
def report(run_dir: str | os.PathLike[str]) -> str:
    """Write ``run_dir/report.html`` (inputs, the table, plots, the best
    cells and the rule, warnings, links to the files beside it: one page,
    no network) from any run directory, as `pupper report DIR` does;
    returns its path. Every run with ``out`` writes one when it ends."""
    from pupper_core import _report

    return str(_report.report(run_dir))


@exported_from("pupper_core")
def merge(dirs: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str], *,
          force: bool = False) -> SweepResult:
    """Puts the shards of one sweep (each run with ``shard="I/N"``) together
    into the run directory `out`, as `pupper merge` does: its summary.csv is
    the unsharded sweep's. Refuses shards of different sweeps, a missing or
    repeated shard (saying which to rerun)."""
    if isinstance(dirs, (str, os.PathLike)):
        dirs = [dirs]  # one directory, never its characters
    return _native.merge([os.fspath(d) for d in dirs], os.fspath(out), force=force)


@exported_from("pupper_core")
def load_run(run_dir: str | os.PathLike[str]) -> SweepResult:
    """A SweepResult from a run directory written by `pupper sweep` or
    sweep(out=...); its rows are checked against its manifest's grid."""
    return _native.load_run(os.fspath(run_dir))
