"""The particle renderer: draws the particles of a State (with its Model) into a picture, by composition of

    canvas.py     the float layers, the 8-bit output, the 2D tiles drawn each frame
    look.py       a particle's colour, size and opacity; each body's drawing style
    footprint.py  the motion-blur streak and the pixels a particle covers (and the light it deposits)
    flat.py       2D: the view, backdrop, springs, splats and tile compositing
    spheres.py    3D: the camera, shaded spheres, translucent particles, ghosts, light
    layout.py     the top band (title, clock, legend, charts) and the part of the world the scene shows
    overlays.py   the title, clock and legend; chart.py: charts; both drawn on the host into the top band

The image is W x H with y up (Taichi's and GGUI's convention); `frame()` returns H x W x 3 uint8, top row first. The
renderer holds no simulation and follows nothing inside it: its motion-blur tails (`tails`) are per-particle fields
that whoever pairs it with a state attaches there (`state.carry(renderer.tails)`), so they move with the particles.
"""

from __future__ import annotations

import numpy as np

from ..config.quantities import PHASE_DIAGRAM
from ..core import transfer
from ..core.taichi_compat import field_info
from ..measure.coexistence_curve import curve_of
from ..measure.phase_map import phase_map_of
from .canvas import Canvas
from .chart import Chart, CurvePlot
from .flat import Flat2D
from .footprint import Footprint
from .look import Look
from .measured_phase_plot import MeasuredPhasePlot
from .phase_plot import PhasePlot
from .plan import plan_picture
from .spheres import Spheres3D
from .words import Words


