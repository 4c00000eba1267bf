"""2D drawing: the backdrop (domain, walls, heat sources), springs, particle splats (strip by strip without atomics,
or atomically), and the compositing pass that resolves the layers into the picture tile by tile. A mixin of Renderer."""

import math

import taichi as ti

from .colormaps import glow
from .style import BLEND, MIN_FADE, R_MIN, SPRING_COLOR, SPRING_OPACITY, TILE, _add


class Flat2D:
    """Renderer's 2D passes."""

    # ------------------------------------------------------------------ 2D
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
            c = self.background * 2.2 + 0.04  # the walls: a faint frame
        for k in range(self.n_src):
            if (
                pix[0] >= self.src_lo[k][0] - 1
                and pix[0] <= self.src_hi[k][0] + 1
                and pix[1] >= self.src_lo[k][1] - 2
                and pix[1] <= self.src_hi[k][1] + 1
            ):
                t = (self.src_t[k] - self.t_lo[None]) / (self.t_hi[None] - self.t_lo[None])
                c = glow(ti.max(t, 0.35)) if t > 0.05 else ti.Vector([0.3, 0.55, 1.0])
        return c

    @ti.kernel
    def _springs_2d(self):
        s = self.state.springs
        p = self.p
        for k in range(s.span[None]):
            if s.alive[k]:
                a = ti.cast(p.x[s.i[k]], ti.f32) * self.px_per_unit + self.offset
                b = ti.cast(p.x[s.j[k]], ti.f32) * self.px_per_unit + self.offset
                if (a - b).norm() < 0.25 * ti.max(self.width, self.height):  # skip periodic wrap-arounds
                    x0, x1, y0, y1 = self._box(a, b, 0.5, a)
                    self._stamp_tiles(x0, x1, y0, y1)
                    for px in range(x0, x1 + 1):
                        for py in range(y0, y1 + 1):
                            d, _ = self._segment(ti.Vector([px + 0.5, py + 0.5]), a, b)
                            cov = SPRING_OPACITY * ti.math.clamp(1.0 - d, 0.0, 1.0)
                            if cov > 0.0:  # lines of one colour "over" each other: only the transmittance adds up
                                self.spring_log[px, py] += ti.log(1.0 - cov)

    def _splat_2d(self) -> None:
        """Bin the particles by screen strip, draw the even strips, then the odd ones, with plain adds (see
        strips.py), then the particles that reach beyond their strip, with atomic adds."""
        self._bin_2d()
        for splat_pass in (0, 1, 2) if self.strip_splat else (2,):
            self._splat_pass_2d(splat_pass)

    @ti.kernel
    def _bin_2d(self):
        """Sort the particles into the strip bins (the wide bin: those drawn with atomics)."""
        p = self.p
        n = p.n[None]
        bins = self.strips
        bins.clear()
        self.model.loops.light()
        for i in range(n):
            tail, ctrl, head, r, _, _ = self._splat_shape(i)
            x0, x1, _, _ = self._box(tail, head, r, ctrl)
            s = bins.strip_for(x0, x1, head[0])
            if self.g_blend[p.group[i]] == BLEND["additive"] or not ti.static(self.strip_splat):
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
    def _splat_shape(self, i):
        """(tail, control point, head) of particle i's streak in pixels (all at the head when it is not blurred),
        its drawn radius r >= R_MIN and true radius in pixels, and whether it is blurred."""
        head = ti.cast(self.p.x[i], ti.f32) * self.px_per_unit + self.offset
        tail, ctrl = head, head
        blurred = False
        if ti.static(self.motion_blur):
            prev = self.x_prev[i] * self.px_per_unit + self.offset
            mid = 0.5 * (prev + head)
            if ti.static(self.spline):
                mid = self.x_mid[i] * self.px_per_unit + self.offset
            tail, ctrl, head = self._streak(prev, mid, head)
            span = ti.max((tail - head).norm(), (mid - head).norm())
            blurred = (tail - head).norm() > 1e-3 and span < 0.5 * self.width  # not a periodic wrap
            if not blurred:
                tail, ctrl = head, head
        r_true = self.drawn_radius(i) * self.px_per_unit
        if self.g_draw[self.p.group[i]] == 0:  # a dot: one pixel
            r_true = 0.5
        return tail, ctrl, head, ti.max(r_true, R_MIN), r_true, blurred

    @ti.func
    def _splat_one(self, i, plain):
        """Add particle i's coverage to the layers: by plain load and store when `plain` (no other thread draws
        near it), else by atomic adds."""
        tail, ctrl, head, r, r_true, blurred = self._splat_shape(i)
        g = self.p.group[i]
        blend, opacity = self.g_blend[g], self.group_opacity(i)
        fade = ti.max((r_true / r) ** 2, MIN_FADE)
        col = self.particle_color(i)
        if blend == 2:
            if ti.static(self.has_additive):
                energy = opacity * math.pi * r_true * r_true
                self._deposit_light(tail, ctrl, head, r, energy, col, blurred, False, 0.0)
        else:
            x0, x1, y0, y1 = self._box(tail, head, r, ctrl)
            self._stamp_tiles(x0, x1, y0, y1)
            for px in range(x0, x1 + 1):
                for py in range(y0, y1 + 1):
                    w = fade * self._weight(ti.Vector([px + 0.5, py + 0.5]), tail, ctrl, head, r, blurred)
                    if w > 0.0:
                        if blend == 0:
                            _add(self.accum, px, py, w * col, plain)
                            _add(self.weight, px, py, w, plain)
                        else:
                            if ti.static(self.has_alpha):
                                a = ti.min(w * opacity, 0.999)
                                _add(self.a_accum, px, py, a * col, plain)
                                _add(self.a_weight, px, py, a, plain)
                                _add(self.a_log, px, py, ti.log(1.0 - a), plain)

    @ti.kernel
    def _resolve_2d(self, full: ti.i32, out: ti.types.ndarray()):
        stamp = self.stamp[None]
        for tx, ty in self.tile_stamp:
            dirty = self.tile_stamp[tx, ty] >= stamp - 1 or full != 0
            for k in range(self.n_overlay[None]):
                o = self.overlay[k]
                if tx >= o[0] and tx <= o[1] and ty >= o[2] and ty <= o[3]:
                    dirty = True
            if dirty:
                self.dirty[ti.atomic_add(self.n_dirty[None], 1)] = tx + ty * self.tiles_x
        # A tile row per iteration: 2x faster than a pixel per iteration, and enough iterations for every thread
        # (Taichi's CPU loops hand out blocks of hundreds of iterations: a loop over tiles would run on one thread)
        for m in range(self.n_dirty[None] * TILE):
            tile = self.dirty[m // TILE]
            x0, y = tile % self.tiles_x * TILE, tile // self.tiles_x * TILE + m % TILE
            if y < self.height:
                for i in range(ti.min(TILE, self.width - x0)):
                    self._resolve_pixel(x0 + i, y, out)
        self.n_dirty[None] = 0
        self.stamp[None] = stamp + 1

    @ti.func
    def _resolve_pixel(self, x, y, out: ti.template()):
        """Composite pixel (x, y) over the backdrop, zero its layers, write it to the float image (when kept) and
        to the 8-bit picture."""
        c = self.backdrop[x, y]
        if ti.static(self.draw_springs):
            log_t = self.spring_log[x, y]
            if log_t < 0.0:
                t = ti.exp(log_t)
                c = c * t + ti.Vector(SPRING_COLOR) * (1.0 - t)
                self.spring_log[x, y] = 0.0
        w = self.weight[x, y]
        if w > 0.0:
            a = ti.min(w, 1.0)
            c = c * (1.0 - a) + self.accum[x, y] / w * a
            self.accum[x, y] = ti.Vector([0.0, 0.0, 0.0])
            self.weight[x, y] = 0.0
        if ti.static(self.has_alpha):
            c = self._over_translucent(x, y, c)
        if ti.static(self.has_additive):
            c += 1.0 - ti.exp(-self.exposure * self.light[x, y])
            self.light[x, y] = ti.Vector([0.0, 0.0, 0.0])
        c = ti.min(c, 1.0)
        if ti.static(self.keep_image):
            self.image[x, y] = c  # the window shows it; picture() packs it to 8 bits only when asked
        else:
            self._put_out(out, x, y, c)
