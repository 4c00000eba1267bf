"""Velocity fields v(x, t): a sum of designed elements and curl noise, for particles carried by (or dragged towards)
the flow rather than pushed by forces.

Elements (scene [[fields]], each `kind` with its keys; r is the distance from `center`, from the `axis` line in 3D):

    wind       v = velocity
    vortex     v = strength / (2 pi r) (1 - exp(-r^2 / radius^2)) exp(-r^2 / falloff^2) around the axis (Lamb-Oseen
               core of `radius`; `falloff` 0 = none); strength is the circulation, counter-clockwise seen from +axis
    source     v = strength / (2 pi r) (1 - exp(-r^2 / radius^2)) outward in 2D, strength / (4 pi r^2) (...) in 3D:
               strength is the volume rate (negative: a sink)
    explosion  v = strength exp(-(t - time) / decay) (1 - exp(-r^2 / radius^2)) outward, for t >= time
    noise      v = curl of a gradient-noise potential of length `scale` and speed `strength`, drifting in noise
               space at `speed` per second: divergence-free, so it swirls without clumping or thinning

With a [smoke] table the smoke grid's velocity (physics/smoke.py) is added to the sum.

Curl noise: in 2D v = (d psi/dy, -d psi/dx) for a scalar potential psi; in 3D v = curl of a vector potential of three
independent noise channels. The derivatives are central differences of step scale/100, whose discrete divergence
vanishes exactly; measured with other steps it is small (tested).
"""

import math

import numpy as np
import taichi as ti

from ..config.scene_tables import COUPLINGS
from ..core import transfer
from ..core.oriented import data_oriented
from .term import Term, register

FIELD_KINDS = ("wind", "vortex", "source", "explosion", "noise")
WIND, VORTEX, SOURCE, EXPLOSION, NOISE = range(5)
NO_COUPLING, KINEMATIC = (COUPLINGS.index(c) for c in ("none", "kinematic"))


@ti.func
def hash_u32(a: ti.u32) -> ti.u32:
    """A 32-bit integer hash (Wellons' lowbias32): well-mixed bits for lattice gradients and random numbers."""
    a ^= a >> 16
    a *= ti.u32(0x7FEB352D)
    a ^= a >> 15
    a *= ti.u32(0x846CA68B)
    a ^= a >> 16
    return a


@ti.func
def random_uniform(seed: ti.u32, index: ti.u32, k: ti.u32) -> ti.f32:
    """Deterministic uniform number in [0, 1) from (seed, index, k): the same whatever the thread schedule."""
    h = hash_u32(seed ^ hash_u32(index * ti.u32(0x9E3779B9) ^ hash_u32(k + ti.u32(0x632BE5AB))))
    return ti.cast(h >> 8, ti.f32) / 16777216.0


@ti.func
def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@ti.func
def _gradient(ix, iy, iz, seed: ti.u32):
    h = hash_u32(
        ti.cast(ix, ti.u32) * ti.u32(73856093)
        ^ hash_u32(ti.cast(iy, ti.u32) * ti.u32(19349663) ^ hash_u32(ti.cast(iz, ti.u32) * ti.u32(83492791) ^ seed))
    )
    # a direction on the unit sphere from two hashed numbers
    u = ti.cast(h & ti.u32(0xFFFF), ti.f32) / 65535.0 * 2.0 - 1.0
    phi = ti.cast(h >> 16, ti.f32) / 65535.0 * 2.0 * math.pi
    s = ti.sqrt(ti.max(1.0 - u * u, 0.0))
    return ti.Vector([s * ti.cos(phi), s * ti.sin(phi), u])


@ti.func
def gradient_noise(p, seed: ti.u32):
    """3D gradient (Perlin-style) noise of the point p (a 3-vector), about in [-1, 1], smooth (C2 fade)."""
    cell = ti.floor(p)
    f = p - cell
    ix, iy, iz = ti.cast(cell[0], ti.i32), ti.cast(cell[1], ti.i32), ti.cast(cell[2], ti.i32)
    s = ti.Vector([_fade(f[0]), _fade(f[1]), _fade(f[2])])
    total = 0.0
    for c in range(8):  # a run-time loop, not unrolled: the curl inlines this many times, and compile time adds up
        dx, dy, dz = c & 1, (c >> 1) & 1, (c >> 2) & 1
        g = _gradient(ix + dx, iy + dy, iz + dz, seed)
        d = f - ti.Vector([dx, dy, dz], dt=float)
        w = (s[0] if dx else 1.0 - s[0]) * (s[1] if dy else 1.0 - s[1]) * (s[2] if dz else 1.0 - s[2])
        total += w * g.dot(d)
    return total


