"""Phases measured from structure: each atom of a molecular scene is counted solid, liquid or gas from how its
neighbours sit around it, never from a temperature or an enthalpy.

For atom i, its neighbours j within molecular.phase_radius (length; 1.5 sigma: the first minimum of the pair
distribution) give its coordination n_i and its local bond order, the unit vector q_i of the sixfold bond-angle
harmonics averaged over its bonds: in 2D psi6 = <exp(6 i theta_ij)> (two numbers), in 3D Steinhardt's q6m =
<Y6m(r_ij)>, m = -6..6 (thirteen; the vector and its dot product as in ten Wolde, Ruiz-Montero and Frenkel, 1996).
A bond i-j is ordered when q_i . q_j exceeds ORDERED (the two atoms' neighbourhoods have the same orientation, as
in a crystal). Then:

    gas     n_i < molecular.gas_below                   (default 3: an atom almost alone; a liquid's surface atom has
                                                        about 4 in 2D and 6 in 3D)
    solid   at least molecular.solid_bonds ordered bonds (default 4 in 2D, 7 in 3D)
    liquid  otherwise (dense, but its neighbours' orientations disagree)

The class is written to the atoms' `kind` field (0 gas, 1 liquid, 2 solid) when it is read after the atoms moved:
the measurements and the renderer ask for it (State.refresh_derived), so a frame split in two step calls (the
window's motion blur) classifies once. The term also sums the atoms' momentum, from which the
kinetic temperature (config/quantities.py) removes the centre-of-mass motion.
"""

import math

import taichi as ti

from ..core.oriented import data_oriented
from .grid import CellGrid
from .term import Measure, Term, register

GAS, LIQUID, SOLID = 0, 1, 2
ORDERED = {2: 0.9, 3: 0.6}  # q_i . q_j above which a bond is ordered, by dimension (calibrated: tests/test_molecular)
DEFAULT_GAS_BELOW = {2: 3, 3: 3}
DEFAULT_SOLID_BONDS = {2: 4, 3: 7}
KEPT = 24  # neighbours within the phase radius kept per atom for the second pass (a dense liquid has about 14 in 3D)


def _legendre6() -> list[tuple[float, list[float]]]:
    """For m = 0..6: (weight, coefficients of the polynomial part of P6m(x) / (1 - x^2)^(m/2), highest power first):
    the weight sqrt((6 - m)! / (6 + m)!) (times sqrt 2 for m > 0, which carries the -m term into the plain dot
    product of the stored real and imaginary parts). The sign convention drops out of q_i . q_j."""
    polys = [
        [231 / 16, 0, -315 / 16, 0, 105 / 16, 0, -5 / 16],
        [-693 / 8, 0, 315 / 4, 0, -105 / 8, 0],
        [3465 / 8, 0, -945 / 4, 0, 105 / 8],
        [-3465 / 2, 0, 945 / 2, 0],
        [10395 / 2, 0, -945 / 2],
        [-10395.0, 0],
        [10395.0],
    ]
    out = []
    for m, poly in enumerate(polys):
        w = math.sqrt(math.factorial(6 - m) / math.factorial(6 + m)) * (math.sqrt(2.0) if m else 1.0)
        out.append((w, poly))
    return out


LEGENDRE6 = _legendre6()


