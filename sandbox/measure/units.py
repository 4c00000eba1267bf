"""The units a scene's numbers come in, and are shown in, in words for labels (docs/physics.md, "Units").

A particle spacing is 1 mm, a particle of density 1 weighs 1 mg and time is in seconds, so energies are in
picojoules (mg mm^2/s^2) and pressures in pJ per mm^2 (2D) or per mm^3 (3D). Reduced Lennard-Jones scenes (every
material "lj") measure length in sigma and energy in epsilon. A scene whose every material is "argon" computes in the
same reduced units and is shown in argon's (REAL_SUBSTANCES: epsilon / k = 119.8 K, sigma = 0.3405 nm, m = 39.95 u):
temperatures in K, pressures in kPa, lengths in nm, times in ps. `shown(kind, ...)` gives the factor and the unit a
value of each kind is shown in; files (CSV, state files, caches) keep the computed, reduced numbers. Units are spelled
in the characters every font of the project has (the window's and the pictures'): "mm^2", "eps", "sigma", and the
degree sign.
"""

from __future__ import annotations

import math

from ..config.quantities import PHASE_DIAGRAM, QUANTITIES

BOLTZMANN = 1.380649e-23  # J/K
ATOMIC_MASS = 1.66053907e-27  # kg
# Real substances a material of reduced Lennard-Jones units may stand for: epsilon / k (K), sigma (nm), mass (u)
REAL_SUBSTANCES = {"argon": {"epsilon_over_k": 119.8, "sigma_nm": 0.3405, "mass_u": 39.95}}


def reduced(material_names) -> bool:
    """Whether a scene of these materials is shown in reduced Lennard-Jones units (every material "lj")."""
    return set(material_names) == {"lj"}


def substance(material_names) -> dict | None:
    """The real substance a scene of these materials stands for (every material that one), else None."""
    names = set(material_names)
    return REAL_SUBSTANCES[next(iter(names))] if len(names) == 1 and names <= set(REAL_SUBSTANCES) else None


def _real_scales(real: dict, dim: int) -> dict[str, tuple[float, str]]:
    """(factor, unit) by kind for a substance of REAL_SUBSTANCES."""
    energy = real["epsilon_over_k"] * BOLTZMANN  # J
    sigma = real["sigma_nm"] * 1e-9  # m
    tau = sigma * math.sqrt(real["mass_u"] * ATOMIC_MASS / energy)  # s
    pressure = (energy / sigma**2 * 1e3, "mN/m") if dim == 2 else (energy / sigma**3 / 1e3, "kPa")
    return {
        "kT": (real["epsilon_over_k"], "K"),
        "energy": (energy / 1e-21, "zJ"),
        "heat": (energy / 1e-21, "zJ"),
        "length": (real["sigma_nm"], "nm"),
        "time": (tau / 1e-12, "ps"),
        "speed": (sigma / tau, "m/s"),
        "power": (energy / tau / 1e-9, "nW"),
        "pressure": pressure,
        "acceleration": (sigma / tau**2 / 1e12, "nm/ps^2"),
    }


def shown(kind: str, material_names, dim: int = 2) -> tuple[float, str]:
    """(factor, unit): a value of unit kind `kind` ("kT", "energy", "heat", "length", "time", "speed", "power",
    "pressure", "acceleration"; any other kind is shown as it is, in that unit) is shown as factor x value in unit."""
    kind = {"s": "time"}.get(kind, kind)  # the clock's declared unit
    real = substance(material_names)
    scales = _real_scales(real, dim) if real is not None else {}
    if kind in scales:
        return scales[kind]
    lj = reduced(material_names) or real is not None
    length, energy = ("sigma", "eps") if lj else ("mm", "pJ")
    unit = {
        "kT": energy,
        "energy": energy,
        "heat": "eps" if lj else "mJ",  # mass (mg) times enthalpy (kJ/kg)
        "length": length,
        "time": "s",
        "speed": f"{length}/s",
        "power": f"{energy}/s",
        "pressure": f"{energy}/{length}^{dim}",
        "acceleration": f"{length}/s^2",
    }.get(kind, kind)
    return 1.0, unit


def length_unit(material_names) -> str:
    """The unit of length lengths are shown in: "mm", "sigma" in reduced units, "nm" for argon."""
    return shown("length", material_names)[1]


def energy_unit(material_names) -> str:
    """The unit energies are shown in: "pJ", "eps" in reduced units, "zJ" for argon."""
    return shown("energy", material_names)[1]


def speed_unit(material_names) -> str:
    """The unit speeds are shown in: "mm/s", "sigma/s" in reduced units, "m/s" for argon."""
    return shown("speed", material_names)[1]


def pressure_unit(material_names, dim: int) -> str:
    """The unit pressures are shown in: energy per area (2D) or per volume (3D), "pJ/mm^2", "eps/sigma^3", ..., or
    argon's "mN/m" (2D) and "kPa" (3D)."""
    return shown("pressure", material_names, dim)[1]


# Each chart series' words and unit kind, from the declared quantities ("kT", "energy", "heat", "speed" and
# "pressure" stand for the scene's units of them)
SERIES = {q.name: (q.words, q.unit) for q in QUANTITIES if q.chart} | {PHASE_DIAGRAM: ("phase diagram", "")}


def series_words(name: str, material_names, dim: int = 2) -> tuple[str, str]:
    """(words, unit) of the measurement `name` for a `dim`-D scene of these materials."""
    words, kind = SERIES.get(name, (name.replace("_", " "), ""))
    return words, shown(kind, material_names, dim)[1]


def series_scale(name: str, material_names, dim: int = 2) -> float:
    """The factor the measurement `name`'s computed value is shown times (1 but for a real substance's scene)."""
    return shown(SERIES.get(name, ("", ""))[1], material_names, dim)[0]
