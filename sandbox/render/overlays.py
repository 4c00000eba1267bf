"""What is drawn on the host onto the 8-bit picture's top band: the title and the simulated time on the left, the
legend on the right (a colour bar with its range and unit, or a swatch per material, or per solid and melt)."""

from __future__ import annotations

import numpy as np

from ..measure.units import shown, speed_unit
from .colormaps import SPEED_STOPS, TEMPERATURE_STOPS, ramp_np_many
from .layout import Layout, title_size
from .look import STRUCTURE_COLORS, STRUCTURE_WORDS, VAPOUR_COLOR
from .text import GREY, dim, draw_text, line_height, text_width

CLOCK_ROOM = "t = 000.00 s"  # the clock the left column keeps room for (longer runs' clocks run on to the right)


def legend_kind(cfg, has_heat: bool) -> str:
    """What the legend shows for [render] settings `cfg`: "bar" (a colour map: temperature with heat, speed),
    "swatches" (material and phase colours) or "" (none asked)."""
    if not cfg.legend:
        return ""
    if cfg.color_by == "speed" or (cfg.color_by == "temperature" and has_heat):
        return "bar"
    return "swatches"


def swatches(model, color_by: str, has_heat: bool) -> list[tuple[str, tuple[float, float, float]]]:
    """(label, colour) of each colour the particles of `model`'s scene take when coloured by material (or by
    temperature without heat), or by phase with heat: each material solid and melted."""
    names = model.material_names
    materials = model.material_list
    if color_by == "phase" and model.scene.molecular is not None:  # phases measured from structure
        return [(word, colour) for word, colour in zip(STRUCTURE_WORDS, STRUCTURE_COLORS)][::-1]
    if color_by == "phase" and has_heat:
        out = []
        for material_name, m in zip(names, materials):
            name = material_name.replace("_", " ")
            out += [(f"{name} solid", tuple(m.color)), (f"{name} melt", tuple(m.liquid_color))]
            if m.boils:
                out.append((f"{name} vapour", VAPOUR_COLOR))
        return out
    out, seen = [], set()
    for group in model.scene.groups:
        color = (
            tuple(group.color) if getattr(group, "color", ()) else tuple(materials[names.index(group.material)].color)
        )
        label = group.material.replace("_", " ")
        if (label, color) not in seen:
            seen.add((label, color))
            out.append((label, color))
    return out


