"""Where things go in a picture, and which part of the world it shows.

A picture is a band along the top (the title and clock on the left, the legend on the right, the charts between
them) above the scene. The scene's content (its bodies, heat sources and emitters, or the box `render.view`
names) is framed into the part below the band, so nothing written in the band covers it. Rows are counted from the
top; world boxes are (lo, hi) in length units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .text import line_height, text_size

CONTENT_MARGIN = 0.12  # of the content's larger side, added on every side of the framed box


@dataclass(frozen=True)
class Layout:
    """The regions of a `width` x `height` picture whose left `panel_px` columns are under a side panel (the
    window's): a band of `band` rows along the top for text and charts, and the scene below it."""

    width: int
    height: int
    panel_px: int
    band: int
    size: int  # font size, pixels

    @property
    def margin(self) -> int:
        """Pixels between the band's items and the picture's edges."""
        return self.size // 2 + 4

    def scene_rect(self) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1): the pixels the scene's content is framed into."""
        return self.panel_px, self.width, self.band, self.height

    def text_origin(self) -> tuple[int, int]:
        """(x, row) of the title's top-left corner; the clock's line is under it."""
        return self.panel_px + self.margin, self.margin

    def chart_rect(self, left: int, right: int) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1) the charts share: the band between pixel columns left and right (the title's and the
        legend's ends), below its top margin, with room for the time axis's labels under the boxes."""
        return left + self.margin, right - self.margin, self.margin, self.band - self.margin // 2


def side_by_side(rect: tuple[int, int, int, int], count: int, gap: int) -> list[tuple[int, int, int, int]]:
    """`count` rectangles of equal width, `gap` pixels apart, sharing rect (x0, x1, row0, row1) from left to right."""
    x0, x1, r0, r1 = rect
    w = (x1 - x0 - gap * (count - 1)) // max(count, 1)
    return [(x0 + k * (w + gap), x0 + k * (w + gap) + w, r0, r1) for k in range(count)]


def title_size(size: int) -> int:
    """The title's font size for text of font size `size` (a fifth larger)."""
    return round(size * 1.2)


def make_layout(
    width: int, height: int, panel_px: int, text_lines: int, legend: int, charts: bool, text_scale: float = 1.0
) -> Layout:
    """The layout of a picture that shows `text_lines` lines on the left (title, clock), a legend `legend` rows
    tall and charts, as asked, with text `text_scale` times the default size; with none of them the band is empty
    and the scene has the whole picture."""
    size = max(11, round(text_size(height) * text_scale))
    rows = max(text_lines * line_height(title_size(size)), legend)
    if charts:
        rows = max(rows, 6 * line_height(size), round(0.26 * height))
    margin = size // 2 + 4
    band = 0 if rows == 0 else min(rows + 2 * margin, height // 2)
    return Layout(width, height, panel_px, band, size)


def content_box(scene) -> tuple[np.ndarray, np.ndarray]:
    """The 2D world box (lo, hi) the camera frames by default: the scene's bodies, visible heat sources and emitters
    (with the path an emitted particle travels in its lifetime), grown by CONTENT_MARGIN and kept inside the
    domain; the domain where the scene has none of them or asks for it (render.frame = "domain"); render.view where
    the scene names a box."""
    lo, hi = np.asarray(scene.world.lo, float), np.asarray(scene.world.hi, float)
    cfg = scene.render
    if cfg.view:
        return np.asarray(cfg.view[:2], float), np.asarray(cfg.view[2:], float)
    boxes = [_body_box(b) for b in scene.bodies] + [_emitter_box(e) for e in scene.emitters]
    if scene.heat is not None:
        boxes += [(np.asarray(s.lo, float), np.asarray(s.hi, float)) for s in scene.heat.sources if s.visible]
    boxes = [b for b in boxes if b is not None]
    if cfg.frame == "domain" or not boxes:
        return lo, hi
    box_lo = np.min([b[0] for b in boxes], axis=0)
    box_hi = np.max([b[1] for b in boxes], axis=0)
    pad = max(CONTENT_MARGIN * float(np.max(box_hi - box_lo)), 2.0)
    return np.maximum(box_lo - pad, lo), np.minimum(box_hi + pad, hi)


def _body_box(body):
    if body.shape in ("disk", "sphere"):
        c = np.asarray(body.center, float)
        return c - body.radius, c + body.radius
    return np.asarray(body.lo, float), np.asarray(body.hi, float)


def _emitter_box(emitter):
    if emitter.shape == "box" or (emitter.lo and emitter.hi):
        lo, hi = np.asarray(emitter.lo, float), np.asarray(emitter.hi, float)
    elif emitter.center:
        c = np.asarray(emitter.center, float)
        lo, hi = c - emitter.size, c + emitter.size
    else:
        return None
    if emitter.velocity and emitter.lifetime > 0:  # where its particles go before they die (ballistic, no forces)
        travel = np.asarray(emitter.velocity, float) * emitter.lifetime
        lo, hi = np.minimum(lo, lo + travel), np.maximum(hi, hi + travel)
    return lo, hi


def fit(box, rect: tuple[int, int, int, int], height: int, domain=None) -> tuple[float, np.ndarray]:
    """(pixels per length, offset): the map pixel = offset + scale * world (pixels y up from the picture's bottom)
    that shows the world box (lo, hi) as large as fits in rect (x0, x1, row0, row1; rows from the top), centred in
    it, then slid, along each axis where the rect shows less than the whole `domain` (lo, hi), so that it shows no
    space outside the domain (a block on the floor sits at the rect's bottom edge)."""
    lo, hi = (np.asarray(b, float) for b in box)
    extent = np.maximum(hi - lo, 1e-9)
    x0, x1, r0, r1 = rect
    scale = min((x1 - x0) / extent[0], (r1 - r0) / extent[1]) * 0.98
    px_lo, px_hi = np.array([x0, height - r1], float), np.array([x1, height - r0], float)
    offset = (px_lo + px_hi) / 2 - scale * (lo + hi) / 2
    if domain is not None:
        d_lo, d_hi = (np.asarray(b, float) for b in domain)
        seen_lo, seen_hi = (px_lo - offset) / scale, (px_hi - offset) / scale  # the world the rect shows
        for k in range(2):
            if seen_hi[k] - seen_lo[k] <= d_hi[k] - d_lo[k]:
                shift = max(d_lo[k] - seen_lo[k], 0.0) - max(seen_hi[k] - d_hi[k], 0.0)
                offset[k] -= scale * shift
    return float(scale), offset
