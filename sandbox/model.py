"""Taichi fields for particles and materials, allocated by capacity and only for what the scene uses."""

import numpy as np
import taichi as ti

from .build import Particles
from .materials import Material


@ti.data_oriented
class ParticleFields:
    """Struct-of-arrays particle state. Capacity C, the first n[None] entries active; D = dim."""

    def __init__(self, dim: int, capacity: int, heat: bool):
        self.dim = dim
        self.capacity = capacity
        self.heat = heat
        self.n = ti.field(ti.i32, shape=())  # active particle count
        self.x = ti.Vector.field(dim, float, shape=capacity)  # position (length), (C, D)
        self.v = ti.Vector.field(dim, float, shape=capacity)  # velocity (length / time), (C, D)
        self.f = ti.Vector.field(dim, float, shape=capacity)  # total force of the last evaluation, (C, D)
        self.mass = ti.field(float, shape=capacity)  # mass, (C,)
        self.radius = ti.field(float, shape=capacity)  # radius (length): walls and drawing, (C,)
        self.material = ti.field(ti.i32, shape=capacity)  # index into the scene's used materials, (C,)
        self.color = ti.Vector.field(3, ti.f32, shape=capacity)  # base colour, RGB in [0, 1], (C, 3)
        self.group = ti.field(ti.i32, shape=capacity)  # the body a particle came from: its drawing style, (C,)
        if heat:
            self.T = ti.field(float, shape=capacity)  # temperature (degrees), (C,)
            self.dTdt = ti.field(float, shape=capacity)  # temperature rate of the last evaluation, (C,)

    def load(self, built: Particles, colors: np.ndarray) -> None:
        """Copy the initial particles in (entries past the count are left as they are)."""
        n = built.count
        self.n[None] = n
        self._set(self.x, built.x)
        self._set(self.v, built.v)
        self._set(self.f, np.zeros_like(built.x))
        self._set(self.mass, built.mass)
        self._set(self.radius, built.radius)
        self._set(self.material, built.material)
        self._set(self.color, colors[built.material])
        self._set(self.group, built.body)
        if self.heat:
            self._set(self.T, built.temperature)
            self._set(self.dTdt, np.zeros(n))

    def _set(self, field, values: np.ndarray) -> None:
        full = field.to_numpy()
        full[: len(values)] = values
        field.from_numpy(full)

    def nbytes(self) -> int:
        """Bytes held by these fields."""
        floats = 3 * self.dim + 2 + (2 if self.heat else 0)  # x, v, f, mass, radius, (T, dTdt)
        return self.capacity * (floats * (8 if _is_f64() else 4) + 8 + 12)  # + material, group ids + f32 colour


@ti.data_oriented
class MaterialTable:
    """Per-material properties as small fields, indexed by a particle's material id."""

    def __init__(self, materials: list[Material]):
        n = len(materials)

        def table(values, dtype=float):
            field = ti.field(dtype, shape=n)
            field.from_numpy(np.asarray(values, dtype=np.float64 if _is_f64() else np.float32))
            return field

        self.density = table([m.density for m in materials])  # mass / volume
        self.specific_heat = table([m.specific_heat for m in materials])  # heat / (mass degree)
        self.conductivity = table([m.conductivity for m in materials])  # heat / (time length degree)
        self.soften = table([min(m.soften_temperature, 1e30) for m in materials])  # degrees
        self.melt = table([min(m.melt_temperature, 1e30) for m in materials])  # degrees
        self.colors = np.array([m.color for m in materials], dtype=np.float32)  # (n_mat, 3)


def _is_f64() -> bool:
    return ti.lang.impl.get_runtime().default_fp == ti.f64
