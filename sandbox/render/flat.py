"""2D drawing: the view (world to pixels), the backdrop (domain, walls, heat sources), springs, particle splats (strip
by strip without atomics, or atomically), and the compositing pass that resolves the layers into the picture tile
by tile.

Compositing: opaque particles blend by coverage-weighted averaging (order-independent); translucent ones by
weighted averaging of colour with total alpha 1 - prod(1 - a) (an exact product, accumulated as a sum of logs);
additive light is tone mapped, 1 - exp(-exposure L) per channel. Only the tiles drawn in this frame or the last are
composited (canvas.py); the rest of the picture is kept from before.
"""

import math

import numpy as np
import taichi as ti

from ..core import transfer
from ..core.oriented import data_oriented
from ..core.worlds import at
from .colormaps import temperature_map
from .pixels import get_pixel, put_pixel
from .strips import StripBins
from .style import (
    BLEND,
    BRUSH_COLOR,
    BRUSH_OPACITY,
    LID_COLOR,
    MIN_FADE,
    R_MIN,
    SPRING_COLOR,
    SPRING_OPACITY,
    TILE,
    WALL_GAIN,
    WALL_LIFT,
    _add,
)


def source_table(cfg, sources: list, lows: list, highs: list) -> list:
    """(field, values) pairs for the drawn heat sources' corners and temperatures (degrees): a power source has no
    temperature of its own, and is drawn hot if it heats, cold if it cools."""
    cold, hot = cfg.temperature_range
    temps = [s.temperature if s.temperature is not None else (hot if s.power >= 0 else cold) for s in sources]
    n = max(len(sources), 1)
    lo, hi, t = ti.Vector.field(2, ti.f32, shape=n), ti.Vector.field(2, ti.f32, shape=n), ti.field(ti.f32, shape=n)
    values = [np.array(lows, np.float32).reshape(-1, 2), np.array(highs, np.float32).reshape(-1, 2)]
    return [(lo, values[0]), (hi, values[1]), (t, np.array(temps, np.float32))]


