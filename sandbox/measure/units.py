"""The units a scene's numbers come in, in words for labels (docs/physics.md, "Units").

A particle spacing is 1 mm, a particle of density 1 weighs 1 mg and time is in seconds, so energies are in
picojoules (mg mm^2/s^2) and pressures in pJ per mm^2 (2D) or per mm^3 (3D). Reduced Lennard-Jones scenes (every
material "lj") measure length in sigma and energy in epsilon. Units are spelled in the characters every font of
the project has (the window's and the pictures'): "mm^2", "eps", "sigma", and the degree sign.
"""

from __future__ import annotations

from ..config.quantities import PHASE_DIAGRAM, QUANTITIES


def reduced(material_names) -> bool:
    """Whether a scene of these materials is in reduced Lennard-Jones units (every material "lj")."""
    return set(material_names) == {"lj"}


def length_unit(material_names) -> str:
    """The unit of length: "mm", or "sigma" in reduced units."""
    return "sigma" if reduced(material_names) else "mm"


def energy_unit(material_names) -> str:
    """The unit of energy: "pJ", or "eps" in reduced units."""
    return "eps" if reduced(material_names) else "pJ"


def speed_unit(material_names) -> str:
    """The unit of speed: "mm/s", or "sigma/s" in reduced units."""
    return f"{length_unit(material_names)}/s"


def pressure_unit(material_names, dim: int) -> str:
    """The unit of pressure: energy per area (2D) or per volume (3D): "pJ/mm^2", "pJ/mm^3", "eps/sigma^2", ..."""
    return f"{energy_unit(material_names)}/{length_unit(material_names)}^{dim}"


# Each chart series' words and unit kind, from the declared quantities ("energy", "heat", "speed" and "pressure"
# stand for the scene's units of them)
SERIES = {q.name: (q.words, q.unit) for q in QUANTITIES if q.chart} | {PHASE_DIAGRAM: ("phase diagram", "")}


def series_words(name: str, material_names, dim: int = 2) -> tuple[str, str]:
    """(words, unit) of the measurement `name` for a `dim`-D scene of these materials."""
    words, unit = SERIES.get(name, (name.replace("_", " "), ""))
    if unit == "length":
        unit = length_unit(material_names)
    elif unit == "energy":
        unit = energy_unit(material_names)
    elif unit == "heat":  # mass (mg) times enthalpy (kJ/kg)
        unit = "eps" if reduced(material_names) else "mJ"
    elif unit == "speed":
        unit = speed_unit(material_names)
    elif unit == "pressure":
        unit = pressure_unit(material_names, dim)
    return words, unit
