"""The renderer's output: tone mapping of additive light, packing the float image into the 8-bit picture, and the
colour-bar legend drawn on it on the host. A mixin of Renderer."""

import numpy as np
import taichi as ti

from .colormaps import GLOW_STOPS, SPEED_STOPS, ramp_np
from .pixels import draw_text, put_pixel


class Output:
    """Renderer's tone mapping, packing and legend."""

    @ti.kernel
    def _tone_map(self):
        for x, y in self.image:
            self.image[x, y] = ti.min(self.image[x, y] + 1.0 - ti.exp(-self.exposure * self.light[x, y]), 1.0)

    @ti.kernel
    def _pack(self, out: ti.types.ndarray()):
        for x, y in self.image:
            self._put_out(out, x, y, self.image[x, y])

    @ti.func
    def _put_out(self, out: ti.template(), x, y, c):
        """Write colour c (floats in [0, 1]) at pixel (x, y) (y up) of the 8-bit output (see put_pixel)."""
        put_pixel(out, self.height, x, y, c)

    # ------------------------------------------------------------------ legend (host side, on the 8-bit frame)
    def legend_colors(self, n: int) -> np.ndarray:
        """The active colour map sampled at n points, (n, 3) floats."""
        ts = np.linspace(0, 1, n)
        if self.cfg.color_by == "speed":
            return np.array([ramp_np(SPEED_STOPS, t) for t in ts])
        return np.array([ramp_np(GLOW_STOPS, t) for t in ts])

    def _legend_geometry(self) -> tuple[int, int, int, int, int]:
        """(x0, row0, bar width, bar height, text scale) of the colour bar, rows counted from the top."""
        h, w = self.height, self.width
        bar_w, bar_h = max(60, w // 6), max(6, h // 60)
        return w - bar_w - 12, h - bar_h - 16, bar_w, bar_h, max(1, h // 240)

    def _legend_rect(self) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1): the pixels the legend (bar, frame and labels) may draw on."""
        x0, y0, bar_w, bar_h, scale = self._legend_geometry()
        return x0 - 64 * scale, x0 + bar_w + 1, y0 - 1, y0 + bar_h + 4 + 5 * scale

    def _legend_shown(self) -> bool:
        """Whether the colour bar is drawn: asked for, colouring by a scale, and room for it in the picture."""
        x0, x1, row0, row1 = self._legend_rect()
        fits = x0 >= 0 and row0 >= 0 and x1 <= self.width and row1 <= self.height
        return self.cfg.legend and self.cfg.color_by in ("temperature", "speed") and fits

    def draw_legend(self, img: np.ndarray) -> None:
        """A colour bar with its range labelled, in the bottom-right corner of an (H, W, 3) uint8 frame."""
        if not self._legend_shown():
            return
        x0, y0, bar_w, bar_h, scale = self._legend_geometry()
        colors = (self.legend_colors(bar_w) * 255).astype(np.uint8)
        img[y0 : y0 + bar_h, x0 : x0 + bar_w] = colors[None, :, :]
        img[y0 - 1, x0 - 1 : x0 + bar_w + 1] = 200
        img[y0 + bar_h, x0 - 1 : x0 + bar_w + 1] = 200
        if self.cfg.color_by == "speed":
            lo, hi = 0.0, self.cfg.speed_range
        else:
            lo, hi = self.cfg.temperature_range
        draw_text(img, f"{lo:g}", x0, y0 + bar_h + 3, scale)
        label = f"{hi:g}"
        draw_text(img, label, x0 + bar_w - 4 * scale * len(label), y0 + bar_h + 3, scale)
