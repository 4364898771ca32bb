"""Tests of pupper_core.plots and pupper_core.render that need no native module.

The modules are loaded straight from python/pupper_core/ so these tests run
before (or without) the Rust extension being built. Run them with
``MUJOCO_GL=egl`` on a headless machine.
"""

from __future__ import annotations

import importlib.util
import json
import math
import sys
import types
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from conftest import assert_drawn_as_traced

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "python" / "pupper_core"


def _load(name: str) -> types.ModuleType:
    """Imports pupper_core.<name> from the source tree without running __init__."""
    full = f"pupper_core.{name}"
    if full in sys.modules:
        return sys.modules[full]
    if "pupper_core" not in sys.modules:
        try:
            import pupper_core  # noqa: F401  (the real package, when it imports)
        except Exception:  # noqa: BLE001 - the native part may be missing
            stub = types.ModuleType("pupper_core")
            stub.__path__ = [str(PKG)]  # type: ignore[attr-defined]
            sys.modules["pupper_core"] = stub
    spec = importlib.util.spec_from_file_location(full, PKG / f"{name}.py")
    assert spec and spec.loader
    mod = importlib.util.module_from_spec(spec)
    sys.modules[full] = mod
    spec.loader.exec_module(mod)
    return mod


plots = _load("plots")
render = _load("render")

#: summary.csv's metric columns, as the Rust core names them
METRIC_COLS = list(sys.modules["pupper_core"].METRICS)


def _fmt(v: Any) -> str:
    if isinstance(v, str):
        return v
    return "" if v is None or (isinstance(v, float) and math.isnan(v)) else repr(float(v))


def make_run(
    root: Path,
    axes: dict[str, list[float]] | None = None,
    *,
    cells: list[dict[str, Any]] | None = None,
    traces: bool = True,
) -> tuple[Path, list[dict[str, Any]]]:
    """Writes a fake run directory; returns it and its rows (dicts)."""
    rows: list[dict[str, Any]] = []
    if cells is None:
        assert axes is not None
        names = list(axes)
        combos: list[dict[str, float]] = [{}]
        for a in names:
            combos = [dict(c, **{a: v}) for c in combos for v in axes[a]]
        cells = combos
    axis_names = [k for k in cells[0] if k != "name"]
    for i, c in enumerate(cells):
        kp, kd = float(c.get("kp", 5.0)), float(c.get("kd", 0.1))
        ls = float(c.get("leg_scale", 1.0))
        # a smooth made-up landscape with its minimum near kp=60, kd=2
        std = 0.05 + 0.3 * (math.log(kp / 60.0)) ** 2 + 0.2 * (math.log(kd / 2.0)) ** 2 + 0.1 * (ls - 1.0) ** 2
        dip = 40.0 / (1.0 + kp / 20.0) + 2.0 * kd
        status = "ok"
        if kp <= 10 and kd <= 0.5:
            status = "fell"
            std = 0.001  # lying still on the floor: tiny std, must not be "best"
        if kp >= 120 and kd >= 5:
            status = "diverged"
            std, dip = float("nan"), float("nan")
        row = {
            "index": i,
            "id": f"c{i:03d}",
            "name": c.get("name", ""),
            **{a: c[a] for a in axis_names},
            "final_z": 0.2,
            "last_1s_std_mm": std,
            "push_dip_mm": dip,
            "settle_time_s": 0.5,
            "max_tilt_deg": 1.0,
            "peak_torque": 1.5,
            "saturation_frac": 0.0,
            "tracking_rms": 0.01,
            "status": status,
            "event_time": float("nan") if status == "ok" else 3.0,
        }
        rows.append(row)
    run = root / "run"
    run.mkdir(parents=True)
    header = ["index", "id", "name", *axis_names, *METRIC_COLS]
    lines = [",".join(header)]
    for r in rows:
        lines.append(",".join(str(r[h]) if h in ("index", "id", "name", "status") else _fmt(r[h]) for h in header))
    (run / "summary.csv").write_text("\n".join(lines) + "\n")
    manifest = {
        "config": {
            "model": {"builtin": "pupper_v3"},
            "grid": {"axes": [{"axis": a} for a in axis_names]},
            "schedule": {
                "duration": 10.0,
                "push": {"start": 2.0, "duration": 0.25, "force": [0, 0, -25], "body": ""},
            },
            "mode": "servo",
            "defaults": {"kp": 5, "kd": 0.1, "max_torque": 3},
        },
        "model": {"name": "pupper_v3", "source": "builtin", "sha256": "0" * 64},
    }
    if any(c.get("name") for c in cells):
        manifest["config"]["grid"]["explicit"] = [[c[a] for a in axis_names] for c in cells]
    (run / "manifest.json").write_text(json.dumps(manifest, indent=2))
    if traces:
        t = np.arange(0.0, 10.0, 0.02) + 0.02
        tl = ["id,t,z"]
        for r in rows:
            kp = float(r.get("kp", 5.0))
            z = 0.2 - 0.01 * np.exp(-t) - np.where((t >= 2.0) & (t < 3.0), 0.02 / (1 + kp / 20) * np.exp(-(t - 2.0) * 4), 0.0)
            tl += [f"{r['id']},{a:.4f},{b:.6f}" for a, b in zip(t, z)]
        (run / "traces.csv").write_text("\n".join(tl) + "\n")
    return run, rows


