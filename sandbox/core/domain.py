"""The domain box: minimum-image separations and walls (restitution and Coulomb friction) or periodic wrapping."""

import math

import taichi as ti

from . import transfer
from .oriented import data_oriented
from .worlds import add_at, per_world


@data_oriented
class Domain:
    """Box lo..hi. Walls push a particle back to one radius from the wall; periodic boxes wrap positions."""

    def __init__(self, lo, hi, periodic: bool, restitution: float, friction: float, worlds: int = 1):
        self.dim = len(lo)
        self.periodic = periodic
        self.lo = ti.Vector(list(lo))
        self.hi = ti.Vector(list(hi))
        self.box = ti.Vector([h - l for l, h in zip(lo, hi)])
        self.inv_box = ti.Vector([1.0 / (h - l) for l, h in zip(lo, hi)])
        self.restitution = ti.field(float, shape=())  # normal speed kept after a wall hit, in [0, 1]
        self.friction = ti.field(float, shape=())  # Coulomb coefficient: tangential impulse <= mu * normal impulse
        transfer.upload([(self.restitution, restitution), (self.friction, friction)])  # in the build's one copy
        # momentum the walls have taken (sum of m (1 + e) |v_n| over hits) since the gauge was last zeroed, per world
        self.impulse = per_world(worlds, float)
        self.wall_area = self._wall_area(lo, hi) if not periodic else 0.0

    @staticmethod
    def _wall_area(lo, hi) -> float:
        """Total area of the box's walls (their length in 2D)."""
        sides = [h - l for l, h in zip(lo, hi)]
        return 2.0 * sum(math.prod(sides[:a] + sides[a + 1 :]) for a in range(len(sides)))  # two walls per axis

    @ti.func
    def separation(self, xi, xj):
        """xj - xi, by the minimum-image convention in a periodic box, for positions at most half a box outside it
        (they are wrapped at every step's end; an integrator's stage moves them by far less)."""
        d = xj - xi
        if ti.static(self.periodic):
            # Compare and shift rather than round(d / box): a rounding per pair is dear in the pair pass. One
            # test first for all axes: almost every pair lies well inside the box.
            far = False
            for a in ti.static(range(self.dim)):
                far = far or ti.abs(d[a]) > 0.5 * self.box[a]
            if far:
                for a in ti.static(range(self.dim)):
                    if d[a] > 0.5 * self.box[a]:
                        d[a] -= self.box[a]
                    elif d[a] < -0.5 * self.box[a]:
                        d[a] += self.box[a]
        return d

    @ti.func
    def inside_by(self, x, margin):
        """Whether x lies farther than `margin` from every face of the box: then a particle within `margin` of it is
        met without crossing a periodic seam, and x_j - x is already the minimum image."""
        inside = True
        for a in ti.static(range(self.dim)):
            inside = inside and x[a] - self.lo[a] > margin and self.hi[a] - x[a] > margin
        return inside

    @ti.func
    def enforce(self, x, v, radius, mass, w):
        """Position and velocity after the walls (or the periodic wrap) act on a particle of the given radius in world
        w; a hit adds its momentum, mass times the normal velocity change, to that world's gauge (mass 0: not
        counted, whatever w)."""
        if ti.static(self.periodic):
            x -= self.box * ti.floor((x - self.lo) / self.box)
        else:
            e, mu = self.restitution[None], self.friction[None]
            for a in ti.static(range(self.dim)):
                lo = self.lo[a] + radius
                hi = self.hi[a] - radius
                sign = 0.0
                if x[a] < lo:
                    x[a] = lo
                    sign = 1.0
                elif x[a] > hi:
                    x[a] = hi
                    sign = -1.0
                vn = v[a] * sign  # negative: moving into the wall
                if sign != 0.0 and vn < 0.0:
                    impulse = -(1.0 + e) * vn
                    v[a] = -e * v[a]
                    if mass > 0.0:
                        add_at(self.impulse, w, mass * impulse)
                    vt2 = 0.0
                    for b in ti.static(range(self.dim)):
                        if b != a:
                            vt2 += v[b] * v[b]
                    if vt2 > 0.0:
                        scale = ti.max(0.0, 1.0 - mu * impulse / ti.sqrt(vt2))
                        for b in ti.static(range(self.dim)):
                            if b != a:
                                v[b] *= scale
        return x, v
