"""Phase change by enthalpy: latent heat, the melt fraction, and refreezing.

Each particle carries its specific enthalpy h (heat per unit mass); heat diffusion changes h, and the temperature T
and melt fraction phi follow from h through the material's specific heat c, solidus Ts (melt_temperature), liquidus
Tl and latent heat L:

    h(T) = c T + L phi(T),    phi(T) = clamp((T - Ts) / (Tl - Ts), 0, 1)    (a step at Ts when Tl = Ts)

so between h_s = c Ts and h_l = c Tl + L, added heat goes into phi rather than T (for a pure substance T holds at Ts
while the solid melts). Above the liquidus the liquid's own specific heat c_l takes over, h = h_l + c_l (T - Tl), up
to the boiling point Tb (h_b = h_l + c_l (Tb - Tl)); the temperature holds at Tb while the vaporization heat L_v is
taken, and the vapour warms with its own c_g: h = h_b + L_v + c_g (T - Tb). A material with one specific heat for every
phase (c_l = c_g = c) keeps the closed forms c T + L phi + L_v psi, bit for bit. Heat flows between particles are
antisymmetric, so the total sum m h is conserved to round-off without sources, through melting and freezing alike.

Refreezing: a particle whose melt fraction reached its material's break_melt_fraction is flagged liquid. Every few
steps (heat.refreeze_interval) a pass bonds pairs of the same material that are both cold (phi = 0 and
T <= Ts - refreeze_undercooling), not yet bonded, closer than heat.refreeze_radius, with a free bond slot each, where at
least one of the two is a liquid particle; the new spring's rest length is their current distance. A liquid particle
that formed a bond is solid again. Breaking needs the melt fraction back at break_melt_fraction, so a particle at the
boundary cannot flicker between phases (hysteresis of the whole mushy band plus the undercooling).
"""

import numpy as np
import taichi as ti

from ..core import runtime
from ..core.model import material_column
from ..core.oriented import data_oriented
from ..core.particles import fold_bonds
from ..core.worlds import add_at, world_of
from .term import Term, register

LIQUID = 1  # flag values of Particles.liquid: molten since it last froze
FREEZING = 2  # (during a refreeze pass: liquid and cold enough to bond)
NEVER_BONDS = 3  # mortal emitted particles (physics/emitters.py): refreezing never bonds them


def melt_fraction_np(T: np.ndarray, solidus: np.ndarray, liquidus: np.ndarray) -> np.ndarray:
    """phi(T) in [0, 1] (NumPy): linear across [solidus, liquidus], a step above the solidus when they are equal."""
    T = np.asarray(T, dtype=np.float64)
    band = np.asarray(liquidus, dtype=np.float64) - solidus
    with np.errstate(divide="ignore", invalid="ignore"):
        ramp = np.where(band > 0, (T - solidus) / np.where(band > 0, band, 1.0), np.where(T > solidus, 1.0, 0.0))
    return np.clip(ramp, 0.0, 1.0)


def _phase_heats(c, liquid_c, gas_c) -> tuple[np.ndarray, np.ndarray]:
    """The liquid's and the vapour's specific heats, defaulting to the solid's and the liquid's."""
    liquid_c = np.asarray(c if liquid_c is None else liquid_c, dtype=np.float64)
    gas_c = np.asarray(liquid_c if gas_c is None else gas_c, dtype=np.float64)
    return liquid_c, gas_c


def enthalpy_np(T, c, solidus, liquidus, latent, boil=np.inf, vapor=0.0, liquid_c=None, gas_c=None) -> np.ndarray:
    """Specific enthalpy (heat per unit mass) of particles at temperature T (degrees): c T + L phi(T) + L_v psi(T)
    with one specific heat c, else each phase warming with its own (liquid_c, gas_c); psi, the gas fraction, is a
    step at the boiling point (a particle set at it starts as liquid)."""
    T = np.asarray(T, dtype=np.float64)
    c, liquidus, boil = (np.asarray(a, dtype=np.float64) for a in (c, liquidus, boil))
    liquid_c, gas_c = _phase_heats(c, liquid_c, gas_c)
    gas = np.where(T > boil, np.asarray(vapor, dtype=np.float64), 0.0)
    one = c * T + np.asarray(latent) * melt_fraction_np(T, solidus, liquidus) + gas
    with np.errstate(invalid="ignore"):
        rise = np.where(T > liquidus, liquid_c * (np.minimum(T, boil) - liquidus), 0.0)
        rise = rise + np.where(T > boil, gas_c * (T - boil), 0.0)
        per_phase = c * np.minimum(T, liquidus) + np.asarray(latent) * melt_fraction_np(T, solidus, liquidus)
    return np.where((liquid_c == c) & (gas_c == c), one, per_phase + gas + rise)


