"""Offscreen rendering of Pupper with ``mujoco.Renderer``.

MuJoCo picks its OpenGL backend from the ``MUJOCO_GL`` environment variable
when ``mujoco`` is first imported. :func:`gl_available` respects a value that
is already set; otherwise it probes ``egl`` then ``osmesa`` (then ``glfw`` when
a display exists) in a short subprocess, sets ``MUJOCO_GL`` to the first that
works and, if ``mujoco`` was already imported with another backend, installs
the chosen backend's context class in MuJoCo's renderer. Setting
``MUJOCO_GL=egl`` before starting Python is the most reliable way.

Rendering runs its own plain Python loop with ``mujoco.mj_step`` (rendering
is not the sweep's hot path); its physics follows the Rust core's: servo mode
writes Kp/Kd into the affine actuators, torque mode computes the clipped PD
torque in Python, and the push is an external force on the base body while
``start <= data.time < start + duration``.
"""

from __future__ import annotations

import copy
import os
import subprocess
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence, Union

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import mujoco
    from PIL import Image as PILImage
    from PIL import ImageFont

__all__ = [
    "RenderUnavailable",
    "builtin_model_path",
    "gl_available",
    "frame",
    "simulate_frames",
    "write_effects",
    "render_png",
]

FIX_HINT = (
    "install libegl1 and libgl1-mesa-dri (apt-get) and set MUJOCO_GL=egl, "
    "or set MUJOCO_GL=osmesa with libosmesa6"
)

#: The tiny scene used to check that a context can be made and drawn into.
_PROBE_XML = (
    "<mujoco><worldbody><light pos='0 0 3'/>"
    "<geom type='sphere' size='0.5' rgba='1 0 0 1'/></worldbody></mujoco>"
)
_PROBE_CODE = (
    "import mujoco\n"
    f"m = mujoco.MjModel.from_xml_string({_PROBE_XML!r})\n"
    "d = mujoco.MjData(m)\n"
    "mujoco.mj_forward(m, d)\n"
    "with mujoco.Renderer(m, 16, 16) as r:\n"
    "    r.update_scene(d)\n"
    "    r.render()\n"
)

ModelLike = Union["mujoco.MjModel", str, os.PathLike]
Push = Union[tuple[float, float, float], tuple[float, float, Sequence[float]], None]

_gl_status: tuple[str, str | None] | None = None  # (MUJOCO_GL, reason) of the last check


class RenderUnavailable(RuntimeError):
    """No OpenGL context can be made for offscreen rendering."""


# ---------------------------------------------------------------------------
# OpenGL backend


def _one_line(text: str) -> str:
    lines = [ln.strip() for ln in str(text).strip().splitlines() if ln.strip()]
    return lines[-1] if lines else "unknown error"


def _probe_subprocess(backend: str) -> str | None:
    """Tries ``backend`` in a fresh interpreter; None when it renders."""
    env = dict(os.environ, MUJOCO_GL=backend)
    env.pop("PYOPENGL_PLATFORM", None)
    try:
        p = subprocess.run(
            [sys.executable, "-c", _PROBE_CODE],
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
        )
    except (OSError, subprocess.TimeoutExpired) as e:
        return f"probe did not run ({e})"
    if p.returncode == 0:
        return None
    return _one_line(p.stderr or p.stdout or f"exit status {p.returncode}")


def _install_backend(backend: str) -> None:
    """Makes an already imported ``mujoco`` use ``backend``'s GL context."""
    import importlib

    from mujoco.rendering.classic import gl_context  # type: ignore[import-not-found]

    module = {"egl": "mujoco.egl", "osmesa": "mujoco.osmesa", "glfw": "mujoco.glfw"}[backend]
    cls = importlib.import_module(module).GLContext
    gl_context.GLContext = cls
    import mujoco

    mujoco.GLContext = cls  # type: ignore[attr-defined]


def _probe_in_process() -> str | None:
    try:
        import mujoco

        m = mujoco.MjModel.from_xml_string(_PROBE_XML)
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        with mujoco.Renderer(m, 16, 16) as r:
            r.update_scene(d)
            img = r.render()
        if img.shape != (16, 16, 3):
            return f"unexpected image shape {img.shape}"
    except Exception as e:  # noqa: BLE001 - any failure means "no rendering"
        return f"{type(e).__name__}: {_one_line(str(e))}"
    return None


