"""The phase diagram panel of a mesoscale scene: its material's pressure-temperature diagram as the model's rule
makes it (measure/phase_map.py: the set melting and boiling points, Clausius-Clapeyron through them), with the model's
temperature as a line across it, drawn on the host into the picture's top band like a chart. `render.chart =
["phase_diagram", ...]` shows it (window, videos and pictures alike).

No dot: a dot would need a measured temperature and a measured pressure of the material, and the mesoscale model has
neither on these axes (its temperature is a field its rule holds at the set points; its parcels' gauge pressure is
no vapour pressure). The title and the line say "rule". The molecular model's diagram (measured_phase_plot.py) draws
a dot, from measurements only."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..measure.phase_map import BOILING, PhaseMap
from ..measure.units import pressure_unit
from .chart import pen_on, value_ticks
from .text import GREY, dim, draw_text, line_height, text_width
from .words import Words

REGION_FILL = {"solid": (60, 90, 120), "liquid": (40, 60, 130), "gas": (75, 75, 75)}
CURVE = (235, 235, 235)
DOT = (255, 70, 40)  # the temperature line's colour (and the molecular diagram's dot's)
SMOOTHING = 0.1  # each frame's share of the gauge's running mean (the wall gauge of a few particles is noisy)


class PressureTemperaturePanel:
    """What both phase diagrams share: their place in the top band, and their axes (temperature t_lo..t_hi across,
    pressure on a log scale from 1e log_lo to 1e log_hi up), which a subclass sets along with `size` and `rect`."""

    def min_width(self) -> int:
        """Pixels across it needs to be legible."""
        return 10 * self.size

    def place(self, rect: tuple[int, int, int, int]) -> None:
        """Draw into rect from now on; `fits` says whether it has room."""
        self.rect = rect
        x0, x1, r0, r1 = rect
        self.fits = x1 - x0 >= self.min_width() and r1 - r0 >= 5 * line_height(self.size)

    def drawn_rect(self) -> tuple[int, int, int, int]:
        return self.rect

    def plot_box(self) -> tuple[int, int, int, int]:
        """The axes' box inside the rectangle: room above for the title, left for the pressure ticks, below for the
        temperature ticks."""
        x0, x1, r0, r1 = self.rect
        lh = line_height(self.size)
        left = text_width(f"1e{self.log_lo}", self.size) + 8
        return x0 + left, x1 - self.size, r0 + lh + 2, r1 - lh - 6

    def to_pixels(self, box, temperature, pressure) -> tuple[np.ndarray, np.ndarray]:
        """(x, row) relative to the plot box of points at `temperature` (°C, or kT) and `pressure` (arrays alike)."""
        bx0, bx1, br0, br1 = box
        t = (np.asarray(temperature, float) - self.t_lo) / (self.t_hi - self.t_lo)
        logp = np.log10(np.maximum(np.asarray(pressure, float), 1e-300))
        p = (logp - self.log_lo) / (self.log_hi - self.log_lo)
        return np.clip(t, 0, 1) * (bx1 - bx0), (1.0 - np.clip(p, 0, 1)) * (br1 - br0)


class PhasePlot(PressureTemperaturePanel):
    """The diagram of `phase_map` in the rectangle rect (x0, x1, row0, row1; rows from the top) at font size `size`;
    record() each frame, label() draws it on an (H, W, 3) uint8 frame. Pressures in the scene's unit (dim-D)."""

    def __init__(
        self,
        phase_map: PhaseMap,
        rect: tuple[int, int, int, int],
        size: int,
        material_names=(),
        dim=2,
        words: Words | None = None,
    ):
        self.map = phase_map
        self.size = size
        self.words = words or Words()
        self.unit = pressure_unit(material_names, dim)
        self.set_axes()
        self.temperature = math.nan  # the model's mean temperature (°C), where the line is drawn
        self.pressure = math.nan  # the gauge's running mean
        self.boiling: list[float] = []  # the running mean's values while the material boiled
        self.place(rect)

    def set_axes(self) -> None:
        """The axes' ranges from the map (whose vapour curve moves once the boiling pressure is measured)."""
        (self.t_lo, self.t_hi), (p_lo, p_hi) = self.map.axes()
        self.log_lo, self.log_hi = math.floor(math.log10(p_lo)), math.ceil(math.log10(p_hi))

    def record(self, stats) -> None:
        """Move the temperature line to this frame's mean temperature. Once the material has boiled, the vapour curve
        passes through the mean pressure the gauge read while it boiled (the box's pressure at the boiling point,
        measured, in place of the ideal gas's estimate)."""
        pressure = stats.wall_pressure if math.isfinite(stats.wall_pressure) else stats.pressure
        if not math.isfinite(stats.mean_temperature):
            return
        if math.isfinite(pressure):
            known = math.isfinite(self.pressure)
            self.pressure = pressure if not known else self.pressure + SMOOTHING * (pressure - self.pressure)
        if BOILING[0] < stats.gas_fraction < BOILING[1] and math.isfinite(self.pressure) and self.pressure > 0:
            self.boiling.append(self.pressure)
            self.map = dataclasses.replace(self.map, anchor=float(np.mean(self.boiling)))
            self.set_axes()
        self.temperature = float(stats.mean_temperature)

    def adopt(self, other) -> None:
        """Take over `other`'s temperature, gauge and boiling pressures (a renderer rebuilt at a new size)."""
        if isinstance(other, PhasePlot):
            self.temperature, self.boiling = other.temperature, list(other.boiling)
            self.pressure, self.map = other.pressure, other.map
            self.set_axes()

    def label(self, img: np.ndarray) -> None:
        """Draw the regions, curves, ticks, labels, trail and dot on an (H, W, 3) uint8 frame."""
        if not self.fits:
            return
        size, pmap = self.size, self.map
        dim(img, self.rect, 0.3)
        box = bx0, bx1, br0, br1 = self.plot_box()
        temps = np.linspace(self.t_lo, self.t_hi, 200)
        xs, rows = self.to_pixels(box, temps, pmap.vapour_pressure(temps))
        mx, _ = self.to_pixels(box, pmap.melt, 1.0)
        with pen_on(img, box) as (pen, w, h):
            curve = list(zip(xs.tolist(), rows.tolist()))
            left = [(x, r) for x, r in curve if x <= mx]
            right = [(x, r) for x, r in curve if x >= mx]
            pen.polygon([(0, h), *curve, (w, h)], fill=REGION_FILL["gas"])  # below the curves: vapour
            if left:
                pen.polygon([(0, 0), (mx, 0), *reversed(left)], fill=REGION_FILL["solid"])
            if right:
                pen.polygon([(mx, 0), (w, 0), *reversed(right)], fill=REGION_FILL["liquid"])
            pen.line(curve, fill=CURVE, width=2)
            ty = self.to_pixels(box, pmap.melt, pmap.triple_point()[1])[1]
            pen.line([(mx, 0), (mx, float(ty))], fill=CURVE, width=2)  # the melting line
            pen.rectangle([0, 0, w, h], outline=(160, 160, 160))
            if math.isfinite(self.temperature):
                x = float(self.line_x(box))
                pen.line([(x, 0), (x, h)], fill=DOT, width=max(2, size // 8))
        for name, (t, frac) in {
            "solid": (self.t_lo, 0.08),
            "liquid": (0.5 * (pmap.melt + pmap.boil), 0.08),
            "gas": (pmap.boil + 0.3 * (self.t_hi - pmap.boil), 0.8),
        }.items():
            x = bx0 + int(self.to_pixels(box, t, 1.0)[0]) + 4
            draw_text(img, self.words.phase(name), x, br0 + int(frac * (br1 - br0)), size, (220, 220, 220))
        mark = f" {self.words.rule_mark()}"  # the whole diagram, and the line's temperature, are the model's rule
        titles = (
            self.words.phase_title(pmap.material, self.unit) + mark,
            self.words.phase_title(pmap.material, self.unit, short=True) + mark,
            self.words.material(pmap.material) + mark,  # the narrowest: what it is a diagram of, and that it is rule
        )
        room = self.rect[1] - self.rect[0] - 4
        title = next((t for t in titles if text_width(t, size) <= room), titles[-1])
        draw_text(img, title, self.rect[0] + 2, self.rect[2], size, DOT)
        middle = (self.log_lo + self.log_hi) / 2
        middle_text = f"1e{middle:g}" if middle == int(middle) else ""
        value_ticks(img, box, (f"1e{self.log_hi}", middle_text, f"1e{self.log_lo}"), size)
        for t in (pmap.melt, pmap.boil):
            text = f"{t:g}"
            x = bx0 + int(self.to_pixels(box, t, 1.0)[0]) - text_width(text, size) // 2
            draw_text(img, text, x, br1 + 3, size, GREY)
        end = "°C"
        draw_text(img, end, bx1 - text_width(end, size), br1 + 3, size, GREY)

    def line_x(self, box) -> int:
        """The temperature line's column relative to the plot box."""
        return int(round(float(self.to_pixels(box, self.temperature, 1.0)[0])))

    def line_region(self) -> str | None:
        """The region the rule gives the line's temperature above the vapour curve ('solid' below the melting point,
        'liquid' from it to the boiling point, 'gas' above; None before the first record)."""
        if not math.isfinite(self.temperature):
            return None
        pmap = self.map
        return "solid" if self.temperature < pmap.melt else "liquid" if self.temperature <= pmap.boil else "gas"
