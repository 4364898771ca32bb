"""Drawing Pupper with ``mujoco.Renderer``.

Nothing here simulates a sweep: :func:`record` and :func:`record_run` get
recorded states (qpos at a frame rate) from the Rust runner that computes
the metrics, so a picture shows exactly the simulation that was measured —
body variants, sine forces, torque mode and all. This module only draws
them, each on the compiled body its cell ran on.

MuJoCo picks its OpenGL backend from the ``MUJOCO_GL`` environment variable
when ``mujoco`` is first imported. :func:`gl_available` respects a value that
is already set; otherwise it probes ``egl`` then ``osmesa`` (then ``glfw`` when
a display exists) in a short subprocess, sets ``MUJOCO_GL`` to the first that
works and, if ``mujoco`` was already imported with another backend, installs
the chosen backend's context class in MuJoCo's renderer. Setting
``MUJOCO_GL=egl`` before starting Python is the most reliable way.
"""

from __future__ import annotations

# The OpenGL probing is in gl, the panels' layout and the GIF's palette in
# panels; this module records and draws.

import copy
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence, Union

import numpy as np

from pupper_core._rundir import atomic_write
from pupper_core.render.gl import FIX_HINT, RenderUnavailable, _one_line, _require_gl, gl_available
from pupper_core.render.panels import _atomic_save, _compose, _font, _labels, _panel, _push_text, _shared_palette
from pupper_core._spec import DEFAULT_METRIC

if TYPE_CHECKING:  # pragma: no cover
    import mujoco

    from pupper_core._types import Recording
    from PIL import Image as PILImage

__all__ = [
    "RenderUnavailable",
    "builtin_model_path",
    "gl_available",
    "frame",
    "scene_option",
    "record",
    "record_run",
    "draw",
    "simulate_frames",
    "write_effects",
    "write_run_effects",
    "render_png",
    "view",
]

ModelLike = Union["mujoco.MjModel", str, os.PathLike]


# ---------------------------------------------------------------------------
# Models


def builtin_model_path(name: str) -> Path | None:
    """The MJCF file of a built-in model, shipped as package data (the scene
    for ``pupper_v3``), or None for names that are not files (``pupper_v3_fixed``
    is derived in memory; ``_native.builtin_model`` compiles any of them)."""
    p = Path(__file__).parent.parent / "models" / name / "scene.xml"
    return p if p.is_file() else None


def _load_model(model: ModelLike) -> "mujoco.MjModel":
    """An MjModel from an MjModel, XML text, a path, or a built-in name."""
    import mujoco

    if isinstance(model, mujoco.MjModel):
        return model
    if isinstance(model, str) and model.lstrip().startswith("<"):
        return mujoco.MjModel.from_xml_string(model)
    p = Path(model)
    if p.exists():
        return mujoco.MjModel.from_xml_path(str(p))
    from pupper_core import _native

    try:  # compiled by the native module, as the CLI compiles it
        return _native.builtin_model(str(model))
    except _native.ModelError:
        raise FileNotFoundError(
            f"model '{model}' is neither an existing XML file nor a built-in model"
        ) from None


def _reset(model: "mujoco.MjModel", data: "mujoco.MjData", keyframe: str | int | None) -> None:
    """Resets to a keyframe (name or index); None: the model's default state.

    A missing "home" (the default name) falls back to keyframe 0, else the
    default state; another missing name is an error.
    """
    import mujoco

    kid = -1
    if isinstance(keyframe, int):
        kid = keyframe if 0 <= keyframe < model.nkey else -1
    elif keyframe:
        kid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, keyframe)
        if kid < 0:
            if keyframe != "home":
                raise ValueError(f"the model has no keyframe '{keyframe}'")
            kid = 0 if model.nkey > 0 else -1
    if kid >= 0:
        mujoco.mj_resetDataKeyframe(model, data, kid)
    else:
        mujoco.mj_resetData(model, data)
    mujoco.mj_forward(model, data)


def _ensure_buffer(model: "mujoco.MjModel", width: int, height: int) -> None:
    g = model.vis.global_
    if width > g.offwidth:
        g.offwidth = int(width)
    if height > g.offheight:
        g.offheight = int(height)


