"""Taichi fields for particles and materials, allocated by capacity and only for what the scene uses."""

import numpy as np
import taichi as ti

from ..config.build import Particles
from ..config.materials import Material
from . import taichi_compat, transfer
from .oriented import data_oriented
from .transfer import real_fields


@data_oriented
class ParticleFields:
    """Struct-of-arrays particle state. Capacity C, the first n[None] entries active; D = dim."""

    def __init__(self, dim: int, capacity: int, heat: bool, refreeze: bool = False, lifetimes: bool = False):
        self.dim = dim
        self.capacity = capacity
        self.heat = heat
        self.refreeze = refreeze
        self.lifetimes = lifetimes
        self.n = ti.field(ti.i32, shape=())  # active particle count
        self.x = ti.Vector.field(dim, float, shape=capacity)  # position (length), (C, D)
        self.v = ti.Vector.field(dim, float, shape=capacity)  # velocity (length / time), (C, D)
        self.f = ti.Vector.field(dim, float, shape=capacity)  # total force of the last evaluation, (C, D)
        self.mass = ti.field(float, shape=capacity)  # mass, (C,)
        self.radius = ti.field(float, shape=capacity)  # radius (length): walls and drawing, (C,)
        self.material = ti.field(ti.i32, shape=capacity)  # index into the scene's used materials, (C,)
        self.color = ti.Vector.field(3, ti.f32, shape=capacity)  # base colour, RGB in [0, 1], (C, 3)
        self.group = ti.field(ti.i32, shape=capacity)  # the body a particle came from: its drawing style, (C,)
        # the particle's id: its index in the built scene, then numbered on as emitters and tools add particles
        # (stable when storage is reordered or compacted; never reused)
        self.ident = ti.field(ti.i32, shape=capacity)
        self.next_ident = 0  # the id the next added particle gets
        self.table_of = None  # what calling this object returns: set by the Simulation (Scripting.particle_table)
        if heat:
            self.h = ti.field(float, shape=capacity)  # specific enthalpy (heat / mass): the heat state, (C,)
            self.T = ti.field(float, shape=capacity)  # temperature (degrees), derived from h (physics/phase.py), (C,)
            self.dhdt = ti.field(float, shape=capacity)  # enthalpy rate of the last evaluation (heat/mass/time), (C,)
        if refreeze:
            self.liquid = ti.field(ti.i32, shape=capacity)  # 1 once molten, until it refreezes (physics/phase.py)
        if lifetimes:
            self.age = ti.field(float, shape=capacity)  # time since birth, (C,)
            self.lifetime = ti.field(float, shape=capacity)  # retired when age reaches it; 0: for ever, (C,)

    def __call__(self) -> dict:
        """`sim.particles()`: the live particles as NumPy arrays keyed by name, sorted by id (see
        Scripting.particle_table for the keys, units and shapes)."""
        return self.table_of()

    def names(self) -> list[str]:
        """Names of the per-particle fields allocated (the state a snapshot copies)."""
        names = ["x", "v", "f", "mass", "radius", "material", "color", "group", "ident"]
        if self.heat:
            names += ["h", "T", "dhdt"]
        if self.refreeze:
            names.append("liquid")
        if self.lifetimes:
            names += ["age", "lifetime"]
        return names

    def load(self, built: Particles, colors: np.ndarray, materials: list[Material] | None = None) -> None:
        """Copy the initial particles in (entries past the count are left as they are); `materials` (by material id)
        turn the initial temperatures into enthalpies and liquid flags."""
        n = built.count
        self.next_ident = n
        pairs = [
            (self.n, n),
            (self.x, built.x),
            (self.v, built.v),
            (self.f, np.zeros_like(built.x)),
            (self.mass, built.mass),
            (self.radius, built.radius),
            (self.material, built.material),
            (self.color, colors[built.material]),
            (self.group, built.body),
            (self.ident, np.arange(n, dtype=np.int32)),
        ]
        if self.heat:
            h, phi = initial_enthalpy(built.temperature, built.material, materials)
            pairs += [(self.h, h), (self.T, built.temperature), (self.dhdt, np.zeros(n))]
            if self.refreeze:
                breaks = material_column(materials, built.material, "break_melt_fraction")
                pairs.append((self.liquid, ((phi >= breaks) | ~built.solid).astype(np.int32)))
        transfer.upload(pairs)

    def nbytes(self) -> int:
        """Bytes held by these fields."""
        floats = 3 * self.dim + 2 + (3 if self.heat else 0)  # x, v, f, mass, radius, (h, T, dhdt)
        floats += 2 if self.lifetimes else 0  # (age, lifetime)
        ints = 3 + (1 if self.refreeze else 0)  # material, group, ident, (liquid)
        return self.capacity * (floats * (8 if _is_f64() else 4) + 4 * ints + 12)  # + f32 colour