def _check_png(path: Path, min_w: int = 300, min_h: int = 200) -> None:
    from PIL import Image

    assert path.exists(), path
    with Image.open(path) as im:
        im.verify()
    with Image.open(path) as im:
        assert im.format == "PNG"
        assert im.width >= min_w and im.height >= min_h, im.size
        arr = np.asarray(im.convert("RGB"), dtype=float)
        assert arr.std() > 5.0, "image is blank"


def _no_temp_files(d: Path) -> None:
    left = [p.name for p in d.iterdir() if ".tmp" in p.name or p.name.startswith(".")]
    assert not left, left


# ---------------------------------------------------------------------------
# plots


def test_read_run(tmp_path: Path) -> None:
    run, rows = make_run(tmp_path, {"kp": [10, 30, 60, 120], "kd": [0.5, 1, 2, 5]})
    table, manifest, traces = plots.read_run(run)
    assert table["id"] == [r["id"] for r in rows]
    assert isinstance(table["status"], list) and isinstance(table["name"], list)
    assert table["kp"].dtype == float and len(table["kp"]) == 16
    assert np.isnan(table["last_1s_std_mm"][-1])  # empty field -> NaN
    assert manifest["config"]["mode"] == "servo"
    assert set(traces) == {r["id"] for r in rows}
    t, z = traces["c000"]
    assert t.shape == z.shape and t.size == 500
    assert plots.grid_axes(table) == ["kp", "kd"]


def test_write_run_plots_kp_kd_grid(tmp_path: Path) -> None:
    run, _ = make_run(tmp_path, {"kp": [10, 30, 60, 120], "kd": [0.5, 1, 2, 5]})
    paths = plots.write_run_plots(run)
    names = sorted(p.name for p in paths)
    assert names == ["base_z.png", "heatmap_last_1s_std_mm.png", "heatmap_push_dip_mm.png"]
    for p in paths:
        assert p.parent == run / "plots"
        _check_png(p)
    _no_temp_files(run / "plots")


def test_write_run_plots_third_axis_panels(tmp_path: Path) -> None:
    run, _ = make_run(tmp_path, {"kp": [10, 60], "kd": [1, 2], "leg_scale": [0.8, 1.0, 1.2]}, traces=False)
    paths = plots.write_run_plots(run)
    assert sorted(p.name for p in paths) == ["heatmap_last_1s_std_mm.png", "heatmap_push_dip_mm.png"]
    for p in paths:
        _check_png(p, min_w=600)
    _no_temp_files(run / "plots")


def test_write_run_plots_single_axis(tmp_path: Path) -> None:
    run, _ = make_run(tmp_path, {"kp": [5, 10, 20, 40, 80]})
    paths = plots.write_run_plots(run)
    assert sorted(p.name for p in paths) == [
        "base_z.png",
        "last_1s_std_mm_vs_kp.png",
        "push_dip_mm_vs_kp.png",
    ]
    for p in paths:
        _check_png(p)
    _no_temp_files(run / "plots")


