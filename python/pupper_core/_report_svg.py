"""The figures of `report.html`, drawn as inline SVG from a run's tables:
a Kp x Kd heatmap (the pick starred, cells no rule may pick greyed), bars
(one scale for all, logarithmic where the values span decades) and lines
(the pick drawn bold and black, always). No charting library, no file."""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from typing import Any

from pupper_core._spec import OVERSHOOT_NOISE_PCT

#: The steadiest-first colour ramp of the heatmaps (viridis, reversed: yellow is best).
RAMP = ["#fde725", "#b5de2b", "#6ece58", "#35b779", "#1f9e89", "#26828e", "#31688e", "#3e4989",
        "#482878", "#440154"]
PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
           "#bcbd22", "#17becf"]


#: A letter's width in ems, by kind, as DejaVu Sans (Linux's usual
#: sans-serif, wider than most) draws it: a label laid out by these fits
#: the box it is given in the common faces.
_EMS = {**dict.fromkeys("'ijlIJ", 0.3), **dict.fromkeys(".,: ;|/·", 0.34),
        **dict.fromkeys("f-()[]tr!", 0.4), **dict.fromkeys("°_sz", 0.53), **dict.fromkeys("×→−", 0.84),
        **dict.fromkeys("mMwW%@…★", 1.0)}


def text_width(text: str, size: float) -> float:
    """About how wide ``text`` is at ``size`` px (never much under)."""
    return size * sum(_EMS.get(c, 0.8 if c.isupper() else 0.65) for c in text)


def wrap(text: str, size: float, width: float) -> list[str]:
    """``text`` broken between words into lines at most ``width`` px wide
    at ``size`` px (a word longer than the line is a line of its own)."""
    lines: list[str] = []
    for word in text.split(" "):
        if lines and text_width(f"{lines[-1]} {word}", size) <= width:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    return lines or [""]


def text_lines(x: float, y: float, lines: Sequence[str], size: float, attrs: str = "") -> str:
    """A ``<text>`` of ``lines``, the first's baseline at ``y``, a line
    every 1.25 em."""
    spans = "".join(f'<tspan x="{x:.1f}" dy="{0 if k == 0 else 1.25 * size:g}">{html.escape(ln)}</tspan>'
                    for k, ln in enumerate(lines))
    return f'<text x="{x:.1f}" y="{y:.1f}" font-size="{size:g}"{attrs}>{spans}</text>'