def _candidates() -> list[str]:
    if sys.platform != "linux":
        return ["glfw"]
    c = ["egl", "osmesa"]
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        c.append("glfw")
    return c


def gl_available() -> str | None:
    """None if an offscreen OpenGL context works, else a one-line reason.

    Respects an existing ``MUJOCO_GL``; otherwise probes egl, then osmesa, and
    sets ``os.environ["MUJOCO_GL"]`` to the first that works. Call it before
    anything renders (``MUJOCO_GL`` is read when ``mujoco`` is imported; if it
    already was, the chosen backend is installed into the imported module).
    The answer is cached per ``MUJOCO_GL`` value.
    """
    global _gl_status
    env = os.environ.get("MUJOCO_GL", "").strip().lower()
    if _gl_status is not None and _gl_status[0] == env:
        return _gl_status[1]
    reason: str | None
    if env:
        err = _probe_in_process()
        reason = None if err is None else f"MUJOCO_GL={env} cannot render ({err}); fix: {FIX_HINT}"
    else:
        tried: list[str] = []
        chosen = None
        for backend in _candidates():
            err = _probe_subprocess(backend)
            if err is None:
                chosen = backend
                break
            tried.append(f"{backend}: {err}")
        if chosen is None:
            reason = f"no OpenGL backend works ({'; '.join(tried)}); fix: {FIX_HINT}"
        else:
            os.environ["MUJOCO_GL"] = chosen
            env = chosen
            err = None
            if "mujoco" in sys.modules:
                try:
                    _install_backend(chosen)
                except Exception as e:  # noqa: BLE001
                    err = f"{type(e).__name__}: {_one_line(str(e))}"
            if err is None:
                err = _probe_in_process()
            reason = (
                None
                if err is None
                else (
                    f"MUJOCO_GL={chosen} works in a fresh process but not in this one, "
                    f"where mujoco was imported first ({err}); fix: set MUJOCO_GL={chosen} "
                    "before importing mujoco"
                )
            )
    _gl_status = (env, reason)
    return reason


def _require_gl() -> None:
    reason = gl_available()
    if reason is not None:
        raise RenderUnavailable(reason)


# ---------------------------------------------------------------------------
# Models


def builtin_model_path(name: str) -> Path | None:
    """Path of a built-in model's XML, shipped as package data, or None."""
    p = Path(__file__).parent / "models" / f"{name}.xml"
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

    try:  # the XML compiled into the native module, as the CLI uses it
        xml = _native.builtin_xml(str(model))
    except _native.ModelError:
        raise FileNotFoundError(
            f"model '{model}' is neither an existing XML file nor a built-in model"
        ) from None
    return mujoco.MjModel.from_xml_string(xml)


def _base_body(model: "mujoco.MjModel", name: str = "") -> int:
    import mujoco

    if name:
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        if bid < 0:
            raise ValueError(f"push body '{name}' is not in the model")
        return int(bid)
    free = np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    if free.size:
        return int(model.jnt_bodyid[free[0]])
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "base_link")
    return int(bid) if bid >= 0 else min(1, model.nbody - 1)


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
        r.update_scene(data, camera=_camera_arg(model, camera))
        return r.render().copy()


# ---------------------------------------------------------------------------
# Simulation


@dataclass
class _CellRun:
    label: str
    params: str
    frames: list[np.ndarray] = field(default_factory=list)
    times: list[float] = field(default_factory=list)
    pushing: list[bool] = field(default_factory=list)
    z: list[float] = field(default_factory=list)
    diverged_at: float | None = None


def _push_tuple(push: Push) -> tuple[float, float, np.ndarray] | None:
    if push is None:
        return None
    start, duration, force = push
    f = np.zeros(3)
    if np.ndim(force) == 0:
        f[2] = float(force)  # type: ignore[arg-type]
    else:
        f[:] = np.asarray(force, dtype=float)[:3]
    return float(start), float(duration), f


