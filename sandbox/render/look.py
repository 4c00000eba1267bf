"""How a particle looks and what it covers: colour by temperature, speed or phase, fading and shrinking over a
lifetime, the motion-blur streak's geometry, pixel coverage and the light an additive particle deposits. A mixin of
Renderer (raster.py), shared by the 2D and 3D passes."""

import taichi as ti

from .colormaps import glow_over_base, speed_map
from .style import BLEND, SPLINE_SEGMENTS, TILE


class ParticleLook:
    """Renderer's per-particle colour, size and coverage functions (Taichi funcs)."""

    # ------------------------------------------------------------------ shared funcs
    @ti.func
    def life_left(self, i):
        """1 at birth falling to 0 at death for particles with a lifetime, else 1."""
        left = 1.0
        if ti.static(self.has_lifetimes):
            life = self.p.lifetime[i]
            if life > 0.0:
                left = ti.max(1.0 - self.p.age[i] / life, 0.0)
        return left

    @ti.func
    def drawn_radius(self, i):
        """Drawn radius (length): the particle's radius times render.particle_scale, shrinking with age if asked."""
        r = self.p.radius[i] * self.particle_scale
        if ti.static(self.has_lifetimes):
            if self.g_shrink[self.p.group[i]]:
                r *= self.life_left(i)
        return r

    @ti.func
    def particle_color(self, i):
        """Drawing colour: the colour map's, darkened over the lifetime when fading (not for alpha: see below)."""
        c = self._base_color(i)
        if ti.static(self.has_lifetimes):
            g = self.p.group[i]
            if self.g_fade[g] and self.g_blend[g] != BLEND["alpha"]:
                c *= self.life_left(i)
        return c

    @ti.func
    def group_opacity(self, i):
        """Opacity of particle i's group; a fading translucent particle grows fainter rather than darker."""
        g = self.p.group[i]
        a = self.g_opacity[g]
        if ti.static(self.has_lifetimes):
            if self.g_fade[g] and self.g_blend[g] == BLEND["alpha"]:
                a *= self.life_left(i)
        return a

    @ti.func
    def _base_color(self, i):
        p = self.p
        base = p.color[i]
        c = base
        if ti.static(self.color_mode == 0 and self.has_heat):
            t = (p.T[i] - self.t_lo[None]) / (self.t_hi[None] - self.t_lo[None])
            c = glow_over_base(base, t)
        elif ti.static(self.color_mode == 2):
            c = speed_map(p.v[i].norm() / self.speed_hi[None])
        elif ti.static(self.color_mode == 3 and self.has_heat):
            phi = self.model.phase.fraction(p.h[i], p.material[i])
            c = (1.0 - phi) * base + phi * self.model.materials.liquid_color[p.material[i]]
        return c

    @ti.func
    def _segment(self, pix, a, b):
        """(distance from pixel centre pix to segment a-b, parameter t in [0, 1] of the nearest point; t = 1 at b)."""
        ab = b - a
        l2 = ab.dot(ab)
        t = 1.0
        if l2 > 1e-12:
            t = ti.math.clamp((pix - a).dot(ab) / l2, 0.0, 1.0)
        return (pix - (a + t * ab)).norm(), t

    @ti.func
    def _curve(self, pix, a, c, b):
        """(distance from pix to the quadratic Bezier a-c-b, its parameter there), on SPLINE_SEGMENTS chords."""
        best = 1e30
        t_best = 1.0
        start = a
        for k in ti.static(range(1, SPLINE_SEGMENTS + 1)):
            t = k / SPLINE_SEGMENTS
            end = (1.0 - t) ** 2 * a + 2.0 * (1.0 - t) * t * c + t * t * b
            d, s = self._segment(pix, start, end)
            if d < best:
                best = d
                t_best = (k - 1 + s) / SPLINE_SEGMENTS
            start = end
        return best, t_best

    @ti.func
    def _streak(self, prev, mid, head):
        """(tail, control point, head) in pixels of the streak of a particle that went prev -> mid -> head over the
        frame: the last `shutter` of the straight segment, or of the quadratic through the three (spline)."""
        tail = head + self.shutter * (prev - head)
        ctrl = 0.5 * (tail + head)
        if ti.static(self.spline):
            t0 = 1.0 - self.shutter
            c = 2.0 * mid - 0.5 * (prev + head)  # the quadratic's control point: it passes through mid at t = 1/2
            tail = (1.0 - t0) ** 2 * prev + 2.0 * (1.0 - t0) * t0 * c + t0 * t0 * head
            ctrl = (1.0 - t0) * c + t0 * head  # de Casteljau: the control point of the piece from t0 to 1
        return tail, ctrl, head

    @ti.func
    def _weight(self, pix, a, c, b, r, blurred):
        """Coverage of pixel pix by the capsule of radius r (pixels) around the streak a-b (curved through control
        point c with spline motion blur), times the fall-off along a streak."""
        w, _ = self._coverage(pix, a, c, b, r, blurred)
        return w

    @ti.func
    def _coverage(self, pix, a, c, b, r, blurred):
        """(_weight, the parameter along the streak of the nearest point: 0 at the tail a, 1 at the head b)."""
        d, t = 0.0, 0.0
        if ti.static(self.spline):
            if blurred:
                d, t = self._curve(pix, a, c, b)
            else:
                d, t = self._segment(pix, a, b)
        else:
            d, t = self._segment(pix, a, b)
        w = ti.math.clamp(r + 0.5 - d, 0.0, 1.0)
        if blurred:
            w *= 0.25 + 0.75 * t
        return w, t

    @ti.func
    def _box(self, a, b, r, c):
        """Pixel bounds of the capsule around a-b (and control point c, which bounds a curve with the ends): every
        pixel whose centre lies within r + 0.5 of it (where the coverage clamp(r + 0.5 - d, 0, 1) is not zero), as
        pixel px's centre is px + 0.5."""
        lo = ti.min(ti.min(a, b), c)
        hi = ti.max(ti.max(a, b), c)
        x0 = ti.max(ti.cast(ti.ceil(lo[0] - r - 1), ti.i32), 0)
        x1 = ti.min(ti.cast(ti.floor(hi[0] + r), ti.i32), self.width - 1)
        y0 = ti.max(ti.cast(ti.ceil(lo[1] - r - 1), ti.i32), 0)
        y1 = ti.min(ti.cast(ti.floor(hi[1] + r), ti.i32), self.height - 1)
        return x0, x1, y0, y1

    @ti.func
    def _stamp_tiles(self, x0, x1, y0, y1):
        """2D: mark the tiles of pixel box [x0, x1] x [y0, y1] as drawn in this frame."""
        self._stamp_tiles_as(x0, x1, y0, y1, self.stamp[None])

    @ti.func
    def _stamp_tiles_as(self, x0, x1, y0, y1, stamp):
        """2D: mark the tiles of pixel box [x0, x1] x [y0, y1] as drawn in frame number `stamp`."""
        if ti.static(self.dim == 2):
            for tx in range(x0 // TILE, x1 // TILE + 1):
                for ty in range(y0 // TILE, y1 // TILE + 1):
                    self.tile_stamp[tx, ty] = stamp

    @ti.func
    def _deposit_light(self, a, c, b, r, energy, col, blurred, use_depth, z):
        """Spread `energy` of colour col over the capsule's footprint with normalised weights (depth-tested in 3D)."""
        x0, x1, y0, y1 = self._box(a, b, r, c)
        self._stamp_tiles(x0, x1, y0, y1)
        total = 0.0
        for px in range(x0, x1 + 1):
            for py in range(y0, y1 + 1):
                total += self._weight(ti.Vector([px + 0.5, py + 0.5]), a, c, b, r, blurred)
        if total > 0.0:
            zbits = ti.bit_cast(ti.cast(ti.max(z, 0.0), ti.f32), ti.i32)
            for px in range(x0, x1 + 1):
                for py in range(y0, y1 + 1):
                    w = self._weight(ti.Vector([px + 0.5, py + 0.5]), a, c, b, r, blurred)
                    visible = True
                    if use_depth:
                        visible = zbits <= self.depth[px, py]
                    if w > 0.0 and visible:
                        self.light[px, py] += energy * w / total * col
