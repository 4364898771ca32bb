"""A fit's part of `report.html`: it opens with the verdict, whether the
calibrated model predicts the logs the fit did not see (``--validate``)
better than the nominal one, with the numbers of validation.csv; or a
warning where it is further from such a log than the nominal model in
bandwidth, phase or RMS error; or, with no such logs, that the fit was not
judged and how to judge it. Then the error on the logs it fitted, the
fitted parameters (on the actuators the logs cover), the validation's
table, bars and Bode plots."""

from __future__ import annotations

import base64
import html
import math
from pathlib import Path

from pupper_core._fit_freq import PHASE_AT
from pupper_core._report import Page, _breakable, _read, _table
from pupper_core._report_svg import bars, num, rounded

#: How much further from the log the calibrated model's -3 dB bandwidth
#: (Hz), phase (deg) or delay left unexplained (s) must lie than the
#: nominal model's to count as worse: the resolution `pupper fit` prints
#: them at (closer is noise).
BANDWIDTH_SAID, PHASE_SAID, DELAY_SAID = 0.01, 0.1, 1e-5


def _r(x: float, fmt: str = ".3g") -> str:
    """``x`` as a reader uses it, every digit in its tooltip."""
    return f'<span title="{float(x)!r}">{float(x):{fmt}}</span>'


def _deg(x: float) -> str:
    return _r(x, ".1f")


def _further(row: dict[str, str]) -> dict[str, str]:
    """What the calibrated model gets further from the log than the
    nominal model does, on one validated (log, joint) pair: the
    calibrated column, and what it says in words."""
    said = {}
    nom, cal = num(row.get("rms_nominal_rad")), num(row.get("rms_calibrated_rad"))
    if cal > nom:
        said["rms_calibrated_rad"] = f"RMS angle error {_r(cal * 1e3)} mrad against the nominal model's {_r(nom * 1e3)}"
    checks = [("bandwidth_hz", "−3 dB bandwidth", " Hz", BANDWIDTH_SAID)]
    checks += [(f"phase_{f:g}hz_deg", f"phase at {f:g} Hz", "°", PHASE_SAID) for f in PHASE_AT]
    for col, what, unit, said_at in checks:
        lg, n, c = (num(row.get(f"{col}_{m}")) for m in ("log", "nominal", "calibrated"))
        if all(math.isfinite(v) for v in (lg, n, c)) and abs(c - lg) > abs(n - lg) + said_at:
            r = _deg if unit == "°" else _r
            said[f"{col}_calibrated"] = (f"{what} {r(c)}{unit} against the log's {r(lg)}{unit} (the nominal "
                                         f"model's {r(n)}{unit})")
    # the pure delay that best explains the log's phase lag behind the model's: more left, phase worse
    n, c = num(row.get("delay_left_s_nominal")), num(row.get("delay_left_s_calibrated"))
    if math.isfinite(n) and math.isfinite(c) and abs(c) > abs(n) + DELAY_SAID:
        said["delay_left_s_calibrated"] = (f"delay left unexplained {_r(c * 1e3)} ms against the nominal "
                                           f"model's {_r(n * 1e3)} ms")
    return said


def _phase_said(rows: list[dict[str, str]]) -> str:
    """How near the log the calibrated model's phase lies at the highest
    of the reported frequencies the logs reach (10 Hz where they do),
    beside the nominal model's."""
    for f in sorted(PHASE_AT, reverse=True):
        col = f"phase_{f:g}hz_deg"
        gaps = [(abs(num(r.get(f"{col}_calibrated")) - num(r.get(f"{col}_log"))),
                 abs(num(r.get(f"{col}_nominal")) - num(r.get(f"{col}_log")))) for r in rows]
        gaps = [g for g in gaps if all(math.isfinite(x) for x in g)]
        if gaps:
            short = "" if f == max(PHASE_AT) else f" (the logs' sines do not reach {max(PHASE_AT):g} Hz)"
            return (f"phase at {f:g} Hz within {_deg(max(c for c, _ in gaps))}° of the log's (the nominal "
                    f"model's: within {_deg(max(n for _, n in gaps))}°){short}")
    return (f"no phase compared at {', '.join(f'{f:g}' for f in PHASE_AT)} Hz: the logs' sines do not reach "
            "them (a multisine has none); validate on stepped sines or chirps for the frequency response")


