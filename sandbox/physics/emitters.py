"""Emitters: particles seeded where and when a scene says.

Seeding: at a point, uniformly by area/volume inside a box, disk or sphere, or uniformly by length/area on its
boundary (`surface = true`). Timing: `count` at the start, `rate` per second from `start` to `stop` (the fraction
left over each step carries to the next, so 2.5 per step gives 5 every 2 steps), and `burst_count` at each of
`bursts`. Every attribute is set at birth: velocity (base, random within a cone, speed spread, outward from the
centre, plus the velocity field), temperature, mass and radius, material and colour, lifetime with a spread.
Random numbers are hashes of (emitter seed, particle serial number, attribute): the same whatever the thread order.
A particle given a lifetime is retired when it has aged (physics/lifetimes.py).
"""

import math
import warnings

import numpy as np
import taichi as ti

from ..core import transfer
from ..core.oriented import data_oriented
from ..core.ranges import COUNT, Range
from ..core.state import WORLDS
from .emitter_masks import mask_pixel_table
from .emitter_worlds import WorldRefill, WorldSeeding
from .fields import random_uniform
from .phase import NEVER_BONDS
from .term import Term, register

SHAPES = ("point", "box", "disk", "sphere", "mask")
MASK = SHAPES.index("mask")


@register
@data_oriented
class Emitters(Term):
    """The scene's emitters as a term: parameter fields, the emit kernel, and the seeding due before each step."""

    key = "emitters"
    stage = "emitters"  # built after the velocity field, which an emitter's particles may inherit
    before_stage = "seeding"  # seeded before the smoke grid steps

    @staticmethod
    def wanted(parts) -> bool:
        return bool(parts.scene.emitters)

    @staticmethod
    def host_work(scene) -> str | None:
        """Why this pass needs the host between `scene`'s steps (see the stepping plan), or None."""
        return "emitters seed particles between steps" if scene.emitters else None

    def __init__(self, parts):
        model, state, scene = parts.model, parts.state, parts.scene
        self.state = state
        self.p = state.particles
        self.dim = model.dim
        self.capacity = model.capacity
        self.specs = list(scene.emitters)
        self.count = len(self.specs)
        self.first_group = len(scene.bodies)
        self.fields = parts.terms.get("fields")
        self.has_fields = self.fields is not None
        self.has_heat, self.lifetimes, self.refreezes = self.p.heat, self.p.lifetimes, self.p.refreeze
        self.phase = model.phase
        emitters = self.specs
        n = max(self.count, 1)
        dim = self.dim
        self.shape = ti.field(ti.i32, shape=n)
        self.surface = ti.field(ti.i32, shape=n)
        self.center = ti.Vector.field(dim, float, shape=n)
        self.lo = ti.Vector.field(dim, float, shape=n)
        self.hi = ti.Vector.field(dim, float, shape=n)
        self.size = ti.field(float, shape=n)
        self.velocity = ti.Vector.field(dim, float, shape=n)
        self.cone = ti.field(float, shape=n)  # half angle, radians
        self.speed_spread = ti.field(float, shape=n)
        self.radial_speed = ti.field(float, shape=n)
        self.inherit = ti.field(ti.i32, shape=n)
        self.jitter = ti.field(float, shape=n)
        self.temperature = ti.field(float, shape=n)
        self.radius = ti.field(float, shape=n)
        self.mass = ti.field(float, shape=n)
        self.material = ti.field(ti.i32, shape=n)
        self.lifetime = ti.field(float, shape=n)
        self.lifetime_spread = ti.field(float, shape=n)
        self.seed = ti.field(ti.u32, shape=n)
        self.color = ti.Vector.field(3, ti.f32, shape=n)
        self.mask_start = ti.field(ti.i32, shape=n)  # mask emitters: their pixels' range in mask_pixels
        self.mask_count = ti.field(ti.i32, shape=n)
        self.pixel_size = ti.Vector.field(dim, float, shape=n)
        ambient = scene.heat.ambient if scene.heat else 20.0
        rows = [self._row(k, e, scene, model.material_names, ambient) for k, e in enumerate(self.specs)]
        mask_pairs = self._mask_pixels(emitters)
        if rows:  # one copy kernel for the whole table: each of _row()'s names is a field of this object
            transfer.upload([(getattr(self, name), np.array([r[name] for r in rows])) for name in rows[0]] + mask_pairs)
        # with worlds (core/worlds.py) each world counts its own, as its lone run does: a list of these a world
        self.serial = self._per_world(0)  # particles emitted so far, per emitter (the random-number index)
        self.carry = self._per_world(0.0)  # fractional particles owed by the rate
        self.emitted = self._per_world(0)
        self._warned_full = False
        self.refills = [k for k, e in enumerate(self.specs) if e.refill_density > 0]
        self.refill_grids = {}
        for k in self.refills:
            self.refill_grids[k] = self._refill_grid(self.specs[k])
        self.reserved = ti.field(ti.i32, shape=())  # refill: slots taken by the last pass
        self.seeding = WorldSeeding(self) if self.p.gaps else None  # every world's due particles in one launch
        self.world_refill = WorldRefill(self) if self.p.gaps and self.refills else None

    def words(self, where: str) -> list[str]:
        return [f"emitters: {', '.join(e.name for e in self.specs)} (rate, bursts)"] if where == "before" else []

    def _per_world(self, value) -> list:
        """A counter per emitter, or with worlds a list of them a world."""
        counters = [value] * self.count
        return [list(counters) for _ in range(self.p.world_count)] if self.p.gaps else counters

    def counters(self, w: int) -> tuple[list, list, list]:
        """World w's (serial, carry, emitted) lists, an entry per emitter (a lone run's own, whatever w)."""
        if self.p.gaps:
            return self.serial[w], self.carry[w], self.emitted[w]
        return self.serial, self.carry, self.emitted

    def took(self, w: int, k: int, serials: int, made: int) -> None:
        """World w's (a lone run's, whatever w) emitter k drew `serials` serial numbers and made `made` particles of
        them (a refill draws serials for particles it has no room for): its counters and the ids numbered on. The
        caller counts the live particles (a lone run's n, a world's count)."""
        serial, _, emitted = self.counters(w)
        serial[k] += serials
        emitted[k] += made
        if self.p.gaps:
            self.p.next_ident[w] += made
        else:
            self.p.next_ident += made

    def declare(self, state) -> None:
        """Particles emitted so far (the random-number index), the rate's carried fraction, the counts."""
        rows = WORLDS if self.p.gaps else ""
        state.declare("emitters", self, ("serial", "emitted"), kind="value", valid=COUNT, rows=rows)
        # the carried fraction may sit a rounding below zero: a particle is due 1e-9 before a whole one is owed
        state.declare("emitters", self, ("carry",), kind="value", valid=Range(lo=-1e-6, hi=2**31 - 1), rows=rows)

    def start(self, state) -> None:
        """The emitters' starting particles (`count`): a lone run's, or every world's in one launch."""
        if self.p.gaps:
            self.seeding.seed([(w, 0.0, [e.count for e in self.specs]) for w in range(self.p.world_count)])
        else:
            self.emit_initial()

    def before_step(self, state) -> None:
        """Emit what is due in the step [t, t + dt) (each world's on its own clock), then top up the refill
        regions."""
        if self.p.gaps:
            times = state.world_times()[: int(self.p.n[None]) // self.p.world_size]
            self.seeding.seed_due(times, state.dt)
            if self.world_refill is not None:
                self.world_refill.refill(times)
            return
        self.emit_due(state.time, state.dt)
        if self.refills:
            self.refill(state.time)

    def _row(self, k: int, e, scene, material_names: list, ambient: float) -> dict:
        """Emitter k's parameters (spec e), by the name of the field that holds each: the values of its row."""
        mat = scene.materials[e.material]
        dim = self.dim
        boxed = e.shape in ("box", "mask")
        spacing = 2 * e.particle_radius
        return {
            "shape": SHAPES.index(e.shape),
            "surface": int(e.surface),
            "center": list(0.5 * (np.asarray(e.lo) + np.asarray(e.hi))) if boxed else list(e.center),
            "lo": list(e.lo) if boxed else [0.0] * dim,
            "hi": list(e.hi) if boxed else [0.0] * dim,
            "size": e.size,
            "velocity": list(e.velocity),
            "cone": math.radians(e.cone) / 2,
            "speed_spread": e.speed_spread,
            "radial_speed": e.radial_speed,
            "inherit": int(e.inherit_field),
            "jitter": e.jitter,
            "temperature": ambient if e.temperature is None else e.temperature,
            "radius": e.particle_radius,
            "mass": mat.particle_mass if mat.particle_mass is not None else mat.density * spacing**dim,
            "material": material_names.index(e.material),
            "lifetime": e.lifetime,
            "lifetime_spread": e.lifetime_spread,
            "seed": e.seed * 7919 + k,
            "color": list(e.color) if e.color else list(mat.color),
        }

    def _mask_pixels(self, emitters: list):
        """Make `mask_pixels`, one (P, 2) int field for every mask emitter's pixels (emitter_masks.py). Returns the
        (field, values) pairs to upload: the pixels and each emitter's range of them and pixel size."""
        made = mask_pixel_table(emitters, self.dim)
        self.mask_pixels = ti.Vector.field(2, ti.i32, shape=len(made[0]) if made else 1)
        if made is None:
            return []
        table, starts, counts, sizes = made
        return [
            (self.mask_start, starts),
            (self.mask_count, counts),
            (self.pixel_size, sizes),
            (self.mask_pixels, table),
        ]

    # ------------------------------------------------------------------ emission (host decides counts)
    def emit_initial(self) -> None:
        """A lone run's starting particles from its emitters (`count`); worlds seed theirs through WorldSeeding."""
        for k, e in enumerate(self.specs):
            if e.count:
                self._emit(k, e.count, 0.0)

    def emit_due(self, t: float, dt: float) -> None:
        """Emit what is due in the step [t, t + dt) of a lone run: the rate's share (with carry) and bursts falling in
        it."""
        for k in range(self.count):
            due = self.due(k, t, dt, self.carry)
            if due:
                self._emit(k, due, t)

    def due(self, k: int, t: float, dt: float, carry: list) -> int:
        """Emitter k's particles due in the step [t, t + dt): its rate's share (the fraction left over carried in
        `carry`, a world's list) and its bursts falling in the step."""
        e = self.specs[k]
        due = 0
        if e.rate > 0:
            overlap = max(0.0, min(t + dt, e.stop) - max(t, e.start))
            carry[k] += e.rate * overlap
            due = int(math.floor(carry[k] + 1e-9))
            carry[k] -= due
        return due + e.burst_count * sum(1 for b in e.bursts if t <= b < t + dt)

    def room_for(self, k: int, count: int, room: int) -> int:
        """Of `count` particles due from emitter k, as many as `room` allows (said once where it cuts them)."""
        if count > room and not self._warned_full:
            self._warned_full = True
            warnings.warn(
                f"emitter {self.specs[k].name!r}: particle capacity {self.capacity} reached; "
                "set world.capacity higher (or shorten lifetimes)",
                stacklevel=4,
            )
        return max(min(count, room), 0)

    # ------------------------------------------------------------------ refilling to a target density
    PER_CELL = 4  # refill cells are sized to hold this many particles at the target density

    def _refill_grid(self, e) -> dict:
        """A lattice of cells over the emitter's region, each holding PER_CELL particles at the target density."""
        if e.shape == "box":
            lo, hi = np.asarray(e.lo, dtype=float), np.asarray(e.hi, dtype=float)
        else:
            lo, hi = np.asarray(e.center) - e.size, np.asarray(e.center) + e.size
        side = (self.PER_CELL / e.refill_density) ** (1.0 / self.dim)
        counts = np.maximum(1, np.round((hi - lo) / side)).astype(int)
        cell = (hi - lo) / counts
        return {
            "lo": ti.Vector(list(lo)),
            "cell": ti.Vector(list(cell)),
            "counts": ti.Vector(list(counts)),
            "count": ti.field(ti.i32, shape=tuple(int(c) for c in counts)),
            "target": int(round(e.refill_density * float(np.prod(cell)))),
        }

    def refill(self, t: float) -> int:
        """Top up every refill emitter's region cell by cell to its target count; returns particles added."""
        added = 0
        for k in self.refills:
            g = self.refill_grids[k]
            n = int(self.p.n[None])
            self._count_cells(g["count"], g["lo"], g["cell"])
            self.reserved[None] = 0
            self._top_up(k, g["count"], g["lo"], g["cell"], g["target"], n, self.serial[k], t, self.p.next_ident)
            made = min(int(self.reserved[None]), self.capacity - n)
            self.p.n[None] = n + made
            self.took(0, k, int(self.reserved[None]), made)
            added += made
        if added:
            self.state.particles_moved()
        return added

    @ti.func
    def cell_of(self, x, lo, cell, shape):
        """(the refill cell of x, whether x is inside the refill lattice at lo of `shape` cells of size `cell`)."""
        c = ti.Vector.zero(ti.i32, self.dim)
        inside = True
        for a in ti.static(range(self.dim)):
            f = (x[a] - lo[a]) / cell[a]
            if f < 0 or f >= shape[a]:
                inside = False
            c[a] = ti.cast(ti.floor(f), ti.i32)
        return c, inside

    @ti.kernel
    def _count_cells(self, count: ti.template(), lo: ti.template(), cell: ti.template()):
        for I in ti.grouped(count):
            count[I] = 0
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            c, inside = self.cell_of(self.p.x[i], lo, cell, count.shape)
            if inside:
                count[c] += 1

    @ti.kernel
    def _top_up(
        self,
        k: ti.i32,
        count: ti.template(),
        lo: ti.template(),
        cell: ti.template(),
        target: ti.i32,
        first: ti.i32,
        serial0: ti.i32,
        t: float,
        ident0: ti.i32,
    ):
        """Each cell's deficit below `target` seeded, the cells in order (serial: which cell takes which serial
        numbers, and so where its particles land, is the same in every run), ids from ident0 on."""
        ti.loop_config(serialize=True)
        for I in ti.grouped(count):
            deficit = target - count[I]
            if self.refills_cell(k, lo, cell, I) and deficit > 0:
                start = ti.atomic_add(self.reserved[None], deficit)
                for m in range(deficit):
                    slot = start + m
                    i = first + slot
                    if i < self.capacity:
                        self.refill_particle(k, i, serial0 + slot, lo, cell, I, t, 0)
                        self.p.ident[i] = ident0 + slot

    @ti.func
    def refills_cell(self, k, lo, cell, I):
        """Whether refill emitter k tops up cell I of its lattice (at lo, cells `cell` wide): every cell of a box,
        those whose centre is inside a disk or sphere."""
        within = True
        if self.shape[k] == 2 or self.shape[k] == 3:
            within = (lo + (ti.cast(I, float) + 0.5) * cell - self.center[k]).norm() <= self.size[k]
        return within

    @ti.func
    def refill_particle(self, k, i, serial, lo, cell, I, t, w):
        """New particle i (serial number `serial`) from refill emitter k at a random place in cell I, born at time t
        of world w's clock."""
        u = ti.Vector([self._u(k, serial, 50 + a) for a in ti.static(range(self.dim))])
        self.init_particle(k, i, serial, lo + (ti.cast(I, float) + u) * cell, t, w)

    def _emit(self, k: int, count: int, t: float) -> None:
        """`count` particles from emitter k into a lone run, born at time t (as many as it has room for)."""
        n = int(self.p.n[None])
        count = self.room_for(k, count, self.capacity - n)
        if count <= 0:
            return
        self._spawn(k, count, n, self.serial[k], t, self.p.next_ident)
        self.p.n[None] = n + count
        self.took(0, k, count, count)
        self.state.particles_moved()

    @ti.func
    def _u(self, k, serial, j):
        return random_uniform(self.seed[k], ti.cast(serial, ti.u32), ti.cast(j, ti.u32))

    @ti.func
    def _unit_vector(self, k, serial, j):
        """Uniform direction (unit circle in 2D, unit sphere in 3D) from random numbers j, j+1."""
        v = ti.Vector.zero(float, self.dim)
        phi = 2.0 * math.pi * self._u(k, serial, j)
        if ti.static(self.dim == 2):
            v = ti.Vector([ti.cos(phi), ti.sin(phi)])
        else:
            z = 2.0 * self._u(k, serial, j + 1) - 1.0
            s = ti.sqrt(ti.max(1.0 - z * z, 0.0))
            v = ti.Vector([s * ti.cos(phi), s * ti.sin(phi), z])
        return v

    @ti.func
    def sample_position(self, k, serial):
        """A birth position: inside the shape uniformly by area/volume, or on its boundary uniformly by length/area."""
        c = self.center[k]
        pos = c
        shape = self.shape[k]
        if shape == 1:  # box
            lo, hi = self.lo[k], self.hi[k]
            ext = hi - lo
            u = ti.Vector([self._u(k, serial, 10 + a) for a in ti.static(range(self.dim))])
            pos = lo + u * ext
            if self.surface[k]:
                pos = self._box_surface(k, serial, lo, ext, u)
        elif shape == MASK:  # a random inside (or boundary) pixel, then a random point in it (masks are 2D)
            if ti.static(self.dim == 2):
                pick = ti.min(ti.cast(self._u(k, serial, 10) * self.mask_count[k], ti.i32), self.mask_count[k] - 1)
                pixel = self.mask_pixels[self.mask_start[k] + pick]
                for a in ti.static(range(2)):
                    pos[a] = self.lo[k][a] + (pixel[a] + self._u(k, serial, 11 + a)) * self.pixel_size[k][a]
        elif shape == 2 or shape == 3:  # disk, sphere
            direction = self._unit_vector(k, serial, 10)
            r = self.size[k]
            if not self.surface[k]:
                r *= self._u(k, serial, 13) ** (1.0 / self.dim)  # radius with density ~ r^(dim-1)
            pos = c + r * direction
        jitter = ti.Vector([self._u(k, serial, 20 + a) - 0.5 for a in ti.static(range(self.dim))])
        return pos + 2.0 * self.jitter[k] * jitter

    @ti.func
    def _box_surface(self, k, serial, lo, ext, u):
        """A point uniform by length (2D) or area (3D) on the boundary of the box lo + ext."""
        pos = lo + u * ext
        # choose the pair of faces normal to axis a with probability proportional to their measure
        measures = ti.Vector.zero(float, self.dim)
        for a in ti.static(range(self.dim)):
            m = 1.0
            for b in ti.static(range(self.dim)):
                if b != a:
                    m *= ext[b]
            measures[a] = m
        pick = self._u(k, serial, 14) * measures.sum()
        axis = self.dim - 1
        acc = 0.0
        for a in ti.static(range(self.dim)):
            if pick >= acc and pick < acc + measures[a]:
                axis = a
            acc += measures[a]
        side = 1.0 if self._u(k, serial, 15) < 0.5 else 0.0
        for a in ti.static(range(self.dim)):
            if a == axis:
                pos[a] = lo[a] + side * ext[a]
        return pos

    @ti.func
    def sample_velocity(self, k, serial, pos, t, w):
        base = self.velocity[k]
        factor = 1.0 + self.speed_spread[k] * (2.0 * self._u(k, serial, 30) - 1.0)  # spreads both speeds
        speed = base.norm() * factor
        v = ti.Vector.zero(float, self.dim)
        if base.norm() > 0:
            d = base / base.norm()
            if self.cone[k] > 0:
                if ti.static(self.dim == 2):
                    angle = ti.atan2(d[1], d[0]) + self.cone[k] * (2.0 * self._u(k, serial, 31) - 1.0)
                    d = ti.Vector([ti.cos(angle), ti.sin(angle)])
                else:
                    # uniform on the spherical cap of half angle cone around d
                    cos_t = 1.0 - self._u(k, serial, 31) * (1.0 - ti.cos(self.cone[k]))
                    sin_t = ti.sqrt(ti.max(1.0 - cos_t * cos_t, 0.0))
                    phi = 2.0 * math.pi * self._u(k, serial, 32)
                    helper = ti.Vector([1.0, 0.0, 0.0]) if ti.abs(d[0]) < 0.9 else ti.Vector([0.0, 1.0, 0.0])
                    e1 = d.cross(helper).normalized()
                    e2 = d.cross(e1)
                    d = cos_t * d + sin_t * (ti.cos(phi) * e1 + ti.sin(phi) * e2)
            v = speed * d
        out = pos - self.center[k]
        if out.norm() > 1e-9:
            v += factor * self.radial_speed[k] * out / out.norm()
        else:
            v += factor * self.radial_speed[k] * self._unit_vector(k, serial, 33)
        if ti.static(self.has_fields):
            if self.inherit[k]:
                v += self.fields.velocity(pos, t, w)
        return v

    @ti.kernel
    def _spawn(self, k: ti.i32, count: ti.i32, first: ti.i32, serial0: ti.i32, t: float, ident0: ti.i32):
        for e in range(count):
            serial = serial0 + e
            self.init_particle(k, first + e, serial, self.sample_position(k, serial), t, 0)
            self.p.ident[first + e] = ident0 + e

    @ti.func
    def init_particle(self, k, i, serial, pos, t, w):
        """Every attribute of new particle i from emitter k, born at pos in world w (0: a lone run) at time t of its
        clock."""
        p = self.p
        p.x[i] = pos
        p.v[i] = self.sample_velocity(k, serial, pos, t, w)
        p.mass[i] = self.mass[k]
        p.radius[i] = self.radius[k]
        mat = self.material[k]
        p.material[i] = mat
        p.color[i] = self.color[k]
        p.group[i] = self.first_group + k
        mortal = 0
        if ti.static(self.lifetimes):
            p.age[i] = 0.0
            spread = 1.0 + self.lifetime_spread[k] * (2.0 * self._u(k, serial, 40) - 1.0)
            p.lifetime[i] = self.lifetime[k] * spread
            mortal = 1 if p.lifetime[i] > 0 else 0
        if ti.static(self.has_heat):
            p.h[i] = self.phase.enthalpy(self.temperature[k], mat)
            p.T[i] = self.temperature[k]
            if ti.static(self.refreezes):
                p.liquid[i] = NEVER_BONDS if mortal else 1