class Overlays:
    """The title, clock and legend of a picture laid out by `layout`, with the [render] settings `cfg`; the clock
    reads `state`'s time, the swatches `model`'s materials."""

    def __init__(self, cfg, layout: Layout, state, model, title: str):
        self.cfg, self.layout, self.state = cfg, layout, state
        self.width, self.height = layout.width, layout.height
        self.title = title.replace("_", " ") if cfg.title else ""
        self.kind = legend_kind(cfg, state.particles.heat)
        self.material_names = model.material_names
        self.entries = swatches(model, cfg.color_by, state.particles.heat) if self.kind == "swatches" else []
        for drop in ("title", "legend"):  # a picture too narrow for all three: the title goes first, then the legend
            if not self.legend_shown() or self.left_end() + self.layout.margin <= self.legend_rect()[0]:
                break
            if drop == "title":
                self.title = ""
            else:
                self.kind = ""

    def legend_height(self) -> int:
        """Rows the legend takes (0: none)."""
        x0, x1, r0, r1 = self.legend_rect()
        return r1 - r0 if self.legend_shown() else 0

    # ------------------------------------------------------------------ where
    def left_end(self) -> int:
        """The pixel column where the title and clock end (the panel's edge plus a margin when there are none)."""
        size = self.layout.size
        x, _ = self.layout.text_origin()
        widths = ([text_width(self.title, title_size(size))] if self.title else []) + (
            [text_width(CLOCK_ROOM, size)] if self.cfg.clock else []
        )
        return x + max(widths, default=0)

    def legend_rect(self) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1): the pixels the legend draws on (none: an empty rectangle at the right edge)."""
        m, size, w = self.layout.margin, self.layout.size, self.width
        if self.kind == "bar":
            caption = text_width(self.caption(), size)
            return w - m - max(self.bar_width(), caption), w - m + 1, m, m + 2 * line_height(size) + size + 5
        if self.kind == "swatches":
            rows = self._swatch_rows()
            width = max((sum(self._swatch_width(e) for e in row) for row in rows), default=0)
            return w - m - width, w - m, m, m + len(rows) * line_height(size)
        return w, w, 0, 0

    def legend_shown(self) -> bool:
        """Whether the legend is drawn: asked for, and room for it in the picture."""
        x0, x1, r0, r1 = self.legend_rect()
        return bool(self.kind) and x0 >= self.layout.panel_px and r1 <= self.height and x1 > x0

    def rects(self) -> list:
        """(x0, x1, row0, row1) of each item shown: pixels, rows counted from the top."""
        x, row = self.layout.text_origin()
        lines = int(bool(self.title)) + int(bool(self.cfg.clock))
        text = [(x - 4, self.left_end() + 4, row - 4, row + lines * line_height(title_size(self.layout.size)) + 4)]
        return (text if lines else []) + ([self.legend_rect()] if self.legend_shown() else [])

    # ------------------------------------------------------------------ drawing
    def draw(self, img: np.ndarray) -> None:
        """The title, clock and legend, as the settings ask, onto an (H, W, 3) uint8 frame (or a view of one)."""
        size = self.layout.size
        x, row = self.layout.text_origin()
        if self.title:
            draw_text(img, self.title, x, row, title_size(size))
            row += line_height(title_size(size))
        if self.cfg.clock:
            scale, unit = shown("time", self.material_names)
            draw_text(img, f"t = {self.state.time * scale:.2f} {unit}", x, row, size)
        if self.legend_shown():
            self.draw_bar(img) if self.kind == "bar" else self.draw_swatches(img)

    def legend_colors(self, n: int) -> np.ndarray:
        """The active colour map sampled at n points, (n, 3) floats."""
        return ramp_np_many(SPEED_STOPS if self.cfg.color_by == "speed" else TEMPERATURE_STOPS, np.linspace(0, 1, n))

    def bar_geometry(self) -> tuple[int, int, int, int]:
        """(x0, row0, width, height) of the colour bar's coloured pixels."""
        _, x1, r0, _ = self.legend_rect()
        size, bar_w = self.layout.size, self.bar_width()
        return x1 - 1 - bar_w, r0 + line_height(size) + 3, bar_w, max(6, round(0.8 * size))

    def bar_width(self) -> int:
        """Pixels across the colour bar: a sixth of the picture, at least 120, at most a third."""
        return min(max(120, self.width // 6), self.width // 3)

    def caption(self) -> str:
        """The colour bar's caption: "temperature (°C)"."""
        _, _, quantity, unit = self.scale()
        return f"{quantity} ({unit})"

    def scale(self) -> tuple[float, float, str, str]:
        """(low, high, quantity, unit) of the colour bar."""
        if self.cfg.color_by == "speed":
            return 0.0, float(self.cfg.speed_range), "speed", speed_unit(self.material_names)
        lo, hi = self.cfg.temperature_range
        return float(lo), float(hi), "temperature", "°C"

    def draw_bar(self, img: np.ndarray) -> None:
        """A colour bar under its caption ("temperature (°C)"), with its ends and middle labelled under it."""
        size = self.layout.size
        x0, r0, bar_w, bar_h = self.bar_geometry()
        lo, hi, _, _ = self.scale()
        left, _, top, _ = self.legend_rect()
        dim(img, (left - 4, x0 + bar_w + 4, top - 2, r0 + bar_h + line_height(size) + 2), 0.45)
        caption = self.caption()
        draw_text(img, caption, x0 + bar_w - text_width(caption, size), top, size)
        colors = (self.legend_colors(bar_w) * 255 + 0.5).astype(np.uint8)
        img[r0 : r0 + bar_h, x0 : x0 + bar_w] = colors[None, :, :]
        below = r0 + bar_h + 2
        mid = f"{0.5 * (lo + hi):g}"
        draw_text(img, f"{lo:g}", x0, below, size, GREY)
        draw_text(img, mid, x0 + (bar_w - text_width(mid, size)) // 2, below, size, GREY)
        draw_text(img, f"{hi:g}", x0 + bar_w - text_width(f"{hi:g}", size), below, size, GREY)

    def _swatch_width(self, entry) -> int:
        size = self.layout.size
        return size + 6 + text_width(entry[0], size) + size

    def _swatch_rows(self) -> list[list]:
        """The swatches in rows, each at most half the picture's width wide."""
        rows, row, used = [], [], 0
        for entry in self.entries:
            w = self._swatch_width(entry)
            if row and used + w > self.width // 2:
                rows.append(row)
                row, used = [], 0
            row.append(entry)
            used += w
        return rows + ([row] if row else [])

    def draw_swatches(self, img: np.ndarray) -> None:
        """A filled square in each colour with what it means beside it ("wax solid", "wax melt")."""
        size = self.layout.size
        x0, x1, r0, r1 = self.legend_rect()
        dim(img, (x0 - 4, x1 + 4, r0 - 2, r1 + 2), 0.45)
        for k, row in enumerate(self._swatch_rows()):
            x, top = x0, r0 + k * line_height(size)
            for label, color in row:
                sq = (top + (line_height(size) - size) // 2 + 2, x)
                img[sq[0] : sq[0] + size - 2, sq[1] : sq[1] + size - 2] = (np.asarray(color) * 255 + 0.5).astype(
                    np.uint8
                )
                draw_text(img, label, x + size + 4, top, size)
                x += self._swatch_width((label, color))
