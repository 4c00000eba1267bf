"""The materials table: physical properties per material, loaded from assets/materials.toml and scene overrides.

Units are the engine's scaled units (see README "Units"): length in particle spacings, mass in the mass of one
particle of density 1, time in simulation seconds, temperature in degrees Celsius.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from dataclasses import dataclass
from pathlib import Path

from ..errors import SceneError
from .schema import celsius, non_negative, parse_table, positive, spec, unit_interval, unknown

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

from .resources import ASSETS_DIR, MATERIALS_FILE, read_small_text  # noqa: F401 - ASSETS_DIR is re-exported for scene.py


def _colour(c: tuple[float, ...]) -> str | None:
    if len(c) != 3 or not all(0 <= v <= 1 for v in c):
        return f"expected [r, g, b] with each in [0, 1], got {list(c)}"
    return None


@dataclass(frozen=True, kw_only=True)
class Material:
    """One material's properties (scaled units)."""

    density: float = spec(1.0, doc="mass per unit volume (per unit area in 2D)", check=positive)
    specific_heat: float = spec(
        1.0, doc="heat per unit mass per degree (of the solid, and of every phase unless set)", check=positive
    )
    liquid_specific_heat: float | None = spec(
        None, doc="heat per unit mass per degree of the liquid (default: specific_heat)", check=positive
    )
    gas_specific_heat: float | None = spec(
        None, doc="heat per unit mass per degree of the vapour (default: liquid_specific_heat)", check=positive
    )
    conductivity: float = spec(1.0, doc="thermal conductivity", check=non_negative)
    stiffness: float = spec(
        1000.0, doc="spring stiffness k_s of bonds in this material (force per length)", check=positive
    )
    damping: float = spec(5.0, doc="spring damping k_d (force per speed)", check=non_negative)
    soften_temperature: float = spec(
        math.inf, doc="bonds start to lose stiffness above this temperature (inf: never)", check=celsius, infinite=True
    )
    melt_temperature: float = spec(
        math.inf, doc="solidus: melting starts at this temperature (inf: never melts)", check=celsius, infinite=True
    )
    liquidus_temperature: float | None = spec(
        None,
        doc="fully liquid at this temperature (default: melt_temperature, a pure substance); the melt fraction "
        "rises linearly from the solidus to here",
        check=celsius,
        infinite=True,
    )
    latent_heat: float = spec(
        0.0, doc="heat per unit mass that melting absorbs and freezing releases (specific enthalpy)", check=non_negative
    )
    boil_temperature: float = spec(
        math.inf,
        doc="the liquid boils at this temperature (inf: never): it holds there while vaporization_heat is taken, "
        "and its vapour feels no pair attraction",
        check=celsius,
        infinite=True,
    )
    vaporization_heat: float = spec(
        0.0,
        doc="heat per unit mass that boiling absorbs and condensing releases (specific enthalpy)",
        check=non_negative,
    )
    molar_mass: float | None = spec(
        None,
        doc="g/mol, for the phase diagram's vapour-pressure curve (Clausius-Clapeyron); unset: Trouton's rule",
        check=positive,
    )
    stiffness_at_melt: float = spec(
        0.2,
        doc="fraction of the bond stiffness left when the solid reaches melt_temperature (softening is linear from "
        "soften_temperature); the melt fraction then takes it to zero",
        check=unit_interval,
    )
    break_melt_fraction: float = spec(
        0.5,
        doc="a bond breaks when both its ends are at least this molten",
        check=lambda f: None if 0 < f <= 1 else f"expected a number in (0, 1], got {f}",
    )
    refreeze_undercooling: float = spec(
        1.0,
        doc="a molten particle refreezes (forms new bonds) once this many degrees below melt_temperature",
        check=non_negative,
    )
    pair_alpha: float = spec(0.0, doc="attraction coefficient alpha of the pair force", check=non_negative)
    pair_beta: float = spec(0.0, doc="repulsion coefficient beta of the pair force", check=non_negative)
    pair_soft: float = spec(0.0, doc="softening epsilon of the attraction term (length)", check=non_negative)
    viscosity: float = spec(0.0, doc="pair damping along the line of centres (liquid viscosity)", check=non_negative)
    color: tuple[float, ...] = spec((0.8, 0.8, 0.8), doc="base colour [r, g, b] in [0, 1]", check=_colour)
    liquid_color: tuple[float, ...] = spec(
        (1.0, 0.45, 0.1), doc="colour of the melt when drawing by phase (render.color_by = 'phase')", check=_colour
    )
    particle_mass: float | None = spec(None, doc="mass of one particle; default density * spacing^dim", check=positive)
    note: str = spec("", doc="where the numbers come from")
    based_on: str = spec(
        "",
        doc="(scene tables only) start from this material (library, or defined earlier in the scene) and override keys",
    )

    def __post_init__(self):
        if self.soften_temperature > self.melt_temperature:
            object.__setattr__(self, "soften_temperature", self.melt_temperature)
        if self.liquidus_temperature is None:
            object.__setattr__(self, "liquidus_temperature", self.melt_temperature)
        if self.liquid_specific_heat is None:
            object.__setattr__(self, "liquid_specific_heat", self.specific_heat)
        if self.gas_specific_heat is None:
            object.__setattr__(self, "gas_specific_heat", self.liquid_specific_heat)

    @property
    def melts(self) -> bool:
        return math.isfinite(self.melt_temperature)

    @property
    def boils(self) -> bool:
        return math.isfinite(self.boil_temperature)