class Renderer:
    """Draws the particles of `state` (scene and materials from `model`) into a `width` x `height` picture."""

    def __init__(
        self,
        model,
        state,
        width: int,
        height: int,
        render_cfg,
        output: str = "image",
        strip_splat: bool = True,
        panel: float = 0.0,
        room_for_charts: bool = False,
        canvas: Canvas | None = None,
    ) -> None:
        """`output`: what render() leaves (canvas.py: "image", "picture" or "rgba"); `strip_splat` False draws every
        2D particle with atomic adds (the reference the strip binning is tested against); `panel`: the fraction of
        the width on the left that a side panel covers (the window's): the scene and the chart are drawn right of
        it; `room_for_charts`: keep the top band tall enough for charts shown later (the window's toggles);
        `canvas`: another renderer's of the same picture to draw in (a classroom host's sessions share one: 17 MB
        each at 960 x 540), where every picture is then drawn whole (what another drew there is not kept)."""
        self.model, self.state = model, state
        self.cfg = render_cfg
        self.width, self.height, self.dim = width, height, model.dim
        self.panel_px = int(round(panel * width))  # pixels on the left under a side panel
        plan = plan_picture(model, state, width, height, render_cfg, self.panel_px, room_for_charts)
        self.plan, self.layout, self.overlays, self.view_box = plan, plan.layout, plan.overlays, plan.view_box
        # The tables go to their fields in one copy kernel when the block ends: a host write of a field element
        # compiles a writer kernel of its own (about 20 ms each at start-up). Nothing in the block reads them.
        with transfer.batched():
            self.look = Look(model, state, render_cfg)
            ghosts = bool(render_cfg.motion_blur) and self.dim == 3 and "opaque" in self.look.blends
            spec = (width, height, self.dim, output, self.look.blends, ghosts, render_cfg.exposure)
            if canvas is None:
                canvas = Canvas(*spec)
            elif canvas.spec != Canvas.spec_of(*spec):
                raise ValueError("canvas: another picture's (size, blends or output differ); expected one alike")
            else:  # every renderer that draws in it draws whole pictures from now on
                canvas.shared = True
            self.canvas = canvas
            self.footprint = Footprint(self.canvas, state.particles, render_cfg, model.capacity, self.dim)
            if self.dim == 2:
                view = plan.view
                self.painter = Flat2D(
                    self.canvas, self.footprint, self.look, model, state, render_cfg, view, strip_splat
                )
            else:
                x0, x1, r0, r1 = self.layout.scene_rect()  # where the view's axis meets the picture (y up)
                axis = (0.5 * (x0 + x1), height - 0.5 * (r0 + r1))
                self.painter = Spheres3D(
                    self.canvas, self.footprint, self.look, model, state, render_cfg, axis, self.view_box
                )
            self.brush: tuple[float, float, float] | None = None  # see set_brush
            self.words: Words | None = None  # the charts' words (render/words.py; None: English)
            self.chart = None
            self.potential = None  # the window's potential panel (a CurvePlot), when shown
            self.phase_plot = None  # the phase diagram (render.chart names "phase_diagram")
            self.set_chart(tuple(render_cfg.chart), place=False)
        self.full_refresh = True
        if self.dim == 2:
            self.refresh_backdrop()
            self._overlays_changed()

    @property
    def tails(self) -> list:
        """Per-particle fields (motion-blur tails) that must move with the particles: attach them to the state."""
        return self.footprint.tails

    @property
    def image(self):
        """The float image, W x H RGB in [0, 1], y up."""
        return self.canvas.image

    @property
    def out(self):
        """The 8-bit output (canvas.py)."""
        return self.canvas.out

    def refresh_backdrop(self) -> None:
        """2D: repaint the static backdrop (domain, walls, heat sources), e.g. after a source's temperature changed."""
        self.painter.paint_backdrop()
        self.full_refresh = True

    def _overlays_changed(self) -> None:
        """The chart, potential panel or legend came or went: composite the whole picture once, and from now on
        redraw their rectangles every frame (their content changes whether or not particles move there)."""
        self.full_refresh = True
        if self.dim == 2:
            plots = [plot.drawn_rect() for plot in self.plots() if plot.fits]
            self.canvas.set_overlays(plots + self.overlays.rects())

    # ------------------------------------------------------------------ the view
    def set_camera(self, eye, target, fov_degrees: float) -> None:
        """3D: place the camera (world units) looking at target with a vertical field of view in degrees."""
        self.painter.set_camera(eye, target, fov_degrees)

    def world_point(self, u: float, v: float) -> np.ndarray:
        """2D: the world position (length units, (2,)) under the window point (u, v) (fractions from the bottom
        left, as GGUI's cursor)."""
        return self.painter.world_point(u, v)

    def pick_index(self, u: float, v: float, reach_px: float = 12.0) -> int | None:
        """3D: the index of the nearest particle drawn within reach_px pixels of the window point (u, v), or None."""
        return self.painter.pick_index(self._positions(), u, v, reach_px) if self.dim == 3 else None

    def pick(self, u: float, v: float, reach_px: float = 12.0) -> np.ndarray | None:
        """3D: the position of the nearest particle drawn within reach_px pixels of the window point (u, v)
        (fractions of width and height, from the bottom left, as GGUI's cursor), or None: where a 3D brush acts."""
        x = self._positions() if self.dim == 3 else np.zeros((0, 3))
        i = self.painter.pick_index(x, u, v, reach_px) if self.dim == 3 else None
        return None if i is None else x[i]

    def _positions(self) -> np.ndarray:
        """The live particles' positions, (N, D) float64."""
        p = self.state.particles
        return p.x.to_numpy()[: int(p.n[None])].astype(float)

    # ------------------------------------------------------------------ frames
    def begin_frame(self) -> None:
        """Remember positions before the simulation advances a frame (the tails of motion-blur streaks)."""
        self.footprint.begin_frame()

    def mid_frame(self) -> None:
        """Remember positions half-way through the frame's substeps (the bend of spline streaks); pass this as
        `midway` to Simulation.advance_frame. Without it a spline streak is drawn straight."""
        self.footprint.mid_frame()

    def render(self) -> None:
        """Draw the current state into the canvas."""
        self.state.refresh_derived()  # the atoms' phases, when drawn by phase
        self.footprint.before_drawing()
        self.painter.draw()
        if self.dim == 2:  # one pass over the dirty tiles paints the backdrop, composites the layers, zeroes them
            whole = self.full_refresh or self.painter.backdrop_moves or self.canvas.shared
            self.painter.composite(int(whole), self.canvas.out)
            self.full_refresh = False
        out = self.canvas.out
        if self.dim == 2 and self.brush is not None:
            self.painter.ring(*self.brush, out)
        if self.canvas.output == "rgba" and self.dim == 3:
            self.canvas.pack(out)

    def frame(self) -> np.ndarray:
        """Render and return the picture as an (H, W, 3) uint8 array, top row first (legend drawn on the host).
        On the CPU the array is the renderer's own buffer, valid until the next render(): copy it to keep it."""
        self.render()
        return self.picture()

    def picture(self) -> np.ndarray:
        """The last rendered picture as an (H, W, 3) uint8 array (what frame() returns, without drawing again)."""
        img = self.canvas.picture()
        self.draw_text_overlays(img)
        return img

    def draw_text_overlays(self, img: np.ndarray) -> None:
        """What is drawn on the host onto an (H, W, 3) uint8 frame (or a view of one): the title, clock and legend,
        the charts and the pair-force panel."""
        self.overlays.draw(img)
        for plot in self.plots():
            plot.label(img)

    def set_brush(self, centre_px: tuple[float, float] | None, radius_px: float = 0.0) -> None:
        """2D: outline a tool's brush over the pictures from the next render(): a ring of radius_px pixels about
        centre_px (pixels, y up, GGUI's cursor times the picture size); None: no outline (the window's cursor).
        Drawn into the picture: GGUI's canvas.circles cost 3 ms a frame on the 2-core machine."""
        self.brush = None if centre_px is None else (float(centre_px[0]), float(centre_px[1]), float(radius_px))

    def show_on(self, canvas) -> None:
        """Hand the last rendered picture to a GGUI canvas: the packed output as it is, else the float image."""
        if self.canvas.output == "rgba":
            self.label_window_output()
            canvas.canvas.set_image(field_info(self.canvas.out))  # what canvas.set_image does after its conversion
        else:
            canvas.set_image(self.canvas.image)

    def label_window_output(self) -> None:
        """The window's picture (GGUI's packed RGBA on the CPU, the renderer's own NumPy buffer): draw the host-side
        text on it in place, as picture() does on its copy (draw_text_overlays)."""
        out = self.canvas.out
        if self.canvas.output != "rgba" or not isinstance(out, np.ndarray):
            return
        rgba = out.view(np.uint8).reshape(self.width, self.height, 4)
        self.draw_text_overlays(rgba[:, ::-1, :3].transpose(1, 0, 2))  # (H, W, 3) top row first: a view of `out`

    # ------------------------------------------------------------------ charts
    def set_potential(self, values: np.ndarray | None, r_range: tuple[float, float] | None = None) -> None:
        """Show a curve (the pair force against distance, over distances r_range) in the top-right corner; None
        hides it."""
        if values is None:
            if self.potential is not None:
                self.potential = None
                self._place_plots()
            return
        if self.potential is None:
            self.potential = CurvePlot((0, 0, 0, 0), self.layout.size, self.model.material_names)
            self._place_plots()
        self.potential.set_curve(values, r_range)

    def record(self, stats) -> None:
        """Give the chart (if the scene has one) this frame's measurements."""
        for plot in (self.chart, self.phase_plot):
            if plot is not None:
                plot.record(stats)

    def set_chart(self, series: tuple[str, ...], place: bool = True, keep_history: bool = False) -> None:
        """Replace the chart (empty: none), e.g. the window's energy plot toggle; its history starts afresh unless
        `keep_history` (the same series in other words: `self.words`, render/words.py). The series
        "phase_diagram" is the phase diagram's panel (render/phase_plot.py)."""
        old_chart, old_phase = self.chart, self.phase_plot
        model, size = self.model, self.layout.size
        measured = tuple(name for name in series if name != PHASE_DIAGRAM)
        words = self.words
        self.chart = Chart(measured, (0, 0, 0, 0), size, model.material_names, model.dim, words) if measured else None
        phase_map = phase_map_of(model) if PHASE_DIAGRAM in series else None
        curve = curve_of(model) if PHASE_DIAGRAM in series else None  # the molecular model's measured curve
        self.phase_plot = None
        if phase_map is not None:
            self.phase_plot = PhasePlot(phase_map, (0, 0, 0, 0), size, model.material_names, model.dim, words)
        elif curve is not None:
            self.phase_plot = MeasuredPhasePlot(curve, (0, 0, 0, 0), size, model.material_names, model.dim, words)
        if keep_history:
            carry_history(((self.chart, old_chart), (self.phase_plot, old_phase)))
        if place:
            self._place_plots()
        else:
            self._share_band()

    def adopt_plots(self, other: Renderer) -> None:
        """Take over the charts' history from `other` (the renderer this one replaces at a new size)."""
        carry_history(((self.chart, other.chart), (self.phase_plot, other.phase_plot)))

    def plots(self) -> list:
        """The charts shown: the measurements', the phase diagram and the pair-force panel."""
        return [plot for plot in (self.chart, self.phase_plot, self.potential) if plot is not None]

    def chart_rect(self) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1): the band between the title's column and the legend that the charts share."""
        return self.plan.chart_rect()

    def _share_band(self) -> None:
        """Share the chart band among the plots shown, side by side, each as wide as it needs at least and the rest
        in proportion; where the band cannot hold them all the measurements' chart gives way first, so the phase
        diagram and the window's pair-force panel stay legible."""
        plots = self.plots()
        x0, x1, r0, r1 = self.chart_rect()
        gap = self.layout.size
        shown = list(plots)
        while shown and sum(plot.min_width() for plot in shown) + gap * (len(shown) - 1) > x1 - x0:
            shown.remove(self.chart if self.chart in shown else shown[0])
        for plot in plots:
            if plot not in shown:
                plot.place((0, 0, 0, 0))
        if not shown:
            return
        need = [plot.min_width() for plot in shown]
        spare = (x1 - x0 - gap * (len(shown) - 1)) / sum(need)
        x = x0
        for plot, width in zip(shown, need):
            plot.place((round(x), round(x + width * spare), r0, r1))
            x += width * spare + gap

    def _place_plots(self) -> None:
        """Share the chart band among the plots shown, then redraw their rectangles each frame."""
        self._share_band()
        self._overlays_changed()

    def legend_colors(self, n: int) -> np.ndarray:
        """The active colour map sampled at n points, (n, 3) floats."""
        return self.overlays.legend_colors(n)


def carry_history(pairs) -> None:
    """Each (new plot, old plot) pair: the new one takes the old one's history, where both are shown."""
    for mine, theirs in pairs:
        if mine is not None and theirs is not None:
            mine.adopt(theirs)