def _camera_arg(model: "mujoco.MjModel", camera: str | int | None) -> str | int:
    """The named camera if the model has it, else the free camera (-1)."""
    import mujoco

    if camera is None:
        return -1
    if isinstance(camera, int):
        return camera
    return camera if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera) >= 0 else -1


def _new_renderer(model: "mujoco.MjModel", width: int, height: int) -> "mujoco.Renderer":
    import mujoco

    _require_gl()
    _ensure_buffer(model, width, height)
    try:
        return mujoco.Renderer(model, height=int(height), width=int(width))
    except Exception as e:  # noqa: BLE001
        raise RenderUnavailable(
            f"cannot create a MuJoCo renderer ({type(e).__name__}: {_one_line(str(e))}); "
            f"fix: {FIX_HINT}"
        ) from e


#: Geom groups MuJoCo draws by default (its viewer's and Renderer's).
_SHOWN_GROUPS = (0, 1, 2)


def scene_option(model: "mujoco.MjModel") -> "mujoco.MjvOption":
    """What to draw of ``model``: MuJoCo's defaults, plus every geom group
    when the robot has no geom in a group drawn by default (a model whose
    collision geoms sit in a hidden group and that has no visual geoms
    would otherwise be drawn as nothing but its sites)."""
    import mujoco

    opt = mujoco.MjvOption()
    robot = model.geom_bodyid != 0
    if not np.any(robot & np.isin(model.geom_group, _SHOWN_GROUPS)):
        opt.geomgroup[:] = 1
    return opt


def frame(
    model: "mujoco.MjModel",
    data: "mujoco.MjData",
    camera: str | int | None = "tracking_cam",
    width: int = 480,
    height: int = 360,
) -> np.ndarray:
    """One RGB image (H, W, 3) uint8 of ``data`` seen from ``camera``.

    Falls back to the free camera when the model has no camera of that name.
    May enlarge ``model.vis.global_.offwidth/offheight`` to fit the image.
    """
    with _new_renderer(model, width, height) as r:
        r.update_scene(data, camera=_camera_arg(model, camera), scene_option=scene_option(model))
        return r.render().copy()


# ---------------------------------------------------------------------------
# Recorded states


def _fps_of(rec: "Recording") -> float:
    return float(rec["fps"])


def record(
    grid: Any = None,
    *,
    fps: float = 25.0,
    preset: str | None = None,
    **options: Any,
) -> list["Recording"]:
    """Simulates every cell of a grid with the sweep's own runner and returns
    its recorded states (qpos at ``fps``, frame 0 the initial state).

    ``grid``, ``preset`` and the keywords are those of :func:`pupper_core.sweep`
    (nothing is written). Each recording holds the compiled body the cell ran
    on (``model``: its leg/torso variant), so drawing it shows that body.
    """
    from pupper_core import _native
    from pupper_core._spec import sweep_options

    return _native.record(grid, preset=preset, fps=float(fps), **sweep_options(options))


def record_run(run_dir: str | os.PathLike[str], cells: Sequence[int], fps: float = 25.0) -> list["Recording"]:
    """Re-runs cells of a run directory (by their ``index`` column) with its
    manifest's settings, recording qpos at ``fps``."""
    from pupper_core import _native

    return _native.record_run(os.fspath(run_dir), [int(c) for c in cells], float(fps))


def _base_body(model: "mujoco.MjModel") -> int:
    """The body of the first free joint (the floating base)."""
    import mujoco

    free = np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    return int(model.jnt_bodyid[free[0]]) if free.size else 0


@dataclass
class _Drawn:
    """One recording drawn: its frames and the base height in each."""

    frames: list[np.ndarray] = field(default_factory=list)
    base_z: list[float] = field(default_factory=list)