def test_write_run_plots_presets_are_bars(tmp_path: Path) -> None:
    cells = [
        {"name": "soft", "kp": 2.0, "kd": 0.05},
        {"name": "default", "kp": 5.0, "kd": 0.1},
        {"name": "stiff", "kp": 20.0, "kd": 0.5},
        {"name": "underD", "kp": 20.0, "kd": 0.02},
    ]
    run, _ = make_run(tmp_path, cells=cells)
    paths = plots.write_run_plots(run)
    assert sorted(p.name for p in paths) == ["bars_last_1s_std_mm.png", "bars_push_dip_mm.png", "base_z.png"]
    for p in paths:
        _check_png(p)
    _no_temp_files(run / "plots")


def test_heatmap_marks_best_ok_cell(tmp_path: Path) -> None:
    from matplotlib.patches import Rectangle

    run, rows = make_run(tmp_path, {"kp": [10, 30, 60, 120], "kd": [0.5, 1, 2, 5]}, traces=False)
    table, _, _ = plots.read_run(run)
    fig = plots.heatmap(table, "last_1s_std_mm")
    ok = [r for r in rows if r["status"] == "ok"]
    want = min(ok, key=lambda r: r["last_1s_std_mm"])
    # the fell cell (kp 10, kd 0.5) has the smallest std but must not win
    assert min(r["last_1s_std_mm"] for r in rows if r["status"] == "fell") < want["last_1s_std_mm"]
    assert fig.pupper_best == [
        {"panel": None, "kp": want["kp"], "kd": want["kd"], "last_1s_std_mm": pytest.approx(want["last_1s_std_mm"])}
    ]
    # the red box sits on that cell's (column, row) position
    ax = fig.axes[0]
    boxes = [p for p in ax.patches if isinstance(p, Rectangle) and p.get_gid() == "best"]
    assert len(boxes) == 1
    cx = boxes[0].get_x() + boxes[0].get_width() / 2
    cy = boxes[0].get_y() + boxes[0].get_height() / 2
    assert (round(cx), round(cy)) == ([10, 30, 60, 120].index(want["kp"]), [0.5, 1, 2, 5].index(want["kd"]))
    texts = [t.get_text() for t in ax.texts]
    assert "diverged" in texts
    assert any(t.startswith("fell") for t in texts)
    # maximize picks the largest ok value instead
    fig2 = plots.heatmap(table, "push_dip_mm", minimize=False)
    top = max((r for r in ok if not math.isnan(r["push_dip_mm"])), key=lambda r: r["push_dip_mm"])
    assert (fig2.pupper_best[0]["kp"], fig2.pupper_best[0]["kd"]) == (top["kp"], top["kd"])


def test_heatmap_by_panels_and_duplicates(tmp_path: Path) -> None:
    run, rows = make_run(tmp_path, {"kp": [30, 60], "kd": [1, 2], "leg_scale": [0.8, 1.2]}, traces=False)
    table, _, _ = plots.read_run(run)
    with pytest.raises(ValueError, match="by="):
        plots.heatmap(table, "last_1s_std_mm")
    fig = plots.heatmap(table, "last_1s_std_mm", by="leg_scale")
    assert [b["panel"] for b in fig.pupper_best] == [0.8, 1.2]
    for b in fig.pupper_best:
        sub = [r for r in rows if r["leg_scale"] == b["panel"]]
        w = min(sub, key=lambda r: r["last_1s_std_mm"])
        assert (b["kp"], b["kd"]) == (w["kp"], w["kd"])


def test_plot_functions_accept_plain_dicts() -> None:
    table = {
        "kp": np.array([1.0, 2.0, 3.0, 1.0, 2.0, 3.0]),
        "leg_scale": np.array([1.0, 1.0, 1.0, 2.0, 2.0, 2.0]),
        "push_dip_mm": np.array([3.0, 2.0, 1.0, 4.0, np.nan, 2.0]),
        "status": ["ok", "ok", "ok", "fell", "diverged", "ok"],
        "name": ["a", "b", "c", "d", "e", "f"],
    }
    fig = plots.metric_vs_axis(table, "push_dip_mm", "kp", group="leg_scale")
    assert len(fig.axes[0].get_lines()) >= 2
    fig = plots.bars(table, "push_dip_mm")
    assert fig.pupper_best[0]["row"] == 2
    t = np.linspace(0, 3, 50)
    traces = {"a": (t, 0.2 + 0 * t), "b": (t, 0.19 + 0 * t)}
    fig = plots.base_z(traces, push=(1.0, 0.25), labels=["A", "B"])
    whole, zoom = fig.axes[:2]  # the second panel zooms on the push
    assert whole.get_xlabel() == "time (s)" and "mm" in whole.get_ylabel()
    assert zoom.get_xlim() == pytest.approx((0.5, 2.75))
    assert any("push" in (h.get_label() or "") for h in zoom.patches)
    assert [t.get_text() for t in zoom.get_legend().get_texts()][:2] == ["A", "B"]
    assert len(plots.base_z(traces, push=(1.0, 0.25), zoom=False).axes) == 1


