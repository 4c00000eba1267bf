"""What a classroom session sends a page that draws the particles itself (serve_session.py): per picture a frame of
the particles (2D: render/particle_frame.py, after b"L" + its light where particles glow, render/light_frame.py; 3D
spheres on a page with WebGL2: render/sphere_frame.py), and apart
what does not move with them: b"B" + a PNG of the picture without its particles when a scene opens (in 3D again
after the camera turns, at most every BACKDROP_SECONDS), b"C" + the charts' band (x0, row0: two u16, then a PNG)
every BAND_SECONDS or when its words change.

Each message goes down `conn` (a multiprocessing pipe) as bytes, its kind in its first byte; the server passes
them to the page as they are.
"""

from __future__ import annotations

import io
import struct

import numpy as np

BAND_SECONDS = 1.0  # seconds between the charts' bands sent to a page that draws the particles
BACKDROP_SECONDS = 0.1  # seconds at least between the 3D backdrops sent while the camera moves


def page_packer(renderer, webgl: bool):
    """What packs `renderer`'s particles for the page to draw: a ParticleFrame (2D discs; where particles glow, with
    their light, which the page adds with WebGL2), a SphereFrame (3D opaque spheres, where the page has WebGL2), or
    None where the page cannot draw them as the renderer does (the session sends pictures)."""
    from ..render import light_frame, particle_frame, sphere_frame

    if renderer.dim == 2:
        if particle_frame.unsupported(renderer) is not None or (light_frame.glows(renderer) and not webgl):
            return None
        return particle_frame.ParticleFrame(renderer)
    if webgl and sphere_frame.unsupported(renderer) is None:
        return sphere_frame.SphereFrame(renderer)
    return None


class PageDrawing:
    """The frames, backdrops and bands of one scene's pictures for a page that draws them (module docstring)."""

    def __init__(self, conn, renderer, packer) -> None:
        """`packer`: page_packer()'s for `renderer` (not None)."""
        self.conn, self.renderer, self.packer = conn, renderer, packer
        self.light = getattr(packer, "light", None)  # a 2D scene's glowing particles' light (light_frame.py)
        self.base: np.ndarray | None = None  # the picture without particles or charts, (H, W, 3) uint8
        self.under: np.ndarray | None = None  # and with the charts: what the page has under its particles
        self.band_due = True  # the charts' band goes with the next picture
        self.backdrop_due = False  # the 3D camera moved: the picture without particles goes with the next one
        self.last_band = self.last_backdrop = -1e9  # when they were last sent (wall seconds)

    def send_backdrop(self, now: float) -> None:
        """The picture without its particles, with the charts (b"B" + PNG), as the camera sees it at wall time
        `now` (seconds)."""
        self.base = self.packer.backdrop()
        self.conn.send_bytes(b"B" + png(self.draw_under()))
        self.backdrop_due, self.last_backdrop = False, now

    def camera_moved(self) -> None:
        """A 3D camera turned: the floor is seen from elsewhere, so the backdrop goes again with a coming frame."""
        self.backdrop_due = self.renderer.dim == 3

    def send(self, now: float, frame: int, seq: int, time: float) -> bytes:
        """The frame of the particles now (it carries the `frame` count, the last setting's `seq` and the simulated
        `time`), after the backdrop or the charts' band where one is due at wall time `now` (seconds); returns the
        frame sent (a paused world's tab sends it again)."""
        if self.backdrop_due and now - self.last_backdrop >= BACKDROP_SECONDS:
            self.send_backdrop(now)  # with the charts drawn on it: the band is in it
        elif self.band_due or (now - self.last_band >= BAND_SECONDS and self.renderer.plots()):
            self.last_band = now
            self.send_band()
        if self.light is not None:  # the light of the frame that follows (the page adds it to that frame)
            self.conn.send_bytes(self.light.encode())
        encoded = self.packer.encode(frame, seq, time)
        self.conn.send_bytes(encoded)
        return encoded

    def draw_under(self) -> np.ndarray:
        """The picture under the particles now: the backdrop with the charts drawn on it, kept as `under` (the
        teacher's thumbnails start from it)."""
        self.under = self.base.copy()
        self.renderer.draw_text_overlays(self.under)
        return self.under

    def send_band(self) -> None:
        """The charts' band as the picture draws it (over the backdrop)."""
        from ..render.particle_frame import band_rect

        self.band_due = False
        rect = band_rect(self.renderer)
        if rect is None:
            return
        x0, x1, r0, r1 = rect
        crop = np.ascontiguousarray(self.draw_under()[r0 : r1 + 1, x0 : x1 + 1])
        self.conn.send_bytes(b"C" + struct.pack("<HH", x0, r0) + png(crop))

    def thumbnail(self, width: int, height: int) -> np.ndarray | None:
        """The teacher's small picture from the 2D particle frame over the picture under it (a few milliseconds;
        uint8, (height, width, 3)); None in 3D (the session makes the renderer's picture small)."""
        from ..render.particle_frame import small_picture

        if self.renderer.dim != 2:
            return None
        return small_picture(self.under, self.packer.pack(), width, height)


def picture_point(renderer, fx: float, fy: float):
    """The scene point under the picture fraction (fx, fy) of `renderer`'s picture, rows from the top: in 2D the
    view's point, in 3D the nearest particle drawn within a few pixels of it (None where there is none)."""
    if renderer.dim == 3:
        return renderer.pick(fx, 1.0 - fy)
    scale, offset = renderer.plan.view
    column, row_up = fx * renderer.width, (1.0 - fy) * renderer.height
    return ((column - offset[0]) / scale, (row_up - offset[1]) / scale)


def png(picture) -> bytes:
    """An (H, W, 3) uint8 picture as a PNG (exact colours and crisp text; fast rather than small)."""
    from PIL import Image

    out = io.BytesIO()
    Image.fromarray(picture).save(out, "PNG", compress_level=1)
    return out.getvalue()


def jpeg(picture, quality: int) -> bytes:
    """An (H, W, 3) uint8 picture as a JPEG of `quality` (1-95): the pictures of scenes the page cannot draw, and the
    teacher's thumbnails."""
    from PIL import Image

    out = io.BytesIO()
    Image.fromarray(picture).save(out, "JPEG", quality=quality)
    return out.getvalue()
