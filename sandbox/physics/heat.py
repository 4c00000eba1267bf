"""Particle heat diffusion and heat sources, conserving heat energy exactly between particles.

Discretises rho c dT/dt = div(k grad T) + q with Brookshaw's SPH Laplacian. The heat flow into i from j is

    Q_ij = V_i V_j  2 k_ij (T_j - T_i) (-W'(r) / r),     k_ij = 2 k_i k_j / (k_i + k_j)   (harmonic mean)

with V = m / rho and W the Wendland C2 kernel of support H. Q_ij = -Q_ji, so the sum of m c T is conserved to
round-off without sources (both ends evaluate the same expression). For a normalised kernel the sum tends to
k laplacian(T) V_i as the particle spacing shrinks relative to H.

On a lattice the discrete sum misses the continuum normalisation by a few percent (3.4% for a square lattice with
H = 2.5 spacings), which would show as a diffusivity 3.4% too low. `lattice_correction` measures the sum
S_i = (1/D) sum_j V_j r_ij^2 (-W'(r_ij)/r_ij) on the initial particles (1 for a perfect continuum) and the flow is
divided by its 90th percentile (the interior value); the factor is the same for every pair, so conservation holds.

Heat also flows from sources and the ambient (physics/heat_sources.py). The flows change the specific enthalpy h
(physics/phase.py); time stepping is explicit Euler, stable for dt below about 0.1 (rho c / k) h^2 for spacing h
(Heat.dt_limit; physics/heat_implicit.py is the unconditionally stable stepper).
"""

import math

import numpy as np
import taichi as ti

from ..config.scene_tables import Heat as HeatTable
from ..config.schema import key_check, out_of_range
from ..core.oriented import data_oriented
from ..core.transfer import real_fields
from ..core.worlds import world_entry
from .heat_sources import HeatSources
from .phase import LIQUID, NEVER_BONDS
from .term import Measure, Slider, Term, register


def wendland_grad_factor(r: float, h: float, dim: int) -> float:
    """-W'(r)/r for the Wendland C2 kernel with support h (NumPy/float side)."""
    q = r / h
    if q >= 1:
        return 0.0
    c = 7 / (math.pi * h * h) if dim == 2 else 21 / (2 * math.pi * h**3)
    return c * 20 * (1 - q) ** 3 / (h * h)


def lattice_correction(x: np.ndarray, volume: np.ndarray, h: float, samples: int = 256, seed: int = 0) -> float:
    """The kernel-sum normalisation S (90th percentile over sampled particles) of a packing; 1.0 when the packing
    is too sparse or irregular to judge (S outside 0.8..1.2)."""
    n, dim = x.shape
    if n < 2:
        return 1.0
    rng = np.random.default_rng(seed)
    pick = rng.choice(n, size=min(samples, n), replace=False)
    sums = []
    for i in pick:
        r = np.linalg.norm(x - x[i], axis=1)
        near = (r > 0) & (r < h)
        grad = np.array([wendland_grad_factor(v, h, dim) for v in r[near]])
        sums.append(np.sum(volume[near] * r[near] ** 2 * grad) / dim)
    s = float(np.percentile(sums, 90))
    return s if 0.8 <= s <= 1.2 else 1.0


