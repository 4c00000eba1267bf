"""A 2D picture as data for a page to draw: the particles' places, sizes and colours (a "particle frame", a few kB)
and, apart, what does not move with them (the backdrop, the charts' band). The browser classroom sends these
instead of a JPEG a picture (app/serve_session.py), so the server does not draw or encode every picture.

The colours are the renderer's own (Look: the colour bar's map, the materials' and phases' colours), the places are
the renderer's view (plan.py), so the page's picture is the window's and the videos': the same colour maps, legend
and charts; the page draws each particle as the renderer's disc (coverage 1 within r, falling to 0 half a pixel
beyond: footprint.py) in painter's order, where the renderer averages overlapping opaque discs by coverage.

A particle frame, little-endian:

    b"P", then frame (u32), seq (u32: the last setting applied), time (f64: simulated seconds), n (u32),
    then n records of three u32: x | y << 16 (pixels x 16, rows from the top), r | kind << 16 (the drawn radius in
    pixels x 16; kind 0 opaque, 1 translucent, 2 light: drawn from the light frame sent before, light_frame.py), and
    R | G << 8 | B << 16 | A << 24 (A: the drawn opacity, 0 to 255),
    then, where the scene draws its springs as lines: m (u32), the lines' R | G << 8 | B << 16 | A << 24 (A: their
    opacity), and m pairs of u32: the particles (records) each live spring joins. The page draws them first, a line
    a pixel wide each, "over" one another as the renderer composites them, then the particles.

Where particles glow (additive light), a light frame (light_frame.py) goes before each particle frame and the page
adds their light as the renderer does. Scenes this cannot show as the renderer does (3D, motion blur of particles
that do not glow, a moving lid) have `unsupported(...)` say why; the classroom sends them as pictures.
"""

import struct

import numpy as np
import taichi as ti

from ..core.oriented import data_oriented
from .light_frame import LightFrame, glows
from .style import BLEND, MIN_FADE, R_MIN, SPRING_COLOR, SPRING_OPACITY

HEADER = struct.Struct("<cIIdI")  # b"P", frame, seq, time, n
PAGE_FRAMES = (b"P", b"S")  # the frames a page draws itself, each starting with HEADER: particle and sphere frames
FIXED = 16.0  # sub-pixel steps per pixel in a frame's places and radii
SPRING_RGBA = bytes(round(255 * v) for v in (*SPRING_COLOR, SPRING_OPACITY))  # the springs' lines, as a frame says


def unsupported(renderer) -> str | None:
    """Why `renderer`'s pictures cannot be sent as particle frames (None where they can)."""
    cfg = renderer.cfg
    if renderer.dim != 2:
        return "a 3D scene (shaded spheres)"
    if cfg.motion_blur and renderer.look.blends != {"additive"}:
        return "motion blur of particles that do not glow"
    if renderer.painter.backdrop_moves:
        return "a moving lid"
    return None


class FramePacker:
    """What the frames a page draws share (ParticleFrame here, sphere_frame.SphereFrame): the renderer and its
    particles, three u32 words a particle that the subclass's `_pack(first, n, records)` kernel writes (particles
    first .. first + n - 1), and HEADER with the subclass's `kind` byte first."""

    kind = b"?"

    def __init__(self, renderer, why: str | None, expected: str):
        """`why`: the module's unsupported(renderer) (ValueError naming it and what was `expected` where not None)."""
        if why is not None:
            raise ValueError(f"page frames: this scene's picture has {why}; expected {expected}")
        self.renderer = renderer
        self.look, self.p = renderer.look, renderer.state.particles
        self.world: int | None = None  # the world whose particles are packed (core/worlds.py), None: every live one
        self.batch: np.ndarray | None = None  # every world's records packed at once (pack_every_world), until cleared
        # on the CPU the kernel writes straight into this host array (no copy; elsewhere Taichi copies it back)
        self.records = np.zeros((max(renderer.model.capacity, 1), 3), np.uint32)

    def rows(self) -> tuple[int, int]:
        """(first slot, count) of the particles packed: every live one, or the block of world `self.world`."""
        if self.world is None:
            return 0, min(int(self.p.n[None]), len(self.records))
        return self.p.block(self.world)

    def pack(self) -> np.ndarray:
        """The live particles' records now (those of `self.world` alone where it is set), (n, 3) uint32 (the
        subclass module's layout): a view of this packer's array, valid until the next pack."""
        first, n = self.rows()
        if self.batch is not None and self.world is not None:
            return self.batch[first : first + n]
        self.renderer.state.refresh_derived()  # the atoms' phases, when drawn by phase
        self._pack(first, n, self.records)  # even for none: compiled where a session warms up (Session.warm_up)
        return self.records[:n]

    def pack_every_world(self) -> None:
        """Pack every live particle in one launch and keep the records (`batch`): each world's pack() is its slice
        of them until `batch` is cleared (a classroom world host's frame: one launch instead of one a tab)."""
        self.world, self.batch = None, None
        self.batch = self.pack()

    def header(self, frame: int, seq: int, time: float, n: int) -> bytes:
        """HEADER of a frame of n particles: the `frame` count, the last setting's `seq`, the simulated `time`."""
        return HEADER.pack(self.kind, frame & 0xFFFFFFFF, seq & 0xFFFFFFFF, float(time), n)


