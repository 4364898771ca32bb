"""Layout checks of the figures pupper draws (issue 47): every text inside
its figure and no two texts on each other, in the matplotlib PNGs (their
texts as drawn when the file was saved) and in report.html's inline SVG;
and in report.html no table, figure or picture past the window's edge
(read back in headless Chromium at 1280 px: a table too wide for the page
must scroll in its own box or wrap, never leave columns off the screen)."""

from __future__ import annotations

import html
import json
import re
import shutil
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from itertools import combinations
from pathlib import Path

#: Pixels a text box may stick out or two may touch (anti-aliasing, a
#: font's rounding): less than a stroke of a letter.
TOL = 1.5
#: The window the page is read in.
WIDTH = 1280

Box = tuple[float, float, float, float]  # x0, y0, x1, y1


@dataclass
class Drawn:
    """A figure as saved: its name, size (px) and drawn texts with their boxes."""

    name: str
    size: tuple[float, float]
    texts: list[tuple[str, Box]] = field(default_factory=list)
    #: the last drawing of each text (a figure with a layout engine is drawn twice on saving)
    drawn: dict[int, tuple[str, Box]] = field(default_factory=dict)


def _overlap(a: Box, b: Box) -> bool:
    return min(a[2], b[2]) - max(a[0], b[0]) > TOL and min(a[3], b[3]) - max(a[1], b[1]) > TOL


def problems(name: str, size: tuple[float, float], texts: list[tuple[str, Box]]) -> list[str]:
    """Each text outside the figure, each pair of texts on each other."""
    w, h = size
    out = [f"{name}: {t!r} leaves the figure ({b[0]:.0f}, {b[1]:.0f})-({b[2]:.0f}, {b[3]:.0f}) of {w:.0f}x{h:.0f}"
           for t, b in texts if b[0] < -TOL or b[1] < -TOL or b[2] > w + TOL or b[3] > h + TOL]
    out += [f"{name}: {a!r} overlaps {b!r}" for (a, ba), (b, bb) in combinations(texts, 2) if _overlap(ba, bb)]
    return out


@contextmanager
def saved_figures() -> Iterator[list[Drawn]]:
    """Records every matplotlib figure saved inside the block: the texts
    its drawing drew (tick labels that fall outside the axes' view are
    never drawn, so never counted) with their boxes at the saved size."""
    import matplotlib.figure
    import matplotlib.text

    got: list[Drawn] = []
    current: list[Drawn] = []
    draw, savefig = matplotlib.text.Text.draw, matplotlib.figure.Figure.savefig

    def text_draw(self, renderer):  # type: ignore[no-untyped-def]
        draw(self, renderer)
        if current and self.get_visible() and self.get_text().strip():
            e = self.get_window_extent(renderer)
            # matplotlib's y axis points up; the figure's box is (0, 0)-(w, h) either way
            current[-1].drawn[id(self)] = (self.get_text(), (e.x0, e.y0, e.x1, e.y1))
            current[-1].size = (renderer.width, renderer.height)

    def fig_savefig(self, fname, *a, **kw):  # type: ignore[no-untyped-def]
        name = Path(str(fname)).name if isinstance(fname, (str, Path)) else "figure"
        # atomic_write's temporary name: .NAME.tmpPID
        name = re.sub(r"^\.(.+)\.tmp\d+$", r"\1", name)
        current.append(Drawn(name, (0.0, 0.0)))
        try:
            return savefig(self, fname, *a, **kw)
        finally:
            done = current.pop()
            done.texts = list(done.drawn.values())
            got.append(done)

    matplotlib.text.Text.draw = text_draw
    matplotlib.figure.Figure.savefig = fig_savefig
    try:
        yield got
    finally:
        matplotlib.text.Text.draw = draw
        matplotlib.figure.Figure.savefig = savefig


def figure_problems(figures: list[Drawn]) -> list[str]:
    return [p for f in figures for p in problems(f.name, f.size, f.texts)]


