"""The lab's figures (``pupper_core.plots`` re-exports them): a Kp x Kd
heatmap per body on one colour scale, and each body at its best gains."""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import TYPE_CHECKING, Mapping, Sequence

import numpy as np

from pupper_core._plots_grid import base_z, heatmap
from pupper_core._plots_replicates import replicate_spread
from pupper_core._plots_style import (
    _BAD_GREY,
    LABELS,
    _cell_text,
    _fmt,
    _ink,
    _new_figure,
    _save,
    _style,
    plain_log_axis,
)
from pupper_core._plots_tables import RunLike, describe, read_run, run_dir_of
from pupper_core._public import exported_from
from pupper_core._spec import DEFAULT_METRIC, ROBUST_METRIC

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure



@exported_from("pupper_core.plots")
def lab_heatmaps(
    bodies: Sequence[str],
    kp: Sequence[float],
    kd: Sequence[float],
    values: Mapping[str, np.ndarray],
    best: Mapping[str, tuple[float, float] | None],
    metric: str = DEFAULT_METRIC,
    status: Mapping[str, np.ndarray] | None = None,
) -> "Figure":
    """One Kp × Kd heatmap per body on one shared (log) colour scale, the
    body's best cell starred, as the sweep's heatmaps: yellow is steadier,
    numbers in the cells. ``values[body]`` is a (len(kd), len(kp)) array,
    NaN where the cell fell, diverged or saturated; ``status[body]`` (the
    same shape, text) names why a cell is blank. A best cell on the grid's
    edge gets a hint to widen the grid that way."""
    from matplotlib.colors import LogNorm

    with _style():
        fig = _new_figure((4.2 * len(bodies) + 1.2, 4.2))
        axes = fig.subplots(1, len(bodies), squeeze=False)[0]
        finite = np.concatenate([v[np.isfinite(v) & (v > 0)] for v in values.values()] or [np.array([1.0])])
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (1e-3, 1.0)
        norm = LogNorm(vmin=lo, vmax=max(hi, lo * 1.0001))
        image = None
        import matplotlib

        cmap = matplotlib.colormaps["viridis_r"].with_extremes(bad=_BAD_GREY)
        edges: list[str] = []
        for ax, body in zip(axes, bodies):
            v = np.ma.masked_invalid(values[body])
            image = ax.imshow(v, origin="lower", cmap=cmap, norm=norm, aspect="auto")
            ax.set_xticks(range(len(kp)), [_fmt(x) for x in kp])
            ax.set_yticks(range(len(kd)), [_fmt(x) for x in kd])
            ax.set_xlabel("Kp (N·m/rad)")
            ax.set_title(body)
            st = status.get(body) if status is not None else None
            for r in range(len(kd)):
                for c in range(len(kp)):
                    x = values[body][r, c]
                    if np.isfinite(x):
                        txt, colour = _cell_text(float(x), metric), _ink(cmap(norm(x)))
                    else:
                        why = str(st[r, c]) if st is not None else ""
                        txt, colour = (why if why and why != "ok" else "n/a"), "#444444"
                    ax.text(c, r, txt, ha="center", va="center", color=colour, fontsize=8, zorder=3)
            b = best.get(body)
            if b is not None:
                c, r = list(kp).index(b[0]), list(kd).index(b[1])
                ax.plot([c + 0.28], [r + 0.25], marker="*", color="red", markersize=12,
                        markeredgecolor="white", zorder=6, gid="best_star")
                side = [w for w, on in (("Kp up", c == len(kp) - 1 and len(kp) > 1),
                                        ("Kp down", c == 0 and len(kp) > 1),
                                        ("Kd up", r == len(kd) - 1 and len(kd) > 1),
                                        ("Kd down", r == 0 and len(kd) > 1)) if on]
                if side:
                    edges.append(f"{body}: {', '.join(side)}")
        axes[0].set_ylabel("Kd (N·m·s/rad)")
        if image is not None:
            plain_log_axis(fig.colorbar(image, ax=list(axes), label=f"{LABELS.get(metric, metric)} (log)").long_axis)
        if edges:
            fig.supxlabel("★ on the grid's edge, the steadiest gains may lie beyond it: widen the grid ("
                          + "; ".join(edges) + ")", fontsize=9, color="#9a6700")
        fig.pupper_edges = edges  # type: ignore[attr-defined]
        return fig


