"""The probe: what the particle under the cursor is (material, phase, temperature, melt fraction, speed).

The window finds the particle (2D: the nearest centre within reach of the cursor's point in the world; 3D: the
nearest drawn particle under the cursor, Renderer.pick_index) and shows `probe(sim, i).text()` in its panel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..physics.phase import ENTHALPY_LAW, temperature_np


@dataclass(frozen=True)
class ProbeReading:
    """One particle's readout: temperature (degrees) and melt fraction (0..1) are None without heat."""

    index: int
    material: str
    phase: str  # solid, melting, liquid; without heat: solid (bonded by springs) or fluid
    temperature: float | None
    melt_fraction: float | None
    speed: float  # length / time

    def text(self) -> str:
        """One line for the panel, e.g. "wax, melting, 52.1 C, 40% molten, speed 0.31 /s" (lengths per second, the
        unit of the speed colour bar)."""
        parts = [self.material, self.phase]
        if self.temperature is not None:
            parts += [f"{self.temperature:.1f} C", f"{100 * self.melt_fraction:.0f}% molten"]
        return ", ".join(parts + [f"speed {self.speed:.3g} /s"])

    def fields(self) -> dict:
        """The reading as values for a page to put in its own words: material and phase names, temperature
        (degrees, rounded to 0.1), melt percent and speed (3 significant digits); None where there is no heat."""
        return {
            "material": self.material,
            "phase": self.phase,
            "temperature": None if self.temperature is None else round(self.temperature, 1),
            "melt": None if self.melt_fraction is None else round(100 * self.melt_fraction),
            "speed": float(f"{self.speed:.3g}"),
        }


def particle_at(sim, point, reach: float | None = None, world: int | None = None) -> int | None:
    """2D (or 3D with a world point): the particle whose centre is nearest `point` (length units, (D,)) within
    `reach` (default: 1.5 particle radii), or None; of world `world` alone where given (a simulation of many,
    core/worlds.py; its storage slot is returned)."""
    x = sim.positions() if world is None else sim.world(world).positions()
    if len(x) == 0:
        return None
    d2 = ((x - np.asarray(point, dtype=float)) ** 2).sum(axis=1)
    j = int(np.argmin(d2))
    i = j if world is None else int(sim.world(world).slots()[j])  # a world's positions are by id
    if reach is None:
        reach = 1.5 * float(sim.particles.radius[i])
    return i if d2[j] <= reach * reach else None


def probe(sim, i: int) -> ProbeReading:
    """The readout of live particle `i` (0 <= i < the live count)."""
    p = sim.particles
    material_id = int(p.material[i])
    name = sim.material_names[material_id]
    speed = float(np.linalg.norm(p.v[i].to_numpy()))
    if sim.terms.heat is None:
        springs = sim.state.springs
        bonds = [int(springs.bonds[i, k]) for k in range(springs.max_bonds)] if springs is not None else []
        bonded = any(s >= 0 and springs.alive[s] for s in bonds)
        return ProbeReading(i, name, "solid" if bonded else "fluid", None, None, speed)

    material = sim.scene.materials[name]
    law = (getattr(material, key) for key in ENTHALPY_LAW)
    phi = float(temperature_np(np.array([float(p.h[i])]), *law)[1][0])
    phase = "solid" if phi <= 0.0 else "liquid" if phi >= 1.0 else "melting"
    return ProbeReading(i, name, phase, float(p.T[i]), phi, speed)
