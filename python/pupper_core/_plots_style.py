"""How pupper's figures look (``pupper_core.plots`` draws them): labels
with units, fonts and sizes, a figure made without pyplot (shown once in
IPython), numbers as the cells and ticks write them, the key line under a
ranked figure, and a figure saved whole."""

from __future__ import annotations

import math
import os
import re
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator, Sequence

from pupper_core._files import atomic_write
from pupper_core._public import exported_from

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np
    from matplotlib.figure import Figure

#: Human labels with units.
LABELS: dict[str, str] = {
    "kp": "Kp (N·m/rad)",
    "kd": "Kd (N·m·s/rad)",
    "push_force": "push force, world z (N)",
    "max_torque": "torque limit (N·m)",
    "friction": "sliding friction μ",
    "timestep": "timestep (s)",
    "leg_scale": "leg length scale (×)",
    "torso_mass_scale": "torso mass scale (×)",
    "final_z": "final base height (m)",
    "last_1s_std_mm": "base-height std, last 1 s (mm)",
    "push_dip_mm": "push dip of base height (mm)",
    "settle_time_s": "settle time after push (s)",
    "max_tilt_deg": "max tilt (°)",
    "peak_torque": "peak joint torque (N·m)",
    "saturation_frac": "fraction of torque samples saturated",
    "tracking_rms": "joint tracking RMS error (rad)",
    "event_time": "fall / divergence time (s)",
    "sag_mm": "sag under the load (mm)",
    "compliance_mm_per_n": "sag per newton of load (mm/N)",
    "sway_mm": "sideways sway after the shove (mm)",
    "recovery_s": "recovery after the shove (s)",
    "copper_w": "copper loss (W)",
}
SHORT: dict[str, str] = {
    "kp": "Kp",
    "kd": "Kd",
    "push_force": "push",
    "max_torque": "τmax",
    "friction": "μ",
    "timestep": "dt",
    "leg_scale": "leg×",
    "torso_mass_scale": "torso×",
}
DPI = 120
_RC = {
    "font.size": 11,
    "axes.titlesize": 12,
    "axes.labelsize": 11,
    "xtick.labelsize": 10,
    "ytick.labelsize": 10,
    "legend.fontsize": 9,
    "figure.titlesize": 13,
    "axes.grid": False,
}
_BAD_GREY = "#c8c8c8"
_FELL = "#f6c9b8"


def _ensure_backend() -> None:
    """Selects Agg when no backend was chosen and there is no display."""
    import matplotlib

    if os.environ.get("MPLBACKEND"):
        return
    chosen = getattr(matplotlib.rcParams, "_get_backend_or_none", lambda: "?")()
    headless = not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if chosen is None and headless and sys.platform.startswith("linux"):
        matplotlib.use("Agg")


@contextmanager
def _style() -> Iterator[None]:
    _ensure_backend()
    import matplotlib

    with matplotlib.rc_context(_RC):
        yield


def _new_figure(figsize: tuple[float, float]) -> "Figure":
    from matplotlib.figure import Figure

    _ipython_display()
    return Figure(figsize=figsize, dpi=DPI, layout="constrained")


_ipython_done = False


def _ipython_display() -> None:
    """In IPython/Jupyter, lets a returned Figure show as a PNG (once).

    Our figures are made without pyplot (so nothing piles up in its registry);
    IPython only knows how to show a Figure once matplotlib's inline support
    registered a formatter, so register one when none is there.
    """
    global _ipython_done
    if _ipython_done or "IPython" not in sys.modules:
        return
    _ipython_done = True
    try:
        from IPython import get_ipython
        from matplotlib.figure import Figure

        ip = get_ipython()
        if ip is None:
            return
        fmt = ip.display_formatter.formatters["image/png"]
        try:
            fmt.lookup_by_type(Figure)
            return  # inline backend (or the user) already handles figures
        except KeyError:
            pass

        def png(fig: "Figure") -> bytes:
            import io

            buf = io.BytesIO()
            fig.savefig(buf, format="png", dpi=fig.dpi)
            return buf.getvalue()

        fmt.for_type(Figure, png)
    except Exception:  # noqa: BLE001 - display is a nicety, never an error
        pass


@exported_from("pupper_core.plots")
def label_of(column: str) -> str:
    """Axis/colorbar label with units for a summary column (statistics over
    replicates, ``mean:M`` and ``p95:M``, say so)."""
    stat, sep, metric = column.partition(":")
    if sep and stat in ("mean", "p95"):
        word = "mean" if stat == "mean" else ("worst-side 95th percentile" if metric != "final_z" else "5th percentile")
        return f"{LABELS.get(metric, metric)}, {word} over replicates"
    if column == "failure_fraction":
        return "share of replicates that fell or diverged"
    return LABELS.get(column, column)


def _fmt(v: Any) -> str:
    """An axis value as a label: at most 3 significant digits (a log
    range's 22.8943 reads 22.9)."""
    if isinstance(v, str):
        return v
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    if math.isnan(f):
        return "—"
    return f"{f:.3g}"


#: Below this a *_mm metric is no difference at all (the ranking's tie, 1 µm).
MM_RESOLUTION = 0.001