@exported_from("pupper_core.plots")
def write_lab_plots(run_dir: RunLike) -> list[Path]:
    """`pupper lab`'s figures in ``<run_dir>/plots/``: ``lab_heatmaps.png``
    (Kp × Kd per body, shared colour scale, best starred; blank where a
    cell fell or diverged) and ``lab_best_base_z.png`` (each body's
    base height at its best gains). Reads summary.csv, best.csv, traces.csv."""
    d = run_dir_of(run_dir)
    with open(d / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    with open(d / "best.csv", newline="") as f:
        best_rows = list(csv.DictReader(f))
    table, manifest, traces = read_run(d)
    replicated = bool(rows) and "failure_fraction" in rows[0]
    metric = ROBUST_METRIC if replicated else DEFAULT_METRIC
    bodies = list(dict.fromkeys(r["variant"] for r in rows))
    kp = sorted({float(r["kp"]) for r in rows})
    kd = sorted({float(r["kd"]) for r in rows})
    values: dict[str, np.ndarray] = {b: np.full((len(kd), len(kp)), np.nan) for b in bodies}
    status: dict[str, np.ndarray] = {b: np.full((len(kd), len(kp)), "", dtype=object) for b in bodies}
    for r in rows:
        up = r["failure_fraction"] == "0" if replicated else r["status"] == "ok"
        at = (kd.index(float(r["kd"])), kp.index(float(r["kp"])))
        status[r["variant"]][at] = ("fell" if not up else "ok") if replicated else r["status"]
        if up and r[metric]:
            values[r["variant"]][at] = float(r[metric])
    best: dict[str, tuple[float, float] | None] = {}
    for b in best_rows:
        best[b["variant"]] = (float(b["kp"]), float(b["kd"])) if b["id"] else None
    out = d / "plots"
    out.mkdir(parents=True, exist_ok=True)
    written = []
    fig = lab_heatmaps(bodies, kp, kd, values, best, metric=DEFAULT_METRIC, status=status)
    head = ("Worst-side 95th percentile over replicates of the last-second base-z std per body"
            if replicated else "Last-second base-z std per body")
    fig.suptitle(f"{head}\n{describe(manifest, len(rows))}", fontsize=11)
    written.append(_save(fig, out / "lab_heatmaps.png"))
    if replicated:
        shares = {**table, "status": ["ok"] * len(rows)}
        fig = heatmap(shares, "failure_fraction", "kp", "kd", by="variant", mark_best=False)
        for a, body in zip(fig.axes, bodies):
            a.set_title(body)
        written.append(_save(fig, out / "lab_failure_fraction.png"))
        fig = replicate_spread(d, DEFAULT_METRIC, by="variant")
        if fig is not None:
            fig.suptitle("Each body's best gains: spread over replicates", fontsize=11)
            written.append(_save(fig, out / "lab_spread_last_1s_std_mm.png"))
    chosen = {b["id"]: f"{b['variant']}: Kp {float(b['kp']):g}, Kd {float(b['kd']):g}" for b in best_rows if b["id"]}
    picked = {cid: traces[cid] for cid in chosen if cid in traces}
    if picked:
        # each body about its own mean: the bodies stand 160 and 230 mm
        # tall, and their response to the sine is a twentieth of a millimetre
        landing = float(((manifest.get("config") or {}).get("schedule") or {}).get("landing", 1.0))
        for cid, (t, z) in list(picked.items()):
            t, z = np.asarray(t, float), np.asarray(z, float)
            mean = float(np.mean(z[t >= landing])) if (t >= landing).any() else float(np.mean(z))
            picked[cid] = (t, z - mean)
            chosen[cid] += f" (stands at {mean * 1000:.1f} mm)"
        fig = base_z(picked, push=None, labels=chosen, landing=landing,
                     title="Each body at its best gains: base height about its own mean",
                     ylabel="base z − its mean after landing (mm)")
        written.append(_save(fig, out / "lab_best_base_z.png"))
    return written
