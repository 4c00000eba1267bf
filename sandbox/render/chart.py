"""A strip chart of measurements over time, drawn into the renderer's image, so the window and videos both show it.

`render.chart = ["mean_temperature", "molten_fraction"]` plots those Stats fields against simulated time in a box in
the top-left corner, the whole run squeezed into the box's width. Series of one unit (the energies) share a scale, the
others each have their own range so far (fractions [0, 1]). Under the box each series' name, latest value and unit
in its colour and the time span; beside it, when the series share one scale, its top, middle and bottom values.
Tick marks divide the time axis into quarters and mark the middle of the scale.
"""

import numpy as np
import taichi as ti

from ..core import transfer
from ..core.oriented import data_oriented
from .pixels import draw_text, get_pixel, put_pixel, text_scale, text_width

FRACTIONS = ("molten_fraction",)  # plotted on a fixed [0, 1] scale
# Each series' label and unit; series of one unit share the chart's scale (the energies), which its ticks then give.
SERIES_LABELS = {
    "mean_temperature": ("mean T", "°C"),
    "molten_fraction": ("molten", ""),
    "heat_content": ("heat", "E"),
    "kinetic_energy": ("kinetic", "E"),
    "potential_energy": ("potential", "E"),
    "total_energy": ("total", "E"),
    "max_speed": ("max speed", "/s"),
}
COLORS = ((1.0, 0.4, 0.25), (0.35, 0.65, 1.0), (0.5, 0.9, 0.4), (0.95, 0.85, 0.3))
SAMPLES = 256  # points per series drawn (the history is resampled to this many)
HISTORY = 16 * SAMPLES  # samples kept; past it every other one is dropped and the sampling stride doubles
TICK = 3  # pixels a tick mark reaches into the box