def _draw(
    recordings: Sequence["Recording"],
    width: int,
    height: int,
    camera: str | int | None,
    shadows: bool,
) -> list[_Drawn]:
    _require_gl()
    import mujoco

    out: list[_Drawn] = []
    for rec in recordings:
        m = copy.copy(rec["model"])  # the buffer size is set on our copy only
        _ensure_buffer(m, width, height)
        d = mujoco.MjData(m)
        body = _base_body(m)
        drawn = _Drawn()
        with _new_renderer(m, width, height) as renderer:
            renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = bool(shadows)
            cam = _camera_arg(m, camera)
            shown = scene_option(m)
            for q in rec["qpos"]:
                d.qpos[:] = q
                mujoco.mj_forward(m, d)
                renderer.update_scene(d, camera=cam, scene_option=shown)
                drawn.frames.append(renderer.render().copy())
                drawn.base_z.append(float(d.xpos[body, 2]))
        out.append(drawn)
    return out


def draw(
    recordings: Sequence["Recording"],
    *,
    width: int = 320,
    height: int = 240,
    camera: str | int | None = "tracking_cam",
    shadows: bool = True,
) -> list[list[np.ndarray]]:
    """The frames (H, W, 3 uint8) of each recording, drawn on its own body.

    Falls back to the free camera when a model has no camera of that name.
    ``shadows=False`` draws about 3x faster on software OpenGL (llvmpipe).
    """
    return [d.frames for d in _draw(recordings, width, height, camera, shadows)]


def simulate_frames(
    grid: Any = None,
    *,
    fps: float = 25.0,
    width: int = 320,
    height: int = 240,
    camera: str | int | None = "tracking_cam",
    shadows: bool = True,
    **options: Any,
) -> list[list[np.ndarray]]:
    """:func:`record` then :func:`draw`: each cell's frames at ``fps``."""
    return draw(record(grid, fps=fps, **options), width=width, height=height, camera=camera, shadows=shadows)


# ---------------------------------------------------------------------------
# Pictures


def _captions(caption: str | None, fps: float, gif: bool) -> tuple[str, str]:
    """The still's caption (each robot's last frame) and the GIF's (how
    fast it plays: a GIF counts whole centiseconds)."""
    head = caption + "  ·  " if caption else ""
    speed = (1000 / fps) / (max(1, round(100 / fps)) * 10)
    played = "played in real time" if abs(speed - 1) < 1e-9 else f"played at {speed:.2f}x real time"
    return head + (f"last frames (the GIF is {played})" if gif else "last frames"), head + played


def write_effects(
    recordings: Sequence["Recording"],
    out_dir: str | os.PathLike[str],
    *,
    width: int = 320,
    height: int = 240,
    stem: str = "gain_sweep_effects",
    camera: str | int | None = "tracking_cam",
    shadows: bool = True,
    gif: bool = True,
    caption: str | None = None,
) -> tuple[Path, Path | None, Path]:
    """Draws recordings side by side: ``<stem>.png`` (final frames),
    ``<stem>.gif`` (synchronized panels at the recordings' frame rate,
    played in real time: GIF frame durations are whole centiseconds, so a
    frame rate that does not divide 100 is played at the nearest one that
    does, and the caption says at what speed; ``gif=False`` skips it) and
    ``<stem>.csv`` (id, frame, time, base z and push of every frame drawn).
    ``caption``: a line under the panels (which cells, and why).

    Returns ``(png_path, gif_path or None, csv_path)``.
    """
    if not recordings:
        raise ValueError("write_effects needs at least one recording")
    drawn = _draw(recordings, width, height, camera, shadows)
    scale = max(1.0, width / 320)
    fonts = (_font(int(round(17 * scale))), _font(int(round(13 * scale))))
    any_title = any(r["name"] for r in recordings)
    header_h = int(round((46 if any_title else 28) * scale))

    def panel(i: int, k: int, final: bool) -> "PILImage.Image":
        rec, dr = recordings[i], drawn[i]
        t = float(rec["times"][k])
        event = float(rec["event_time"])
        if rec["status"] == "diverged" and t >= event:
            status = "DIVERGED"
        else:
            status = f"base z {dr.base_z[k] * 1000:.0f} mm"
        title, params = _labels(rec)
        pushing = bool(rec["pushing"][k]) and not final
        return _panel(dr.frames[k], title, params, t, pushing, _push_text(rec), status, fonts, header_h)

    nframes = min(len(d.frames) for d in drawn) if gif else 0
    gif_frames = [_compose([panel(i, k, False) for i in range(len(drawn))]) for k in range(nframes)]
    finals = [panel(i, len(d.frames) - 1, True) for i, d in enumerate(drawn)]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    png_path = out / f"{stem}.png"
    gif_path = out / f"{stem}.gif"
    csv_path = out / f"{stem}.csv"
    fps = _fps_of(recordings[0])
    # a GIF counts in centiseconds: the real-time frame duration, rounded
    centis = max(1, round(100 / fps))
    still, moving = _captions(caption, fps, gif)

    finals = [_captioned(_compose(finals), still, fonts[1])]
    gif_frames = [_captioned(f, moving, fonts[1]) for f in gif_frames]
    _atomic_save(finals[0], png_path, "PNG")
    if gif:
        _atomic_save(_shared_palette(gif_frames), gif_path, "GIF", duration=centis * 10, loop=0)

    atomic_write(csv_path, lambda tmp: _frames_table(tmp, recordings, drawn))
    return png_path, (gif_path if gif else None), csv_path


