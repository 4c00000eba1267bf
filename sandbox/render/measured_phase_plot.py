"""The molecular model's phase diagram: the liquid-vapour curve its own study measured (measure/coexistence_curve.py)
with the state as a dot at the measured kinetic temperature and pressure, and the dot's uncertainty as a bar.

Nothing places the dot by rule: its temperature is `motion_temperature`, its pressure the lid's gauge (the momentum
the atoms give the lid), else the walls' gauge, else the virial pressure, each the mean of the last SAMPLES frames,
the bar the standard error of that mean. The curve's measured points are drawn as small marks on the fitted line,
which ends at the fitted critical point (a ring)."""

from __future__ import annotations

import math

import numpy as np

from ..measure.coexistence_curve import CoexistenceCurve
from ..measure.units import pressure_unit, shown
from .chart import pen_on, value_ticks
from .phase_plot import CURVE, DOT, REGION_FILL, PressureTemperaturePanel
from .text import GREY, dim, draw_text, text_width
from .words import Words

SAMPLES = 40  # frames averaged for the dot
TRAIL = 240  # positions kept for the trail


class MeasuredPhasePlot(PressureTemperaturePanel):
    """The measured diagram of `curve` in the rectangle rect (x0, x1, row0, row1; rows from the top) at font size
    `size`; record() each frame, label() draws it on an (H, W, 3) uint8 frame (PhasePlot's interface)."""

    def __init__(self, curve: CoexistenceCurve, rect, size: int, material_names=(), dim=2, words: Words | None = None):
        self.curve = curve
        self.size = size
        self.words = words or Words()
        self.unit = pressure_unit(material_names, dim)
        # a real substance's scene labels the axes in its units (K, kPa); the plot itself stays in reduced units
        self.t_scale, self.t_unit = shown("kT", material_names, dim)
        self.p_scale = shown("pressure", material_names, dim)[0]
        tc = curve.critical_temperature
        self.t_lo, self.t_hi = 0.8 * min(curve.temperatures), 1.25 * tc
        p_lo = float(curve.vapour_pressure(self.t_lo))
        self.log_lo = math.floor(math.log10(p_lo))
        self.log_hi = math.ceil(math.log10(4.0 * curve.critical_pressure))
        self.samples: list[tuple[float, float]] = []  # (kT, pressure) of the last SAMPLES frames
        self.trail: list[tuple[float, float]] = []
        self.place(rect)

    def record(self, stats) -> None:
        """Add this frame's measured (kT, pressure) and move the dot to the mean of the last SAMPLES."""
        pressure = next(
            (p for p in (stats.lid_pressure, stats.wall_pressure, stats.pressure) if math.isfinite(p)), math.nan
        )
        kt = stats.motion_temperature
        if not (math.isfinite(kt) and math.isfinite(pressure)):
            return
        self.samples.append((kt, pressure))
        del self.samples[:-SAMPLES]
        self.trail.append(self.dot())
        del self.trail[:-TRAIL]

    def dot(self) -> tuple[float, float]:
        """(kT, pressure): the means of the recent samples."""
        t, p = np.asarray(self.samples, float).T
        return float(t.mean()), float(p.mean())

    def error(self) -> tuple[float, float]:
        """The standard errors of the dot's two means (0 with one sample)."""
        if len(self.samples) < 2:
            return 0.0, 0.0
        t, p = np.asarray(self.samples, float).T
        return float(t.std(ddof=1) / math.sqrt(len(t))), float(p.std(ddof=1) / math.sqrt(len(p)))

    def adopt(self, other) -> None:
        if isinstance(other, MeasuredPhasePlot):
            self.samples, self.trail = list(other.samples), list(other.trail)

    def dot_region(self) -> str | None:
        """The region of the diagram the dot lies in ("gas", "liquid", "fluid"; None before the first record)."""
        return self.curve.region(*self.trail[-1]) if self.trail else None

    def label(self, img: np.ndarray) -> None:
        """Draw the regions, the measured curve and points, the critical point, the trail and the dot with its bar."""
        if not self.fits:
            return
        size, curve = self.size, self.curve
        dim(img, self.rect, 0.3)
        box = bx0, bx1, br0, br1 = self.plot_box()
        tc = curve.critical_temperature
        temps = np.linspace(self.t_lo, tc, 160)
        xs, rows = self.to_pixels(box, temps, curve.vapour_pressure(temps))
        cx, cr = self.to_pixels(box, tc, curve.critical_pressure)
        with pen_on(img, box) as (pen, w, h):
            line = list(zip(xs.tolist(), rows.tolist()))
            pen.polygon([(0, h), *line, (float(cx), h)], fill=REGION_FILL["gas"])
            pen.polygon([(0, 0), (float(cx), 0), *reversed(line)], fill=REGION_FILL["liquid"])
            pen.line(line, fill=CURVE, width=2)
            pen.ellipse([cx - 4, cr - 4, cx + 4, cr + 4], outline=CURVE, width=2)  # the critical point
            px, pr = self.to_pixels(box, np.asarray(curve.temperatures), np.asarray(curve.pressures))
            for x, r in zip(px.tolist(), pr.tolist()):
                pen.rectangle([x - 2, r - 2, x + 2, r + 2], fill=(255, 255, 255))
            pen.rectangle([0, 0, w, h], outline=(160, 160, 160))
            if self.trail:
                tx, tr = self.to_pixels(box, *np.asarray(self.trail, float).T)
                if len(tx) > 1:
                    pen.line(list(zip(tx.tolist(), tr.tolist())), fill=(255, 170, 150), width=1)
                t, p = self.trail[-1]
                dt, dp = self.error()
                (x0, x1), (r_hi, r_lo) = (
                    self.to_pixels(box, [t - dt, t + dt], p)[0],
                    self.to_pixels(box, t, [max(p + dp, 1e-300), max(p - dp, 1e-300)])[1],
                )
                x, r = float(tx[-1]), float(tr[-1])
                pen.line([(x, float(r_hi)), (x, float(r_lo))], fill=DOT, width=2)  # the uncertainty
                pen.line([(float(x0), r), (float(x1), r)], fill=DOT, width=2)
                radius = max(3, size // 3)
                pen.ellipse([x - radius, r - radius, x + radius, r + radius], fill=DOT, outline=(255, 255, 255))
        for name, (t, frac) in {"liquid": (self.t_lo, 0.08), "gas": (0.5 * (self.t_lo + tc), 0.8)}.items():
            x = bx0 + int(self.to_pixels(box, t, 1.0)[0]) + 4
            draw_text(img, self.words.phase(name), x, br0 + int(frac * (br1 - br0)), size, (220, 220, 220))
        title = self.words.phase_title("atoms", self.unit)
        if text_width(title, size) > self.rect[1] - self.rect[0] - 4:
            title = self.words.phase_title("atoms", self.unit, short=True)
        draw_text(img, title, self.rect[0] + 2, self.rect[2], size, DOT)
        middle = (self.log_lo + self.log_hi) / 2
        decade = (lambda e: f"1e{e:g}") if self.p_scale == 1.0 else (lambda e: _short(10.0**e * self.p_scale))
        middle_text = decade(middle) if middle == int(middle) else ""
        value_ticks(img, box, (decade(self.log_hi), middle_text, decade(self.log_lo)), size)
        for t in (min(curve.temperatures), tc):
            text = f"{t:.2f}" if self.t_scale == 1.0 else f"{t * self.t_scale:.0f}"
            x = bx0 + int(self.to_pixels(box, t, 1.0)[0]) - text_width(text, size) // 2
            draw_text(img, text, x, br1 + 3, size, GREY)
        end = "kT" if self.t_scale == 1.0 else self.t_unit
        draw_text(img, end, bx1 - text_width(end, size), br1 + 3, size, GREY)


def _short(value: float) -> str:
    """A pressure tick in two digits, its exponent without the sign and zeros ("42", "4.2e4")."""
    text = f"{value:.2g}"
    return text.replace("e+0", "e").replace("e+", "e").replace("e-0", "e-")