def shortened(label: str, size: float, width: float) -> str:
    """``label`` cut in its middle (…) to fit ``width`` px, its ends kept."""
    if text_width(label, size) <= width:
        return label
    keep = len(label)
    while keep > 4 and text_width(label[: keep // 2] + "…" + label[len(label) - (keep - keep // 2):], size) > width:
        keep -= 1
    return label[: keep // 2] + "…" + label[len(label) - (keep - keep // 2):]


def num(v: Any) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def fmt(v: str, column: str = "") -> str:
    """A table's text rounded to what a reader uses (4 significant digits);
    an overshoot below the simulation's resolution is 0."""
    x = num(v)
    if math.isnan(x) or v.strip() == "":
        return html.escape(v)
    if column.startswith("overshoot_pct") and abs(x) < OVERSHOOT_NOISE_PCT:
        return "0"
    return f"{x:.4g}"


def rounded(v: str, column: str = "") -> str:
    """``v`` rounded, every digit in its tooltip."""
    return f'<span title="{html.escape(v)}">{fmt(v, column)}</span>'


def _colour(x: float, lo: float, hi: float, log: bool) -> str:
    if math.isnan(x):
        return "#ffffff"
    if log and lo > 0:
        x, lo, hi = math.log10(max(x, lo)), math.log10(lo), math.log10(hi)
    f = 0.0 if hi <= lo else min(max((x - lo) / (hi - lo), 0.0), 1.0)
    return RAMP[min(int(f * len(RAMP)), len(RAMP) - 1)]


def _cell(r: dict[str, str] | None, metric: str) -> tuple[float, str, str, str]:
    """A heatmap cell's value, fill (None: on the ramp), label and tooltip."""
    v = num(r.get(metric)) if r else math.nan
    status = r.get("status", "") if r else ""
    if status == "ok":
        label = "–" if math.isnan(v) else f"{v:.3g}"
        return v, "", label, label
    if status in ("past_bound", "saturated"):
        label = "past bound" if status == "past_bound" else "saturated"
        why = "the integrator's number" if status == "past_bound" else "at the torque limit"
        return v, "#d0d0d0", label, label if math.isnan(v) else f"{label} ({v:.3g}: {why})"
    return v, "#f0c0c0" if r else "#ffffff", status, status


def heatmap(rows: list[dict[str, str]], xa: str, ya: str, metric: str, best: str | None,
            title: str = "") -> str:
    """``metric`` over the ``xa`` x ``ya`` grid, yellow lowest; a cell past
    the stability bound or saturated is grey (no rule picks it), one that
    fell or diverged red; ★ the pick."""
    xs = sorted({num(r[xa]) for r in rows})
    ys = sorted({num(r[ya]) for r in rows})
    cells = {(num(r[xa]), num(r[ya])): r for r in rows}
    # the ramp spans the cells a rule may pick: no grey cell sets its scale
    vals = [num(r.get(metric)) for r in rows if r.get("status") == "ok"]
    vals = [v for v in vals if not math.isnan(v)]
    lo, hi = (min(vals), max(vals)) if vals else (0.0, 1.0)
    log = lo > 0 and hi / max(lo, 1e-300) > 20
    w, h, left = 64, 34, 70
    full = max(left + w * len(xs) + 20, 640)
    head = wrap(title or metric, 12, full - left - 4)
    key = wrap("yellow is lower; red: fell or diverged; grey: past the stability bound or saturated; ★ the pick",
               10, full - left - 4)
    top = 14 + 15 * len(head) + 13 * len(key) + 4
    full_h = top + h * len(ys) + 50
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{full}" height="{full_h}" viewBox="0 0 {full} {full_h}" '
           f'role="img" aria-label="{html.escape(metric)} heatmap">']
    for j, y in enumerate(reversed(ys)):
        out.append(f'<text x="{left - 6}" y="{top + j * h + h / 2 + 4}" text-anchor="end" font-size="11">'
                   f'{y:g}</text>')
        for i, x in enumerate(xs):
            r = cells.get((x, y))
            v, fill, label, tip = _cell(r, metric)
            fill = fill or _colour(v, lo, hi, log)
            px, py = left + i * w, top + j * h
            picked = r is not None and best is not None and r.get("id") == best
            mark = ' stroke="#000" stroke-width="3"' if picked else ' stroke="#fff"'
            out.append(f'<rect x="{px}" y="{py}" width="{w}" height="{h}" fill="{fill}"{mark}>'
                       f'<title>{html.escape(xa)} {x:g}, {html.escape(ya)} {y:g}: {html.escape(tip)}</title></rect>')
            ink = "#fff" if fill in RAMP[6:] else "#000"  # legible on the dark end of the ramp
            out.append(f'<text x="{px + w / 2}" y="{py + h / 2 + 4}" text-anchor="middle" font-size="10" '
                       f'fill="{ink}">{html.escape(label)}{" ★" if picked else ""}</text>')
    for i, x in enumerate(xs):
        out.append(f'<text x="{left + i * w + w / 2}" y="{top + h * len(ys) + 16}" text-anchor="middle" '
                   f'font-size="11">{x:g}</text>')
    out.append(f'<text x="{left + w * len(xs) / 2}" y="{top + h * len(ys) + 36}" text-anchor="middle" '
               f'font-size="12">{html.escape(xa)}</text>')
    out.append(f'<text x="12" y="{top + h * len(ys) / 2}" font-size="12" transform="rotate(-90 12 '
               f'{top + h * len(ys) / 2})" text-anchor="middle">{html.escape(ya)}</text>')
    out.append(text_lines(left, 16, head, 12, ' font-weight="bold"')
               + text_lines(left, 16 + 15 * len(head) + 1, key, 10) + "</svg>")
    return "".join(out)


def bars(labels: Sequence[str], series: Mapping[str, Sequence[float]], title: str, best: int | None = None,
         unit: str = "") -> str:
    """Horizontal bars, a group per label and a bar per series, all on one
    scale: logarithmic where the positive values span more than two
    decades (the axis says so); the ``best`` label's bars orange. The
    labels' column is as wide as its longest label (a label past 360 px
    is cut in its middle, whole in its tooltip); the title wraps to the
    figure."""
    flat = [v for vs in series.values() for v in vs if not math.isnan(v)]
    pos = [v for v in flat if v > 0]
    log = bool(pos) and max(pos) / min(pos) > 100
    if log:
        lo, hi = math.floor(math.log10(min(pos))), math.ceil(math.log10(max(pos)))
        hi = hi if hi > lo else lo + 1
    top = max([v for v in flat if v > 0], default=1.0)
    bh, width, size = 14, 420, 10
    label_w = min(max([text_width(lab, size) for lab in labels] + [120.0]), 360.0)
    left = label_w + 12
    shown = [["–" if math.isnan(v) else f"{v:.3g}{unit}" for v in vs] for vs in series.values()]
    full = left + width + 8 + max([text_width(t, size) for ts in shown for t in ts] + [30.0]) + 8
    k = len(series)
    # the legend's entries side by side, a row more where they would not fit
    legend: list[list[tuple[float, int, str]]] = [[]]
    x = left
    for s_, name in enumerate(series):
        w = 14 + text_width(name, size) + 20
        if legend[-1] and x + w > full:
            legend.append([])
            x = left
        legend[-1].append((x, s_, name))
        x += w
    head = wrap(title + (" (log scale)" if log else ""), 12, full - 8)
    gh = bh * k + 6
    y_top = 8 + 15 * len(head)
    axis_y = y_top + gh * len(labels) + 2
    height = axis_y + (16 if log else 4) + (16 * len(legend) if k > 1 else 0) + 4
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{full:.0f}" height="{height:.0f}" '
           f'viewBox="0 0 {full:.0f} {height:.0f}" role="img" aria-label="{html.escape(title)}">'
           + text_lines(4, 18, head, 12)]

    def length(v: float) -> float:
        if math.isnan(v) or v <= 0:
            return 0.0
        if log:
            return width * (math.log10(v) - lo) / (hi - lo)
        return width * v / top

    if k > 1:
        for row, entries in enumerate(legend):
            y = axis_y + (16 if log else 4) + 16 * row
            for x, s_, name in entries:
                out.append(f'<rect x="{x:.1f}" y="{y + 2}" width="10" height="10" '
                           f'fill="{PALETTE[s_ % len(PALETTE)]}"/><text x="{x + 14:.1f}" y="{y + 11}" '
                           f'font-size="{size}">{html.escape(name)}</text>')
    if log:
        for e in range(lo, hi + 1):
            x = left + width * (e - lo) / (hi - lo)
            out.append(f'<line x1="{x:.1f}" y1="{y_top - 2}" x2="{x:.1f}" y2="{axis_y}" stroke="#ddd"/>'
                       f'<text x="{x:.1f}" y="{axis_y + 11}" text-anchor="middle" font-size="9">1e{e}</text>')
    for i, lab in enumerate(labels):
        y0 = y_top + i * gh
        cut = shortened(lab, size, label_w)
        tip = f"<title>{html.escape(lab)}</title>" if cut != lab else ""
        out.append(f'<text x="{left - 6:.1f}" y="{y0 + gh / 2 + 3}" text-anchor="end" font-size="{size}">'
                   f'{html.escape(cut)}{tip}</text>')
        for s_, vs in enumerate(series.values()):
            v, y = vs[i], y0 + s_ * bh
            fill = "#f0a030" if i == best else PALETTE[s_ % len(PALETTE)]
            wv = length(v)
            out.append(f'<rect x="{left:.1f}" y="{y + 2}" width="{wv:.1f}" height="{bh - 3}" fill="{fill}">'
                       f'<title>{html.escape(repr(v))}</title></rect>'
                       f'<text x="{left + wv + 4:.1f}" y="{y + 11}" font-size="{size}">{html.escape(shown[s_][i])}</text>')
    out.append("</svg>")
    return "".join(out)


def lines(series: dict[str, tuple[list[float], list[float]]], title: str, xlabel: str, ylabel: str,
          pick: str | None = None, guide: float | None = None, height: int = 260) -> str:
    """A line per series; ``pick``'s drawn last, bold and black, named
    first in the legend; ``guide`` a dashed level (a step's target)."""
    pts = [(x, y) for xs, ys in series.values() for x, y in zip(xs, ys) if not math.isnan(y)]
    if not pts:
        return ""
    x0, x1 = min(p[0] for p in pts), max(p[0] for p in pts)
    y0, y1 = min(p[1] for p in pts), max(p[1] for p in pts)
    if guide is not None:
        y0, y1 = min(y0, guide), max(y1, guide)
    x1 = x1 if x1 > x0 else x0 + 1
    y1 = y1 if y1 > y0 else y0 + 1e-9
    W, H, R = 640, height, 200
    L = _left(y0, y1)
    head = wrap(title, 12, W + R - 4)
    xl = wrap(xlabel, 11, W)
    T = 9 + 15 * len(head)
    full_h = T + H + 34 + 14 * len(xl)

    def at(x: float, y: float) -> str:
        return f"{L + W * (x - x0) / (x1 - x0):.1f},{T + H - H * (y - y0) / (y1 - y0):.1f}"

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W + L + R}" height="{full_h}" '
           f'viewBox="0 0 {W + L + R} {full_h}" role="img" aria-label="{html.escape(title)}">'
           + text_lines(L, 16, head, 12),
           f'<rect x="{L}" y="{T}" width="{W}" height="{H}" fill="none" stroke="#999"/>']
    if guide is not None:
        out.append(f'<polyline points="{at(x0, guide)} {at(x1, guide)}" stroke="#555" stroke-dasharray="4 3" '
                   'fill="none"/>')
    order = [n for n in series if n != pick] + ([pick] if pick in series else [])
    legend = ([pick] if pick in series else []) + [n for n in series if n != pick]
    colour = {n: PALETTE[k % len(PALETTE)] for k, n in enumerate(n for n in series if n != pick)}
    colour.update({pick: "#000"} if pick in series else {})
    for name in order:
        xs, ys = series[name]
        path = " ".join(at(x, y) for x, y in zip(xs, ys) if not math.isnan(y))
        wide = "2.6" if name == pick else "1.1"
        out.append(f'<polyline points="{path}" fill="none" stroke="{colour[name]}" stroke-width="{wide}" '
                   f'data-id="{html.escape(name)}"/>')
    for k, name in enumerate(legend[:14]):
        star, weight = ("★ ", ' font-weight="bold"') if name == pick else ("", "")
        cut = shortened(star + name, 10, R - 12)
        tip = f"<title>{html.escape(name)}</title>" if cut != star + name else ""
        out.append(f'<text x="{L + W + 8}" y="{T + 12 + 13 * k}" font-size="10" fill="{colour[name]}"'
                   f'{weight}>{html.escape(cut)}{tip}</text>')
    out.append(_axes_text(L, T, W, H, (x0, x1), (y0, y1), xl, ylabel))
    return "".join(out)


