"""The pressure-temperature phase diagram of a scene's boiling material, as the mesoscale model's rule makes it.

The curves are Clausius-Clapeyron's, from the material's latent heats and molar mass (its `molar_mass`, g/mol; where
unset, Trouton's rule L_v M = 88 J/mol/K x T_b):

    vapour pressure      P_v(T) = P_b exp(B_v (1/T_b - 1/T)),   B_v = L_v M / R
    sublimation          P_s(T) = P_v(T_m) exp(B_s (1/T_m - 1/T)),   B_s = (L_f + L_v) M / R   (below T_m)
    melting line         T = T_m (the sandbox's melting point does not depend on pressure)

with temperatures in kelvin. The vapour curve is anchored at the boiling point T_b to P_b, the vapour pressure there:
until the material has boiled, the ideal gas's estimate of the pressure in the scene's box with all of it vapour at
T_b, N k T_b / V (N particles of it, k = heat.agitation_scale, V the box's volume, its area in 2D); once it has, the
mean pressure the gauge read while it boiled (render/phase_plot.py).

This is the model's rule, not a measurement (the mesoscale model's melting and boiling points are set numbers): the
panel says so, and marks the model's temperature on it with a line, not a dot (render/phase_plot.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

KELVIN = 273.15
GAS_CONSTANT = 8.314  # J / (mol K)
TROUTON = 88.0  # J / (mol K): the entropy of vaporization of most liquids at their boiling point
HEADROOM = 16.0  # the pressure axis reaches this factor above the vapour curve a little past the boiling point
BOILING = (0.05, 0.95)  # gas fractions between which the material is boiling (on the vapour curve)
REGIONS = ("solid", "liquid", "gas")


@dataclass(frozen=True)
class PhaseMap:
    """The phase diagram of one material (temperatures in °C, pressures in the scene's unit of pressure)."""

    material: str
    melt: float  # °C
    boil: float  # °C
    b_vapour: float  # K: L_v M / R
    b_solid: float  # K: (L_f + L_v) M / R
    anchor: float  # P_b: the pressure at the boiling point with all of the material vapour

    def vapour_pressure(self, temperature):
        """Coexistence pressure (liquid or solid with its vapour) at `temperature` °C (scalar or array)."""
        t = np.asarray(temperature, float) + KELVIN
        tm, tb = self.melt + KELVIN, self.boil + KELVIN
        liquid = self.anchor * np.exp(self.b_vapour * (1.0 / tb - 1.0 / np.maximum(t, tm)))
        triple = self.anchor * math.exp(self.b_vapour * (1.0 / tb - 1.0 / tm))
        solid = triple * np.exp(self.b_solid * (1.0 / tm - 1.0 / np.minimum(t, tm)))
        return np.where(t >= tm, liquid, solid)

    def triple_point(self) -> tuple[float, float]:
        """(°C, pressure) where solid, liquid and vapour coexist."""
        return self.melt, float(self.vapour_pressure(self.melt))

    def region(self, temperature: float, pressure: float) -> str:
        """'solid', 'liquid' or 'gas': the region of the diagram the point (°C, pressure) lies in."""
        if pressure < float(self.vapour_pressure(temperature)):
            return "gas"
        return "solid" if temperature < self.melt else "liquid"

    def axes(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((T lo, T hi) °C, (P lo, P hi)): the diagram's ranges, from below the melting point to well past boiling
        and from the sublimation curve's foot to HEADROOM above the vapour curve a little past boiling."""
        span = self.boil - self.melt
        t_lo, t_hi = self.melt - 0.5 * span, self.boil + 2.0 * span
        p_lo = float(self.vapour_pressure(t_lo))
        p_hi = HEADROOM * float(self.vapour_pressure(self.boil + 0.25 * span))
        return (t_lo, t_hi), (p_lo, p_hi)


def phase_map_of(model) -> PhaseMap | None:
    """The phase map of `model`'s first material that boils (None if none does, or the scene has no heat)."""
    scene = model.scene
    if scene.heat is None:
        return None
    for mid, material in enumerate(model.material_list):
        if not material.boils:
            continue
        tb = material.boil_temperature + KELVIN
        molar = material.molar_mass
        b_vapour = material.vaporization_heat * molar / GAS_CONSTANT if molar else TROUTON * tb / GAS_CONSTANT
        b_solid = b_vapour * (1.0 + material.latent_heat / max(material.vaporization_heat, 1e-12))
        count = int(np.count_nonzero(np.asarray(model.built.material) == mid))
        volume = float(np.prod(np.asarray(scene.world.hi, float) - np.asarray(scene.world.lo, float)))
        anchor = count * scene.heat.agitation_scale * tb / volume
        return PhaseMap(
            model.material_names[mid], material.melt_temperature, material.boil_temperature, b_vapour, b_solid, anchor
        )
    return None
