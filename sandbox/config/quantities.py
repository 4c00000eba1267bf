"""Every quantity a simulation reports, declared once: its name (the CSV column, the `Stats` attribute, the chart
series), its unit, its words, and how it follows from the measuring kernel's sums.

The terms declare the sums they feed (physics/term.py's `measures`: "ke", "tsum", ...; the reduction and what it
runs over); this table turns them into the quantities people read. Everything else is derived from it: the
measurements CSV's columns (measure/stats.STAT_COLUMNS), the `Stats` record, the series a scene's `render.chart` may
plot and their axis labels (measure/units.series_words), and the table in docs/physics.md (`python -m
sandbox.config.quantities` prints it; a test keeps the two equal). It sits in config, the lowest layer, because the
scene schema checks and documents chart names with it, and the CSV must have the same columns for every scene.

A new readout is one `Quantity(...)` here (and, where it needs a new sum, a `Measure` in its term).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

NAN = float("nan")


@dataclass(frozen=True)
class Sums:
    """What a quantity is computed from: the kernel's named sums and counts `m` (physics/term.py's measures), the
    clock, the dimension, the box's volume (area in 2D), the walls' gauge, whether the scene has heat and springs;
    `of(name)` is another quantity's value (computed once, whatever the declaration order)."""

    m: dict
    time: float
    dim: int
    volume: float
    wall_pressure: float
    heat: bool
    springs: bool
    done: dict

    def of(self, name: str) -> float:
        """The quantity `name`'s value."""
        if name not in self.done:
            q = BY_NAME[name]
            value = q.value(self)
            self.done[name] = int(value) if q.integer else float(value)
        return self.done[name]


@dataclass(frozen=True)
class Quantity:
    """One reported quantity (module docstring). `unit`: one of UNIT_KINDS, read in the scene's units
    (measure/units.py); `words`: a few words for labels; `doc`: one sentence for docs/physics.md; `value`: from Sums
    (nan where the scene has nothing to measure); `chart`: whether render.chart may plot it; `integer`: a count;
    `source`: one of SOURCES, what a reader is told the number is (panel, page, chart legends, docs)."""

    name: str
    unit: str
    words: str
    doc: str
    value: Callable[[Sums], float]
    chart: bool = True
    integer: bool = False
    source: str = "measured"


# What a number is: "measured" from the particles' motion, forces and the energy exchanged (it comes out of a run);
# "rule": the mesoscale model's heat and phase variables, which follow the material's set numbers (its melting and
# boiling points, latent heats, conductivity) and the rules that break bonds and switch a parcel's pull; "clock": the
# simulated time. The molecular model has no rule-made readout: its temperature and phases come from the motion.
SOURCES = ("measured", "rule", "clock")
RULE_WORDS = "set by the model's rule, not measured"

UNIT_KINDS = ("s", "length", "energy", "kT", "energy per particle", "pressure", "°C", "%", "heat", "speed", "count")


def _per_particle(name: str) -> Callable[[Sums], float]:
    return lambda s: s.of(name) / s.of("particles") if s.of("particles") else NAN


def _share(total: str, count: str) -> Callable[[Sums], float]:
    return lambda s: s.m[total] / s.m[count] if s.m.get(count) else 0.0


def _motion_temperature(s: Sums) -> float:
    """kT of the atoms' motion about their centre of mass (k = 1), from the kinetic energy, momentum and mass sums."""
    if "momentum_x" not in s.m or s.m["n"] < 2 or not s.m["mass"]:
        return NAN
    p2 = sum(s.m[f"momentum_{a}"] ** 2 for a in "xyz")
    return (2.0 * s.m["ke"] - p2 / s.m["mass"]) / (s.dim * (s.m["n"] - 1))


def _phase_temperature(energy: str, kinds: tuple[str, ...]) -> Callable[[Sums], float]:
    def value(s: Sums) -> float:
        count = sum(s.m.get(kind, 0) for kind in kinds)
        return 2.0 * s.m[energy] / (s.dim * count) if energy in s.m and count else NAN

    return value


def _structure_share(kind: str) -> Callable[[Sums], float]:
    return lambda s: s.m[kind] / s.m["n"] if kind in s.m and s.m["n"] else NAN


