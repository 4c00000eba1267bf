"""The additive light of a 2D picture as data for a page to draw: a "light frame", sent before each particle frame
(particle_frame.py) of a scene whose particles glow (candle's flame, fireworks' sparks), so that the classroom's page
draws those scenes too instead of receiving the renderer's JPEG pictures.

The renderer spreads each additive particle's energy, opacity * pi R^2 (R its radius in pixels), over its footprint
(the capsule around its motion-blur streak, footprint.py) by normalised weights, adds up the light per pixel and
tone maps it over the picture, 1 - exp(-exposure L) per channel (flat.py). A light frame carries what a page needs
to do the same per pixel: each glowing particle's streak (head, tail and control point), radius, whether it is
blurred, its colour, and its intensity: energy over the sum of its weights, which the server computes here with the
renderer's own code (a page's pixel then adds intensity x weight x colour, as the renderer's does). The page
(sandbox/app/web/light.js) adds them up in a float buffer with WebGL2 and tone maps them over its picture.

A light frame, little-endian:

    b"L", n (u32), exposure (f32), flags (u32: 1 where blurred streaks are curved, motion_path = "spline"), then n
    records of ten 32-bit words: the head, tail and control point as x, y f32 pairs (pixels, rows from the top: a
    particle partly off the picture keeps its place), r | blurred << 16 (u32; the drawn radius in pixels x 16), the
    intensity (f32), and R | G << 8 | B << 16 (u32: the colour over its largest channel, whose value the intensity
    carries).
"""

import math
import struct

import numpy as np
import taichi as ti

from ..core.oriented import data_oriented
from .style import BLEND

LIGHT_HEADER = struct.Struct("<cIfI")  # b"L", n, exposure, flags
CURVED = 1  # flags: blurred streaks are quadratic curves through their control point
FIXED = 16.0  # sub-pixel steps per pixel in the radius, as particle frames
RECORD_WORDS = 10


def glows(renderer) -> bool:
    """Whether `renderer`'s 2D picture has additive light (then its particle frames go with light frames)."""
    return renderer.dim == 2 and "additive" in renderer.look.blends


@data_oriented
class LightFrame:
    """Packs the additive light of a 2D `renderer`'s particles into light frames (module docstring)."""

    def __init__(self, renderer):
        if not glows(renderer):
            raise ValueError("light frames: this scene's picture has no additive light; expected a 2D scene that glows")
        self.renderer = renderer
        self.painter, self.footprint, self.look = renderer.painter, renderer.footprint, renderer.look
        self.p, self.canvas = renderer.state.particles, renderer.canvas
        self.height = renderer.height
        self.flags = CURVED if self.footprint.spline else 0
        self.exposure = float(renderer.canvas.exposure)
        self.world: int | None = None  # the world whose light is packed (core/worlds.py), None: every live particle's
        # on the CPU the kernel writes straight into this host array (no copy)
        self.records = np.zeros((max(renderer.model.capacity, 1), RECORD_WORDS), np.uint32)
        self.count = ti.field(ti.i32, shape=())

    def encode(self) -> bytes:
        """The light frame of the state now (the module docstring's layout); the renderer's tails must be those of
        the frame just stepped (Renderer.begin_frame before its steps)."""
        self.footprint.before_drawing()  # no middle position this frame: curved streaks drawn straight
        first, n = self.p.block(self.world)
        m = self._pack(first, n, self.records)  # even for none: compiled where a session warms up
        return LIGHT_HEADER.pack(b"L", m, self.exposure, self.flags) + self.records[:m].tobytes()

    @ti.kernel
    def _pack(self, first: ti.i32, n: ti.i32, records: ti.types.ndarray()) -> ti.i32:
        look, p, fp = self.look, self.p, self.footprint
        self.count[None] = 0
        for i in range(first, first + n):
            if look.g_blend[p.group[i]] == BLEND["additive"]:
                tail, ctrl, head, r, r_true, blurred = self.painter.splat_shape(i)
                x0, x1, y0, y1 = self.canvas.box(tail, head, r, ctrl)
                total = 0.0  # the sum of its weights over the picture's pixels, as footprint.deposit_light's
                for px in range(x0, x1 + 1):
                    for py in range(y0, y1 + 1):
                        total += fp.weight(ti.Vector([px + 0.5, py + 0.5]), tail, ctrl, head, r, blurred)
                if total > 0.0:
                    col = look.color(i)
                    top = ti.max(ti.max(col[0], col[1]), ti.max(col[2], 1e-12))
                    intensity = look.opacity(i) * math.pi * r_true * r_true / total * top
                    rgb = ti.cast(ti.math.clamp(col / top, 0.0, 1.0) * 255.0 + 0.5, ti.u32)
                    k = ti.atomic_add(self.count[None], 1)  # in any order: light adds up alike
                    for c, point in ti.static(enumerate((head, tail, ctrl))):
                        records[k, 2 * c] = ti.bit_cast(ti.cast(point[0], ti.f32), ti.u32)
                        records[k, 2 * c + 1] = ti.bit_cast(ti.cast(self.height - point[1], ti.f32), ti.u32)
                    records[k, 6] = ti.cast(ti.min(r * FIXED + 0.5, 65535.0), ti.u32) | (ti.cast(blurred, ti.u32) << 16)
                    records[k, 7] = ti.bit_cast(ti.cast(intensity, ti.f32), ti.u32)
                    records[k, 8] = rgb[0] | (rgb[1] << 8) | (rgb[2] << 16)
        return self.count[None]


def decode_light(data: bytes) -> dict:
    """A light frame read back (for tests and tools; the page reads the same layout): exposure, curved, and per
    glowing particle head, tail, ctrl ((m, 2) pixels, rows from the top), r (pixels), blurred, intensity, rgb."""
    _, m, exposure, flags = LIGHT_HEADER.unpack_from(data)
    records = np.frombuffer(data, np.uint32, count=RECORD_WORDS * m, offset=LIGHT_HEADER.size).reshape(m, RECORD_WORDS)
    points = records[:, :6].copy().view(np.float32)

    def place(c):
        return points[:, 2 * c : 2 * c + 2]

    return {
        "exposure": exposure,
        "curved": bool(flags & CURVED),
        "head": place(0),
        "tail": place(1),
        "ctrl": place(2),
        "r": (records[:, 6] & 0xFFFF) / FIXED,
        "blurred": (records[:, 6] >> 16).astype(bool),
        "intensity": records[:, 7].copy().view(np.float32),
        "rgb": records[:, 8].astype("<u4").view(np.uint8).reshape(-1, 4)[:, :3],
    }
