"""The OpenGL backend MuJoCo renders with (``pupper_core.render``
re-exports what a user calls): MuJoCo picks it from ``MUJOCO_GL`` when
``mujoco`` is first imported; :func:`gl_available` respects a value already
set, else probes ``egl`` then ``osmesa`` (then ``glfw`` with a display) in a
short subprocess and sets ``MUJOCO_GL`` to the first that works, installing
that backend's context class into an already imported ``mujoco``."""

from __future__ import annotations

import os
import subprocess
import sys

from pupper_core._types import exported_from

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

_gl_status: tuple[str, str | None] | None = None  # (MUJOCO_GL, reason) of the last check


@exported_from("pupper_core.render")
class RenderUnavailable(RuntimeError):
    """No OpenGL context can be made for offscreen rendering."""


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


@exported_from("pupper_core.render")
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