@data_oriented
class Flat2D:
    """Draws the particles (and springs) of a 2D scene onto `canvas` through `view` (pixels per length, offset:
    pixel = offset + scale * world, y up; layout.fit)."""

    def __init__(self, canvas, footprint, look, model, state, cfg, view, strip_splat: bool = True):
        """`strip_splat` False draws every particle with atomic adds (the reference the strip binning is tested
        against)."""
        self.canvas, self.footprint, self.look = canvas, footprint, look
        self.model, self.state, self.p = model, state, state.particles
        self.strip_splat = strip_splat
        self.background = ti.Vector(list(cfg.background))
        self.draw_springs = bool(cfg.draw_springs) and state.springs is not None
        width = canvas.width
        lo, hi = np.asarray(model.scene.world.lo), np.asarray(model.scene.world.hi)
        scale, offset = view
        self.px_per_unit = float(scale)
        self.offset = ti.Vector(list(offset))
        self.px_lo = ti.Vector(list(offset + scale * lo))
        self.px_hi = ti.Vector(list(offset + scale * hi))
        heat = model.scene.heat
        sources = [s for s in heat.sources if s.visible] if heat else []
        self.n_src = len(sources)
        corners = [np.asarray(s.lo) for s in sources], [np.asarray(s.hi) for s in sources]
        table = source_table(
            cfg,
            sources,
            [offset + scale * c for c in corners[0]],
            [offset + scale * c for c in corners[1]],
        )
        (self.src_lo, _), (self.src_hi, _), (self.src_t, _) = table
        transfer.upload(table)
        self.strips = StripBins(width, model.capacity)
        # the molecular model's lid (physics/lid.py): drawn at its height, so the picture is composited whole while
        # it moves (the backdrop is not static there)
        lid = state.entry("lid.height")
        self.has_lid = lid is not None
        self.lid = lid.owner if lid is not None else None  # its height: world 0's where there are many
        self.backdrop_moves = self.has_lid
        # the walls and heat sources do not move: painted once (refresh_backdrop() after changing a source)
        self.backdrop = canvas.layer(3)
        if self.draw_springs:
            self.spring_log = canvas.layer()  # sum of log(1 - coverage) of the spring lines: log transmittance

    def world_point(self, u: float, v: float) -> np.ndarray:
        """The world position (length units, (2,)) under the picture point (u, v) (fractions from the bottom left, as
        GGUI's cursor)."""
        pixel = np.array([u * self.canvas.width, v * self.canvas.height]) - np.asarray(self.offset.to_list())
        return pixel / self.px_per_unit

    @ti.kernel
    def paint_backdrop(self):
        for x, y in self.backdrop:
            self.backdrop[x, y] = self._background(x, y)

    def draw(self) -> None:
        """The springs and splats into the layers (stamping the tiles they touch)."""
        if self.draw_springs:
            self._springs_2d()
        self._bin_2d()
        for splat_pass in (0, 1, 2) if self.strip_splat else (2,):
            self._splat_pass_2d(splat_pass)

    @ti.func
    def _background(self, x, y):
        """The 2D backdrop at pixel (x, y): the domain, its walls as a faint frame, the heat sources."""
        pix = ti.Vector([x + 0.5, y + 0.5])
        c = self.background
        inside = (
            pix[0] >= self.px_lo[0] and pix[0] <= self.px_hi[0] and pix[1] >= self.px_lo[1] and pix[1] <= self.px_hi[1]
        )
        if not inside:
            c = self.background * 0.6
        elif (
            ti.min(pix[0] - self.px_lo[0], self.px_hi[0] - pix[0], pix[1] - self.px_lo[1], self.px_hi[1] - pix[1]) < 1.5
        ):
            c = self.background * WALL_GAIN + WALL_LIFT  # the walls: a faint frame
        for k in range(self.n_src):
            if (
                pix[0] >= self.src_lo[k][0] - 1
                and pix[0] <= self.src_hi[k][0] + 1
                and pix[1] >= self.src_lo[k][1] - 2
                and pix[1] <= self.src_hi[k][1] + 1
            ):
                t = (self.src_t[k] - self.look.t_lo[None]) / (self.look.t_hi[None] - self.look.t_lo[None])
                c = temperature_map(ti.math.clamp(t, 0.0, 1.0))
        return c

    @ti.kernel
    def _springs_2d(self):
        s = self.state.springs
        p = self.p
        canvas = self.canvas
        for k in range(s.span[None]):
            if s.alive[k]:
                a = ti.cast(p.x[s.i[k]], ti.f32) * self.px_per_unit + self.offset
                b = ti.cast(p.x[s.j[k]], ti.f32) * self.px_per_unit + self.offset
                if (a - b).norm() < 0.25 * ti.max(canvas.width, canvas.height):  # skip periodic wrap-arounds
                    x0, x1, y0, y1 = canvas.box(a, b, 0.5, a)
                    canvas.stamp_tiles(x0, x1, y0, y1)
                    for px in range(x0, x1 + 1):
                        for py in range(y0, y1 + 1):
                            d, _ = self.footprint.segment(ti.Vector([px + 0.5, py + 0.5]), a, b)
                            cov = SPRING_OPACITY * ti.math.clamp(1.0 - d, 0.0, 1.0)
                            if cov > 0.0:  # lines of one colour "over" each other: only the transmittance adds up
                                self.spring_log[px, py] += ti.log(1.0 - cov)

    @ti.kernel
    def _bin_2d(self):
        """Sort the particles into the strip bins (the wide bin: those drawn with atomics)."""
        p = self.p
        n = p.n[None]
        bins = self.strips
        bins.clear()
        self.model.loops.light()
        for i in range(n):
            tail, ctrl, head, r, _, _ = self.splat_shape(i)
            x0, x1, _, _ = self.canvas.box(tail, head, r, ctrl)
            s = bins.strip_for(x0, x1, head[0])
            if self.look.g_blend[p.group[i]] == BLEND["additive"] or not ti.static(self.strip_splat):
                s = bins.wide
            bins.put(i, s)
        bins.finish(n)

    @ti.kernel
    def _splat_pass_2d(self, splat_pass: ti.i32):
        """Pass 0 or 1: draw the even or the odd strips' particles with plain adds, a strip per iteration; pass 2:
        the wide bin's, a particle per iteration, with atomic adds. One kernel for the three passes compiles the
        drawing code once (three inlined copies were 60% of the renderer's compile time)."""
        bins = self.strips
        iterations = bins.pass_iterations
        if splat_pass == 2:
            iterations = bins.count[bins.wide]
        for u in range(iterations):
            first, end = 0, 0  # the range of bins.ids this iteration draws
            if splat_pass < 2:
                s = bins.strip_at(u, splat_pass)
                if s >= 0:
                    first, end = bins.start[s], bins.start[s] + bins.count[s]
            else:
                first = bins.start[bins.wide] + u
                end = first + 1
            for k in range(first, end):
                self._splat_one(bins.ids[k], splat_pass < 2)

    @ti.func
    def splat_shape(self, i):
        """(tail, control point, head) of particle i's streak in pixels (all at the head when it is not blurred),
        its drawn radius r >= R_MIN and true radius in pixels, and whether it is blurred."""
        fp = self.footprint
        head = ti.cast(self.p.x[i], ti.f32) * self.px_per_unit + self.offset
        tail, ctrl = head, head
        blurred = False
        if ti.static(fp.motion_blur):
            prev = fp.x_prev[i] * self.px_per_unit + self.offset
            mid = 0.5 * (prev + head)
            if ti.static(fp.spline):
                mid = fp.x_mid[i] * self.px_per_unit + self.offset
            tail, ctrl, head = fp.streak(prev, mid, head)
            span = ti.max((tail - head).norm(), (mid - head).norm())
            blurred = (tail - head).norm() > 1e-3 and span < 0.5 * self.canvas.width  # not a periodic wrap
            blurred = blurred and fp.has_tail(i)
            if not blurred:
                tail, ctrl = head, head
        r_true = self.look.drawn_radius(i) * self.px_per_unit
        if self.look.g_draw[self.p.group[i]] == 0:  # a dot: one pixel
            r_true = 0.5
        return tail, ctrl, head, ti.max(r_true, R_MIN), r_true, blurred

    @ti.func
    def _splat_one(self, i, plain):
        """Add particle i's coverage to the layers: by plain load and store when `plain` (no other thread draws
        near it), else by atomic adds."""
        canvas = self.canvas
        tail, ctrl, head, r, r_true, blurred = self.splat_shape(i)
        g = self.p.group[i]
        blend, opacity = self.look.g_blend[g], self.look.opacity(i)
        fade = ti.max((r_true / r) ** 2, MIN_FADE)
        col = self.look.color(i)
        if blend == 2:
            if ti.static(canvas.has_additive):
                energy = opacity * math.pi * r_true * r_true
                self.footprint.deposit_light(tail, ctrl, head, r, energy, col, blurred, False, 0.0)
        else:
            x0, x1, y0, y1 = canvas.box(tail, head, r, ctrl)
            canvas.stamp_tiles(x0, x1, y0, y1)
            for px in range(x0, x1 + 1):
                for py in range(y0, y1 + 1):
                    w = fade * self.footprint.weight(ti.Vector([px + 0.5, py + 0.5]), tail, ctrl, head, r, blurred)
                    if w > 0.0:
                        if blend == 0:
                            _add(canvas.accum, px, py, w * col, plain)
                            _add(canvas.weight, px, py, w, plain)
                        else:
                            if ti.static(canvas.has_alpha):
                                a = ti.min(w * opacity, 0.999)
                                _add(canvas.a_accum, px, py, a * col, plain)
                                _add(canvas.a_weight, px, py, a, plain)
                                _add(canvas.a_log, px, py, ti.log(1.0 - a), plain)

    @ti.kernel
    def composite(self, full: ti.i32, out: ti.types.ndarray()):
        """Composite the dirty tiles (every tile when `full`) into the image or the 8-bit `out`."""
        canvas = self.canvas
        stamp = canvas.stamp[None]
        for tx, ty in canvas.tile_stamp:
            dirty = canvas.tile_stamp[tx, ty] >= stamp - 1 or full != 0
            for k in range(canvas.n_overlay[None]):
                o = canvas.overlay[k]
                if tx >= o[0] and tx <= o[1] and ty >= o[2] and ty <= o[3]:
                    dirty = True
            if dirty:
                canvas.dirty[ti.atomic_add(canvas.n_dirty[None], 1)] = tx + ty * canvas.tiles_x
        # A tile row per iteration: faster than a pixel per iteration, and enough iterations for every thread
        # (Taichi's CPU loops hand out blocks of hundreds of iterations: a loop over tiles would run on one thread)
        for m in range(canvas.n_dirty[None] * TILE):
            tile = canvas.dirty[m // TILE]
            x0, y = tile % canvas.tiles_x * TILE, tile // canvas.tiles_x * TILE + m % TILE
            if y < canvas.height:
                for i in range(ti.min(TILE, canvas.width - x0)):
                    self._resolve_pixel(x0 + i, y, out)
        canvas.n_dirty[None] = 0
        canvas.stamp[None] = stamp + 1

    @ti.func
    def _resolve_pixel(self, x, y, out: ti.template()):
        """Composite pixel (x, y) over the backdrop, zero its layers, write it to the float image (when kept) and
        to the 8-bit picture."""
        canvas = self.canvas
        c = self.backdrop[x, y]
        if ti.static(self.has_lid):
            c = self._lid(x, y, c)
        if ti.static(self.draw_springs):
            log_t = self.spring_log[x, y]
            if log_t < 0.0:
                t = ti.exp(log_t)
                c = c * t + ti.Vector(SPRING_COLOR) * (1.0 - t)
                self.spring_log[x, y] = 0.0
        w = canvas.weight[x, y]
        if w > 0.0:
            a = ti.min(w, 1.0)
            c = c * (1.0 - a) + canvas.accum[x, y] / w * a
            canvas.accum[x, y] = ti.Vector([0.0, 0.0, 0.0])
            canvas.weight[x, y] = 0.0
        if ti.static(canvas.has_alpha):
            c = canvas.over_translucent(x, y, c)
        if ti.static(canvas.has_additive):
            c += 1.0 - ti.exp(-canvas.exposure * canvas.light[x, y])
            canvas.light[x, y] = ti.Vector([0.0, 0.0, 0.0])
        c = ti.min(c, 1.0)
        if ti.static(canvas.keep_image):
            canvas.image[x, y] = c  # the window shows it; picture() packs it to 8 bits only when asked
        else:
            canvas.put_out(out, x, y, c)

    @ti.func
    def _lid(self, x, y, c):
        """Pixel (x, y) of the lid: its underside a light line at its height across the box, the box above it
        tinted (the weight that presses on the atoms)."""
        under = self.offset[1] + self.px_per_unit * ti.cast(at(self.lid.height, 0), ti.f32)
        py = y + 0.5
        if x + 0.5 >= self.px_lo[0] and x + 0.5 <= self.px_hi[0] and py >= under and py <= self.px_hi[1]:
            c = c * 0.85 + 0.1
            if py <= under + 2.0:
                c = ti.Vector(LID_COLOR)
        return c

    @ti.kernel
    def ring(self, cx: ti.f32, cy: ti.f32, r: ti.f32, out: ti.types.ndarray()):
        """A tool's brush outline, anti-aliased, over the composited picture. Its tiles are stamped with this frame's
        number (compositing has moved the count on), so the next frame composites them again and wipes it."""
        canvas = self.canvas
        x0 = ti.max(ti.cast(ti.floor(cx - r - 2.0), ti.i32), 0)
        x1 = ti.min(ti.cast(ti.ceil(cx + r + 2.0), ti.i32), canvas.width - 1)
        y0 = ti.max(ti.cast(ti.floor(cy - r - 2.0), ti.i32), 0)
        y1 = ti.min(ti.cast(ti.ceil(cy + r + 2.0), ti.i32), canvas.height - 1)
        if x0 <= x1 and y0 <= y1:
            canvas.stamp_tiles_as(x0, x1, y0, y1, canvas.stamp[None] - 1)
        for px, py in ti.ndrange((x0, x1 + 1), (y0, y1 + 1)):
            d = ti.abs((ti.Vector([px + 0.5 - cx, py + 0.5 - cy])).norm() - r)
            a = BRUSH_OPACITY * ti.math.clamp(1.25 - d, 0.0, 1.0)
            if a > 0.0:
                if ti.static(canvas.keep_image):
                    canvas.image[px, py] = canvas.image[px, py] * (1.0 - a) + ti.Vector(BRUSH_COLOR) * a
                else:
                    behind = get_pixel(out, canvas.height, px, py)
                    put_pixel(out, canvas.height, px, py, behind * (1.0 - a) + ti.Vector(BRUSH_COLOR) * a)
