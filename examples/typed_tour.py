"""The README's Python tour as a typed script: `make test` runs mypy on it
(tests/test_types.py), so the stubs stay true to what a notebook writes."""

from __future__ import annotations

import numpy as np

import pupper_core as pc


def tour(out: str) -> float:
    info: pc.ModelInfo = pc.info("pupper_v3")
    assert info["nq"] == 19
    report: pc.StandReport = pc.stand(kp=5.0, kd=0.1, seconds=2.0)
    height: float = report["final_z"]
    res: pc.SweepResult = pc.sweep({"kp": [10, 30], "kd": 1.0}, seconds=2.0, out=out, progress=False)
    if "push_dip_mm" in res:
        dips = np.asarray(res["push_dip_mm"], dtype=float)
        assert dips.shape == (len(res),)
    for row in res:
        status: str = row["status"]
        assert status in ("ok", "saturated", "fell", "diverged")
    best = res.best("last_1s_std_mm")
    assert best is not None and best["id"]
    groups = res.best("last_1s_std_mm", by=["kd"])
    assert len(groups) == 1
    html: str = res._repr_html_()
    assert html.startswith("<table")
    back: pc.SweepResult = pc.load_run(out)
    assert back.complete
    lab = pc.lab("heavy", {"kp": [30], "kd": 1}, seconds=2.0, progress=False)
    assert list(lab["variant"]) == ["heavy"]
    return height


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        print(f"stood at {tour(d + '/run'):.4f} m")