def _cell_label(cell: Mapping[str, Any], kp: float, kd: float) -> tuple[str, str]:
    params = f"Kp {kp:g}  Kd {kd:g}"
    extras = [
        f"{k} {float(cell[k]):g}"
        for k in ("max_torque", "push_force", "friction", "timestep")
        if k in cell and cell[k] is not None
    ]
    if extras:
        params += "  " + "  ".join(extras)
    label = str(cell.get("label") or cell.get("name") or "")
    return label, params


def _simulate(
    model: ModelLike,
    cells: Sequence[Mapping[str, Any]],
    seconds: float,
    fps: float,
    push: Push,
    mode: str,
    width: int,
    height: int,
    *,
    camera: str | int | None = "tracking_cam",
    keyframe: str | int | None = "home",
    max_torque: float = 3.0,
    push_body: str = "",
    defaults: Mapping[str, float] | None = None,
    shadows: bool = True,
    pose: Sequence[float] | None = None,
) -> list[_CellRun]:
    _require_gl()
    import mujoco

    if mode not in ("servo", "torque"):
        raise ValueError(f"mode must be 'servo' or 'torque', got {mode!r}")
    if fps <= 0 or seconds < 0:
        raise ValueError("fps must be > 0 and seconds >= 0")
    base_model = _load_model(model)
    _ensure_buffer(base_model, width, height)
    base_push = _push_tuple(push)
    runs: list[_CellRun] = []
    with _new_renderer(base_model, width, height) as renderer:
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = bool(shadows)
        cam = _camera_arg(base_model, camera)
        for cell in cells:
            for k in ("leg_scale", "torso_mass_scale"):
                if k in cell and cell[k] is not None and float(cell[k]) != 1.0:
                    warnings.warn(
                        f"render: {k}={cell[k]} is not applied (the rendered body is unscaled)",
                        stacklevel=3,
                    )
            dflt = defaults or {}
            kp = float(cell.get("kp", dflt.get("kp", 5.0)))
            kd = float(cell.get("kd", dflt.get("kd", 0.1)))
            tmax = float(cell.get("max_torque", max_torque))
            label, params = _cell_label(cell, kp, kd)
            run = _CellRun(label=label, params=params)
            runs.append(run)

            m = copy.copy(base_model)
            if cell.get("timestep") is not None:
                m.opt.timestep = float(cell["timestep"])
            if cell.get("friction") is not None:
                colliding = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
                m.geom_friction[colliding, 0] = float(cell["friction"])
            m.actuator_forcerange[:, 0] = -tmax
            m.actuator_forcerange[:, 1] = tmax
            m.actuator_forcelimited[:] = 1
            m.actuator_gainprm[:, :] = 0.0
            m.actuator_biasprm[:, :] = 0.0
            if mode == "servo":
                m.actuator_gainprm[:, 0] = kp
                m.actuator_biasprm[:, 1] = -kp
                m.actuator_biasprm[:, 2] = -kd
            else:
                m.actuator_gainprm[:, 0] = 1.0
                m.actuator_ctrllimited[:] = 0
            d = mujoco.MjData(m)
            jnt = m.actuator_trnid[:, 0]
            qadr = m.jnt_qposadr[jnt]
            vadr = m.jnt_dofadr[jnt]
            if pose is not None:  # start and target pose; the base as in the first keyframe
                if len(pose) != m.nu:
                    raise ValueError(f"pose has {len(pose)} angles, the model has {m.nu} actuators")
                _reset(m, d, 0 if m.nkey > 0 else None)
                d.qpos[qadr] = np.asarray(pose, dtype=float)
                d.ctrl[:] = np.asarray(pose, dtype=float)
                mujoco.mj_forward(m, d)
            else:
                _reset(m, d, keyframe)
            targets = d.ctrl.copy()
            if mode == "torque":
                d.ctrl[:] = 0.0
            body = _base_body(m, push_body)
            cell_push = base_push
            if cell.get("push_force") is not None:
                pf = np.zeros(3) if base_push is None else base_push[2].copy()
                pf[2] = float(cell["push_force"])
                s, du = (2.0, 0.25) if base_push is None else base_push[:2]
                cell_push = (s, du, pf)

            def capture(pushing: bool) -> None:
                renderer.update_scene(d, camera=cam)
                run.frames.append(renderer.render().copy())
                run.times.append(float(d.time))
                run.pushing.append(pushing)
                run.z.append(float(d.xpos[body, 2]))

            capture(False)
            nframes = int(round(seconds * fps)) + 1
            nsteps = int(round(seconds / m.opt.timestep))
            bad0 = int(d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number)
            k = 1
            pushing = False
            for _ in range(nsteps):
                t = d.time
                pushing = cell_push is not None and cell_push[0] <= t < cell_push[0] + cell_push[1]
                d.xfrc_applied[body, :3] = cell_push[2] if pushing else 0.0  # type: ignore[index]
                if mode == "torque":
                    tau = kp * (targets - d.qpos[qadr]) - kd * d.qvel[vadr]
                    d.ctrl[:] = np.clip(tau, -tmax, tmax)
                mujoco.mj_step(m, d)
                if run.diverged_at is None and (
                    int(d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number) > bad0
                    or not np.isfinite(d.qpos).all()
                ):
                    run.diverged_at = float(d.time)
                while k < nframes and d.time >= k / fps - 1e-9:
                    capture(pushing)
                    k += 1
            while k < nframes:  # rounding: pad with the last state
                capture(pushing)
                k += 1
    return runs


