"""The pair force between particles not joined by a live spring: a pair law (physics/pair_laws.py, written once for
NumPy and Taichi) and what this term applies to any law: the cutoff, the energy and force shifts, the core cap, the
viscous term, materials' tables and the sliders' scales.

Force on i from j, with d = x_j - x_i, r = |d| (attraction positive along d), g the law's radial factor:

    F_i = m_i m_j g(r) d          for core <= r < cutoff; the power law's g = alpha / (r + eps)^a - beta / r^b

The 12-6 Lennard-Jones force is the power law with a = 8, b = 14, eps = 0, alpha = 24 e s^6, beta = 48 e s^12.
Below r_core = core * r_eq (r_eq: where the force vanishes) the force keeps its magnitude at r_core, so two particles
at (almost) the same point get a large but finite push; at r = 0 exactly the push is along the first axis, in
opposite directions for i and j (by index order). The energy is continued linearly there, so dU/dr still equals the
force. Energy is shifted to zero at the cutoff unless pair.shift = false (then U is the plain potential, as in
LAMMPS's lj/cut without pair_modify shift yes); the forces are the same either way. With pair.force_shift the force
at the cutoff, F_c = g(r_c) r_c, is subtracted from every pair's force magnitude, so the force falls continuously to
zero there (the linear-force-shifted potential U(r) - U(r_c) + F_c (r - r_c) of NIST's Lennard-Jones tables).

A viscous term -gamma ((v_i - v_j) . n) n w(r), w = 1 - r/cutoff, gives the melt its viscosity; it is antisymmetric,
so momentum is conserved. Materials mix by geometric means of alpha and beta, arithmetic means of eps and gamma.
"""

import warnings

import numpy as np
import taichi as ti

from ..config.schema import non_negative, out_of_range
from ..core import transfer
from ..core.oriented import data_oriented
from ..core.particles import fold_bonds
from ..core.transfer import real_fields
from ..core.worlds import world_of
from .pair_laws import NUMPY, TAICHI, PowerLaw, law_for
from .term import Measure, Slider, Term, register


def radial_force(r, alpha, beta, eps, a, b):
    """Radial force factor g(r) of the power law such that F_i = g(r) d (NumPy/float; unit masses)."""
    return PowerLaw(a, b).g(np.multiply(r, r), (alpha, beta, eps), NUMPY)


def equilibrium_distance(alpha: float, beta: float, eps: float, a: float, b: float) -> float:
    """The r where the power law's force vanishes (alpha/(r+eps)^a = beta/r^b); inf without attraction."""
    return PowerLaw(a, b).equilibrium((alpha, beta, eps))


def pair_energy(r: float, alpha: float, beta: float, eps: float, a: float, b: float, cutoff: float) -> float:
    """The power law's potential U(r), shifted to zero at the cutoff, with dU/dr = r g(r) (unit masses, r >= core)."""
    law, c = PowerLaw(a, b), (alpha, beta, eps)
    return float(law.u(r, c, NUMPY) - law.u(cutoff, c, NUMPY))


# A law's g and u are plain Python on purpose (physics/pair_laws.py: the same lines run on NumPy arrays), with no branch
# on a run-time value, so Taichi's warning that it does not transform them is expected.
warnings.filterwarnings("ignore", message=r'.*Calling non-taichi function "self\.pair_law\.', category=SyntaxWarning)


