"""Charts of measurements against time, drawn on the host into the picture's top band (window and videos alike).

`render.chart = ["mean_temperature", "molten_fraction"]` plots those Stats fields against simulated time. Series
of one unit share a panel; each unit gets its own panel with its own axis, so no series is drawn on a scale the
reader cannot see. A panel has a title in words with its unit, a value axis with three labelled ticks, a time
axis labelled in seconds, and each series' latest value in its colour.
"""

from __future__ import annotations

import contextlib
import math

import numpy as np
from PIL import Image, ImageDraw

from ..config.quantities import BY_NAME, QUANTITIES
from ..measure.units import length_unit, series_scale, series_words, shown
from .layout import side_by_side
from .text import GREY, dim, draw_text, line_height, text_width
from .words import Words

COLORS = ((255, 110, 70), (90, 170, 255), (130, 230, 100), (240, 215, 80))
HISTORY = 4096  # samples kept; past it every other one is dropped and the sampling stride doubles
FRACTIONS = tuple(q.name for q in QUANTITIES if q.unit == "%")  # drawn in percent on a fixed 0 to 100 scale


def nice_range(lo: float, hi: float) -> tuple[float, float]:
    """A range covering [lo, hi] whose ends are round numbers (1, 2 or 5 times a power of ten)."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return 0.0, 1.0
    if hi - lo < 1e-12 * max(1.0, abs(hi)):
        lo, hi = lo - max(1.0, abs(lo)) * 0.05, hi + max(1.0, abs(hi)) * 0.05
    raw = (hi - lo) / 2
    power = 10 ** math.floor(math.log10(raw))
    step = next(s * power for s in (1, 2, 5, 10) if s * power >= raw)
    return math.floor(lo / step) * step, math.ceil(hi / step) * step


def tick_text(value: float) -> str:
    """A tick's label: up to three significant digits, no float noise."""
    return f"{value:.3g}"


def short_words(name: str) -> str:
    """A series' name in one word, for a narrow panel."""
    return {"mean_temperature": "mean", "kinetic_temperature": "motion", "molten_fraction": "melted"}.get(
        name, name.split("_")[0]
    )


def set_by_rule(name: str) -> bool:
    """Whether the series `name` is set by the model's rule rather than measured (config/quantities.py's source)."""
    quantity = BY_NAME.get(name)
    return quantity is not None and quantity.source == "rule"


def value_text(value: float, unit: str) -> str:
    """A latest value as a reader wants it: temperatures to a tenth of a degree, percentages whole, else three
    significant digits."""
    if unit == "°C":
        return f"{value:.1f}"
    if unit == "%":
        return f"{value:.0f}"
    return f"{value:.3g}"


@contextlib.contextmanager
def pen_on(img: np.ndarray, box: tuple[int, int, int, int]):
    """A Pillow pen on the plot box (x0, x1, row0, row1; rows from the top) of an (H, W, 3) uint8 image, with the
    box's width and height: yields (pen, w, h) in coordinates relative to the box; what it draws is copied back."""
    bx0, bx1, br0, br1 = box
    crop = img[br0 : br1 + 1, bx0 : bx1 + 1]
    picture = Image.fromarray(np.ascontiguousarray(crop))
    yield ImageDraw.Draw(picture), bx1 - bx0, br1 - br0
    crop[:] = np.asarray(picture)


