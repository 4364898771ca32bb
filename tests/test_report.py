"""report.html: every run directory's page, opened in headless Chromium
(Debian's package; `make test` installs it): no console error, no network
request beyond what Chromium makes by itself on an empty page, a screenshot
that is not blank, and the best cell's numbers as summary.csv has them."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path
from urllib.parse import urlsplit

import pupper_core as pc
import pytest

from conftest import read_csv

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (make test installs it)")


def browse(page: Path, work: Path, *, dom: bool = False) -> dict:
    """Opens ``page`` in headless Chromium with every host unresolvable:
    the console lines, the URLs it asked for (scheme, host and path), the
    screenshot and, with ``dom``, the page's text after its script ran."""
    work.mkdir(parents=True, exist_ok=True)
    net, shot = work / f"{page.stem}.net.json", work / f"{page.stem}.png"
    common = [CHROMIUM, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
              "--disable-background-networking", "--disable-component-update", "--disable-sync",
              "--host-resolver-rules=MAP * ~NOTFOUND", "--window-size=1200,1800"]
    p = subprocess.run(common + ["--enable-logging=stderr", "--v=0", f"--log-net-log={net}",
                                 f"--screenshot={shot}", page.as_uri()],
                       capture_output=True, text=True, timeout=120)
    urls = {f"{u.scheme}://{u.netloc}{u.path}" for u in map(urlsplit, re.findall(r'"url":"([^"]+)"', net.read_text()))
            if u.scheme in ("http", "https", "ws", "wss", "ftp")}
    out = {"console": [ln for ln in p.stderr.splitlines() if ":CONSOLE" in ln], "urls": urls, "shot": shot}
    if dom:
        d = subprocess.run(common + ["--dump-dom", page.as_uri()], capture_output=True, text=True, timeout=120)
        out["dom"] = d.stdout
    return out


def not_blank(png: Path) -> bool:
    from PIL import Image

    img = Image.open(png).convert("RGB").resize((300, 450))
    colours = img.getcolors(maxcolors=1 << 16) or []
    return len(colours) > 20 and sum(n for n, c in colours if c != (255, 255, 255)) > 0.05 * 300 * 450


@pytest.fixture(scope="module")
def baseline(tmp_path_factory) -> set[str]:
    d = tmp_path_factory.mktemp("empty")
    (d / "empty.html").write_text("<!DOCTYPE html><html><body></body></html>")
    return browse(d / "empty.html", d)["urls"]


def test_the_checks_can_fail(tmp_path, baseline):
    """A page with a script error and a picture from the network is caught
    by both checks (so their silence on the reports means something)."""
    bad = tmp_path / "bad.html"
    bad.write_text('<!DOCTYPE html><html><body><img src="http://example.invalid/pixel.png">'
                   "<script>undefinedFunction();</script></body></html>")
    got = browse(bad, tmp_path)
    assert any("Uncaught ReferenceError" in ln for ln in got["console"]), got["console"]
    assert got["urls"] - baseline == {"http://example.invalid/pixel.png"}


def check_page(run_dir: Path, work: Path, baseline: set[str]) -> str:
    page = run_dir / "report.html"
    assert page.is_file()
    text = page.read_text()
    # nothing to fetch: no script, style, font or picture from elsewhere
    assert not re.search(r'(src|href)\s*=\s*"(https?:)?//', text)
    got = browse(page, work, dom=True)
    assert got["console"] == [], got["console"]
    assert got["urls"] <= baseline, got["urls"] - baseline
    assert not_blank(got["shot"])
    return got["dom"]


def answer_of(dom: str) -> str:
    """The block the page opens with: the pick, the rule, the warnings."""
    m = re.search(r'<section id="answer">(.+?)</section>', dom, re.S)
    assert m and dom.index('<section id="answer">') < dom.index("<h2>Figures</h2>"), dom[:2000]
    return m.group(1)


def shown_as_in(para: str, header: list[str], row: dict[str, str], skip=("index", "name", "id")) -> None:
    """Each of the row's values in the paragraph: every digit in its
    tooltip, as the table has it; shown rounded."""
    for h in header:
        if h not in skip and row[h] != "":
            m = re.search(rf'{re.escape(h)} <span title="{re.escape(row[h])}">([^<]+)</span>', para)
            assert m, (h, row[h], para[:500])
            try:
                assert float(m.group(1)) == pytest.approx(float(row[h]), rel=1e-3, abs=1e-6)
            except ValueError:
                assert m.group(1) == row[h]  # text (a status)


def few_digits(dom: str) -> None:
    """No number above the inputs printed with more than 6 significant
    digits outside tooltips (attributes and SVG titles)."""
    text = dom[: dom.index("<h2>Inputs")]
    text = re.sub(r"<title>[^<]*</title>|<style>.*?</style>", "", text, flags=re.S)
    text = re.sub(r"<[^>]*>", " ", text)
    for number in re.findall(r"\d[\d.]*(?:e-?\d+)?", text):
        digits = number.split("e")[0].replace(".", "").lstrip("0")
        assert len(digits) <= 6, number


