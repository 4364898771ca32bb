"""The example notebook runs top to bottom, so it cannot rot."""

from __future__ import annotations

import os
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOK = Path(__file__).resolve().parents[1] / "examples" / "quickstart.ipynb"


def test_quickstart_notebook_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    nb = nbformat.read(NOTEBOOK, as_version=4)
    # the kernel knows it is one (a progress bar draws there; a process that
    # merely imported ipykernel prints plain lines)
    nb.cells.append(nbformat.v4.new_code_cell(
        "from pupper_core._run.progress import in_notebook\nprint('in a notebook:', in_notebook())"))
    # for the kernel only: this process may have imported mujoco already
    monkeypatch.setenv("MUJOCO_GL", os.environ.get("MUJOCO_GL", "egl"))
    client = NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}})
    client.execute()
    outputs = [o for cell in nb.cells if cell.cell_type == "code" for o in cell.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    text = "".join(
        o.get("text", "") + str(o.get("data", {}).get("text/plain", "")) for o in outputs
    )
    assert "in a notebook: True" in text
    # the sweep ran and its best cell was shown
    assert "last_1s_std_mm" in text
    images = [o for o in outputs if "image/png" in o.get("data", {}) or "image/gif" in o.get("data", {})]
    assert images, "the notebook shows a heatmap"