def _captioned(img: "PILImage.Image", line: str, font: Any) -> "PILImage.Image":
    """``img`` with ``line`` in a grey strip under it."""
    from PIL import Image, ImageDraw

    strip = Image.new("RGB", (img.width, font.size + 12), (245, 245, 245))
    ImageDraw.Draw(strip).text((8, 5), line, font=font, fill=(60, 60, 60))
    both = Image.new("RGB", (img.width, img.height + strip.height), (255, 255, 255))
    both.paste(img, (0, 0))
    both.paste(strip, (0, img.height))
    return both


def _frames_table(tmp: Path, recordings: Sequence["Recording"], drawn: Sequence[Any]) -> None:
    """The effects' CSV: id, frame, time, base z and push of every frame drawn."""
    import csv

    with open(tmp, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["id", "frame", "time", "base_z", "pushing"])
        for rec, dr in zip(recordings, drawn):
            for k, z in enumerate(dr.base_z):
                w.writerow([rec["id"], k, repr(float(rec["times"][k])), repr(z), int(bool(rec["pushing"][k]))])


def _still(rec: "Recording", k: int, title: str, width: int, height: int,
           camera: str | int | None) -> "PILImage.Image":
    """Frame ``k`` of a recording with a header inside the asked size: the
    body, its gains, the time and how high the base stands."""
    scale = max(1.0, int(width) / 320)
    header_h = min(int(round(46 * scale)), int(height) // 3)
    drawn = _draw([rec], int(width), int(height) - header_h, camera, True)[0]
    fonts = (_font(int(round(17 * scale))), _font(int(round(13 * scale))))
    _, gains = _labels(rec)
    params = f"{gains}  ·  base z {drawn.base_z[k] * 1000:.1f} mm"
    status = "" if rec["status"] == "ok" else rec["status"]
    return _panel(drawn.frames[k], title, params, float(rec["times"][k]), bool(rec["pushing"][k]),
                  _push_text(rec), status, fonts, header_h)


def _save_png(img: "PILImage.Image", path: str | os.PathLike[str]) -> Path:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    _atomic_save(img, out, "PNG")
    return out


def render_png(
    path: str | os.PathLike[str],
    *,
    width: int = 640,
    height: int = 480,
    camera: str | int | None = "tracking_cam",
    time: float | None = None,
    **options: Any,
) -> Path:
    """The robot after standing ``seconds`` (no push), or at ``time`` s,
    drawn to a PNG with a header naming body, gains, time and base height.

    Keywords are those of :func:`pupper_core.stand` (model, mode, seconds,
    gains, keyframe or pose); the stand is simulated by the sweep's runner.
    """
    _require_gl()
    seconds = float(options.get("seconds", 10.0))
    at = seconds if time is None else float(time)
    recs = record(None, fps=_fps_for(at, seconds), **{**options, "push": False})
    rec = recs[0]
    model = str(options.get("model", "pupper_v3"))
    body = str(options.get("variant", "original"))
    title = f"{Path(model).name if os.sep in model else model}" + ("" if body == "original" else f" ({body})")
    return _save_png(_still(rec, _frame_at(rec, at), title, width, height, camera), path)


def _fps_for(at: float, seconds: float) -> float:
    """A frame rate whose frames fall on ``at`` (frame 1) and are few."""
    if at > 0:
        return 1.0 / at
    return 1.0 / seconds if seconds > 0 else 1.0


def _frame_at(rec: "Recording", at: float) -> int:
    times = np.asarray(rec["times"], dtype=float)
    return int(np.argmin(np.abs(times - at)))


def render_cell_png(
    path: str | os.PathLike[str],
    run_dir: str | os.PathLike[str],
    cell: int,
    *,
    time: float | None = None,
    width: int = 640,
    height: int = 480,
    camera: str | int | None = "tracking_cam",
) -> Path:
    """Cell ``cell`` (its ``index`` in summary.csv) of a finished run at
    ``time`` s (default: the run's end), re-simulated with the run's
    manifest (its push included) and drawn to a PNG; the header names the
    cell, its gains and axis values, the time and the base height."""
    _require_gl()
    from pupper_core import _native

    manifest = _native.read_manifest(os.fspath(run_dir))
    seconds = float(manifest["config"]["schedule"]["duration"])
    at = seconds if time is None else float(time)
    (rec,) = record_run(run_dir, [int(cell)], fps=_fps_for(at, seconds))
    title = f"{rec['id']}" + (f" {rec['name']}" if rec["name"] else "")
    return _save_png(_still(rec, _frame_at(rec, at), title, width, height, camera), path)


def write_run_effects(run_dir: str | os.PathLike[str], max_cells: int = 6, fps: float = 10) -> list[Path]:
    """`pupper sweep --render`: the effects GIF, final-frame PNG and frame
    table of a run, in ``<run_dir>/plots/``.

    Draws up to ``max_cells`` cells of the run's summary.csv (all of them if
    the grid is that small, else evenly spread ones, the steadiest included),
    re-simulated by the sweep's runner with the run's manifest, for the run's
    duration. Shadows are off to keep software rendering quick.
    """
    import csv

    run = Path(run_dir)
    with open(run / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{run}/summary.csv has no cells to render")
    picks = list(range(len(rows)))
    caption = f"all {len(rows)} cells"
    if len(rows) > max_cells:
        step = (len(rows) - 1) / (max_cells - 1)
        picks = sorted({round(i * step) for i in range(max_cells)})
        caption = f"{len(picks)} of {len(rows)} cells, evenly spread over the grid"
        # the steadiest by pupper's rule (what `pupper sweep` printed)
        from pupper_core import _native

        header = list(rows[0])
        try:
            (best,) = _native.best_rows(header, [[r[h] for h in header] for r in rows], DEFAULT_METRIC)
        except _native.PupperError:  # a replicated run ranks by a statistic: none named here
            best = None
        if best is not None:
            if best not in picks:
                picks[-1] = best
                picks.sort()
            caption += f", the steadiest ({rows[best]['id']}) among them"
    recs = record_run(run, [int(rows[i]["index"]) for i in picks], fps=fps)
    paths = write_effects(recs, run / "plots", shadows=False, caption=caption)
    return [p for p in paths if p is not None]


def write_lab_effects(run_dir: str | os.PathLike[str], gif: bool = False, fps: float = 10) -> list[Path]:
    """`pupper lab`: each body at its best gains (best.csv), re-simulated by
    the sweep's runner and drawn side by side on its own body:
    ``plots/lab_best.png`` (final frames), with ``gif=True`` also
    ``plots/lab_best.gif``, and the frame table ``plots/lab_best.csv``.
    Nothing (an empty list) when no body has best gains: none stood, or the
    run was too short to rank them."""
    import csv

    run = Path(run_dir)
    with open(run / "best.csv", newline="") as f:
        picks = [int(r["index"]) for r in csv.DictReader(f) if r["index"]]
    if not picks:
        return []
    recs = record_run(run, picks, fps=fps)
    paths = write_effects(recs, run / "plots", stem="lab_best", shadows=False, gif=gif)
    return [p for p in paths if p is not None]


def view(model: ModelLike) -> None:
    """`pupper view`: MuJoCo's interactive viewer on a model, from its home keyframe."""
    import mujoco
    import mujoco.viewer

    m = _load_model(model)
    d = mujoco.MjData(m)
    _reset(m, d, "home" if m.nkey else None)
    mujoco.viewer.launch(m, d)