@register
@data_oriented
class PairForce(Term):
    """The pair force as a term: per material pair n_mat x n_mat tables, the force and energy funcs, its part of the
    rates (each neighbour pair's force, excluding pairs joined by a live spring) and its pair energy and virial."""

    key = "pair"
    stage = "pairs"
    pair_channel = "force"
    excludes_bonded = True
    measures = (Measure("pair", "sum", "pairs"), Measure("pair_virial", "sum", "pairs"))

    @staticmethod
    def wanted(parts) -> bool:
        return parts.scene.pair is not None

    def __init__(self, parts):
        scene, model, particles = parts.scene, parts.model, parts.state.particles
        pair = scene.pair
        materials = model.material_list
        self.parts = parts  # its neighbourhood (the grid the pair energy scans) is built after the terms
        self.springs = parts.state.springs
        self.has_springs = self.springs is not None
        self.domain = model.domain
        self.loops = model.loops
        n = len(materials)
        self.force_shifted = bool(pair.force_shift)  # the force at the cutoff subtracted (linear force shift)
        # the energy shifted to zero at the cutoff (forces are the same either way; always with the force shift)
        self.shifted = bool(pair.shift) or self.force_shifted
        self.dim = model.dim
        self.a, self.b = float(pair.a), float(pair.b)
        self.cutoff = float(pair.cutoff)
        self.reach = self.cutoff
        soft = any(m.pair_soft for m in materials)
        self.pair_law = law_for(pair, soft)  # its formula (pair_laws.py); the cutoff, shifts and core are here
        visc = np.array([m.viscosity for m in materials])
        self.n_materials = n
        self.core = float(pair.core)
        self.base_np = self.pair_law.coefficients(materials, pair)  # the law's three (n, n) coefficient tables
        self.visc_np = 0.5 * (visc[:, None] + visc[None, :])
        (self.visc,) = real_fields(self.visc_np)  # the law's coefficients and what follows from them: set_scale
        # The scaled tables: materials p, q of world w at row w n + p (core/worlds.py: each world its own scales)
        self.worlds = model.worlds
        rows = (self.worlds * n, n)
        self.alpha, self.beta, self.eps = (ti.field(float, shape=rows) for _ in range(3))  # coefficients 0, 1, 2
        self.r_core, self.shift, self.f_core = (ti.field(float, shape=rows) for _ in range(3))
        self.f_cut = ti.field(float, shape=rows)  # g(cutoff) cutoff: the force shift (zero without it)
        self.shift_att = ti.field(float, shape=rows)  # the attraction's part of the shift (vapour scales it)
        self.scales = [(1.0, 1.0)] * self.worlds
        self.set_scale(1.0, 1.0)
        self.single_material = n == 1
        self.has_viscosity = bool(np.any(self.visc_np > 0))
        self.mass, self.material, self.v, self.x = particles.mass, particles.material, particles.v, particles.x
        # boiling: a particle's vapour share feels no attraction (compiled in only where a material boils)
        self.boils = particles.heat and any(m.boils for m in materials) and self.pair_law.attraction is not None
        self.phase, self.h = (model.phase, particles.h) if self.boils else (None, None)

    def words(self, where: str) -> list[str]:
        return [f"pair force ({self.pair_law.words()}, cutoff {self.cutoff:g})"] if where == "rates" else []

    world_controls = True  # each world's pairs have their own scales (core/worlds.py)

    scale = property(lambda self: self.scales[0], doc="(attraction, repulsion) scales of a lone run (world 0's)")

    def controls(self, world: int = 0) -> dict:
        return {"scale": list(self.scales[world])}

    def sliders(self) -> list[Slider]:
        """Every pair's attraction and repulsion as multiples of the materials' (the pair-force panel's law)."""
        out = [Slider("attraction", "pair attraction", "scale", 0.0, 4.0, "x", 0.01, index=0)]
        if "repulsion" in self.pair_law.scaled:
            out.append(Slider("repulsion", "pair repulsion", "scale", 0.25, 4.0, "x", 0.01, index=1))
        return out

    def control_checks(self) -> dict:
        """The potential sliders' scales: numbers of the scene's range, not negative."""
        return {"scale": lambda v: out_of_range(v) or next((non_negative(x) for x in v if non_negative(x)), None)}

    def apply_controls(self, values: dict, world: int | None = None) -> None:
        if "scale" in values:
            self.set_scale(*values["scale"], world=world)

    def set_scale(self, attraction: float, repulsion: float, world: int | None = None) -> None:
        """Scale every pair's attraction and repulsion (the law's `scaled` coefficients: the power law's alpha and
        beta) from the materials' values, live (the window's potential sliders), in world `world` (None: in every
        world): the equilibrium distance, core cap and energy shift follow; no kernel recompiles. The host tables
        (coef_np, r_eq_np ...: the window's panel) are world 0's."""
        worlds = range(self.worlds) if world is None else (world,)
        for w in worlds:
            self.scales[w] = (float(attraction), float(repulsion))
        host = self._scaled_tables(attraction, repulsion)
        if 0 in worlds:
            for name, table in host.items():
                setattr(self, name, table)
        fields = (self.alpha, self.beta, self.eps, self.r_core, self.shift, self.shift_att, self.f_core, self.f_cut)
        c = host["coef_np"]
        values = [*c, *(host[f"{name}_np"] for name in ("r_core", "shift", "shift_att", "f_core", "f_cut"))]
        if self.worlds == 1:
            transfer.upload(list(zip(fields, values)))
            return
        n = self.n_materials
        tables = transfer.download_all(list(fields))
        for table, mine in zip(tables, values):
            for w in worlds:
                table[w * n : (w + 1) * n] = mine
        transfer.upload_all(list(zip(fields, tables)))

    def _scaled_tables(self, attraction: float, repulsion: float) -> dict:
        """The (n, n) tables of the law scaled so, by the name the host keeps them under (coef_np: its three
        coefficient tables; r_eq_np, r_core_np, shift_np, shift_att_np, f_core_np, f_cut_np)."""
        law, n = self.pair_law, self.n_materials
        factors = {"attraction": attraction, "repulsion": repulsion}
        c = [base * next((factors[k] for k, i in law.scaled.items() if i == j), 1.0) for j, base in
             enumerate(self.base_np)]  # fmt: skip
        r_eq = np.array([[law.equilibrium([t[p, q] for t in c]) for q in range(n)] for p in range(n)])
        r_core = np.maximum(self.core * np.where(np.isfinite(r_eq), r_eq, 1.0), 1e-6)
        # Energy shift so that U(cutoff) = 0 (zero with pair.shift = false), and its attraction's part (what a vapour
        # share does not feel, for a law that boils); the force at the core radius (held below it) and at the cutoff.
        cut = self.cutoff
        shift = law.u(np.full((n, n), cut), c, NUMPY)
        shift_att = np.zeros((n, n))
        if law.attraction is not None:
            shift_att = law.u(np.full((n, n), cut), law.attracting(c), NUMPY)
        if not self.shifted:
            shift, shift_att = np.zeros_like(shift), np.zeros_like(shift_att)
        g_cut = law.g(np.full((n, n), cut * cut), c, NUMPY)
        return {
            "coef_np": c,
            "r_eq_np": r_eq,
            "r_core_np": r_core,
            "shift_np": shift,
            "shift_att_np": shift_att,
            "f_core_np": law.g(r_core * r_core, c, NUMPY) * r_core,
            "f_cut_np": g_cut * cut if self.force_shifted else np.zeros_like(g_cut),
        }

    @property
    def alpha_np(self) -> np.ndarray:
        """The first coefficient's table, scaled (the power law's alpha)."""
        return self.coef_np[0]

    @property
    def beta_np(self) -> np.ndarray:
        return self.coef_np[1]

    @property
    def eps_np(self) -> np.ndarray:
        return self.coef_np[2]

    def potential(self, r: float, p: int, q: int) -> float:
        """The law's unshifted potential per unit mass product at r (length) between materials p and q."""
        return float(self.pair_law.u(r, [t[p, q] for t in self.coef_np], NUMPY))

    def curve(self, samples: int = 128, p: int = 0, q: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(r, radial force per unit mass product, positive attracting) for materials p, q from half the core radius to
        the cutoff, with the core cap: what the window's potential panel draws."""
        r = np.linspace(0.5 * self.r_core_np[p, q], self.cutoff, samples)
        held = np.maximum(r, self.r_core_np[p, q])
        g = self.pair_law.g(held * held, [t[p, q] for t in self.coef_np], NUMPY)
        return r, g * held - self.f_cut_np[p, q]

    @ti.func
    def _pair_ids(self, i, j):
        p, q = 0, 0
        if ti.static(not self.single_material):
            p, q = self.material[i], self.material[j]
        return p, q

    @ti.func
    def row_base(self, i):
        """Where particle i's world's rows of the scaled tables start (material p's row: base + p); 0 in a lone run
        (a constant: its tables are read as they always were). Loaded once per particle by the callers."""
        base = 0
        if ti.static(self.worlds > 1):
            base = world_of(self.parts.state.particles, i) * self.n_materials
        return base

    @ti.func
    def coefficients(self, p, q):
        """The pair law of table row p (material p's in its world: row_base + p) and material q as one vector: (alpha,
        beta, eps, r_core, f_core)."""
        return ti.Vector([self.alpha[p, q], self.beta[p, q], self.eps[p, q], self.r_core[p, q], self.f_core[p, q]])

    @ti.func
    def pair_coefficients(self, shared, base, i, j):
        """Coefficients of the pair (i, j): `shared` (row()'s) with one material; `base`: i's row_base."""
        c = shared
        if ti.static(not self.single_material):
            c = self.coefficients(base + self.material[i], self.material[j])
        return c

    @ti.func
    def scaled_force(self, i, j, d, r2, base):
        """Pair-law force on i from j divided by m_i (i.e. m_j g(r) d), with the core cap; r2 < cutoff^2; `base`:
        i's row_base."""
        p, q = self._pair_ids(i, j)
        return self.mass[j] * self.law(self.coefficients(base + p, q), i, j, d, r2, base)

    @ti.func
    def liquid_share(self, i, j):
        """(1 - psi_i)(1 - psi_j): the share of the pair's attraction its particles' liquid parts feel (a material
        that boils; psi the gas fraction)."""
        return (1.0 - self.phase.gas(self.h[i], self.material[i])) * (1.0 - self.phase.gas(self.h[j], self.material[j]))

    @ti.func
    def law(self, c, i, j, d, r2, base):
        """g(r) d per unit mass product for coefficients c (see coefficients), with the core cap: finite at any r."""
        k0, k1, k2, rc, f_core = c[0], c[1], c[2], c[3], c[4]
        if ti.static(self.boils):  # vapour does not stick: attraction (the power law's alpha) only between liquid
            k0 *= self.liquid_share(i, j)
        f = ti.Vector.zero(float, self.dim)
        if r2 >= rc * rc:
            f = self.pair_law.g(r2, (k0, k1, k2), TAICHI) * d
        else:  # inside the core: the force keeps its magnitude at the core radius
            r = ti.sqrt(r2)
            n = d / ti.max(r, 1e-12)
            if r < 1e-12:  # coincident: a deterministic, antisymmetric direction
                n = ti.Vector.zero(float, self.dim)
                n[0] = 1.0 if j > i else -1.0
            f = f_core * n
        if ti.static(self.force_shifted):  # the force at the cutoff subtracted: continuous to zero there
            p, q = self._pair_ids(i, j)
            f -= self.f_cut[base + p, q] / ti.max(ti.sqrt(r2), 1e-12) * d
        return f

    @ti.func
    def viscous_force(self, i, j, d, r2):
        """Viscous pair force on i from j: gamma (1 - r/cutoff) ((v_j - v_i) . n) n."""
        f = ti.Vector.zero(float, self.dim)
        if ti.static(self.has_viscosity):
            p, q = self._pair_ids(i, j)
            r = ti.sqrt(r2)
            inv_r = 1.0 / ti.max(r, 1e-12)  # one division, not one per component
            f = (self.visc[p, q] * (1.0 - r * (1.0 / self.cutoff)) * (self.v[j] - self.v[i]).dot(d) * inv_r * inv_r) * d
        return f

    @ti.func
    def force(self, i, j, d, r2, base):
        """Total pair force on particle i from particle j, d = x_j - x_i, r2 = |d|^2 < cutoff^2; `base`: i's
        row_base."""
        return self.mass[i] * self.scaled_force(i, j, d, r2, base) + self.viscous_force(i, j, d, r2)

    @ti.func
    def force_with(self, c, m_i, base, i, j, d, r2):
        """force(i, j, d, r2, base) given the pair's coefficients c, m_i and i's row_base (loaded by the caller);
        finite at any r, so a caller may evaluate it beyond the cutoff and discard the result (no branch)."""
        return (m_i * self.mass[j]) * self.law(c, i, j, d, r2, base) + self.viscous_force(i, j, d, r2)

    @ti.func
    def energy(self, i, j, r2, base):
        """Potential energy of the pair (i, j) at squared distance r2 (< cutoff^2), shifted to zero at the cutoff
        unless pair.shift is false, continued linearly inside the core (dU/dr stays the capped force); `base`: i's
        row_base."""
        p, q = base + self.material[i], self.material[j]
        r = ti.sqrt(r2)
        rc = self.r_core[p, q]
        re = ti.max(r, rc)
        k0, k1, k2 = self.alpha[p, q], self.beta[p, q], self.eps[p, q]
        s = 1.0  # the attraction's share: vapour feels none, as in law()
        if ti.static(self.boils):
            s = self.liquid_share(i, j)
            k0 *= s
        u = self.pair_law.u(re, (k0, k1, k2), TAICHI) - self.shift[p, q]
        if ti.static(self.boils):
            u += (1.0 - s) * self.shift_att[p, q]
        if r < rc:  # linear continuation: dU/dr stays equal to the (capped) force
            u += self.pair_law.g(rc * rc, (k0, k1, k2), TAICHI) * rc * (r - rc)
        if ti.static(self.force_shifted):
            u -= self.f_cut[p, q] * (r - self.cutoff)
        return self.mass[i] * self.mass[j] * u

    # ------------------------------------------------------------------ its part of the rates
    @ti.func
    def row(self, i):
        """What the pairs of particle i read of i, loaded once per row: the coefficients when every pair has the same
        law (the compiler cannot keep them in registers across the row's field stores), m_i and its row_base."""
        base = self.row_base(i)
        return self.coefficients(base, 0), self.mass[i], base

    @ti.func
    def pair(self, ctx, i, j, d, r2, bonded):
        """Force on i from j (d = x_j - x_i, r2 = |d|^2): evaluated for any listed pair and masked beyond the cutoff
        and for bonded pairs rather than branched around (a listed pair lies within reach + skin, where the law is
        finite, and a branch taken for 80% of pairs mispredicts often)."""
        shared, m_i, base = ctx
        fij = self.force_with(self.pair_coefficients(shared, base, i, j), m_i, base, i, j, d, r2)
        fij *= ti.select((r2 < self.cutoff**2) and not bonded, 1.0, 0.0)
        return fij

    # ------------------------------------------------------------------ its measurements
    @ti.func
    def measure_pairs(self, i):
        """(pair energy, pair virial -d . F_i) of particle i with every j > i within the cutoff, less the pairs
        joined by a live spring (they feel the spring instead)."""
        xi = self.x[i]
        grid = self.parts.neighbours.grid
        base = self.row_base(i)
        acc = grid.fold(i, xi, ti.Vector([0.0, 0.0]), self._measure_one, (i, base))
        if ti.static(self.has_springs):
            acc = fold_bonds(self.springs, i, acc, self._unmeasure_bond, (xi, base))
        return acc[0], acc[1]

    @ti.func
    def _measure_one(self, acc, j, d, k, extra: ti.template()):
        i, base = extra[0], extra[1]
        r2 = d.dot(d)
        if j > i and r2 < self.cutoff**2:
            acc += ti.Vector([self.energy(i, j, r2, base), -d.dot(self.force(i, j, d, r2, base))])
        return acc

    @ti.func
    def _unmeasure_bond(self, acc, i, j, s, extra: ti.template()):
        if j > i:
            d = self.domain.separation(extra[0], self.x[j])
            r2 = d.dot(d)
            if r2 < self.cutoff**2:
                acc -= ti.Vector([self.energy(i, j, r2, extra[1]), -d.dot(self.force(i, j, d, r2, extra[1]))])
        return acc