def simulate_frames(
    model_xml_path_or_string: ModelLike,
    cells: Sequence[Mapping[str, Any]],
    seconds: float = 10.0,
    fps: float = 25,
    push: Push = (2.0, 0.25, -25.0),
    mode: str = "servo",
    width: int = 320,
    height: int = 240,
    *,
    camera: str | int | None = "tracking_cam",
    keyframe: str | int | None = "home",
    max_torque: float = 3.0,
    shadows: bool = True,
) -> list[list[np.ndarray]]:
    """Simulates each cell and returns its frames (H, W, 3 uint8) at ``fps``.

    ``cells`` are dicts with ``kp``, ``kd`` and optionally ``max_torque``,
    ``push_force`` (world z, N), ``friction``, ``timestep``, ``name``/``label``.
    ``push`` is ``(start_s, duration_s, force_z_N or (fx, fy, fz))`` or None.
    Frames are taken at t = 0, 1/fps, ..., seconds (``round(seconds*fps)+1``).
    ``shadows=False`` renders about 3x faster on software OpenGL (llvmpipe).
    """
    runs = _simulate(
        model_xml_path_or_string,
        cells,
        seconds,
        fps,
        push,
        mode,
        width,
        height,
        camera=camera,
        keyframe=keyframe,
        max_torque=max_torque,
        shadows=shadows,
    )
    return [r.frames for r in runs]


# ---------------------------------------------------------------------------
# Pictures


def _font(size: int) -> "ImageFont.FreeTypeFont | ImageFont.ImageFont":
    from PIL import ImageFont

    for name in ("DejaVuSans.ttf", "DejaVuSans-Bold.ttf"):
        try:
            return ImageFont.truetype(name, size)
        except OSError:
            pass
    try:
        import importlib.util

        spec = importlib.util.find_spec("matplotlib")
        if spec is not None and spec.submodule_search_locations:
            p = Path(list(spec.submodule_search_locations)[0]) / "mpl-data/fonts/ttf/DejaVuSans.ttf"
            if p.exists():
                return ImageFont.truetype(str(p), size)
    except (ImportError, OSError):
        pass
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # old Pillow
        return ImageFont.load_default()


def _text_box(draw: Any, xy: tuple[int, int], text: str, font: Any, fill: tuple[int, int, int]) -> None:
    """Text with a dark translucent backing box for legibility on any scene."""
    x0, y0, x1, y1 = draw.textbbox(xy, text, font=font)
    draw.rectangle((x0 - 4, y0 - 3, x1 + 4, y1 + 3), fill=(0, 0, 0, 150))
    draw.text(xy, text, font=font, fill=fill)