@data_oriented
class ParticleFrame(FramePacker):
    """Packs the particles of a 2D `renderer`'s state into particle frames (module docstring)."""

    kind = b"P"

    def __init__(self, renderer):
        super().__init__(renderer, unsupported(renderer), "a 2D scene drawn as discs")
        painter = renderer.painter
        self.scale = float(painter.px_per_unit)
        self.offset = painter.offset  # pixels (y up) of the world's origin
        self.height = renderer.height
        self.springs = renderer.state.springs if painter.draw_springs else None
        if self.springs is not None:
            self.pairs = np.zeros((max(self.springs.count, 1), 2), np.uint32)  # the live springs' ends
            self.n_pairs = ti.field(ti.i32, shape=())
        self.light = LightFrame(renderer) if glows(renderer) else None  # the glowing particles' light, sent before

    @ti.kernel
    def _pack(self, first: ti.i32, n: ti.i32, records: ti.types.ndarray()):
        look, p = self.look, self.p
        for row in range(n):
            i = first + row
            head = ti.cast(p.x[i], ti.f32) * self.scale + self.offset
            r_true = look.drawn_radius(i) * self.scale
            if look.g_draw[p.group[i]] == 0:  # a dot: one pixel
                r_true = 0.5
            r = ti.max(r_true, R_MIN)
            alpha = ti.max((r_true / r) ** 2, MIN_FADE)  # a particle smaller than R_MIN is drawn fainter
            kind = 0
            if look.g_blend[p.group[i]] == BLEND["alpha"]:
                alpha = ti.min(alpha * look.opacity(i), 0.999)
                kind = 1
            elif look.g_blend[p.group[i]] == BLEND["additive"]:
                kind = 2  # light: drawn from the light frame (light_frame.py), not as a disc
            c = ti.math.clamp(look.color(i), 0.0, 1.0)
            col = ti.cast(c * 255.0 + 0.5, ti.u32)
            a = ti.cast(ti.math.clamp(alpha, 0.0, 1.0) * 255.0 + 0.5, ti.u32)
            x = ti.cast(ti.math.clamp(head[0] * FIXED + 0.5, 0.0, 65535.0), ti.u32)
            y = ti.cast(ti.math.clamp((self.height - head[1]) * FIXED + 0.5, 0.0, 65535.0), ti.u32)
            records[row, 0] = x | (y << 16)
            records[row, 1] = ti.cast(ti.min(r * FIXED + 0.5, 65535.0), ti.u32) | (ti.cast(kind, ti.u32) << 16)
            records[row, 2] = col[0] | (col[1] << 8) | (col[2] << 16) | (a << 24)

    def backdrop(self) -> np.ndarray:
        """The picture without its particles or text, (H, W, 3) uint8 (backdrop_picture)."""
        return backdrop_picture(self.renderer)

    def encode(self, frame: int, seq: int, time: float) -> bytes:
        """The particle frame of the state now (the module docstring's layout)."""
        records = self.pack()
        lines = b""
        if self.springs is not None:
            m = self._pack_springs(*self.rows(), self.pairs)
            lines = struct.pack("<I", m) + SPRING_RGBA + self.pairs[:m].tobytes()
        return self.header(frame, seq, time, len(records)) + records.tobytes() + lines

    @ti.kernel
    def _pack_springs(self, first: ti.i32, n: ti.i32, pairs: ti.types.ndarray()) -> ti.i32:
        """The ends of the live springs of particles first .. first + n - 1 into `pairs`, as records (from first);
        returns how many."""
        s = self.springs
        self.n_pairs[None] = 0
        for k in range(s.span[None]):
            if s.alive[k] and first <= s.i[k] < first + n:
                slot = ti.atomic_add(self.n_pairs[None], 1)  # in any order: lines of one colour composite alike
                pairs[slot, 0] = ti.cast(s.i[k] - first, ti.u32)
                pairs[slot, 1] = ti.cast(s.j[k] - first, ti.u32)
        return self.n_pairs[None]


