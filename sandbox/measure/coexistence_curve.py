"""The molecular model's liquid-vapour curve, as measured by `sandbox study --coexistence` and shipped with the
assets (assets/coexistence_lj_lfs25.csv in 3D, assets/coexistence_lj_lfs25_2d.csv in 2D), in reduced units.

Between the measured points the vapour pressure follows the fitted Clausius-Clapeyron line ln p = a - b / T (a
straight line of ln p against 1/T, as the measured points are within their errors); it ends at the critical point
fitted from the coexisting densities (research/coexistence.py), above which there is one fluid. The curve belongs to
one model only: the 12-6 Lennard-Jones force, force-shifted at 2.5 sigma, in one material of unit mass; a scene of
any other pair law has no measured curve (curve_of returns None), never a borrowed one.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass

import numpy as np

from ..config.resources import ASSETS_DIR

CURVES = {3: "coexistence_lj_lfs25.csv", 2: "coexistence_lj_lfs25_2d.csv"}
BETA = {3: 0.325, 2: 0.125}  # the Ising critical exponents of rho_l - rho_v


@dataclass(frozen=True)
class CoexistenceCurve:
    """The measured points (T, p_sat with its error; reduced units), the fitted line and critical point."""

    temperatures: tuple[float, ...]
    pressures: tuple[float, ...]
    errors: tuple[float, ...]
    a: float  # ln p = a - b / T
    b: float
    critical_temperature: float
    critical_pressure: float
    critical_density: float  # from the law of rectilinear diameters

    def boiling_temperature(self, pressure: float) -> float:
        """The temperature at which the fitted line ln p = a - b / T reaches `pressure` (an extrapolation outside
        the measured points)."""
        return self.b / (self.a - math.log(pressure))

    def vapour_pressure(self, temperature):
        """The fitted saturation pressure at `temperature` (scalar or array; nan above the critical point)."""
        t = np.asarray(temperature, float)
        p = np.exp(self.a - self.b / np.maximum(t, 1e-6))
        return np.where(t <= self.critical_temperature, p, np.nan)

    def region(self, temperature: float, pressure: float) -> str:
        """ "gas" below the curve, "liquid" above it, "fluid" above the critical temperature."""
        if temperature > self.critical_temperature:
            return "fluid"
        return "gas" if pressure < float(self.vapour_pressure(temperature)) else "liquid"


def fit_curve(temperatures, pressures, errors, rho_liquid, rho_vapour, dim: int) -> CoexistenceCurve:
    """The curve through measured points (at least two; reduced units): the line ln p = a - b / T by least squares,
    and the critical point from the scaling law rho_l - rho_v = A (T_c - T)^beta (BETA[dim]) and the law of
    rectilinear diameters (rho_l + rho_v) / 2 = rho_c + B (T - T_c)."""
    t, p = np.asarray(temperatures, float), np.asarray(pressures, float)
    rl, rv = np.asarray(rho_liquid, float), np.asarray(rho_vapour, float)
    slope, intercept = np.polyfit(1.0 / t, np.log(p), 1)
    s, c = np.polyfit(t, (rl - rv) ** (1.0 / BETA[dim]), 1)
    tc = -c / s
    d_slope, d_intercept = np.polyfit(t, 0.5 * (rl + rv), 1)
    return CoexistenceCurve(
        tuple(t),
        tuple(p),
        tuple(np.asarray(errors, float)),
        float(intercept),
        float(-slope),
        float(tc),
        float(math.exp(intercept + slope / tc)),
        float(d_slope * tc + d_intercept),
    )


def load_curve(rows: list[dict], dim: int) -> CoexistenceCurve:
    """The curve from a study's CSV rows (research/coexistence.py's SlabPoint fields)."""
    column = {
        key: [float(r[key]) for r in rows] for key in ("temperature", "p_sat", "p_sat_err", "rho_liquid", "rho_vapour")
    }
    return fit_curve(*column.values(), dim)


def curve_of(model) -> CoexistenceCurve | None:
    """The measured curve of `model`'s scene when it is the molecular model with the force-shifted 12-6 LJ force at
    2.5 sigma in one material of unit mass (else None), from the shipped CSV of its dimension."""
    scene = model.scene
    pair = scene.pair
    if scene.molecular is None or pair is None or len(model.material_list) != 1:
        return None
    material = model.material_list[0]
    if not (pair.a == 8.0 and pair.b == 14.0 and pair.cutoff == 2.5 and pair.force_shift):
        return None
    if not (material.pair_alpha == 24.0 and material.pair_beta == 48.0 and material.particle_mass == 1.0):
        return None
    return shipped_curve(scene.dim)


def shipped_curve(dim: int) -> CoexistenceCurve | None:
    """The measured curve of the force-shifted 12-6 LJ atom in `dim` dimensions as shipped (None where its CSV is
    missing)."""
    path = ASSETS_DIR / CURVES[dim]
    if not path.exists():
        return None
    with open(path, newline="") as f:
        return load_curve(list(csv.DictReader(f)), dim)
