"""Pixels on the renderer's 8-bit outputs: one pixel written or read in a kernel (an (H, W, 3) picture or GGUI's
packed RGBA). Text is drawn on the host (text.py)."""

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
