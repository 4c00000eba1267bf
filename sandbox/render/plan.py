"""Where a picture puts things, decided before anything is drawn (and without Taichi): the band's layout, the
title, clock and legend, and the 2D view that frames the scene's content below the band. The renderer draws by
it; tests and tools read it to know where a particle lands."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .chart import Chart
from .layout import Layout, content_box, fit, make_layout
from .overlays import Overlays

MIN_CHART_HEIGHT = 240  # pixels: a shorter picture keeps no band for charts (they would not be legible)


@dataclass
class PicturePlan:
    """`layout` of the picture, its `overlays`, the world box framed (`view_box`) and, in 2D, the view (pixels per
    length, offset: pixel = offset + scale * world, y up)."""

    layout: Layout
    overlays: Overlays
    view_box: tuple[np.ndarray, np.ndarray]
    view: tuple[float, np.ndarray] | None

    def chart_rect(self) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1): the band between the title's column and the legend that the charts share."""
        return chart_band(self.overlays)

    def pixels(self, x: np.ndarray) -> np.ndarray:
        """2D: the picture points (columns, rows from the top) of world positions x, (N, 2)."""
        scale, offset = self.view
        p = np.asarray(x, float) * scale + offset
        return np.stack([p[:, 0], self.layout.height - p[:, 1]], axis=1)


def chart_band(overlays: Overlays) -> tuple[int, int, int, int]:
    """(x0, x1, row0, row1) of `overlays`' layout between the title's column and the legend (the picture's right
    edge where no legend is shown): where the charts go."""
    right = overlays.legend_rect()[0] if overlays.legend_shown() else overlays.layout.width
    return overlays.layout.chart_rect(overlays.left_end(), right)


def plan_picture(model, state, width: int, height: int, cfg, panel_px: int = 0, room_for_charts: bool = False):
    """The PicturePlan of a `width` x `height` picture of `state` with the [render] settings `cfg`, `panel_px`
    columns on the left under a side panel; `room_for_charts` keeps the band tall enough for charts shown later."""
    scale = cfg.text_scale
    # the legend and title decide the band's height: laid out first on a picture with no band
    overlays = Overlays(cfg, make_layout(width, height, panel_px, 0, 0, False, scale), state, model, model.scene.name)
    lines = int(bool(overlays.title)) + int(bool(cfg.clock))
    charts = (bool(cfg.chart) or room_for_charts) and height >= MIN_CHART_HEIGHT
    if cfg.chart and not room_for_charts:  # no band for a chart the picture is too narrow to hold
        band = chart_band(overlays)
        room = (band[0], band[1], 0, height // 2)
        charts = charts and Chart(tuple(cfg.chart), room, overlays.layout.size, model.material_names).fits
    layout = make_layout(width, height, panel_px, lines, overlays.legend_height(), charts, scale)
    overlays.layout = layout
    view_box = content_box(model.scene)
    view = None
    if model.dim == 2:
        view = fit(view_box, layout.scene_rect(), height, (model.scene.world.lo, model.scene.world.hi))
    return PicturePlan(layout, overlays, view_box, view)