@register
@data_oriented
class VelocityField(Term):
    """The scene's field elements as small parameter fields, velocity(x, t) as a Taichi func, and which groups
    follow it (kinematic) or are dragged toward it (drag): their velocity there, sampled at each step's start."""

    key = "fields"
    stage = "fields"  # built after the smoke grid, whose velocity it adds

    @staticmethod
    def wanted(parts) -> bool:
        return bool(parts.scene.fields or parts.scene.smoke)

    @staticmethod
    def host_work(scene) -> str | None:
        """Why this pass needs the host between `scene`'s steps (see the stepping plan), or None: particles coupled
        to the field (kinematic or drag) sample it at each step's start."""
        coupled = bool(scene.fields or scene.smoke) and any(g.field != "none" for g in scene.groups)
        return "particles follow a velocity field sampled at each step" if coupled else None

    def __init__(self, parts):
        smoke = parts.terms.get("smoke")
        self._build(parts.model.dim, parts.scene.fields, smoke.grid if smoke is not None else None)
        groups = parts.scene.groups
        couplings = [g.field for g in groups]
        self.has_kinematic = "kinematic" in couplings
        self.has_drag = "drag" in couplings
        self.p = parts.state.particles
        self.state = parts.state
        if self.p.gaps:  # each world's clock, as the particles sample the field
            self.world_time = ti.field(float, shape=self.p.world_count)
        # per group (every body, every emitter, then the spawn tool's particles):
        self.coupling = ti.field(ti.i32, shape=len(groups) + 1)  # index into COUPLINGS
        self.drag_rate = ti.field(float, shape=len(groups) + 1)  # field = drag: relaxation rate (1/time)
        transfer.upload(
            [
                (self.coupling, np.array([COUPLINGS.index(c) for c in couplings], np.int32)),
                (self.drag_rate, np.array([g.field_drag for g in groups], float)),
            ]
        )
        if self.has_kinematic or self.has_drag:
            self.v_field = ti.Vector.field(self.dim, float, shape=parts.model.capacity)  # v(x, t) at coupled particles

    def sample_at_particles(self, t: float) -> None:
        """v_field[i] = v(x_i, t) at every particle coupled to the field (kinematic or drag); t is the simulation's
        time, and with worlds each world's particles sample at its own clock's (t less the time it started)."""
        if self.p.gaps:
            self.world_time.from_numpy(np.array([t - start for start in self.state.world_started]))
        self._sample_particles(t)

    @ti.kernel
    def _sample_particles(self, t: float):
        p = self.p
        for i in range(p.n[None]):
            if p.idle(i):
                continue
            if self.coupling[p.group[i]] != NO_COUPLING:
                if ti.static(p.gaps):
                    w = p.world[i]
                    self.v_field[i] = self.velocity(p.x[i], self.world_time[w], w)
                else:
                    self.v_field[i] = self.velocity(p.x[i], t, 0)

    def _build(self, dim: int, elements: list, grid=None):
        """The element tables; `grid`: a SmokeGrid whose velocity is added to the elements' (None: elements only)."""
        self.dim = dim
        self.grid = grid
        self.has_grid = grid is not None
        self.count = len(elements)
        n = max(self.count, 1)
        self.kind = ti.field(ti.i32, shape=n)
        self.center = ti.Vector.field(dim, float, shape=n)
        self.axis = ti.Vector.field(3, float, shape=n)  # 3D vortex axis (unit)
        self.vector = ti.Vector.field(dim, float, shape=n)  # wind velocity
        self.strength = ti.field(float, shape=n)
        self.radius = ti.field(float, shape=n)
        self.falloff = ti.field(float, shape=n)
        self.time = ti.field(float, shape=n)
        self.decay = ti.field(float, shape=n)
        self.scale = ti.field(float, shape=n)
        self.speed = ti.field(float, shape=n)
        self.seed = ti.field(ti.u32, shape=n)
        axes = [np.asarray(e.axis if e.axis else (0.0, 0.0, 1.0), dtype=float) for e in elements]
        columns = [
            (self.kind, [FIELD_KINDS.index(e.kind) for e in elements]),
            (self.center, [list(e.center) if e.center else [0.0] * dim for e in elements]),
            (self.axis, [axis / np.linalg.norm(axis) for axis in axes]),
            (self.vector, [list(e.velocity) if e.velocity else [0.0] * dim for e in elements]),
            (self.strength, [e.strength for e in elements]),
            (self.radius, [e.radius for e in elements]),
            (self.falloff, [e.falloff for e in elements]),
            (self.time, [e.time for e in elements]),
            (self.decay, [e.decay for e in elements]),
            (self.scale, [e.scale for e in elements]),
            (self.speed, [e.speed for e in elements]),
            (self.seed, [e.seed for e in elements]),
        ]
        if elements:  # one copy kernel for the whole table (in the build's batched copy)
            transfer.upload([(field, np.asarray(values)) for field, values in columns])
        self.query_x = None

    @ti.func
    def velocity(self, x, t, w):
        """v(x, t): the sum of every element at position x (a dim-vector) and time t, with world w's smoke grid (0:
        a lone run's)."""
        v = ti.Vector.zero(float, self.dim)
        for k in range(self.count):
            kind = self.kind[k]
            if kind == WIND:
                v += self.vector[k]
            elif kind == NOISE:
                v += self._curl_noise(k, x, t)
            else:
                v += self._radial_element(k, kind, x, t)
        if ti.static(self.has_grid):
            v += self.grid.sample(x, w)
        return v

    @ti.func
    def _core(self, k, r2):
        """1 - exp(-r^2 / radius^2): removes the 1/r singularity inside the core radius."""
        rc = ti.max(self.radius[k], 1e-6)
        return 1.0 - ti.exp(-r2 / (rc * rc))

    @ti.func
    def _radial_element(self, k, kind, x, t):
        v = ti.Vector.zero(float, self.dim)
        d = x - self.center[k]
        if ti.static(self.dim == 3):
            if kind == VORTEX:  # distance from the axis line
                a = self.axis[k]
                d = d - d.dot(a) * a
        r2 = ti.max(d.dot(d), 1e-12)
        r = ti.sqrt(r2)
        core = self._core(k, r2)
        if kind == VORTEX:
            speed = self.strength[k] / (2.0 * math.pi * r) * core
            if self.falloff[k] > 0.0:
                speed *= ti.exp(-r2 / (self.falloff[k] * self.falloff[k]))
            if ti.static(self.dim == 2):
                v = speed * ti.Vector([-d[1], d[0]]) / r
            else:
                v = speed * self.axis[k].cross(d) / r
        elif kind == SOURCE:
            speed = 0.0
            if ti.static(self.dim == 2):
                speed = self.strength[k] / (2.0 * math.pi * r) * core
            else:
                speed = self.strength[k] / (4.0 * math.pi * r2) * core
            v = speed * d / r
        elif kind == EXPLOSION:
            if t >= self.time[k]:
                decay = ti.max(self.decay[k], 1e-6)
                v = self.strength[k] * ti.exp(-(t - self.time[k]) / decay) * core * d / r
        return v

    @ti.func
    def _potential(self, k, p, channel):
        return gradient_noise(p + ti.Vector([0.0, 0.0, 0.0]) + channel * ti.Vector([31.4, 17.3, 11.9]), self.seed[k])

    @ti.func
    def _curl_noise(self, k, x, t):
        s = ti.max(self.scale[k], 1e-6)
        h = 0.01  # difference step, in noise units (scale / 100 in length)
        drift = t * self.speed[k]
        v = ti.Vector.zero(float, self.dim)
        if ti.static(self.dim == 2):
            p = ti.Vector([x[0] / s, x[1] / s, drift])
            dpdy = (
                self._potential(k, p + ti.Vector([0.0, h, 0.0]), 0)
                - self._potential(k, p - ti.Vector([0.0, h, 0.0]), 0)
            ) / (2 * h)
            dpdx = (
                self._potential(k, p + ti.Vector([h, 0.0, 0.0]), 0)
                - self._potential(k, p - ti.Vector([h, 0.0, 0.0]), 0)
            ) / (2 * h)
            v = ti.Vector([dpdy, -dpdx])
        else:
            p = ti.Vector([x[0] / s, x[1] / s, x[2] / s]) + drift * ti.Vector([0.37, 0.21, 0.11])
            # component j of the curl is d psi_(j+2) / d p_(j+1) - d psi_(j+1) / d p_(j+2) (indices mod 3); a run-time
            # loop, not unrolled: each derivative inlines two noise evaluations, and compile time adds up
            for j in range(3):
                ahead, behind = (j + 1) % 3, (j + 2) % 3
                along = self._derivative(k, p, behind, ahead, h) - self._derivative(k, p, ahead, behind, h)
                v += along * ti.Vector([j == 0, j == 1, j == 2], dt=float)
        # the potential has unit amplitude per noise cell: dividing the derivatives by scale would make speed
        # depend on scale; `strength` is the typical speed instead
        return self.strength[k] * v

    @ti.func
    def _derivative(self, k, p, channel, a, h):
        """d psi_channel / d p_a at noise point p (a 3-vector) by a central difference of step h."""
        step = h * ti.Vector([a == 0, a == 1, a == 2], dt=float)
        return (self._potential(k, p + step, channel) - self._potential(k, p - step, channel)) / (2 * h)

    def sample(self, points: np.ndarray, t: float) -> np.ndarray:
        """v(x, t) at points (K, dim) as a (K, dim) NumPy array (for tests, plots and emitters' inspection)."""
        k = len(points)
        if self.query_x is None or self.query_x.shape[0] < k:
            self.query_x = ti.Vector.field(self.dim, float, shape=max(k, 1))
            self.query_v = ti.Vector.field(self.dim, float, shape=max(k, 1))
        full = np.zeros((self.query_x.shape[0], self.dim))
        full[:k] = points
        self.query_x.from_numpy(full)
        self._sample(k, t)
        return self.query_v.to_numpy()[:k].astype(np.float64)

    @ti.kernel
    def _sample(self, k: ti.i32, t: float):
        for i in range(k):
            self.query_v[i] = self.velocity(self.query_x[i], t, 0)
