"""The renderer's output: tone mapping of additive light, packing the float image into the 8-bit picture, and the
colour-bar legend drawn on it on the host. A mixin of Renderer."""

import numpy as np
import taichi as ti

from .colormaps import GLOW_STOPS, SPEED_STOPS, ramp_np_many
from .pixels import draw_text, put_pixel, text_scale, text_width


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
        return ramp_np_many(SPEED_STOPS if self.cfg.color_by == "speed" else GLOW_STOPS, np.linspace(0, 1, n))

    def _legend_geometry(self) -> tuple[int, int, int, int, int]:
        """(x0, row0, bar width, bar height, text scale) of the colour bar, rows counted from the top."""
        h, w = self.height, self.width
        bar_w, bar_h, scale = max(60, w // 6), max(6, h // 60), text_scale(h)
        return w - bar_w - 12, h - bar_h - 5 * scale - 12, bar_w, bar_h, scale  # its labels fit below it

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
            (lo, hi), unit = (0.0, self.cfg.speed_range), "/s"
        else:
            (lo, hi), unit = self.cfg.temperature_range, " °C"
        draw_text(img, f"{lo:g}", x0, y0 + bar_h + 3, scale)
        label = f"{hi:g}{unit}"
        draw_text(img, label, x0 + bar_w - text_width(label, scale), y0 + bar_h + 3, scale)

    def draw_clock(self, img: np.ndarray) -> None:
        """The simulated time, "t = 2.40 s", in the bottom-left corner of an (H, W, 3) uint8 frame."""
        x0, _, row0, _ = self._clock_rect()
        draw_text(img, f"t = {self.state.time:.2f} s", x0, row0, text_scale(self.height))

    def _clock_rect(self) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1): the pixels the clock may draw on (room for "t = 100000.00 s")."""
        scale = text_scale(self.height)
        return 10, min(self.width, 10 + text_width("t = 100000.00 s", scale)), self.height - 10 - 5 * scale, self.height

    def label_window_output(self) -> None:
        """The window's picture (GGUI's packed RGBA on the CPU, the renderer's own NumPy buffer): draw the host-side
        text on it in place, as picture() does on its copy (draw_text_overlays)."""
        if self.output != "rgba" or not isinstance(self.out, np.ndarray):
            return
        rgba = self.out.view(np.uint8).reshape(self.width, self.height, 4)
        self.draw_text_overlays(rgba[:, ::-1, :3].transpose(1, 0, 2))  # (H, W, 3) top row first: a view of `out`

    def draw_text_overlays(self, img: np.ndarray) -> None:
        """What is drawn on the host onto an (H, W, 3) uint8 frame (or a view of one): the colour bar, the chart's
        and the pair-force panel's labels, and the clock."""
        if self.cfg.legend:
            self.draw_legend(img)
        if self.chart is not None:
            self.chart.label(img)
        if self.potential is not None:
            self.potential.label(img)
        if self.cfg.clock:
            self.draw_clock(img)
