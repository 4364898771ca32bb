"""Every report kind laid out whole (issue 47): in each figure pupper
draws, no text outside the figure and no two texts on each other
(matplotlib's PNGs in plots/ as drawn when saved; report.html's inline SVG
as headless Chromium lays it out), and no table, figure or picture of
report.html past the edge of a 1280 px window (a table too wide scrolls in
its own box or wraps). A small run of each kind (sweep, replicated sweep,
lab, response, hold, tune, recommend; a fit's in test_fit_report.py);
each test's docstring names what it caught in the code before
(tests/figure_check.py measures)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from figure_check import (
    Drawn,
    assert_whole,
    chromium,
    figure_problems,
    page_layout,
    page_problems,
    problems,
    saved_figures,
)

pytestmark = pytest.mark.skipif(chromium() is None, reason="needs Debian's chromium (make test installs it)")


def drawn_plots(d: Path) -> list[Drawn]:
    """The run's plots/ drawn again here, as `--plot` draws them, each
    figure's texts recorded as it is saved."""
    from pupper_core import plots

    kind = json.loads((d / "manifest.json").read_text()).get("kind")
    with saved_figures() as figs:
        if kind == "tune":
            from pupper_core._tune_figures import write_plots

            write_plots(d)
        else:
            plots.write_plots(d)
    return figs


def test_the_checks_catch_what_they_look_for(tmp_path):
    """A text past a figure's edge, two texts on each other, a table
    wider than the window and a page that scrolls sideways are each
    caught (so their silence on the reports means something)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(3, 2), dpi=100)
    fig.text(0.9, 0.5, "past the right edge")
    fig.text(0.1, 0.2, "one text")
    fig.text(0.12, 0.2, "on another")
    with saved_figures() as figs:
        fig.savefig(tmp_path / "bad.png")
    found = figure_problems(figs)
    assert figs[0].name == "bad.png" and figs[0].size == (300, 200)
    assert any("'past the right edge' leaves the figure" in p for p in found), found
    assert any("'one text' overlaps 'on another'" in p for p in found), found
    assert problems("x", (10, 10), [("a", (0, 0, 5, 5)), ("b", (5.5, 0, 9, 5))]) == []
    run = tmp_path / "page"
    run.mkdir()
    cells = "".join(f"<th>column_{i}_with_a_long_name</th>" for i in range(40))
    svg = ('<svg width="200" height="50"><text x="150" y="20" font-size="12">out of the box</text>'
           '<text x="10" y="40" font-size="12">here</text><text x="14" y="40" font-size="12">there</text></svg>')
    (run / "report.html").write_text(f"<!DOCTYPE html><html><body>{svg}<table><tr>{cells}</tr></table>"
                                     "</body></html>")
    found = page_problems(page_layout(run / "report.html", tmp_path))
    assert any("'out of the box' leaves the figure" in p for p in found), found
    assert any("'here' overlaps 'there'" in p for p in found), found
    assert any(p.startswith("table 'column_0_with_a_long_name' is clipped") for p in found), found
    assert any(p.startswith("the page is") for p in found), found
    # the same table in a box that scrolls is whole
    (run / "report.html").write_text(f"<!DOCTYPE html><html><body><div style='overflow-x:auto'><table><tr>{cells}"
                                     "</tr></table></div></body></html>")
    assert page_problems(page_layout(run / "report.html", tmp_path)) == []


def test_a_sweeps_figures_and_table(run, tmp_path):
    """Before: summary.csv's table ran past a 1280 px window (its last
    columns off the screen). The sweep's other figures (presets' bars, a
    metric against one axis or grouped by another, a panel per third
    axis, a wide grid) drawn from made-up runs are checked alike."""
    d = tmp_path / "sweep"
    run("sweep", "-g", "kp=10,60", "-g", "kd=0.5,2", "--seconds", "2", "--trace", "-q", "-o", d, check=0)
    assert_whole(d, tmp_path, drawn_plots(d), {"base_z.png", "heatmap_last_1s_std_mm.png"})
    from test_plots_render import make_run

    shapes = [dict(cells=[{"name": "soft", "kp": 2.0, "kd": 0.05}, {"name": "default", "kp": 5.0, "kd": 0.1},
                          {"name": "underdamped", "kp": 20.0, "kd": 0.02}]),
              dict(axes={"kp": [5, 10, 20, 40, 80]}), dict(axes={"kp": [5, 20, 80, 320], "leg_scale": [0.8, 1.2]}),
              dict(axes={"kp": [10, 60], "kd": [1, 2], "leg_scale": [0.8, 1.0, 1.2]}),
              dict(axes={"kp": [10, 20, 30, 40, 60, 80, 120, 160, 240, 320], "kd": [0.5, 1, 2, 5]})]
    for k, shape in enumerate(shapes):
        made, _ = make_run(tmp_path / f"made{k}", **shape)
        figs = drawn_plots(made)
        assert len(figs) == 3 and figure_problems(figs) == [], (shape, figure_problems(figs))


def test_a_replicated_sweeps_figures_and_table(run, tmp_path):
    """Before: the p95 heatmap's title ran out of the figure's both sides
    on a 2 x 2 grid and its colour bar's label ran into the title; the
    table of the statistics ran 1600 px past the window."""
    d = tmp_path / "rep"
    run("sweep", "-g", "kp=10,30", "-g", "kd=0.5,1", "--replicates", "3", "--randomize", "torso_mass=±10%",
        "--seconds", "2", "--trace", "-q", "-o", d, check=0)
    assert_whole(d, tmp_path, drawn_plots(d), {"heatmap_p95_last_1s_std_mm.png", "spread_last_1s_std_mm.png",
                                               "heatmap_failure_fraction.png", "base_z.png"})


def test_a_labs_figures_and_table(run, tmp_path):
    """Before: summary.csv's table ran past the window."""
    d = tmp_path / "lab"
    run("lab", "-g", "kp=10,60", "-g", "kd=0.5,2", "--seconds", "2", "-q", "-o", d, check=0)
    assert_whole(d, tmp_path, drawn_plots(d), {"lab_heatmaps.png", "lab_best_base_z.png"})


