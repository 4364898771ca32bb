"""A fit's figures in its run directory (``pupper_core._fit_output`` and
``pupper_core._fit_validate`` hand them the angles): per fitted log, the
measured against the simulated angle of each joint before and after the
fit, its residual beneath; per validated log, the Bode plot of the log and
both models over their angle error in time. Every title wrapped to its
figure and the frequency axes numbered plainly (1, 2, 5, 10 Hz), so no
text leaves a figure or meets another."""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pupper_core._files import atomic_write
from pupper_core._plots_style import plain_log_axis

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from pupper_core._fit_validate import Validation

#: The fit's figures' resolution (dots per inch).
DPI = 90
STYLE = {"log": dict(color="black", lw=1.4, marker="o", ms=3), "nominal": dict(color="tab:gray", ls="--", lw=1.0),
         "calibrated": dict(color="tab:orange", lw=1.0)}


def _wrapped(text: str, width_in: float, fontsize: float) -> str:
    """``text`` broken between words to fit ``width_in`` inches at
    ``fontsize`` pt (a glyph about 0.6 of it wide; each line given as its
    own kept whole where it fits)."""
    limit = max(20, int(0.92 * width_in * 72 / (0.6 * fontsize)))
    return "\n".join(w for line in text.split("\n") for w in (textwrap.wrap(line, limit) or [line]))


def _figure(size: tuple[float, float]) -> "Figure":
    from matplotlib.figure import Figure

    return Figure(figsize=size, dpi=DPI, layout="constrained")


def save(fig: "Figure", path: Path) -> Path:
    path.parent.mkdir(exist_ok=True)
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=DPI))
    return path


def fit_figure(log: str, t: np.ndarray, measured: np.ndarray, nominal: np.ndarray, fitted: np.ndarray,
               names: Sequence[str]) -> "Figure":
    """A fitted log: per joint (column k of the arrays, named by
    ``names``), measured against simulated angle at the nominal and the
    fitted values, and beneath it the residual (simulated minus measured,
    mrad): the lines on top lie on each other where the fit is good, the
    residuals say by how much."""
    nu = len(names)
    cols = 4 if nu >= 4 else nu
    rows = math.ceil(nu / cols)
    fig = _figure((max(4.0 * cols, 5.0), 3.4 * rows + 0.4))
    grid = fig.add_gridspec(2 * rows, cols, height_ratios=[2.4, 1.0] * rows)
    for k in range(nu):
        r, c = k // cols, k % cols
        ax = fig.add_subplot(grid[2 * r, c])
        res = fig.add_subplot(grid[2 * r + 1, c], sharex=ax)
        ax.plot(t, measured[:, k], color="black", lw=1.0, label="measured")
        ax.plot(t, nominal[:, k], color="tab:gray", lw=0.8, ls="--", label="nominal model")
        ax.plot(t, fitted[:, k], color="tab:orange", lw=0.8, label="fitted model")
        res.plot(t, (nominal[:, k] - measured[:, k]) * 1e3, color="tab:gray", lw=0.8, ls="--")
        res.plot(t, (fitted[:, k] - measured[:, k]) * 1e3, color="tab:orange", lw=0.8)
        res.axhline(0, color="black", lw=0.6)
        r0 = np.sqrt(np.mean((measured[:, k] - nominal[:, k]) ** 2)) * 1e3
        r1 = np.sqrt(np.mean((measured[:, k] - fitted[:, k]) ** 2)) * 1e3
        ax.set_title(f"{names[k]}: RMS {r0:.2f} → {r1:.2f} mrad", fontsize=8)
        ax.tick_params(labelsize=7, labelbottom=False)
        res.tick_params(labelsize=7)
        if k == 0:
            ax.legend(fontsize=7, loc="upper right")
        if c == 0:
            ax.set_ylabel("angle (rad)", fontsize=8)
            res.set_ylabel("sim − meas.\n(mrad)", fontsize=7)
        if r == rows - 1 or k + cols >= nu:
            res.set_xlabel("time (s)", fontsize=8)
    fig.suptitle(_wrapped(f"{log}: measured against simulated joint angle, before and after the fit; beneath "
                          "each, the residual", fig.get_figwidth(), 10), fontsize=10)
    return fig


def validation_figure(log: str, traces: Sequence[Any]) -> "Figure":
    """A validated log: per joint (a ``_fit_validate.Trace`` each), the
    gain and phase of the log, the nominal and the calibrated model against
    frequency, and both models' angle error over time."""
    n = len(traces)
    fig = _figure((max(5.0 * n, 5.0), 7.8))
    axes = fig.subplots(3, n, squeeze=False)
    for c, tr in enumerate(traces):
        gain_ax, phase_ax, err_ax = axes[0][c], axes[1][c], axes[2][c]
        for m in ("log", "nominal", "calibrated"):
            r = tr.response[m]
            if r is not None:
                gain_ax.semilogx(r.freq, 20 * np.log10(r.gain), label=m, **STYLE[m])
                phase_ax.semilogx(r.freq, r.phase, label=m, **STYLE[m])
        gain_ax.set_title(_wrapped(f"{tr.actuator}: command to angle", 5.0, 9), fontsize=9)
        gain_ax.set_ylabel("gain (dB)", fontsize=8)
        phase_ax.set_ylabel("phase (deg)", fontsize=8)
        phase_ax.set_xlabel("frequency (Hz)", fontsize=8)
        if gain_ax.get_lines():
            gain_ax.legend(fontsize=7)
            for a in (gain_ax, phase_ax):
                plain_log_axis(a.xaxis)
        for m in ("nominal", "calibrated"):
            err_ax.plot(tr.t, (tr.q["log"] - tr.q[m]) * 1e3, lw=0.7, label=m,
                        **{k: x for k, x in STYLE[m].items() if k in ("color", "ls")})
        err_ax.set_ylabel("log - model (mrad)", fontsize=8)
        err_ax.set_xlabel("time (s)", fontsize=8)
        err_ax.legend(fontsize=7)
        for ax in (gain_ax, phase_ax, err_ax):
            ax.tick_params(which="both", labelsize=7)
            ax.grid(alpha=0.3)
    fig.suptitle(_wrapped(f"{log} (not fitted):\nthe log, the nominal and the calibrated model",
                          fig.get_figwidth(), 10), fontsize=10)
    return fig


def write_validation(out: Path, v: "Validation") -> list[Path]:
    """plots/validate_<log>.png for each validated log."""
    wrote = []
    for log in dict.fromkeys(tr.log for tr in v.traces):
        fig = validation_figure(log, [tr for tr in v.traces if tr.log == log])
        wrote.append(save(fig, out / "plots" / f"validate_{Path(log).stem}.png"))
    return wrote