# ---------------------------------------------------------------------------
# render


def _need_gl() -> None:
    reason = render.gl_available()
    if reason is not None:
        pytest.skip(f"no OpenGL context for offscreen rendering: {reason}")


def test_builtin_model_path() -> None:
    p = render.builtin_model_path("pupper_v3")
    assert p is not None and p.name == "scene.xml" and p.exists()
    assert render.builtin_model_path("pupper_v3_fixed") is None  # derived in memory
    assert render.builtin_model_path("no_such_model") is None


def test_render_png_shows_the_robot(tmp_path: Path) -> None:
    from PIL import Image

    _need_gl()
    path = render.render_png(tmp_path / "pupper.png", width=320, height=240, seconds=0.01)
    assert path.exists()
    _no_temp_files(tmp_path)
    img = np.asarray(Image.open(path).convert("RGB"), dtype=float)
    assert img.shape == (240, 320, 3)
    assert img.std() > 10.0, "blank image"
    # the robot (tracking camera aims at it) makes the centre differ from the
    # plain floor: compare with the same view with the robot's geoms hidden.
    import mujoco

    # a header says what is drawn (46 px at 320 px wide); the scene is below
    header = 46
    assert img[:header].std() > 5.0, "the header has text"
    img = img[header:]
    m = mujoco.MjModel.from_xml_path(str(render.builtin_model_path("pupper_v3")))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    with_robot = render.frame(m, d, width=320, height=240 - header).astype(float)
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    m.geom_rgba[[g for g in range(m.ngeom) if g != floor], 3] = 0.0
    background = render.frame(m, d, width=320, height=240 - header).astype(float)
    diff = np.abs(with_robot - background).sum(axis=2) > 40
    h, w = diff.shape
    centre = diff[h // 4 : 3 * h // 4, w // 4 : 3 * w // 4]
    assert centre.mean() > 0.08, f"robot covers only {centre.mean():.1%} of the centre"
    assert np.abs(with_robot - img).mean() < 5.0  # render_png drew the same scene


def test_record_gives_the_runners_states() -> None:
    import pupper_core as pc

    recs = render.record({"leg_scale": [1, 1.5]}, fps=10, seconds=1.0, sine=(2, 1.2), mode="torque")
    assert [r["id"] for r in recs] == ["leg1", "leg1.5"]
    for r in recs:
        assert r["qpos"].shape == (11, 19) and r["times"].shape == (11,)
        assert r["times"][0] == 0.0 and r["times"][-1] == pytest.approx(1.0, abs=0.01)
        assert r["status"] == "ok" and r["fps"] == 10
    # each cell is drawn on its own compiled body: the long legs' calves sit lower
    short, long = (r["model"] for r in recs)
    assert np.linalg.norm(long.body_pos - short.body_pos) > 0.01
    # the same runner as the sweep: the final state's base z is its final_z
    res = pc.sweep({"leg_scale": [1, 1.5]}, seconds=1.0, sine=(2, 1.2), mode="torque", progress=False)
    assert [r["qpos"][-1, 2] for r in recs] == list(res["final_z"])


def test_write_effects_two_cells(tmp_path: Path) -> None:
    from PIL import Image

    _need_gl()
    recs = render.record({"kp": [2, 20]}, kd=0.5, fps=20, seconds=1.0, push_at=0.3)
    png, gif, table = render.write_effects(recs, tmp_path / "out", width=160, height=120)
    assert png.name == "gain_sweep_effects.png" and gif.name == "gain_sweep_effects.gif"
    assert table.name == "gain_sweep_effects.csv"
    _no_temp_files(tmp_path / "out")
    with Image.open(gif) as g:
        assert g.format == "GIF"
        assert g.n_frames == 21  # t = 0, 0.05, ..., 1.0
        g.seek(0)
        first = np.asarray(g.convert("RGB"), dtype=float)
        g.seek(g.n_frames - 1)
        last = np.asarray(g.convert("RGB"), dtype=float)
        assert np.abs(first - last).mean() > 0.5  # the robot moved
    with Image.open(png) as p:
        assert p.format == "PNG"
        assert 2 * 160 <= p.width <= 2 * 160 + 20, p.width
        assert p.height > 120
        assert np.asarray(p.convert("RGB"), dtype=float).std() > 10
    # the still says it is one (last frames), the GIF how fast it plays
    assert render._captions("Kp", 20, True) == ("Kp  ·  last frames (the GIF is played in real time)",
                                                "Kp  ·  played in real time")
    assert render._captions(None, 30, False)[0] == "last frames"
    assert render._captions(None, 30, True)[1] == "played at 1.11x real time"
    frames = render.draw(recs[:1], width=64, height=48)
    assert len(frames) == 1 and len(frames[0]) == 21 and frames[0][0].shape == (48, 64, 3)
    assert frames[0][0].dtype == np.uint8


def test_sweep_render_draws_what_was_simulated(run, tmp_path: Path) -> None:
    _need_gl()
    out = tmp_path / "variants"
    run("sweep", "--grid", "leg_scale=1,1.5", "--sine", "2,1.2", "--seconds", "1.5", "--trace",
        "--trace-every", "1", "--render", "--plot", "-o", out, "-q", check=0)
    assert_drawn_as_traced(out)
    plots = sorted(p.name for p in (out / "plots").iterdir())
    assert {"gain_sweep_effects.gif", "gain_sweep_effects.png", "gain_sweep_effects.csv"} <= set(plots)
    assert any(n.startswith("base_z") and n.endswith(".png") for n in plots), plots
    _check_png(out / "plots" / "gain_sweep_effects.png")
    _no_temp_files(out / "plots")


def test_pupper_render_command(run, tmp_path: Path) -> None:
    _need_gl()
    run("render", "--seconds", "0.5", "--mode", "torque", "--kp", "20", "--width", "320", "--height", "240",
        "-o", tmp_path / "pic.png", check=0)
    _check_png(tmp_path / "pic.png")
    p = run("render", "--kp", "-1", "-o", tmp_path / "bad.png", check=2)
    assert len(p.stderr.strip().splitlines()) == 1 and "kp" in p.stderr
    assert not (tmp_path / "bad.png").exists()


def test_render_draws_a_cell_of_a_finished_run_at_a_time(run, tmp_path: Path) -> None:
    """`render --run DIR --cell ID --time T`: the cell re-simulated with the
    run's inputs, drawn at T; by id or index; -o a directory or a file;
    bad cell, time or extra controller flags: one line, exit 2, no file."""
    from PIL import Image

    _need_gl()
    d = tmp_path / "run"
    run("sweep", "--grid", "kp=2,30", "--grid", "kd=0.1", "--seconds", "1.5", "-o", d, "-q", check=0)
    p = run("render", "--run", d, "--cell", "kp30_kd0.1", "--time", "0", "--width", "320", "--height", "240",
            check=0)
    start = d / "plots" / "render-kp30_kd0.1-t0.png"
    assert p.stdout.strip() == f"wrote {start}"
    _check_png(start)
    p = run("render", "--run", d, "--cell", "1", "-o", tmp_path, "--json", "--width", "320", "--height", "240",
            check=0)
    end = tmp_path / "render-kp30_kd0.1-t1.5.png"
    assert json.loads(p.stdout) == {"path": str(end)}
    _check_png(end)
    # the robot dropped and settled between 0 and 1.5 s: not the same picture
    a, b = (np.asarray(Image.open(x).convert("RGB"), dtype=float) for x in (start, end))
    assert np.abs(a - b).mean() > 1.0
    for bad, word in ((["--cell", "nope"], "--cell nope"), (["--time", "9"], "--time 9"),
                      (["--kp", "3"], "drop the model")):
        p = run("render", "--run", d, *bad, "-o", tmp_path / "bad.png", check=2)
        assert len(p.stderr.strip().splitlines()) == 1 and word in p.stderr, p.stderr
    assert not (tmp_path / "bad.png").exists()


def test_render_without_gl_says_how_to_fix(tmp_path: Path) -> None:
    import subprocess

    code = (
        "import sys; sys.path.insert(0, sys.argv[1]); import pupper_core.render as r\n"
        "try:\n    r.render_png(sys.argv[2], seconds=0.1)\n"
        "except r.RenderUnavailable as e:\n    print('unavailable:', e)\n"
    )
    p = subprocess.run([sys.executable, "-c", code, str(PKG.parent), str(tmp_path / "x.png")],
                       env={**__import__("os").environ, "MUJOCO_GL": "no-such-backend"},
                       capture_output=True, text=True, timeout=120)
    assert p.stdout.startswith("unavailable: MUJOCO_GL=no-such-backend cannot render"), p.stdout + p.stderr
    assert "fix:" in p.stdout and not (tmp_path / "x.png").exists()


# ---------------------------------------------------------------------------
# figures that answer the question (issue 25), read back from the files'
# own figures


@pytest.fixture(scope="module")
def chapter_grid(pupper_bin, tmp_path_factory) -> Path:
    import subprocess

    from conftest import clean_env

    d = tmp_path_factory.mktemp("grid") / "run"
    p = subprocess.run([str(pupper_bin), "sweep", "--grid", "kp=10,30,60,120", "--grid", "kd=0.5,1,2,5",
                        "--trace", "-q", "-o", str(d)], capture_output=True, text=True, env=clean_env(),
                       timeout=300)
    assert p.returncode == 0, p.stderr
    return d


def test_the_heatmap_marks_what_the_cli_names_and_says_what_is_not_ranked(chapter_grid: Path, run) -> None:
    from matplotlib.patches import Rectangle

    table, _, _ = plots.read_run(chapter_grid)
    fig = plots.heatmap(table, "last_1s_std_mm")
    # the star is on the cell `pupper sweep` printed as steadiest (the tie
    # within 1 um goes to the smaller dip among the cells inside the
    # stability bound: Kp 120, Kd 1)
    assert fig.pupper_best == [{"panel": None, "kp": 120.0, "kd": 1.0,
                                "last_1s_std_mm": pytest.approx(float(table["last_1s_std_mm"][13]))}]
    ax = fig.axes[0]
    # the eight Kd 2 and 5 cells, past the stability bound, are hatched and
    # say so
    hatched = [p for p in ax.patches if isinstance(p, Rectangle) and p.get_gid() == "past_bound"]
    assert len(hatched) == 8
    texts = [t.get_text() for t in ax.texts]
    assert sum("past bound" in t for t in texts) == 8
    # one number format: micrometres, "<0.001" below; never 9.42e-06
    assert not any("e-" in t for t in texts), texts
    assert "<0.001" in texts
    # yellow is steadier in both the sweep's and the lab's heatmaps
    image = ax.images[0]
    assert image.get_cmap().name.startswith("viridis_r")


def test_base_z_tells_cells_apart_and_shows_the_dip(chapter_grid: Path) -> None:
    import matplotlib.colors as mcolors

    table, manifest, traces = plots.read_run(chapter_grid)
    status = dict(zip(table["id"], table["status"]))
    fig = plots.base_z(traces, push=manifest["config"]["schedule"]["push"], status=status)
    whole, zoom = fig.axes[:2]
    lines = whole.get_lines()
    assert len(lines) == 16
    assert len({mcolors.to_hex(line.get_color()) for line in lines}) == 16, "16 distinct colours"
    # the whole-run range is the robots after landing: the 280 mm start is
    # off the top, and the millimetre dips fill the panel
    lo, hi = whole.get_ylim()
    assert hi < 140 and hi - lo < 15, (lo, hi)
    assert "off the top" in whole.get_title()
    # cells past the stability bound (the chattering Kd 5 ones among them)
    # are dashed and set no range
    dashed = [line for line in lines if line.get_linestyle() == "--"]
    assert len(dashed) == 8


def test_lab_figures_name_the_disturbance_number_the_cells_and_hint_at_the_edge(run, tmp_path: Path) -> None:
    import matplotlib.image as mpimg

    run("lab", "--seconds", "2", "-q", "-o", tmp_path / "lab", check=0)
    table, manifest, _ = plots.read_run(tmp_path / "lab")
    assert "vertical sine 2 N at 1.2 Hz" in plots.describe(manifest)
    rows = [dict(zip(table, vals)) for vals in zip(*table.values())]
    bodies = list(dict.fromkeys(r["variant"] for r in rows))
    kp = sorted({float(r["kp"]) for r in rows})
    kd = sorted({float(r["kd"]) for r in rows})
    values = {b: np.full((len(kd), len(kp)), 0.05) for b in bodies}
    fig = plots.lab_heatmaps(bodies, kp, kd, values, {b: (kp[-1], kd[0]) for b in bodies})
    assert fig.pupper_edges and all("Kp up" in e for e in fig.pupper_edges)
    assert all(any(t.get_text() == "0.050" for t in a.texts) for a in fig.axes[:3])
    assert fig.axes[0].images[0].get_cmap().name.startswith("viridis_r")
    png = mpimg.imread(tmp_path / "lab" / "plots" / "lab_heatmaps.png")
    assert png.std() > 0.05, "blank figure"


def test_every_plot_takes_a_result_or_its_run_directory_alike(chapter_grid: Path) -> None:
    """heatmap, base_z and the run-directory plots draw the same from a
    result (load_run's, or a sweep's with out=) as from its directory."""
    import pupper_core as pc

    res = pc.load_run(chapter_grid)
    from_table = plots.heatmap(plots.read_run(chapter_grid)[0], "last_1s_std_mm").pupper_best
    assert plots.heatmap(chapter_grid, "last_1s_std_mm").pupper_best == from_table
    assert plots.heatmap(str(chapter_grid), "last_1s_std_mm").pupper_best == from_table
    assert plots.heatmap(res, "last_1s_std_mm").pupper_best == from_table
    for given in (chapter_grid, res):
        lines = plots.base_z(given).axes[0].get_lines()
        # 16 cells, the 8 past the bound dashed, the push shaded in both panels
        assert len(lines) == 16 and sum(ln.get_linestyle() == "--" for ln in lines) == 8
        assert len(plots.base_z(given).axes) == 2
    with pytest.raises(ValueError, match="no run directory"):
        plots.response_steps(pc.sweep({"kp": [10]}, seconds=2, progress=False))


def test_step_plots_draw_each_groups_pick_zoomed_to_its_settling(run, tmp_path: Path) -> None:
    import pupper_core as pc
    from pupper_core._report import _read, response_pick

    d = tmp_path / "r"
    run("response", "--grid", "kp=5,10,20,30", "--grid", "kd=0.1,0.3,0.5", "--seconds", "2", "--trace", "-q",
        "-o", d, check=0)
    header, rows = _read(d / "summary.csv")
    fig = plots.response_steps(pc.load_run(d))
    assert fig is not None and fig.pupper_cells == plots.response_steps(d).pupper_cells
    panels = [a for a in fig.axes if a.get_title()]
    for ax, g in zip(panels, ("haa", "hfe", "kfe")):
        pick = response_pick(header, rows, g)
        assert pick is not None and fig.pupper_picks[g] == pick["id"]
        # drawn, whatever its place in the grid, and the boldest line
        bold = max(ax.get_lines(), key=lambda ln: ln.get_linewidth())
        assert bold.get_label() == pick["id"]
        # the x axis: three of the pick's settling times, not the whole run
        assert ax.get_xlim()[1] == pytest.approx(3 * float(pick[f"settling_time_s.{g}"]), rel=1e-6)
        assert ax.get_xlim()[1] < 0.5


def test_an_overshoot_below_the_simulations_resolution_is_drawn_as_none() -> None:
    table = {"kp": [5.0, 20.0, 5.0, 20.0], "kd": [0.1, 0.1, 0.5, 0.5], "status": ["ok"] * 4,
             "overshoot_pct.kfe": [8.97, 36.6, 0.0132, 9.91e-10]}
    fig = plots.heatmap(table, "overshoot_pct.kfe")
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert "0" in texts and not any("e-" in t for t in texts), texts
    # a linear colour scale from 0: noise is no decade of its own
    assert fig.axes[0].images[0].norm.vmin == 0
    # the star still goes by summary.csv's digits
    assert fig.pupper_best[0]["overshoot_pct.kfe"] == 9.91e-10


def test_the_heatmap_key_names_the_metric_it_plots_and_its_tie_break() -> None:
    """The key line says which metric the star ranks and what breaks its
    ties: the smaller push dip where the table has one, else grid order
    (it said 'the smaller dip' on a response's overshoot)."""
    response = {"kp": [5.0, 20.0, 5.0, 20.0], "kd": [0.1, 0.1, 0.5, 0.5], "status": ["ok"] * 4,
                "overshoot_pct.kfe": [8.97, 36.6, 0.0132, 9.91e-10]}
    key = " ".join(plots.heatmap(response, "overshoot_pct.kfe")._suptitle.get_text().split())
    assert "★ = lowest overshoot_pct.kfe among" in key, key
    assert "equal values: the first in grid order" in key and "dip" not in key, key
    sweep = {"kp": [5.0, 20.0], "kd": [0.1, 0.1], "status": ["ok"] * 2,
             "last_1s_std_mm": [0.01, 0.02], "push_dip_mm": [1.5, 1.2]}
    key = " ".join(plots.heatmap(sweep, "last_1s_std_mm")._suptitle.get_text().split())
    assert "★ = lowest base-height std, last 1 s among" in key, key
    assert "ties within 0.001 mm: the smaller push dip" in key, key
    key = " ".join(plots.heatmap(sweep, "push_dip_mm")._suptitle.get_text().split())
    assert "lowest push dip of base height among" in key and "the first in grid order" in key, key
    # a run without a push: its empty dip column breaks no tie
    quiet = dict(sweep, push_dip_mm=[math.nan, math.nan])
    key = " ".join(plots.heatmap(quiet, "last_1s_std_mm")._suptitle.get_text().split())
    assert "the first in grid order" in key and "dip" not in key.split("(")[1], key


def test_step_curves_are_at_the_physics_rate_and_the_run_s_own(run, tmp_path: Path) -> None:
    """The step figure and report.html's step curve draw every physics step
    of the cells they show (the cells run again: response_traces.csv keeps
    every --trace-every-th step, 20 ms against rise times of 10 ms); the
    samples the run wrote are among them, digit for digit."""
    from pupper_core._plots_response import step_curves
    from pupper_core._report import _read

    d = tmp_path / "r"
    run("response", "--grid", "kp=5,20", "--grid", "kd=0.1,0.5", "--seconds", "1", "--trace",
        "--trace-every", "10", "-q", "-o", d, check=0)
    before = (d / "response_traces.csv").read_bytes()
    fig = plots.response_steps(d)
    assert fig.pupper_sample_dt == pytest.approx(0.002, rel=1e-9)
    for ax in (a for a in fig.axes if a.get_title()):
        for ln in ax.get_lines():
            if ln.get_label() in fig.pupper_cells:
                t = ln.get_xdata()
                assert np.diff(t).max() == pytest.approx(0.002, rel=1e-6), ln.get_label()
    # every 10th physics-rate sample is the row the run wrote
    _, traces = _read(d / "response_traces.csv")
    _, joints = _read(d / "response.csv")
    kfe = [r["joint"] for r in joints if r["group"] == "kfe"]
    written = [(float(r["t"]), float(r["angle"])) for r in traces if r["id"] == "kp20_kd0.1" and r["joint"] == kfe[0]]
    from pupper_core import _native

    index = next(int(r["index"]) for r in _read(d / "summary.csv")[1] if r["id"] == "kp20_kd0.1")
    full = next(tr for tr in _native.step_traces(str(d), [index]) if tr["joint"] == kfe[0])
    assert list(zip(full["t"][::10], full["angle"][::10])) == written
    curves = step_curves(d, ["kp20_kd0.1"])
    assert len(curves[("kp20_kd0.1", "kfe")][0]) == len(full["t"]) > 10 * (len(written) - 1)
    # nothing written by drawing
    assert (d / "response_traces.csv").read_bytes() == before
    page = (d / "report.html").read_text()
    assert "every physics step (2 ms)" in page


def test_a_replicated_heatmap_keeps_its_title_and_colour_bar_label_inside(tmp_path: Path) -> None:
    # a narrow grid (2 x 2) and the longest labels, a statistic over replicates:
    # every line of the title, the key and the colour bar's label lies inside the
    # figure, none on another (the texts as drawn: a tick off the bar is never drawn)
    import pupper_core as pc
    from pupper_core import plots

    from figure_check import figure_problems, saved_figures

    res = pc.sweep({"kp": [10, 30], "kd": [0.5, 1]}, replicates=3, randomize=["torso_mass=±10%"], seconds=3.75,
                   progress=False)
    fig = plots.heatmap(res, "p95:push_dip_mm")
    with saved_figures() as figs:
        fig.savefig(tmp_path / "heatmap.png")
    assert any("worst-side 95th" in t for t, _ in figs[0].texts)
    assert figure_problems(figs) == []
