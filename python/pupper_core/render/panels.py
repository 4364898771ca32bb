"""Pictures of drawn frames (Pillow): a panel per recording with its
header, time, push and status, panels side by side, and GIFs quantized to
one shared palette (``pupper_core.render`` draws the frames)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from pupper_core._rundir import atomic_write

if TYPE_CHECKING:  # pragma: no cover
    from PIL import Image as PILImage
    from PIL import ImageFont

    from pupper_core._types import Recording


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
    def save(tmp: Path) -> None:
        if isinstance(img_or_frames, list):
            first, rest = img_or_frames[0], img_or_frames[1:]
            first.save(tmp, format=fmt, save_all=True, append_images=rest, **kw)
        else:
            img_or_frames.save(tmp, format=fmt, **kw)

    atomic_write(path, save)


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


def _labels(rec: "Recording") -> tuple[str, str]:
    """A panel's title (the cell's name) and its parameter line."""
    setup = rec["setup"]

    def gain(values: list[float]) -> str:
        lo, hi = min(values), max(values)
        return f"{lo:g}" if lo == hi else f"{lo:g}..{hi:g}"

    params = f"Kp {gain(setup['kp'])}  Kd {gain(setup['kd'])}"
    extras = [value if isinstance(value, str) else f"{axis} {value:g}"
              for axis, value in rec["values"].items() if axis not in ("kp", "kd")]
    if extras:
        params += "  " + "  ".join(extras)
    return rec["name"], params


def _push_text(rec: "Recording") -> str:
    f = np.asarray(rec["setup"]["push_force"], dtype=float)
    if f[0] == 0 and f[1] == 0:  # vertical: magnitude and an arrow
        return f"PUSH {abs(f[2]):g} N {'↓' if f[2] < 0 else '↑'}"
    return f"PUSH {float(np.linalg.norm(f)):g} N"