def embedded(dom: str) -> None:
    """Figures inline: SVG, or pictures as data: URIs; nothing to fetch."""
    assert "<svg" in dom.split("<h2>Figures</h2>", 1)[1]
    assert not re.search(r'<img[^>]+src="(?!data:)', dom)


def drawn(dom: str, cell: str) -> bool:
    """``cell`` has a line of its own in a trace figure (bold, the pick's)."""
    return f'stroke-width="2.6" data-id="{cell}"' in dom


def best_cell_shown(run_dir: Path, dom: str) -> str:
    best = pc.load_run(run_dir).best()
    assert best is not None
    header, rows = read_csv(run_dir / "summary.csv")
    row = next(r for r in rows if r["id"] == best["id"])
    answer = answer_of(dom)
    para = re.search(r'<p class="pick" data-id="([^"]+)"><b>([^<]+)</b>: (.+?)</p>', answer)
    assert para and para.group(1) == para.group(2) == best["id"], answer[:2000]
    shown_as_in(para.group(3), header, row)
    few_digits(dom)
    embedded(dom)
    return answer


def test_a_sweeps_report(run, tmp_path, baseline):
    out = tmp_path / "sweep"
    p = run("sweep", "-g", "kp=10,30,60,120", "-g", "kd=0.5,1,2,5", "--seconds", "4", "--trace",
            "-o", out, check=0)
    # the command prints the page's path last
    assert p.stderr.strip().splitlines()[-1] == f"wrote {out / 'report.html'}"
    dom = check_page(out, tmp_path / "b1", baseline)
    answer = best_cell_shown(out, dom)
    best = pc.load_run(out).best()["id"]
    # the warnings that qualify the pick, beside it: cells past the bound,
    # the pick on the grid's edge (kp 120), the cells its metric ties with
    assert "lie past the stability bound" in answer
    assert f"the picked cell {best} lies on the edge of the searched grid (kp 120, the largest)" in answer
    assert re.search(r"\d other cells? \([^)]+\) tie with the pick on last_1s_std_mm: push_dip_mm decided",
                     answer), answer
    figures = dom.split("<h2>Figures</h2>", 1)[1]
    # the map of what decided (the push dip) before the near-tied steadiness, the pick starred
    assert figures.index('aria-label="push_dip_mm heatmap"') < figures.index('aria-label="last_1s_std_mm heatmap"')
    assert figures.count(" ★</text>") == 2
    # the winner in the base-height figure (bold), whatever its place in the grid
    assert drawn(dom, best)
    assert 'href="summary.csv"' in dom


def test_a_saturated_run_says_so_beside_no_pick(run, tmp_path):
    """Every cell at its torque limit: the answer is that no cell is
    eligible, and the warning beside it says why."""
    out = tmp_path / "sat"
    run("sweep", "-g", "kp=30,60", "-g", "kd=0.5", "--max-torque", "0.9", "--seconds", "3", "-q", "-o", out, check=0)
    answer = answer_of((out / "report.html").read_text())
    assert '<p class="pick"' not in answer and "no cell is eligible" in answer
    assert "2 of 2 cells saturated (at the torque limit in 5 % or more of actuator-steps)" in answer


def test_a_labs_report(run, tmp_path, baseline):
    out = tmp_path / "lab"
    run("lab", "--seconds", "3", "-q", "-o", out, check=0)
    dom = check_page(out, tmp_path / "b2", baseline)
    assert "pupper lab" in dom
    header, rows = read_csv(out / "summary.csv")
    _, picks = read_csv(out / "best.csv")
    answer = answer_of(dom)
    # a pick per body, its numbers rounded and in full in the tooltips
    assert len(picks) == 3
    for pick in picks:
        para = re.search(rf'<p class="pick" data-body="{pick["variant"]}"><b>[^<]+</b>: <b>([^<]+)</b>: (.+?)</p>',
                         answer)
        assert para and para.group(1) == pick["id"], answer[:2000]
        shown_as_in(para.group(2), header, next(r for r in rows if r["id"] == pick["id"]),
                    skip=("index", "name", "id", "variant"))
        # each body's traces, its pick drawn
        assert drawn(dom, pick["id"])
    assert "lie past the stability bound" in answer
    few_digits(dom)
    embedded(dom)