def _left(y0: float, y1: float) -> int:
    """The plot box's left edge: room for the y axis's name (rotated, about
    x = 6 to 18) and its widest number (0.0008447 is nine characters)."""
    return max(70, math.ceil(26 + max(text_width(f"{y0 + f * (y1 - y0):.4g}", 10) for f in (0.0, 0.5, 1.0))))


def _axes_text(L: float, T: float, W: float, H: float, xr: tuple[float, float], yr: tuple[float, float],
               xlabel: Sequence[str], ylabel: str, pad: float = 0.0) -> str:
    """The ticks' numbers (both ends and the middle) and the axes' names of
    a plot box at (L, T), W x H; the x numbers a line below the lowest y
    number's, so the corner's two never meet; then the closing tag."""
    out = []
    for f in (0.0, 0.5, 1.0):
        out.append(f'<text x="{L - 4}" y="{T + H - pad - (H - 2 * pad) * f + 4:.1f}" text-anchor="end" '
                   f'font-size="10">{yr[0] + f * (yr[1] - yr[0]):.4g}</text>'
                   f'<text x="{L + pad + (W - 2 * pad) * f:.1f}" y="{T + H + 17}" text-anchor="middle" '
                   f'font-size="10">{xr[0] + f * (xr[1] - xr[0]):.4g}</text>')
    out.append(text_lines(L + W / 2, T + H + 34, xlabel, 11, ' text-anchor="middle"'))
    yl = shortened(ylabel, 11, H)
    out.append(f'<text x="14" y="{T + H / 2}" font-size="11" transform="rotate(-90 14 {T + H / 2})" '
               f'text-anchor="middle">{html.escape(yl)}</text></svg>')
    return "".join(out)