def _cell_text(v: float, metric: str) -> str:
    """A heatmap cell's number, one format per metric: millimetres to the
    micrometre ("<0.001" below it: nanometres are no result), fractions in
    percent, others to 3 significant digits."""
    name = metric.split(":")[-1]
    if name.endswith("_mm"):
        if abs(v) < MM_RESOLUTION:
            return "<0.001"
        return f"{v:.3f}" if abs(v) < 10 else f"{v:.1f}"
    if name.endswith("_frac") or name == "failure_fraction":
        return f"{v * 100:.1f}%"
    return f"{v:.3g}"


def _ink(rgba: Sequence[float]) -> str:
    """The text colour that reads on a cell of colour ``rgba``: black on a
    light one, white on a dark one."""
    lum = 0.299 * rgba[0] + 0.587 * rgba[1] + 0.114 * rgba[2]
    return "black" if lum > 0.55 else "white"


def _key_line(best_word: str, status: np.ndarray, metric: str = "last_1s_std_mm", dip: bool = True) -> str:
    """'★ = lowest <the metric plotted> …' plus the colours used for fallen /
    diverged cells; the tie rule as the Rust core applies it to ``metric``
    (0.001 mm on a millimetre column, exact equality on others), broken by
    the smaller push dip when ``dip`` (the table has one and the metric is
    not the dip itself), else by grid order."""
    name = metric.split(":")[-1]
    tie = "ties within 0.001 mm" if name.endswith("_mm") else "equal values"
    breaker = "the smaller push dip" if dip and name != "push_dip_mm" else "the first in grid order"
    what = re.sub(r" \([^)]*\)", "", label_of(metric))
    parts = [f"★ = {best_word} {what} among cells that stood below 5 % saturation ({tie}: {breaker})"
             if best_word == "lowest" else f"★ = {best_word} {what} among cells that stood"]
    if (status == "fell").any():
        parts.append("pink = fell")
    if (status == "diverged").any():
        parts.append("grey = diverged")
    return " · ".join(parts)


def _has_dip(table: Any, metric: str) -> bool:
    """Whether the table's push dip (the same statistic as ``metric``) can
    break a tie: a column with a number in it (a run with a push)."""
    import numpy as np

    stat = metric.split(":")[0] + ":" if ":" in metric else ""
    col = f"{stat}push_dip_mm"
    if col not in table:
        return False
    try:
        v = np.asarray(table[col], dtype=float)
    except (TypeError, ValueError):
        return False
    return bool(np.isfinite(v).any())


def _wrap_parts(text: str, width_in: float, fontsize: float = 11.0) -> str:
    """Breaks a ' · '-separated line so it fits ``width_in`` inches."""
    limit = max(30, int(width_in * 72 / (0.55 * fontsize)))
    lines: list[str] = []
    cur = ""
    for part in text.split(" · "):
        cand = part if not cur else f"{cur} · {part}"
        if len(cand) > limit and cur:
            lines.append(cur)
            cur = part
        else:
            cur = cand
    if cur:
        lines.append(cur)
    # a part longer than the line breaks between words
    import textwrap

    return "\n".join(w for line in lines for w in (textwrap.wrap(line, limit) or [line]))


def _say_setting(fig: "Figure", what: str) -> None:
    """What was run, in small grey type below the figure (its title says
    what is shown)."""
    fig.supxlabel(_wrap_parts(what, fig.get_figwidth(), 8), fontsize=8, color="#555555")


def _save(fig: "Figure", path: Path) -> Path:
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=DPI))
    return path


def _plain_log_ticks(lo: float, hi: float) -> list[float]:
    """Where a log axis from ``lo`` to ``hi`` is numbered: at 1, 2, 5 per
    decade (1, 2, 3, 5, or 1 to 9 on a short axis; every decade, or every
    few, on a long one), 3 to 8 numbers; on an axis too short for any of
    these, a linear axis's ticks."""
    from matplotlib.ticker import MaxNLocator

    lo, hi = sorted((lo, hi))
    if not (hi > 0 and math.isfinite(hi)):
        return []
    lo = max(lo, hi * 1e-30)
    e0, e1 = math.floor(math.log10(lo)), math.ceil(math.log10(hi))

    def at(subs: Sequence[int]) -> list[float]:
        return [s * 10.0**e for e in range(e0, e1 + 1) for s in subs
                if lo * (1 - 1e-9) <= s * 10.0**e <= hi * (1 + 1e-9)]

    ticks = at((1, 2, 5))
    if len(ticks) > 8:
        decades = at((1,))
        return decades[:: math.ceil(len(decades) / 8)]
    for subs in ((1, 2, 5), (1, 2, 3, 5), range(1, 10)):
        ticks = at(subs)
        if len(ticks) >= 3:
            return ticks
    return [float(v) for v in MaxNLocator(4).tick_values(lo, hi) if lo <= v <= hi]


def plain_log_axis(axis: Any) -> None:
    """Numbers a log-scaled axis (an Axes' xaxis or yaxis, or a colour
    bar's) plainly, 2 and 5 rather than 2×10⁰ and 5×10⁰, and few enough
    that no two meet; the minor ticks unnumbered."""
    from matplotlib.ticker import FuncFormatter, Locator, NullFormatter

    class PlainLog(Locator):
        def __call__(self) -> list[float]:
            return self.tick_values(*self.axis.get_view_interval()) if self.axis is not None else []

        def tick_values(self, vmin: float, vmax: float) -> list[float]:
            return _plain_log_ticks(vmin, vmax)

    axis.set_major_locator(PlainLog())
    axis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:.3g}"))
    axis.set_minor_formatter(NullFormatter())
