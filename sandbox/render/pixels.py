"""Pixels and text on the renderer's 8-bit outputs: one pixel written or read in a kernel (an (H, W, 3) picture or
GGUI's packed RGBA), and a 3 x 5 pixel font for the numbers of legends and charts."""

import numpy as np
import taichi as ti


@ti.func
def put_pixel(out: ti.template(), height, x, y, c):
    """Write colour c (floats in [0, 1]) at pixel (x, y), y counted up from the bottom, into the 8-bit output `out`:
    an (H, W, 3) picture stored top row first, or GGUI's (W, H) packed RGBA (a uint32 per pixel, R in the low byte,
    y up)."""
    if ti.static(len(out.shape) == 2):
        v = ti.cast(ti.math.clamp(c, 0.0, 1.0) * 255.0 + 0.5, ti.u32)
        out[x, y] = v[0] | (v[1] << 8) | (v[2] << 16) | (ti.cast(255, ti.u32) << 24)
    else:
        v = ti.cast(ti.math.clamp(c, 0.0, 1.0) * 255.0 + 0.5, ti.u8)
        for k in ti.static(range(3)):
            out[height - 1 - y, x, k] = v[k]


@ti.func
def get_pixel(out: ti.template(), height, x, y):
    """The colour (floats in [0, 1]) at pixel (x, y) of an 8-bit output written by put_pixel."""
    c = ti.Vector([0.0, 0.0, 0.0])
    if ti.static(len(out.shape) == 2):
        v = out[x, y]
        c = ti.Vector([v & 255, (v >> 8) & 255, (v >> 16) & 255]) / 255.0
    else:
        c = ti.Vector([out[height - 1 - y, x, k] for k in ti.static(range(3))]) / 255.0
    return c


# A 3 x 5 pixel font for legend numbers.
_GLYPHS = {
    "0": "111101101101111",
    "1": "010110010010111",
    "2": "111001111100111",
    "3": "111001111001111",
    "4": "101101111001001",
    "5": "111100111001111",
    "6": "111100111101111",
    "7": "111001001001001",
    "8": "111101111101111",
    "9": "111101111001111",
    ".": "000000000000010",
    "-": "000000111000000",
    "e": "000111101110111",
    "+": "000010111010000",
}


def draw_text(img: np.ndarray, text: str, x: int, y: int, scale: int = 1, color=(230, 230, 230)) -> None:
    """Draw `text` (digits . - + e) into an (H, W, 3) uint8 image with its top-left corner at (x, y)."""
    for k, ch in enumerate(text):
        glyph = _GLYPHS.get(ch)
        if glyph is None:
            continue
        for row in range(5):
            for col in range(3):
                if glyph[row * 3 + col] == "1":
                    ys, xs = y + row * scale, x + (4 * k + col) * scale
                    if 0 <= ys and ys + scale <= img.shape[0] and 0 <= xs and xs + scale <= img.shape[1]:
                        img[ys : ys + scale, xs : xs + scale] = color