def _panel(
    img: np.ndarray,
    title: str,
    params: str,
    t: float,
    pushing: bool,
    push_text: str,
    status: str,
    fonts: tuple[Any, Any],
    header_h: int,
) -> "PILImage.Image":
    from PIL import Image, ImageDraw

    big, small = fonts
    h, w = img.shape[:2]
    panel = Image.new("RGB", (w, h + header_h), (245, 245, 245))
    panel.paste(Image.fromarray(img), (0, header_h))
    d = ImageDraw.Draw(panel)
    if title:
        d.text((8, 4), title, font=big, fill=(20, 20, 20))
        d.text((8, 4 + big.size + 4), params, font=small, fill=(60, 60, 60))
    else:
        d.text((8, 4), params, font=big, fill=(20, 20, 20))
    over = Image.new("RGBA", panel.size, (0, 0, 0, 0))
    od = ImageDraw.Draw(over)
    _text_box(od, (8, h + header_h - small.size - 10), f"t = {t:5.2f} s", small, (255, 255, 255))
    if pushing:
        od.rectangle((0, header_h, w - 1, h + header_h - 1), outline=(230, 30, 30, 255), width=4)
        tw = od.textlength(push_text, font=big)
        _text_box(od, (int(w - tw - 12), header_h + 8), push_text, big, (255, 60, 60))
    if status:
        tw = od.textlength(status, font=small)
        _text_box(od, (int(w - tw - 12), h + header_h - small.size - 10), status, small, (255, 200, 60))
    panel = Image.alpha_composite(panel.convert("RGBA"), over).convert("RGB")
    return panel


def _compose(panels: Sequence["PILImage.Image"], gap: int = 4) -> "PILImage.Image":
    from PIL import Image

    w = sum(p.width for p in panels) + gap * (len(panels) - 1)
    h = max(p.height for p in panels)
    out = Image.new("RGB", (w, h), (255, 255, 255))
    x = 0
    for p in panels:
        out.paste(p, (x, 0))
        x += p.width + gap
    return out


def _atomic_save(img_or_frames: Any, path: Path, fmt: str, **kw: Any) -> None:
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        if isinstance(img_or_frames, list):
            first, rest = img_or_frames[0], img_or_frames[1:]
            first.save(tmp, format=fmt, save_all=True, append_images=rest, **kw)
        else:
            img_or_frames.save(tmp, format=fmt, **kw)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


_LABEL_COLOURS = [(255, 60, 60), (230, 30, 30), (255, 255, 255), (255, 200, 60), (20, 20, 20), (60, 60, 60), (245, 245, 245), (0, 0, 0)]