@data_oriented
class Chart:
    """Strip chart of some Stats fields; record() each frame, the renderer calls draw()."""

    def __init__(
        self, image, width: int, height: int, series: tuple[str, ...], scene_in_image: bool = True, left: int = 0
    ):
        """`image`: the renderer's float image; `scene_in_image`: the drawn scene is there (else only in the 8-bit
        output draw() gets), which is what the box dims behind its lines; `left`: pixels a side panel covers."""
        self.scene_in_image = scene_in_image
        self.series = tuple(series)
        self.n_series = len(self.series)
        self.image = image
        self.width, self.height = width, height
        self.box_w, self.box_h = max(64, width // 4), max(40, height // 5)
        self.label_height = 4 + 5 * text_scale(height)  # the values printed under the box
        self.x0, self.y_top = left + 10, 10  # top-left corner of the box, pixels from the top-left of the picture
        # A picture too small to hold the box and its margins gets no chart (drawing it would write out of bounds).
        self.fits = width >= self.box_w + self.x0 + 10 and height >= self.box_h + 2 * self.y_top
        self.values = ti.field(ti.f32, shape=(len(self.series), SAMPLES))  # normalised to [0, 1]
        self.colors = ti.Vector.field(3, ti.f32, shape=len(self.series))
        transfer.upload([(self.colors, np.array([COLORS[k % len(COLORS)] for k in range(self.n_series)], np.float32))])
        self.history: list[list[float]] = [[] for _ in self.series]
        self.times: list[float] = []  # simulated time of each kept sample
        self.ranges: list[tuple[float, float]] = [(0.0, 1.0)] * len(self.series)  # each series' scale
        self.n = 0
        self.frames = 0  # frames offered to record()
        self.stride = 1  # one sample kept per this many frames

    def record(self, stats) -> None:
        """Append this frame's values and upload the resampled, normalised series."""
        self.frames += 1
        if (self.frames - 1) % self.stride:
            return  # between kept samples
        for k, name in enumerate(self.series):
            value = float(getattr(stats, name))
            self.history[k].append(value if np.isfinite(value) else 0.0)
        self.times.append(float(stats.time))
        if len(self.history[0]) > HISTORY:  # bounded work per frame on a long run: keep every other sample, and
            self.history = [h[::2] for h in self.history]  # from now on record every other frame, so the samples
            self.times = self.times[::2]
            self.stride *= 2  # stay evenly spread in time
        length = len(self.history[0])
        self.n = min(length, SAMPLES)
        pick = np.linspace(0, length - 1, self.n).round().astype(int)
        table = np.zeros((len(self.series), SAMPLES), dtype=np.float32)
        for k, name in enumerate(self.series):
            values = np.asarray(self.history[k])
            lo, hi = self.ranges[k] = self._range(name)
            span = hi - lo if hi > lo else 1.0
            table[k, : self.n] = np.clip((values[pick] - lo) / span, 0.0, 1.0)
        self.values.from_numpy(table)

    def _range(self, name: str) -> tuple[float, float]:
        """The scale of series `name`: [0, 1] for fractions, else the range so far of every series of its unit."""
        if name in FRACTIONS:
            return 0.0, 1.0
        unit = SERIES_LABELS.get(name, (name, name))[1]
        same = [np.asarray(h) for n, h in zip(self.series, self.history) if SERIES_LABELS.get(n, (n, n))[1] == unit]
        return float(min(v.min() for v in same)), float(max(v.max() for v in same))

    def drawn_rect(self) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1), rows from the top: the pixels the box and its labels may draw on. The labels under
        the box and the scale beside it run to the right, as long as their text is (it changes every frame)."""
        return self.x0, self.width, self.y_top, self.y_top + self.box_h + self.label_height

    def shared_scale(self) -> bool:
        """Whether every series is drawn on one scale (one unit, not a fraction), so ticks can give it."""
        units = {SERIES_LABELS.get(n, (n, n))[1] for n in self.series}
        return len(units) == 1 and not any(n in FRACTIONS for n in self.series)

    def draw(self, out) -> None:
        """Draw the box and the series into the renderer's float image and its 8-bit output `out` (put_pixel)."""
        if self.fits:
            self._draw(self.n, out)

    @ti.func
    def _put(self, out: ti.template(), x, y, c):
        """Set pixel (x, y) of the picture, y counted up from the bottom, in the float image and the 8-bit one."""
        self.image[x, y] = c
        put_pixel(out, self.height, x, y, c)

    @ti.kernel
    def _draw(self, n: ti.i32, out: ti.types.ndarray()):
        x0, w, h = self.x0, self.box_w, self.box_h
        y0 = self.height - self.y_top - h  # bottom row of the box
        for i, j in ti.ndrange(w, h):
            behind = ti.Vector([0.0, 0.0, 0.0])
            if ti.static(self.scene_in_image):
                behind = self.image[x0 + i, y0 + j]
            else:
                behind = get_pixel(out, self.height, x0 + i, y0 + j)
            c = behind * 0.3  # dim what is behind, so the lines read
            # the frame, with ticks pointing in: time at each quarter along the bottom, the scale's middle at the sides
            time_tick = j < TICK and (i == w // 4 or i == w // 2 or i == 3 * w // 4)
            value_tick = (i < TICK or i >= w - TICK) and j == h // 2
            if i == 0 or j == 0 or i == w - 1 or j == h - 1 or time_tick or value_tick:
                c = ti.Vector([0.6, 0.6, 0.6])
            self._put(out, x0 + i, y0 + j, c)
        for s, k in ti.ndrange(self.n_series, SAMPLES - 1):
            if k < n - 1:
                ax = x0 + 1 + (w - 3) * k / ti.max(n - 1, 1)
                bx = x0 + 1 + (w - 3) * (k + 1) / ti.max(n - 1, 1)
                ay = y0 + 1 + (h - 3) * self.values[s, k]
                by = y0 + 1 + (h - 3) * self.values[s, k + 1]
                steps = ti.cast(ti.max(ti.abs(bx - ax), ti.abs(by - ay)), ti.i32) + 1
                for t in range(steps + 1):
                    f = t / steps
                    px = ti.cast(ax + f * (bx - ax) + 0.5, ti.i32)
                    py = ti.cast(ay + f * (by - ay) + 0.5, ti.i32)
                    self._put(out, px, py, self.colors[s])

    def label(self, img: np.ndarray) -> None:
        """Under the box, each series' name, latest value and unit in its colour (with its own scale's bottom and top
        when the series do not share one), then the time span; beside the box the shared scale's top and bottom
        values; on an (H, W, 3) uint8 frame."""
        if not self.history[0] or not self.fits:
            return
        scale = text_scale(self.height)
        y = self.y_top + self.box_h + 3
        x = self.x0
        for k, name in enumerate(self.series):
            label, unit = SERIES_LABELS.get(name, (name, ""))
            unit = "" if unit == "E" else unit  # energies: in the scene's units (docs/physics.md)
            text = f"{label} {self.history[k][-1]:.3g}{' ' + unit if unit.startswith('°') else unit}"
            if not self.shared_scale() and name not in FRACTIONS:  # its own scale: bottom and top of the box
                lo, hi = self.ranges[k]
                text += f" ({lo:.3g} to {hi:.3g})"
            color = tuple(int(255 * c) for c in COLORS[k % len(COLORS)])
            draw_text(img, text, x, y, scale, color)
            x += text_width(text + "  ", scale)
        draw_text(img, f"t 0-{self.times[-1]:.3g} s", x, y, scale, (200, 200, 200))
        if self.shared_scale():  # the scale at the top, the middle tick and the bottom of the box
            lo, hi = self.ranges[0]
            right = self.x0 + self.box_w + 3
            middle = self.y_top + self.box_h - 1 - self.box_h // 2 - (5 * scale) // 2
            draw_text(img, f"{hi:.3g}", right, self.y_top, scale, (200, 200, 200))
            draw_text(img, f"{0.5 * (lo + hi):.3g}", right, middle, scale, (200, 200, 200))
            draw_text(img, f"{lo:.3g}", right, self.y_top + self.box_h - 5 * scale, scale, (200, 200, 200))


class CurvePlot(Chart):
    """A fixed curve (the window's potential panel: the pair force against distance) in the top-right corner, with
    its zero line; set_curve() replaces it."""

    def __init__(self, image, width: int, height: int, scene_in_image: bool = True):
        super().__init__(image, width, height, ("curve", "zero"), scene_in_image)
        self.x0 = width - self.box_w - 10
        self.r_range: tuple[float, float] | None = None
        self.force_top = 1.0

    def set_curve(self, values: np.ndarray, r_range: tuple[float, float] | None = None) -> None:
        """Plot `values` (any length up to SAMPLES; distances r_range, evenly spaced) scaled so that zero is
        mid-height and the largest attraction reaches a third of the way up; repulsion beyond the box is clipped."""
        self.r_range = r_range
        values = np.asarray(values, dtype=float)
        scale = max(float(np.max(values)), 1e-12) * 3.0
        self.force_top = scale  # the force at the top of the box (the bottom is minus it)
        self.n = min(len(values), SAMPLES)
        pick = np.linspace(0, len(values) - 1, self.n).round().astype(int)
        table = np.zeros((2, SAMPLES), dtype=np.float32)
        table[0, : self.n] = np.clip(0.5 + 0.5 * values[pick] / scale, 0.0, 1.0)
        table[1, : self.n] = 0.5
        self.values.from_numpy(table)

    def record(self, stats) -> None:  # a fixed curve: nothing to record
        pass

    def drawn_rect(self) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1), rows from the top: the box, the force values left of it and the distance axis under
        it."""
        scale = text_scale(self.height)
        left = max(0, self.x0 - text_width("-1.2e+03 ", scale))  # the widest force value (2 significant digits)
        return left, self.width, self.y_top, self.y_top + self.box_h + self.label_height

    def label(self, img: np.ndarray) -> None:
        """Name the curve and its axes on an (H, W, 3) uint8 frame: "pair force" with which way attracts at the top of
        the box, the force at its top, zero line and bottom, and the distance axis's range under the box."""
        if not self.fits:
            return
        scale = text_scale(self.height)
        grey = (200, 200, 200)
        draw_text(img, "pair force, + attracts", self.x0 + 3, self.y_top + 3, scale, grey)
        draw_text(img, "0", self.x0 - text_width("0 ", scale), self.y_top + (self.box_h - 5 * scale) // 2, scale, grey)
        top = f"{self.force_top:.2g}"
        draw_text(img, top, self.x0 - text_width(top + " ", scale), self.y_top, scale, grey)
        bottom = f"-{self.force_top:.2g}"
        low = self.y_top + self.box_h - 5 * scale
        draw_text(img, bottom, self.x0 - text_width(bottom + " ", scale), low, scale, grey)
        if self.r_range is not None:
            lo, hi = self.r_range
            axis = f"r {lo:.2g} to {hi:.2g}"
            x = self.x0 + self.box_w - text_width(axis, scale)
            draw_text(img, axis, x, self.y_top + self.box_h + 3, scale, grey)
