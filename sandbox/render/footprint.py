"""What a particle covers in the picture: its motion-blur streak and the coverage of each pixel, and the light an
additive particle deposits.

A particle is a segment from where it was a shutter ago to where it is (a point when still, or without motion blur),
curved through where it was at the frame's middle with `motion_path = "spline"`; a pixel's coverage is
clamp(R + 0.5 - d, 0, 1) for its distance d to the segment, R the radius in pixels. Additive particles deposit an
energy of opacity * pi R^2 (in pixel units), spread over their footprint by normalised weights: a sub-pixel spark
deposits its full intensity wherever it falls, and a streak deposits the same energy as the still particle,
brighter towards its head.

The tails (positions a frame ago, and at its middle) are per-particle fields that must move with the particles when
the state sorts or compacts them: whoever pairs a renderer with a state attaches them (`state.carry(tails)`).
"""

import taichi as ti

from ..core.oriented import data_oriented
from .style import SPLINE_SEGMENTS


@data_oriented
class Footprint:
    """Motion-blur tails and coverage for particles of `particles` drawn on `canvas`, with the [render] settings
    `cfg` (motion_blur, shutter, motion_path)."""

    def __init__(self, canvas, particles, cfg, capacity: int, dim: int):
        self.canvas, self.p = canvas, particles
        self.motion_blur = bool(cfg.motion_blur)
        self.spline = self.motion_blur and cfg.motion_path == "spline"
        self.shutter = float(cfg.shutter) if self.motion_blur else 0.0
        self.tails = []  # per-particle drawing state that moves with the particles
        if self.motion_blur:
            self.x_prev = ti.Vector.field(dim, ti.f32, shape=capacity)  # positions a frame ago
            # ... and the id of the particle each was: a particle born since (an emitter's, into a slot whose tail
            # is another's or none) has no tail yet, and is drawn still (its stale tail drew a streak from where a
            # dead spark had been, or from the corner: up to half the picture long, and costly to draw)
            self.id_prev = ti.field(ti.i32, shape=capacity)
            self.id_prev.fill(-1)
            self.tails += [self.x_prev, self.id_prev]
        if self.spline:
            self.x_mid = ti.Vector.field(dim, ti.f32, shape=capacity)  # positions at the frame's middle
            self.tails.append(self.x_mid)
        self.mid_captured = False

    def begin_frame(self) -> None:
        """Remember positions before the simulation advances a frame (the tails of motion-blur streaks)."""
        if self.motion_blur:
            self._remember(self.x_prev, True)
            self.mid_captured = False

    def mid_frame(self) -> None:
        """Remember positions half-way through the frame's substeps (the bend of spline streaks)."""
        if self.spline:
            self._remember(self.x_mid, False)
            self.mid_captured = True

    def before_drawing(self) -> None:
        """No middle position this frame (a single step, a paused window): draw spline streaks straight."""
        if self.spline and not self.mid_captured:
            self._straight_mids()
            self.mid_captured = True

    @ti.kernel
    def _remember(self, into: ti.template(), ids: ti.template()):
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            into[i] = ti.cast(self.p.x[i], ti.f32)
            if ti.static(ids):
                self.id_prev[i] = self.p.ident[i]

    @ti.func
    def has_tail(self, i):
        """Whether particle i was where its tail is a frame ago (it is not one born since)."""
        return self.id_prev[i] == self.p.ident[i]

    @ti.kernel
    def _straight_mids(self):
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            self.x_mid[i] = 0.5 * (self.x_prev[i] + ti.cast(self.p.x[i], ti.f32))

    @ti.func
    def segment(self, pix, a, b):
        """(distance from pixel centre pix to segment a-b, parameter t in [0, 1] of the nearest point; t = 1 at b)."""
        ab = b - a
        l2 = ab.dot(ab)
        t = 1.0
        if l2 > 1e-12:
            t = ti.math.clamp((pix - a).dot(ab) / l2, 0.0, 1.0)
        return (pix - (a + t * ab)).norm(), t

    @ti.func
    def curve(self, pix, a, c, b):
        """(distance from pix to the quadratic Bezier a-c-b, its parameter there), on SPLINE_SEGMENTS chords."""
        best = 1e30
        t_best = 1.0
        start = a
        for k in ti.static(range(1, SPLINE_SEGMENTS + 1)):
            t = k / SPLINE_SEGMENTS
            end = (1.0 - t) ** 2 * a + 2.0 * (1.0 - t) * t * c + t * t * b
            d, s = self.segment(pix, start, end)
            if d < best:
                best = d
                t_best = (k - 1 + s) / SPLINE_SEGMENTS
            start = end
        return best, t_best

    @ti.func
    def streak(self, prev, mid, head):
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
    def weight(self, pix, a, c, b, r, blurred):
        """Coverage of pixel pix by the capsule of radius r (pixels) around the streak a-b (curved through control
        point c with spline motion blur), times the fall-off along a streak."""
        w, _ = self.coverage(pix, a, c, b, r, blurred)
        return w

    @ti.func
    def coverage(self, pix, a, c, b, r, blurred):
        """(weight, the parameter along the streak of the nearest point: 0 at the tail a, 1 at the head b)."""
        d, t = 0.0, 0.0
        if ti.static(self.spline):
            if blurred:
                d, t = self.curve(pix, a, c, b)
            else:
                d, t = self.segment(pix, a, b)
        else:
            d, t = self.segment(pix, a, b)
        w = ti.math.clamp(r + 0.5 - d, 0.0, 1.0)
        if blurred:
            w *= 0.25 + 0.75 * t
        return w, t

    @ti.func
    def deposit_light(self, a, c, b, r, energy, col, blurred, use_depth, z):
        """Spread `energy` of colour col over the capsule's footprint with normalised weights (depth-tested in 3D)."""
        canvas = self.canvas
        x0, x1, y0, y1 = canvas.box(a, b, r, c)
        canvas.stamp_tiles(x0, x1, y0, y1)
        total = 0.0
        for px in range(x0, x1 + 1):
            for py in range(y0, y1 + 1):
                total += self.weight(ti.Vector([px + 0.5, py + 0.5]), a, c, b, r, blurred)
        if total > 0.0:
            zbits = ti.bit_cast(ti.cast(ti.max(z, 0.0), ti.f32), ti.i32)
            for px in range(x0, x1 + 1):
                for py in range(y0, y1 + 1):
                    w = self.weight(ti.Vector([px + 0.5, py + 0.5]), a, c, b, r, blurred)
                    visible = True
                    if use_depth:
                        visible = zbits <= canvas.depth[px, py]
                    if w > 0.0 and visible:
                        canvas.light[px, py] += energy * w / total * col