def unpack(records: np.ndarray) -> dict:
    """Records ((n, 3) uint32) read back: per particle x, y (pixels, rows from the top), r (pixels), kind, rgba
    (uint8, (n, 4))."""
    return {
        "x": (records[:, 0] & 0xFFFF) / FIXED,
        "y": (records[:, 0] >> 16) / FIXED,
        "r": (records[:, 1] & 0xFFFF) / FIXED,
        "kind": records[:, 1] >> 16,
        "rgba": records[:, 2].astype("<u4").view(np.uint8).reshape(-1, 4),  # a contiguous little-endian copy
    }


def frame_records(data: bytes) -> np.ndarray:
    """The records ((n, 3) uint32) of a particle frame (the module docstring's layout), without a copy."""
    n = HEADER.unpack_from(data)[4]
    return np.frombuffer(data, np.uint32, count=3 * n, offset=HEADER.size).reshape(n, 3)


def decode(data: bytes) -> dict:
    """A particle frame read back: frame, seq, time and unpack()'s fields. For tests and tools; the page reads the
    same layout."""
    _, frame, seq, time, n = HEADER.unpack_from(data)
    records = frame_records(data)
    out = {"frame": frame, "seq": seq, "time": time, "n": n, **unpack(records)}
    end = HEADER.size + 12 * n
    if len(data) > end:  # the springs' lines
        (m,) = struct.unpack_from("<I", data, end)
        out["line_rgba"] = np.frombuffer(data, np.uint8, count=4, offset=end + 4)
        out["springs"] = np.frombuffer(data, "<u4", count=2 * m, offset=end + 8).reshape(m, 2)
    return out


def backdrop_picture(renderer) -> np.ndarray:
    """The 2D picture without its particles or its text, (H, W, 3) uint8, top row first: the domain, walls and heat
    sources (the charts are drawn on a copy: Renderer.draw_text_overlays)."""
    layer = renderer.painter.backdrop.to_numpy()  # (W, H, 3), y up
    return np.ascontiguousarray((np.clip(layer, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8).transpose(1, 0, 2)[::-1])


def band_rect(renderer) -> tuple[int, int, int, int] | None:
    """(x0, x1, row0, row1) of the rectangle that holds the picture's charts and text (None where it has none): what
    changes in the backdrop from one moment to the next."""
    rects = [plot.drawn_rect() for plot in renderer.plots() if plot.fits] + list(renderer.overlays.rects())
    if not rects:
        return None
    x0, x1 = min(r[0] for r in rects), max(r[1] for r in rects)
    r0, r1 = min(r[2] for r in rects), max(r[3] for r in rects)
    return max(x0, 0), min(x1, renderer.width - 1), max(r0, 0), min(r1, renderer.height - 1)


def small_picture(under: np.ndarray, records: np.ndarray, width: int, height: int) -> np.ndarray:
    """A `width` x `height` picture (uint8, top row first) of a particle frame's `records` ((n, 3) uint32, the
    module docstring's layout) over `under`, the full-size picture without its particles: the teacher's thumbnails,
    without the renderer drawing a whole picture for each (discs at least a pixel across, in painter's order)."""
    from PIL import Image, ImageDraw

    full_h, full_w = under.shape[:2]
    picture = Image.fromarray(under).resize((width, height), Image.Resampling.BILINEAR)
    if len(records):
        sx, sy = width / full_w, height / full_h
        fields = unpack(records)
        x, y, r = fields["x"] * sx, fields["y"] * sy, np.maximum(fields["r"] * sx, 0.5)
        colours = fields["rgba"][:, :3]
        pen = ImageDraw.Draw(picture)
        for xi, yi, ri, c in zip(x.tolist(), y.tolist(), r.tolist(), colours.tolist()):
            pen.ellipse((xi - ri, yi - ri, xi + ri, yi + ri), fill=tuple(c))
    return np.asarray(picture)