# (key, the key it defaults to): the order matters, a follower may lead the next
FOLLOWERS = (
    ("liquidus_temperature", "melt_temperature"),
    ("liquid_specific_heat", "specific_heat"),
    ("gas_specific_heat", "liquid_specific_heat"),
)


def check_material(material: Material, file: str, key: str) -> Material:
    """Cross-key checks of one material table; raises SceneError naming the key."""
    if material.liquidus_temperature < material.melt_temperature:
        raise SceneError(
            file,
            f"{key}.liquidus_temperature",
            f"expected a temperature >= melt_temperature ({material.melt_temperature:g}), "
            f"got {material.liquidus_temperature:g}",
        )
    if not material.melts and (material.latent_heat > 0 or math.isfinite(material.liquidus_temperature)):
        raise SceneError(file, f"{key}.melt_temperature", "expected a finite melting temperature with latent heat")
    return material


def load_library(path: Path = MATERIALS_FILE) -> dict[str, Material]:
    """Read the materials library (a TOML file of [name] tables) into Material objects."""
    try:
        data = tomllib.loads(read_small_text(path))
    except FileNotFoundError as exc:
        raise SceneError(str(path), "", "materials library not found") from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SceneError(str(path), "", f"not valid TOML: {exc}") from exc
    except (ValueError, OSError) as exc:
        raise SceneError(str(path), "", f"not a materials library: {exc}") from exc
    return {
        name: check_material(parse_table(Material, table, str(path), name), str(path), name)
        for name, table in data.items()
    }


def resolve_materials(scene_tables: dict, file: str) -> dict[str, Material]:
    """The library plus a scene's [materials.NAME] tables (each may start from a library entry with `based_on`)."""
    library = load_library()
    if not isinstance(scene_tables, dict):
        raise SceneError(file, "materials", "expected a table of [materials.NAME] tables")
    result = dict(library)
    for name, table in scene_tables.items():
        key = f"materials.{name}"
        if not isinstance(table, dict):
            raise SceneError(file, key, "expected a table")
        base_name = table.get("based_on", "")
        if not isinstance(base_name, str):
            raise SceneError(file, f"{key}.based_on", f"expected a material name (a string), got {base_name!r}")
        if base_name:
            if base_name not in result:  # the library, or a material defined earlier in the scene
                raise SceneError(
                    file,
                    f"{key}.based_on",
                    unknown("material", base_name, result),
                )
            merged = {f.name: getattr(result[base_name], f.name) for f in dataclasses.fields(Material)}
            merged["based_on"] = ""
            base = result[base_name]
            # a key that follows another in the base (a pure substance's liquidus, one specific heat for every
            # phase) goes on following it when the table sets the other
            for follower, leader in FOLLOWERS:
                if getattr(base, follower) == getattr(base, leader) and (leader in table or leader not in merged):
                    merged.pop(follower)
            merged.update(table)
            merged = {k: list(v) if isinstance(v, tuple) else v for k, v in merged.items() if v is not None}
            table = merged
        result[name] = check_material(parse_table(Material, table, file, key), file, key)
    return result
