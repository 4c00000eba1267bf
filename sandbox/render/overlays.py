"""What is drawn on the host onto the 8-bit picture: the colour bar with its range, and the simulated time."""

import numpy as np

from .colormaps import SPEED_STOPS, TEMPERATURE_STOPS, ramp_np_many
from .pixels import draw_text, text_scale, text_width


class Overlays:
    """The legend (colour bar) and clock of a `width` x `height` picture with the [render] settings `cfg`; the clock
    reads `state`'s time."""

    def __init__(self, cfg, width: int, height: int, state):
        self.cfg, self.width, self.height, self.state = cfg, width, height, state

    def legend_colors(self, n: int) -> np.ndarray:
        """The active colour map sampled at n points, (n, 3) floats."""
        return ramp_np_many(SPEED_STOPS if self.cfg.color_by == "speed" else TEMPERATURE_STOPS, np.linspace(0, 1, n))

    def legend_geometry(self) -> tuple[int, int, int, int, int]:
        """(x0, row0, bar width, bar height, text scale) of the colour bar, rows counted from the top."""
        h, w = self.height, self.width
        bar_w, bar_h, scale = max(60, w // 6), max(6, h // 60), text_scale(h)
        return w - bar_w - 12, h - bar_h - 5 * scale - 12, bar_w, bar_h, scale  # its labels fit below it

    def legend_rect(self) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1): the pixels the legend (bar, frame and labels) may draw on."""
        x0, y0, bar_w, bar_h, scale = self.legend_geometry()
        return x0 - 64 * scale, x0 + bar_w + 1, y0 - 1, y0 + bar_h + 4 + 5 * scale

    def legend_shown(self) -> bool:
        """Whether the colour bar is drawn: asked for, colouring by a scale, and room for it in the picture."""
        x0, x1, row0, row1 = self.legend_rect()
        fits = x0 >= 0 and row0 >= 0 and x1 <= self.width and row1 <= self.height
        return self.cfg.legend and self.cfg.color_by in ("temperature", "speed") and fits

    def rects(self) -> list:
        """(x0, x1, row0, row1) of each overlay shown: pixels, rows counted from the top."""
        return ([self.legend_rect()] if self.legend_shown() else []) + ([self.clock_rect()] if self.cfg.clock else [])

    def draw(self, img: np.ndarray) -> None:
        """The legend and the clock, as the settings ask, onto an (H, W, 3) uint8 frame (or a view of one)."""
        if self.cfg.legend:
            self.draw_legend(img)
        if self.cfg.clock:
            self.draw_clock(img)

    def draw_legend(self, img: np.ndarray) -> None:
        """A colour bar with its range labelled, in the bottom-right corner of an (H, W, 3) uint8 frame."""
        if not self.legend_shown():
            return
        x0, y0, bar_w, bar_h, scale = self.legend_geometry()
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
        x0, _, row0, _ = self.clock_rect()
        draw_text(img, f"t = {self.state.time:.2f} s", x0, row0, text_scale(self.height))

    def clock_rect(self) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1): the pixels the clock may draw on (room for "t = 100000.00 s")."""
        scale = text_scale(self.height)
        return 10, min(self.width, 10 + text_width("t = 100000.00 s", scale)), self.height - 10 - 5 * scale, self.height
