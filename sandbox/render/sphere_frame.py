"""A 3D picture as data for a page to draw with WebGL (a "sphere frame"): the camera, and each particle's place,
drawn radius and colour. The browser classroom sends these instead of a JPEG a picture (app/serve_session.py), so a
3D tab costs the server no drawing or encoding either; what does not move with the particles (the background, the
floor and its heat sources, the charts) goes apart as the picture without its particles (`backdrop_picture`), again
whenever the camera moves.

The page draws each particle as the renderer does (render/spheres.py): projected through the same pinhole camera, a
disc of max(radius x focal / depth, R_MIN) pixels covering the pixels whose centres lie on it, the sphere's front
surface depth-tested per pixel, shaded (diffuse, ambient 0.3, a specular highlight) where its group is drawn shaded,
flat otherwise; colours are the renderer's (Look), written to 8 bits as the renderer writes them.

A sphere frame, little-endian:

    b"S", then frame (u32), seq (u32: the last setting applied), time (f64: simulated seconds), n (u32),
    then the camera: 36 f32: eye, right, up, forward (3 each, world units), focal length (pixels), the view's axis
    on the picture cx, cy (pixels, y up), the light's direction (3), specular strength, R_MIN (pixels), then the
    lid (the molecular model's, physics/lid.py): 1 where there is one (else 0), its height, the box's x and z
    bounds (x0, z0, x1, z1) and its outline's colour (3), then the span the places are given in: its low corner
    (3) and its size (3), and the largest radius R (world units),
    then n records of three u32: x | y << 16, z | r << 16 (places as fractions of the span, the radius as a
    fraction of R, in 65,535ths: a 65,535th of a 40-unit box is 0.0006 units, a hundredth of a pixel at the
    usual distance), and R | G << 8 | B << 16 | S << 24 (S: 255 shaded, 0 drawn flat). 12 bytes a particle.

The lid is drawn by the page too (it moves): the backdrop comes without it, and the page tints the box's
cross-section at the lid's height and draws its outline, which hides the spheres behind it, as the renderer does.
Scenes this cannot show as the renderer does (motion blur, translucent or additive particles) have
`unsupported(...)` say why; the classroom sends them as pictures.
"""

import struct

import numpy as np
import taichi as ti

from ..core.oriented import data_oriented
from .particle_frame import HEADER, FramePacker  # HEADER: b"S", frame, seq, time, n
from .style import LID_COLOR, R_MIN

CAMERA = struct.Struct("<36f")  # eye, right, up, forward, focal, cx, cy, light, specular, R_MIN, lid (9), span (7)
WORDS = 3  # u32 words a particle: x | y << 16, z | r << 16, RGB and shading
STEPS = 65535.0  # a place's and a radius's steps across the span and up to the largest radius
MARGIN = 0.05  # the span: the box widened by this fraction of its size each way (a particle pressed past a wall)


def unsupported(renderer) -> str | None:
    """Why `renderer`'s pictures cannot be sent as sphere frames (None where they can)."""
    if renderer.dim != 3:
        return "a 2D scene (discs: particle frames)"
    if renderer.cfg.motion_blur:
        return "motion blur"
    blends = renderer.look.blends - {"opaque"}
    if blends:
        return f"{' and '.join(sorted(blends))} particles"
    return None


@data_oriented
class SphereFrame(FramePacker):
    """Packs the particles of a 3D `renderer`'s state into sphere frames (module docstring)."""

    kind = b"S"

    def __init__(self, renderer):
        super().__init__(renderer, unsupported(renderer), "a 3D scene of opaque spheres")
        self.painter = renderer.painter
        world = renderer.model.scene.world
        lo, hi = np.asarray(world.lo, float), np.asarray(world.hi, float)
        self.span_lo, self.span = lo - MARGIN * (hi - lo), (1 + 2 * MARGIN) * (hi - lo)
        self.r_max = float(self.span.max())  # no drawn sphere is wider than its box
        self._span_lo, self._inv_span = ti.Vector(list(self.span_lo)), ti.Vector(list(STEPS / self.span))

    @ti.kernel
    def _pack(self, first: ti.i32, n: ti.i32, records: ti.types.ndarray()):
        look, p = self.look, self.p
        for row in range(n):
            i = first + row
            q = ti.cast(ti.math.clamp((p.x[i] - self._span_lo) * self._inv_span + 0.5, 0.0, STEPS), ti.u32)
            r = ti.cast(ti.math.clamp(look.drawn_radius(i) * (STEPS / self.r_max) + 0.5, 0.0, STEPS), ti.u32)
            shaded = ti.cast(look.g_draw[p.group[i]] == 2, ti.u32) * 255  # render/spheres.py shades draw mode 2 only
            c = ti.cast(ti.math.clamp(look.color(i), 0.0, 1.0) * 255.0 + 0.5, ti.u32)
            records[row, 0] = q[0] | (q[1] << 16)
            records[row, 1] = q[2] | (r << 16)
            records[row, 2] = c[0] | (c[1] << 8) | (c[2] << 16) | (shaded << 24)

    def camera(self) -> bytes:
        """The camera block of a frame (module docstring)."""
        painter = self.painter
        eye, right, up, forward = painter.camera.to_numpy()
        focal = float(painter.focal_field[None])
        values = [*eye, *right, *up, *forward, focal, painter.cx, painter.cy, *painter.light_np]
        lid = [0.0] * 9
        if painter.has_lid:
            lid = [1.0, painter.lid.height_of(self.world or 0), *painter.floor_box, *LID_COLOR]
        return CAMERA.pack(*values, painter.specular, R_MIN, *lid, *self.span_lo, *self.span, self.r_max)

    def backdrop(self) -> np.ndarray:
        """The picture without its particles or text as the camera sees it now, (H, W, 3) uint8 (backdrop_picture)."""
        return backdrop_picture(self.renderer)

    def encode(self, frame: int, seq: int, time: float) -> bytes:
        """The sphere frame of the state now (the module docstring's layout)."""
        records = self.pack()
        return self.header(frame, seq, time, len(records)) + self.camera() + records.tobytes()


def decode(data: bytes) -> dict:
    """A sphere frame read back: frame, seq, time, the camera's numbers and per particle x ((n, 3) world units), r
    (world units; negative: drawn flat) and rgb ((n, 3) uint8). For tests and tools; the page reads the same
    layout."""
    _, frame, seq, time, n = HEADER.unpack_from(data)
    camera = CAMERA.unpack_from(data, HEADER.size)
    records = np.frombuffer(data, "<u4", count=WORDS * n, offset=HEADER.size + CAMERA.size).reshape(n, WORDS)
    lo, span, r_max = np.array(camera[29:32]), np.array(camera[32:35]), camera[35]
    q = np.stack([records[:, 0] & 0xFFFF, records[:, 0] >> 16, records[:, 1] & 0xFFFF], axis=1)
    colour = records[:, 2].astype("<u4").view(np.uint8).reshape(-1, 4)
    radius = (records[:, 1] >> 16) / STEPS * r_max
    return {
        "frame": frame,
        "seq": seq,
        "time": time,
        "camera": camera,
        "x": lo + q / STEPS * span,
        "r": np.where(colour[:, 3] > 0, radius, -radius),
        "rgb": colour[:, :3],
    }


def backdrop_picture(renderer) -> np.ndarray:
    """The 3D picture without its particles, its lid or its text, (H, W, 3) uint8, top row first: the background and
    the floor with its heat sources, as the camera sees them now (the charts are drawn on a copy)."""
    renderer.painter.paint_backdrop(lid=False)
    return renderer.canvas.picture().copy()