# what the page measures of itself once drawn, written into the page for --dump-dom
PROBE = """<script>
(function () {
  var W = document.documentElement.clientWidth, out = {width: W, scroll: document.documentElement.scrollWidth,
    svgs: [], boxes: []};
  function box(r) { return [r.left, r.top, r.right, r.bottom]; }
  // the part of the window an element can be seen in: narrowed by every box around it that clips or scrolls
  function seen(el) {
    var right = W, scroller = null;
    for (var p = el.parentElement; p; p = p.parentElement) {
      var o = getComputedStyle(p).overflowX;
      if (o !== 'visible') {
        right = Math.min(right, p.getBoundingClientRect().right);
        if ((o === 'auto' || o === 'scroll') && !scroller) scroller = p;
      }
    }
    return {right: right, scrolls: !!scroller && scroller.scrollWidth > scroller.clientWidth,
            scroller_right: scroller ? scroller.getBoundingClientRect().right : null};
  }
  document.querySelectorAll('svg').forEach(function (svg) {
    var texts = [];
    svg.querySelectorAll('text').forEach(function (t) {
      if (t.textContent.trim()) texts.push([t.textContent, box(t.getBoundingClientRect())]);
    });
    out.svgs.push({label: svg.getAttribute('aria-label') || '', box: box(svg.getBoundingClientRect()),
                   texts: texts});
  });
  document.querySelectorAll('table, svg, img, pre').forEach(function (el) {
    var s = seen(el), first = el.querySelector('th') || el;
    out.boxes.push({tag: el.tagName.toLowerCase(), what: (el.getAttribute('aria-label') || el.getAttribute('alt')
                    || first.textContent || '').slice(0, 60), box: box(el.getBoundingClientRect()),
                    right: s.right, scrolls: s.scrolls, scroller_right: s.scroller_right});
  });
  var pre = document.createElement('pre');
  pre.id = 'layout-probe';
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
})();
</script>"""


def chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


def page_layout(page: Path, work: Path, width: int = WIDTH) -> dict:
    """report.html as headless Chromium lays it out in a window ``width``
    px wide: each SVG's box and its texts' boxes, and each table's, SVG's,
    picture's and preformatted block's box with the right edge it can be
    seen to (the window, or a box around it that clips or scrolls)."""
    work.mkdir(parents=True, exist_ok=True)
    probe = work / f"probe_{page.parent.name}.html"
    text = page.read_text()
    probe.write_text(text.replace("</body>", PROBE + "</body>"))
    exe = chromium()
    assert exe is not None
    p = subprocess.run([exe, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
                        "--disable-background-networking", "--disable-component-update", "--disable-sync",
                        "--hide-scrollbars", "--host-resolver-rules=MAP * ~NOTFOUND",
                        f"--window-size={width},1800", "--dump-dom", probe.as_uri()],
                       capture_output=True, text=True, timeout=120)
    m = re.search(r'<pre id="layout-probe">(.*?)</pre>', p.stdout, re.S)
    assert m, p.stderr[-2000:]
    return json.loads(html.unescape(m.group(1)))


def page_problems(layout: dict) -> list[str]:
    """Every SVG text outside its figure or on another, every table,
    figure or picture that leaves the window (past the visible edge and not
    in a box of its own that scrolls), and a page wider than the window."""
    out: list[str] = []
    for svg in layout["svgs"]:
        x0, y0 = svg["box"][0], svg["box"][1]
        size = (svg["box"][2] - x0, svg["box"][3] - y0)
        texts = [(t, (b[0] - x0, b[1] - y0, b[2] - x0, b[3] - y0)) for t, b in svg["texts"]]
        out += problems(f"svg {svg['label'][:60]!r}", size, texts)
    for b in layout["boxes"]:
        if b["box"][2] > b["right"] + TOL and not (b["scrolls"] and b["scroller_right"] <= layout["width"] + TOL):
            out.append(f"{b['tag']} {b['what']!r} is clipped: its right edge {b['box'][2]:.0f} px lies past "
                       f"{b['right']:.0f} px, the edge it can be seen to, and nothing scrolls it into view")
    if layout["scroll"] > layout["width"]:
        out.append(f"the page is {layout['scroll']} px wide in a {layout['width']} px window: what lies past "
                   "its right edge is off the screen")
    return out


def assert_whole(d: Path, work: Path, figs: list[Drawn], want_figures: set[str], svg: bool = True) -> None:
    """Every figure of ``figs`` and report.html's SVG and tables laid out
    whole; the figures named in ``want_figures`` among them, and SVG on
    the page where ``svg`` (no check passes on nothing drawn)."""
    assert want_figures <= {f.name for f in figs}, [f.name for f in figs]
    assert all(f.texts for f in figs)
    layout = page_layout(d / "report.html", work)
    assert any(b["tag"] == "table" for b in layout["boxes"]), layout["boxes"]
    assert bool(layout["svgs"]) or not svg
    found = figure_problems(figs) + page_problems(layout)
    assert not found, "\n".join(found)