def test_a_responses_report(run, tmp_path, baseline):
    out = tmp_path / "resp"
    run("response", "-g", "kp=5,20", "-g", "kd=0.1,0.5", "--seconds", "1.5", "--trace", "-q", "-o", out, check=0)
    dom = check_page(out, tmp_path / "b3", baseline)
    assert "rise_time_s per cell, a bar per joint group" in dom
    # per group, the cell that settles soonest, its numbers as summary.csv has them
    header, rows = read_csv(out / "summary.csv")
    answer = answer_of(dom)
    for g in ("haa", "hfe", "kfe"):
        ok = [r for r in rows if r[f"status.{g}"] == "ok"]
        want = min(ok, key=lambda r: float(r[f"settling_time_s.{g}"]))
        para = re.search(rf'<p class="pick" data-group="{g}">{g}: <b>([^<]+)</b>: (.+?)</p>', answer)
        assert para and para.group(1) == want["id"], (g, answer[:3000])
        shown_as_in(para.group(2), [h for h in header if h.endswith(f".{g}") or h in ("kp", "kd")], want)
        # its step curve, bold, zoomed to three of its settling times
        step = re.search(rf'aria-label="{g}: angle change / step[^"]*">(.+?)</svg>', dom)
        assert step and drawn(step.group(1), want["id"]), g
        ends = re.findall(r'text-anchor="middle" font-size="10">([\d.e+-]+)</text>', step.group(1))
        assert float(ends[-1]) <= 3 * float(want[f"settling_time_s.{g}"]) + 1e-9
    few_digits(dom)
    embedded(dom)


def test_overshoot_below_the_simulations_resolution_is_shown_as_none():
    from pupper_core._report_svg import fmt

    assert fmt("9.91e-10", "overshoot_pct.kfe") == "0"
    assert fmt("0.0572", "overshoot_pct.kfe") == "0.0572"
    assert fmt("9.91e-10", "tracking_rms") == "9.91e-10"


def test_a_heatmap_greys_what_no_rule_picks():
    """Saturated and past-bound cells grey with their word, fallen red, the
    ramp spanning the rest; the pick starred."""
    from pupper_core._report_svg import heatmap

    rows = [{"id": f"c{i}", "kp": str(kp), "kd": "1", "m": str(v), "status": s}
            for i, (kp, v, s) in enumerate([(1, 0.1, "ok"), (2, 0.01, "saturated"), (3, 0.001, "past_bound"),
                                            (4, 5.0, "fell"), (5, 0.2, "ok")])]
    svg = heatmap(rows, "kp", "kd", "m", "c0")
    fills = re.findall(r'<rect [^>]*fill="(#[0-9a-f]+)"', svg)
    assert fills == ["#fde725", "#d0d0d0", "#d0d0d0", "#f0c0c0", "#440154"]
    assert ">saturated<" in svg and ">past bound<" in svg and "0.1 ★" in svg


def test_a_tunes_report_shows_its_best_trial_as_a_table(run, tmp_path, baseline):
    out = tmp_path / "tune"
    run("tune", "--space", "kp=5:50", "--space", "kd=0.1:1", "--seconds", "3", "--trials", "4", "--batch", "4",
        "-q", "-o", out, check=0)
    dom = check_page(out, tmp_path / "b4", baseline)
    answer = answer_of(dom)
    best = json.loads((out / "best.json").read_text())
    assert len(best) == 1 and "<pre>" not in dom
    # in a box that scrolls sideways where the page is too narrow for it
    table = re.search(r'<h3>Best trial \(best.json\)</h3><div class="scroll"><table.+?</table></div>', answer, re.S)
    assert table, answer
    for name, value in [*best[0]["params"].items(), *zip(best[0]["objectives"], best[0]["values"])]:
        # a long column name may wrap after its underscores
        assert f'<th class="">{name}</th>' in table.group(0).replace("<wbr>", "")
        assert f'<td title="{value!r}">{value:.4g}</td>' in table.group(0)
    few_digits(dom)
    embedded(dom)


def test_a_fits_report_draws_before_and_after_on_one_log_scale(run, tmp_path, baseline):
    import mujoco

    spec = mujoco.MjSpec.from_file(str(Path(pc.__file__).parents[2] / "models/pupper_v3/pupper_v3.xml"))
    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_HINGE:
            joint.damping[0] = 0.02
    (tmp_path / "robot.xml").write_text(spec.to_xml())
    run("excite", "--model", tmp_path / "robot.xml", "--seconds", "0.5", "--hold", "0.2", "-o", tmp_path / "log.csv",
        check=0)
    run("fit", tmp_path / "log.csv", "--params", "damping", "-o", tmp_path / "fit", check=0)
    dom = check_page(tmp_path / "fit", tmp_path / "b5", baseline)
    answer = answer_of(dom)
    assert "RMS angle error over 12 (log, actuator) pairs" in answer and "Fitted parameters" in answer
    # one figure, both series on one scale; logarithmic: after is decades below before
    assert dom.count('aria-label="RMS angle error before and after the fit') == 1
    assert "(log scale)" in dom and "after (fitted model)" in dom
    few_digits(dom)
    embedded(dom)


def test_report_of_any_run_and_of_no_run(run, tmp_path):
    out = tmp_path / "s"
    pc.sweep({"kp": [10, 60]}, seconds=2, out=out, progress=False)
    page = out / "report.html"
    assert page.is_file()
    page.unlink()
    p = run("report", out, check=0)
    assert p.stderr.strip() == f"wrote {page}" and page.is_file()
    assert pc.report(out) == str(page)
    p = run("report", tmp_path / "nothing", check=2)
    assert p.stderr.count("\n") == 1 and "no manifest.json" in p.stderr
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"]
