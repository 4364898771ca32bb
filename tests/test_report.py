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


def best_cell_shown(run_dir: Path, dom: str) -> None:
    best = pc.load_run(run_dir).best()
    assert best is not None
    header, rows = read_csv(run_dir / "summary.csv")
    row = next(r for r in rows if r["id"] == best["id"])
    para = re.search(r"<h2>Best cell</h2><p><b>([^<]+)</b>: (.+?)</p>", dom)
    assert para and para.group(1) == best["id"], dom[:2000]
    for h in header:
        if h not in ("index", "name") and row[h] != "":
            # every digit in the tooltip, as summary.csv has it; shown rounded
            m = re.search(rf'{re.escape(h)} <span title="{re.escape(row[h])}">([^<]+)</span>', para.group(2))
            assert m, (h, row[h], para.group(2)[:500])
            try:
                assert float(m.group(1)) == pytest.approx(float(row[h]), rel=1e-3, abs=1e-12)
            except ValueError:
                assert m.group(1) == row[h]  # text (a status)
    # no number with more than 6 significant digits outside the tooltips
    text = re.sub(r'title="[^"]*"', "", para.group(2))
    for number in re.findall(r"\d[\d.]*(?:e-?\d+)?", text):
        digits = number.split("e")[0].replace(".", "").lstrip("0")
        assert len(digits) <= 6, number


def test_a_sweeps_report(run, tmp_path, baseline):
    out = tmp_path / "sweep"
    p = run("sweep", "-g", "kp=10,30,60,120", "-g", "kd=0.5,1,2,5", "--seconds", "4", "--trace",
            "-o", out, check=0)
    # the command prints the page's path last
    assert p.stderr.strip().splitlines()[-1] == f"wrote {out / 'report.html'}"
    dom = check_page(out, tmp_path / "b1", baseline)
    best_cell_shown(out, dom)
    assert "saturated" in dom and "<svg" in dom and 'href="summary.csv"' in dom


def test_a_labs_report(run, tmp_path, baseline):
    out = tmp_path / "lab"
    run("lab", "--seconds", "3", "-q", "-o", out, check=0)
    dom = check_page(out, tmp_path / "b2", baseline)
    assert "pupper lab" in dom


def test_a_responses_report(run, tmp_path, baseline):
    out = tmp_path / "resp"
    run("response", "-g", "kp=5,20", "-g", "kd=0.1,0.5", "--seconds", "1.5", "-q", "-o", out, check=0)
    dom = check_page(out, tmp_path / "b3", baseline)
    assert "rise_time_s.hfe per cell" in dom
    # per group, the cell that settles soonest, its numbers as summary.csv has them
    header, rows = read_csv(out / "summary.csv")
    for g in ("haa", "hfe", "kfe"):
        ok = [r for r in rows if r[f"status.{g}"] == "ok"]
        want = min(ok, key=lambda r: float(r[f"settling_time_s.{g}"]))
        para = re.search(rf'<p class="pick" data-group="{g}">{g}: <b>([^<]+)</b>: ([^<]+)</p>', dom)
        assert para and para.group(1) == want["id"], (g, dom[:3000])
        for m in ("rise_time_s", "settling_time_s", "overshoot_pct"):
            assert f"{m}.{g} {want[f'{m}.{g}']}" in para.group(2)


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