@register
@data_oriented
class Structure(Term):
    """Each atom's phase from its neighbours (module docstring), and the atoms' momentum."""

    key = "structure"
    stage = "coupling"
    measures = (
        Measure("solid", "count", "particles"),
        Measure("liquid", "count", "particles"),
        Measure("gas", "count", "particles"),
        Measure("momentum_x", "sum", "particles"),
        Measure("momentum_y", "sum", "particles"),
        Measure("momentum_z", "sum", "particles"),
        Measure("ke_condensed", "sum", "particles"),  # kinetic energy of the atoms counted solid or liquid
        Measure("ke_gas", "sum", "particles"),  # ... and of those counted gas
    )

    @staticmethod
    def wanted(parts) -> bool:
        return parts.scene.molecular is not None

    def __init__(self, parts):
        self.p = parts.state.particles
        self.dim = dim = parts.model.dim
        molecular = parts.scene.molecular
        self.radius = float(molecular.phase_radius)
        self.gas_below = molecular.gas_below or DEFAULT_GAS_BELOW[dim]
        self.solid_bonds = molecular.solid_bonds or DEFAULT_SOLID_BONDS[dim]
        self.ordered = ORDERED[dim]
        self.width = 2 if dim == 2 else 13
        capacity = parts.model.capacity
        self.order = ti.Vector.field(self.width, float, shape=capacity)  # unit bond-order vector q_i
        self.count = ti.field(ti.i32, shape=capacity)  # neighbours within the phase radius
        self.near = ti.field(ti.i32, shape=(capacity, KEPT))  # the first KEPT of them, for the second pass
        # a grid of its own, its cells the phase radius wide: the pair force's (cutoff plus skin wide) would offer
        # each atom some 40 candidates per neighbour within the phase radius in 3D
        world = parts.scene.world
        self.stale = True  # the atoms moved since the last classification
        self.every = int(molecular.phase_every)  # ... and it is redone once they have taken this many steps
        self.classified_at = -(1 << 30)  # the step of the last classification
        self.state = parts.state
        parts.state.refreshers.append(self.refresh)
        self.grid = CellGrid(self.p.x, self.p.n, world.lo, world.hi, self.radius, world.periodic, capacity,
                             parts.model.loops, cells_per_particle=16, particles=self.p)  # fmt: skip

    def nbytes(self) -> int:
        grid = self.grid.n_cells * 8 + self.count.shape[0] * (12 + 8 * self.dim)  # cells; ids, slots, sorted x
        return self.count.shape[0] * (4 + 8 * self.width + 4 * KEPT) + grid

    def after_steps(self, state) -> None:
        self.stale = True

    def after_restore(self, state) -> None:
        self.stale = True
        self.classified_at = -(1 << 30)  # a restored state is classified when next read, whatever molecular.phase_every

    def refresh(self) -> None:
        """Classify the atoms if they moved since the last time, and at least molecular.phase_every steps ago
        (State.refresh_derived)."""
        step = self.state.step
        if self.stale and step - self.classified_at >= self.every:
            self.classify()
            self.stale, self.classified_at = False, step

    def classify(self) -> None:
        """Write each live atom's phase (0 gas, 1 liquid, 2 solid) to particles.kind from where its neighbours are
        now."""
        self.grid.rebuild()
        self._order(self.grid)
        self._kind()

    @ti.func
    def _harmonics(self, d, r):
        """The bond d (length r > 0)'s sixfold harmonics as a vector of `width` numbers (module docstring)."""
        out = ti.Vector.zero(float, self.width)
        if ti.static(self.dim == 2):
            c, s = d[0] / r, d[1] / r
            re, im = 1.0, 0.0
            for _ in ti.static(range(6)):
                re, im = re * c - im * s, re * s + im * c
            out[0], out[1] = re, im
        else:
            x = d[2] / r
            wr, wi = d[0] / r, d[1] / r  # sin(theta) e^(i phi)
            pr, pi = 1.0, 0.0  # (sin(theta) e^(i phi))^m
            for m in ti.static(range(7)):
                weight, poly = ti.static(LEGENDRE6[m])
                value = 0.0
                for c in ti.static(poly):
                    value = value * x + c
                value *= weight
                if ti.static(m == 0):
                    out[0] = value
                else:
                    pr, pi = pr * wr - pi * wi, pr * wi + pi * wr
                    out[2 * m - 1], out[2 * m] = value * pr, value * pi
        return out

    @ti.func
    def _add_bond(self, acc, j, d, k, extra: ti.template()):
        r2 = d.dot(d)
        i = extra[0]
        if j != i and r2 < self.radius**2 and r2 > 0.0:
            h = self._harmonics(d, ti.sqrt(r2))
            for a in ti.static(range(self.width)):
                acc[a] += h[a]
            kept = ti.cast(acc[self.width], ti.i32)
            if kept < KEPT:
                self.near[i, kept] = j
            acc[self.width] += 1.0
        return acc

    @ti.kernel
    def _order(self, grid: ti.template()):
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            acc = grid.fold(i, self.p.x[i], ti.Vector.zero(float, self.width + 1), self._add_bond, (i,))
            q = ti.Vector([acc[a] for a in ti.static(range(self.width))])
            norm = q.norm()
            self.order[i] = q / norm if norm > 0.0 else ti.Vector.zero(float, self.width)
            self.count[i] = ti.cast(acc[self.width], ti.i32)

    @ti.kernel
    def _kind(self):
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            kind = GAS
            if self.count[i] >= self.gas_below:
                bonds = 0
                for k in range(ti.min(self.count[i], KEPT)):
                    if self.order[i].dot(self.order[self.near[i, k]]) > self.ordered:
                        bonds += 1
                kind = SOLID if bonds >= self.solid_bonds else LIQUID
            self.p.kind[i] = kind

    @ti.func
    def measure_particle(self, i):
        """(solid, liquid, gas) as 0/1 by the atom's kind, its momentum m v (three components, z 0 in 2D), and its
        kinetic energy as a condensed (solid or liquid) atom or as a gas atom."""
        kind = self.p.kind[i]
        mv = self.p.mass[i] * self.p.v[i]
        z = 0.0
        if ti.static(self.dim == 3):
            z = mv[2]
        ke = 0.5 * mv.dot(self.p.v[i])
        gas = kind == GAS
        return (
            int(kind == SOLID),
            int(kind == LIQUID),
            int(gas),
            mv[0],
            mv[1],
            z,
            ti.select(gas, 0.0, ke),
            ti.select(gas, ke, 0.0),
        )