def verdict(rows: list[dict[str, str]], page: Page) -> str:
    """The fit's verdict from validation.csv's ``rows``: how much closer
    the calibrated model is to the logs it did not see than the nominal
    one (the RMS angle error over every pair, pooled) and its phase; or a
    warning naming each pair and quantity where it is further."""
    if not rows:
        return ("<p class='verdict unjudged'><b>Not judged on logs it did not see.</b> The errors below are on "
                "the logs the fit was fitted to: they say how well it fits them, not whether it predicts the "
                "robot elsewhere. Judge it with <code>--validate</code>: <code>pupper fit LOG... --validate "
                "OTHER_LOG...</code>, logs of the same motors at other gains (stepped sines or chirps, for the "
                "frequency response) that the fit does not use.</p>")
    logs = len({r.get("log") for r in rows})
    nom = math.sqrt(sum(num(r.get("rms_nominal_rad")) ** 2 for r in rows) / len(rows))
    cal = math.sqrt(sum(num(r.get("rms_calibrated_rad")) ** 2 for r in rows) / len(rows))
    ratio = nom / cal if cal > 0 else math.inf
    # a tenth closer or less is no gain a reader should act on
    how = (f"{_r(ratio)}× closer than the nominal one" if ratio >= 1.1 else
           f"about as close as the nominal one ({_r(ratio)}×)" if ratio >= 1 / 1.1 else
           f"{_r(1 / ratio)}× further than the nominal one")
    closeness = (f"the calibrated model is {how} (RMS angle error {_r(cal * 1e3)} mrad against "
                 f"{_r(nom * 1e3)} over {len(rows)} (log, joint) pair{'s' * (len(rows) > 1)}), {_phase_said(rows)}")
    worse = [(r, list(_further(r).values())) for r in rows]
    worse = [(r, w) for r, w in worse if w]
    seen = f"On the {logs} logs it did not see" if logs > 1 else "On the log it did not see"
    if not worse and ratio >= 1.1:
        return f"<p class='verdict good'><b>{seen}</b>, {closeness}.</p>"
    if not worse:
        return (f"<p class='verdict unjudged'><b>{seen}</b>, {closeness}: the calibration gains nothing there "
                "over the nominal model.</p>")
    page.warnings.append(f"the calibrated model lies further from the log than the nominal one on {len(worse)} of "
                         f"{len(rows)} validated (log, joint) pairs: see the verdict")
    items = "".join(f"<li>{html.escape(r.get('log', ''))} {html.escape(r.get('actuator', ''))}: "
                    + "; ".join(w) + "</li>" for r, w in worse)
    return (f"<div class='verdict bad'><p><b>Warning: on the logs it did not see, the calibrated model is further "
            f"from the log than the nominal model</b> in:</p><ul>{items}</ul><p>{seen}, {closeness}: an error "
            "in time can shrink while the response in frequency moves away. Read the Bode plots below before "
            "putting this model to use (a fit of more parameters, or of logs at more gains, may explain "
            "it).</p></div>")


def _logged(d: Path) -> list[str]:
    """The actuators the fit was fitted on (residuals.csv's), in order."""
    _, rows = _read(d / "residuals.csv")
    return list(dict.fromkeys(r.get("actuator", "") for r in rows if r.get("actuator")))


def fit_sections(page: Page) -> list[str]:
    """The verdict, the error before and after on the logs fitted (one
    scale), the fitted parameters, the validation, the warnings."""
    parts: list[str] = []
    fh, frows = _read(page.dir / "fit.csv")
    rh, rrows = _read(page.dir / "residuals.csv")
    vh, vrows = _read(page.dir / "validation.csv")
    page.answer.append(verdict(vrows, page))
    if rrows:
        before = [num(r["rms_before_rad"]) * 1e3 for r in rrows]
        after = [num(r["rms_after_rad"]) * 1e3 for r in rrows]
        page.answer.append(f"<p class='pick'>On the logs it fitted, RMS angle error over {len(rrows)} (log, "
                           f"actuator) pairs: before {rounded(repr(max(before)))} mrad at worst, after "
                           f"{rounded(repr(max(after)))} mrad at worst</p>")
        labels = [f"{r['log']} {r['actuator']}" for r in rrows]
        parts.append("<h2>Figures</h2>" + bars(labels, {"before (nominal model)": before,
                                                         "after (fitted model)": after},
                                               "RMS angle error before and after the fit (mrad, both on one scale)",
                                               unit=" mrad"))
    logged = _logged(page.dir)

    def actuators(h: str, row: dict[str, str]) -> str:
        # the logged ones: a parameter shared by every joint (--per all)
        # lists all twelve, though the logs saw one
        names = row.get(h, "").split()
        if h != "actuators" or not logged:
            return html.escape(row.get(h, ""))
        shown = [a for a in names if a in logged] or names
        more = len(names) - len(shown)
        return (html.escape(" ".join(shown)) + (f' <span class="note" title="{html.escape(row[h])}">(and {more} '
                                                 "more in calibrated.xml)</span>" if more else ""))

    note = ("<p class='note'>actuators: those the logs cover; a parameter fitted once for several joints "
            "(--per all, or group) is written to the others of calibrated.xml as well (their motors are taken "
            "to be alike).</p>") if any(len(r.get("actuators", "").split()) > len(logged) for r in frows) else ""
    page.answer.append("<h3>Fitted parameters (fit.csv)</h3>" + _table(fh, frows, set(), key="parameter",
                                                                         shown=actuators) + note)
    parts += _validation_sections(page.dir, vh, vrows)
    page.warnings.extend(page.manifest.get("warnings", []))
    return parts