QUANTITIES: tuple[Quantity, ...] = (
    Quantity("time", "s", "time", "simulated time", lambda s: s.time, chart=False, source="clock"),
    Quantity("kinetic_energy", "energy", "kinetic energy", "sum of m v^2 / 2", lambda s: s.m["ke"]),
    Quantity("potential_energy", "energy", "potential energy", "spring + pair + gravity energy",
             lambda s: s.of("spring_energy") + s.of("pair_energy") + s.of("gravity_energy")),
    Quantity("total_energy", "energy", "total energy", "kinetic + potential energy",
             lambda s: s.of("kinetic_energy") + s.of("potential_energy")),
    Quantity("spring_energy", "energy", "spring energy", "elastic energy of the live springs",
             lambda s: s.m.get("spring", 0.0), chart=False),
    Quantity("pair_energy", "energy", "pair energy", "pair potential energy, shifted to zero at the cutoff "
             "unless pair.shift = false", lambda s: s.m.get("pair", 0.0), chart=False),
    Quantity("gravity_energy", "energy", "gravity energy", "m g h against the scene's gravity",
             lambda s: s.m.get("grav", 0.0), chart=False),
    Quantity("kinetic_energy_per_particle", "energy per particle", "kinetic energy per particle",
             "kinetic energy / particles", _per_particle("kinetic_energy"), chart=False),
    Quantity("potential_energy_per_particle", "energy per particle", "potential energy per particle",
             "potential energy / particles", _per_particle("potential_energy"), chart=False),
    Quantity("total_energy_per_particle", "energy per particle", "total energy per particle",
             "total energy / particles", _per_particle("total_energy"), chart=False),
    Quantity("pressure", "pressure", "pressure", "virial pressure (sum m v^2 + sum r_ij . F_ij) / (dim V), V the "
             "box's volume (area in 2D)",
             lambda s: (2.0 * s.m["ke"] + s.m.get("pair_virial", 0.0) + s.m.get("spring_virial", 0.0))
             / (s.dim * s.volume)),
    Quantity("wall_pressure", "pressure", "pressure on the walls", "momentum the walls took per unit time and wall "
             "area since the frame began; nan without walls", lambda s: s.wall_pressure),
    Quantity("mean_temperature", "°C", "mean temperature", "mean particle temperature (the heat model's: "
             "conducted, and held at the material's melting and boiling points by its rule); nan without heat",
             lambda s: s.m["tsum"] / s.m["n"] if (s.heat and s.m["n"]) else NAN, source="rule"),
    Quantity("kinetic_temperature", "°C", "temperature of the motion", "the temperature the molten particles' "
             "motion relative to the local flow says (heat.agitation_time); nan without it",
             lambda s: s.m["agitation"] / (s.dim * s.m["free"]) - 273.15 if s.m.get("free") else NAN),
    Quantity("motion_temperature", "kT", "temperature (kT)", "the atoms' kinetic temperature kT (k = 1): "
             "(sum m v^2 - |sum m v|^2 / sum m) / (dim (N - 1)); nan outside the molecular model",
             _motion_temperature),
    Quantity("condensed_temperature", "kT", "temperature of solid and liquid (kT)", "kT of the atoms counted "
             "solid or liquid: sum m v^2 / (dim N) over them (a drop at rest); nan when there are none",
             _phase_temperature("ke_condensed", ("solid", "liquid"))),
    Quantity("gas_temperature", "kT", "temperature of the gas (kT)", "kT of the atoms counted gas: sum m v^2 / "
             "(dim N) over them; nan when there are none", _phase_temperature("ke_gas", ("gas",))),
    Quantity("structure_solid", "%", "solid (by structure)", "share of the atoms whose neighbours sit in order "
             "(physics/structure.py); nan outside the molecular model", _structure_share("solid")),
    Quantity("structure_liquid", "%", "liquid (by structure)", "share of the atoms that are dense but not in "
             "order; nan outside the molecular model", _structure_share("liquid")),
    Quantity("structure_gas", "%", "gas (by structure)", "share of the atoms with almost no neighbours; nan "
             "outside the molecular model", _structure_share("gas")),
    Quantity("wall_heat", "energy", "heat through the walls", "energy the thermal walls have given the atoms "
             "(negative: taken) since the start; 0 without them", lambda s: s.m.get("wall_heat", 0.0)),
    Quantity("heater_heat", "energy", "heat from the heater", "energy the molecular heater has shared among the "
             "atoms (negative: taken) since the start; 0 without it", lambda s: s.m.get("heater_heat", 0.0)),
    Quantity("lid_height", "length", "lid height", "the molecular model's lid's height along y; nan without a lid",
             lambda s: s.m.get("lid_height", NAN)),
    Quantity("lid_pressure", "pressure", "pressure on the lid", "momentum the atoms gave the lid per unit time and "
             "lid area since the frame began (its outside pressure and weight, on average, once it rests); nan without "
             "a lid", lambda s: s.m["lid_impulse"] / (s.time - s.m["lid_since"])
             if "lid_impulse" in s.m and s.time > s.m["lid_since"] else NAN),
    Quantity("molten_fraction", "%", "molten", "mean melt fraction of the particles of meltable materials (each melts "
             "at its material's set point by rule)", _share("phi", "meltable"), source="rule"),
    Quantity("gas_fraction", "%", "boiled", "mean vapour fraction of the particles of materials that boil (each "
             "boils at its material's set point by rule)", _share("psi", "boilable"), source="rule"),
    Quantity("heat_content", "heat", "heat content", "sum of m h: the enthalpy in the particles, conserved without "
             "sources; nan without heat", lambda s: s.m["heat"] if s.heat else NAN, source="rule"),
    Quantity("broken_springs", "count", "broken bonds", "springs created minus springs alive (a spring "
             "breaks by rule: both ends molten enough, or stretched 100-fold)",
             lambda s: int(s.m["created"]) - int(s.m["alive"]) if s.springs else 0, chart=False, integer=True,
             source="rule"),
    Quantity("max_speed", "speed", "fastest particle", "the largest particle speed", lambda s: s.m["vmax"]),
    Quantity("centre_of_mass_height", "length", "centre of mass height", "the particles' centre of mass along y "
             "(the axis of every shipped scene's gravity): sum m y / sum m; nan without particles",
             lambda s: s.m["mass_height"] / s.m["mass"] if s.m.get("mass") else NAN),
    Quantity("particles", "count", "particles", "particles alive", lambda s: s.m["n"], chart=False, integer=True),
)  # fmt: skip