@register
@data_oriented
class Heat(Term):
    """Heat diffusion between particles and from sources, as a term: the flow of each neighbour pair and of the
    sources into each particle (with the explicit stepper: the implicit one is physics/heat_implicit.py), the power
    sources' per-step mass sums, the enthalpy update at a step's end (temperature and melt fraction follow from it),
    the temperatures and heat content it measures, and its explicit stability limit."""

    key = "heat"
    stage = "heat"
    finish_stage = "heat_update"  # after the walls and kinematic particles have moved: fixed sources hold by position
    measures = (
        Measure("tsum", "sum", "particles"),
        Measure("tcold", "max", "particles", -1e30),  # the largest -T: the coldest
        Measure("thot", "max", "particles", -1e30),
        Measure("heat", "sum", "particles"),
        Measure("phi", "sum", "particles"),
        Measure("meltable", "count", "particles"),
        Measure("psi", "sum", "particles"),
        Measure("boilable", "count", "particles"),
    )

    @staticmethod
    def wanted(parts) -> bool:
        return parts.scene.heat is not None

    @staticmethod
    def host_work(scene) -> str | None:
        """Why this pass needs the host between `scene`'s steps (see the stepping plan), or None."""
        scheduled = scene.heat is not None and any(src.schedule_times for src in scene.heat.sources)
        return "scheduled heat sources change between steps" if scheduled else None

    @staticmethod
    def team_blocker(scene) -> str | None:
        """Why a team of threads cannot step `scene` (team.py), or None: a power source's per-step mass sum is not
        shared out among the workers."""
        power = scene.heat is not None and any(src.mode == "power" for src in scene.heat.sources)
        return "power sources sum their mass each step" if power else None

    def __init__(self, parts):
        model, state = parts.model, parts.state
        heat_scene, built = parts.scene.heat, model.built
        dim, particles, materials, phase = model.dim, state.particles, model.materials, model.phase
        density = model.column("density", built.material)
        correction = lattice_correction(built.x, built.mass / density, parts.scene.heat_radius)
        support = parts.scene.heat_radius
        self.model = model
        self.explicit = heat_scene.stepper == "explicit"  # the rates evaluate its flows; else the implicit solve
        self.pair_channel = "heat" if self.explicit else ""
        self.particle_heat = self.finishes = self.explicit
        self.refreezes = particles.refreeze
        self.reach = float(support)
        self._dt_limit = None  # dt_limit, computed when first asked for
        self.dim = dim
        self.phase = phase
        self.support = float(support)  # the kernel's support radius (length)
        self.correction = correction
        self.norm = (7 / (math.pi * self.support**2) if dim == 2 else 21 / (2 * math.pi * self.support**3)) / correction
        self.p = particles
        self.mats = materials
        # per material pair: 2 k_ij (harmonic mean of the conductivities) times the kernel's constant factor, and
        # per material 1 / density, so the per-pair conductance needs no division
        k = materials.host["conductivity"]
        k_pair = 2.0 * np.outer(k, k) / np.maximum(k[:, None] + k[None, :], 1e-30)
        self.single_material = len(k) == 1
        self.g_pair, self.inv_density = real_fields(
            2.0 * k_pair * self.norm * 20.0 / self.support**2, 1.0 / materials.host["density"]
        )
        self.inv_support = 1.0 / self.support
        self.sources = HeatSources(heat_scene, dim, particles, phase, model.loops)
        self.n_sources = self.sources.n_sources
        self.prestep = self.sources.has_power

    def words(self, where: str) -> list[str]:
        if where == "before":
            return ["scheduled heat sources set to the step's start time"] if self.sources.scheduled else []
        if where == "rates" and self.explicit:
            return [f"heat diffusion (kernel support {self.support:g}, {self.n_sources} sources)"]
        if where == "finish" and self.explicit:
            return ["enthalpy update (temperature and melt fraction from it)"]
        return []

    def before_step(self, state) -> None:
        if self.sources.scheduled:
            self.sources.set_time(state.world_times())

    def after_restore(self, state) -> None:
        self.sources.set_time(state.world_times())

    world_controls = True  # the air's and the sources' temperatures are each world's own (core/worlds.py)

    def controls(self, world: int = 0) -> dict:
        """The air's temperature; with heat sources, each one's temperature or power now and whether it was set by
        hand (1: its schedule no longer applies), so a slider's value survives a save and load; world `world`'s."""
        sources = self.sources
        out = {"ambient": world_entry(sources.ambient, sources.worlds, world)}
        n = len(sources.specs)
        if n:
            out["sources"] = [sources.value(k, world) for k in range(n)]
            out["by_hand"] = [1.0 if k in sources.by_hands[world] else 0.0 for k in range(n)]
        return out

    def sliders(self) -> list[Slider]:
        """The air's temperature, and the first two heat sources' temperature (or power)."""
        out = [Slider("air", "air temperature", "ambient", -50.0, 300.0, "C", 1.0)]
        for k, src in enumerate(self.sources.specs[:2]):
            if src.mode == "power":
                top = 2.0 * max([abs(src.power), *map(abs, src.schedule_values)]) or 1.0
                out.append(Slider(f"source{k}", src.name, "sources", -top, top, "mJ/s", top / 100, index=k))
            else:
                out.append(Slider(f"source{k}", src.name, "sources", -100.0, 1500.0, "C", 1.0, index=k))
        return out

    def control_checks(self) -> dict:
        flags = lambda v: next((f"expected 0 or 1 each, got {x:g}" for x in v if x not in (0.0, 1.0)), None)  # noqa: E731
        return {"ambient": key_check(HeatTable, "ambient"), "sources": out_of_range, "by_hand": flags}

    def apply_controls(self, values: dict, world: int | None = None) -> None:
        """Set world `world`'s controls from `controls()`'s numbers (None: every world's)."""
        sources = self.sources
        if "ambient" in values:
            sources.set_ambient(values["ambient"], world)
        for w in range(sources.worlds) if world is None else (world,):
            if "sources" in values:  # held by hand: kept; scheduled: its schedule sets it again (after_restore)
                now = [sources.value(k, w) for k in range(len(values["sources"]))]
                hand = sources.by_hands[w]
                changed = [1.0 if k in hand or v != now[k] else 0.0 for k, v in enumerate(values["sources"])]
                held = values.get("by_hand", changed)  # without the flags (a slider): those set now are held by hand
                for k, (value, by_hand) in enumerate(zip(values["sources"], held)):
                    if by_hand:
                        sources.hold(k, float(value), w)
                    else:
                        sources.release(k, float(value), w)

    @ti.func
    def flow(self, i, j, r2):
        """Heat flow rate into i from j at squared distance r2 (< support^2)."""
        t_i, c_i, mat_i = self.own_terms(i)
        return self.flow_with(t_i, c_i, mat_i, j, r2)

    @ti.func
    def own_terms(self, i):
        """What the flows into particle i read of i, for a loop over its neighbours to load once: (T_i, c_i, its
        material), c_i being its volume m_i / density, times the pair constant and 1 / density again when every
        particle has one material (the loop then reads only m_j, T_j and the distance of each neighbour)."""
        mat_i = self.p.material[i]
        c_i = self.p.mass[i] * self.inv_density[mat_i]
        if ti.static(self.single_material):
            c_i *= self.g_pair[0, 0] * self.inv_density[0]
        return self.p.T[i], c_i, mat_i

    @ti.func
    def flow_with(self, t_i, c_i, mat_i, j, r2):
        """flow(i, j, r2) from i's own_terms."""
        return self.conductance_with(c_i, mat_i, j, r2) * (self.p.T[j] - t_i)

    @ti.func
    def conductance(self, i, j, r2):
        """G_ij >= 0 with flow_ij = G_ij (T_j - T_i); symmetric in i and j (to round-off)."""
        _t_i, c_i, mat_i = self.own_terms(i)
        return self.conductance_with(c_i, mat_i, j, r2)

    @ti.func
    def conductance_with(self, c_i, mat_i, j, r2):
        """conductance(i, j, r2) from i's own_terms."""
        w = 1.0 - ti.sqrt(r2) * self.inv_support
        g = c_i * self.p.mass[j]
        if ti.static(not self.single_material):
            mat_j = self.p.material[j]
            g *= self.g_pair[mat_i, mat_j] * self.inv_density[mat_j]
        return g * w * w * w

    # ------------------------------------------------------------------ its part of the rates
    @ti.func
    def prestep_loops(self):
        """The mass inside each power source, summed each stage before the rates (they share the power by mass)."""
        self.sources.sum_masses()

    @ti.func
    def row(self, i):
        return self.own_terms(i)

    @ti.func
    def pair(self, ctx, i, j, d, r2, bonded):
        """Heat flow into i from j, masked beyond the kernel's support (finite for any listed pair)."""
        t_i, c_i, mat_i = ctx
        return ti.select(r2 < self.support**2, 1.0, 0.0) * self.flow_with(t_i, c_i, mat_i, j, r2)

    @ti.func
    def heat(self, i):
        return self.sources.flow(i)

    @ti.func
    def finish(self, i, dt, rates: ti.template()):
        """Explicit Euler on the enthalpy with the step's last heat rate; temperature and melt fraction follow."""
        self.set_enthalpy(i, self.p.h[i] + dt * rates.heat_rate[i])

    @ti.func
    def set_enthalpy(self, i, h):
        """Give particle i specific enthalpy h (held by fixed sources), and its temperature and liquid flag."""
        p = self.p
        if ti.static(self.sources.has_fixed):
            h = self.sources.held(i, h)
        p.h[i] = h
        t, phi = self.phase.state(h, p.material[i])
        p.T[i] = t
        if ti.static(self.refreezes):
            if phi >= self.mats.break_fraction[p.material[i]] and p.liquid[i] != NEVER_BONDS:
                p.liquid[i] = LIQUID

    @ti.kernel
    def sync_temperatures(self):
        """Recompute every particle's enthalpy from its temperature (after temperatures were set directly)."""
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            self.p.h[i] = self.phase.enthalpy(self.p.T[i], self.p.material[i])
            self.set_enthalpy(i, self.p.h[i])

    # ------------------------------------------------------------------ its measurements
    @ti.func
    def measure_particle(self, i):
        """(T, -T, T, m h, melt fraction where the material melts, 1 where it melts, gas fraction where it boils,
        1 where it boils)."""
        p = self.p
        t = p.T[i]
        phi, meltable = 0.0, 0
        if self.mats.melt[p.material[i]] < 1e29:
            meltable = 1
            phi = self.phase.fraction(p.h[i], p.material[i])
        psi, boilable = 0.0, 0
        if self.mats.boil[p.material[i]] < 1e29:
            boilable = 1
            psi = self.phase.gas(p.h[i], p.material[i])
        return t, -t, t, p.mass[i] * p.h[i], phi, meltable, psi, boilable

    # ------------------------------------------------------------------ its stability
    def stable_dt(self, integrator) -> float:
        return self.dt_limit if self.explicit else math.inf

    def auto_dt(self, integrator) -> float:
        return 0.5 * self.dt_limit if self.explicit else math.inf

    @property
    def dt_limit(self) -> float:
        """Largest stable explicit heat step on the initial particles (Gershgorin bound), inf without a pair."""
        if self._dt_limit is None:
            self._dt_limit = _explicit_limit(self.model, self.support, self.correction)
        return self._dt_limit


def _explicit_limit(model, support: float, correction: float) -> float:
    """Gershgorin bound on the explicit heat step of the built particles: 1 / max_i (row sum of the heat matrix),
    probed at up to 64 particles."""
    b = model.built
    if b.count < 2:
        return math.inf
    rho = model.column("density", b.material)
    heats = ("specific_heat", "liquid_specific_heat", "gas_specific_heat")
    cap = np.min([model.column(name, b.material) for name in heats], axis=0) * b.mass  # the least of its phases
    k = model.column("conductivity", b.material)
    probe = np.linspace(0, b.count - 1, num=min(b.count, 64)).astype(int)
    worst = 0.0
    vol = b.mass / rho
    for i in probe:
        r = np.linalg.norm(b.x - b.x[i], axis=1)
        near = (r > 0) & (r < support)
        kij = 2 * k[i] * k[near] / np.maximum(k[i] + k[near], 1e-30)
        grad = np.array([wendland_grad_factor(rr, support, model.dim) for rr in r[near]]) / correction
        worst = max(worst, np.sum(vol[i] * vol[near] * 2 * kij * grad) / cap[i])
    return 2.0 / (2.0 * worst) if worst > 0 else math.inf