def material_column(materials: list[Material], material: np.ndarray, name: str) -> np.ndarray:
    """Property `name` of each particle's material, (N,), from material ids (N,); infinities held at 1e30 as in
    the MaterialTable fields, so NumPy and the kernels see the same numbers."""
    return np.array([min(getattr(m, name), 1e30) for m in materials])[material]


ENTHALPY_LAW = ("specific_heat", "melt_temperature", "liquidus_temperature", "latent_heat")  # phase.py's arguments


def initial_enthalpy(
    temperature: np.ndarray, material: np.ndarray, materials: list[Material]
) -> tuple[np.ndarray, np.ndarray]:
    """(specific enthalpy, melt fraction) of particles at `temperature` (degrees) of `material` ids."""
    from ..physics.phase import enthalpy_np, melt_fraction_np

    c, ts, tl, latent = (material_column(materials, material, name) for name in ENTHALPY_LAW)
    return enthalpy_np(temperature, c, ts, tl, latent), melt_fraction_np(temperature, ts, tl)


@data_oriented
class MaterialTable:
    """Per-material properties as small fields, indexed by a particle's material id."""

    def __init__(self, materials: list[Material]):
        n = len(materials)
        self.liquid_color = ti.Vector.field(3, ti.f32, shape=n)  # melt colour when drawing by phase, (n_mat, 3)
        liquid = np.array([m.liquid_color for m in materials], dtype=np.float32)
        # Float fields of the running precision, one entry per material, all filled by one copy kernel; NumPy copies
        # of the same numbers are kept for host-side set-up (heat conductance tables).
        self.host = {
            "density": [m.density for m in materials],  # mass / volume
            "specific_heat": [m.specific_heat for m in materials],  # heat / (mass degree)
            "conductivity": [m.conductivity for m in materials],  # heat / (time length degree)
            "soften": [min(m.soften_temperature, 1e30) for m in materials],  # degrees
            "melt": [min(m.melt_temperature, 1e30) for m in materials],  # solidus (degrees)
            "liquidus": [min(m.liquidus_temperature, 1e30) for m in materials],  # degrees
            "latent": [m.latent_heat for m in materials],  # heat / mass
            "stiff_at_melt": [m.stiffness_at_melt for m in materials],  # fraction of k_s left at the solidus
            "break_fraction": [m.break_melt_fraction for m in materials],  # both ends this molten: bond breaks
            "undercool": [m.refreeze_undercooling for m in materials],  # degrees below the solidus to refreeze
            "stiffness": [m.stiffness for m in materials],  # k_s of bonds made by refreezing
            "damping": [m.damping for m in materials],  # k_d of bonds made by refreezing
        }
        self.host = {k: np.asarray(v, dtype=np.float64) for k, v in self.host.items()}
        fields = real_fields(*self.host.values(), also=((self.liquid_color, liquid),))
        for name, field in zip(self.host, fields):
            setattr(self, name, field)
        self.colors = np.array([m.color for m in materials], dtype=np.float32)  # (n_mat, 3)


def _is_f64() -> bool:
    return taichi_compat.default_fp_is_f64()
