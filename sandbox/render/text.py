"""Text on the 8-bit pictures (titles, clocks, legends, chart labels) in a real, anti-aliased font.

The font is Pillow's built-in scalable one (`ImageFont.load_default(size)`, FreeType), so no font file has to be
found on the machine. It has ASCII and a few signs only: a text with other letters (accents, Arabic: a classroom
page's language) is drawn in DejaVu Sans where one is found (matplotlib's copy, else the system's), laid out by
Pillow's Raqm engine (right-to-left scripts shaped and ordered) where Pillow has it. Text is drawn with a dark
outline, so it reads over any colour of the scene.
"""

from __future__ import annotations

import importlib.util
import unicodedata
from functools import lru_cache
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont, features

LIGHT = (235, 235, 235)  # the text colour when none is given
GREY = (190, 190, 190)
PAD = 2  # pixels of margin around a text's glyphs (room for the outline)
SYSTEM_FONTS = ("/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf", "/usr/share/fonts/TTF/DejaVuSans.ttf")


def text_size(height: int) -> int:
    """The font size (pixels) for a picture `height` pixels tall: 1/40 of it, at least 11 (legible at 360p, about
    18 at 720p and 27 at 1080p)."""
    return max(11, round(height / 40))


@lru_cache(maxsize=32)
def font(size: int) -> ImageFont.FreeTypeFont:
    """Pillow's built-in scalable font at `size` pixels."""
    return ImageFont.load_default(size=size)


@lru_cache(maxsize=1)
def wide_font_path() -> Path | None:
    """DejaVu Sans (Latin with accents, Greek, Cyrillic, Arabic): matplotlib's copy where it is installed (found
    without importing it), else the system's; None where there is neither."""
    spec = importlib.util.find_spec("matplotlib")
    places = []
    if spec and spec.origin:
        places.append(Path(spec.origin).parent / "mpl-data" / "fonts" / "ttf" / "DejaVuSans.ttf")
    places += [Path(p) for p in SYSTEM_FONTS]
    return next((p for p in places if p.is_file()), None)


@lru_cache(maxsize=32)
def wide_font(size: int) -> ImageFont.FreeTypeFont | None:
    """The wide font at `size` pixels, laid out by Raqm where Pillow has it; None without the font."""
    path = wide_font_path()
    if path is None:
        return None
    layout = ImageFont.Layout.RAQM if features.check("raqm") else ImageFont.Layout.BASIC
    return ImageFont.truetype(str(path), size, layout_engine=layout)


def _draws(face: ImageFont.FreeTypeFont, char: str) -> bool:
    """Whether `face` has a glyph for `char` (not its missing-glyph box)."""
    mask, missing = face.getmask(char), face.getmask("\uffff")
    return (bytes(mask), mask.size) != (bytes(missing), missing.size)


@lru_cache(maxsize=1024)
def in_default_font(char: str) -> bool:
    """Whether Pillow's built-in font draws `char`."""
    return char.isspace() or _draws(font(18), char)


@lru_cache(maxsize=1024)
def has_glyph(char: str) -> bool:
    """Whether the picture can draw `char`: the built-in font has it, or the wide font does (a right-to-left letter
    only where Raqm can order and shape it)."""
    if in_default_font(char):
        return True
    wide = wide_font(18)
    if wide is None or not _draws(wide, char):
        return False
    return unicodedata.bidirectional(char) not in ("R", "AL") or features.check("raqm")


def direction_of(text: str) -> str | None:
    """ "rtl" for a text whose first strong letter is right-to-left (Arabic, Hebrew) where Raqm lays it out, so that
    its parentheses and numbers sit as a reader of that script expects; else None (Pillow's default)."""
    for c in text:
        kind = unicodedata.bidirectional(c)
        if kind in ("R", "AL"):
            return "rtl" if features.check("raqm") else None
        if kind == "L":
            return None
    return None


def face_for(text: str, size: int) -> ImageFont.FreeTypeFont:
    """The font `text` is drawn in at `size` pixels: the built-in one where it has every letter, else the wide one."""
    if all(in_default_font(c) for c in text):
        return font(size)
    return wide_font(size) or font(size)


@lru_cache(maxsize=4096)
def text_width(text: str, size: int) -> int:
    """Pixels `text` takes across at font size `size`."""
    return int(np.ceil(face_for(text, size).getlength(text, direction=direction_of(text))))


def line_height(size: int) -> int:
    """Pixels from one line's top to the next's at font size `size`."""
    return round(size * 1.3)


@lru_cache(maxsize=2048)
def _masks(text: str, size: int, outline: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """The coverage of `text`'s glyphs and of its outline, (h, w, 1) floats in [0, 1] with a 2-pixel margin: drawn
    by Pillow once per text and size, then reused (a picture's labels repeat from frame to frame)."""
    face = face_for(text, size)
    w, h = text_width(text, size) + 2 * PAD, line_height(size) + 2 * PAD
    glyphs = Image.new("L", (w, h))
    direction = direction_of(text)
    ImageDraw.Draw(glyphs).text((PAD, PAD), text, font=face, fill=255, direction=direction)
    cover = np.asarray(glyphs, np.float32)[:, :, None] / 255.0
    shade = None
    if outline:
        halo = Image.new("L", (w, h))
        ImageDraw.Draw(halo).text(
            (PAD, PAD), text, font=face, fill=255, stroke_width=max(1, size // 10), direction=direction
        )
        shade = np.asarray(halo, np.float32)[:, :, None] / 255.0 * 0.75
    return cover, shade


def draw_text(img: np.ndarray, text: str, x: int, y: int, size: int, color=LIGHT, outline: bool = True) -> None:
    """Draw `text` into an (H, W, 3) uint8 image (or a view of one) with its top-left corner at pixel (x, y), rows
    counted from the top, font size `size` pixels; what falls outside the image is clipped."""
    if not text:
        return
    cover, shade = _masks(text, size, outline)
    h, w = cover.shape[:2]
    x0, y0 = x - PAD, y - PAD
    cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x0 + w, img.shape[1]), min(y0 + h, img.shape[0])
    if cx0 >= cx1 or cy0 >= cy1:
        return
    region = img[cy0:cy1, cx0:cx1]
    if shade is not None:
        region[:] = (region * (1.0 - shade[cy0 - y0 : cy1 - y0, cx0 - x0 : cx1 - x0])).astype(np.uint8)
    cover = cover[cy0 - y0 : cy1 - y0, cx0 - x0 : cx1 - x0]
    ink = np.asarray(color, np.float32)[None, None, :]
    region[:] = (region * (1.0 - cover) + ink * cover + 0.5).astype(np.uint8)


def dim(img: np.ndarray, rect: tuple[int, int, int, int], keep: float = 0.3) -> None:
    """Darken the pixels of rect (x0, x1, row0, row1; rows from the top) of an (H, W, 3) uint8 image to `keep` of
    their brightness: the backing of a chart or legend, so that its lines read over the scene."""
    x0, x1, r0, r1 = rect
    x0, r0, x1, r1 = max(x0, 0), max(r0, 0), min(x1, img.shape[1]), min(r1, img.shape[0])
    if x0 < x1 and r0 < r1:
        img[r0:r1, x0:x1] = (img[r0:r1, x0:x1] * keep).astype(np.uint8)