def _boiling_enthalpy_np(c, liquidus, latent, boil, liquid_c) -> np.ndarray:
    """h_b: the liquid at its boiling point (boil held at 1e30 for a material that never boils)."""
    boil = np.minimum(boil, 1e30)
    with np.errstate(invalid="ignore"):
        per_phase = np.asarray(c) * liquidus + latent + liquid_c * (boil - liquidus)
    return np.where(liquid_c == c, np.asarray(c) * boil + latent, per_phase)


def gas_fraction_np(h, c, liquidus, latent, boil=np.inf, vapor=0.0, liquid_c=None) -> np.ndarray:
    """psi in [0, 1] (NumPy twin of Phase.gas): the share of the vaporization heat taken above the enthalpy at which
    the liquid reaches its boiling point."""
    h = np.asarray(h, dtype=np.float64)
    liquid_c, _ = _phase_heats(c, liquid_c, None)
    hb = _boiling_enthalpy_np(c, liquidus, latent, boil, liquid_c)
    vapor = np.asarray(vapor, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        psi = np.where(vapor > 0, (h - hb) / np.where(vapor > 0, vapor, 1.0), np.where(h > hb, 1.0, 0.0))
    return np.clip(psi, 0.0, 1.0)


def temperature_np(
    h, c, solidus, liquidus, latent, boil=np.inf, vapor=0.0, liquid_c=None, gas_c=None
) -> tuple[np.ndarray, np.ndarray]:
    """(T, phi) from specific enthalpy h (NumPy twin of Phase.state, for tests and initial states)."""
    h = np.asarray(h, dtype=np.float64)
    liquid_c, gas_c = _phase_heats(c, liquid_c, gas_c)
    boil, vapor, liquid_c, gas_c = (
        np.broadcast_to(np.asarray(a, dtype=np.float64), h.shape) for a in (boil, vapor, liquid_c, gas_c)
    )
    c, ts, tl, lat = (np.broadcast_to(np.asarray(a, dtype=np.float64), h.shape) for a in (c, solidus, liquidus, latent))
    hs, hl = c * ts, c * tl + lat
    T = h / c
    phi = np.zeros_like(h)
    above = h >= hl
    one = (liquid_c == c) & (gas_c == c)
    hb = _boiling_enthalpy_np(c, tl, lat, boil, liquid_c)  # the liquid at its boiling point
    with np.errstate(invalid="ignore", over="ignore"):
        liquid_t = np.where(one, (h - lat) / c, tl + (h - hl) / liquid_c)
        gas_t = np.where(one, (h - lat - vapor) / c, np.minimum(boil, 1e30) + (h - hb - vapor) / gas_c)
    T = np.where(above, liquid_t, T)
    T = np.where(above & (h > hb), np.where(h < hb + vapor, boil, gas_t), T)
    phi = np.where(above, 1.0, phi)
    mushy = (h > hs) & ~above
    wide = mushy & (tl > ts)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_wide = ts + (h - hs) / (c + lat / np.where(tl > ts, tl - ts, 1.0))
        T = np.where(wide, t_wide, T)
        phi = np.where(wide, (t_wide - ts) / np.where(tl > ts, tl - ts, 1.0), phi)
        narrow = mushy & ~(tl > ts)
        T = np.where(narrow, ts, T)
        phi = np.where(narrow, (h - hs) / np.where(lat > 0, lat, 1.0), phi)
    return T, phi


# the law's arguments (temperature_np and enthalpy_np take them in this order)
ENTHALPY_LAW = (
    "specific_heat",
    "melt_temperature",
    "liquidus_temperature",
    "latent_heat",
    "boil_temperature",
    "vaporization_heat",
    "liquid_specific_heat",
    "gas_specific_heat",
)


def initial_enthalpy(temperature: np.ndarray, material: np.ndarray, materials: list) -> tuple[np.ndarray, np.ndarray]:
    """(specific enthalpy, melt fraction) of particles at `temperature` (degrees) of `material` ids (into the
    `materials` records)."""
    law = [material_column(materials, material, name) for name in ENTHALPY_LAW]
    return enthalpy_np(temperature, *law), melt_fraction_np(temperature, law[1], law[2])


@data_oriented
class Phase:
    """The enthalpy -> (temperature, melt fraction) law per material, as Taichi funcs."""

    def __init__(self, materials):
        self.mats = materials

    @ti.func
    def one_heat(self, mat):
        """Whether material mat has one specific heat for every phase (then the closed forms hold bit for bit)."""
        c = self.mats.specific_heat[mat]
        return self.mats.liquid_heat[mat] == c and self.mats.gas_heat[mat] == c

    @ti.func
    def boiling_enthalpy(self, mat):
        """h_b: the liquid of material mat at its boiling point (about 1e30 c for one that never boils)."""
        c = self.mats.specific_heat[mat]
        hb = c * self.mats.boil[mat] + self.mats.latent[mat]
        if not self.one_heat(mat):
            tl = self.mats.liquidus[mat]
            hb = c * tl + self.mats.latent[mat] + self.mats.liquid_heat[mat] * (self.mats.boil[mat] - tl)
        return hb

    @ti.func
    def state(self, h, mat):
        """(T, phi) of specific enthalpy h in material mat."""
        c = self.mats.specific_heat[mat]
        ts, tl, lat = self.mats.melt[mat], self.mats.liquidus[mat], self.mats.latent[mat]
        hs = c * ts
        hl = c * tl + lat
        t = 0.0
        phi = 0.0
        if h <= hs:
            t = h / c
        elif h >= hl:
            phi = 1.0
            boil, lv = self.mats.boil[mat], self.mats.vaporize[mat]
            hb = self.boiling_enthalpy(mat)  # never reached by a material that does not boil (boil = 1e30)
            if self.one_heat(mat):
                t = (h - lat) / c
                if h > hb:
                    t = boil if h < hb + lv else (h - lat - lv) / c
            else:
                t = tl + (h - hl) / self.mats.liquid_heat[mat]
                if h > hb:
                    t = boil if h < hb + lv else boil + (h - hb - lv) / self.mats.gas_heat[mat]
        elif tl > ts:
            t = ts + (h - hs) / (c + lat / (tl - ts))
            phi = (t - ts) / (tl - ts)
        else:
            t = ts
            phi = (h - hs) / lat
        return t, phi

    @ti.func
    def enthalpy(self, t, mat):
        """Specific enthalpy of material mat at temperature t (liquid at the boiling point, gas above it)."""
        ts, tl = self.mats.melt[mat], self.mats.liquidus[mat]
        phi = 0.0
        if tl > ts:
            phi = ti.min(ti.max((t - ts) / (tl - ts), 0.0), 1.0)
        elif t > ts:
            phi = 1.0
        c, boil = self.mats.specific_heat[mat], self.mats.boil[mat]
        h = 0.0
        if self.one_heat(mat):
            h = c * t + self.mats.latent[mat] * phi
            if t > boil:
                h += self.mats.vaporize[mat]
        else:
            h = c * ti.min(t, tl) + self.mats.latent[mat] * phi
            if t > tl:
                h += self.mats.liquid_heat[mat] * (ti.min(t, boil) - tl)
            if t > boil:
                h += self.mats.vaporize[mat] + self.mats.gas_heat[mat] * (t - boil)
        return h

    @ti.func
    def capacity(self, h, mat):
        """dh/dT away from a phase change: the specific heat of the phase that specific enthalpy h is in (the
        solid's up to the liquidus, the liquid's up to the end of boiling, then the vapour's)."""
        c = self.mats.specific_heat[mat]
        if h >= c * self.mats.liquidus[mat] + self.mats.latent[mat]:
            c = self.mats.liquid_heat[mat]
            if h >= self.boiling_enthalpy(mat) + self.mats.vaporize[mat]:
                c = self.mats.gas_heat[mat]
        return c

    @ti.func
    def gas(self, h, mat):
        """Gas fraction psi in [0, 1] of specific enthalpy h in material mat: the share of its vaporization heat
        taken (0 for a material that never boils)."""
        hb = self.boiling_enthalpy(mat)
        lv = self.mats.vaporize[mat]
        psi = 0.0
        if h > hb:
            psi = 1.0
            if lv > 0.0:
                psi = ti.min((h - hb) / lv, 1.0)
        return psi

    @ti.func
    def fraction(self, h, mat):
        """Melt fraction phi in [0, 1] of specific enthalpy h in material mat."""
        _, phi = self.state(h, mat)
        return phi


@register
@data_oriented
class Refreeze(Term):
    """The refreezing pass, every heat.refreeze_interval steps at a step boundary: new springs between cold
    particles where at least one end was liquid."""

    key = "refreeze"
    stage = "refreeze"

    @staticmethod
    def wanted(parts) -> bool:
        heat = parts.scene.heat
        return bool(heat and heat.refreeze and any(m.melts for m in parts.model.material_list))

    def __init__(self, parts):
        self.parts = parts  # the grid it scans is built after the terms
        self.p = parts.state.particles
        self.springs = parts.state.springs
        self.mats = parts.model.materials
        self.phase = parts.model.phase
        self.radius = parts.scene.refreeze_radius
        self.interval = parts.scene.heat.refreeze_interval
        self.made = ti.field(ti.i32, shape=())  # springs made by the last pass
        self.full = ti.field(ti.i32, shape=())  # 1 when the last pass found no free spring slot

    def words(self, where: str) -> list[str]:
        if where != "boundary":
            return []
        return [
            f"every {self.interval} steps: refreezing (new bonds within {self.radius:g} between frozen particles where "
            "one was molten)"
        ]

    def next_due(self, state) -> int:
        return self.interval - state.step % self.interval

    def at_step(self, state, done: int) -> bool:
        """Refreeze when the `done` steps just taken passed a multiple of the interval; True when springs were made."""
        return state.step // self.interval > (state.step - done) // self.interval and self.run() > 0

    def run(self) -> int:
        """One refreezing pass at the current positions (rebuilds the cell grid); returns the springs made."""
        self.parts.neighbours.grid.rebuild()
        with runtime.without_cfg_pass():  # run between batches: see transfer.py's docstring
            self._prepare()
            self._bond()
        return int(self.made[None])

    @ti.func
    def cold(self, i):
        """Frozen through: no melt left and at least the undercooling below the solidus."""
        mat = self.p.material[i]
        t, phi = self.phase.state(self.p.h[i], mat)
        return phi <= 0.0 and t <= self.mats.melt[mat] - self.mats.undercool[mat]

    @ti.kernel
    def _prepare(self):
        """Drop broken springs from every bond list (keeping each list packed) and mark cold liquid particles."""
        s = self.springs
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            kept = 0
            for k in range(s.max_bonds):
                b = s.bonds[i, k]
                if b >= 0 and s.alive[b]:
                    s.bonds[i, kept] = b
                    kept += 1
            for k in range(kept, s.max_bonds):
                s.bonds[i, k] = -1
            if self.p.liquid[i] == LIQUID and self.cold(i):
                self.p.liquid[i] = FREEZING

    @ti.func
    def bond_count(self, i):
        """Particle i's bonds (after _prepare every listed spring is alive, the lists packed)."""
        return fold_bonds(self.springs, i, 0, self._count_bond, ())

    @ti.func
    def already_bonded(self, i, j):
        """Whether i and j are joined by a spring (of i's list, all alive after _prepare)."""
        return fold_bonds(self.springs, i, 0, self._count_bond_to, (j,)) > 0

    @ti.func
    def _count_bond(self, n, i, j, s, extra: ti.template()):
        return n + 1

    @ti.func
    def _count_bond_to(self, n, i, j, s, extra: ti.template()):
        return n + ti.cast(j == extra[0], ti.i32)

    @ti.kernel
    def _bond(self):
        """Serial: bond each freezing particle to its cold same-material neighbours in reach, reusing dead slots."""
        p = self.p
        grid = self.parts.neighbours.grid
        self.made[None] = 0
        self.full[None] = 0
        cursor = 0
        ti.loop_config(serialize=True)
        for i in range(p.n[None]):
            if p.idle(i):
                continue
            if p.liquid[i] == FREEZING:
                cursor = grid.fold(i, p.x[i], cursor, self._bond_to, (i, p.material[i]))
        for i in range(p.n[None]):
            if p.idle(i):
                continue
            if p.liquid[i] == FREEZING:
                p.liquid[i] = LIQUID
                if self.bond_count(i) > 0:
                    p.liquid[i] = 0

    @ti.func
    def _bond_to(self, cursor, j, d, k, extra: ti.template()):
        """Bond freezing particle i = extra[0] (of material extra[1]) to j if j qualifies, in the first free spring
        slot at or after `cursor`; returns where the next search starts."""
        s, p = self.springs, self.p
        i, mat = extra[0], extra[1]
        r2 = d.dot(d)
        candidate = p.liquid[j] == 0 or p.liquid[j] == FREEZING  # not molten, not mortal
        if j != i and r2 <= self.radius**2 and p.material[j] == mat and candidate:
            ni, nj = self.bond_count(i), self.bond_count(j)
            if ni < s.max_bonds and nj < s.max_bonds and self.cold(j) and not self.already_bonded(i, j):
                while cursor < s.count and s.alive[cursor]:
                    cursor += 1
                if cursor < s.count:
                    s.i[cursor] = i
                    s.j[cursor] = j
                    s.rest[cursor] = ti.sqrt(r2)
                    s.ks[cursor] = self.mats.stiffness[mat]
                    s.kd[cursor] = self.mats.damping[mat]
                    s.factor[cursor] = 1.0
                    s.alive[cursor] = 1
                    s.bonds[i, ni] = cursor
                    s.bonds[j, nj] = cursor
                    add_at(s.created, world_of(p, i), 1)
                    s.span[None] = ti.max(s.span[None], cursor + 1)
                    self.made[None] += 1
                else:
                    self.full[None] = 1
        return cursor