def scatter(points: Mapping[str, tuple[float, float]], title: str, xlabel: str, ylabel: str,
            marked: Sequence[str] = (), pick: str | None = None) -> str:
    """A dot per point, by id: the ``marked`` ones filled (a trade-off
    set), ``pick`` a black star drawn last; each dot's id and values in
    its tooltip."""
    pts = {k: v for k, v in points.items() if math.isfinite(v[0]) and math.isfinite(v[1])}
    if not pts:
        return ""
    x0, x1 = min(v[0] for v in pts.values()), max(v[0] for v in pts.values())
    y0, y1 = min(v[1] for v in pts.values()), max(v[1] for v in pts.values())
    x1, y1 = (x1 if x1 > x0 else x0 + 1), (y1 if y1 > y0 else y0 + 1e-9)
    W, H, R, pad = 520, 260, 20, 8
    L = _left(y0, y1)
    head = wrap(title, 12, W + R - 4)
    xl = wrap(xlabel, 11, W)
    T = 9 + 15 * len(head)
    full_h = T + H + 34 + 14 * len(xl)

    def at(x: float, y: float) -> tuple[float, float]:
        return L + pad + (W - 2 * pad) * (x - x0) / (x1 - x0), T + H - pad - (H - 2 * pad) * (y - y0) / (y1 - y0)

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W + L + R}" height="{full_h}" '
           f'viewBox="0 0 {W + L + R} {full_h}" role="img" aria-label="{html.escape(title)}">'
           + text_lines(L, 16, head, 12),
           f'<rect x="{L}" y="{T}" width="{W}" height="{H}" fill="none" stroke="#999"/>']
    order = [k for k in pts if k != pick and k not in marked] + [k for k in marked if k in pts and k != pick]
    for k in order + ([pick] if pick in pts else []):
        x, y = at(*pts[k])
        tip = f"<title>{html.escape(k)}: {pts[k][0]:.6g}, {pts[k][1]:.6g}</title>"
        if k == pick:
            out.append(f'<text x="{x:.1f}" y="{y + 5:.1f}" text-anchor="middle" font-size="16" data-id="{html.escape(k)}"'
                       f'>★{tip}</text>')
        else:
            fill = PALETTE[0] if k in marked else "none"
            out.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="4" fill="{fill}" stroke="{PALETTE[0]}" '
                       f'data-id="{html.escape(k)}">{tip}</circle>')
    out.append(_axes_text(L, T, W, H, (x0, x1), (y0, y1), xl, ylabel, pad))
    return "".join(out)