PHASE_DIAGRAM = "phase_diagram"  # a chart that is not a measurement: the phase diagram with the state's dot


def _checked(quantities: tuple[Quantity, ...]) -> dict[str, Quantity]:
    """The quantities by name; ValueError at import for a name declared twice or an unknown unit kind."""
    by_name: dict[str, Quantity] = {}
    for q in quantities:
        if q.name in by_name or q.name == PHASE_DIAGRAM:
            raise ValueError(f"quantity {q.name!r} is declared twice; expected one declaration per name")
        if q.source not in SOURCES:
            raise ValueError(f"quantity {q.name!r} has source {q.source!r}; expected one of {', '.join(SOURCES)}")
        if q.unit not in UNIT_KINDS:
            raise ValueError(f"quantity {q.name!r} has unit {q.unit!r}; expected one of {', '.join(UNIT_KINDS)}")
        by_name[q.name] = q
    return by_name


BY_NAME = _checked(QUANTITIES)
CHART_SERIES = tuple(q.name for q in QUANTITIES if q.chart) + (PHASE_DIAGRAM,)


def compute(m: dict, time: float, dim: int, volume: float, wall_pressure: float, heat: bool, springs: bool) -> dict:
    """Every quantity by name from the kernel's sums `m` (see Sums), in declaration order."""
    sums = Sums(m, time, dim, volume, wall_pressure, heat, springs, {})
    return {q.name: sums.of(q.name) for q in QUANTITIES}


class _Reading(dict):
    """A table of sums that notes every name read from it (each reads as 1.0, so every branch that needs a value
    is taken)."""

    def __init__(self) -> None:
        super().__init__()
        self.read: set[str] = set()

    def __getitem__(self, name):
        self.read.add(name)
        return 1.0

    def get(self, name, default=None):
        self.read.add(name)
        return 1.0

    def __contains__(self, name) -> bool:
        self.read.add(name)
        return True


def measures_read() -> dict[str, set[str]]:
    """The measure names (physics/term.py's `measures`, and the particle count "n") each quantity reads, found by
    computing it on a table that notes what is read."""
    out = {}
    for q in QUANTITIES:
        m = _Reading()
        Sums(m, 1.0, 2, 1.0, 1.0, True, True, {}).of(q.name)
        out[q.name] = m.read
    return out


def check_measures(known: set[str]) -> None:
    """Every measure a quantity reads is one of `known` (every name any term or the motion declares): ValueError
    naming the quantity and the measure otherwise, so a renamed measure stops the build instead of reading 0."""
    for name, read in measures_read().items():
        unknown = sorted(read - known)
        if unknown:
            raise ValueError(
                f"quantity {name!r} reads the measure {', '.join(map(repr, unknown))}, which no term declares; "
                "expected a name of a term's `measures` (physics/term.py)"
            )


def markdown_table() -> str:
    """The quantities as docs/physics.md's table: name, unit, what it is (SOURCES), meaning."""
    rows = ["| quantity | unit | source | meaning |", "|---|---|---|---|"]
    rows += [f"| `{q.name}` | {q.unit} | {q.source} | {q.doc} |" for q in QUANTITIES]
    return "\n".join(rows)


if __name__ == "__main__":  # python -m sandbox.config.quantities: the table for docs/physics.md
    print(markdown_table())
