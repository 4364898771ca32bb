"""`report.html`: one self-contained page per run directory, readable in any
browser with no network (no script, font or picture from elsewhere). Plots
are inline SVG drawn here from the files beside it, so the page weighs a
few tens of kB and needs no charting library; the only script is a few
lines that sort the table by a clicked column.

Built from what the run directory holds (manifest.json, summary.csv and the
experiment kind's own tables), never by stepping physics.
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any

from pupper_core._report import fit, lab, recommend, response, sweep, tune, walk
from pupper_core._report import page as kit
from pupper_core._report.page import SCRIPT, STYLE, Page, Sections, inputs_html, read_table

__all__ = ["report"]

#: The registry: each kind's sections, in a module of its own.
SECTIONS: dict[str, Sections] = {
    "sweep": sweep.sections,
    "lab": lab.sections,
    "response": response.sections,
    "hold": sweep.sections,
    "walk": walk.sections,
    "tune": tune.sections,
    "fit": fit.sections,
    "recommend": recommend.sections,
}


def kind_of(manifest: dict[str, Any]) -> str:
    """The kind a run's manifest names, one of the registry's."""
    return kit.kind_of(manifest, SECTIONS)


def report(run_dir: str | os.PathLike[str]) -> Path:
    """Writes ``run_dir/report.html`` from the files in it; returns its path."""
    from pupper_core._rundir import atomic_write

    d = Path(run_dir)
    from pupper_core import _native

    if not (d / "manifest.json").is_file():
        raise _native.OutputError(f"{d} holds no pupper run (no manifest.json): give a run directory")
    manifest = _native.read_manifest(os.fspath(d))
    kind = kind_of(manifest)
    warnings: list[str] = []
    answer: list[str] = []
    header, rows = read_table(d / "summary.csv")
    parts = SECTIONS[kind](Page(d, manifest, kind, header, rows, warnings, answer))
    files = sorted(p.relative_to(d).as_posix() for p in d.rglob("*")
                   if p.is_file() and not p.name.startswith(".") and p.name != "report.html")
    links = "".join(f'<li><a href="{html.escape(f)}">{html.escape(f)}</a></li>' for f in files)
    warn_html = "".join(f'<div class="warn">{html.escape(w)}</div>' for w in warnings) or "<p>None.</p>"
    # the page opens with the run's answer and the warnings that qualify it
    top = (f'<section id="answer"><h2>Answer</h2>{"".join(answer)}<h3>Warnings</h3>{warn_html}</section>'
           if answer else f"<h2>Warnings</h2>{warn_html}")
    page = (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            f"<title>pupper {kind}: {html.escape(d.name)}</title><style>{STYLE}</style></head><body>"
            f"<h1>pupper {kind}: {html.escape(d.name)}</h1>{top}"
            + "".join(parts)
            + f"<h2>Inputs (manifest.json)</h2>{inputs_html(manifest, kind)}"
            f"<h2>Files</h2><ul>{links}</ul>"
            f"<script>{SCRIPT}</script></body></html>\n")
    out = d / "report.html"
    # a name that is not UTF-8 shows as U+FFFD in the page
    atomic_write(out, lambda tmp: tmp.write_bytes(page.encode("utf-8", "replace")))
    return out

def _cli_hex(run_dir: str) -> list[str]:
    """The CLI's call: the directory's path as the hex of its bytes (the CLI
    says the page's path itself)."""
    report(os.fsdecode(bytes.fromhex(run_dir)))
    return []