def _palette_of(img: "PILImage.Image", colors: int) -> list[tuple[int, int, int]]:
    """The colours (at most ``colors``) of a median-cut quantization of ``img``."""
    from PIL import Image

    q = img.quantize(colors=colors, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    pal = q.getpalette() or []
    used = sorted({c for _, c in (q.getcolors(colors) or [])})
    return [tuple(pal[3 * i : 3 * i + 3]) for i in used]  # type: ignore[misc]


def _shared_palette(frames: Sequence["PILImage.Image"]) -> list["PILImage.Image"]:
    """Quantizes all frames to one palette (smaller, flicker-free GIFs).

    The palette mixes the common colours of a few sample frames, the vivid
    ones (the legs, which are small) and the label colours.
    """
    from PIL import Image

    n = len(frames)
    picks = sorted({0, n // 4, n // 2, (3 * n) // 4, n - 1})
    w, h = frames[0].size
    mosaic = Image.new("RGB", (w, h * len(picks)))
    for j, i in enumerate(picks):
        mosaic.paste(frames[i], (0, h * j))
    colours = list(_LABEL_COLOURS)
    arr = np.asarray(mosaic).reshape(-1, 3).astype(np.int16)
    vivid = arr[(arr.max(axis=1) - arr.min(axis=1)) > 90]
    if len(vivid) > 64:
        vivid_img = Image.fromarray(vivid.astype(np.uint8)[None, :, :], "RGB")
        colours += _palette_of(vivid_img, 48)
    colours += _palette_of(mosaic, 256 - len(colours))
    colours = colours[:256]
    flat = [v for c in colours for v in c]
    flat += flat[-3:] * (256 - len(colours))
    pal = Image.new("P", (1, 1))
    pal.putpalette(flat)
    return [f.quantize(palette=pal, dither=Image.Dither.NONE) for f in frames]


def _run_settings(source: ModelLike | Path) -> dict[str, Any]:
    """Model, mode, push and defaults of a run directory, else of a model."""
    p = Path(source) if isinstance(source, (str, os.PathLike)) and not str(source).lstrip().startswith("<") else None
    if p is not None and p.is_dir():
        import json

        man_path = p / "manifest.json"
        if not man_path.exists():
            raise FileNotFoundError(f"{p} has no manifest.json: is it a pupper run directory?")
        man = json.loads(man_path.read_text())
        cfg = man.get("config", {})
        src = cfg.get("model") or {"builtin": "pupper_v3"}
        if "path" in src:
            model: ModelLike = src["path"]
        else:
            model = src.get("builtin", "pupper_v3")
        sched = cfg.get("schedule") or {}
        pu = sched.get("push")
        push: Push = None if not pu else (float(pu["start"]), float(pu["duration"]), tuple(pu["force"]))
        initial = sched.get("initial")
        keyframe = initial.get("keyframe", "home") if isinstance(initial, dict) else "home"
        pose = initial.get("pose") if isinstance(initial, dict) else None
        return {
            "pose": pose,
            "model": model,
            "mode": cfg.get("mode", "servo"),
            "push": push,
            "push_body": (pu or {}).get("body", "") or "",
            "defaults": cfg.get("defaults") or {"kp": 5.0, "kd": 0.1, "max_torque": 3.0},
            "keyframe": keyframe,
        }
    return {
        "pose": None,
        "model": source,
        "mode": "servo",
        "push": (2.0, 0.25, -25.0),
        "push_body": "",
        "defaults": {"kp": 5.0, "kd": 0.1, "max_torque": 3.0},
        "keyframe": "home",
    }


def write_effects(
    run_dir_or_model: ModelLike | Path,
    cells: Sequence[Mapping[str, Any]],
    out_dir: str | os.PathLike,
    seconds: float = 10.0,
    fps: float = 20,
    *,
    push: Push | str = "auto",
    mode: str | None = None,
    width: int = 320,
    height: int = 240,
    stem: str = "gain_sweep_effects",
    shadows: bool = True,
) -> tuple[Path, Path]:
    """Writes ``<stem>.png`` (final frames) and ``<stem>.gif`` (synchronized panels).

    ``run_dir_or_model`` is a run directory (model, mode, push and default
    gains come from its manifest) or a model (path, XML, MjModel, built-in
    name; servo mode and the default push then). ``push="auto"`` keeps that
    push; pass a ``(start, duration, force)`` tuple or None to override.
    Returns ``(png_path, gif_path)``.
    """
    from PIL import Image

    if not cells:
        raise ValueError("write_effects needs at least one cell")
    st = _run_settings(run_dir_or_model)
    the_push: Push = st["push"] if isinstance(push, str) else push
    the_mode = mode or st["mode"]
    defaults = {k: float(v) for k, v in st["defaults"].items() if v is not None}
    runs = _simulate(
        st["model"],
        cells,
        seconds,
        fps,
        the_push,
        the_mode,
        width,
        height,
        keyframe=st["keyframe"],
        pose=st["pose"],
        push_body=st["push_body"],
        max_torque=defaults.get("max_torque", 3.0),
        defaults=defaults,
        shadows=shadows,
    )
    pt = _push_tuple(the_push)
    push_text = "PUSH"
    if pt is not None:
        f = pt[2]
        if f[0] == 0 and f[1] == 0:  # vertical: magnitude and an arrow
            push_text = f"PUSH {abs(f[2]):g} N {'↓' if f[2] < 0 else '↑'}"
        else:
            push_text = f"PUSH {float(np.linalg.norm(f)):g} N"
    scale = max(1.0, width / 320)
    fonts = (_font(int(round(17 * scale))), _font(int(round(13 * scale))))
    any_title = any(r.label for r in runs)
    header_h = int(round((46 if any_title else 28) * scale))

    def status(r: _CellRun, i: int) -> str:
        if r.diverged_at is not None and r.times[i] >= r.diverged_at:
            return "DIVERGED"
        return f"base z {r.z[i] * 1000:.0f} mm"

    nframes = min(len(r.frames) for r in runs)
    gif_frames: list[Image.Image] = []
    for i in range(nframes):
        panels = [
            _panel(r.frames[i], r.label, r.params, r.times[i], r.pushing[i], push_text, status(r, i), fonts, header_h)
            for r in runs
        ]
        gif_frames.append(_compose(panels))
    finals = []
    for r in runs:
        i = len(r.frames) - 1
        finals.append(_panel(r.frames[i], r.label, r.params, r.times[i], False, push_text, status(r, i), fonts, header_h))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    png_path = out / f"{stem}.png"
    gif_path = out / f"{stem}.gif"
    _atomic_save(_compose(finals), png_path, "PNG")
    _atomic_save(_shared_palette(gif_frames), gif_path, "GIF", duration=int(round(1000 / fps)), loop=0)
    return png_path, gif_path


def render_png(
    model: ModelLike,
    path: str | os.PathLike,
    camera: str | int | None = "tracking_cam",
    keyframe: str | int | None = "home",
    seconds: float = 0.0,
    kp: float | None = None,
    kd: float | None = None,
    width: int = 640,
    height: int = 480,
) -> Path:
    """Renders one model (optionally after ``seconds`` of servo simulation) to a PNG.

    ``kp``/``kd`` override the servo gains (None keeps the model's). No push.
    """
    _require_gl()  # before importing mujoco: a broken MUJOCO_GL breaks that import
    import mujoco
    from PIL import Image

    m = copy.copy(_load_model(model))
    if kp is not None:
        m.actuator_gainprm[:, 0] = kp
        m.actuator_biasprm[:, 1] = -kp
    if kd is not None:
        m.actuator_biasprm[:, 2] = -kd
    d = mujoco.MjData(m)
    _reset(m, d, keyframe)
    if seconds > 0:
        mujoco.mj_step(m, d, nstep=max(1, int(round(seconds / m.opt.timestep))))
    img = frame(m, d, camera=camera, width=int(width), height=int(height))
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    _atomic_save(Image.fromarray(img), out, "PNG")
    return out


def write_run_effects(run_dir: str | os.PathLike, max_cells: int = 6, fps: float = 15) -> list[Path]:
    """`pupper sweep --render`: the effects GIF and final-frame PNG of a run.

    Renders up to ``max_cells`` cells of the run's summary.csv (all of them if
    the grid is that small, else evenly spread ones, the steadiest included),
    for the run's duration, into ``<run_dir>/plots/``. Shadows are off to keep
    software rendering quick.
    """
    import csv
    import json

    run = Path(run_dir)
    with open(run / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{run}/summary.csv has no cells to render")
    picks = list(range(len(rows)))
    if len(rows) > max_cells:
        step = (len(rows) - 1) / (max_cells - 1)
        picks = sorted({round(i * step) for i in range(max_cells)})
        ok = [i for i, r in enumerate(rows) if r["status"] == "ok" and r["last_1s_std_mm"]]
        if ok:
            best = min(ok, key=lambda i: float(rows[i]["last_1s_std_mm"]))
            if best not in picks:
                picks[-1] = best
                picks.sort()
    skip = {"index", "id", "name", "status"}
    cells: list[dict[str, Any]] = []
    for i in picks:
        cell: dict[str, Any] = {}
        for key, value in rows[i].items():
            if key in skip or value == "":
                continue
            try:
                cell[key] = float(value)
            except ValueError:
                continue
        if rows[i]["name"]:
            cell["name"] = rows[i]["name"]
        cells.append(cell)
    seconds = float(json.loads((run / "manifest.json").read_text())["config"]["schedule"]["duration"])
    png, gif = write_effects(run, cells, run / "plots", seconds=seconds, fps=fps, shadows=False)
    return [png, gif]


def view(model: ModelLike) -> None:
    """`pupper view`: MuJoCo's interactive viewer on a model, from its home keyframe."""
    import mujoco
    import mujoco.viewer

    m = _load_model(model)
    d = mujoco.MjData(m)
    _reset(m, d, "home" if m.nkey else None)
    mujoco.viewer.launch(m, d)