def value_ticks(img: np.ndarray, box: tuple[int, int, int, int], texts: tuple[str, str, str], size: int) -> None:
    """The value axis's labels (top, middle, bottom) right-aligned left of the plot box."""
    bx0, _, br0, br1 = box
    for text, row in zip(texts, (br0, (br0 + br1) // 2, br1)):
        draw_text(img, text, bx0 - 6 - text_width(text, size), row - line_height(size) // 2, size, GREY)


class Panel:
    """One plot box: the series of one unit, with its axes."""

    def __init__(self, names: list[int], title: str, unit: str, fixed: tuple[float, float] | None):
        self.names, self.title, self.unit, self.fixed = names, title, unit, fixed


class Chart:
    """Measurements of `series` (Stats field names) against time, in the picture rectangle `rect` (x0, x1, row0,
    row1; rows from the top) at font size `size`; record() each frame, label() draws it on an (H, W, 3) frame.
    `material_names` and `dim` choose the units (measure/units.py)."""

    def __init__(
        self,
        series: tuple[str, ...],
        rect: tuple[int, int, int, int],
        size: int,
        material_names=(),
        dim=2,
        words: Words | None = None,
    ):
        self.series = tuple(series)
        self.size = size
        self.translated = words is not None and any(words.series(n, "") for n in self.series)
        words = words or Words()
        # a series the model's rule sets (a mesoscale scene's heat and phases) says so after its words
        self.marks = [f" {words.rule_mark()}" if set_by_rule(n) else "" for n in self.series]
        english = [series_words(n, material_names, dim) for n in self.series]  # (words, unit) of each
        full = [words.series(n, said) for n, (said, _) in zip(self.series, english)]
        self.words = [(w + mark, unit) for w, mark, (_, unit) in zip(full, self.marks, english)]
        # a narrow panel's words: one word (the catalogue's `chart_short_<name>` in another language), with the mark
        self.short = [
            ((words.series(f"short_{n}", "") if self.translated else short_words(n)) or w) + mark
            for n, w, mark in zip(self.series, full, self.marks)
        ]
        by_unit: dict[str, list[int]] = {}
        for k, (_, unit) in enumerate(self.words):
            by_unit.setdefault(unit, []).append(k)
        self.panels = []
        for unit, ks in by_unit.items():
            title = ", ".join(self.words[k][0] for k in ks)
            fixed = (0.0, 100.0) if all(self.series[k] in FRACTIONS for k in ks) else None
            self.panels.append(Panel(ks, title, unit, fixed))
        # a real substance's scene is shown in its units (measure/units.py): the factors, and the clock's unit
        self.scales = [series_scale(n, material_names, dim) for n in self.series]
        self.time_scale, self.time_unit = shown("time", material_names, dim)
        self.history: list[list[float]] = [[] for _ in self.series]
        self.times: list[float] = []
        self.frames = 0  # frames offered to record()
        self.stride = 1  # one sample kept per this many frames
        self.place(rect)

    def place(self, rect: tuple[int, int, int, int]) -> None:
        """Draw into rect (x0, x1, row0, row1; rows from the top) from now on; `fits` says whether it has room."""
        self.rect = rect
        x0, x1, r0, r1 = rect
        self.fits = x1 - x0 >= self.min_width() and r1 - r0 >= 4 * line_height(self.size)

    def min_width(self) -> int:
        """Pixels across it needs to be legible."""
        return 8 * self.size * len(self.panels)

    def record(self, stats) -> None:
        """Append this frame's values (every `stride`-th frame once the history is long)."""
        self.frames += 1
        if (self.frames - 1) % self.stride:
            return
        for k, name in enumerate(self.series):
            value = float(getattr(stats, name)) * (100.0 if name in FRACTIONS else self.scales[k])
            self.history[k].append(value if math.isfinite(value) else math.nan)
        self.times.append(float(stats.time) * self.time_scale)
        if len(self.times) > HISTORY:  # bounded work per frame on a long run
            self.history = [h[::2] for h in self.history]
            self.times = self.times[::2]
            self.stride *= 2

    def adopt(self, other: Chart) -> None:
        """Take over `other`'s history where it plots the same series (a renderer rebuilt at a new size)."""
        if other.series == self.series:
            self.history, self.times = [list(h) for h in other.history], list(other.times)
            self.frames, self.stride = other.frames, other.stride

    def drawn_rect(self) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1), rows from the top: the pixels the chart draws on."""
        return self.rect

    def panel_rects(self) -> list[tuple[int, int, int, int]]:
        """Each panel's rectangle within the chart's, side by side."""
        return side_by_side(self.rect, len(self.panels), self.size)

    def data_range(self, panel: Panel) -> tuple[float, float]:
        """The value axis of `panel`: fixed (percent) or the nice range of its series so far."""
        if panel.fixed:
            return panel.fixed
        values = np.concatenate([np.asarray(self.history[k], float) for k in panel.names])
        values = values[np.isfinite(values)]
        return nice_range(float(values.min()), float(values.max())) if values.size else (0.0, 1.0)

    def xy(self, panel: Panel, k: int, plot: tuple[int, int, int, int]) -> list[tuple[float, float]]:
        """Series k's points in pixels (x, row) of the plot box `plot`."""
        x0, x1, r0, r1 = plot
        t = np.asarray(self.times, float)
        v = np.asarray(self.history[k], float)
        lo, hi = self.data_range(panel)
        t_end = max(t[-1], 1e-9)
        keep = np.isfinite(v)
        xs = x0 + (x1 - x0) * t[keep] / t_end
        rows = r1 - (r1 - r0) * np.clip((v[keep] - lo) / (hi - lo), 0.0, 1.0)
        if len(xs) > 2 * (x1 - x0):  # no more points than the box has half-pixels across
            pick = np.linspace(0, len(xs) - 1, 2 * (x1 - x0)).round().astype(int)
            xs, rows = xs[pick], rows[pick]
        return list(zip(xs.tolist(), rows.tolist()))

    def plot_box(self, rect: tuple[int, int, int, int], lo: float, hi: float) -> tuple[int, int, int, int]:
        """The axes' box inside a panel's rectangle: room above for the title, left for the value ticks, below for
        the time ticks."""
        x0, x1, r0, r1 = rect
        lh = line_height(self.size)
        left = max(text_width(tick_text(v), self.size) for v in (lo, hi, 0.5 * (lo + hi))) + 8
        return x0 + left, x1 - self.size, r0 + lh + 2, r1 - lh - 6

    def label(self, img: np.ndarray) -> None:
        """Draw every panel (backing, axes, ticks, lines, labels) on an (H, W, 3) uint8 frame."""
        if not self.times or not self.fits:
            return
        for panel, rect in zip(self.panels, self.panel_rects()):
            self.draw_panel(img, panel, rect)

    def draw_panel(self, img: np.ndarray, panel: Panel, rect: tuple[int, int, int, int]) -> None:
        size = self.size
        dim(img, rect, 0.3)
        lo, hi = self.data_range(panel)
        box = bx0, bx1, br0, br1 = self.plot_box(rect, lo, hi)
        with pen_on(img, box) as (pen, w, h):
            for frac in (0.25, 0.5, 0.75):  # light grid lines at the ticks
                pen.line([(0, round(h * frac)), (w, round(h * frac))], fill=(70, 70, 70))
                pen.line([(round(w * frac), 0), (round(w * frac), h)], fill=(70, 70, 70))
            pen.rectangle([0, 0, w, h], outline=(160, 160, 160))
            for k in panel.names:
                points = [(x - bx0, r - br0) for x, r in self.xy(panel, k, box)]
                color = COLORS[k % len(COLORS)]
                if len(points) > 1:
                    pen.line(points, fill=color, width=max(2, size // 8), joint="curve")
                elif points:
                    pen.ellipse([points[0][0] - 2, points[0][1] - 2, points[0][0] + 2, points[0][1] + 2], fill=color)
        # the title: each series in its colour with its latest value, then the unit; the words shortened, then
        # left out, where the panel is too narrow for them
        latest = [next((v for v in reversed(self.history[k]) if math.isfinite(v)), math.nan) for k in panel.names]
        unit = f"({panel.unit})" if panel.unit else ""
        for words in (lambda k: self.words[k][0], lambda k: self.short[k], lambda k: self.marks[k].strip()):
            texts = [f"{words(k)} {value_text(v, panel.unit)}".strip() for k, v in zip(panel.names, latest)]
            if sum(text_width(t + "   ", size) for t in texts) + text_width(unit, size) <= rect[1] - rect[0] - 4:
                break
        x = rect[0] + 2
        for k, text in zip(panel.names, texts):
            draw_text(img, text, x, rect[2], size, COLORS[k % len(COLORS)])
            x += text_width(text + "   ", size)
        draw_text(img, unit, x, rect[2], size, GREY)
        value_ticks(img, box, (tick_text(hi), tick_text(0.5 * (lo + hi)), tick_text(lo)), size)
        t_end = self.times[-1]
        unit = f" {self.time_unit}"
        middle_fits = text_width(tick_text(t_end) + unit + "  " + tick_text(t_end / 2), size) < w / 2
        for frac in (0.0, 0.5, 1.0) if middle_fits else (0.0, 1.0):
            text = tick_text(frac * t_end) + (unit if frac == 1.0 else "")
            x = bx0 + round(frac * w) - text_width(text, size) * (frac if frac < 1 else 1.0)
            draw_text(img, text, round(x) if frac < 1 else bx1 - text_width(text, size), br1 + 3, size, GREY)


class CurvePlot(Chart):
    """A fixed curve (the window's pair force against distance) with its zero line; set_curve() replaces it."""

    def __init__(self, rect: tuple[int, int, int, int], size: int, material_names=()):
        super().__init__(("pair_force",), rect, size)
        self.r: np.ndarray = np.zeros(0)
        self.force: np.ndarray = np.zeros(0)
        self.length = length_unit(material_names)

    def set_curve(self, values: np.ndarray, r_range: tuple[float, float] | None = None) -> None:
        """Plot the force `values` at distances evenly spaced over r_range (length)."""
        self.force = np.asarray(values, float)
        lo, hi = r_range or (0.0, 1.0)
        self.r = np.linspace(lo, hi, len(self.force))

    def record(self, stats) -> None:  # a fixed curve: nothing to record
        pass

    def label(self, img: np.ndarray) -> None:
        """The curve, clipped so that the attraction's well fills a third of the box, with zero at mid-height."""
        if not self.fits or not len(self.force):
            return
        rect = self.rect
        size = self.size
        top = max(float(np.max(self.force)), 1e-12) * 3.0  # the force at the top of the box (the bottom is minus it)
        dim(img, rect, 0.3)
        box = bx0, bx1, br0, br1 = self.plot_box(rect, -top, top)
        with pen_on(img, box) as (pen, w, h):
            pen.rectangle([0, 0, w, h], outline=(160, 160, 160))
            pen.line([(0, h // 2), (w, h // 2)], fill=(110, 110, 110))
            xs = (self.r - self.r[0]) / max(self.r[-1] - self.r[0], 1e-12) * w
            rows = h / 2 - np.clip(self.force / top, -1.0, 1.0) * h / 2
            pen.line(list(zip(xs.tolist(), rows.tolist())), fill=COLORS[0], width=2)
        draw_text(img, "pair force (+ attracts)", rect[0] + 2, rect[2], size, COLORS[0])
        value_ticks(img, box, (f"{top:.2g}", f"{0.0:.2g}", f"{-top:.2g}"), size)
        draw_text(img, f"{self.r[0]:.2g}", bx0, br1 + 3, size, GREY)
        end = f"distance {self.r[-1]:.2g} {self.length}"
        draw_text(img, end, bx1 - text_width(end, size), br1 + 3, size, GREY)
