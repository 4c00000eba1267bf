"""Pixels and text on the renderer's 8-bit outputs: one pixel written or read in a kernel (an (H, W, 3) picture or
GGUI's packed RGBA), and a 3 x 5 pixel font for the labels of legends, charts and the clock."""

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


# A 3 x 5 pixel font: digits, capital letters (lower case is drawn as capitals, except the exponent's e), the degree
# sign and the punctuation of labels and units. Each glyph is its five rows, top first, three pixels each.
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
    "A": "010101111101101",
    "B": "110101110101110",
    "C": "011100100100011",
    "D": "110101101101110",
    "E": "111100110100111",
    "F": "111100110100100",
    "G": "011100101101011",
    "H": "101101111101101",
    "I": "111010010010111",
    "J": "001001001101010",
    "K": "101101110101101",
    "L": "100100100100111",
    "M": "101111111101101",
    "N": "110101101101101",
    "O": "010101101101010",
    "P": "110101110100100",
    "Q": "010101101110011",
    "R": "110101110101101",
    "S": "011100010001110",
    "T": "111010010010010",
    "U": "101101101101111",
    "V": "101101101101010",
    "W": "101101111111101",
    "X": "101101010101101",
    "Y": "101101010010010",
    "Z": "111001010100111",
    "°": "010101010000000",
    "=": "000111000111000",
    "/": "001001010100100",
    ":": "000010000010000",
    "%": "101001010100101",
    "(": "010100100100010",
    ")": "010001001001010",
    ",": "000000000010100",
    "_": "000000000000111",
    " ": "000000000000000",
}


def glyph(ch: str) -> str | None:
    """The 3 x 5 bitmap of `ch` (lower case as upper case, but for the exponent's e), or None."""
    return _GLYPHS.get(ch) or _GLYPHS.get(ch.upper())


def text_scale(height: int) -> int:
    """The font's scale for a picture `height` pixels tall: one font pixel per 240 rows (at least 1)."""
    return max(1, height // 240)


def text_width(text: str, scale: int = 1) -> int:
    """Pixels `text` takes across: 4 per character (3 and a gap) at scale 1."""
    return 4 * scale * len(text)


def draw_text(img: np.ndarray, text: str, x: int, y: int, scale: int = 1, color=(230, 230, 230)) -> None:
    """Draw `text` (digits, letters, degree sign, . - + = / : % ( ) , _ and spaces) into an (H, W, 3) uint8 image
    (or a view of one) with its top-left corner at (x, y); characters the font lacks are skipped."""
    for k, ch in enumerate(text):
        bits = glyph(ch)
        if bits is None:
            continue
        for row in range(5):
            for col in range(3):
                if bits[row * 3 + col] == "1":
                    ys, xs = y + row * scale, x + (4 * k + col) * scale
                    if 0 <= ys and ys + scale <= img.shape[0] and 0 <= xs and xs + scale <= img.shape[1]:
                        img[ys : ys + scale, xs : xs + scale] = color
