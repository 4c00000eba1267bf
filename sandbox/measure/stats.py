"""What a simulation measures at an instant (`Stats`), and the columns of the measurements CSV."""

# No `from __future__ import annotations`: the dataclass's fields are read as they are written.
from dataclasses import dataclass

STAT_COLUMNS = (
    "frame",
    "time",
    "kinetic_energy",
    "potential_energy",
    "total_energy",
    "spring_energy",
    "pair_energy",
    "gravity_energy",
    "kinetic_energy_per_particle",
    "potential_energy_per_particle",
    "total_energy_per_particle",
    "pressure",
    "wall_pressure",
    "mean_temperature",
    "kinetic_temperature",
    "molten_fraction",
    "gas_fraction",
    "heat_content",
    "broken_springs",
    "max_speed",
    "particles",
    "step_seconds",
)


def stat_values(frame: int, stats: "Stats", step_seconds: float) -> dict:
    """The STAT_COLUMNS of frame `frame` by name: its measurements `stats` and its steps' wall time (seconds)."""
    row = {"frame": frame, "step_seconds": step_seconds}
    row.update({k: getattr(stats, k) for k in STAT_COLUMNS if k not in row})
    return row


@dataclass
class Stats:
    """Measurements of one instant. Energies are totals over the particles in scaled units (mass x length^2 /
    time^2); the pair energy is shifted to zero at the cutoff unless pair.shift = false. Temperatures in degrees."""

    time: float
    kinetic_energy: float
    spring_energy: float
    pair_energy: float
    gravity_energy: float
    mean_temperature: float
    molten_fraction: float  # mean melt fraction of the particles of meltable materials
    heat_content: float  # sum of m h: the heat (enthalpy) in the particles, conserved without sources
    broken_springs: int
    max_speed: float
    particles: int
    pressure: float = float("nan")  # virial pressure (sum m v^2 + sum r_ij . F_ij) / (dim V), V the box's volume
    # momentum the walls took per unit time and wall area since the gauge restarted (each frame); nan without walls
    # or before any time has passed
    wall_pressure: float = float("nan")
    # temperature as motion (heat.agitation_time): the temperature the molten particles' motion relative to the local
    # flow says, m |v - u|^2 / (dim x heat.agitation_scale) - 273.15 averaged; nan without the thermostat
    kinetic_temperature: float = float("nan")
    gas_fraction: float = 0.0  # mean gas (vapour) fraction of the particles of materials that boil

    @property
    def phase_shares(self) -> tuple[float, float, float]:
        """(solid, liquid, gas) shares in [0, 1] of a scene whose material melts and boils: the gas is counted among
        the molten."""
        gas = min(max(self.gas_fraction, 0.0), 1.0)
        molten = max(self.molten_fraction, gas)
        return 1.0 - molten, molten - gas, gas

    @property
    def potential_energy(self) -> float:
        return self.spring_energy + self.pair_energy + self.gravity_energy

    @property
    def total_energy(self) -> float:
        return self.kinetic_energy + self.potential_energy

    @property
    def kinetic_energy_per_particle(self) -> float:
        return self.kinetic_energy / self.particles if self.particles else float("nan")

    @property
    def potential_energy_per_particle(self) -> float:
        return self.potential_energy / self.particles if self.particles else float("nan")

    @property
    def total_energy_per_particle(self) -> float:
        return self.total_energy / self.particles if self.particles else float("nan")

    @classmethod
    def from_sums(cls, m: dict, time: float, dim: int, volume: float, wall_pressure: float, heat: bool, springs: bool):
        """The Stats of the named sums and counts `m` (measure/diagnostics.py) at `time`: the pressure over the box's
        volume `volume` (area in 2D)."""
        n = m["n"]
        return cls(
            time=time,
            kinetic_energy=m["ke"],
            spring_energy=m.get("spring", 0.0),
            pair_energy=m.get("pair", 0.0),
            gravity_energy=m.get("grav", 0.0),
            mean_temperature=m["tsum"] / n if (heat and n) else float("nan"),
            molten_fraction=m["phi"] / m["meltable"] if m.get("meltable") else 0.0,
            heat_content=m["heat"] if heat else float("nan"),
            broken_springs=int(m["created"]) - int(m["alive"]) if springs else 0,
            max_speed=m["vmax"],
            particles=n,
            pressure=(2.0 * m["ke"] + m.get("pair_virial", 0.0) + m.get("spring_virial", 0.0)) / (dim * volume),
            wall_pressure=wall_pressure,
            kinetic_temperature=m["agitation"] / (dim * m["free"]) - 273.15 if m.get("free") else float("nan"),
            gas_fraction=m["psi"] / m["boilable"] if m.get("boilable") else 0.0,
        )