def _validation_sections(d: Path, vh: list[str], vrows: list[dict[str, str]]) -> list[str]:
    """A fit's validation (fit --validate): its table, the RMS angle error
    of both models, and each log's Bode plot and residual (the PNG, inline)."""
    if not vrows:
        return []
    labels = [f"{r['log']} {r['actuator']}" for r in vrows]
    parts = ["<h2>Validation on logs not fitted (validation.csv)</h2>" + validation_table(vh, vrows),
             bars(labels, {"nominal model": [num(r["rms_nominal_rad"]) * 1e3 for r in vrows],
                           "calibrated model": [num(r["rms_calibrated_rad"]) * 1e3 for r in vrows]},
                  "RMS angle error on the validation logs (mrad, both on one scale)", unit=" mrad")]
    for png in sorted((d / "plots").glob("validate_*.png")):
        data = base64.b64encode(png.read_bytes()).decode("ascii")
        parts.append(f'<figure><img alt="{html.escape(png.name)}: Bode plot and residual" '
                     f'src="data:image/png;base64,{data}"><figcaption>{html.escape(png.name)}</figcaption></figure>')
    return parts


#: validation.csv's columns as the page groups them: the quantity (and
#: its unit), the column's pattern, the models, the scale to that unit.
COLUMNS: list[tuple[str, str, tuple[str, ...], float]] = [
    ("RMS angle error (mrad)", "rms_{}_rad", ("nominal", "calibrated"), 1e3),
    ("−3 dB bandwidth (Hz)", "bandwidth_hz_{}", ("log", "nominal", "calibrated"), 1.0),
    *[(f"phase at {f:g} Hz (°)", f"phase_{f:g}hz_deg_{{}}", ("log", "nominal", "calibrated"), 1.0) for f in PHASE_AT],
    ("delay left (ms)", "delay_left_s_{}", ("nominal", "calibrated"), 1e3),
]
SHORT = {"log": "log", "nominal": "nom.", "calibrated": "calib."}


def validation_table(header: list[str], rows: list[dict[str, str]]) -> str:
    """validation.csv as `pupper fit` prints it: a column group per
    quantity (log, nominal, calibrated beneath), in the reader's units
    (every digit of the file in each tooltip); a calibrated value further
    from the log than the nominal model's is shaded. Columns the page does
    not know follow, each by its name."""
    groups = [(what, col, [m for m in models if col.format(m) in header], scale)
              for what, col, models, scale in COLUMNS]
    groups = [g for g in groups if g[2]]
    known = {"log", "actuator"} | {col.format(m) for _, col, models, _ in groups for m in models}
    rest = [h for h in header if h not in known]
    top = ("<tr><th class='text' rowspan='2'>log</th><th class='text' rowspan='2'>joint</th>"
           + "".join(f"<th class='group' colspan='{len(models)}'>{html.escape(what)}</th>"
                     for what, _, models, _ in groups)
           + "".join(f"<th rowspan='2'>{_breakable(h)}</th>" for h in rest) + "</tr>")
    sub = "<tr>" + "".join(f"<th>{SHORT[m]}</th>" for _, _, models, _ in groups for m in models) + "</tr>"
    body = []
    for r in rows:
        worse = _further(r)
        cells = [f"<td class='text'>{_breakable(r.get('log', ''))}</td>",
                 f"<td class='text'>{_breakable(r.get('actuator', ''))}</td>"]
        for _, col, models, scale in groups:
            for m in models:
                v = r.get(col.format(m), "")
                x = num(v) * scale
                shown = html.escape(v) if math.isnan(x) else f"{x:.4g}"
                cls = " class='worse'" if col.format(m) in worse else ""
                cells.append(f'<td{cls} title="{html.escape(v)}">{shown}</td>')
        cells += [f'<td title="{html.escape(r.get(h, ""))}">{html.escape(r.get(h, ""))}</td>' for h in rest]
        body.append("<tr>" + "".join(cells) + "</tr>")
    return (f"<div class='scroll'><table><thead>{top}{sub}</thead><tbody>{''.join(body)}</tbody></table></div>"
            "<p class='note'>Shaded: the calibrated model further from the log than the nominal one.</p>")