def test_a_responses_figures_and_table(run, tmp_path):
    """Before: the per-group table ran 2000 px past the window; a chirp's
    Bode plot numbered its log frequency axis 3×10⁰ and 4×10⁰ on top of
    each other."""
    d = tmp_path / "step"
    run("response", "-g", "kp=5,20", "-g", "kd=0.1,0.5", "--seconds", "1.5", "--trace", "-q", "-o", d, check=0)
    assert_whole(d, tmp_path, drawn_plots(d), {"response_steps.png", "response_rise_time_s.png"})
    d = tmp_path / "chirp"
    run("response", "--signal", "chirp", "--chirp", "2,20", "-g", "kp=5,20", "-g", "kd=0.1", "--seconds", "2.5",
        "-q", "-o", d, check=0)
    figs = drawn_plots(d)
    assert_whole(d, tmp_path, figs, {"bode.png"}, svg=False)
    # the frequency axis numbered plainly, as a reader says it
    ticks = {t for f in figs for t, _ in f.texts}
    assert {"2", "5", "10", "20"} <= ticks, ticks


def test_a_holds_figures_and_table(run, tmp_path):
    """Before: summary.csv's table ran 900 px past the window."""
    d = tmp_path / "hold"
    run("hold", "-g", "kp=3,6", "-g", "kd=0.5", "--trace", "-q", "-o", d, check=0)
    assert_whole(d, tmp_path, drawn_plots(d), {"base_z.png", "compliance_mm_per_n_vs_kp.png"})


def test_a_tunes_figures_and_table(run, tmp_path):
    """Before: over log-scaled spaces, the trials figure numbered its Kp
    axis 1.5×10¹, 1.6×10¹, ... each on the next."""
    pytest.importorskip("optuna")
    d = tmp_path / "tune"
    run("tune", "--space", "kp=5:60:log", "--space", "kd=0.05:1:log", "--seconds", "2", "--trials", "4",
        "--batch", "4", "-q", "-o", d, check=0)
    assert_whole(d, tmp_path, drawn_plots(d), {"tune_progress.png", "tune_trials.png"})


def test_a_recommendations_figures_and_table(run, tmp_path):
    """Before: the candidates' table ran 1100 px past the window. (The
    smallest search that gives a card: two candidates on two robots, the
    pick's neighbours scored; about 25 s of CPU.)"""
    pytest.importorskip("optuna")
    d = tmp_path / "rec"
    run("recommend", "--trials", "2", "--batch", "2", "--robots", "2", "--polish", "0", "--seconds", "3.75", "-q",
        "-o", d, check=0)
    assert (d / "recommend.csv").is_file()
    assert_whole(d, tmp_path, [], set())


def test_a_line_or_scatter_figure_makes_room_for_long_numbers(tmp_path):
    """Before: a tune's best objective, 4.5e-05 to 0.0016 mm, numbered its
    y axis 0.0008447 across the axis's name (the plot's left edge was
    fixed at 70 px); a scatter alike."""
    from pupper_core._report_svg import lines, scatter

    ys = [0.001644, 0.0011, 0.0001349, 4.502e-05]
    svg = lines({"best so far": ([4002.0, 8004.0, 40000.0, 64030.0], ys)}, "best objective against cell-steps spent",
                "cell-steps", "last_1s_std_mm", pick="best so far")
    svg += scatter({f"trial {k}": (float(k), y) for k, y in enumerate(ys)}, "candidates", "x", "p95 push dip (mm)")
    d = tmp_path / "page"
    d.mkdir()
    from pupper_core._report import STYLE

    # in report.html's own style (its font)
    (d / "report.html").write_text(f"<!DOCTYPE html><html><head><style>{STYLE}</style></head><body>{svg}</body></html>")
    layout = page_layout(d / "report.html", tmp_path)
    assert len(layout["svgs"]) == 2 and any(len(t) == 9 and t.startswith("0.000") for s in layout["svgs"] for t, _ in s["texts"])
    assert page_problems(layout) == []
